"""The memory of steady rolling along the motion (petroll.solver.steady): the time integrator's pulse
response as a kernel along the motion, fields held as whole lines of cells along it, and the far wake.

A body moving at constant speed V along the direction d (+X, -X, +Y or -Y): in its frame the material
streams backwards, and a material point now at body-frame cell j was at j + V s d a time s ago (the
material arrives from ahead). The transient run's time integrator ([solver] integrator, step dt) turns a
point's pressure history into its displacement in pressure space W (w = A W, formulation §4): a linear,
time-invariant, causal filter of that history, whose response to a unit pressure pulse is h[s] (s steps
later; :func:`pulse_response`, computed by the integrator itself). In steady state the history of the point
at j is the body-frame field ahead of it, so

    W_j = sum_s h[s] p(j + s c),     c = V dt / (cell along d),

with p interpolated linearly between cell centres along d: a correlation with a per-cell kernel H
(:func:`memory_kernel`). With c = 1 (the body crosses one cell per step: [time] steps_per_cell = 1 on square
cells) there is no interpolation and this is exactly the steady state of the transient run with that step
and integrator. Smaller c refines the time integration of the same body-frame field.

**Lines.** W couples cells along the motion only, so its fields are held in lines (:class:`Lines`): each
rank holds whole lines along the motion for a slab of lines across it (motion along Y: its own grid rows;
along X: a slab of columns, moved there by an all-to-all transpose), index t = 0 the rearmost cell and t
growing towards the front. Along a line W is an upper-triangular Toeplitz matrix (W_t needs the cells
t + m, m >= 0): applied by FFT (:class:`Memory`), and inverted on a set of cells exactly, segment by
segment from the front, with the reciprocal series of H (:func:`inverse_series`): no matrix is formed.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft
from mpi4py import MPI

from petroll.solver.fft_work import fft_cost, tally
from petroll.solver.history import state_space
from petroll.solver.partition import RowPartition, columns_to_rows, move_rows, rows_to_columns


def pulse_response(material, integrator: str, dt: float, steps: int) -> np.ndarray:
    """W (1/Pa) of one material point at steps 0 ... steps - 1 after it carried a unit pressure over step
    0 only (zero before and after), as ``integrator`` computes it with steps of dt (s): h[0] = J_eff.
    The history is guarded: a step at which the integrator cannot hold a penetration is refused
    (SolverError), as in a transient run.

    The integrator is a linear state machine (petroll.solver.history.state_space): after the pulse (state
    S_1) a step at p = 0 maps the state S to M S and outputs W = c S; h[1 + j K + r] = (c M^r) (M^K)^j S_1
    for r < K ~ sqrt(steps): about 2 sqrt(steps) products of d x d matrices instead of ``steps`` integrator steps."""
    h0, after, M, c = state_space(material, integrator, dt)
    h = np.zeros(steps)
    h[0] = h0
    rest = steps - 1
    if rest <= 0 or M is None:
        return h
    d = len(after)
    K = math.isqrt(rest - 1) + 1
    outputs, power = np.empty((K, d)), np.eye(d)  # rows c M^r; M^r
    for r in range(K):
        outputs[r] = c @ power
        power = power @ M
    J = -(-rest // K)
    states = np.empty((d, J))  # (M^K)^j S_1
    states[:, 0] = after
    for b in range(1, J):
        states[:, b] = power @ states[:, b - 1]
    h[1:] = (outputs @ states).T.ravel()[:rest]
    return h


def memory_steps(material, integrator: str, dt: float, tol: float) -> float:
    """The steps of the pulse response (:func:`pulse_response`) that matter: those before its slowest mode
    has decayed below ``tol``, 2 + ln(tol) / ln(rho), rho the spectral radius of the integrator's state
    matrix (the slowest mode's decay per step: exp(-dt / tau) for the exponential and paper integrators,
    tau the longest creep time; a little slower for the relaxation integrator at steps beyond tau); 1 for
    a material without memory; infinite if it never decays."""
    M = state_space(material, integrator, dt)[2]
    rho = 0.0 if M is None else float(np.abs(np.linalg.eigvals(M)).max(initial=0.0))
    if rho == 0.0:
        return 1
    return 2 + math.ceil(math.log(tol) / math.log(rho)) if rho < 1.0 else math.inf


def memory_kernel(h: np.ndarray, c: float, cells: int) -> np.ndarray:
    """H[m], m = 0 ... cells - 1: W_j = sum_m H[m] p_{j+m} (module docstring) from the pulse response h
    of steps that cross c cells each (p linear between cell centres; c = 1: H = h)."""
    if c == 1:
        return np.concatenate([h, np.zeros(max(cells - len(h), 0))])[:cells]
    position = np.arange(len(h)) * c
    i = np.floor(position + 1e-12).astype(int)
    f = np.clip(position - i, 0.0, 1.0)
    inside = i < cells
    i, f, h = i[inside], f[inside], h[inside]
    return (np.bincount(i, (1 - f) * h, cells + 1) + np.bincount(i + 1, f * h, cells + 1))[:cells]


def inverse_series(h: np.ndarray, n: int) -> np.ndarray:
    """The first n coefficients of the reciprocal power series of h (h[0] != 0): g with h * g = 1, 0, 0, ...
    (so the Toeplitz matrix of g inverts that of h, either triangle), by Newton's doubling g <- g (2 - h g)
    with FFT products: O(n log n)."""
    g = np.array([1.0 / h[0]])
    while len(g) < n:
        m = min(2 * len(g), n)
        e = -_product(h[:m], g, m)
        e[0] += 2.0
        g = _product(g, e, m)
    return g[:n]


def _product(a: np.ndarray, b: np.ndarray, m: int) -> np.ndarray:
    """The first m coefficients of the product of the series a and b (FFT)."""
    length = scipy.fft.next_fast_len(len(a) + len(b) - 1, real=True)
    return scipy.fft.irfft(scipy.fft.rfft(a, length) * scipy.fft.rfft(b, length), length)[:m]


class Lines:
    """The grid's fields as whole lines along the motion (module docstring), and the extended grid's.

    Motion along ``axis`` (0: X, 1: Y) with ``sign`` +1 towards increasing index. The grid's fields are
    split by rows (``rows``, nx x ``ny`` cells over ``comm``); the extended grid adds ``behind`` cells
    behind the grid along the motion (the near wake) and is split by its own rows (``extended_rows``,
    those of its convolution). Lines: (local lines, cells along the motion), t = 0 the rearmost cell."""

    def __init__(self, rows: RowPartition, ny: int, axis: int, sign: int, behind: int, comm: MPI.Comm):
        self.rows, self.axis, self.sign, self.behind, self.comm = rows, axis, sign, behind, comm
        nx = rows.n
        self.n_along, self.n_across = (nx, ny) if axis == 0 else (ny, nx)
        self.across = RowPartition(ny, comm.size) if axis == 0 else rows  # each rank's lines
        self.a0, self.a1 = self.across.range(comm.rank)
        self.extended = (nx + behind, ny) if axis == 0 else (nx, ny + behind)
        self.extended_rows = RowPartition(self.extended[0], comm.size)

    def from_grid(self, field: np.ndarray) -> np.ndarray:
        """This rank's lines (local lines, n_along) of a grid field given by its rows."""
        return self._lines(field, self.rows)

    def to_grid(self, lines: np.ndarray) -> np.ndarray:
        """This rank's grid rows of a field given by its lines (local lines, n_along)."""
        return self._rows(lines, self.rows)

    def to_extended(self, lines: np.ndarray) -> np.ndarray:
        """This rank's rows of the extended grid (``extended_rows``) of a field given by its lines (local
        lines, behind + n_along)."""
        return self._rows(lines, self.extended_rows)

    def inside(self, field: np.ndarray) -> np.ndarray:
        """This rank's grid rows of the grid's part of an extended-grid field given by its rows."""
        offset = self.behind if self.sign > 0 else 0
        if self.axis == 1:
            return field[:, offset : offset + self.n_along]
        ranges = [self.extended_rows.range(r) for r in range(self.comm.size)]
        wanted = [(offset + a, offset + b) for a, b in (self.rows.range(r) for r in range(self.comm.size))]
        return move_rows(field, ranges, wanted, self.comm)

    def along(self, row_index: np.ndarray) -> np.ndarray:
        """The line index t (0: the grid's rear row) of the grid's cells at ``row_index`` along the motion."""
        return row_index if self.sign > 0 else self.n_along - 1 - row_index

    def _lines(self, field: np.ndarray, rows: RowPartition) -> np.ndarray:
        if self.axis == 0:
            field = rows_to_columns(field, rows, self.across, self.comm).T
        return np.ascontiguousarray(field[:, ::-1] if self.sign < 0 else field)

    def _rows(self, lines: np.ndarray, rows: RowPartition) -> np.ndarray:
        if self.sign < 0:
            lines = lines[:, ::-1]
        if self.axis == 0:
            return columns_to_rows(np.ascontiguousarray(lines.T), rows, self.across, self.comm)
        return np.ascontiguousarray(lines)


