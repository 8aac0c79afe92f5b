"""Steady rolling at constant velocity solved directly in the body frame (no transient): a fixed point over
elastic contact problems (:class:`SteadySolve`), its memory along the motion in petroll.solver.memory.

In the body frame the displacement is w = A W(p), W the memory of the scene's time integrator along the
motion (petroll.solver.memory; with one step per cell crossed, exactly the state the transient run
converges to). The fixed point splits W(p) = Jc p + (W - Jc) p, Jc the compliance at the time the material
takes to cross the contact: each iteration solves the elastic QP of compliance Jc with the known height
Z + A (W - Jc) x (plus the far wake of x), x the iterate the memory is lagged from; the QP's pressure g(x)
is the fixed point's map. Its Jacobian on the contact cells I is -(Jc A_II)^-1 A_I (W - Jc), so
I - g' = (Jc A_II)^-1 (A W)_II ~ W_II / Jc when (A W)_II is approximated by A_II W_II (the wake's own push,
A from outside I, left out). The residual g(x) - x is therefore mapped by Jc W_II^-1 on I (no convolution
with A) and kept elsewhere: a Newton-like step, Anderson-mixed.

Distributed: every rank holds only its rows of the grid and of the wake-extended grid (the latter's
convolution is petroll's distributed FFT) and its lines along the motion (petroll.solver.memory.Lines);
no rank holds a whole field. Every decision (the QPs' tolerance, the stop, the mixing coefficients) is
computed once, from reduced values, and broadcast from rank 0, so that all ranks take the same path.
"""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from petroll.errors import SceneError, SolverError
from petroll.model.clock import steady_dt
from petroll.model.materials import Prony
from petroll.solver.memory import FarWake, Lines, Memory, memory_kernel, memory_steps, pulse_response

WAKE_CELLS = 2**22
"""The longest wake (cells behind the grid) a steady solve keeps: 30 V tau up to V tau/a ~ 1e4 at a/dx = 10;
beyond, a wake of relative weight ~ (a / V tau) E1(WAKE_CELLS dx / V tau) is dropped."""

MEMORY_STEPS = 2**24
"""The most integrator steps a steady solve's memory spans (its pulse response: 8 bytes a step, a few
times over while it is made); more only with a time step far below the material's relaxation times."""


def steady_step(scene) -> tuple[np.ndarray, float]:
    """The constant velocity (m/s, taken at t = 0) of a steady solve and its integrator's step dt (s): [time]
    dt, else the time to cross a cell over [time] steps_per_cell (default 1; petroll.model.clock.steady_dt).
    SceneError for a material that is not a Prony series or a zero velocity."""
    if not isinstance(scene.material, Prony):
        raise SceneError(scene.source, "[material] model", "tabulated",
                         'the direct steady solve needs a Prony series: use [time] mode = "transient"')
    velocity = np.asarray(scene.velocity(0.0), dtype=float)
    speed = float(np.hypot(*velocity))
    if speed == 0:
        raise SceneError(scene.source, "[motion] velocity", list(velocity),
                         "the steady solve needs a non-zero velocity")
    return velocity, steady_dt(scene)


