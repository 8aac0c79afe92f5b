"""Bodies given by formulas: sphere, ellipsoid, finite cylinder (roller) and, for line contact, the
cylinder's section. Heights and slopes are exact (closed forms, evaluated without cancellation)."""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, InitVar, dataclass

import numpy as np

from petroll.errors import SceneError
from petroll.model.bodies.base import PYTHON_SOURCE, Body, is_number, positive, type_name


def _arc(s: np.ndarray, radius: float) -> np.ndarray:
    """Circular arc R - sqrt(R^2 - s^2) for |s| < R, continued as R + (|s| - R) beyond.

    Evaluated as s^2 / (R + sqrt((R - s)(R + s))): no cancellation when s << R (R - sqrt(R^2 - s^2) loses
    all digits once s/R < 1e-8, e.g. a 3 um contact under a 10 m radius) and no overflow of R^2."""
    a = np.abs(s)
    inside = a < radius
    root = np.sqrt(np.where(inside, radius - a, 0.0)) * np.sqrt(np.where(inside, radius + a, 0.0))
    with np.errstate(over="ignore"):  # heights beyond 1e308 m are +inf
        return np.where(inside, a * (a / (radius + root)), a)


def _arc_slope(s: np.ndarray, radius: float) -> np.ndarray:
    """d/ds of :func:`_arc`: s / sqrt(R^2 - s^2) inside, sign(s) (unit slope) for |s| >= R."""
    a = np.abs(s)
    inside = a < radius
    root = np.sqrt(np.where(inside, radius - a, 1.0)) * np.sqrt(np.where(inside, radius + a, 1.0))
    return np.where(inside, s / root, np.sign(s))


@dataclass(frozen=True)
class _Round(Body):
    """A body described by one ``radius`` (m), which is also its radius hint."""

    radius: float
    _: KW_ONLY
    source: InitVar[str] = PYTHON_SOURCE

    def __post_init__(self, source: str) -> None:
        object.__setattr__(self, "radius", positive(source, "[body] radius", self.radius))

    @property
    def radius_hint(self) -> float:
        return self.radius


