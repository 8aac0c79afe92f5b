"""How the grid's rows are split over MPI ranks, and how distributed fields move between ranks.

Fields on the grid are numpy arrays of shape (nx, ny), axis 0 along X; a flattened field has index
ix * ny + iy. Under MPI every field is split by rows: a rank owns the contiguous X-rows of its
:class:`RowPartition` range and all ny columns of them.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from mpi4py.util.dtlib import from_numpy_dtype


@dataclass(frozen=True)
class RowPartition:
    """An even split of ``n`` rows over ``size`` ranks: rank r owns rows ``starts[r]:starts[r+1]``."""

    n: int
    size: int

    @cached_property
    def starts(self) -> np.ndarray:
        counts = np.full(self.size, self.n // self.size)
        counts[: self.n % self.size] += 1
        return np.concatenate([[0], np.cumsum(counts)])

    @property
    def counts(self) -> np.ndarray:
        return np.diff(self.starts)

    def range(self, rank: int) -> tuple[int, int]:
        return int(self.starts[rank]), int(self.starts[rank + 1])


def move_rows(local: np.ndarray, src: list[tuple[int, int]], dst: list[tuple[int, int]], comm) -> np.ndarray:
    """Re-split the rows of a distributed 2-D array.

    ``local`` holds global rows ``src[rank]`` (all its columns); the result holds rows ``dst[rank]``. Every
    row a rank asks for must be owned by some rank in ``src``. Only the rows that change hands travel,
    straight from ``local`` into the result (no packed copies).
    """
    rank = comm.rank
    ncol = local.shape[1]
    s0, (d0, d1) = src[rank][0], dst[rank]
    if comm.size == 1:
        return local[d0 - s0 : d1 - s0]
    send = [_overlap(src[rank], dst[r]) for r in range(comm.size)]
    recv = [_overlap(src[r], dst[rank]) for r in range(comm.size)]
    out = np.empty((d1 - d0, ncol), dtype=local.dtype)
    sent = ([(b - a) * ncol for a, b in send], [(a - s0) * ncol for a, _ in send])
    received = ([(b - a) * ncol for a, b in recv], [(a - d0) * ncol for a, _ in recv])
    comm.Alltoallv([np.ascontiguousarray(local), sent], [out, received])
    return out


def _overlap(a: tuple[int, int], b: tuple[int, int]) -> tuple[int, int]:
    lo, hi = max(a[0], b[0]), min(a[1], b[1])
    return (lo, max(lo, hi))


def shift_field(local: np.ndarray, di: int, dj: int, rows: RowPartition, comm) -> np.ndarray:
    """The distributed field moved by (di, dj) cells: out[i, j] = field[i - di, j - dj], zero where that
    falls outside the grid. ``local`` holds this rank's rows of ``rows``."""
    ranges = [rows.range(r) for r in range(comm.size)]
    wanted = [(min(max(a - di, 0), rows.n), min(max(b - di, 0), rows.n)) for a, b in ranges]
    wanted = [(a, max(a, b)) for a, b in wanted]
    got = move_rows(local, ranges, wanted, comm)
    out = np.zeros_like(local)
    r0 = ranges[comm.rank][0]
    a, b = wanted[comm.rank]
    start = a + di - r0
    ny = local.shape[1]
    c0, c1 = max(dj, 0), min(ny, ny + dj)
    if c1 > c0 and b > a:
        out[start : start + (b - a), c0:c1] = got[:, c0 - dj : c1 - dj]
    return out


def roll_field(local: np.ndarray, di: int, dj: int, rows: RowPartition, comm) -> np.ndarray:
    """The distributed field of a periodic grid moved by (di, dj) cells: out[i, j] = field[(i - di) mod nx,
    (j - dj) mod ny]. ``local`` holds this rank's rows of ``rows``."""
    n = rows.n
    ranges = [rows.range(r) for r in range(comm.size)]
    parts = []
    for first in (True, False):  # the source rows of each rank, before and after they wrap past row n - 1
        wanted = []
        for a, b in ranges:
            start, cut = (a - di) % n, b - a
            split = min(cut, n - start)  # rows from start up to n, then from 0
            wanted.append((start, start + split) if first else (0, cut - split))
        parts.append(move_rows(local, ranges, wanted, comm))
    return np.roll(np.concatenate(parts), dj, axis=1)


def rows_to_columns(a: np.ndarray, rows: RowPartition, cols: RowPartition, comm) -> np.ndarray:
    """Local rows (all columns) -> all rows of the local columns (an all-to-all transpose). Each rank's
    block of columns travels straight from ``a`` (an MPI vector type picks it out) into the result."""
    if comm.size == 1:
        return a
    a = np.ascontiguousarray(a)
    my_cols = cols.counts[comm.rank]
    out = np.empty((rows.n, my_cols), dtype=a.dtype)
    comm.Alltoallw([a, (np.ones(comm.size, int), cols.starts[:-1] * a.itemsize),
                     _column_blocks(a.dtype, a.shape[0], cols)],
                    [out, (rows.counts * my_cols, rows.starts[:-1] * my_cols * a.itemsize),
                     [from_numpy_dtype(a.dtype)] * comm.size])
    return out


