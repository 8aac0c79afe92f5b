"""HDF5 files holding fields split by rows over MPI ranks, written and read without gathering a field.

Writing: rank 0 alone opens the file, through a :class:`petroll.io.journal.Session` (a failed disk write
never reaches HDF5, and an existing file is changed only by a journaled commit), and the other ranks'
rows reach it in blocks of at most ``BLOCK_BYTES``, so that no rank ever holds a whole field. Every
failure is rank 0's, found in Python, and told to every rank when the file is closed: no rank can be left
waiting inside a collective HDF5 call.

Reading: with parallel HDF5 (h5py built with MPI, as Debian's h5py is under ``mpirun``) every rank opens
the file (driver "mpio") and reads its own rows independently; without it (e.g. PyPI's serial h5py) rank
0 reads and sends the rows in blocks. Which path is :func:`parallel_hdf5`; :func:`notice` says it once
when the rank-0 path is taken under MPI.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import contextlib
import errno
import hashlib
import os
import pathlib
import sys

import h5py
import numpy as np

from petroll.errors import PetrollError, reason
from petroll.io.journal import Session, atomic_write

if TYPE_CHECKING:
    from mpi4py import MPI

BLOCK_BYTES = 1 << 22
"""Largest message of the rank-0 path (4 MiB), and the target size of a field chunk in the file."""

_noticed = []


def string_list(f: h5py.File, name: str) -> tuple[str, ...]:
    """The attribute ``name`` of an open file as a tuple of strings (() if absent): e.g. a results file's
    ``warnings``, one line each."""
    return tuple(str(v.decode() if isinstance(v, bytes) else v) for v in f.attrs.get(name, ()))


def add_strings(f: h5py.File, name: str, lines) -> None:
    """Append ``lines`` not already there, in order, to the string-list attribute ``name`` of ``f``."""
    held = list(string_list(f, name))
    new = [line for line in lines if line not in held]
    if new:
        f.attrs[name] = np.array(held + new, dtype=h5py.string_dtype())


@contextlib.contextmanager
def reading_as(path, what: str):
    """Within the block ``path``, an HDF5 file, is read as ``what`` (e.g. "petroll results file"): any
    exception but a PetrollError is raised as one, "PATH: not a readable WHAT (reason)". h5py reports a
    damaged file as OSError, KeyError, RuntimeError, ValueError, TypeError, ..., and a damaged file's values
    and names can be of any type: each is the file's problem, told in one line."""
    try:
        yield
    except PetrollError:
        raise
    except Exception as exc:  # noqa: BLE001 - see above
        raise PetrollError(f"{path}: not a readable {what} ({reason(exc)})") from None


def overgrown(f: h5py.File, written: dict[str, int]) -> str | None:
    """Which dataset growing along its first axis (maxshape None there) in a group of ``written`` has more
    rows than that group's count written, or other axes than its maximum's (a damaged extent: HDF5 walks
    every chunk of a cut, e.g. 10^12 rows cut back to 10, a hang); None if none."""
    for group, rows in written.items():
        for name, d in f[group].items() if group in f else ():
            if d.maxshape[0] is None and d.shape[0] > rows:
                return f"{group}/{name} holds {d.shape[0]} rows, more than the {rows} written"
            if d.maxshape[0] is None and d.shape[1:] != d.maxshape[1:]:
                return f"{group}/{name} has shape {d.shape}, not (n, {', '.join(map(str, d.maxshape[1:]))})"
    return None


def parallel_hdf5(comm: MPI.Comm) -> bool:
    """True when several ranks can open one HDF5 file together (h5py has MPI and comm has > 1 rank)."""
    return comm.size > 1 and bool(h5py.get_config().mpi)


def notice(comm: MPI.Comm) -> None:
    """One line on rank 0's stderr, once per process, when several ranks write through rank 0."""
    if comm.size > 1 and not parallel_hdf5(comm) and not _noticed:
        _noticed.append(True)
        if comm.rank == 0:
            print("petroll: notice: h5py has no MPI support; HDF5 files are read through rank 0",
                  file=sys.stderr)


