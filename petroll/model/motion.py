"""Programs in time: the body's velocity V(t) (and its path s(t)), the penetration delta(t) or load F(t).

A program is constant, a ramp, a sinusoid or a table; values may be scalars or [x, y] vectors (numpy
arrays). Times in s; values in the unit of the quantity (m/s, m, N).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


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
