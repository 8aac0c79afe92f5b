"""The time loop: body path, preceding displacement from the history, one contact QP per step, outputs.

Rolling is solved in the material frame (formulation §5): the cells never move; at step n the body sits
at s(t_n) = position + integral of V, its profile is Z(X - sx, Y - sy), and the history fields stay on
their cells. The first step (t = 0) is the sudden start: the instantaneous (J(0)) elastic problem. A
scene without [time] is that single step.

All functions are collective over ``comm``: every rank calls them with the same scene.
"""

from __future__ import annotations

import math
import time as clock
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from petroll.solver.contact import BeyondReach, ContactSolver
from petroll.errors import SceneError, SolverError
from petroll.solver.history import make_history
from petroll.solver.influence import influence_operator
from petroll.solver.steady import Anderson, FarWake, SteadyMemory
from petroll.model.materials import Prony
from petroll.model.scene import Scene
from petroll.solver.wake import Wake
from petroll.solver.warm import WarmStart


WAKE_CELLS = 2**22
"""The longest wake (cells behind the grid) a steady solve keeps: 30 V tau up to V tau/a ~ 1e4 at a/dx = 10;
beyond, a wake of relative weight ~ (a / V tau) E1(WAKE_CELLS dx / V tau) is dropped."""


@dataclass
class StepRecord:
    """What one step reports (global values; formulation §6). Lengths m, forces N, pressures Pa."""

    step: int
    t: float
    sx: float
    sy: float
    delta: float
    force: float
    force_x: float  # rolling resistance along X: sum p dZ/dX dA, > 0 when it resists motion in +X
    force_y: float
    mu_r: float  # resisting force along the motion / normal force
    area: float
    p_max: float
    cop_x: float  # centre of pressure relative to the body
    cop_y: float
    lead: float  # leading and trailing patch edges along the motion, relative to the body
    trail: float
    dissipation: float  # power of the resisting force, W
    distance: float  # rolled path length so far
    iterations: int
    applications: int
    residual: float
    solve_time: float