class SteadySolve:
    """The steady rolling state of ``scene`` at its constant velocity, by the fixed point of the module
    docstring, with the contact ``solver`` (its grid rows, TAO objects and operator); collective over its
    comm. A steady solve of petroll.solver.steady_state (``velocity``, ``direction``, ``speed``,
    ``profile``, ``iterations``, :meth:`solve`).

    ``tol``: relative change of the memory field (scaled by Jc p_max) at which the fixed point stops; the
    QPs are solved to 1e-4 of the memory's last change until then (at most 1e-3, at least [solver] tol),
    the last ones to max([solver] tol, tol / 100); the memory is kept until the material has relaxed to
    tol / 100. (QPs solved to 1 % of the change stall the fixed point on fine grids: runs/sphere.toml on
    2048 x 1024 cells takes 172 iterations at tol 1e-8 that way, 19 this way; docs/benchmarks.md.)
    ``steady``: stop also once force and resisting force change by at most ``steady`` x force from one
    iteration to the next, once the QPs are solved to steady / 3 or tighter (looser QPs can agree by
    chance). The wake behind the grid is kept up to 30 V tau (or as far as the memory reaches): cell by
    cell on the grid extended behind by up to 2 grid lengths (line contact: 4), in blocks beyond
    (FarWake; 3-D half-spaces only)."""

    def __init__(self, scene, solver, tol: float, steady: float | None = None):
        self.scene, self.solver, self.comm, self.tol, self.steady = scene, solver, solver.comm, tol, steady
        g = scene.grid
        velocity, dt = steady_step(scene)
        self.speed = speed = float(np.hypot(*velocity))
        axis = 0 if abs(velocity[1]) == 0 else 1
        if abs(velocity[1 - axis]) > 0:
            raise SceneError(scene.source, "[motion] velocity", list(velocity),
                             "the steady solve needs a non-zero velocity along X or Y")
        self.direction = velocity / speed
        self.velocity = speed * self.direction
        sign = 1 if velocity[axis] > 0 else -1
        cell = g.dx if axis == 0 else g.dy
        self.x, self.y = g.x[solver.r0 : solver.r1, None], g.y[None, :]
        sx, sy = scene.position
        self.profile = scene.body.height(self.x - sx, self.y - sy)
        self.slopes = scene.body.slope(self.x - sx, self.y - sy)
        self.compliance = self._crossing_compliance()
        self._memory(dt, cell, axis, sign)
        self.extended = solver.influence.window(*self.lines.extended)
        self.iterations = 0

    def _memory(self, dt: float, cell: float, axis: int, sign: int) -> None:
        """The memory along the motion (its kernel, lines, far wake). It lasts until the material has relaxed
        below 1 % of tol (c = V dt / cell: cells crossed per step), at most 30 V tau behind the grid: cell
        by cell on the extended grid, in blocks beyond."""
        scene, material, g = self.scene, self.scene.material, self.scene.grid
        c = self.speed * dt / cell
        decay = memory_steps(material, scene.solver.integrator, dt, 0.01 * self.tol)
        needed = math.ceil(min(30 * self.speed * material.longest_time / cell, decay * c, WAKE_CELLS))
        n_along = (g.nx, g.ny)[axis]
        behind = min(needed, 4 * n_along if g.line else max(2 * n_along, 64))
        far = needed - behind if not g.line and scene.layer is None else 0  # a layer's fades within reach
        cells = n_along + behind + far + 1
        steps = min(decay, math.ceil(cells / c) + 1)
        if steps > MEMORY_STEPS:
            key = "[time] dt" if scene.time.dt else "[time] steps_per_cell"
            raise SceneError(scene.source, key, scene.time.dt or scene.time.steps_per_cell,
                             f"the steady memory would span {steps:.3g} steps of {dt:.3g} s (the material's "
                             f"relaxation, {material.longest_time:g} s, to {0.01 * self.tol:g}); at most "
                             f"{MEMORY_STEPS} are kept: use a larger [time] dt or fewer steps_per_cell")
        kernel = memory_kernel(pulse_response(material, scene.solver.integrator, dt, steps), c, cells)
        self.lines = Lines(self.solver.rows, g.ny, axis, sign, behind, self.comm)
        self.memory = Memory(kernel, n_along, behind, self.lines.n_across, self.solver.influence.workers)
        self.far_wake = None
        if far > 0:
            self.far_wake = FarWake(kernel, self.lines, behind, far, cell, g.dy if axis == 0 else g.dx)

    def _crossing_compliance(self) -> float:
        """Jc: J at the time the material takes to cross a Hertz half-width (relaxed when rolling slowly,
        instantaneous when fast); the rest of the operator is the memory, lagged."""
        scene = self.scene
        radius, material = scene.body.radius_hint, scene.material
        if scene.penetration is not None:
            half_width = math.sqrt(radius * float(scene.penetration(0.0)))
        else:
            half_width = (0.75 * float(scene.load(0.0)) * radius * material.Jinf) ** (1 / 3)
        return float(material(half_width / self.speed))

    # -- the fixed point ---------------------------------------------------------------------------------
    def solve(self, start: tuple[np.ndarray, float] | None = None, max_iterations: int = 500):
        """The steady state: the last QP's StepSolution (pressure on this rank's grid rows) and the surface
        displacement w = A W(p) (m, this rank's rows). ``start``: a first guess (the grid's pressure, Pa,
        whole or this rank's rows, and its penetration, m); else, under penetration control in 3-D,
        Hertz's pressure for Jc as the first QP's warm start. SolverError after ``max_iterations``
        iterations; the solver's tolerance is left as it was in every case. The solution's iterations and
        applications are those of every QP solved."""
        solver, lines = self.solver, self.lines
        work = list(solver.work)
        x, warm, delta = self._first_guess(start)
        mixer = Anderson(self.comm)
        memory = self.lagged(x)
        tolerance, final = solver.tol, max(solver.tol, min(0.01 * self.tol, 1e-3))  # the last QPs' tolerance
        change, scale, previous, solution = math.inf, 1.0, None, None
        try:
            for self.iterations in range(1, max_iterations + 1):
                # inexact QPs while the memory is far from converged: 1e-4 of its last change, at least final
                solver.tol = max(final, min(1e-3, 1e-4 * change / scale))
                solution = self.contact(self.profile + self.displacement(memory, x), warm, delta)
                warm, delta = solution.pressure, solution.delta
                p = lines.from_grid(solution.pressure)
                change, scale = self._reduce_max(np.abs(self.lagged(p) - memory), self.compliance * p)
                forces = self.forces(solution.pressure)
                if self._agreed(change <= self.tol * scale and solver.tol == final
                                or self._steady(forces, previous, solver.tol)):
                    break
                previous = forces
                x = mixer.next(x, x + self.newton_step(p - x, p > 0))
                memory = self.lagged(x)
            else:
                raise SolverError(f"the steady solve did not converge within {max_iterations} iterations")
        finally:
            solver.tol = tolerance
        solution.iterations, solution.applications = solver.work[0] - work[0], solver.work[1] - work[1]
        return solution, self.displacement(self.memory.extended(p), p)

    def _first_guess(self, start):
        """(x on the lines, the first QP's warm start on the grid rows or None, the penetration or None)."""
        solver, scene, comm = self.solver, self.scene, self.comm
        g = scene.grid
        if start is not None:
            rows = solver.own_rows(start[0])
            return self.lines.from_grid(rows), rows, start[1]
        zero = self.lines.from_grid(np.zeros(solver.local_shape))
        if scene.penetration is None or g.line:
            return zero, None, None
        lowest = comm.allreduce(float(np.min(self.profile, initial=np.inf)), op=MPI.MIN)
        radius, penetration = scene.body.radius_hint, float(scene.penetration(0.0))
        load = 4 * math.sqrt(radius) * max(penetration - lowest, 0.0) ** 1.5 / (3 * self.compliance)
        return zero, solver.hertz_pressure(self.profile, self.compliance, load, radius, penetration), None

    def lagged(self, x: np.ndarray) -> np.ndarray:
        """(W - Jc) x on the extended lines, x on the grid's lines (zero behind the grid)."""
        out = self.memory.extended(x)
        out[:, self.lines.behind :] -= self.compliance * x
        return out

    def displacement(self, memory: np.ndarray, x: np.ndarray) -> np.ndarray:
        """A ``memory`` (on the extended lines) plus the far wake of x (on the grid's lines): the height it
        adds on this rank's grid rows (m)."""
        lines = self.lines
        u = lines.inside(self.extended(lines.to_extended(memory)))
        return u if self.far_wake is None else u + self.far_wake(x)

    def contact(self, height: np.ndarray, warm: np.ndarray | None, delta: float | None):
        """The elastic QP of compliance Jc on the known ``height`` (this rank's rows), at the scene's
        penetration or load (``delta``: the last penetration found, a guess for load control)."""
        scene, solver = self.scene, self.solver
        if scene.penetration is not None:
            return solver.solve_penetration(height, self.compliance, float(scene.penetration(0.0)), warm)
        return solver.solve_load(height, self.compliance, float(scene.load(0.0)), scene.body.radius_hint,
                                 delta, warm)

    def newton_step(self, residual: np.ndarray, contact: np.ndarray) -> np.ndarray:
        """Jc W_II^-1 on the contact cells I, the identity elsewhere (fields on the grid's lines)."""
        return np.where(contact, self.compliance * self.memory.solve_restricted(residual, contact), residual)

    def forces(self, pressure: np.ndarray) -> tuple[float, float]:
        """(normal force, resisting force along the motion), N, of the pressure on this rank's grid rows
        (summed over the ranks)."""
        slope = self.slopes[0] * self.direction[0] + self.slopes[1] * self.direction[1]
        sums = np.array([pressure.sum(), (pressure * slope).sum()]) * self.scene.grid.cell_area
        self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        return float(sums[0]), float(sums[1])

    def dissipated(self, pressure: np.ndarray) -> None:
        """None: a rolling body's resisting force is the pressure's on its slope (:meth:`forces`), and
        the dissipation that force's power (the steady state's protocol, petroll.solver.steady_state)."""
        return None

    def _steady(self, forces, previous, qp_tol: float) -> bool:
        """The ``steady`` stop: forces changed by at most steady x force, with QPs solved to steady / 3."""
        return (self.steady is not None and previous is not None and qp_tol <= self.steady / 3
                and all(abs(now - then) <= self.steady * forces[0] for now, then in zip(forces, previous)))

    def _reduce_max(self, *fields) -> list[float]:
        """The largest value of each field over all ranks."""
        values = np.array([float(f.max(initial=0.0)) for f in fields])
        self.comm.Allreduce(MPI.IN_PLACE, values, op=MPI.MAX)
        return list(values)

    def _agreed(self, decision: bool) -> bool:
        """Rank 0's decision, on every rank."""
        return bool(self.comm.bcast(bool(decision), root=0))