class Memory:
    """W on lines (:class:`Lines`) from a kernel H (``kernel``, at least ``behind`` + ``n`` values; a
    grid of ``n`` cells along the motion, ``behind`` more in the extended grid): W_t = sum_m H[m] p_{t+m}.
    ``n_across``: the lines over all ranks (what petroll.solver.fft_work counts); ``workers``: FFT threads."""

    def __init__(self, kernel: np.ndarray, n: int, behind: int, n_across: int = 1, workers: int = 1):
        self.n, self.behind, self.n_across, self.workers = n, behind, n_across, workers
        self.kernel = kernel
        self.long = scipy.fft.next_fast_len(2 * n + behind - 1, real=True)
        self.short = scipy.fft.next_fast_len(2 * n - 1, real=True)
        self._spectra = (scipy.fft.rfft(kernel[: n + behind], self.long),
                         scipy.fft.rfft(kernel[:n], self.short),
                         scipy.fft.rfft(inverse_series(kernel, n), self.short))

    def extended(self, lines: np.ndarray) -> np.ndarray:
        """W on the extended lines (local lines, behind + n) of a field on the grid's lines (local lines, n),
        zero behind the grid."""
        return self._correlate(lines, self._spectra[0], self.long, self.n + self.behind)

    def grid(self, lines: np.ndarray) -> np.ndarray:
        """W on the grid's lines of a field on them (zero behind)."""
        return self._correlate(lines, self._spectra[1], self.short, self.n)

    def _correlate(self, lines, spectrum, length, out):
        """sum_m K[m] q_{t+m} for the last ``out`` values of t, q on the grid's lines (the last n of them):
        reversed, a causal convolution of q with K."""
        tally(fft_cost(self.n_across * length, length))
        reverse = scipy.fft.rfft(lines[:, ::-1], length, axis=1, workers=self.workers)
        return scipy.fft.irfft(reverse * spectrum, length, axis=1, workers=self.workers)[:, :out][:, ::-1]

    def solve_restricted(self, f: np.ndarray, on: np.ndarray) -> np.ndarray:
        """y with W_II y_I = f_I on the cells I where ``on`` (W's principal submatrix on them) and y = f
        elsewhere; fields on the grid's lines. W_II is upper-triangular along each line: its segments
        (runs of cells of I) are solved from the front, each with the reciprocal series G of H (the inverse
        of a Toeplitz block of W is the same block of G's Toeplitz matrix), after the push of the segments
        ahead of it (W of their solution) is taken from f: exact, two FFT correlations per segment."""
        ahead = np.zeros_like(on)
        ahead[:, :-1] = on[:, 1:]
        fronts = on & ~ahead  # the front cell of each segment
        order = np.cumsum(fronts[:, ::-1], axis=1)[:, ::-1] - 1  # segment index counted from the front
        y = np.zeros_like(f)
        for k in range(int(np.max(np.where(on, order, -1), initial=-1)) + 1):
            segment = on & (order == k)
            rhs = np.where(segment, f - self.grid(y) if k else f, 0.0)
            y = np.where(segment, self._correlate(rhs, self._spectra[2], self.short, self.n), y)
        return np.where(on, y, f)


