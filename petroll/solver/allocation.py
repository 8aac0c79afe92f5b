"""Where the C heap takes big blocks while a run holds whole-grid fields: :class:`LargeBlocksMapped`.

Loading PETSc loads Debian 12's libsuperlu_dist.so.8, whose constructor calls ``mallopt(M_MMAP_MAX, 0)``
and ``mallopt(M_TRIM_THRESHOLD, -1)``: from then on glibc maps no block of its own, every array comes from
the one brk heap, which never shrinks and fragments (docs/benchmarks.md, *The allocator*). A run whose QP
covers the whole grid (``Topology.whole``: periodic grids) holds several field-sized arrays at once and
makes field-sized temporaries around them, and there the heap's holes add to the peak. While such a run
goes (petroll.driver.run), and while ``petroll run`` reads a scene (petroll.cli: its grid is unknown until
read, and a read allocates its arrays once), blocks of :data:`BLOCK` and more that no free part of the
heap holds are mapped, each returned to the system when it is freed. The price is a fresh mapping's pages,
zeroed at first touch: a threshold of 4 MiB for every run cost rolling runs 40-50 % wall time (their
steps allocate anew each time), whence whole-grid runs only and 16 MiB (docs/benchmarks.md, *Memory per
rank*).
"""

from __future__ import annotations

import ctypes
import os

M_MMAP_THRESHOLD, M_MMAP_MAX = -3, -4
"""glibc's mallopt parameters (malloc.h)."""
BLOCK = 16 << 20
"""Blocks of this many bytes and more are mapped (a field of 2^21 doubles; 2048^2 cells: 32 MiB)."""
MAPPINGS = 65536
"""glibc's own M_MMAP_MAX: the most blocks mapped at once."""


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd",
                                                     "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]


class LargeBlocksMapped:
    """A context manager: inside it glibc maps blocks of :data:`BLOCK` and more (``active`` true: a run
    whose QP covers the whole grid), and on leaving it stops mapping again if it did not before. It does
    nothing where ``reason`` (why, in words) is set: ``active`` false, a C library that is not glibc, or a
    glibc that maps big blocks already (no library turned its mapping off)."""

    def __init__(self, active: bool):
        self.libc, self.reason = None, None if active else "the run's QP is posed on windows"
        self.switched = False  # mapping was turned on here, to be turned off on leaving
        if active:
            self.libc, self.reason = _glibc()

    def __enter__(self) -> LargeBlocksMapped:
        if self.libc is not None:
            if _maps_big_blocks(self.libc):
                self.reason = "glibc maps big blocks already"
            else:
                self.libc.mallopt(M_MMAP_MAX, MAPPINGS)
                self.libc.mallopt(M_MMAP_THRESHOLD, BLOCK)
                self.switched = True
        return self

    def __exit__(self, *exc) -> None:
        if self.switched:
            self.libc.mallopt(M_MMAP_MAX, 0)
            self.switched = False


def _glibc() -> tuple[ctypes.CDLL | None, str | None]:
    """This process's C library if it is glibc 2.33 or later (mallinfo2), else None and why not."""
    try:
        version = os.confstr("CS_GNU_LIBC_VERSION")
    except (ValueError, OSError):
        version = None
    if not version:
        return None, "the C library is not glibc"
    libc = ctypes.CDLL(None)
    if not hasattr(libc, "mallinfo2"):
        return None, f"{version} has no mallinfo2 (glibc 2.33 and later)"
    libc.mallinfo2.restype = _Mallinfo2
    libc.malloc.restype, libc.malloc.argtypes = ctypes.c_void_p, [ctypes.c_size_t]
    libc.free.argtypes = [ctypes.c_void_p]
    libc.malloc_trim.argtypes = [ctypes.c_size_t]
    return libc, None


def _maps_big_blocks(libc) -> bool:
    """Whether glibc maps a block of BLOCK bytes more than the heap has free (glibc has no getter for
    M_MMAP_MAX): one such block, never touched, allocated and freed. Where it came from the heap, the heap
    grew by it: given back at once (malloc_trim)."""
    before = libc.mallinfo2().hblks
    block = libc.malloc(libc.mallinfo2().fordblks + BLOCK)
    mapped = libc.mallinfo2().hblks > before
    libc.free(block)
    if not mapped:
        libc.malloc_trim(0)
    return mapped
