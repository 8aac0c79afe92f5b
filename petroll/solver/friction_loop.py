"""Friction in the time loop: the tangential problem of each step solved on the normal one's pressure
(scene [friction]; docs/friction.md), its series, fields and checkpoint state.

:class:`FrictionLoop` is what a :class:`petroll.solver.simulation.Simulation` of a scene with friction
holds beside its contact solver: after a step's normal solve, :meth:`FrictionLoop.step` solves the step's
tangential problem (petroll.solver.friction.Stepping: a quasi-static shift while the body has not moved
over the step, Kalker's transient rolling otherwise) on the traction bound mu p, and :meth:`steady` the
steady rolling state (SteadyRolling) on the steady pressure. Each step's :class:`FrictionRecord` holds its
global values (the series of results.h5); :attr:`FrictionLoop.fields` the newest step's fields.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np
from mpi4py import MPI

from petroll.solver.friction import Stepping, SteadyRolling
from petroll.solver.tangential import TangentialSolution, TangentialSolver


@dataclass
class FrictionRecord:
    """What one step reports of friction (global values). Forces N (N/m in line contact)."""

    traction_x: float  # sum q_x dA: the tangential force the half-space exerts on the body, N
    traction_y: float
    creepage_x: float  # given or found (force control); NaN for a step without motion (a shift)
    creepage_y: float
    shift_x: float  # the body's rigid tangential displacement of the shifts so far, m
    shift_y: float
    stick_area: float  # cells with p > 0 and |q| < mu p (within the solver's tolerance), m^2 (m)
    friction_power: float  # -sum q . (slip velocity) dA >= 0, W (W/m); NaN for a step of no duration
    friction_iterations: int
    friction_applications: int


SERIES_UNITS = {"traction_x": "N", "traction_y": "N", "creepage_x": "-", "creepage_y": "-", "shift_x": "m",
                "shift_y": "m", "stick_area": "m^2", "friction_power": "W", "friction_iterations": "-",
                "friction_applications": "-"}
"""The series of a run with friction, with their units."""

LINE_ABSENT = ("traction_y", "creepage_y", "shift_y")
"""Friction's series a line-contact run does not write."""

LINE_UNITS = {"traction_x": "N/m", "stick_area": "m", "friction_power": "W/m"}
"""Friction's series whose unit differs in line contact (per unit length)."""

INTEGER_SERIES = ("friction_iterations", "friction_applications")


def series_units(line: bool) -> dict[str, str]:
    """Friction's series and their units (``line``: a line-contact run's)."""
    return {name: (LINE_UNITS.get(name, unit) if line else unit) for name, unit in SERIES_UNITS.items()
            if not (line and name in LINE_ABSENT)}


def as_record(values: dict) -> FrictionRecord:
    """A FrictionRecord from a step's values by name (a checkpoint's series; line contact's absent ones 0)."""
    return FrictionRecord(**{f.name: (int if f.name in INTEGER_SERIES else float)(values.get(f.name, 0))
                             for f in fields(FrictionRecord)})


class FrictionLoop:
    """The tangential problems of a run of ``scene`` (its [friction]) on ``comm``: the solver, the stepping
    state (the last tractions), the records so far and the newest step's fields (this rank's rows)."""

    def __init__(self, scene, comm: MPI.Comm):
        self.scene, self.friction, self.comm = scene, scene.friction, comm
        f = scene.friction
        self.solver = TangentialSolver(scene.grid, comm, f.nu, f.compliance, tol=scene.solver.tol)
        self.stepping = Stepping(self.solver)
        self.records: list[FrictionRecord] = []
        self.fields: dict[str, np.ndarray] = {}

    def _force(self, t: float) -> np.ndarray | None:
        force = self.friction.force_at(t)
        return None if force is None else force[: self.solver.m]

    def step(self, record, before, pressure: np.ndarray, direction, dt: float) -> FrictionRecord:
        """The tangential problem of the step of ``record`` (a StepRecord; ``before`` the step before's, or
        None) on its ``pressure`` (Pa, this rank's rows), the body moving along ``direction`` (a unit
        vector) over the step of length ``dt`` (s)."""
        f, stepping = self.friction, self.stepping
        bound = f.coefficient * pressure
        distance = record.distance - before.distance if before is not None else 0.0
        if distance > 0:
            force = None if f.force is None else np.asarray(f.force)[: self.solver.m]
            solution = stepping.roll(bound, (record.sx, record.sy), distance, direction, f.creepage, f.spin,
                                     force)
            creepage, rate = stepping.creepage, distance / (dt * stepping.scale)
        else:
            force = self._force(record.t)
            increment = None if force is not None else np.zeros(self.solver.m)
            solution = stepping.shift(bound, increment, force)
            creepage, rate = np.full(self.solver.m, math.nan), (1 / dt if dt > 0 else math.nan)
        return self._record(solution, bound, creepage, rate)

    def steady(self, record, pressure: np.ndarray, direction, speed: float) -> FrictionRecord:
        """The steady rolling state on the steady ``pressure`` (Pa, this rank's rows) of the body at
        (record.sx, record.sy) moving along ``direction`` (X or Y) at ``speed`` (m/s)."""
        f, m = self.friction, self.solver.m
        axis = 0 if direction[1] == 0 else 1
        rolling = SteadyRolling(self.solver, axis, 1 if direction[axis] > 0 else -1)
        force = None if f.force is None else np.asarray(f.force)[:m]
        bound = f.coefficient * pressure
        steady = rolling.solve(bound, f.creepage, f.spin, (record.sx, record.sy), force)
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
        """(fields: name -> this rank's rows of each component, small: [last rolled distance (NaN: the last
        step was a shift), shift (m), creepage]) of the stepping state a restart needs."""
        st = self.stepping
        parts = {"traction": list(st.traction)}
        if st.older is not None:
            parts["traction_older"] = list(st.older)
        last = math.nan if st.last_distance is None else st.last_distance
        return parts, np.array([last, st.scale, *st.shift_total, *st.creepage], dtype=float)

    def restore(self, state: dict, series: dict[str, np.ndarray]) -> None:
        """Put a checkpoint's state (this rank's rows: "traction", "traction_older" as :meth:`state` gave
        them, "friction" its small array) and ``series`` (name: values) back."""
        st, m, small = self.stepping, self.solver.m, state["friction"]
        st.traction = np.stack(state["traction"])
        st.older = np.stack(state["traction_older"]) if "traction_older" in state else None
        st.last_distance = None if math.isnan(small[0]) else float(small[0])
        st.scale = float(small[1])
        st.shift_total, st.creepage = np.array(small[2 : 2 + m]), np.array(small[2 + m : 2 + 2 * m])
        n = len(series["step"])
        self.records = [as_record({k: v[i] for k, v in series.items()}) for i in range(n)]


class Joined:
    """A StepRecord with its step's FrictionRecord's values as attributes too: the rows of the series of a
    run with friction (results.h5, checkpoints)."""

    def __init__(self, record, friction: FrictionRecord):
        self.record, self.friction = record, friction

    def __getattr__(self, name: str):
        return getattr(self.friction if name in SERIES_UNITS else self.record, name)


def series_rows(sim) -> list:
    """The rows of ``sim``'s series: its StepRecords, joined with their FrictionRecords with friction."""
    if sim.friction is None:
        return sim.records
    return [Joined(r, f) for r, f in zip(sim.records, sim.friction.records)]
