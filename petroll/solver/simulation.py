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

import numpy as np
from mpi4py import MPI

from petroll.solver.contact import BeyondReach, ContactSolver
from petroll.errors import SceneError
from petroll.solver.friction_loop import friction_loop
from petroll.solver.history import make_history
from petroll.records import RoughOutputs, StepRecord, lateral_friction
from petroll.solver.rough import radial_spectrum, spectrum_edges
from petroll.solver.steady_state import steady_state
from petroll.model.clock import TimeMode, step_length
from petroll.model.rough_contact import release_statistics
from petroll.model.scene import Scene
from petroll.solver.wake import Wake
from petroll.solver.warm import WarmStart


class Simulation:
    """A scene being run on ``comm``: owns the contact solver, the history and the step clock.

    ``steps()`` runs it to its end, one step per iteration; ``t`` is the time of the newest step (s) and
    ``dt_next`` the length of the step after it (None: the run is over).
    """

    def __init__(self, scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD):
        self.scene, self.comm = scene, comm
        release_statistics()  # the scene's checks are made: their kept heights go before the run's arrays
        self.solver = ContactSolver(scene.grid, comm, tao_type=scene.solver.tao_type, tol=scene.solver.tol,
                                    layer=scene.layer, pressure_tol=scene.solver.pressure_tol)
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
        self.fixed_point_iterations = 0  # the last solve_steady's fixed-point iterations
        self.window = None  # the newest step's QP window, cells [i0, i1) x [j0, j1)
        self.friction = friction_loop(scene, comm) if scene.friction is not None else None  # [friction]
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
        if self.scene.time.mode is TimeMode.STEADY:
            record = self.solve_steady(tol=self.scene.solver.tol)
            self.t, self.dt_next = 0.0, None
            yield record
            return
        lengths = iter(dts) if dts is not None else None
        resumed, dt = bool(self.records), 0.0
        while True:
            if not resumed:
                self._within_max_steps(len(self.records))
            record = self.records[-1] if resumed else self.step(t, dt)
            if lengths is not None:
                dt = next(lengths, None)
            else:
                dt = self.next_dt(t, record.distance)
                if dt is not None and self.steady():
                    dt = None
            self.t, self.dt_next = t, dt
            yield record
            resumed = False
            if dt is None:
                return
            t += dt

    # -- the clock --------------------------------------------------------------------------------------
    def next_dt(self, t: float, distance: float) -> float | None:
        """Length of the step after time t (None: the run is over): petroll.model.clock.step_length."""
        return step_length(self.scene, t, distance)

    def last_step(self, after_step=None) -> StepRecord:
        """Run the scene to the end of its clock and return the last step's record: the record
        :meth:`steps` ends with, but for its ``solve_time`` (the last step's), on a fresh simulation of a
        scene without [time] steady (whose stop needs every step's record; it is not applied here). The
        diagnostics (force, mu_r, the patch ...) are made for the last step only, and no record is kept in
        ``self.records``: what the error estimate reads of its coarser grids (petroll.studies.estimate).
        A steady solve ([time] mode = "steady") is its one step, solved by :meth:`steps` (which keeps its
        record). RuntimeError on a simulation that has solved or restored steps. ``after_step()``: called on
        every rank after each step (e.g. to stop on a signal by raising). Collective."""
        if self.records:
            raise RuntimeError("last_step runs a fresh simulation: this one has solved or restored steps")
        if self.scene.time.mode is TimeMode.STEADY:
            record = list(self.steps())[-1]
            if after_step is not None:
                after_step()
            return record
        t, dt, n, distance, delta, where = 0.0, 0.0, 0, 0.0, None, None
        while True:
            self._within_max_steps(n)
            solution, sx, sy, velocity, elapsed = self._advance(t, dt, delta)
            if where is not None:
                distance += float(np.hypot(sx - where[0], sy - where[1]))
            where, delta = (float(sx), float(sy)), solution.delta
            if after_step is not None:
                after_step()
            dt = self.next_dt(t, distance)
            if dt is None:
                break
            t, n = t + dt, n + 1
        self.t, self.dt_next = t, None
        return self._diagnose(n, t, sx, sy, solution, velocity, distance, elapsed)

    def _within_max_steps(self, n: int) -> None:
        """SceneError for a step numbered ``n`` beyond [time] max_steps."""
        if n > self.scene.time.max_steps:
            raise SceneError(self.scene.source, "[time] max_steps", self.scene.time.max_steps,
                             "the run needs more steps: raise max_steps or the time step")

    # -- one step ---------------------------------------------------------------------------------------
    def step(self, t: float, dt: float) -> StepRecord:
        """Solve the step ending at time t (length dt; dt = 0 is the sudden start)."""
        before = self.records[-1] if self.records else None
        solution, sx, sy, velocity, elapsed = self._advance(t, dt, before.delta if before else None)
        distance = 0.0
        if before is not None:
            distance = before.distance + float(np.hypot(sx - before.sx, sy - before.sy))
        record = self._diagnose(len(self.records), t, sx, sy, solution, velocity, distance, elapsed)
        if self.friction is not None:  # the step's tangential problem on its pressure
            self.friction.step(record, before, self.pressure, self.direction, dt)
        self.records.append(record)
        return record

    def _advance(self, t: float, dt: float, previous: float | None):
        """Solve the step ending at time t (length dt) and move the history, the warm start and the
        direction of motion on; ``previous``: the step before's penetration (m; None: none). Returns the
        solution, the body's position (m), its velocity (m/s) and the step's wall time (s)."""
        scene, solver = self.scene, self.solver
        start = clock.perf_counter()
        sx, sy = np.asarray(scene.position) + scene.velocity.integral(t)
        profile = scene.body.height(*scene.grid.offsets(self.x, self.y, sx, sy))
        v = self.history.preceding(dt)
        compliance = self.history.compliance(dt)
        warm = self.warm.guess(sx, sy)
        work = list(solver.work)
        if scene.penetration is not None:
            delta = float(scene.penetration(t))
            height = profile if v is None else profile + self.wake.displacement(v, profile, delta)
            solution = solver.solve_penetration(height, compliance, delta, warm)
        else:
            solution = self._solve_load(profile, v, compliance, float(scene.load(t)), previous, warm)
        solution.iterations = solver.work[0] - work[0]  # all QPs of the step, a redone attempt's too
        solution.applications = solver.work[1] - work[1]
        self.history.advance(solution.pressure, dt)
        self.pressure, self.window = solution.pressure, solution.window
        self._newest = (profile, v, compliance, solution.delta)
        self.warm.record(solution.pressure, sx, sy)
        elapsed = clock.perf_counter() - start
        velocity = np.asarray(scene.velocity(t), dtype=float)
        if np.hypot(*velocity) > 0:
            self.direction = velocity / np.hypot(*velocity)
        return solution, sx, sy, velocity, elapsed

    def solve_steady(self, tol: float = 1e-10, max_iterations: int = 500,
                     start: tuple[np.ndarray, float] | None = None, steady: float | None = None) -> StepRecord:
        """The constant-velocity steady state solved directly (the grid's steady solve,
        petroll.solver.steady_state: rolling, or sliding on a grid that repeats; each says what ``tol``
        and ``steady`` stop), recorded as step 0 at t = 0 with the body at [body] position. Velocity,
        penetration or load are taken at t = 0 and must be constant (the scene checks this for [time]
        mode = "steady"). The memory is the scene's integrator at its time step: dt from [time] dt or
        steps_per_cell (default 1 step per cell), so that with one step per cell crossed this is exactly
        the state the transient run converges to. ``start``: a first guess (the grid's pressure, Pa, and
        its penetration, m), e.g. a neighbouring steady state (continuation; default
        ``self.steady_start``). The fixed point's iterations are kept in ``self.fixed_point_iterations``.
        Collective; every rank holds only its rows (and lines)."""
        began = clock.perf_counter()
        solve = steady_state(self.scene, self.solver, tol, steady)
        solution, w = solve.solve(start if start is not None else self.steady_start, max_iterations)
        self.fixed_point_iterations = solve.iterations
        self.direction = solve.direction
        self.pressure, self.window = solution.pressure, solution.window
        self._newest = (solve.profile, w, None, solution.delta)
        sx, sy = self.scene.position
        record = self._diagnose(0, 0.0, sx, sy, solution, solve.velocity, 0.0, clock.perf_counter() - began,
                                solve.dissipated(solution.pressure))
        if self.friction is not None:  # steady rolling or sliding with friction on the steady pressure
            self.friction.steady(record, self.pressure, solve.direction, solve.speed)
        self.records.append(record)
        return record

    def rough_outputs(self) -> RoughOutputs:
        """The newest solved step's contact fraction, mean gap (m), pressure spectrum and lateral force's
        coefficient on a 3-D grid periodic along both axes (petroll.solver.rough,
        petroll.records.lateral_friction). The mean displacement is the kernel's k = 0
        response to the mean of its source (0 on a half-space: displacements from the mean plane); a
        steady solve's w is averaged. Collective; RuntimeError for a restored step not solved since."""
        if self._newest is None:
            raise RuntimeError("no solved step: the surface of a restored step is not kept")
        g, p = self.scene.grid, self.pressure
        profile, v, compliance, delta = self._newest
        if compliance is None:  # a steady solve: v is w
            source, scale = v.sum(), 1.0
        else:  # the sum of compliance p + v
            source = compliance * p.sum() + (0.0 if v is None else v.sum())
            scale = float(self.solver.influence.kernel.values(0, 0))
        sums = np.array([np.count_nonzero(p > 0), profile.sum(), source], dtype=float)
        self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        cells = g.nx * g.ny
        conv = self.solver.influence.window(g.nx, g.ny)
        q, spectrum, modes = radial_spectrum(conv, p, g, spectrum_edges(g))
        return RoughOutputs(sums[0] / cells, (sums[1] + scale * sums[2]) / cells - delta, q, spectrum, modes,
                            lateral_friction(self.records[-1], self.direction))

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

    def _solve_load(self, profile, v, compliance: float, load: float, previous: float | None, warm):
        """The step under load control (``previous``: the step before's penetration, m, or None). With a
        history, u is first computed on the box for a penetration up to 1.5 times the previous step's, and
        no penetration beyond that is tried; only if the load needs more is the step solved again with u on
        every cell (the first attempt's work counted too). Any other failure is the step's failure."""
        solver, radius = self.solver, self.scene.body.radius_hint
        if v is not None and previous and previous > 0:
            reach = 1.5 * previous
            height = profile + self.wake.displacement(v, profile, reach)
            try:
                return solver.solve_load(height, compliance, load, radius, previous, warm, reach=reach)
            except BeyondReach:
                pass
        height = profile if v is None else profile + self.wake.displacement(v, profile, np.inf)
        return solver.solve_load(height, compliance, load, radius, previous, warm)

    def _diagnose(self, n, t, sx, sy, solution, velocity, distance, elapsed, power=None) -> StepRecord:
        """The step's record. Its resisting force along the motion is the pressure's on the body's slope
        (force_x, force_y: the lateral force), and ``dissipation`` that force's power; given the material's
        dissipated ``power`` (W: a steady sliding solve's), the resisting force is power / speed and
        ``dissipation`` that power (mu_r from the dissipation; force_x, force_y stay the lateral force:
        petroll.records.lateral_friction)."""
        g, comm, p = self.scene.grid, self.comm, solution.pressure
        rows, columns = np.nonzero(p)  # the cells that carry pressure: the sums over them are the grid's
        carried = p[rows, columns]
        x, y = g.offsets(self.x[rows, 0], self.y[0, columns], sx, sy)
        slope_x, slope_y = self.scene.body.slope(x, y)
        d = self.direction
        contact = carried > 0
        along = x[contact] * d[0] + y[contact] * d[1]
        sums = np.array([p.sum(), carried @ slope_x, carried @ slope_y, carried @ x, carried @ y,
                         contact.sum()], dtype=float)
        comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        extremes = np.array([p.max(initial=0.0), along.max(initial=-np.inf), -along.min(initial=np.inf)])
        comm.Allreduce(MPI.IN_PLACE, extremes, op=MPI.MAX)
        total, px, py, mx, my, cells = sums
        area = g.cell_area
        force, force_x, force_y = total * area, px * area, py * area
        resisting = force_x * d[0] + force_y * d[1]
        dissipation = force_x * velocity[0] + force_y * velocity[1]
        if power is not None:
            dissipation, resisting = power, power / float(np.hypot(*velocity))
        half = 0.5 * (abs(d[0]) * g.dx + abs(d[1]) * g.dy)
        has = cells > 0
        return StepRecord(
            step=n, t=t, sx=float(sx), sy=float(sy), delta=solution.delta, force=force, force_x=force_x,
            force_y=force_y, mu_r=resisting / force if has else 0.0, area=cells * area, p_max=extremes[0],
            cop_x=mx / total if has else math.nan, cop_y=my / total if has else math.nan,
            lead=extremes[1] + half if has else math.nan, trail=-extremes[2] - half if has else math.nan,
            dissipation=dissipation, distance=distance,
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
