"""Writing an HDF5 file so that neither a kill nor a failed write can leave it unreadable.

HDF5 has no journal of its own: an append rewrites metadata in place (the superblock, object headers,
chunk indexes, attributes), and a process killed halfway, or a write refused by a full disk, leaves those
blocks half old and half new. Here HDF5 writes through h5py's ``fileobj`` driver into a :class:`Session`:

- bytes *beyond* the file's size when the session began (``base``: new chunks, new metadata) go to disk at
  once: until the session commits, no committed metadata points at them;
- bytes *below* ``base`` (rewritten metadata, a partly filled series chunk) are kept in memory, page by
  page, and written only by :meth:`Session.commit`, after the file is closed: first the rollback journal
  ``.NAME.journal`` (the old bytes of every page about to change and the old size, with a SHA-256 over
  them; fsynced), then the new pages, an fsync of the file, and the journal is emptied;
- a disk write that fails (no space, quota, I/O error) is recorded and its bytes kept in memory, so that
  HDF5 itself never sees an error: the session then ends with :meth:`Session.abandon`, which cuts the file
  back to ``base``. Nothing below ``base`` was written, so the file is exactly as before.

At any instant the file, read through its journal when one is present (:func:`reading`), is the file as
it was after the last committed session: before the journal is in place nothing below ``base`` has
changed; while it is, it holds the old bytes of everything that may have changed. :func:`recover` puts
those bytes back in place (what a writer does before continuing a file).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import pathlib

import h5py

PAGE = 512
"""Granularity of the pages kept in memory and journaled (bytes): small, since an append rewrites a few
hundred bytes here and there (object headers, the last chunk of each series)."""

MAGIC = b"petroll-journal 1\n"


def journal_path(path: pathlib.Path) -> pathlib.Path:
    """The rollback journal of ``path`` (hidden, in the same directory)."""
    path = pathlib.Path(path)
    return path.with_name(f".{path.name}.journal")


def sync_directory(directory: pathlib.Path) -> None:
    """fsync a directory, so that a rename in it survives a crash of the machine (where the OS allows it)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_all(fd: int, data, at: int) -> None:
    """os.pwrite until every byte is written (a short write is retried; the error that ends it raised)."""
    data = memoryview(data).cast("B")
    while len(data):
        n = os.pwrite(fd, data, at)
        data, at = data[n:], at + n


class _Seekable:
    """The position and size part of a file-like object for h5py's ``fileobj`` driver."""

    pos = size = 0

    def seek(self, offset: int, whence: int = 0) -> int:
        self.pos = offset if whence == 0 else self.pos + offset if whence == 1 else self.size + offset
        return self.pos

    def tell(self) -> int:
        return self.pos

    def flush(self) -> None:
        pass


