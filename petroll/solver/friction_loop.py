"""Friction in the time loop: the tangential problem of each step solved on the normal one's pressure
(scene [friction]; docs/friction.md), its series, fields and checkpoint state.

:class:`FrictionLoop` is what a :class:`petroll.solver.simulation.Simulation` of a scene with friction
holds beside its contact solver: after a step's normal solve, :meth:`FrictionLoop.step` solves the step's
tangential problem (petroll.solver.friction.Stepping: a quasi-static shift while the body has not moved
over the step, Kalker's transient rolling otherwise) on the traction bound mu p, and :meth:`steady` the
steady rolling state (SteadyRolling) on the steady pressure. Each step's :class:`FrictionRecord` holds its
global values (the series of results.h5); :attr:`FrictionLoop.fields` the newest step's fields.
:class:`FullSlip` is steady sliding's instead (a periodic grid, petroll.model.friction.Sliding): no
tangential problem, the traction mu p; :func:`friction_loop` picks the one of a scene.
"""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from petroll.model.friction import Sliding
from petroll.records import FrictionRecord
from petroll.solver.friction import ShearMemory, Stepping, SteadyRolling
from petroll.solver.history import make_history, state_space
from petroll.solver.tangential import TangentialSolution, TangentialSolver


def friction_loop(scene, comm: MPI.Comm):
    """What a run of ``scene`` (with [friction]) solves beside the normal problem on ``comm``: steady
    sliding's :class:`FullSlip`, or the tangential problems of :class:`FrictionLoop`."""
    return FullSlip(scene, comm) if isinstance(scene.friction, Sliding) else FrictionLoop(scene, comm)


class FullSlip:
    """Steady sliding with friction ([time] mode = "steady" on a periodic grid; docs/friction.md#steady-
    sliding): the body slides over the whole contact, so the traction is q = -mu p d at every cell (d the
    direction of sliding: it opposes the body's slip), stick area 0, and the slip velocity is the sliding
    speed V at every cell in contact (the surface's tangential strain rate, of the order of the strain
    times V, is left out, as the linear theory leaves it out). The bodies being quasi-identical, q moves no
    surface normally: the steady pressure is the frictionless one, and the force resisting the sliding is
    mu P (the tractions') plus the pressure's hysteresis force mu_r P (the StepRecord's mu_r: the
    dissipated power's, petroll.solver.sliding).
    :meth:`steady` records it; :attr:`records`, :attr:`fields` as :class:`FrictionLoop`'s."""

    def __init__(self, scene, comm: MPI.Comm):
        self.scene, self.comm = scene, comm
        self.records: list[FrictionRecord] = []
        self.fields: dict[str, np.ndarray] = {}

    def steady(self, record, pressure: np.ndarray, direction, speed: float) -> FrictionRecord:
        """The full slip of the steady ``pressure`` (Pa, this rank's rows; ``record`` its StepRecord), the
        body sliding along ``direction`` (a unit vector) at ``speed`` (m/s)."""
        mu, line = self.scene.friction.coefficient, self.scene.grid.line
        area = self.scene.grid.cell_area
        traction = [-mu * d * pressure for d in direction]
        sums = np.array([t.sum() for t in traction])
        self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        self.fields = {"traction_x": traction[0], "slip": np.where(pressure > 0, speed, 0.0)}
        if not line:
            self.fields["traction_y"] = traction[1]
        force = sums * area * np.array([1.0, 0.0 if line else 1.0])
        nan = math.nan
        out = FrictionRecord(float(force[0]), float(force[1]), nan, 0.0 if line else nan, 0.0, 0.0, 0.0,
                             mu * record.force * speed, 0, 0)
        self.records.append(out)
        return out


