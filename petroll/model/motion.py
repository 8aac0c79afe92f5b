"""Programs in time: the body's velocity V(t) (and its path s(t)), the penetration delta(t) or load F(t).

A program is constant, a ramp, a sinusoid or a table; values may be scalars or [x, y] vectors (numpy
arrays). Times in s; values in the unit of the quantity (m/s, m, N).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ProgramKind:
    """How a program of one kind is written in a scene: ``kind = NAME`` in an inline table with ``keys``
    (name: (unit, meaning); unit "value" stands for the quantity's own unit, m/s, m or N), of which
    ``optional`` ones have defaults; ``example`` is a [motion] line using it."""

    doc: str
    keys: dict[str, tuple[str, str]]
    example: str
    optional: dict[str, float] = field(default_factory=dict)


PROGRAMS = {
    "constant": ProgramKind(
        "the value itself, written without a table: a number ([x, y] for the velocity)", {},
        "velocity = [0.01, 0.0]"),
    "ramp": ProgramKind(
        "from start at t = 0 linearly to end at t = duration, then constant at end",
        {"start": ("value", "the value at t = 0 (a load: >= 0)"),
         "end": ("value", "the value from t = duration on"),
         "duration": ("s", "the ramp's length in time, > 0")},
        'load = {kind = "ramp", start = 0.0, end = 0.05, duration = 0.02}'),
    "sinusoidal": ProgramKind(
        "value = mean + amplitude sin(2 pi t / period + phase)",
        {"mean": ("value", "the mean value"),
         "amplitude": ("value", "the amplitude (a load: no larger than the mean)"),
         "period": ("s", "the period, > 0"), "phase": ("rad", "the phase at t = 0 (default 0)")},
        'velocity = {kind = "sinusoidal", mean = [0.01, 0.0], amplitude = [0.008, 0.0], period = 0.2}',
        optional={"phase": 0.0}),
    "tabulated": ProgramKind(
        "linear between the points of a table, constant before the first and after the last",
        {"t": ("s", "increasing times, from t >= 0"), "value": ("value", "one value per time")},
        'penetration = {kind = "tabulated", t = [0.0, 0.05, 0.1], value = [1.0e-5, 2.0e-5, 2.0e-5]}'),
}
"""The kinds of program a [motion] key takes (docs/scene.md is generated from this)."""


@dataclass(frozen=True)
class Constant:
    value: np.ndarray

    def __call__(self, t: float) -> np.ndarray:
        return self.value

    def integral(self, t: float) -> np.ndarray:
        """The integral of the program from 0 to t."""
        return self.value * t

    def peak(self) -> float:
        """The largest magnitude the program takes."""
        return float(np.linalg.norm(self.value))

    def largest(self) -> float:
        """The largest value a scalar program takes (signed; penetration, load)."""
        return float(np.max(self.value))


@dataclass(frozen=True)
class Ramp:
    """From ``start`` at t = 0 linearly to ``end`` at t = ``duration``, then constant."""

    start: np.ndarray
    end: np.ndarray
    duration: float

    def __call__(self, t: float) -> np.ndarray:
        return self.start + (self.end - self.start) * min(t / self.duration, 1.0)

    def integral(self, t: float) -> np.ndarray:
        rising = min(t, self.duration)
        area = self.start * rising + (self.end - self.start) * rising**2 / (2 * self.duration)
        return area + self.end * max(t - self.duration, 0.0)

    def peak(self) -> float:
        return float(max(np.linalg.norm(self.start), np.linalg.norm(self.end)))

    def largest(self) -> float:
        return float(max(np.max(self.start), np.max(self.end)))


@dataclass(frozen=True)
class Sinusoidal:
    """mean + amplitude sin(2 pi t / period + phase) (phase in radians)."""

    mean: np.ndarray
    amplitude: np.ndarray
    period: float
    phase: float = 0.0

    def __call__(self, t: float) -> np.ndarray:
        return self.mean + self.amplitude * math.sin(2 * math.pi * t / self.period + self.phase)

    def integral(self, t: float) -> np.ndarray:
        w = 2 * math.pi / self.period
        return self.mean * t - self.amplitude * (math.cos(w * t + self.phase) - math.cos(self.phase)) / w

    def peak(self) -> float:
        return float(np.linalg.norm(np.abs(self.mean) + np.abs(self.amplitude)))

    def largest(self) -> float:
        return float(np.max(self.mean + np.abs(self.amplitude)))


@dataclass(frozen=True)
class Tabulated:
    """Linear interpolation in (times, values), constant outside; ``values`` has one row per time."""

    times: np.ndarray
    values: np.ndarray

    def __call__(self, t: float) -> np.ndarray:
        return _interp_rows(t, self.times, self.values)

    def integral(self, t: float) -> np.ndarray:
        times, values = self.times, self.values
        area = values[0] * (min(t, times[0]) - 0.0)  # constant before the first time
        inside = times[(times > times[0]) & (times < t)]
        knots = np.concatenate([[times[0]], inside, [t]]) if t > times[0] else np.array([])
        if knots.size:
            v = np.array([_interp_rows(k, times, values) for k in knots])
            area = area + np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(knots)[:, None], axis=0).reshape(
                np.shape(values[0]))
        return area

    def peak(self) -> float:
        return float(np.max(np.linalg.norm(self.values.reshape(len(self.times), -1), axis=1)))

    def largest(self) -> float:
        return float(np.max(self.values))


def _interp_rows(t: float, times: np.ndarray, values: np.ndarray) -> np.ndarray:
    if values.ndim == 1:
        return np.asarray(np.interp(t, times, values))
    return np.array([np.interp(t, times, values[:, k]) for k in range(values.shape[1])])