class Session(_Seekable):
    """One writing session of an HDF5 file, as the file-like object of h5py's ``fileobj`` driver.

    ``fresh``: a new (empty) file at ``path``; else the existing file, continued. Use :meth:`h5` to open it
    with h5py, close that, then :meth:`commit` (which raises the OSError that stopped it, if any) or
    :meth:`abandon`. ``error`` is the first failed disk write (None while all went to disk).
    """

    def __init__(self, path: str | pathlib.Path, fresh: bool):
        self.path = pathlib.Path(path)
        if not fresh:
            recover(self.path)  # a commit cut short: back to the last committed state first
        self.fd = os.open(self.path, os.O_RDWR | (os.O_CREAT | os.O_TRUNC if fresh else 0), 0o644)
        self.base = os.fstat(self.fd).st_size  # bytes below it are committed: never written before commit
        self.size = self.base  # the size HDF5 sees
        self.floor: int | None = None  # disk bytes at and beyond it are no longer the file's (a cut)
        self.pages: dict[int, bytearray] = {}  # page index -> its bytes, where memory holds the truth
        self.pos = 0
        self.error: OSError | None = None
        self.memory_only = False  # after a failure or a cut below base: every write stays in memory

    def h5(self, mode: str, **kwargs) -> h5py.File:
        """The file opened by h5py through this session (``mode`` "w" for a fresh one, else "r+")."""
        return h5py.File(self, mode, **kwargs)

    # -- the file-like interface h5py's driver uses (and seek, tell, flush) ----------------------------
    def read(self, size: int = -1) -> bytes:
        start = self.pos
        end = self.size if size < 0 else start + size
        out = bytearray(max(0, end - start))  # zeros beyond the file's end
        at, stop_all = start, min(end, self.size)
        while at < stop_all:  # runs of pages from memory, or from disk in one read
            page = at // PAGE
            stop = min(stop_all, (page + 1) * PAGE)
            if page in self.pages:
                out[at - start : stop - start] = self.pages[page][at - page * PAGE : stop - page * PAGE]
            else:
                while stop < stop_all and stop // PAGE not in self.pages:
                    stop = min(stop_all, (stop // PAGE + 1) * PAGE)
                data = self._disk(at, stop)
                out[at - start : at - start + len(data)] = data
            at = stop
        self.pos = end
        return bytes(out)

    def write(self, data) -> int:
        data = memoryview(data).cast("B")
        start, end = self.pos, self.pos + len(data)
        at = start
        while at < end:  # runs of pages: to disk (new bytes beyond the committed file) or to memory
            direct = self._direct(at)
            stop = min(end, (at // PAGE + 1) * PAGE)
            while stop < end and self._direct(stop) == direct:
                stop = min(end, (stop // PAGE + 1) * PAGE)
            if direct and not self._to_disk(data[at - start : stop - start], at):
                continue  # it failed: from now on, memory (the same bytes again)
            if not direct:
                self._to_memory(data[at - start : stop - start], at)
            at = stop
        self.pos = end
        self.size = max(self.size, end)
        return len(data)

    def _direct(self, at: int) -> bool:
        """Bytes written at ``at`` go to disk now (new bytes beyond the committed file, no page kept)."""
        return at >= self.base and not self.memory_only and at // PAGE not in self.pages

    def _to_disk(self, data: memoryview, at: int) -> bool:
        try:
            write_all(self.fd, data, at)
            return True
        except OSError as exc:
            self.error = self.error or exc
            self.memory_only = True
            return False

    def _to_memory(self, data: memoryview, at: int) -> None:
        end = at + len(data)
        for page in range(at // PAGE, (end - 1) // PAGE + 1):
            a, b = max(at, page * PAGE), min(end, (page + 1) * PAGE)
            buffer = self.pages.get(page)
            if buffer is None:
                buffer = self.pages[page] = bytearray(self._page_bytes(page))
            buffer[a - page * PAGE : b - page * PAGE] = data[a - at : b - at]

    def truncate(self, size: int | None = None) -> int:
        size = self.pos if size is None else size
        for page in [p for p in self.pages if p * PAGE >= size]:
            del self.pages[page]
        if size % PAGE and size // PAGE in self.pages:
            buffer = self.pages[size // PAGE]
            buffer[size % PAGE :] = bytes(PAGE - size % PAGE)
        if size < self.size:
            if size >= self.base and not self.memory_only:
                self._cut_disk(size)
            else:  # below the committed size: cut at commit; until then the disk bytes beyond are void
                self.floor = size if self.floor is None else min(self.floor, size)
                self.memory_only = True
        self.size = size
        return size

    # -- ending the session ---------------------------------------------------------------------------
    def commit(self) -> None:
        """Make the session's writes the file's content (after h5py closed it): journal, pages, fsync,
        journal removed. Raises the OSError that stopped the session or the commit; the file is then as
        it was before the session (:meth:`abandon` has run)."""
        if self.error is not None:
            self.abandon()
            raise self.error
        journal = journal_path(self.path)
        try:
            changed = self._old_ranges()
            if changed:
                _write_journal(journal, self.path, self.fd, self.base, changed)
        except OSError:
            self.abandon()
            raise
        try:
            for a, data in self._runs():
                write_all(self.fd, data, a)
            if os.fstat(self.fd).st_size != self.size:
                os.ftruncate(self.fd, self.size)
            os.fsync(self.fd)
        except OSError:
            if changed:
                _roll_back(self.path, self.fd, journal)
            self.abandon()
            raise
        if changed:
            _clear_journal(journal)
        self._close()

    def abandon(self) -> None:
        """End the session without committing: the file is cut back to its committed size (releasing the
        space of the bytes written beyond it); nothing below it was written."""
        if self.fd < 0:
            return
        with contextlib.suppress(OSError):
            if os.fstat(self.fd).st_size > self.base:
                os.ftruncate(self.fd, self.base)
        self._close()

    # -- helpers --------------------------------------------------------------------------------------
    def _close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1
        self.pages = {}

    def _page_bytes(self, page: int) -> bytes:
        """A page as HDF5 sees it: memory where kept, else disk."""
        buffer = self.pages.get(page)
        if buffer is not None:
            return buffer
        data = self._disk(page * PAGE, min(self.size, (page + 1) * PAGE))
        return data + bytes(PAGE - len(data))

    def _disk(self, start: int, end: int) -> bytes:
        """The file's bytes in [start, end) as on disk, but for what a cut made void (read as zeros)."""
        if self.floor is not None:
            end = min(end, self.floor)
        return os.pread(self.fd, end - start, start) if end > start else b""

    def _runs(self):
        """(offset, bytes) of the pages kept in memory, adjacent ones joined, cut at the file's size."""
        run_start, parts = None, []
        for page in sorted(self.pages):
            if run_start is not None and page * PAGE != run_start + PAGE * len(parts):
                yield run_start, b"".join(parts)[: max(0, self.size - run_start)]
                run_start, parts = None, []
            if run_start is None:
                run_start = page * PAGE
            parts.append(self.pages[page])
        if run_start is not None:
            yield run_start, b"".join(parts)[: max(0, self.size - run_start)]

    def _old_ranges(self) -> list[tuple[int, int]]:
        """The (offset, length) ranges below ``base`` that commit will change (pages or a cut)."""
        ranges = []
        for page in sorted(self.pages):
            a = page * PAGE
            if a < self.base:
                ranges.append((a, min(PAGE, self.base - a)))
        if self.size < self.base:
            ranges.append((self.size, self.base - self.size))
        merged: list[list[int]] = []
        for a, n in sorted(ranges):
            if merged and a <= merged[-1][0] + merged[-1][1]:
                merged[-1][1] = max(merged[-1][1], a + n - merged[-1][0])
            else:
                merged.append([a, n])
        return [(a, n) for a, n in merged]

    def _cut_disk(self, size: int) -> None:
        try:
            os.ftruncate(self.fd, size)
        except OSError as exc:
            self.error = self.error or exc
            self.memory_only = True


def _write_journal(journal: pathlib.Path, path: pathlib.Path, fd: int, base: int,
                   ranges: list[tuple[int, int]]) -> None:
    """The rollback journal of ``path`` (open as ``fd``): its old bytes in ``ranges`` and its old size,
    with a SHA-256 over all of it (a journal cut short is no journal), fsynced. The journal file is kept
    between sessions (emptied, not removed: no directory update, hence no directory fsync, per commit)."""
    info = os.fstat(fd)
    header = json.dumps({"file": path.name, "device": info.st_dev, "inode": info.st_ino, "base": base,
                         "ranges": ranges}).encode()
    parts = [MAGIC + header + b"\n"]
    for a, n in ranges:
        old = os.pread(fd, n, a)
        parts.append(old + bytes(n - len(old)))
    body = b"".join(parts)
    new = not journal.exists()
    out = os.open(journal, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        os.ftruncate(out, 0)
        write_all(out, body + hashlib.sha256(body).digest(), 0)
        os.fsync(out)
    except OSError:
        with contextlib.suppress(OSError):
            os.ftruncate(out, 0)  # no part-written journal left taking space
        raise
    finally:
        os.close(out)
    if new:
        sync_directory(journal.parent)


def _clear_journal(journal: pathlib.Path) -> None:
    """Empty the journal: the session it guarded is over (no fsync: if the emptying is lost in a crash,
    the file rolls back to its previous committed state, which is whole too)."""
    with contextlib.suppress(OSError):
        os.truncate(journal, 0)


def read_journal(path: pathlib.Path) -> tuple[int, list[tuple[int, bytes]]] | None:
    """The committed size and old bytes [(offset, bytes)] of ``path`` from its journal, if one is present,
    whole, and made for this very file (same device and inode); else None."""
    journal = journal_path(path)
    try:
        data = journal.read_bytes()
        info = os.stat(path)
    except OSError:
        return None
    if not data.startswith(MAGIC) or len(data) < len(MAGIC) + 33:
        return None
    body, digest = data[:-32], data[-32:]
    if hashlib.sha256(body).digest() != digest:
        return None
    end = body.index(b"\n", len(MAGIC))
    try:
        header = json.loads(body[len(MAGIC) : end])
    except ValueError:
        return None
    if (header.get("file"), header.get("device"), header.get("inode")) != (path.name, info.st_dev,
                                                                           info.st_ino):
        return None
    chunks, at = [], end + 1
    for a, n in header["ranges"]:
        chunks.append((int(a), body[at : at + n]))
        at += n
    return int(header["base"]), chunks


def _roll_back(path: pathlib.Path, fd: int, journal: pathlib.Path) -> None:
    """Put the journal's old bytes back into ``path`` (open as ``fd``) and its old size; remove the journal
    once that is on disk (left in place if it cannot be: readers still go through it)."""
    found = read_journal(path)
    if found is None:
        return
    base, chunks = found
    for a, old in chunks:
        write_all(fd, old, a)
    os.ftruncate(fd, base)
    os.fsync(fd)
    _clear_journal(journal)


def recover(path: str | pathlib.Path) -> bool:
    """Bring ``path`` back to its last committed state if a session was cut short while committing (its
    journal is present): True if it did. A journal left by another file (a replaced one) is removed.
    For a writer that is about to continue the file; readers use :func:`reading`. Raises OSError."""
    path = pathlib.Path(path)
    journal = journal_path(path)
    if not journal.exists():
        return False
    if read_journal(path) is None:  # empty (no session under way), cut short, or another file's
        if journal.stat().st_size:
            _clear_journal(journal)
        return False
    fd = os.open(path, os.O_RDWR)
    try:
        _roll_back(path, fd, journal)
    finally:
        os.close(fd)
    return True


def copy_committed(source: str | pathlib.Path, target: str | pathlib.Path) -> None:
    """Copy ``source`` as last committed (through its journal, if a commit was cut short) to ``target``,
    fsynced; ``source`` itself is not changed."""
    import shutil

    source, target = pathlib.Path(source), pathlib.Path(target)
    found = read_journal(source) if journal_path(source).exists() else None
    shutil.copyfile(source, target)
    fd = os.open(target, os.O_RDWR)
    try:
        if found is not None:
            base, chunks = found
            for a, old in chunks:
                write_all(fd, old, a)
            os.ftruncate(fd, base)
        os.fsync(fd)
    finally:
        os.close(fd)


class _Recovered(_Seekable):
    """A committed file seen through its journal (read-only file-like object for h5py)."""

    def __init__(self, path: pathlib.Path, base: int, chunks: list[tuple[int, bytes]]):
        self.fd = os.open(path, os.O_RDONLY)
        self.size, self.chunks, self.pos = base, chunks, 0

    def read(self, size: int = -1) -> bytes:
        start = self.pos
        end = min(self.size, self.size if size < 0 else start + size)
        out = bytearray(os.pread(self.fd, max(0, end - start), start)) if end > start else bytearray()
        out += bytes(max(0, end - start) - len(out))
        for a, old in self.chunks:
            lo, hi = max(a, start), min(a + len(old), end)
            if lo < hi:
                out[lo - start : hi - start] = old[lo - a : hi - a]
        self.pos = start + (size if size >= 0 else len(out))
        return bytes(out) + bytes(max(0, size - len(out)) if size >= 0 else 0)

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1


@contextlib.contextmanager
def reading(path: str | pathlib.Path, **kwargs):
    """``path`` opened read-only by h5py as last committed: through its journal if a commit was cut
    short (the file itself is not changed), else as it is."""
    path = pathlib.Path(path)
    found = read_journal(path) if journal_path(path).exists() else None
    if found is None:
        with h5py.File(path, "r", **kwargs) as f:
            yield f
        return
    view = _Recovered(path, *found)
    try:
        with h5py.File(view, "r", **kwargs) as f:
            yield f
    finally:
        view.close()


def atomic_write(path: pathlib.Path, write) -> None:
    """Write ``path`` as a whole or not at all: ``write(tmp)`` fills a temporary file in the same directory,
    which is fsynced and renamed over ``path`` (the directory is fsynced too). On any failure the temporary
    file is removed and ``path`` keeps its previous contents."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        write(tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        sync_directory(path.parent)
    finally:
        if tmp.exists():
            tmp.unlink()
