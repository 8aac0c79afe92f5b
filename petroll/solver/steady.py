"""Steady rolling at constant velocity solved directly in the body frame (no transient).

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
and integrator: the long transient converges to it. Smaller c refines the time integration of the same
body-frame field (c -> 0: the exact hereditary law for p linear between cell centres).

Simulation.solve_steady finds p by a fixed point over elastic contact problems: compliance Jc (J at the
time to cross the contact) and the known height Z + A (W(x) - Jc x), x the iterate the memory is lagged
from. The QP's pressure g(x) is the fixed point's map; its Jacobian on the contact cells I is
-(Jc A_II)^-1 A_I (W - Jc), so I - g' = (Jc A_II)^-1 (A W)_II ~ W_II / Jc when (A W)_II is approximated by
A_II W_II (the wake's own push, A from outside I, left out). The residual g(x) - x is therefore mapped by
Jc W_II^-1 on I (:meth:`SteadyMemory.solve_restricted`, no convolution with A) and kept elsewhere: a
Newton-like step, Anderson-mixed.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft
import scipy.linalg

from petroll.solver.history import state_space


def pulse_response(material, integrator: str, dt: float, steps: int) -> np.ndarray:
    """W (1/Pa) of one material point at steps 0 ... steps - 1 after it carried a unit pressure over step
    0 only (zero before and after), as ``integrator`` computes it with steps of dt (s): h[0] = J_eff.
    The history is guarded: a step at which the integrator cannot hold a penetration is refused
    (SolverError), as in a transient run.

    The integrator is a linear state machine (petroll.solver.history.state_space): after the pulse (state
    S_1) a step at p = 0 maps the state S to M S and outputs W = c S; h[1 + j K + r] = (c M^r) (M^K)^j S_1
    for r < K ~ sqrt(steps): about 2 sqrt(steps) products of d x d matrices instead of ``steps`` integrator
    steps."""
    h = np.zeros(steps)
    h[0], after, M, c = state_space(material, integrator, dt)
    rest = steps - 1
    if rest <= 0 or after is None:
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


class SteadyMemory:
    """W(p) of the module docstring on a body-frame field, motion along ``axis`` (0: X, 1: Y) with ``sign``
    +1 towards increasing index; ``kernel`` (H) holds ``cells`` values. ``__call__`` takes and returns
    fields extended behind by cells where p = 0 (the near wake), along the motion at most ``cells`` long."""

    def __init__(self, material, integrator: str, speed: float, dt: float, cell: float, axis: int,
                 sign: int, cells: int):
        c = speed * dt / cell
        steps = math.ceil(cells / c) + 1
        self.kernel = memory_kernel(pulse_response(material, integrator, dt, steps), c, cells)
        self.axis, self.sign = axis, sign
        self._spectra = {}  # the kernel's spectrum per field length along the motion
        self._toeplitz = {}  # W and W^-1, dense lower-triangular, per field length (solve_restricted)

    def __call__(self, p: np.ndarray) -> np.ndarray:
        q = np.moveaxis(p, self.axis, 0)
        if self.sign > 0:  # reversed so that "ahead" is towards lower index: a causal convolution
            q = q[::-1]
        n = q.shape[0]
        length = scipy.fft.next_fast_len(2 * n - 1, real=True)
        if n not in self._spectra:
            self._spectra[n] = scipy.fft.rfft(self.kernel[:n], length)[:, None]
        w = scipy.fft.irfft(scipy.fft.rfft(q, length, axis=0) * self._spectra[n], length, axis=0)[:n]
        if self.sign > 0:
            w = w[::-1]
        return np.moveaxis(w, 0, self.axis)

    def solve_restricted(self, f: np.ndarray, on: np.ndarray) -> np.ndarray:
        """y with W_II y_I = f_I on the cells I where ``on`` (W's principal submatrix on them) and y = f
        elsewhere; fields at most ``cells`` long along the motion (I's cells alone matter). Along each line
        of cells along the motion W_II is lower-triangular (diagonal H[0] > 0); where a line's cells of I
        are contiguous it is the leading block of the Toeplitz matrix W, whose inverse is the leading block
        of W^-1 (one matrix product for all such lines); other lines are solved by substitution."""
        q, mask = (np.moveaxis(a, self.axis, 0) for a in (f, on))
        if self.sign > 0:
            q, mask = q[::-1], mask[::-1]
        n = q.shape[0]
        if n not in self._toeplitz:
            offsets = np.subtract.outer(np.arange(n), np.arange(n))
            toeplitz = np.where(offsets >= 0, self.kernel[np.clip(offsets, 0, n - 1)], 0.0)
            self._toeplitz[n] = (toeplitz, scipy.linalg.solve_triangular(toeplitz, np.eye(n), lower=True))
        toeplitz, inverse = self._toeplitz[n]
        y = q.copy()
        count = mask.sum(axis=0)
        first = np.argmax(mask, axis=0)
        last = n - 1 - np.argmax(mask[::-1], axis=0)
        contiguous = (count > 0) & (last - first + 1 == count)
        lines = np.flatnonzero(contiguous)
        if len(lines):
            length = int(count[lines].max())
            rows = np.arange(length)[:, None] + first[lines][None, :]
            inside = np.arange(length)[:, None] < count[lines][None, :]
            rows = np.where(inside, rows, 0)
            packed = np.where(inside, q[rows, lines[None, :]], 0.0)  # each line's cells of I from row 0
            solved = inverse[:length, :length] @ packed
            y[rows[inside], np.broadcast_to(lines, rows.shape)[inside]] = solved[inside]
        for line in np.flatnonzero((count > 0) & ~contiguous):
            cells = np.flatnonzero(mask[:, line])
            y[cells, line] = scipy.linalg.solve_triangular(toeplitz[np.ix_(cells, cells)], q[cells, line],
                                                           lower=True, check_finite=False)
        if self.sign > 0:
            y = y[::-1]
        return np.moveaxis(y, 0, self.axis)


class FarWake:
    """The displacement on the grid of the wake far behind it: cells ``near`` < t <= ``near + far`` behind
    the grid's rear row (t in cells along the motion), where p = 0 and W_{-t} = sum_k H[k + t] p_k varies
    only over V tau. They are lumped into blocks growing geometrically (by ``ratio``), each carrying its
    mean W (exact, from the cumulative sums of H) as line sources along the motion, one per column of cells
    across (blocks are at least ``near`` cells from the grid, where W is smooth). 3-D grids only.
    ``along``, ``across``: cell sides (m) along and across the motion; ``n_across`` cells across;
    ``axis``, ``sign`` as :class:`SteadyMemory`."""

    def __init__(self, kernel: np.ndarray, n_along: int, n_across: int, near: int, far: int, along: float,
                 across: float, axis: int, sign: int, ratio: float = 1.05):
        edges = [near + 1]
        while edges[-1] <= near + far:
            edges.append(min(max(edges[-1] + 1, round(edges[-1] * ratio)), near + far + 1))
        e = np.array(edges)
        cumulative = np.concatenate([[0.0], np.cumsum(kernel)])
        k = np.arange(n_along)[None, :]
        width = np.diff(e)[:, None]
        self.mean = (cumulative[k + e[1:, None]] - cumulative[k + e[:-1, None]]) / width  # (blocks, n_along)
        self.length = 2 * n_across
        # a block's strip of cells across as a line source along the motion (exact along it; across, its
        # width dy is lumped at its centre line: the blocks are >= near cells away): per unit compliance
        # (dy / pi) ln((x2 + r2) / (x1 + r1)), x1, x2 the block's ends ahead of the target, r = sqrt(x^2 + y^2)
        x1 = (np.arange(n_along)[:, None, None] + e[None, :-1, None] - 0.5) * along
        x2 = x1 + width[None, :, :] * along
        y = np.arange(n_across)[None, None, :] * across
        half = across / np.pi * np.log((x2 + np.hypot(x2, y)) / (x1 + np.hypot(x1, y)))
        r = np.concatenate([half, half[:, :, :1] * 0, half[:, :, :0:-1]], axis=2)  # even across: wrap-around
        self.spectrum = np.fft.rfft(r, axis=2)  # (n_along, blocks, frequencies)
        self.axis, self.sign, self.n_across = axis, sign, n_across

    def __call__(self, p: np.ndarray) -> np.ndarray:
        """The far wake's displacement (m per unit compliance x Pa) on the grid, from its pressure p."""
        q = np.moveaxis(p, self.axis, 0)
        if self.sign < 0:  # so that the rear row is row 0
            q = q[::-1]
        blocks = np.fft.rfft(self.mean @ q, n=self.length, axis=1)
        u = np.fft.irfft(np.einsum("kbf,bf->kf", self.spectrum, blocks), n=self.length, axis=1)[:, : self.n_across]
        if self.sign < 0:
            u = u[::-1]
        return np.moveaxis(u, 0, self.axis)


class Anderson:
    """Anderson mixing of a fixed point x = g(x) keeping ``depth`` differences (type II)."""

    def __init__(self, depth: int = 6):
        self.depth, self.last, self.df, self.dg = depth, None, [], []

    def next(self, x: np.ndarray, gx: np.ndarray) -> np.ndarray:
        f = (gx - x).ravel()
        if self.last is not None:
            self.df.append(f - self.last[0])
            self.dg.append(gx.ravel() - self.last[1])
            if len(self.df) > self.depth:
                self.df.pop(0)
                self.dg.pop(0)
        self.last = (f, gx.ravel())
        if not self.df:
            return gx
        # min |f - df gamma| by least squares: the minimum-norm gamma where differences are degenerate (two
        # equal residuals: a zero column, gamma 0 for it)
        gamma = np.linalg.lstsq(np.array(self.df).T, f, rcond=None)[0]
        return gx - (gamma @ np.array(self.dg)).reshape(gx.shape)