class Simulation:
    """A scene being run on ``comm``: owns the contact solver, the history and the step clock.

    ``steps()`` runs it to its end, one step per iteration; ``t`` is the time of the newest step (s) and
    ``dt_next`` the length of the step after it (None: the run is over).
    """

    def __init__(self, scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD):
        self.scene, self.comm = scene, comm
        self.solver = ContactSolver(scene.grid, comm, tao_type=scene.solver.tao_type, tol=scene.solver.tol,
                                    layer=scene.layer)
        self.history = make_history(scene.material, scene.solver.integrator, self.solver.local_shape)
        g = scene.grid
        self.x = g.x[self.solver.r0 : self.solver.r1, None]
        self.y = g.y[None, :]
        self.direction = np.array([1.0, 0.0])
        self.records: list[StepRecord] = []
        self.pressure = np.zeros(self.solver.local_shape)
        self.warm = WarmStart(scene.grid, self.solver.rows, comm)
        self.wake = Wake(self.solver, scene.solver.history_cutoff)
        self.t, self.dt_next = 0.0, None
        self.steady_start = None  # a first guess for solve_steady: (whole-grid pressure in Pa, penetration in m)
        self.fixed_point_iterations = 0  # the last solve_steady's QPs (each with its extended-grid convolution)
        self._newest = None  # the newest step's (profile, v, J_eff, delta): what surface() needs (a steady
        # solve: (profile, w, None, delta))

    # -- the run ----------------------------------------------------------------------------------------
    def steps(self, t: float = 0.0, dts: Iterable[float] | None = None) -> Iterator[StepRecord]:
        """Solve the run's steps one per iteration, yielding each StepRecord, until the clock ends
        ([time] end or distance; a scene without [time] is one step) or the run is steady ([time] steady).

        A fresh simulation starts with the sudden start at t = 0. One restored from a checkpoint
        (``Checkpoint.restore``, which returns ``t``, the time of its last step) first yields that last
        record again, unsolved, then the steps after it. While a record is out, ``self.t`` is its time and
        ``self.dt_next`` the length of the next step (None: it is the last). ``dts``: the step lengths
        after the sudden start (s), instead of the scene's clock and steady stop. A step numbered beyond
        [time] max_steps raises SceneError. A scene with [time] mode = "steady" yields its one step,
        the steady state solved directly (:meth:`solve_steady`).
        """
        if self.scene.time.mode == "steady":
            record = self.solve_steady(tol=self.scene.solver.tol)
            self.t, self.dt_next = 0.0, None
            yield record
            return
        lengths = iter(dts) if dts is not None else None
        resumed, dt = bool(self.records), 0.0
        while True:
            record = self.records[-1] if resumed else self.step(t, dt)
            if lengths is not None:
                dt = next(lengths, None)
            else:
                dt = self.next_dt(t, record.distance)
                if dt is not None and self.steady():
                    dt = None
            if not resumed and record.step > self.scene.time.max_steps:
                raise SceneError(self.scene.source, "[time] max_steps", self.scene.time.max_steps,
                                 "the run needs more steps: raise max_steps or the time step")
            self.t, self.dt_next = t, dt
            yield record
            resumed = False
            if dt is None:
                return
            t += dt

    # -- the clock --------------------------------------------------------------------------------------
    def next_dt(self, t: float, distance: float) -> float | None:
        """Length of the step after time t (None: the run is over)."""
        tm = self.scene.time
        if tm.dt is None and tm.steps_per_cell is None:
            return None
        if tm.end is not None and t >= tm.end * (1 - 1e-12):
            return None
        if tm.distance is not None and distance >= tm.distance * (1 - 1e-12):
            return None
        speed = float(np.hypot(*self.scene.velocity(t)))
        if tm.dt is not None:
            dt = tm.dt
        else:
            scale = self.scene.velocity.peak()
            if scale == 0:
                raise SceneError(self.scene.source, "[time] steps_per_cell", tm.steps_per_cell,
                                 "needs a moving body: give [time] dt for a body at rest")
            cell = self.scene.grid.cell
            dt = cell / (tm.steps_per_cell * max(speed, 0.1 * scale))
        if tm.end is not None:
            dt = min(dt, tm.end - t)
        elif speed > 0:
            dt = min(dt, (tm.distance - distance) / speed * (1 + 1e-9))
        return dt

    # -- one step ---------------------------------------------------------------------------------------
    def step(self, t: float, dt: float) -> StepRecord:
        """Solve the step ending at time t (length dt; dt = 0 is the sudden start)."""
        scene, solver = self.scene, self.solver
        start = clock.perf_counter()
        sx, sy = np.asarray(scene.position) + scene.velocity.integral(t)
        profile = scene.body.height(self.x - sx, self.y - sy)
        v = self.history.preceding(dt)
        compliance = self.history.compliance(dt)
        warm = self.warm.guess(sx, sy)
        work = list(solver.work)
        if scene.penetration is not None:
            delta = float(scene.penetration(t))
            height = profile if v is None else profile + self.wake.displacement(v, profile, delta)
            solution = solver.solve_penetration(height, compliance, delta, warm)
        else:
            solution = self._solve_load(profile, v, compliance, float(scene.load(t)), warm)
        solution.iterations = solver.work[0] - work[0]  # all QPs of the step, a redone attempt's too
        solution.applications = solver.work[1] - work[1]
        self.history.advance(solution.pressure, dt)
        self.pressure = solution.pressure
        self._newest = (profile, v, compliance, solution.delta)
        self.warm.record(solution.pressure, sx, sy)
        elapsed = clock.perf_counter() - start
        velocity = np.asarray(scene.velocity(t), dtype=float)
        if np.hypot(*velocity) > 0:
            self.direction = velocity / np.hypot(*velocity)
        distance = self.records[-1].distance if self.records else 0.0
        if self.records:
            distance += float(np.hypot(sx - self.records[-1].sx, sy - self.records[-1].sy))
        record = self._diagnose(len(self.records), t, sx, sy, solution, velocity, distance, elapsed)
        self.records.append(record)
        return record

    def solve_steady(self, tol: float = 1e-10, max_iterations: int = 500,
                     start: tuple[np.ndarray, float] | None = None, steady: float | None = None) -> StepRecord:
        """The constant-velocity steady state solved directly in the body frame (petroll.solver.steady),
        recorded as step 0 at t = 0 with the body at [body] position. Velocity, penetration or load are
        taken at t = 0 and must be constant (the scene checks this for [time] mode = "steady"); the motion
        must be along X or Y. The memory is the scene's integrator at its time step: dt from [time] dt or
        steps_per_cell (default 1 step per cell), so that with one step per cell crossed this is exactly
        the state the transient run converges to. ``tol``: relative change of the memory field (scaled by
        the QP compliance x p_max) at which the fixed point stops; the QPs are solved to 1 % of the memory's
        last change until then (at least [solver] tol), the last ones to max([solver] tol, tol / 100).
        ``steady``: stop also once force and resisting force change by at most ``steady`` x force
        from one fixed-point iteration to the next (the [time] steady test of a transient run, applied to
        the iterations; petroll bench steady), once the QPs are solved to steady / 3 or tighter (looser
        QPs can agree by chance). ``start``: a first guess (the whole grid's pressure, Pa, and its
        penetration, m), e.g. a neighbouring steady state (continuation; default ``self.steady_start``;
        else, under penetration control in 3-D, Hertz's pressure for the QP compliance as the first QP's
        warm start). The fixed point's step is Newton-like (petroll.solver.steady); its iterations are
        kept in ``self.fixed_point_iterations``. The wake behind the grid up
        to 30 V tau is included (cell by cell up to 2 grid lengths, in blocks beyond: FarWake; line contact:
        up to 4 grid lengths). Collective: the memory is computed whole on every rank."""
        scene, solver, comm, g = self.scene, self.solver, self.comm, self.scene.grid
        material = scene.material
        if not isinstance(material, Prony):
            raise SceneError(scene.source, "[material] model", "tabulated",
                             'the direct steady solve needs a Prony series: use [time] mode = "transient"')
        began = clock.perf_counter()
        velocity = np.asarray(scene.velocity(0.0), dtype=float)
        speed = float(np.hypot(*velocity))
        axis = 0 if abs(velocity[1]) == 0 else 1
        if speed == 0 or abs(velocity[1 - axis]) > 0:
            raise SceneError(scene.source, "[motion] velocity", list(velocity),
                             "the steady solve needs a non-zero velocity along X or Y")
        sign = 1 if velocity[axis] > 0 else -1
        cell = g.dx if axis == 0 else g.dy
        dt = scene.time.dt or g.cell / ((scene.time.steps_per_cell or 1.0) * speed)
        self.direction = velocity / speed
        sx, sy = scene.position
        profile = scene.body.height(self.x - sx, self.y - sy)
        # the QPs' compliance: J at the time the material takes to cross a Hertz half-width (relaxed when
        # rolling slowly, instantaneous when fast); the rest of the operator is the memory, lagged
        if scene.penetration is not None:
            half_width = math.sqrt(scene.body.radius_hint * float(scene.penetration(0.0)))
        else:
            half_width = (0.75 * float(scene.load(0.0)) * scene.body.radius_hint * material.Jinf) ** (1 / 3)
        compliance = float(material(half_width / speed))
        # the wake behind the grid (no pressure, memory decaying over V tau) pushes on the contact too, up
        # to 30 V tau: the memory and its displacement are computed on the grid extended behind by
        # ``behind`` cells, the rest (3-D) lumped in blocks (FarWake)
        r0, r1 = solver.r0, solver.r1
        n_along = (g.nx, g.ny)[axis]
        needed = min(math.ceil(30 * speed * material.longest_time / cell), WAKE_CELLS)
        behind = min(needed, 4 * n_along if g.line else max(2 * n_along, 64))
        far = needed - behind if not g.line and scene.layer is None else 0  # a layer's kernel fades within reach
        shape = [g.nx, g.ny]
        shape[axis] += behind
        pad = [(0, 0), (0, 0)]
        pad[axis] = (behind, 0) if sign > 0 else (0, behind)
        inside = [slice(None), slice(None)]
        inside[axis] = slice(pad[axis][0], pad[axis][0] + n_along)
        extended = influence_operator(g, layer=scene.layer).window(*shape)
        memory = SteadyMemory(material, scene.solver.integrator, speed, dt, cell, axis, sign,
                              n_along + behind + far + 1)
        wake = None
        if far > 0:
            wake = FarWake(memory.kernel, n_along, (g.ny, g.nx)[axis], behind, far, cell,
                           g.dy if axis == 0 else g.dx, axis, sign)

        def lagged(field):  # (W - compliance) field on the extended grid
            return memory(field) - compliance * field

        def displacement(field, p):  # A field + the far wake of p on this rank's rows (field extended)
            u = extended(field)[tuple(inside)]
            return (u if wake is None else u + wake(p))[r0:r1]

        def newton_step(residual, contact):  # Jc W_II^-1 on the contact cells I, the identity elsewhere
            return np.where(contact, compliance * memory.solve_restricted(residual, contact), residual)

        # the fixed point is over the pressure x the memory is lagged from, m = lagged(x); its residual
        # g(x) - x (g: the QP's pressure) is mapped by newton_step, then Anderson-mixed
        p = np.zeros((g.nx, g.ny))
        mixer, work = Anderson(), list(solver.work)
        solution, warm, delta = None, None, None
        start = start if start is not None else self.steady_start
        if start is not None:
            p = np.asarray(start[0], dtype=float).reshape(g.nx, g.ny)
            warm, delta = p[r0:r1], start[1]
        elif scene.penetration is not None and not g.line:  # a cold start: Hertz's pressure at the penetration
            lowest = comm.allreduce(float(np.min(profile, initial=np.inf)), op=MPI.MIN)
            radius, penetration = scene.body.radius_hint, float(scene.penetration(0.0))
            load = 4 * math.sqrt(radius) * max(penetration - lowest, 0.0) ** 1.5 / (3 * compliance)
            warm = solver.hertz_pressure(profile, compliance, load, radius, penetration)
        x = p
        m = lagged(np.pad(x, pad))
        scene_tol, change, scale, previous = solver.tol, math.inf, 1.0, None
        final = max(scene_tol, min(0.01 * tol, 1e-3))  # the last QPs' tolerance
        try:  # a failed QP leaves the solver's tolerance as it was
            for self.fixed_point_iterations in range(1, max_iterations + 1):
                height = profile + displacement(m, x)
                warm = warm if solution is None else solution.pressure
                # inexact QPs while the memory is far from converged: 1 % of its last change, at least final
                solver.tol = max(final, min(1e-3, 0.01 * change / scale))
                if scene.penetration is not None:
                    solution = solver.solve_penetration(height, compliance, float(scene.penetration(0.0)), warm)
                else:
                    solution = solver.solve_load(height, compliance, float(scene.load(0.0)),
                                                 scene.body.radius_hint, delta, warm)
                delta = solution.delta
                p = np.vstack(comm.allgather(solution.pressure))
                padded = np.pad(p, pad)
                target = lagged(padded)
                scale = compliance * float(p.max(initial=0.0))
                change = float(np.abs(target - m).max(initial=0.0))
                if change <= tol * scale and solver.tol == final:
                    break
                forces = self._forces(solution.pressure, sx, sy, velocity / speed)
                if steady is not None and previous is not None and solver.tol <= steady / 3 and all(
                        abs(now - then) <= steady * forces[0] for now, then in zip(forces, previous)):
                    break
                previous = forces
                x = mixer.next(x, x + newton_step(p - x, p > 0))
                m = lagged(np.pad(x, pad))
            else:
                raise SolverError(f"the steady solve did not converge within {max_iterations} iterations")
        finally:
            solver.tol = scene_tol
        solution.iterations = solver.work[0] - work[0]
        solution.applications = solver.work[1] - work[1]
        self.pressure = solution.pressure
        w = displacement(memory(padded), p)
        self._newest = (profile, w, None, delta)
        record = self._diagnose(0, 0.0, sx, sy, solution, velocity, 0.0, clock.perf_counter() - began)
        self.records.append(record)
        return record

    def _forces(self, p: np.ndarray, sx: float, sy: float, d: np.ndarray) -> tuple[float, float]:
        """(normal force, resisting force along d) of the pressure p (this rank's rows) of a body at (sx,
        sy), N (collective)."""
        slope_x, slope_y = self.scene.body.slope(self.x - sx, self.y - sy)
        sums = np.array([p.sum(), (p * (slope_x * d[0] + slope_y * d[1])).sum()]) * self.scene.grid.cell_area
        self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        return float(sums[0]), float(sums[1])

    def surface(self) -> tuple[np.ndarray, np.ndarray]:
        """The newest solved step's surface displacement w (m, positive into the half-space) and gap
        g = Z + w - delta (m) on this rank's rows. w = J_eff A p + A v is the whole displacement at that
        step: the step's own pressure plus the preceding displacement of the whole history (no cut-off);
        for line contact it is relative to the datum (petroll.solver.kernels.love.strip_coefficients).
        One convolution on the whole grid; collective. A step restored from a checkpoint, not solved since,
        has none (RuntimeError)."""
        if self._newest is None:
            raise RuntimeError("no solved step: the surface of a restored step is not kept")
        profile, v, compliance, delta = self._newest
        if compliance is None:  # a steady solve: v is already w (its wake lies beyond the grid)
            return v, profile + v - delta
        g = self.scene.grid
        source = compliance * self.pressure if v is None else compliance * self.pressure + v
        w = self.solver.influence.window(g.nx, g.ny)(source)
        return w, profile + w - delta

    def _solve_load(self, profile, v, compliance: float, load: float, warm):
        """The step under load control. With a history, u is first computed on the box for a penetration
        up to 1.5 times the previous step's, and no penetration beyond that is tried; only if the load
        needs more is the step solved again with u on every cell (the first attempt's work counted too).
        Any other failure is the step's failure."""
        solver, radius = self.solver, self.scene.body.radius_hint
        previous = self.records[-1].delta if self.records else None
        if v is not None and previous and previous > 0:
            reach = 1.5 * previous
            height = profile + self.wake.displacement(v, profile, reach)
            try:
                return solver.solve_load(height, compliance, load, radius, previous, warm, reach=reach)
            except BeyondReach:
                pass
        height = profile if v is None else profile + self.wake.displacement(v, profile, np.inf)
        return solver.solve_load(height, compliance, load, radius, previous, warm)

    def _diagnose(self, n, t, sx, sy, solution, velocity, distance, elapsed) -> StepRecord:
        g, comm, p = self.scene.grid, self.comm, solution.pressure
        x, y = self.x - sx, self.y - sy
        slope_x, slope_y = self.scene.body.slope(x, y)
        d = self.direction
        along = x * d[0] + y * d[1]
        contact = p > 0
        sums = np.array([p.sum(), (p * slope_x).sum(), (p * slope_y).sum(), (p * x).sum(), (p * y).sum(),
                         contact.sum()], dtype=float)
        comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        extremes = np.array([p.max(initial=0.0), np.max(along, where=contact, initial=-np.inf),
                             -np.min(along, where=contact, initial=np.inf)])
        comm.Allreduce(MPI.IN_PLACE, extremes, op=MPI.MAX)
        total, px, py, mx, my, cells = sums
        area = g.cell_area
        force, force_x, force_y = total * area, px * area, py * area
        resisting = force_x * d[0] + force_y * d[1]
        half = 0.5 * (abs(d[0]) * g.dx + abs(d[1]) * g.dy)
        has = cells > 0
        return StepRecord(
            step=n, t=t, sx=float(sx), sy=float(sy), delta=solution.delta, force=force, force_x=force_x,
            force_y=force_y, mu_r=resisting / force if has else 0.0, area=cells * area, p_max=extremes[0],
            cop_x=mx / total if has else math.nan, cop_y=my / total if has else math.nan,
            lead=extremes[1] + half if has else math.nan, trail=-extremes[2] - half if has else math.nan,
            dissipation=force_x * velocity[0] + force_y * velocity[1], distance=distance,
            iterations=solution.iterations, applications=solution.applications, residual=solution.residual,
            solve_time=elapsed)

    def steady(self) -> bool:
        """Force and resisting force changed by less than [time] steady (x force) over one patch length."""
        tol, records = self.scene.time.steady, self.records
        if tol is None or len(records) < 3 or records[-1].force == 0:
            return False
        now = records[-1]
        length = now.lead - now.trail
        earlier = [r for r in records[1:-1] if r.distance <= now.distance - length]
        if not earlier:
            return False
        then = earlier[-1]
        scale = tol * now.force
        return abs(now.force - then.force) <= scale and abs(now.mu_r * now.force - then.mu_r * then.force) <= scale