class FrictionLoop:
    """The tangential problems of a run of ``scene`` (its [friction]) on ``comm``: the solver, the stepping
    state (the last tractions), the records so far and the newest step's fields (this rank's rows)."""

    def __init__(self, scene, comm: MPI.Comm):
        self.scene, self.friction, self.comm = scene, scene.friction, comm
        f = scene.friction
        self.solver = TangentialSolver(scene.grid, comm, f.nu, f.compliance, tol=scene.solver.tol)
        memory = None
        if f.memory is not None:  # viscoelastic: the scene's creep function through its integrator
            history = make_history(scene.material, scene.solver.integrator, (self.solver.m, *self.solver.local_shape))
            memory = ShearMemory(history, f.memory)
        self.stepping = Stepping(self.solver, memory=memory)
        self.records: list[FrictionRecord] = []
        self.fields: dict[str, np.ndarray] = {}

    def _force(self, t: float) -> np.ndarray | None:
        """The tangential force held at time t (N, an m-vector; a shift's ramp), or None: creepage control."""
        force = self.friction.force_at(t)
        return None if force is None else force[: self.solver.m]

    def step(self, record, before, pressure: np.ndarray, direction, dt: float) -> FrictionRecord:
        """The tangential problem of the step of ``record`` (a StepRecord; ``before`` the step before's, or
        None) on its ``pressure`` (Pa, this rank's rows), the body moving along ``direction`` (a unit
        vector) over the step of length ``dt`` (s)."""
        f, stepping = self.friction, self.stepping
        bound = f.coefficient * pressure
        distance = record.distance - before.distance if before is not None else 0.0
        force = self._force(record.t)
        if distance > 0:
            solution = stepping.roll(bound, (record.sx, record.sy), distance, direction, f.creepage, f.spin,
                                     force, dt=dt)
            creepage, rate = stepping.creepage, distance / (dt * stepping.scale)
        else:
            increment = None if force is not None else np.zeros(self.solver.m)
            solution = stepping.shift(bound, increment, force, dt=dt)
            creepage, rate = np.full(self.solver.m, math.nan), (1 / dt if dt > 0 else math.nan)
        return self._record(solution, bound, creepage, rate)

    def steady(self, record, pressure: np.ndarray, direction, speed: float) -> FrictionRecord:
        """The steady rolling state on the steady ``pressure`` (Pa, this rank's rows) of the body at
        (record.sx, record.sy) moving along ``direction`` (X or Y) at ``speed`` (m/s)."""
        f = self.friction
        axis = 0 if direction[1] == 0 else 1
        rolling = SteadyRolling(self.solver, axis, 1 if direction[axis] > 0 else -1)
        bound = f.coefficient * pressure
        memory = None
        if f.memory is not None:  # the creep function's response at one cell per step, h0 and c as c(t)'s
            h0, s1, M, c = state_space(self.scene.material, self.scene.solver.integrator, rolling.cell / speed)
            memory = (f.memory * h0, s1, M, None if c is None else f.memory * c)
        steady = rolling.solve(bound, f.creepage, f.spin, (record.sx, record.sy), self._force(record.t),
                               memory=memory)
        return self._record(steady.solution, bound, steady.creepage, speed)

    def _record(self, solution: TangentialSolution, bound: np.ndarray, creepage, rate: float) -> FrictionRecord:
        """The step's record and fields: ``rate`` turns the solution's slip into a slip velocity (1/s; NaN:
        a step of no duration)."""
        q, s, m = solution.traction, solution.slip, self.solver.m
        magnitude = np.sqrt((s * s).sum(axis=0))
        moving = (bound > 0) & ~solution.stick
        sums = np.array([np.count_nonzero(solution.stick), -(q * s).sum() if math.isfinite(rate) else 0.0])
        self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        area = self.scene.grid.cell_area
        self.fields = {"traction_x": q[0], "slip": np.where(moving, magnitude * rate, 0.0)}
        if m == 2:
            self.fields["traction_y"] = q[1]
        pad = [0.0] * (2 - m)
        force, creepage = [*solution.force, *pad], [*np.asarray(creepage, dtype=float), *pad]
        shift = [*self.stepping.shift_total, *pad]
        record = FrictionRecord(force[0], force[1], creepage[0], creepage[1], shift[0], shift[1],
                                sums[0] * area, sums[1] * area * rate if math.isfinite(rate) else math.nan,
                                solution.iterations, solution.applications)
        self.records.append(record)
        return record

    # -- the checkpoint's state -------------------------------------------------------------------------
    def state(self) -> tuple[dict[str, list[np.ndarray]], np.ndarray]:
        """(fields: name -> this rank's rows of each component, small: [last rolled distance (m; NaN: the
        last step was a shift), its distance in the QP's form (m), shift (m), creepage]) of the stepping
        state a restart needs."""
        st = self.stepping
        parts = {"traction": list(st.traction)}
        if st.older is not None:
            parts["traction_older"] = list(st.older)
        if st.memory is not None:  # viscoelastic: the sources and the history's fields, component by component
            parts["source"] = list(st.source)
            if st.source_older is not None:
                parts["source_older"] = list(st.source_older)
            parts["shear"] = [c for f in st.memory.history.state() for c in f]
        last = math.nan if st.last_distance is None else st.last_distance
        return parts, np.array([last, st.scale, *st.shift_total, *st.creepage], dtype=float)

    def restore(self, state: dict, series: dict[str, np.ndarray]) -> None:
        """Put a checkpoint's state (this rank's rows: "traction", "traction_older" as :meth:`state` gave
        them, "friction" its small array) and ``series`` (name: values) back."""
        st, m, small = self.stepping, self.solver.m, state["friction"]
        st.traction = np.stack(state["traction"])
        st.older = np.stack(state["traction_older"]) if "traction_older" in state else None
        if st.memory is not None:
            st.source = np.stack(state["source"])
            st.source_older = np.stack(state["source_older"]) if "source_older" in state else None
            shear = state["shear"]
            st.memory.history.load_state([np.stack(shear[k : k + m]) for k in range(0, len(shear), m)])
        st.last_distance = None if math.isnan(small[0]) else float(small[0])
        st.scale = float(small[1])
        st.shift_total, st.creepage = np.array(small[2 : 2 + m]), np.array(small[2 + m : 2 + 2 * m])
        n = len(series["step"])
        self.records = [FrictionRecord.from_series(series, i) for i in range(n)]

