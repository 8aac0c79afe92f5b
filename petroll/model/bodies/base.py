"""What every body shares: the :class:`Body` interface and the validation of the values a scene gives it.

Conventions (lengths in m, or any one consistent length unit): the half-space surface is z = 0 and the body
presses down on it; a body's lower surface is ``Z(x, y) >= 0``, its height above its own lowest point at
offsets ``(x, y)`` from the body's reference point; ``Z = +inf`` where it has no surface (slope 0 there).
"""

from __future__ import annotations

import abc
import math
import numbers

import numpy as np

from petroll.errors import SceneError

ON_SAMPLE = 1e-9
"""A point within this many cells of a sample along each axis is on that sample: a body given by samples
(a height map, a periodic surface) takes its height there from the sample, with no interpolation."""

PYTHON_SOURCE = "<python>"
"""The ``source`` of a body built from Python rather than from a scene file (error messages name it)."""


class Body(abc.ABC):
    """The lower surface of a rigid body: Z(x, y) >= 0 in m above its lowest point, +inf where no surface."""

    @abc.abstractmethod
    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Z(x, y) in m at offsets (x, y) in m from the reference point; +inf where there is no surface."""

    @abc.abstractmethod
    def slope(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(dZ/dx, dZ/dy), dimensionless, broadcast like :meth:`height`; 0 where Z is +inf."""

    @property
    @abc.abstractmethod
    def radius_hint(self) -> float:
        """An equivalent radius of curvature in m at the lowest point (only for first guesses)."""


def is_number(value: object) -> bool:
    """A real number, not a bool."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def type_name(value: object) -> str:
    return type(value).__name__


def positive(source: str, key: str, value: object, what: str = "a length in m") -> float:
    """``value`` as a float, or SceneError unless it is a finite number > 0."""
    if not is_number(value):
        raise SceneError(source, key, value, f"must be a number > 0 ({what}), not {type_name(value)}")
    number = float(value)
    if not (math.isfinite(number) and number > 0.0):
        raise SceneError(source, key, value, f"must be a finite number > 0 ({what})")
    return number


def cell_pair(source: str, value: object, key: str = "[body] cell") -> tuple[float, float]:
    """A grid spacing: a number (hx = hy) or a pair [hx, hy], each finite and > 0 (SceneError on ``key``)."""
    allowed = "must be a number > 0 or a pair [hx, hy] of numbers > 0 (grid spacing in m)"
    if is_number(value):
        spacing = float(value)
        if not (math.isfinite(spacing) and spacing > 0.0):
            raise SceneError(source, key, value, allowed)
        return (spacing, spacing)
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) == 2:
        if not all(is_number(item) for item in value):
            raise SceneError(source, key, value, allowed)
        pair = (float(value[0]), float(value[1]))
        if not all(math.isfinite(item) and item > 0.0 for item in pair):
            raise SceneError(source, key, value, allowed)
        return pair
    raise SceneError(source, key, value, allowed)


def point_pair(source: str, key: str, value: object) -> tuple[float, float]:
    """A point [x, y] of finite numbers (m)."""
    allowed = "must be a pair [x, y] of finite numbers (offset in m)"
    if not (isinstance(value, (list, tuple, np.ndarray)) and len(value) == 2):
        raise SceneError(source, key, value, allowed)
    if not all(is_number(item) and math.isfinite(float(item)) for item in value):
        raise SceneError(source, key, value, allowed)
    return (float(value[0]), float(value[1]))