class Anderson:
    """Anderson mixing of a fixed point x = g(x) keeping ``depth`` differences (type II), on vectors split
    over ``comm`` (each rank passes its part). The mixing coefficients solve min |f - dF gamma| (f = g(x) -
    x, dF its last differences) by least squares, the minimum-norm gamma where differences are degenerate
    (two equal residuals: a zero column, gamma 0 for it): each rank reduces its rows of [dF f] to a
    triangle (QR), rank 0 solves the stacked triangles (TSQR) and broadcasts gamma. The differences are
    kept only where some x or g(x) so far was non-zero (a contact's cells, not the grid's)."""

    def __init__(self, comm: MPI.Comm = MPI.COMM_SELF, depth: int = 6):
        self.comm, self.depth = comm, depth
        self.support = np.zeros(0, dtype=np.intp)  # flat indices where some x or g(x) was non-zero
        self.last, self.df, self.dg = None, [], []  # on the support

    def next(self, x: np.ndarray, gx: np.ndarray) -> np.ndarray:
        self._grow(np.flatnonzero((x != 0) | (gx != 0)))
        f = gx.ravel()[self.support] - x.ravel()[self.support]
        g = gx.ravel()[self.support]
        if self.last is not None:
            self.df.append(f - self.last[0])
            self.dg.append(g - self.last[1])
            if len(self.df) > self.depth:
                self.df.pop(0)
                self.dg.pop(0)
        self.last = (f, g)
        if not self.df:
            return gx
        columns = np.column_stack([*self.df, f])
        triangle = np.linalg.qr(columns, mode="r") if len(columns) else columns
        stacked = self.comm.gather(triangle, root=0)
        gamma = None
        if self.comm.rank == 0:
            rows = np.vstack(stacked)
            r = np.linalg.qr(rows, mode="r") if len(rows) else rows
            gamma = np.linalg.lstsq(r[:, :-1], r[:, -1], rcond=None)[0]
        gamma = self.comm.bcast(gamma, root=0)
        out = np.array(gx, dtype=float, order="C")
        out.reshape(-1)[self.support] -= sum(c * d for c, d in zip(gamma, self.dg))
        return out

    def _grow(self, cells: np.ndarray) -> None:
        """Add ``cells`` (flat indices) to the support; the kept vectors are 0 on the new cells."""
        grown = np.union1d(self.support, cells)
        if len(grown) == len(self.support):
            return
        where = np.searchsorted(grown, self.support)

        def spread(v: np.ndarray) -> np.ndarray:
            out = np.zeros(len(grown))
            out[where] = v
            return out

        self.df, self.dg = [spread(v) for v in self.df], [spread(v) for v in self.dg]
        self.last = None if self.last is None else (spread(self.last[0]), spread(self.last[1]))
        self.support = grown
