"""What a run reports, step by step: the records the time loop (petroll.solver) makes and the files
(petroll.io: results.h5, checkpoints) store and read back.

Plain data, no numerics: a module of its own, beside errors.py, that solver and io both import, so that
io reads and writes a run's records without importing the solver (and ``import petroll.io.results``
starts neither MPI nor PETSc). docs/design.md, "Where code lives".
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np


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
    mu_r: float  # resisting force along the motion / normal force (steady sliding: dissipation / (F V))
    area: float
    p_max: float
    cop_x: float  # centre of pressure relative to the body
    cop_y: float
    lead: float  # leading and trailing patch edges along the motion, relative to the body
    trail: float
    dissipation: float  # power of the resisting force, W (steady sliding: the material's dissipated power)
    distance: float  # rolled path length so far
    iterations: int
    applications: int
    residual: float
    solve_time: float

    @classmethod
    def from_series(cls, series, i: int) -> StepRecord:
        """Step ``i`` of ``series`` ({name: sequence} holding every name of :data:`SERIES`), each value of
        its field's type (:data:`INTEGER_SERIES` as int, the others as float)."""
        return cls(**{name: (int if name in INTEGER_SERIES else float)(series[name][i]) for name in SERIES})


def lateral_friction(record: StepRecord, direction) -> float:
    """The lateral force's coefficient (force_x, force_y) . ``direction`` / force (a unit vector along the
    motion; 0 without force): a record's mu_r, except for a steady sliding solve's, whose mu_r is from the
    material's dissipated power and this its diagnostic (docs/rough.md)."""
    if record.force == 0:
        return 0.0
    return (record.force_x * float(direction[0]) + record.force_y * float(direction[1])) / record.force


SERIES = tuple(f.name for f in fields(StepRecord))
"""The per-step series of a run, in order: the fields of :class:`StepRecord`."""

INTEGER_SERIES = ("step", "iterations", "applications", "friction_iterations", "friction_applications")
"""Series stored as 64-bit integers (the others as doubles)."""


@dataclass
class FrictionRecord:
    """What one step of a run with [friction] reports beside its StepRecord (global values; forces N, N/m
    in line contact; docs/results.md)."""

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

    @classmethod
    def from_series(cls, series, i: int) -> FrictionRecord:
        """Step ``i`` of ``series`` (a line-contact run's absent _y series: 0)."""
        return cls(**{name: (int if name in INTEGER_SERIES else float)(series[name][i] if name in series else 0)
                      for name in FRICTION_SERIES})


FRICTION_SERIES = tuple(f.name for f in fields(FrictionRecord))
"""The series a run with [friction] writes beside :data:`SERIES` (line contact: without
:data:`FRICTION_LINE_ABSENT`)."""

FRICTION_UNITS = {"traction_x": "N", "traction_y": "N", "creepage_x": "-", "creepage_y": "-", "shift_x": "m",
                  "shift_y": "m", "stick_area": "m^2", "friction_power": "W", "friction_iterations": "-",
                  "friction_applications": "-"}
"""The units of friction's series (3-D)."""

FRICTION_LINE_ABSENT = ("traction_y", "creepage_y", "shift_y")
FRICTION_LINE_UNITS = {"traction_x": "N/m", "stick_area": "m", "friction_power": "W/m"}
"""Friction's series a line-contact run does not write, and those whose unit is per unit length there."""


def friction_units(line: bool) -> dict[str, str]:
    """Friction's series and their units (``line``: a line-contact run's)."""
    return {name: (FRICTION_LINE_UNITS.get(name, unit) if line else unit) for name, unit in FRICTION_UNITS.items()
            if not (line and name in FRICTION_LINE_ABSENT)}


class Joined:
    """A StepRecord with its step's FrictionRecord's values as attributes too: a row of the series of a run
    with friction (results.h5, checkpoints)."""

    def __init__(self, record: StepRecord, friction: FrictionRecord):
        self.record, self.friction = record, friction

    def __getattr__(self, name: str):
        return getattr(self.friction if name in FRICTION_UNITS else self.record, name)


def series_rows(records: list[StepRecord], friction: list[FrictionRecord] | None) -> list:
    """The rows of a run's series: its StepRecords, joined with their FrictionRecords (``friction``; None:
    a run without friction)."""
    return records if friction is None else [Joined(r, f) for r, f in zip(records, friction)]


@dataclass(frozen=True)
class RoughOutputs:
    """One step's values: ``area_fraction`` (-), ``mean_gap`` (m; mean of Z + w - delta over the cell),
    the spectrum's bins: ``q`` (mean |k| of each bin's modes, rad/m; NaN for an empty bin), ``spectrum``
    (mean C(q) of the pressure, Pa^2 m^2), ``modes`` (the independent modes in each bin); ``mu_lateral``
    (-): the lateral force's coefficient (:func:`lateral_friction`)."""

    area_fraction: float
    mean_gap: float
    q: np.ndarray
    spectrum: np.ndarray
    modes: np.ndarray
    mu_lateral: float