class FarWake:
    """The displacement on the grid of the wake far behind it: cells ``near`` < t <= ``near + far`` behind
    the grid's rear row (t in cells along the motion), where p = 0 and W_{-t} = sum_k H[k + t] p_k varies
    only over V tau. They are lumped into blocks growing geometrically (by ``ratio``), each carrying its
    mean W (exact, from the cumulative sums of H) as line sources along the motion, one per line across
    (blocks are at least ``near`` >= 2 grid lengths from the grid, where W is smooth). Their push on the
    grid's row k (along the motion) is interpolated from ``nodes`` Chebyshev points in k (the sources are
    >= 2 grid lengths away: the interpolation error falls like 10^-nodes) and convolved across by FFT, the
    frequencies split over the ranks. 3-D grids only. ``along``, ``across``: cell sides (m)."""

    def __init__(self, kernel: np.ndarray, lines: Lines, near: int, far: int, along: float, across: float,
                 ratio: float = 1.05, nodes: int = 12):
        n, n_across, comm = lines.n_along, lines.n_across, lines.comm
        edges = [near + 1]
        while edges[-1] <= near + far:
            edges.append(min(max(edges[-1] + 1, round(edges[-1] * ratio)), near + far + 1))
        e = np.array(edges)
        cumulative = np.concatenate([[0.0], np.cumsum(kernel)])
        k = np.arange(n)[None, :]
        width = np.diff(e)[:, None]
        self.mean = (cumulative[k + e[1:, None]] - cumulative[k + e[:-1, None]]) / width  # (blocks, n)
        points, self.basis = _chebyshev(min(nodes, n), n)  # basis (n, nodes): row k interpolates at k
        # a block's strip of cells across as a line source along the motion (exact along it; across, its
        # width is lumped at its centre line): per unit compliance (across / pi) ln((x2 + r2) / (x1 + r1)),
        # x1, x2 the block's ends behind the target row, r = sqrt(x^2 + y^2)
        self.length = 2 * n_across
        self.freqs = RowPartition(n_across + 1, comm.size)
        f0, f1 = self.freqs.range(comm.rank)
        x1 = (points[:, None, None] + e[None, :-1, None] - 0.5) * along
        x2 = x1 + width[None, :, :] * along
        y = np.arange(n_across)[None, None, :] * across
        half = across / np.pi * np.log((x2 + np.hypot(x2, y)) / (x1 + np.hypot(x1, y)))
        r = np.concatenate([half, half[:, :, :1] * 0, half[:, :, :0:-1]], axis=2)  # even across: wrap-around
        self.spectrum = np.fft.rfft(r, axis=2)[:, :, f0:f1]  # (nodes, blocks, this rank's frequencies)
        self.lines = lines

    def __call__(self, lines: np.ndarray) -> np.ndarray:
        """The far wake's displacement (m per unit compliance x Pa) on this rank's grid rows, from the
        pressure on the grid's lines (collective)."""
        g, comm = self.lines, self.lines.comm
        f0, f1 = self.freqs.range(comm.rank)
        blocks = np.ascontiguousarray((lines @ self.mean.T).T)  # (blocks, local lines)
        counts = g.across.counts * blocks.shape[0]
        every = np.empty((g.n_across, blocks.shape[0])) if comm.size > 1 else blocks.T
        if comm.size > 1:
            comm.Allgatherv(np.ascontiguousarray(blocks.T), [every, counts])
        tally(fft_cost((len(blocks) + self.basis.shape[1]) * self.length, self.length) / 2)  # half pairs each
        spectra = np.fft.rfft(every.T, n=self.length, axis=1)[:, f0:f1]  # (blocks, this rank's frequencies)
        mine = np.einsum("jbf,bf->jf", self.spectrum, spectra)
        nodes = mine if comm.size == 1 else np.concatenate(comm.allgather(mine), axis=1)
        u = np.fft.irfft(nodes, n=self.length, axis=1)[:, : g.n_across]  # (nodes, across)
        r0, r1 = g.rows.range(comm.rank)
        if g.axis == 0:  # rows along the motion
            return self.basis[g.along(np.arange(r0, r1))] @ u
        return (self.basis[g.along(np.arange(g.n_along))] @ u[:, r0:r1]).T


def _chebyshev(m: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """m Chebyshev points (first kind) spanning [0, n - 1], and the Lagrange basis through them at 0 ... n-1
    (n, m): the barycentric formula with the points' closed-form weights (-1)^j sin((2j + 1) pi / 2m)."""
    angles = np.pi * (np.arange(m) + 0.5) / m
    points = (n - 1) / 2 * (1 - np.cos(angles))
    weights = (-1.0) ** np.arange(m) * np.sin(angles)
    difference = np.arange(n)[:, None] - points[None, :]
    exact = difference == 0
    difference[exact] = 1.0
    terms = weights / difference
    basis = terms / terms.sum(axis=1, keepdims=True)
    hit = exact.any(axis=1)
    basis[hit] = exact[hit]
    return points, basis