def chunk_rows(ny: int, itemsize: int = 8) -> int:
    """Rows of a (1, rows, ny) field chunk of about BLOCK_BYTES."""
    return max(1, BLOCK_BYTES // max(1, ny * itemsize))


class RowFile:
    """An HDF5 file opened by every rank of ``comm`` (``parallel``: reading with parallel HDF5) or by rank
    0 only (``file`` None elsewhere). ``put``/``get`` move one rank's contiguous rows of a dataset; every
    rank calls them in the same order with its own rows.

    ``mode`` "r" reads (``parallel`` None: :func:`parallel_hdf5` decides); "w" writes a new file and "r+"
    continues one, both on rank 0 through a journaled :class:`petroll.io.journal.Session`. :meth:`close`
    (collective) then commits: it raises the OSError that stopped the writing on every rank, the file being
    as it was before it was opened ("r+") or empty ("w"). ``sealed`` ("w"): the file starts with an HDF5
    user block of SEAL_BYTES for :func:`seal`.
    """

    def __init__(self, path, mode: str, comm: MPI.Comm, parallel: bool | None = None, sealed: bool = False):
        self.comm = comm
        self.writing = writing = mode != "r"
        self.parallel = not writing and (parallel_hdf5(comm) if parallel is None else parallel)
        self.session, self.file = None, None
        notice(comm)
        if self.parallel:
            self.file = h5py.File(path, mode, driver="mpio", comm=comm)
            return
        failure = None
        if comm.rank == 0:
            try:
                if writing:
                    self.session = Session(path, fresh=mode == "w")
                    block = {"userblock_size": SEAL_BYTES} if sealed else {}  # room for seal()
                    self.file = self.session.h5(mode, rdcc_nbytes=4 * BLOCK_BYTES, **block)
                else:
                    self.file = h5py.File(path, mode, rdcc_nbytes=4 * BLOCK_BYTES)
            except Exception as exc:  # noqa: BLE001 - h5py's errors are OSError, RuntimeError, ...: told to all
                if self.session is not None:
                    self.session.abandon()
                failure = (getattr(exc, "errno", None) or errno.EIO, reason(exc))
        failure = comm.bcast(failure, root=0) if comm.size > 1 else failure
        if failure is not None:
            raise OSError(*failure)

    @property
    def writer(self) -> bool:
        """This rank writes the small datasets and is the one that must create and set them."""
        return self.parallel or self.comm.rank == 0

    @property
    def failure(self) -> OSError | None:
        """The disk write that failed so far (rank 0 of a writing file; None elsewhere)."""
        return self.session.error if self.session is not None else None

    def close(self, commit: bool = True) -> None:
        """Close the file; a written one is committed (or, ``commit`` False, abandoned). Collective for a
        written file: an OSError raised on every rank if the writing failed."""
        session, self.session = self.session, None
        failure = None
        if self.file is not None:
            try:
                self.file.close()
            finally:
                self.file = None
        if session is not None:
            try:
                session.commit() if commit else session.abandon()
            except OSError as exc:
                failure = (exc.errno or errno.EIO, reason(exc))
        if self.writing:
            failure = self.comm.bcast(failure, root=0)
        if failure is not None:
            raise OSError(*failure)

    def __enter__(self):
        return self

    def __exit__(self, kind, *exc) -> None:
        self.close(commit=kind is None)

    # -- rows of a dataset ------------------------------------------------------------------------------
    def put(self, name: str, index: tuple, start: int, local: np.ndarray) -> None:
        """dataset[index + (start:start + len(local),)] = local, each rank its own rows. Collective."""
        local = np.ascontiguousarray(local)
        for s, rows in self._blocks(start, local):
            if self.comm.rank == 0 and self.failure is None:  # after a failure: receive, write no more
                self.file[name][index + (slice(s, s + len(rows)),)] = rows

    def put_rows(self, name: str, r0: int, r1: int, per_row: int, make) -> None:
        """Rows r0:r1 of this rank (each ``per_row`` dataset rows, from r0 * per_row on) written a block of
        chunk_rows(per_row) at a time, ``make(a, b)`` giving rows a:b: the whole is never in memory.
        Collective (every rank writes as many blocks, some empty)."""
        rows = chunk_rows(per_row)
        for a in range(r0, r0 + self.comm.allreduce(-(-(r1 - r0) // rows), op=max) * rows, rows):
            a, b = min(a, r1), min(a + rows, r1)
            self.put(name, (), a * per_row, make(a, b))

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


def atomic_hdf5(path: pathlib.Path, fill) -> None:
    """Write a new HDF5 file ``path`` whole or not at all (:func:`atomic_write`): ``fill(f, failed)`` fills
    the h5py file ``f``, which writes through a journal Session (petroll.io.journal): a disk write that
    fails (a full disk) is kept from HDF5, which may otherwise crash the process ("Disable slist on flush
    dest failure", then SIGSEGV); ``failed()`` is that OSError (None so far), for ``fill`` to stop writing.
    The OSError is raised once HDF5 has closed the file; ``path`` keeps its previous contents."""
    def write(tmp: pathlib.Path) -> None:
        session = Session(tmp, fresh=True)
        try:
            with session.h5("w") as f:
                fill(f, lambda: session.error)
        except BaseException:
            session.abandon()
            raise
        session.commit()

    atomic_write(path, write)


SEAL_BYTES = 512
"""The HDF5 user block of a sealed file (a checkpoint): bytes before HDF5's own, which HDF5 never reads."""

SEAL_MAGIC = b"petroll-seal 1 sha256 "

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
"""The first bytes of HDF5's superblock (at offset 0, or after a user block)."""


def seal(path: pathlib.Path) -> None:
    """Write into the user block of a complete file made with ``RowFile(..., sealed=True)`` the SHA-256 of
    everything after it, fsynced (rank 0, before the file is renamed into place): :func:`seal_broken` can
    then tell a damaged file before HDF5 parses it (HDF5 may crash on damaged metadata, not only fail)."""
    digest, size = _rest_digest(path), os.path.getsize(path)
    with open(path, "r+b") as fh:
        fh.write(SEAL_MAGIC + f"{digest} bytes {size}\n".encode())
        fh.flush()
        os.fsync(fh.fileno())


def seal_broken(path: pathlib.Path) -> str | None:
    """Why a sealed file is damaged, "truncated (...)" or "corrupted (...)" (its content no longer the
    sealed one, or its seal itself damaged: a user block that is neither a seal nor blank); None if it is
    whole or has no seal (an older file, HDF5 from its first byte, or a blank user block)."""
    with open(path, "rb") as fh:
        head = fh.read(SEAL_BYTES + len(HDF5_SIGNATURE))
    if not head.startswith(SEAL_MAGIC):
        block, rest = head[:SEAL_BYTES], head[SEAL_BYTES:]
        if rest == HDF5_SIGNATURE and block.strip(b"\0"):
            return f"corrupted (its seal, the file's first {SEAL_BYTES} bytes, is damaged)"
        return None
    digest, _, size = head[len(SEAL_MAGIC):].partition(b"\n")[0].decode("ascii", "replace").partition(" bytes ")
    actual = os.path.getsize(path)
    if size.isdigit() and actual < int(size):
        return f"truncated ({actual} of the {int(size)} bytes it was sealed with)"
    if _rest_digest(path) != digest or not size.isdigit() or actual != int(size):
        return "corrupted (its bytes do not match the checksum it was sealed with)"
    return None


def _rest_digest(path: pathlib.Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        fh.seek(SEAL_BYTES)
        while block := fh.read(BLOCK_BYTES):
            digest.update(block)
    return digest.hexdigest()
