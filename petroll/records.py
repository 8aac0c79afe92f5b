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

    @classmethod
    def from_series(cls, series, i: int) -> StepRecord:
        """Step ``i`` of ``series`` ({name: sequence} holding every name of :data:`SERIES`), each value of
        its field's type (:data:`INTEGER_SERIES` as int, the others as float)."""
        return cls(**{name: (int if name in INTEGER_SERIES else float)(series[name][i]) for name in SERIES})


SERIES = tuple(f.name for f in fields(StepRecord))
"""The per-step series of a run, in order: the fields of :class:`StepRecord`."""

INTEGER_SERIES = ("step", "iterations", "applications")
"""Series stored as 64-bit integers (the others as doubles)."""


@dataclass(frozen=True)
class RoughOutputs:
    """One step's values: ``area_fraction`` (-), ``mean_gap`` (m; mean of Z + w - delta over the cell),
    the spectrum's bins: ``q`` (mean |k| of each bin's modes, rad/m; NaN for an empty bin), ``spectrum``
    (mean C(q) of the pressure, Pa^2 m^2), ``modes`` (the independent modes in each bin)."""

    area_fraction: float
    mean_gap: float
    q: np.ndarray
    spectrum: np.ndarray
    modes: np.ndarray
