"""The tangential problem of one step: Coulomb friction on a given pressure, solved on the contact's window.

Conventions (docs/friction.md). q = (q_x, q_y) (Pa) is the tangential traction the half-space exerts on the
body (CONTACT's "tractions on body 1", the upper body); the relative tangential displacement of the body's
surface with respect to the half-space's is u = c K q, K the Cerruti (line contact: strip) kernel of
petroll.solver.kernels.cerruti and c the bodies' summed shear compliance (1/Pa): 1/(2 G) for a rigid body
on a half-space of shear modulus G, 1/G for a body of the same material (quasi-identical: the
normal-tangential coupling cancels; it is left out, exact also for a rigid body at nu = 1/2). The slip of
a step (m; the slip velocity times the step) at each cell is

    S = W + u - u',

W the rigid slip of the step (creepage x distance rolled, or a shift), u' the relative displacement the
same material points had one step earlier. Coulomb: |q| <= g = mu p; S = 0 where |q| < g (stick);
q = -g S/|S| where S != 0 (slip, the traction opposing it). These are the optimality conditions of

    minimise 1/2 q^T (c K) q + q^T (W - u'),   |q_I| <= g_I   (friction disks; line contact: -g <= q_x <= g)

a convex QP whose gradient is the slip. Force control: sum q dA = F held, W's uniform part the constraint's
multiplier (the rigid shift or creepage found).

Solver (:class:`DiskPCG`): a projected, preconditioned conjugate gradient in the manner of Polonsky and
Keer's, with the friction disk in place of the bound: conjugate directions on the stick cells' two
components and on the slip cells' one tangential direction (along their disk's edge), each step's exact
minimiser along the direction (a slip cell turning along its edge adds the curvature -t.S/g: turning pulls
its traction inwards), projection onto the disks (a stick cell that leaves its disk becomes a slip cell; a
slip cell moves along its edge's arc), slip cells whose slip points along their traction released,
conjugacy restarted whenever the sets change; preconditioned by the inverse of the block circulant
approximation of K on the window (the normal problem's preconditioner at nu = 0). Plain numpy over the
distributed FFT convolution of petroll.solver.influence; every reduction over the communicator, so every
rank takes the same path. Measured against its alternatives in docs/friction.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft
from mpi4py import MPI

from petroll.errors import SolverError
from petroll.solver.fft_work import tally
from petroll.solver.influence import Convolution, spare_cores
from petroll.solver.kernels.cerruti import Tangential, tangential_kernel
from petroll.solver.partition import RowPartition, move_rows


class BlockConvolution:
    """u = K q for the m traction components of a tangential kernel on an (nx, ny) block of cells whose
    rows are split over ``comm``; q and u have shape (m, local rows, ny). The same zero-padded FFTs as the
    normal problem's operator (petroll.solver.influence.Convolution), one transform per component and the
    m x m block of kernel spectra between them (K_xy is odd in each offset, even in the pair: its spectrum
    is real, like the others').

    ``inverse=True``: instead the inverse of the block circulant (Strang) approximation of K on the torus
    ``torus`` >= (nx, ny) (the block zero-padded onto it, the result cut back): per frequency the inverse
    of the symmetric m x m symbol, its eigenvalues floored at 1e-12 of the largest (symmetric positive
    definite; at nu = 0 the normal problem's preconditioner for each component)."""

    def __init__(self, kernel: Tangential, nx: int, ny: int, comm: MPI.Comm = MPI.COMM_SELF,
                 inverse: bool = False, torus: tuple[int, int] | None = None, workers: int = 1):
        self.kernel, self.nx, self.ny, self.comm, self.m = kernel, nx, ny, comm, kernel.components
        self.fft = Convolution(None, nx, ny, comm, inverse=inverse, workers=workers, torus=torus)
        self.r0, self.r1 = self.fft.r0, self.fft.r1
        self.cost = self.m * self.fft.cost
        spectra = self.fft.kernel_spectrum(kernel.values)
        # the wrapped odd kernel of an even torus is not exactly odd at its middle offset: its symbol's
        # imaginary part is that asymmetry; the real part is the symmetric circulant's (C + C^T)/2
        blocks = kernel.blocks(np.ascontiguousarray(spectra.real))
        self.blocks = _invert(blocks, comm) if inverse else blocks
        self.diagonal = kernel.diagonal
        # a bound of every row sum of |K| (forward operator): K_xx's sum (its symbol at frequency 0, the
        # largest for a positive kernel) times 1 + nu, which bounds the row sums of |K_xy| (nu x y/r^3)
        # against those of K_xx >= (1 - nu)/r + nu x^2/r^3 (a bound for the solver's gradient updates)
        self.row_sum = (1 + kernel.nu) * comm.allreduce(float(np.abs(blocks[0][0]).max(initial=0.0)),
                                                        op=MPI.MAX)

    def __call__(self, q: np.ndarray) -> np.ndarray:
        tally(self.cost)
        transforms = [self.fft.forward(q[i]) for i in range(self.m)]
        out = np.empty((self.m, self.r1 - self.r0, self.ny))
        for i in range(self.m):
            product = self.blocks[i][0] * transforms[0]
            for j in range(1, self.m):
                product += self.blocks[i][j] * transforms[j]
            out[i] = self.fft.backward(product, overwrite=True)
        return out


class CouplingConvolution:
    """The normal-tangential coupling on an (nx, ny) block of cells (rows split over ``comm``): ``normal(t)``
    = sum_j K_zj t_j (t of shape (m, local rows, ny)) and its transpose ``tangential(p)`` = (K_zj^T p)_j,
    K the kernels of petroll.solver.kernels.cerruti.Coupling (odd along their own axis: complex spectra;
    the transpose's are their conjugates). Signs and factors: a traction t on the half-space moves its
    surface into it by (1 - 2 nu)/(4 G) normal(t); a pressure p moves it tangentially by
    -(1 - 2 nu)/(4 G) tangential(p)."""

    def __init__(self, kernel, nx: int, ny: int, comm: MPI.Comm = MPI.COMM_SELF, workers: int = 1):
        self.nx, self.ny, self.m = nx, ny, kernel.components
        self.fft = Convolution(None, nx, ny, comm, workers=workers)
        self.r0, self.r1 = self.fft.r0, self.fft.r1
        self.spectra = self.fft.kernel_spectrum(kernel.values)

    def normal(self, t: np.ndarray) -> np.ndarray:
        tally(self.m * self.fft.cost)
        total = sum(self.spectra[j] * self.fft.forward(t[j]) for j in range(self.m))
        return self.fft.backward(total, overwrite=True)

    def tangential(self, p: np.ndarray) -> np.ndarray:
        tally(self.m * self.fft.cost)
        transform = self.fft.forward(p)
        return np.stack([self.fft.backward(np.conj(self.spectra[j]) * transform) for j in range(self.m)])


def _invert(blocks: list[list[np.ndarray]], comm: MPI.Comm) -> list[list[np.ndarray]]:
    """The per-frequency inverse of a symmetric m x m (m = 1, 2) block symbol, eigenvalues floored at 1e-12
    of the largest over all ranks."""
    if len(blocks) == 1:
        a = blocks[0][0]
        floor = comm.allreduce(float(a.max(initial=0.0)), op=MPI.MAX) * 1e-12
        return [[1.0 / np.maximum(a, floor)]]
    a, c, b = blocks[0][0], blocks[0][1], blocks[1][1]
    mean, half = 0.5 * (a + b), np.hypot(0.5 * (a - b), c)
    floor = comm.allreduce(float((mean + half).max(initial=0.0)), op=MPI.MAX) * 1e-12
    hi, lo = np.maximum(mean + half, floor), np.maximum(mean - half, floor)
    # K = lam_hi P + lam_lo (I - P), P = (K - lam_lo_raw I)/(2 half) the projector on the larger eigenvalue
    with np.errstate(divide="ignore", invalid="ignore"):
        split = half > 1e-14 * (mean + half)
        pa = np.where(split, (a - (mean - half)) / np.where(split, 2 * half, 1.0), 0.5)
        pc = np.where(split, c / np.where(split, 2 * half, 1.0), 0.0)
    pb = 1.0 - pa
    inv_hi, inv_lo = 1.0 / hi, 1.0 / lo
    xx = inv_hi * pa + inv_lo * (1 - pa)
    yy = inv_hi * pb + inv_lo * (1 - pb)
    xy = (inv_hi - inv_lo) * pc
    return [[xx, xy], [xy, yy]]


class TangentialOperator:
    """Block convolutions of one grid's tangential kernel on windows of its cells (spectra built once per
    window shape and kept, the last ``kept``), and their preconditioners (the inverse block circulant on
    the window grown to fast FFT lengths)."""

    kept = 12

    def __init__(self, kernel: Tangential, comm: MPI.Comm = MPI.COMM_SELF, workers: int = 1):
        self.kernel, self.comm, self.workers = kernel, comm, workers
        self._windows: dict[tuple[int, int, bool], BlockConvolution] = {}

    @property
    def components(self) -> int:
        return self.kernel.components

    @property
    def diagonal(self) -> float:
        return self.kernel.diagonal

    def window(self, nx: int, ny: int, inverse: bool = False) -> BlockConvolution:
        key = (nx, ny, inverse)
        conv = self._windows.pop(key, None)
        if conv is None:
            torus = (scipy.fft.next_fast_len(nx), scipy.fft.next_fast_len(ny, real=True)) if inverse else None
            conv = BlockConvolution(self.kernel, nx, ny, self.comm, inverse, torus, self.workers)
        self._windows[key] = conv
        while len(self._windows) > self.kept:
            del self._windows[next(iter(self._windows))]
        return conv


# -- the QP on the friction disks ----------------------------------------------------------------------------

EDGE = 1e-12
"""A cell whose |q| is within this fraction of its bound counts as on the bound (slip)."""

SAFE = 2.0
"""An updated gradient's error bound counts SAFE times in the residual (a disk's projection: <= sqrt 2)."""


@dataclass
class DiskResult:
    """What :meth:`DiskPCG.solve` returns (scaled units, this rank's cells)."""

    q: np.ndarray  # (m, n) tractions
    slip: np.ndarray  # (m, n) the slip H q + b + multiplier
    multiplier: np.ndarray  # (m,) the force constraint's multiplier (the uniform slip found; 0 without)
    iterations: int
    applications: int
    residual: float  # max over cells of |q - P(q - slip)|, P the projection onto the disks
    force_error: float  # |sum q - total| (0 without force control)


def project(q: np.ndarray, g: np.ndarray) -> np.ndarray:
    """Each cell's traction q[:, I] put on its disk |q_I| <= g_I (radially); q of shape (m,) + g's."""
    norm = np.sqrt((q * q).sum(axis=0))
    scale = np.where(norm > g, g / np.where(norm > 0, norm, 1.0), 1.0)
    return q * scale


@dataclass
class _State:
    """The sets and gradients of one iterate (this rank's cells)."""

    slip: np.ndarray  # on the disk's edge (and not released)
    stick: np.ndarray  # inside the contact and not slip
    t: np.ndarray  # (m, n) unit traction direction on slip cells (0 elsewhere)
    tau: np.ndarray | None  # (2, n) along the edge (3-D only)
    multiplier: np.ndarray  # (m,) the force constraint's multiplier
    s: np.ndarray  # (m, n) the slip: gradient plus multiplier
    pg: np.ndarray  # (m, n) the slip on the free directions (the projected gradient)
    residual: float  # max |q - P(q - s)|
    force_error: float
    changed: bool  # the slip set differs from the previous iterate's


class DiskPCG:
    """minimise 1/2 q^T H q + b^T q over |q_I| <= g_I (the module docstring's method), with sum q = total
    (an m-vector) held when ``total`` is given. Arrays hold this rank's cells: q, b (m, n) (m = 1: the
    interval [-g, g]); g (n,) >= 0 (a cell with g = 0 holds q = 0). ``apply(d)``: H d for (m, n) d;
    ``precondition(r)``: an approximation of H^-1 r (symmetric positive definite); ``norm``: a bound of
    |H|_inf (the largest row sum of |H|). :meth:`solve` stops when the natural residual max |q - P(q - s)|
    <= tol (and under force control |sum q - total| <= tol sum g), plus SAFE x the bound of an updated
    gradient's error; SolverError after ``max_iterations`` iterations or for non-positive curvature.

    The gradient is updated from H d between fresh evaluations; a slip cell's turn along its edge's arc
    moves it off the straight step by e (second order in the turn), which leaves the updated gradient off
    by at most |H|_inf max|e|: it is computed afresh once those errors add up to the residual, after any
    projection of a stick cell, and at least every ``refresh`` iterations. The reductions over
    the ranks are batched: about five a iteration besides the convolution's."""

    def __init__(self, apply, precondition, g: np.ndarray, comm: MPI.Comm, tol: float, max_iterations: int,
                 total: np.ndarray | None = None, norm: float = 1.0, refresh: int = 25, monitor=None):
        self.apply, self.precondition, self.g, self.comm = apply, precondition, g, comm
        self.tol, self.max_iterations, self.total, self.norm = tol, max_iterations, total, norm
        self.refresh, self.monitor = refresh, monitor
        self.inside = g > 0
        self.capacity = comm.allreduce(float(g.sum()), op=MPI.SUM)
        self.applications = 0

    def sums(self, *parts) -> list[np.ndarray]:
        """The sums over the ranks of each part (scalars or arrays), in one reduction."""
        flat = [np.atleast_1d(np.asarray(part, dtype=float)).ravel() for part in parts]
        out = np.concatenate(flat) if flat else np.zeros(0)
        self.comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
        pieces, start = [], 0
        for part, f in zip(parts, flat):
            pieces.append(out[start : start + f.size].reshape(np.shape(part)))
            start += f.size
        return pieces

    def largest(self, *values: float) -> list[float]:
        """The largest of each value over the ranks, in one reduction."""
        out = np.array(values, dtype=float)
        self.comm.Allreduce(MPI.IN_PLACE, out, op=MPI.MAX)
        return list(out)

    def gradient(self, q: np.ndarray, b: np.ndarray) -> np.ndarray:
        self.applications += 1
        return self.apply(q if self.source is None else q - self.source) + b

    def state(self, q: np.ndarray, r: np.ndarray, previous_slip) -> _State:
        """The sets at q (slip cells whose slip points along their traction released), the multiplier,
        the slip and its free part, the residuals."""
        g, m = self.g, q.shape[0]
        norm = np.sqrt((q * q).sum(axis=0))
        slip = self.inside & (norm >= g * (1 - EDGE))
        t = np.where(slip, q / np.where(slip, norm, 1.0), 0.0)
        tau = np.stack([-t[1], t[0]]) if m == 2 else None
        multiplier = np.zeros(m)
        force_error = 0.0
        if self.total is not None:
            stick = self.inside & ~slip
            matrix, rhs, q_sum = self.sums(_free_matrix(stick, slip, tau, m), _restrict(r, stick, slip, tau).sum(axis=1),
                                           q.sum(axis=1))
            multiplier = -_solve_small(matrix, rhs)
            force_error = float(np.abs(q_sum - self.total).max())
        s = r + multiplier[:, None]
        slip = slip & ~((s * t).sum(axis=0) > 0)
        stick = self.inside & ~slip
        local = float(np.abs(q - project(q - s, g)).max(initial=0.0))
        moved = 1.0 if previous_slip is None or np.any(slip != previous_slip) else 0.0
        residual, changed = self.largest(local, moved)
        return _State(slip, stick, t, tau, multiplier, s, _restrict(s, stick, slip, tau), residual, force_error,
                      changed > 0)

    def solve(self, q: np.ndarray, b: np.ndarray, source: np.ndarray | None = None) -> DiskResult:
        """The minimiser from the first guess q, the linear term b - H ``source`` (None: 0)."""
        g, total, self.source = self.g, self.total, source
        q = project(np.where(self.inside, q, 0.0), g)
        if total is not None:
            q = self.restore(q)
        r = self.gradient(q, b)
        stale, drift = 0, 0.0  # drift: a bound of |r - (H q + b)|_inf (round-off of exact updates aside)
        d = z_prev = pgz_prev = previous_slip = None
        for iteration in range(self.max_iterations + 1):
            st = self.state(q, r, previous_slip)
            if self.monitor is not None:
                y = q if source is None else q - source  # the objective less 1/2 f.H f - b.f: a constant
                self.monitor(iteration, st, 0.5 * float(self.sums(np.vdot(y, r + b))[0]))
            if st.residual <= self.tol and st.force_error <= self.tol * max(self.capacity, 1e-300):
                if st.residual + SAFE * drift <= self.tol:
                    return DiskResult(q, st.s, st.multiplier, iteration, self.applications, st.residual,
                                      st.force_error)
                r, stale, drift = self.gradient(q, b), 0, 0.0
                continue
            if iteration == self.max_iterations:
                break
            previous_slip = st.slip
            d, z_prev, pgz_prev, kappa = self.direction(st, d, z_prev, pgz_prev)
            q, r, clipped, error = self.step(q, r, st, d, kappa)
            stale, drift = stale + 1, drift + self.norm * error
            if clipped or stale >= self.refresh or drift > st.residual:
                r, stale, drift = self.gradient(q, b), 0, 0.0
        raise SolverError(f"the tangential QP did not converge within {self.max_iterations} iterations "
                          f"(natural residual {st.residual:.3g}, tolerance {self.tol:g}); try a larger "
                          "[solver] tol")

    def direction(self, st: _State, d, z_prev, pgz_prev):
        """The next conjugate direction (Polak-Ribiere, restarted when the sets change), preconditioned
        by D M D: M the given preconditioner on the free directions, D = (1 + kappa)^-1/2 on slip cells
        (kappa = -t.s/g: a slip cell turning along its edge by dt moves its traction inwards by
        dt^2/(2 g), which the slip's outward component -t.s > 0 turns into that much more curvature).
        Under force control z is projected onto sum z = 0 (which leaves pg.z as it is: pg sums to 0).
        Returns (d, z, <pg, z>, kappa)."""
        g, m = self.g, st.s.shape[0]
        kappa = np.where(st.slip, -(st.s * st.t).sum(axis=0) / np.where(st.slip, g, 1.0), 0.0)
        scale = np.where(st.slip, 1.0 / np.sqrt(1.0 + kappa), 1.0)
        z = scale * _restrict(self.precondition(scale * st.pg), st.stick, st.slip, st.tau)
        previous = 0.0 if z_prev is None else np.vdot(st.pg, z_prev)
        if self.total is not None:
            matrix, z_sum, pgz, pg_prev = self.sums(_free_matrix(st.stick, st.slip, st.tau, m), z.sum(axis=1),
                                                    np.vdot(st.pg, z), previous)
            mu = _solve_small(matrix, z_sum)
            z = z - _restrict(np.broadcast_to(mu[:, None], z.shape), st.stick, st.slip, st.tau)
        else:
            pgz, pg_prev = self.sums(np.vdot(st.pg, z), previous)
        changed = st.changed
        if pgz <= 0:  # round-off, or a free set too small to meet the force: steepest descent
            z, pgz, changed = st.pg, float(self.sums(np.vdot(st.pg, st.pg))[0]), True
        beta = 0.0
        if not changed and d is not None:
            beta = max(0.0, float(pgz - pg_prev) / pgz_prev)
        return (-z + beta * d if beta > 0 else -z), z, float(pgz), kappa

    def step(self, q, r, st: _State, d, kappa):
        """The exact minimiser along d of the quadratic model (slip cells along their edge's arc), projected
        onto the disks (and the force restored). Returns (q, r updated from H d, whether q left the
        straight step, whether a stick cell was projected, the largest deviation from the straight step)."""
        hd = self.apply(d)
        self.applications += 1
        dhd, bend, pgd = self.sums(np.vdot(d, hd), np.vdot(kappa, (d * d).sum(axis=0)), np.vdot(st.pg, d))
        curvature = float(dhd + bend)
        if not curvature > 0:
            raise SolverError(f"the tangential QP met a direction of non-positive curvature ({curvature:.3g}): "
                              "its influence matrix is not positive definite")
        alpha = -float(pgd) / curvature
        straight = q + alpha * d
        trial = straight
        if st.tau is not None:
            g = self.g
            turn = np.where(st.slip, alpha * (st.tau * d).sum(axis=0) / np.where(st.slip, g, 1.0), 0.0)
            trial = np.where(st.slip, g * (st.t * np.cos(turn) + st.tau * np.sin(turn)), straight)
        q = project(trial, self.g)
        clipped = float(np.any(st.stick & (np.abs(q - trial).max(axis=0, initial=0.0) > 0)))
        if self.total is not None:
            q = self.restore(q)
        clipped, error = self.largest(clipped, float(np.abs(q - straight).max(initial=0.0)))
        return q, r + alpha * hd, clipped > 0, error

    def restore(self, q: np.ndarray, rounds: int = 20) -> np.ndarray:
        """q moved on its free directions (and projected) until sum q = total, as far as the disks allow."""
        g, m, total = self.g, q.shape[0], self.total
        scale = max(float(np.abs(total).max()), 1e-300)
        for _ in range(rounds):
            norm = np.sqrt((q * q).sum(axis=0))
            slip = self.inside & (norm >= g * (1 - EDGE))
            stick = self.inside & ~slip
            t = np.where(slip, q / np.where(slip, norm, 1.0), 0.0)
            tau = np.stack([-t[1], t[0]]) if m == 2 else None
            matrix, q_sum = self.sums(_free_matrix(stick, slip, tau, m), q.sum(axis=1))
            deficit = total - q_sum
            if np.abs(deficit).max() <= 1e-15 * scale or not np.abs(matrix).max() > 0:
                break
            mu = _solve_small(matrix, deficit)
            q = project(q + _restrict(np.broadcast_to(mu[:, None], q.shape), stick, slip, tau), g)
        return q


def _restrict(z: np.ndarray, stick: np.ndarray, slip: np.ndarray, tau: np.ndarray | None) -> np.ndarray:
    """z on the free directions: both components on stick cells, the edge's direction on slip cells."""
    out = np.where(stick, z, 0.0)
    if tau is not None:
        out += np.where(slip, tau * (tau * z).sum(axis=0), 0.0)
    return out


def _free_matrix(stick, slip, tau, m: int) -> np.ndarray:
    """This rank's sum over its cells of the projector on their free directions (m x m): I on stick
    cells, tau tau^T on slip cells."""
    out = np.count_nonzero(stick) * np.eye(m)
    if tau is not None:
        out = out + np.einsum("in,jn->ij", tau * slip, tau)
    return out


def _solve_small(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    return np.linalg.lstsq(matrix, rhs, rcond=1e-12)[0]


# -- one step's problem on the grid --------------------------------------------------------------------------

@dataclass
class TangentialSolution:
    """A solved tangential problem. Fields hold this rank's grid rows, shape (m, local rows, ny), m the
    traction components (2; line contact 1): ``traction`` q (Pa, on the body), ``slip`` S (m, over the
    step: W + u - u', u = c K q: ``TangentialSolver.displacement``), ``stick`` (bool, local rows x ny: p > 0
    and |q| < g - tol max g). Global values: ``shift`` the uniform part of W found under force control (m;
    0 without), ``force`` sum q dA (N), the work and residual of the solve, the window [i0, i1) x [j0, j1)."""

    traction: np.ndarray
    slip: np.ndarray
    stick: np.ndarray
    shift: np.ndarray
    force: np.ndarray
    iterations: int
    applications: int
    residual: float
    window: tuple[int, int, int, int]


@dataclass
class Scaled:
    """A window's problem in the solvers' units: tractions over ``q_ref`` (the largest bound), slips over
    ``s_ref`` = c K_00 q_ref (the slip that bound causes on its own cell), so that ``apply`` (H = K/K_00,
    unit diagonal) and ``precondition`` (its inverse block circulant) act on (m, window rows, ny) fields.
    ``g``: the bounds (window rows, ny), Pa; ``nx``, ``ny``: the window's shape; ``norm``: a bound of
    |H|_inf; ``box``: the window on the grid."""

    box: tuple[int, int, int, int]
    g: np.ndarray
    q_ref: float
    s_ref: float
    nx: int
    ny: int
    apply: object
    precondition: object
    norm: float


class TangentialSolver:
    """Tangential problems (module docstring) on ``grid`` (rows split over ``comm``), Poisson's ratio ``nu``
    and the bodies' summed shear compliance ``compliance`` (1/Pa: 1/(2 G) for a rigid body on the
    half-space, 1/G for a body of the same material). ``tol``: the relative tolerance of the natural
    residual (in units of the largest traction bound and of the slip it causes on its own cell).
    ``workers``: FFT threads per rank (default: the rank's share of its node's cores)."""

    def __init__(self, grid, comm: MPI.Comm, nu: float, compliance: float, tol: float = 1e-8,
                 max_iterations: int = 10000, workers: int | None = None):
        if not compliance > 0:
            raise ValueError(f"the tangential compliance {compliance} must be > 0")
        self.grid, self.comm, self.nu, self.compliance = grid, comm, nu, compliance
        self.tol, self.max_iterations = tol, max_iterations
        self.operator = TangentialOperator(tangential_kernel(grid, nu), comm,
                                           spare_cores(comm) if workers is None else workers)
        self.m = self.operator.components
        self.rows = RowPartition(grid.nx, comm.size)
        self.r0, self.r1 = self.rows.range(comm.rank)
        self.work = [0, 0]  # iterations and operator applications of every solve so far
        self.monitor = None  # called as monitor(iteration, state, objective) by every iteration of a solve

    @property
    def local_shape(self) -> tuple[int, int]:
        return (self.r1 - self.r0, self.grid.ny)

    def zeros(self) -> np.ndarray:
        """A tangential field of zeros on this rank's rows, shape (m, local rows, ny)."""
        return np.zeros((self.m, *self.local_shape))

    # -- boxes of cells ----------------------------------------------------------------------------------
    def box(self, cells: np.ndarray) -> tuple[int, int, int, int] | None:
        """The bounding box [i0, i1) x [j0, j1) of the True ``cells`` (this rank's rows) over all ranks;
        None when there are none."""
        rows = np.flatnonzero(cells.any(axis=1)) + self.r0
        cols = np.flatnonzero(cells.any(axis=0))
        big = self.grid.nx + self.grid.ny
        ends = np.array([rows.min(initial=big), cols.min(initial=big), -rows.max(initial=-1),
                         -cols.max(initial=-1)])
        self.comm.Allreduce(MPI.IN_PLACE, ends, op=MPI.MIN)
        if ends[0] == big:
            return None
        return int(ends[0]), int(-ends[2]) + 1, int(ends[1]), int(-ends[3]) + 1

    def _layouts(self, box):
        """(every rank's grid rows, every rank's rows of the box split evenly)."""
        i0, i1 = box[0], box[1]
        part = RowPartition(i1 - i0, self.comm.size)
        return ([self.rows.range(r) for r in range(self.comm.size)],
                [(i0 + a, i0 + b) for a, b in (part.range(r) for r in range(self.comm.size))])

    def to_box(self, field: np.ndarray, box) -> np.ndarray:
        """The box's part of a grid field (m, local grid rows, ny) or (local grid rows, ny), in the box's
        even row split (this rank's box rows)."""
        grid_rows, box_rows = self._layouts(box)
        j0, j1 = box[2], box[3]
        if field.ndim == 2:
            return move_rows(field[:, j0:j1], grid_rows, box_rows, self.comm)
        return np.stack([move_rows(f[:, j0:j1], grid_rows, box_rows, self.comm) for f in field])

    def from_box(self, values: np.ndarray, box, fill: float = 0.0) -> np.ndarray:
        """A grid field (this rank's rows) holding the box's ``values`` (its even row split), ``fill``
        elsewhere; shape (m, local rows, ny) or (local rows, ny) like ``values``."""
        grid_rows, box_rows = self._layouts(box)
        i0, i1, j0, j1 = box
        dst = [(min(max(a, i0), i1), max(min(max(a, i0), i1), min(b, i1))) for a, b in grid_rows]
        a, b = dst[self.comm.rank]
        stack = values if values.ndim == 3 else values[None]
        out = np.full((len(stack), *self.local_shape), fill, dtype=values.dtype)
        for k, v in enumerate(stack):
            out[k, a - self.r0 : b - self.r0, j0:j1] = move_rows(v, box_rows, dst, self.comm)
        return out if values.ndim == 3 else out[0]

    def displacement(self, traction: np.ndarray, box, compliance: float | None = None) -> np.ndarray:
        """u = c K q (m; this rank's grid rows, zero outside ``box``) of a traction ``traction`` (Pa, grid
        rows) that vanishes outside ``box``; ``compliance`` c (1/Pa; default the solver's; 1: K applied
        to a field of displacement sources, u = K s)."""
        if box is None:
            return self.zeros()
        c = self.compliance if compliance is None else compliance
        conv = self.operator.window(box[1] - box[0], box[3] - box[2])
        return self.from_box(c * conv(self.to_box(traction, box)), box)

    def scaled(self, bound: np.ndarray, box, compliance: float | None = None) -> Scaled:
        """The problem on ``box`` of the traction bound ``bound`` (Pa, this rank's grid rows) in scaled units
        (:class:`Scaled`; its operators take (m, window rows, ny) fields), with the step's compliance c
        (1/Pa; default the solver's: a viscoelastic step's is its integrator's effective one)."""
        g = self.to_box(bound, box)
        q_ref = self.comm.allreduce(float(g.max(initial=0.0)), op=MPI.MAX)
        nx, ny = box[1] - box[0], box[3] - box[2]
        conv, pc = self.operator.window(nx, ny), self.operator.window(nx, ny, inverse=True)
        k00 = conv.diagonal
        c = self.compliance if compliance is None else compliance
        return Scaled(box, g, q_ref, c * k00 * q_ref, nx, ny, lambda v: conv(v) / k00,
                      lambda v: pc(v) * k00, conv.row_sum / k00)

    def scaled_force(self, force, problem: Scaled) -> np.ndarray:
        """A tangential force (N, an m-vector) as the scaled sum of tractions; SolverError when it exceeds
        the friction bound mu x the normal force (the body slides)."""
        force = np.asarray(force, dtype=float).reshape(self.m)
        area = self.grid.cell_area
        capacity = self.comm.allreduce(float(problem.g.sum()), op=MPI.SUM) * area
        if np.hypot.reduce(force) > capacity * (1 + 1e-12):
            raise SolverError(f"the tangential force {np.hypot.reduce(force):.6g} N exceeds the friction bound "
                              f"mu x force = {capacity:.6g} N: the body slides")
        return force / (area * problem.q_ref)

    # -- the QP ------------------------------------------------------------------------------------------
    def solve(self, bound: np.ndarray, rigid: np.ndarray | None = None, previous: np.ndarray | None = None,
              warm: np.ndarray | None = None, force: np.ndarray | None = None, tol: float | None = None,
              compliance: float | None = None, earlier: np.ndarray | None = None) -> TangentialSolution:
        """The tractions on the traction bound ``bound`` g = mu p (Pa, this rank's grid rows), the rigid
        slip of the step ``rigid`` W (m; (m, rows, ny) or None: 0) and the relative displacement u' the
        material points at each cell had a step earlier: ``previous`` (m, (m, rows, ny), or None: 0) plus
        c K X of ``earlier`` X (Pa, the last tractions; in the QP's gradient H (q - X c/c_s): no convolution
        of its own). ``force`` (N, an m-vector): hold sum q dA = force, a uniform slip added to W found
        (``shift``). ``warm``: a first guess (Pa). ``compliance``: the step's c_s (1/Pa; default the
        solver's c), u = c_s K q. The QP is posed on the bounding box of g > 0 and X != 0. SolverError when
        the force exceeds what the bound allows, or when the solve fails."""
        g_cells = bound > 0
        tol = self.tol if tol is None else tol
        zero = self.zeros()
        if self.box(g_cells) is None:
            if force is not None and np.any(np.asarray(force) != 0):
                raise SolverError("a tangential force with no contact to carry it")
            return TangentialSolution(zero, zero.copy(), np.zeros(self.local_shape, bool), np.zeros(self.m),
                                      np.zeros(self.m), 0, 0, 0.0, (0, 0, 0, 0))
        box = self.box(g_cells if earlier is None else g_cells | np.any(earlier != 0, axis=0))
        problem = self.scaled(bound, box, compliance)
        g, q_ref, s_ref, m, ny = problem.g, problem.q_ref, problem.s_ref, self.m, problem.ny
        b = zero.copy() if rigid is None else np.array(rigid, dtype=float)
        if previous is not None:
            b -= previous
        b = self.to_box(b, box).reshape(m, -1) / s_ref
        ratio = self.compliance / (self.compliance if compliance is None else compliance) / q_ref
        source = None if earlier is None else self.to_box(earlier, box).reshape(m, -1) * ratio
        total = None if force is None else self.scaled_force(force, problem)
        start = np.zeros((m, g.size)) if warm is None else self.to_box(warm, box).reshape(m, -1) / q_ref
        result = DiskPCG(lambda d: problem.apply(d.reshape(m, -1, ny)).reshape(m, -1),
                         lambda r: problem.precondition(r.reshape(m, -1, ny)).reshape(m, -1), g.ravel() / q_ref,
                         self.comm, tol, self.max_iterations, total, problem.norm,
                         monitor=self.monitor).solve(start, b, source)
        self.work[0] += result.iterations
        self.work[1] += result.applications
        q = result.q.reshape(self.m, -1, ny) * q_ref
        slip = result.slip.reshape(self.m, -1, ny) * s_ref
        stick = (g > 0) & (np.sqrt((q * q).sum(axis=0)) < g - tol * q_ref)
        sums = np.array(q.sum(axis=(1, 2)), dtype=float)
        self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        return TangentialSolution(self.from_box(q, box), self.from_box(slip, box), self.from_box(stick, box, False),
                                  result.multiplier * s_ref, sums * self.grid.cell_area, result.iterations,
                                  result.applications, result.residual, box)