def columns_to_rows(a: np.ndarray, rows: RowPartition, cols: RowPartition, comm) -> np.ndarray:
    """All rows of the local columns -> local rows (all columns): the inverse of :func:`rows_to_columns`.
    ``a`` may be a view of the first columns of wider rows (:func:`padded_columns`): each rank's rows leave
    from there and arrive straight in their columns of the result (MPI vector types pick and place them)."""
    if comm.size == 1:
        return a
    if a.strides[1] != a.itemsize or a.strides[0] % a.itemsize:
        a = np.ascontiguousarray(a)
    lead = a.strides[0] // a.itemsize  # values from one row's start to the next's
    my_rows, width = rows.counts[comm.rank], a.shape[1]
    # the rows' memory, from the first value to the last (the padding between rows included, never sent)
    flat = np.lib.stride_tricks.as_strided(a, shape=(max(0, (a.shape[0] - 1) * lead + width),),
                                           strides=(a.itemsize,), writeable=False)
    out = np.empty((my_rows, cols.n), dtype=a.dtype)
    comm.Alltoallw([flat, (np.ones(comm.size, int), rows.starts[:-1] * lead * a.itemsize),
                    _blocks(a.dtype, rows.counts, width, lead)],
                   [out, (np.ones(comm.size, int), cols.starts[:-1] * a.itemsize),
                    _column_blocks(a.dtype, my_rows, cols)])
    return out


def padded_columns(n_rows: int, width: int, dtype=complex, buffer: np.ndarray | None = None) -> np.ndarray:
    """An (n_rows, width) array whose rows are ALIASED values apart rounded off by one where ``width`` is a
    multiple of ALIASED (a view of wider rows): transforms along axis 0 then run 1.4-1.6x faster than
    on rows 4 KiB apart, which map onto the same cache sets (measured: scipy.fft.fft along axis 0 of
    2079 x 512 complex values, 27 us per column against 18). In ``buffer`` (1-D, of ``dtype``) if given."""
    lead = width + 1 if width % ALIASED == 0 else width
    whole = np.empty(n_rows * lead, dtype=dtype) if buffer is None else buffer[: n_rows * lead]
    return whole.reshape(n_rows, lead)[:, :width]


ALIASED = 256
"""Row lengths (complex values: 4 KiB) at which :func:`padded_columns` pads its rows."""


KEPT_BLOCK_TYPES = 32
"""Block types (:func:`_column_blocks`) kept for reuse, the most recently used: making and committing them
for every transpose costs ~15 us, 4-10 % of a small window's application on 2 ranks."""

_block_types: dict[tuple, list] = {}


def _column_blocks(dtype: np.dtype, n_rows: int, cols: RowPartition) -> list:
    """For each rank r, the (committed) MPI type of an n_rows x cols.counts[r] block of a row-major array
    with cols.n columns (:func:`_blocks`)."""
    return _blocks(dtype, np.full(cols.size, n_rows), cols.counts, cols.n)


def _blocks(dtype: np.dtype, n_rows, widths, lead: int) -> list:
    """For each rank r, the (committed) MPI type of an n_rows[r] x widths[r] block of a row-major array whose
    rows are ``lead`` values apart (scalars for every rank alike); kept for the next transpose of the same
    shape (the least recently used freed)."""
    n_rows, widths = np.broadcast_arrays(np.asarray(n_rows), np.asarray(widths))
    key = (np.dtype(dtype).str, tuple(n_rows.ravel()), tuple(widths.ravel()), lead)
    types = _block_types.pop(key, None)
    if types is None:
        base = from_numpy_dtype(dtype)
        types = [base.Create_vector(int(n), int(w), lead).Commit() for n, w in zip(n_rows, widths)]
    _block_types[key] = types  # the newest last
    while len(_block_types) > KEPT_BLOCK_TYPES:
        for block in _block_types.pop(next(iter(_block_types))):
            block.Free()
    return types


def gather_field(local: np.ndarray, nx: int, comm) -> np.ndarray | None:
    """The whole (nx, ny) field on rank 0 (None elsewhere), from each rank's rows. For output only."""
    counts = comm.gather(local.size, root=0)
    if comm.rank != 0:
        comm.Gatherv(np.ascontiguousarray(local), None, root=0)
        return None
    whole = np.empty(sum(counts))
    comm.Gatherv(np.ascontiguousarray(local), [whole, counts], root=0)
    return whole.reshape(nx, -1)
