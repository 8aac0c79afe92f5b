"""HDF5 files holding fields split by rows over MPI ranks, written and read without gathering a field.

With parallel HDF5 (h5py built with MPI, as Debian's h5py is under ``mpirun``) every rank opens the file
(driver "mpio") and writes or reads its own rows of each field collectively. Without it (e.g. PyPI's
serial h5py) rank 0 alone opens the file and moves the other ranks' rows through it in blocks of at most
``BLOCK_BYTES``, so that no rank ever holds a whole field. Which path a run takes is
:func:`parallel_hdf5`; :func:`notice` says it once when the rank-0 path is taken under MPI.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import sys

import h5py
import numpy as np

if TYPE_CHECKING:
    from mpi4py import MPI

BLOCK_BYTES = 1 << 22
"""Largest message of the rank-0 path (4 MiB), and the target size of a field chunk in the file."""

_noticed = []


def parallel_hdf5(comm: MPI.Comm) -> bool:
    """True when several ranks can open one HDF5 file together (h5py has MPI and comm has > 1 rank)."""
    return comm.size > 1 and bool(h5py.get_config().mpi)


def notice(comm: MPI.Comm) -> None:
    """One line on rank 0's stderr, once per process, when several ranks write through rank 0."""
    if comm.size > 1 and not parallel_hdf5(comm) and not _noticed:
        _noticed.append(True)
        if comm.rank == 0:
            print("petroll: notice: h5py has no MPI support; HDF5 files are written through rank 0",
                  file=sys.stderr)


def chunk_rows(ny: int, itemsize: int = 8) -> int:
    """Rows of a (1, rows, ny) field chunk of about BLOCK_BYTES."""
    return max(1, BLOCK_BYTES // max(1, ny * itemsize))


class RowFile:
    """An HDF5 file opened by every rank of ``comm`` (``parallel``) or by rank 0 only (``file`` None
    elsewhere). ``put``/``get`` move one rank's contiguous rows of a dataset; every rank calls them in the
    same order with its own rows. ``parallel`` None: :func:`parallel_hdf5` decides."""

    def __init__(self, path, mode: str, comm: MPI.Comm, parallel: bool | None = None):
        self.comm = comm
        self.parallel = parallel_hdf5(comm) if parallel is None else parallel
        notice(comm)
        if self.parallel:
            self.file = h5py.File(path, mode, driver="mpio", comm=comm)
        elif comm.rank == 0:
            self.file = h5py.File(path, mode, rdcc_nbytes=4 * BLOCK_BYTES)
        else:
            self.file = None

    @property
    def writer(self) -> bool:
        """This rank writes the small datasets and is the one that must create and set them (collectively
        under parallel HDF5: every rank then creates and sets them alike)."""
        return self.parallel or self.comm.rank == 0

    def close(self) -> None:
        if self.file is not None:
            self.file.close()
            self.file = None

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- rows of a dataset ------------------------------------------------------------------------------
    def put(self, name: str, index: tuple, start: int, local: np.ndarray) -> None:
        """dataset[index + (start:start + len(local),)] = local, each rank its own rows. Collective."""
        local = np.ascontiguousarray(local)
        if self.parallel:
            self._transfer(name, index, start, local, write=True)
            return
        for s, rows in self._blocks(start, local):
            if self.comm.rank == 0:
                self.file[name][index + (slice(s, s + len(rows)),)] = rows

    def get(self, name: str, index: tuple, start: int, count: int, dtype=np.float64) -> np.ndarray:
        """dataset[index + (start:start + count,)] on each rank (its own rows). Collective."""
        shape = None
        if self.file is not None:
            shape = (count, *self.file[name].shape[len(index) + 1:])
        if not self.parallel:
            shape = self.comm.bcast(shape, root=0)
            shape = (count, *shape[1:])
        out = np.empty(shape, dtype=dtype)
        if self.parallel:  # independent reads: a rank failing to read (a damaged chunk) blocks no other
            if count:
                self.file[name].read_direct(out, np.s_[index + (slice(start, start + count),)])
            return out
        comm = self.comm
        for r in range(comm.size):
            a, n = comm.bcast((start, count) if comm.rank == r else None, root=r)
            step = max(1, BLOCK_BYTES // max(1, out[:1].nbytes))
            for s in range(a, a + n, step):
                m = min(step, a + n - s)
                if comm.rank == 0:
                    block = np.ascontiguousarray(self.file[name][index + (slice(s, s + m),)], dtype=dtype)
                    if r == 0:
                        out[s - a : s - a + m] = block
                    else:
                        comm.Send(block, dest=r, tag=7)
                elif comm.rank == r:
                    comm.Recv(out[s - a : s - a + m], source=0, tag=7)
        return out

    def _blocks(self, start: int, local: np.ndarray):
        """(first row, rows) blocks of every rank's ``local``, on rank 0 (the others send theirs)."""
        comm = self.comm
        for r in range(comm.size):
            a, shape, dtype = comm.bcast((start, local.shape, local.dtype) if comm.rank == r else None, root=r)
            row_bytes = int(np.prod(shape[1:], dtype=np.int64)) * np.dtype(dtype).itemsize
            step = max(1, BLOCK_BYTES // max(1, row_bytes))
            for s in range(0, shape[0], step):
                m = min(step, shape[0] - s)
                if r == 0:
                    if comm.rank == 0:
                        yield a + s, local[s : s + m]
                elif comm.rank == r:
                    comm.Send(local[s : s + m], dest=0, tag=8)
                elif comm.rank == 0:
                    block = np.empty((m, *shape[1:]), dtype=dtype)
                    comm.Recv(block, source=r, tag=8)
                    yield a + s, block

    def _transfer(self, name: str, index: tuple, start: int, buf: np.ndarray, write: bool) -> None:
        """Collective write (or read) of this rank's hyperslab (h5py's high-level calls skip empty
        selections, which would leave the other ranks waiting: the low-level call is made on every rank)."""
        from h5py import h5fd, h5p, h5s

        dset = self.file[name]
        fspace = dset.id.get_space()
        rank_shape = dset.shape
        offset = tuple(int(i) for i in index) + (start,) + (0,) * (len(rank_shape) - len(index) - 1)
        count = (1,) * len(index) + buf.shape
        mspace = h5s.create_simple(tuple(max(1, n) for n in buf.shape))
        if buf.size:
            fspace.select_hyperslab(offset, count)
        else:
            fspace.select_none()
            mspace.select_none()
        dxpl = h5p.create(h5p.DATASET_XFER)
        dxpl.set_dxpl_mpio(h5fd.MPIO_COLLECTIVE)
        data = buf if buf.size else np.zeros(tuple(max(1, n) for n in buf.shape), dtype=buf.dtype)
        if write:
            dset.id.write(mspace, fspace, data, dxpl=dxpl)
        else:
            dset.id.read(mspace, fspace, data, dxpl=dxpl)