@dataclass(frozen=True)
class Sphere(_Round):
    """Exact sphere of ``radius`` m: Z = R - sqrt(R^2 - r^2) for r < R, and R + (r - R) for r >= R.

    The continuation past r = R (unit slope) keeps Z finite and continuous; a valid scene never touches
    there.
    """

    def height(self, x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return _arc(np.hypot(x, y), self.radius)

    def slope(self, x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        r = np.hypot(x, y)
        inside = r < self.radius
        # (dZ/dr) / r: 1/sqrt(R^2 - r^2) inside, 1/r on the unit-slope continuation (where r >= R > 0)
        denom = np.where(inside, np.sqrt(np.where(inside, self.radius - r, 1.0))
                         * np.sqrt(np.where(inside, self.radius + r, 1.0)), r)
        return x / denom, y / denom


@dataclass(frozen=True)
class Ellipsoid(Body):
    """Elliptic paraboloid Z = x^2 / (2 Rx) + y^2 / (2 Ry), with Rx = ``radius_x``, Ry = ``radius_y`` in m.

    The "two radii" are the two principal radii of curvature at the lowest point (along x and along y),
    as in Hertz's theory; the surface is their paraboloid, not an exact ellipsoid.
    """

    radius_x: float
    radius_y: float
    _: KW_ONLY
    source: InitVar[str] = PYTHON_SOURCE

    def __post_init__(self, source: str) -> None:
        object.__setattr__(self, "radius_x", positive(source, "[body] radius_x", self.radius_x))
        object.__setattr__(self, "radius_y", positive(source, "[body] radius_y", self.radius_y))

    def height(self, x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return x * x / (2.0 * self.radius_x) + y * y / (2.0 * self.radius_y)

    def slope(self, x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        shape = np.broadcast(x, y).shape
        return (
            np.broadcast_to(x / self.radius_x, shape).copy(),
            np.broadcast_to(y / self.radius_y, shape).copy(),
        )

    @property
    def radius_hint(self) -> float:
        return math.sqrt(self.radius_x * self.radius_y)


@dataclass(frozen=True)
class Cylinder(Body):
    """Finite cylinder (roller) of ``radius`` R and ``width`` W in m, axis along ``axis`` ("y" or "x").

    With s the coordinate across the axis and t the one along it (axis "y": s = x, t = y, so it rolls
    along x), Z = arc(s) + edge(t):

    * arc(s) = R - sqrt(R^2 - s^2) for |s| < R, continued as R + (|s| - R) beyond;
    * edge(t) = 0 on the flat part |t| <= W/2 - e, e - sqrt(e^2 - (|t| - (W/2 - e))^2) on the rounded
      edges (e = ``edge_radius``, 0 for sharp edges), and +inf for |t| > W/2.

    Where a circular arc ends (|s| >= R, or the rim |t| = W/2 of a rounded edge) the slope is taken from
    the unit-slope continuation, so the slope is always finite.
    """

    radius: float
    width: float
    edge_radius: float = 0.0
    axis: str = "y"
    _: KW_ONLY
    source: InitVar[str] = PYTHON_SOURCE

    def __post_init__(self, source: str) -> None:
        radius = positive(source, "[body] radius", self.radius)
        width = positive(source, "[body] width", self.width)
        edge = self.edge_radius
        if not is_number(edge):
            raise SceneError(
                source,
                "[body] edge_radius",
                edge,
                f"must be a number >= 0 (length in m), not {type_name(edge)}",
            )
        edge = float(edge)
        if not (math.isfinite(edge) and 0.0 <= edge <= width / 2.0):
            raise SceneError(
                source,
                "[body] edge_radius",
                self.edge_radius,
                f"must be a number in [0, width/2] = [0, {width / 2.0!r}] (m)",
            )
        if not (isinstance(self.axis, str) and self.axis in ("x", "y")):
            raise SceneError(
                source, "[body] axis", self.axis,
                'must be "x" or "y" (direction of the cylinder axis)',
            )
        object.__setattr__(self, "radius", radius)
        object.__setattr__(self, "width", width)
        object.__setattr__(self, "edge_radius", edge)

    def _across_along(self, x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        return (x, y) if self.axis == "y" else (y, x)

    def _edge(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(edge(t), d edge/dt) along the axis; edge is +inf (slope 0) past the half-width."""
        half = self.width / 2.0
        e = self.edge_radius
        a = np.abs(t)
        outside = a > half
        if e > 0.0:
            u = np.maximum(a - (half - e), 0.0)  # distance into the rounded edge
            rim = u >= e
            root = np.sqrt(np.where(rim, 1.0, (e - u) * (e + u)))
            z = np.where(rim, e, u * (u / (e + np.where(rim, 0.0, root))))  # e - root, without cancellation
            dz = np.sign(t) * np.where(rim, 1.0, u / root)
        else:
            z = np.zeros_like(a)
            dz = np.zeros_like(a)
        return np.where(outside, np.inf, z), np.where(outside, 0.0, dz)

    def height(self, x, y):
        s, t = self._across_along(x, y)
        edge, _ = self._edge(t)
        return _arc(s, self.radius) + edge

    def slope(self, x, y):
        s, t = self._across_along(x, y)
        edge, dedge = self._edge(t)
        shape = np.broadcast(s, t).shape
        ds = np.where(np.isinf(edge), 0.0, _arc_slope(s, self.radius))
        ds = np.broadcast_to(ds, shape).copy()
        dt = np.broadcast_to(dedge, shape).copy()
        return (ds, dt) if self.axis == "y" else (dt, ds)

    @property
    def radius_hint(self) -> float:
        return self.radius


@dataclass(frozen=True)
class CylinderSection(_Round):
    """A cylinder of ``radius`` R (m) in line contact (plane strain; axis along Y, infinitely long):
    Z = R - sqrt(R^2 - x^2) for |x| < R, continued as R + (|x| - R) beyond; independent of y."""

    def height(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return _arc(x, self.radius)

    def slope(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return _arc_slope(x, self.radius), np.zeros(x.shape)
