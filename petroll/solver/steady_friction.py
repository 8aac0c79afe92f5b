"""Steady rolling with Coulomb friction solved directly, in the body's frame: a semismooth Newton method on
the natural residual, its linear systems by GMRES preconditioned along the motion.

In the body's frame the material streams backwards through the contact, one cell per step of the transient
run it is the steady state of (steps_per_cell = 1: petroll.solver.friction). The slip of a step is
S = W + u - u' with u = c K q and u' the same material's displacement a step earlier, read from the cells
ahead: u' = S_1 u, (S_1 v)_t = v_{t+1} (first order, CONTACT's), or the second-order upwind difference
S = W + (3 u_t - 4 u_{t+1} + u_{t+2})/2, written as (3/2) [W' + u - S_2 u] with W' = 2 W/3 and
S_2 v = (4 v_{t+1} - v_{t+2})/3 (``order`` 2, the default: second order in the rolled step, where the first
order's slip sits half a cell behind its traction). The convolution commutes with the shift (the tractions
vanish beyond the window), so s = b + H (q - S_k q) (+ w, a uniform slip found under force control) in the
units of petroll.solver.tangential (H = K / K_00, tractions over the largest bound, slips over the slip that
bound causes on its own cell), and the steady tractions solve

    F(q) = q - P(q - s(q)) = 0        (P: projection onto the friction disks; the natural residual)

with sum q = F_hat held under force control. F is piecewise smooth: Newton's step on the current stick
cells (|q - s| < g: dF = ds) and slip cells (dF = dq - gamma (I - n n^T)(dq - ds), n the unit vector of
q - s and gamma = g / |q - s|), with a backtracking line search on |F|^2. Its linear systems are solved by
restarted GMRES (right preconditioned, classical Gram-Schmidt twice, every reduction over the communicator)
with the preconditioner (I - S_k)_II^-1 M_II on the stick cells I (M the inverse block circulant of the
kernel, (I - S_k)_II^-1 solved from the front of each run of stick cells along the motion: the operator's
exact inverse if the convolution and the shift commuted on I, so GMRES only resolves the runs' ends) and the
identity elsewhere; under force control the uniform slip's row and column are eliminated exactly with the
preconditioner's response to a uniform slip on the stick cells.

Viscoelastic bodies (``hereditary``): the displacement is u = c K L q, L the integrator's response along the
motion (:class:`Hereditary`: the material now at cell t was at t + k k steps ago, so (L q)_t = sum_k h_k
q_(t+k), h its pulse response over h_0), so s = b + H (I - S_k) L q (L and S_k, both triangular Toeplitz
along the lines, commute); the window reaches behind the contact over the wake L spreads the tractions into,
and the preconditioner applies L^-1 after the run sums.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.linalg
from mpi4py import MPI

from petroll.errors import SolverError
from petroll.solver.memory import Lines
from petroll.solver.partition import RowPartition
from petroll.solver.tangential import project


def gmres(matvec, precondition, rhs: np.ndarray, comm: MPI.Comm, tol: float, restart: int = 40,
          max_iterations: int = 400, replicated: int = 0) -> tuple[np.ndarray, int]:
    """x with |matvec(x) - rhs| <= tol |rhs| (2-norm over every rank's entries): restarted GMRES, right
    preconditioned (x = precondition(y)), classical Gram-Schmidt applied twice (one reduction each), the
    least-squares problem updated by Givens rotations. The last ``replicated`` entries of every vector
    are the same on every rank (counted once). Returns x and the operator applications (the best x
    found after ``max_iterations`` if not converged)."""
    n_local = rhs.size - replicated

    def dots(basis: np.ndarray, v: np.ndarray) -> np.ndarray:
        # einsum, not BLAS: a threaded BLAS's small products slow down 5x on a loaded node (measured)
        out = np.einsum("ij,j->i", basis[:, :n_local], v[:n_local])
        comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
        return out + np.einsum("ij,j->i", basis[:, n_local:], v[n_local:])

    x = np.zeros_like(rhs)
    r = rhs.copy()
    beta = math.sqrt(max(float(dots(r[None], r)[0]), 0.0))
    target = tol * beta
    applications = 0
    while beta > target and applications < max_iterations:
        basis = np.zeros((restart + 1, rhs.size))
        basis[0] = r / beta
        zs = np.zeros((restart, rhs.size))
        h = np.zeros((restart + 1, restart))
        cs, sn = np.zeros(restart), np.zeros(restart)
        e = np.zeros(restart + 1)
        e[0] = beta
        k = 0
        while k < restart:
            zs[k] = precondition(basis[k])
            w = matvec(zs[k])
            applications += 1
            for _ in range(2):
                c = dots(basis[: k + 1], w)
                w = w - np.einsum("i,ij->j", c, basis[: k + 1])
                h[: k + 1, k] += c
            h[k + 1, k] = math.sqrt(max(float(dots(w[None], w)[0]), 0.0))
            for i in range(k):  # the previous rotations, then this column's
                h[i, k], h[i + 1, k] = cs[i] * h[i, k] + sn[i] * h[i + 1, k], -sn[i] * h[i, k] + cs[i] * h[i + 1, k]
            radius = math.hypot(h[k, k], h[k + 1, k])
            cs[k], sn[k] = (1.0, 0.0) if radius == 0 else (h[k, k] / radius, h[k + 1, k] / radius)
            breakdown = h[k + 1, k] <= 1e-14 * beta
            if not breakdown:
                basis[k + 1] = w / h[k + 1, k]
            h[k, k], h[k + 1, k] = radius, 0.0
            e[k], e[k + 1] = cs[k] * e[k], -sn[k] * e[k]
            k += 1
            if abs(e[k]) <= target or breakdown or applications >= max_iterations:
                break
        y = _back_substitute(h[:k, :k], e[:k])
        x = x + np.einsum("i,ij->j", y, zs[:k])
        if abs(e[k]) <= target or breakdown or applications >= max_iterations:
            break  # converged by the recurrence's residual (exact but for round-off), or no better x
        r = rhs - matvec(x)  # a restart: the true residual
        applications += 1
        beta = math.sqrt(max(float(dots(r[None], r)[0]), 0.0))
    return x, applications


def _back_substitute(upper: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """y with upper y = rhs for an upper-triangular matrix (a zero pivot's unknown set to 0), without LAPACK
    (whose threads slow small solves on a loaded node)."""
    k = len(rhs)
    y = np.zeros(k)
    for i in range(k - 1, -1, -1):
        pivot = upper[i, i]
        y[i] = 0.0 if pivot == 0 else (rhs[i] - upper[i, i + 1 :] @ y[i + 1 :]) / pivot
    return y


class Hereditary:
    """The integrator's steady response along the motion on ``lines`` (petroll.solver.memory.Lines of a
    window): the state machine (h0, s1, M, c) of petroll.solver.history.state_space, a traction pulse giving
    h0 on its own step and h_k = c M^(k-1) s1 k steps later (the material arrives from the cells ahead).
    :meth:`__call__` is L v over h0, (L v)_t = v_t + sum_k (h_k/h0) v_(t+k) along each line: a unit upper
    triangular Toeplitz matrix of the line's length, whose inverse (:meth:`inverse`) is one too (its first
    row found once); both applied as correlations along the lines by zero-padded FFTs."""

    def __init__(self, machine, lines):
        h0, s1, M, c = machine
        n = lines.n_along
        h, state = np.zeros(n), np.asarray(s1, dtype=float)
        h[0] = 1.0
        for k in range(1, n):
            h[k] = float(np.asarray(c, dtype=float) @ state) / h0
            state = np.asarray(M, dtype=float) @ state
        inverse = scipy.linalg.solve_triangular(scipy.linalg.toeplitz(np.eye(n)[0], h), np.eye(n)[0], trans="T")
        self.lines, self.n, self.size = lines, n, scipy.fft.next_fast_len(2 * n, real=True)
        self.spectra = [scipy.fft.rfft(f, self.size) for f in (h, inverse)]

    def _apply(self, spectrum: np.ndarray, v: np.ndarray) -> np.ndarray:
        out = np.empty_like(v)
        for k, field in enumerate(v):  # (L v)_t = sum_k h_k v_(t+k): a convolution of the reversed lines
            lines = self.lines.from_grid(field)[:, ::-1]
            product = scipy.fft.rfft(lines, self.size, axis=1) * spectrum
            out[k] = self.lines.to_grid(scipy.fft.irfft(product, self.size, axis=1)[:, : self.n][:, ::-1])
        return out

    def __call__(self, v: np.ndarray) -> np.ndarray:
        return self._apply(self.spectra[0], v)

    def inverse(self, v: np.ndarray) -> np.ndarray:
        return self._apply(self.spectra[1], v)


@dataclass
class _Point:
    """The natural residual and its pieces at one iterate (window cells, this rank's rows)."""

    q: np.ndarray  # (m, rows, ny)
    w: np.ndarray  # (m,) uniform slip (force control)
    s: np.ndarray  # the slip b + H (q - S q) + w
    residual: np.ndarray  # F = q - P(q - s)
    force: np.ndarray  # (m,) sum q - total (0 without force control)
    stick: np.ndarray  # (rows, ny)
    slip: np.ndarray
    n: np.ndarray  # unit vector of q - s on slip cells
    gamma: np.ndarray  # g / |q - s| on slip cells
    merit: float  # |F|^2 + |force|^2
    largest: float  # max |F|, max |force| / capacity


class SteadyNewton:
    """The steady problem of the module docstring on a window of cells (arrays (m, local rows, ny) in the
    window's even row split over ``comm``): ``apply(v)`` H v, ``precondition(v)`` M v, ``g`` (rows, ny) the
    bounds, ``b`` the rigid slip, motion along ``axis`` with ``sign``, ``order`` 1 or 2, ``total`` the
    force held (m-vector, or None), all in the scaled units of petroll.solver.tangential; ``hereditary``: a
    viscoelastic material's state machine (:class:`Hereditary`; None: elastic)."""

    def __init__(self, apply, precondition, g, b, comm, nx: int, axis: int, sign: int, order: int,
                 total=None, hereditary=None):
        self.apply, self.precondition, self.g, self.b, self.comm = apply, precondition, g, b, comm
        self.m, self.order, self.total = b.shape[0], order, total
        self.inside = g > 0
        self.lines = Lines(RowPartition(nx, comm.size), g.shape[1], axis, sign, 0, comm)
        self.hereditary = None if hereditary is None else Hereditary(hereditary, self.lines)
        self.capacity = comm.allreduce(float(g.sum()), op=MPI.SUM)
        self.applications = 0
        self.k = 0 if total is None else self.m  # entries of the uniform slip in a packed vector

    # -- along the motion ---------------------------------------------------------------------------------
    def operator(self, v: np.ndarray) -> np.ndarray:
        """H (I - S_k) L v: the slip's response to the tractions v (L = I: elastic)."""
        d = v - self.shifted(v)
        return self.apply(d if self.hereditary is None else self.hereditary(d))

    def shifted(self, v: np.ndarray) -> np.ndarray:
        """S_k v: each cell's value read from the cells ahead of it (0 beyond the window)."""
        out = np.empty_like(v)
        for c, field in enumerate(v):
            lines = self.lines.from_grid(field)
            ahead = np.zeros_like(lines)
            ahead[:, :-1] = lines[:, 1:]
            if self.order == 2:
                ahead *= 4.0 / 3.0
                ahead[:, :-2] -= lines[:, 2:] / 3.0
            out[c] = self.lines.to_grid(ahead)
        return out

    def run_solve(self, f: np.ndarray, on: np.ndarray) -> np.ndarray:
        """An approximation of (I - S_k)_II^-1 f on the cells I where ``on`` (f elsewhere), I's runs along the
        motion solved from their fronts: order 1 exactly (each cell's sum of f over itself and the cells
        ahead of it in its run); order 2 as (I - S_1/3)^-1 (I - S_1)^-1 on the runs ((I - S_2) = (I - S_1)
        (I - S_1/3)), the first factor's series cut after S_1^4/81."""
        mask = self.lines.from_grid(on.astype(float)) > 0.5
        n = mask.shape[1]
        index = np.broadcast_to(np.arange(n), mask.shape)
        # the first cell at or ahead of t that is not in a run (n: none): where t's run's sum stops
        stop = np.minimum.accumulate(np.where(mask, n, index)[:, ::-1], axis=1)[:, ::-1]
        out = np.empty_like(f)
        for c, field in enumerate(f):
            lines = self.lines.from_grid(field)
            total = np.zeros((lines.shape[0], n + 1))
            total[:, :n] = np.cumsum(np.where(mask, lines, 0.0)[:, ::-1], axis=1)[:, ::-1]
            sums = total[:, :n] - np.take_along_axis(total, stop, axis=1)
            if self.order == 2:
                term, series = sums, sums.copy()
                for k in range(1, 5):
                    ahead = np.zeros_like(term)
                    ahead[:, :-1] = term[:, 1:]
                    term = np.where(mask, ahead, 0.0) / 3.0
                    series += term
                sums = series
            out[c] = self.lines.to_grid(np.where(mask, sums, lines))
        return out

    # -- a first guess: Kalker's simplified theory -------------------------------------------------------
    def simplified(self) -> tuple[np.ndarray, np.ndarray]:
        """A cold start (q, w): Kalker's simplified theory (FASTSIM's marching) on the window, the operator
        replaced by a local flexibility, H v ~ v / lam: from the front of each line along the motion
        q_t = P(a1 q_t+1 + a2 q_t+2 - (b + w)_t lam) (the disk's projection; a = (1, 0) or (4/3, -1/3)),
        lam fitted by least squares to the operator's response to the unbounded march (one application);
        under force control w found so that sum q = total (Newton on the marches, which need no
        convolution)."""
        q_free = self._march(-self.b, None)
        v = self.operator(q_free)
        self.applications += 1
        vb, vv = self._sum_pair(np.vdot(v, self.b), np.vdot(v, v))
        lam = -vv / vb if vb < 0 else 1.0  # b + v / lam ~ 0: the flexibility lam = 1/(its fit)
        lam = 1.0 / lam if lam > 0 else 1.0
        w = np.zeros(self.m)
        if self.total is None:
            return self._march(-self.b * lam, self.g), w
        for _ in range(30):
            q = self._march(-(self.b + w[:, None, None]) * lam, self.g)
            error = self.sums(q) - self.total
            if np.abs(error).max() <= 1e-12 * max(self.capacity, 1e-300):
                break
            jac = np.empty((self.m, self.m))
            h = 1e-6 * (1.0 + np.abs(w).max())
            for k in range(self.m):
                dw = w.copy()
                dw[k] += h
                jac[:, k] = (self.sums(self._march(-(self.b + dw[:, None, None]) * lam, self.g)) - self.total
                             - error) / h
            step = np.linalg.lstsq(jac, -error, rcond=1e-12)[0]
            w = w + step
        return q, w

    def _sum_pair(self, a: float, b: float) -> tuple[float, float]:
        out = np.array([a, b], dtype=float)
        self.comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
        return float(out[0]), float(out[1])

    def _march(self, source: np.ndarray, bound: np.ndarray | None) -> np.ndarray:
        """q from the front of each line: q_t = P(a1 q_t+1 + a2 q_t+2 + source_t) on the contact cells (the
        disks of ``bound``; None: unbounded), 0 elsewhere."""
        coefficients = (1.0, 0.0) if self.order == 1 else (4.0 / 3.0, -1.0 / 3.0)
        inside = self.lines.from_grid(self.inside.astype(float)) > 0.5
        src = np.stack([self.lines.from_grid(f) for f in source])
        g = None if bound is None else self.lines.from_grid(bound)
        q = np.zeros_like(src)
        n = src.shape[2]
        for t in range(n - 1, -1, -1):
            value = src[:, :, t].copy()
            if t + 1 < n:
                value += coefficients[0] * q[:, :, t + 1]
            if t + 2 < n:
                value += coefficients[1] * q[:, :, t + 2]
            if g is not None:
                norm = np.sqrt((value * value).sum(axis=0))
                value *= np.where(norm > g[:, t], g[:, t] / np.where(norm > 0, norm, 1.0), 1.0)
            q[:, :, t] = np.where(inside[:, t], value, 0.0)
        return np.stack([self.lines.to_grid(f) for f in q])

    # -- the residual and its Newton systems -----------------------------------------------------------
    def point(self, q: np.ndarray, w: np.ndarray) -> _Point:
        self.applications += 1
        s = self.b + self.operator(q) + w[:, None, None]
        z = q - s
        norm = np.sqrt((z * z).sum(axis=0))
        stick = self.inside & (norm < self.g)
        slip = self.inside & ~stick
        n = np.where(slip, z / np.where(slip, norm, 1.0), 0.0)
        gamma = np.where(slip, self.g / np.where(slip, norm, 1.0), 0.0)
        residual = q - project(z, self.g)
        force = np.zeros(self.m) if self.total is None else self.sums(q) - self.total
        local = np.array([float((residual * residual).sum()), float(np.abs(residual).max(initial=0.0))])
        merit = self.comm.allreduce(local[0], op=MPI.SUM) + float(force @ force)
        largest = max(self.comm.allreduce(local[1], op=MPI.MAX),
                      float(np.abs(force).max(initial=0.0)) / max(self.capacity, 1e-300))
        return _Point(q, w, s, residual, force, stick, slip, n, gamma, merit, largest)

    def sums(self, v: np.ndarray) -> np.ndarray:
        out = np.array(v.sum(axis=(1, 2)), dtype=float)
        self.comm.Allreduce(MPI.IN_PLACE, out, op=MPI.SUM)
        return out

    def pack(self, q: np.ndarray, w: np.ndarray) -> np.ndarray:
        return np.concatenate([q.ravel(), w]) if self.k else q.ravel().copy()

    def unpack(self, v: np.ndarray):
        k = self.k
        q = (v[:-k] if k else v).reshape(self.b.shape)
        return q, (v[-k:] if k else np.zeros(self.m))

    def jacobian(self, at: _Point):
        def matvec(v: np.ndarray) -> np.ndarray:
            dq, dw = self.unpack(v)
            ds = self.operator(dq) + dw[:, None, None]
            e = dq - ds
            tangential = e - at.n * (at.n * e).sum(axis=0) if self.m == 2 else 0.0 * e
            out = np.where(at.stick, ds, np.where(at.slip, dq - at.gamma * tangential, dq))
            return self.pack(out, self.sums(np.where(self.inside, dq, 0.0)) if self.k else dw)

        return matvec

    def preconditioner(self, at: _Point):
        def stick_part(r: np.ndarray) -> np.ndarray:
            y = self.run_solve(self.precondition(np.where(at.stick, r, 0.0)), at.stick)
            return y if self.hereditary is None else np.where(at.stick, self.hereditary.inverse(y), y)

        uniform = None
        if self.k:  # the stick cells' response to a unit uniform slip, and its sums (m x m)
            uniform = [np.where(at.stick, stick_part(np.where(at.stick, e[:, None, None], 0.0)), 0.0)
                       for e in np.eye(self.m)]
            matrix = np.array([self.sums(u) for u in uniform]).T

        def apply(v: np.ndarray) -> np.ndarray:
            r, rw = self.unpack(v)
            y = np.where(at.stick, stick_part(r), r)
            if not self.k:
                return self.pack(y, rw)
            dw = np.linalg.solve(matrix, self.sums(np.where(self.inside, y, 0.0)) - rw)
            y = y - sum(c * u for c, u in zip(dw, uniform))
            return self.pack(y, dw)

        return apply

    GROWTH = 100.0
    """A full Newton step is taken while the merit |F|^2 stays below GROWTH times the largest of the last
    three iterates' (non-monotone: a step that changes many cells' sets from a cold start overshoots
    before it settles; measured on Carter's problem from q = 0: 8-13 iterations with full steps against
    8-19 with a monotone backtracking line search); beyond, the step is halved until the merit falls."""

    def solve(self, q: np.ndarray | None, w: np.ndarray, tol: float, max_newton: int = 100):
        """Newton's iterations from (q, w) (q None: the simplified theory's) until max |F| <= tol (and
        |sum q - total| <= tol sum g). Returns the last point and the Newton iterations."""
        if q is None:
            q, w = self.simplified()
        at = self.point(q, w)
        recent, forcing = [at.merit], 0.1
        for iteration in range(max_newton + 1):
            if at.largest <= tol:
                return at, iteration
            if iteration == max_newton:
                break
            if iteration:  # Eisenstat and Walker's choice 2: 0.9 (|F_k|/|F_k-1|)^2, safeguarded
                forcing = min(0.1, max(0.9 * at.merit / recent[-2], 0.9 * forcing**2 if forcing > 0.1 else 0.0))
            forcing = max(forcing, 0.5 * tol / max(at.largest, 1e-300))
            step, apps = gmres(self.jacobian(at), self.preconditioner(at), -self.pack(at.residual, at.force),
                               self.comm, forcing, replicated=self.k)
            self.applications += apps
            dq, dw = self.unpack(step)
            trial = self.point(at.q + dq, at.w + dw)
            alpha = 1.0
            while trial.merit > self.GROWTH * max(recent[-3:]) or (alpha < 1 and trial.merit > at.merit):
                alpha *= 0.5
                if alpha < 1e-6:
                    break
                trial = self.point(at.q + alpha * dq, at.w + alpha * dw)
            at = trial
            recent.append(at.merit)
        raise SolverError(f"steady rolling with friction did not converge within {max_newton} Newton "
                          f"iterations (natural residual {at.largest:.3g}, tolerance {tol:g})")
