"""The influence operator: surface displacement at cell centres from uniform pressure on rectangular cells.

For unit surface compliance (J = 1) the displacement at the centre of cell i from unit pressure on cell j is
Love's (1929) rectangle formula A_ij (formulation §2); A has units of length, so w = J A p with J in 1/Pa and
p in Pa gives w in m, positive into the half-space. A is block-Toeplitz, so A p is a linear (not periodic)
convolution, applied with zero-padded FFTs (DC-FFT) on a grid whose rows are split over MPI ranks:

    rows:    real FFT along Y (zero-padded to ly >= 2 ny - 1) on the local rows
    -> all-to-all transpose: every rank gets all rows of a slab of Y-frequencies
    -> FFT along X (zero-padded to lx >= 2 nx - 1), multiply by the kernel spectrum, inverse FFT along X
    -> transpose back, inverse real FFT along Y, keep the first nx x ny values.

The coefficients are a kernel's of petroll/solver/kernels (Love's rectangles, a line-contact grid's
plane-strain strips, whose Y transforms are then of length 1, or a layer's).

The transforms are scipy.fft's (pocketfft: real transforms along Y, about 2.5x numpy's at these sizes),
on ``workers`` threads (a rank's spare cores, :func:`spare_cores`); the padded lengths are
``scipy.fft.next_fast_len`` (fast FFT sizes). Only the nx x (ly/2 + 1) non-zero part
travels in each transpose (the X padding is added after it), so the communication is half that of a
distributed FFT of the padded array (e.g. mpi4py-fft), and no rank ever holds the whole field.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
import scipy.fft
from mpi4py import MPI

from petroll.model.grid import Grid
from petroll.model.materials import Layer
from petroll.solver.fft_work import fft_cost, tally
from petroll.solver.kernels import Kernel, grid_kernel
from petroll.solver import partition
from petroll.solver.partition import RowPartition, columns_to_rows, padded_columns, rows_to_columns


def dense_influence(coefficients: np.ndarray) -> np.ndarray:
    """The assembled (nx ny) x (nx ny) influence matrix of a whole grid: a small-grid reference."""
    nx, ny = coefficients.shape
    ix, iy = np.divmod(np.arange(nx * ny), ny)
    return coefficients[np.abs(ix[:, None] - ix[None, :]), np.abs(iy[:, None] - iy[None, :])]


class Convolution:
    """y = A x on an (nx, ny) grid whose rows are split over ``comm`` by :class:`RowPartition`.

    ``coefficients`` is a coefficient table (Love's, or the strip kernel's) at least nx x ny (a larger one
    is cut), or a function giving its rows ``coefficients(ix)`` = A(ix, 0:ny) for an array of row offsets
    ix (so that a rank computes only the rows its part of the kernel needs); x and y are the local rows,
    shape (local rows, ny). One instance per grid shape: the kernel spectrum is computed once.

    ``inverse=True`` gives instead y = C^-1 x, C the circulant (periodic, Strang) approximation of A on the
    nx x ny torus: the kernel wrapped without padding. For Love's coefficients its spectrum is positive in
    every case checked (400 random shapes with dx/dy from 1e-3 to 1e3, all windows up to 8 x 8 and 8 x 256:
    smallest eigenvalue >= 0.08 A_00; this is measured, not proven for a truncated wrap); it is floored at
    1e-12 of its largest value, so C^-1 is symmetric positive definite. ``torus`` = (lx, ly) >= (nx, ny)
    (with ``inverse``): C is instead the circulant of the kernel wrapped on an lx x ly torus, x is
    zero-padded onto it and C^-1 x cut back to the block: R C^-1 R^T, symmetric positive definite too
    (``coefficients`` must then cover the torus). C^-1 is the preconditioner of the contact QP's conjugate
    gradients (petroll.solver.petsc.CirculantInverse): it undoes A's 1/|k| smoothing, whose spread of scales
    makes plain conjugate gradients need more iterations as the grid is refined.

    ``coefficients=None`` builds no kernel: the instance then gives the padded transforms only
    (:meth:`forward`, :meth:`backward`, :meth:`kernel_spectrum`), e.g. for kernels that are not even
    (petroll/solver/stress.py).

    ``coefficients`` may also be a :class:`petroll.solver.kernels.periodic.Spectral` kernel of an nx x ny
    grid: along its Fourier axes the transforms are not padded (length n: a periodic convolution) and its
    values are the spectrum there; along the others, as above. ``diagonal`` is then the mean of the
    spectrum over all frequencies (the coefficient at offset 0), and with ``inverse`` (the whole grid:
    no torus) the spectrum is floored at its smallest positive value (a half-space's k = 0 value is 0),
    so that C^-1 is symmetric positive definite and the exact inverse on every other frequency.
    """

    THREADED = 1 << 16
    """Fewest transformed points per rank for which the FFTs run on ``workers`` threads; fewer run on one.
    Measured on 2 cores (a window's application, best of 15): one thread is faster up to 192 x 192 points
    (0.69 ms against 0.76 at 192^2, 0.23 against 0.35 at 63 x 64: each call's hand-off to the threads costs
    more than it shares), two are 1.6x faster from 256 x 256 (1.7 ms against 2.7)."""

    def __init__(self, coefficients, nx: int, ny: int, comm: MPI.Comm = MPI.COMM_SELF,
                 inverse: bool = False, workers: int = 1, torus: tuple[int, int] | None = None):
        self.nx, self.ny, self.comm = nx, ny, comm
        self.fourier = getattr(coefficients, "fourier", (False, False))
        if inverse:
            self.lx, self.ly = torus or (nx, ny)
        else:  # padded lengths: >= 2n - 1 (no wrap-around), rounded up to fast FFT sizes
            self.lx = nx if self.fourier[0] else scipy.fft.next_fast_len(2 * nx - 1)
            self.ly = ny if self.fourier[1] else scipy.fft.next_fast_len(2 * ny - 1, real=True)
        self.workers = workers if self.lx * self.ly >= self.THREADED * comm.size else 1
        self.kx, self.ky = (self.lx, self.ly) if inverse else (nx, ny)  # the kernel's offsets are below these
        self.cost = fft_cost(self.lx * self.ly, self.lx * self.ly)  # of one application (fft_work)
        self.rows = RowPartition(nx, comm.size)
        self.freqs = RowPartition(self.ly // 2 + 1, comm.size)  # Y-frequencies, split after transposing
        self.r0, self.r1 = self.rows.range(comm.rank)
        if coefficients is None:
            return
        if any(self.fourier):
            self._spectral(coefficients, inverse)
            return
        if callable(coefficients):
            rows_of = coefficients
        else:
            table = np.asarray(coefficients)[: self.kx, : self.ky]
            rows_of = table.__getitem__
        self.diagonal = float(rows_of(np.zeros(1, dtype=int))[0, 0])
        self.spectrum = self.kernel_spectrum(
            lambda ox, oy: rows_of(np.abs(np.ravel(ox)))[:, np.abs(np.ravel(oy))]).real
        if inverse:
            floor = comm.allreduce(float(self.spectrum.max(initial=0.0)), op=MPI.MAX) * 1e-12
            self.spectrum = 1.0 / np.maximum(self.spectrum, floor)

    def _spectral(self, kernel, inverse: bool) -> None:
        """The spectrum of a kernel with Fourier axes (class docstring), and its diagonal."""
        spectrum = self.kernel_spectrum(kernel.values, kernel.fourier)
        weights = np.full(self.ly // 2 + 1, 2.0)  # each rfft frequency counts for itself and its mirror
        weights[0] = 1.0
        if self.ly % 2 == 0:
            weights[-1] = 1.0
        f0, f1 = self.freqs.range(self.comm.rank)
        total = self.comm.allreduce(float((spectrum.real * weights[f0:f1]).sum()))
        self.diagonal = total / (self.lx * self.ly)
        self.spectrum = spectrum.real if kernel.even else spectrum
        if inverse:
            floor = self.comm.allreduce(float(np.min(self.spectrum, initial=np.inf,
                                                     where=self.spectrum > 0)), op=MPI.MIN)
            self.spectrum = 1.0 / np.maximum(self.spectrum, floor)

    def kernel_spectrum(self, kernel, fourier: tuple[bool, bool] = (False, False)) -> np.ndarray:
        """The lx x ly DFT of a kernel given at signed cell offsets, for this rank's Y-frequencies.

        ``kernel(ox, oy)`` returns the kernel at integer offsets (target minus source cell; broadcast
        arrays with |ox| < nx, |oy| < ny; an inverse's on a torus: every offset of the torus), or a stack
        of kernels (m, ...); they are zero beyond those offsets. The spectrum (or the stack of m spectra)
        is complex in general, real for an even kernel. ``fourier``: along those axes the kernel is
        given at DFT frequency indices instead (signed along X, 0 ... ly/2 along Y) and not transformed; a
        complex kernel (Fourier along X, real space along Y) is transformed along Y at the non-negative
        frequencies only (the operator's output is real: the others are their conjugates').
        Collective.
        """
        padded_rows = RowPartition(self.lx, self.comm.size)
        k0, k1 = padded_rows.range(self.comm.rank)
        offsets_x = _wrapped_offsets(self.lx)[k0:k1]
        offsets_y = np.arange(self.ly // 2 + 1) if fourier[1] else _wrapped_offsets(self.ly)
        rows = np.arange(k1 - k0) if fourier[0] else np.flatnonzero(np.abs(offsets_x) < self.kx)
        cols = np.arange(len(offsets_y)) if fourier[1] else np.flatnonzero(np.abs(offsets_y) < self.ky)
        inside = np.asarray(kernel(offsets_x[rows, None], offsets_y[None, cols]))
        inside = inside.astype(complex if np.iscomplexobj(inside) else float, copy=False)
        lead = inside.shape[:-2]
        stack = inside.reshape((int(np.prod(lead)), len(rows), len(cols)))
        spectra = []
        for block in stack:  # each block's transformed rows passed on alone: freed once they have travelled
            columns = rows_to_columns(self._half_rows(block, rows, cols, k1 - k0, fourier[1]), padded_rows,
                                      self.freqs, self.comm)
            spectra.append(columns if fourier[0] else
                           scipy.fft.fft(columns, axis=0, overwrite_x=True, workers=self.workers))
        return spectra[0] if not lead else np.stack(spectra).reshape(lead + spectra[0].shape)

    def _half_rows(self, block: np.ndarray, rows: np.ndarray, cols: np.ndarray, n_rows: int,
                   fourier_y: bool) -> np.ndarray:
        """This rank's n_rows padded rows of a kernel at its Y-frequencies 0 ... ly/2, from its values
        ``block`` on the rows ``rows`` and columns ``cols`` (at frequencies already if ``fourier_y``)."""
        if fourier_y:
            half = np.zeros((n_rows, self.ly // 2 + 1), dtype=block.dtype)
            half[np.ix_(rows, cols)] = block
            return half
        # the kernel's rows transformed alone: the others are zero, and so are their transforms
        values = np.zeros((len(rows), self.ly), dtype=block.dtype)
        values[:, cols] = block
        if len(rows) == n_rows:
            return _half_transform(values, self.workers)
        half = np.zeros((n_rows, self.ly // 2 + 1), dtype=complex)
        half[rows] = _half_transform(values, self.workers)
        return half

    def forward(self, x: np.ndarray, into: np.ndarray | None = None) -> np.ndarray:
        """The padded DFT of a field's local rows ``x`` (local rows, ny): this rank's Y-frequencies.
        ``into``: a complex (lx, this rank's Y-frequencies) array to transform in (overwritten, returned)."""
        columns = rows_to_columns(scipy.fft.rfft(x, n=self.ly, axis=1, workers=self.workers), self.rows,
                                  self.freqs, self.comm)  # the transform passed on alone: freed once sent
        if into is None:
            return scipy.fft.fft(columns, n=self.lx, axis=0, overwrite_x=True, workers=self.workers)
        into[: self.nx] = columns
        into[self.nx :] = 0.0
        return scipy.fft.fft(into, axis=0, overwrite_x=True, workers=self.workers)

    def backward(self, spectrum: np.ndarray, overwrite: bool = False) -> np.ndarray:
        """This rank's rows (local rows, ny) of the field whose padded DFT is ``spectrum`` (:meth:`forward`);
        ``overwrite``: ``spectrum`` may be overwritten (then, under MPI, its memory is let go before the
        last transform if the caller keeps no reference to it)."""
        half = columns_to_rows(scipy.fft.ifft(spectrum, axis=0, overwrite_x=overwrite, workers=self.workers)
                               [: self.nx], self.rows, self.freqs, self.comm)
        del spectrum
        return scipy.fft.irfft(half, n=self.ly, axis=1, workers=self.workers)[:, : self.ny]

    WORKSPACE = 1 << 21
    """Largest spectrum (complex values per rank) an application transforms in the process's kept work
    array (32 MiB at most, one for all convolutions: applications never overlap, and none returns a view
    of it); a larger one is allocated afresh each time. Arrays of that size allocated at every
    application can cost a page mapping and zeroing each time, depending on the allocator's state
    (docs/design.md)."""

    _scratch = np.empty(0, dtype=complex)  # the kept work array, grown up to WORKSPACE values

    def __call__(self, x: np.ndarray) -> np.ndarray:
        tally(self.cost)
        return self.backward(self._product(x), overwrite=True)

    def _product(self, x: np.ndarray) -> np.ndarray:
        """The padded DFT of A x (x's, times the kernel's), in the kept work array where it fits, its rows
        padded where their length would slow the transforms along X (partition.padded_columns); beyond it
        in an array of its own only where rows need padding, else in the transform's (in place unpadded)."""
        columns = int(self.freqs.counts[self.comm.rank])
        need = self.lx * (columns + 1)
        if need <= self.WORKSPACE:
            if Convolution._scratch.size < need:
                Convolution._scratch = np.empty(need, dtype=complex)
            into = padded_columns(self.lx, columns, complex, Convolution._scratch)
        else:
            into = padded_columns(self.lx, columns) if columns % partition.ALIASED == 0 else None
        spectrum = self.forward(x, into)
        spectrum *= self.spectrum
        return spectrum


def _half_transform(values: np.ndarray, workers: int) -> np.ndarray:
    """The DFT along axis 1 at its non-negative frequencies (0 ... n/2) of real or complex rows (a complex
    row's: the real part's plus i times the imaginary part's)."""
    if not np.iscomplexobj(values):
        return scipy.fft.rfft(values, axis=1, workers=workers)
    return (scipy.fft.rfft(values.real, axis=1, workers=workers)
            + 1j * scipy.fft.rfft(values.imag, axis=1, workers=workers))


def spare_cores(comm: MPI.Comm) -> int:
    """FFT threads for each rank of ``comm``: the cores this process may run on, shared among the ranks on
    its node (at least 1). Collective."""
    import os

    node = comm.Split_type(MPI.COMM_TYPE_SHARED)
    ranks = node.size
    node.Free()
    return max(1, len(os.sched_getaffinity(0)) // ranks)


def _wrapped_offsets(n: int) -> np.ndarray:
    """Cell offsets in wrap-around order of an n-point DFT: 0, 1, ..., then negative ones up to -1."""
    k = np.arange(n)
    return np.where(k <= (n - 1) // 2, k, k - n)


class InfluenceOperator:
    """Influence convolutions on windows of one grid's cells with one kernel (petroll/solver/kernels),
    their spectra built once.

    ``window(nx, ny)`` returns the :class:`Convolution` for an nx x ny block of cells; each window shape's
    kernel spectrum is computed on first use and kept (the last ``kept`` shapes). The kernel's table is
    kept for blocks up to ``TABLE_CELLS`` cells; a larger block's kernel, where the kernel computes any
    rows directly (Love's), is computed for the rows each rank needs, so that no rank holds a table of a
    whole large grid. :func:`influence_operator` picks a grid's.

    A periodic kernel (petroll.solver.kernels.periodic; ``whole`` True) is applied on its whole grid
    only (its windows are the grid: ``window(kernel.nx, kernel.ny)``), unpadded along its periodic axes,
    and has no row-sum bounds.
    """

    TABLE_CELLS = 1 << 20
    """Largest coefficient table kept (8 MiB) for a kernel that computes its rows directly."""

    def __init__(self, kernel: Kernel, comm: MPI.Comm = MPI.COMM_SELF, workers: int = 1):
        self.kernel, self.comm, self.workers = kernel, comm, workers
        self.dx, self.dy = kernel.dx, kernel.dy
        self.positive = kernel.positive  # every coefficient > 0 (a layer's are not: its surface bulges)
        self.whole = any(getattr(kernel, "fourier", (False, False)))
        # a periodic kernel without a k = 0 response: displacements are taken from their mean plane
        self.mean_free = all(getattr(kernel, "fourier", (False, False))) and float(kernel.values(0, 0)) == 0
        self._table = None if self.whole else kernel.table(1, 1)
        self._windows: dict[tuple[int, int], Convolution] = {}

    def coefficients(self, nx: int, ny: int) -> np.ndarray:
        """The kernel's table A(|di|, |dj|) for offsets below (nx, ny)."""
        return self.kernel.table(nx, ny)

    @property
    def diagonal(self) -> float:
        """A_ii, the displacement at a loaded cell's own centre per unit pressure (unit compliance)."""
        if self.whole:
            return self.window(self.kernel.nx, self.kernel.ny).diagonal
        return float(self._table[0, 0])

    kept = 12
    """Kernels kept (the most recently used; a window's forward and inverse kernels count as two): a
    transient that changes the window every step would otherwise keep a spectrum per shape."""

    def window(self, nx: int, ny: int, inverse: bool = False) -> Convolution:
        """A on an nx x ny block; ``inverse``: the inverse of its circulant approximation (a preconditioner),
        on the torus of :meth:`pc_torus`."""
        key = (nx, ny, inverse)
        conv = self._windows.pop(key, None)
        if conv is None and self.whole:
            if (nx, ny) != (self.kernel.nx, self.kernel.ny):
                raise ValueError(f"a periodic kernel applies to its whole grid ({self.kernel.nx} x "
                                 f"{self.kernel.ny} cells), not to a {nx} x {ny} block")
            conv = Convolution(self.kernel, nx, ny, self.comm, inverse, self.workers)
        elif conv is None:
            torus = self.pc_torus(nx, ny) if inverse else None
            table = self.table_rows(*(torus or (nx, ny)))
            conv = Convolution(table, nx, ny, self.comm, inverse, self.workers, torus)
        self._windows[key] = conv  # the newest last
        while len(self._windows) > self.kept:
            del self._windows[next(iter(self._windows))]
        return conv

    def pc_torus(self, nx: int, ny: int) -> tuple[int, int] | None:
        """The torus of the preconditioner's circulant for an nx x ny block: None (the block itself) unless
        the kernel's ``torus`` factor exceeds 1; then each axis longer than 1 grown by that factor and
        rounded up to a fast FFT length."""
        if self.kernel.torus <= 1:
            return None
        grown = [n if n == 1 else scipy.fft.next_fast_len(math.ceil(self.kernel.torus * n), real=real)
                 for n, real in ((nx, False), (ny, True))]
        return grown[0], grown[1]

    def row_sum_bound(self, nx: int, ny: int) -> float:
        """An upper bound of every row sum of |A| on an nx x ny block: sum_k |A_ik| <= this (unit
        compliance), i.e. the largest displacement a field of unit magnitude can cause: the sum over all
        offsets |di| < nx, |dj| < ny (the kernel's closed form where it has one, else its table's)."""
        bound = self.kernel.row_sum_bound(nx, ny)
        if bound is not None:
            return bound
        return self._offsets_sum(np.abs(self.table_rows(nx, ny)(np.arange(nx))))

    def lift_bound(self, nx: int, ny: int) -> float:
        """The sum of -A over the offsets |di| < nx, |dj| < ny where A < 0 (unit compliance): the most a
        field of unit magnitude can lift a cell's surface (0 for positive coefficients)."""
        if self.positive:
            return 0.0
        return self._offsets_sum(np.maximum(-self.table_rows(nx, ny)(np.arange(nx)), 0.0))

    @staticmethod
    def _offsets_sum(t: np.ndarray) -> float:
        """The sum over all signed offsets of a table given for offsets >= 0 (even in both)."""
        return float(4 * t.sum() - 2 * t[0, :].sum() - 2 * t[:, 0].sum() + t[0, 0])

    def table_rows(self, nx: int, ny: int) -> Callable[[np.ndarray], np.ndarray]:
        """The rows of the coefficient table of an nx x ny block: ``rows(ix)`` = A(ix, 0:ny) for row offsets
        ix (from a kept table, or for a block beyond TABLE_CELLS cells of a kernel that computes its rows
        directly, from its closed form)."""
        kernel = self.kernel
        if kernel.direct and nx * ny > self.TABLE_CELLS:
            return lambda ix: kernel.table(nx, ny, rows=ix)
        if nx > self._table.shape[0] or ny > self._table.shape[1]:
            big = (max(nx, self._table.shape[0]), max(ny, self._table.shape[1]))
            self._table = kernel.table(*big)
        table = self._table
        return lambda ix: table[ix, :ny]


def influence_operator(grid: Grid, comm: MPI.Comm = MPI.COMM_SELF, layer: Layer | None = None,
                       workers: int = 1) -> InfluenceOperator:
    """The influence operator of ``grid`` on a half-space or on ``layer`` (the kernel of
    :func:`petroll.solver.kernels.grid_kernel`), ``workers`` FFT threads per rank."""
    return InfluenceOperator(grid_kernel(grid, layer), comm, workers)
