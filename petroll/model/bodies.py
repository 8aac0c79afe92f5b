"""Rigid bodies: the shape of the body's lower surface.

Conventions (all lengths in metres, or any one consistent length unit):

* The half-space surface is z = 0 and the body presses down on it from above.
* A body's lower surface is given by ``Z(x, y) >= 0``: the height of the body's surface above its own
  lowest point, at offsets ``(x, y)`` from the body's reference point (for the symmetric shapes, the
  lowest point itself, so ``Z(0, 0) = 0``).
* Where the body has no surface (past the width of a cylinder, outside a height map) ``Z = +inf``: it can
  never touch there.  Its slope is 0 there.

Evaluation is vectorised: ``x`` and ``y`` are numpy arrays that broadcast against each other (for example
``x`` of shape ``(n, 1)`` and ``y`` of shape ``(1, m)`` give an ``(n, m)`` result).
"""

from __future__ import annotations

import abc
import math
import numbers
import os
import pathlib
from dataclasses import KW_ONLY, InitVar, dataclass, field

import numpy as np

from petroll.errors import MISSING, SceneError

__all__ = [
    "Body",
    "Sphere",
    "Ellipsoid",
    "Cylinder",
    "HeightMap",
    "CylinderSection",
    "HeightProfile",
    "mesh_height_map",
    "make_body",
    "BODY_KEYS",
]

PYTHON_SOURCE = "<python>"


# ----------------------------------------------------------------------------------------------------------
# validation helpers


def _is_number(value: object) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _type_name(value: object) -> str:
    return type(value).__name__


def _positive(source: str, key: str, value: object, what: str = "a length in m") -> float:
    """``value`` as a float, or SceneError unless it is a finite number > 0."""
    if not _is_number(value):
        raise SceneError(source, key, value, f"must be a number > 0 ({what}), not {_type_name(value)}")
    number = float(value)
    if not (math.isfinite(number) and number > 0.0):
        raise SceneError(source, key, value, f"must be a finite number > 0 ({what})")
    return number


def _cell_pair(source: str, value: object) -> tuple[float, float]:
    """A grid spacing: a number (hx = hy) or a pair [hx, hy], each finite and > 0."""
    key = "[body] cell"
    allowed = "must be a number > 0 or a pair [hx, hy] of numbers > 0 (grid spacing in m)"
    if _is_number(value):
        spacing = float(value)
        if not (math.isfinite(spacing) and spacing > 0.0):
            raise SceneError(source, key, value, allowed)
        return (spacing, spacing)
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) == 2:
        if not all(_is_number(item) for item in value):
            raise SceneError(source, key, value, allowed)
        pair = (float(value[0]), float(value[1]))
        if not all(math.isfinite(item) and item > 0.0 for item in pair):
            raise SceneError(source, key, value, allowed)
        return pair
    raise SceneError(source, key, value, allowed)


def _point_pair(source: str, key: str, value: object) -> tuple[float, float]:
    allowed = "must be a pair [x, y] of finite numbers (offset in m)"
    if not (isinstance(value, (list, tuple, np.ndarray)) and len(value) == 2):
        raise SceneError(source, key, value, allowed)
    if not all(_is_number(item) and math.isfinite(float(item)) for item in value):
        raise SceneError(source, key, value, allowed)
    return (float(value[0]), float(value[1]))


# ----------------------------------------------------------------------------------------------------------
# profile helpers


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


# ----------------------------------------------------------------------------------------------------------
# bodies


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


@dataclass(frozen=True)
class _Round(Body):
    """A body described by one ``radius`` (m), which is also its radius hint."""

    radius: float
    _: KW_ONLY
    source: InitVar[str] = PYTHON_SOURCE

    def __post_init__(self, source: str) -> None:
        object.__setattr__(self, "radius", _positive(source, "[body] radius", self.radius))

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
        object.__setattr__(self, "radius_x", _positive(source, "[body] radius_x", self.radius_x))
        object.__setattr__(self, "radius_y", _positive(source, "[body] radius_y", self.radius_y))

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
        radius = _positive(source, "[body] radius", self.radius)
        width = _positive(source, "[body] width", self.width)
        edge = self.edge_radius
        if not _is_number(edge):
            raise SceneError(
                source,
                "[body] edge_radius",
                edge,
                f"must be a number >= 0 (length in m), not {_type_name(edge)}",
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


def _check_heights(source: str, label: object, heights: object) -> np.ndarray:
    """Heights as a 2-D float array (own copy), or SceneError on "[body] file" (``label`` is its value)."""
    key = "[body] file"
    try:
        array = np.array(heights, dtype=float)
    except (TypeError, ValueError) as exc:
        raise SceneError(source, key, label, f"height map must be a 2-D array of numbers ({exc})") from None
    if array.ndim != 2:
        raise SceneError(
            source, key, label,
            f"height map must be a 2-D array, got {array.ndim}-D shape {array.shape}",
        )
    if array.shape[0] < 2 or array.shape[1] < 2:
        raise SceneError(
            source, key, label,
            f"height map needs at least 2 samples along each axis, got shape {array.shape}",
        )
    if np.isnan(array).any() or np.isneginf(array).any():
        raise SceneError(
            source, key, label,
            "height map values must be finite numbers (or +inf for no surface), found NaN or -inf",
        )
    finite = np.isfinite(array)
    if not (finite[:-1, :-1] & finite[1:, :-1] & finite[:-1, 1:] & finite[1:, 1:]).any():
        raise SceneError(
            source, key, label,
            "height map has no grid cell with four finite corners (no surface at all)",
        )
    return array


@dataclass(frozen=True, eq=False)
class HeightMap(Body):
    """A body given by sampled heights, bilinearly interpolated.

    ``heights[i, j]`` (m, positive upward) is the lower-surface height at grid point i along x, j along y,
    spacing ``cell`` = (hx, hy) m (a number means hx = hy).  The midpoint of the map's extent (the box
    spanned by its sample points) sits at offset ``center`` (m) from the body reference point.

    Z = heights - min(heights), bilinearly interpolated, +inf outside the extent.  Entries equal to +inf
    mean "no surface there" (as produced by :func:`mesh_height_map` where no triangle covers a point): Z
    is +inf in every grid cell with such a corner.  NaN and -inf are refused.
    """

    heights: np.ndarray
    cell: tuple[float, float] | float
    center: tuple[float, float] = (0.0, 0.0)
    _: KW_ONLY
    source: InitVar[str] = PYTHON_SOURCE
    _z: np.ndarray = field(init=False, repr=False)
    _zf: np.ndarray = field(init=False, repr=False)
    _ok: np.ndarray = field(init=False, repr=False)
    _origin: tuple[float, float] = field(init=False, repr=False)
    _radius_hint: float = field(init=False, repr=False)

    def __post_init__(self, source: str) -> None:
        shape = getattr(self.heights, "shape", None)
        if shape is not None:
            label = f"<heights array of shape {tuple(shape)}>"
        else:
            label = f"<heights {_type_name(self.heights)}>"
        heights = _check_heights(source, label, self.heights)
        cell = _cell_pair(source, self.cell)
        center = _point_pair(source, "[body] center", self.center)
        heights.setflags(write=False)
        finite = np.isfinite(heights)
        z = heights - heights[finite].min()
        z.setflags(write=False)
        nx, ny = heights.shape
        origin = (center[0] - 0.5 * (nx - 1) * cell[0], center[1] - 0.5 * (ny - 1) * cell[1])
        set_ = object.__setattr__
        set_(self, "heights", heights)
        set_(self, "cell", cell)
        set_(self, "center", center)
        set_(self, "_z", z)
        set_(self, "_zf", np.where(finite, z, 0.0))
        set_(self, "_ok", finite[:-1, :-1] & finite[1:, :-1] & finite[:-1, 1:] & finite[1:, 1:])
        set_(self, "_origin", origin)
        set_(self, "_radius_hint", self._estimate_radius())

    @classmethod
    def from_npy(
        cls,
        path: str | os.PathLike,
        cell: tuple[float, float] | float,
        *,
        center: tuple[float, float] = (0.0, 0.0),
        source: str = PYTHON_SOURCE,
    ) -> "HeightMap":
        """Load ``heights`` from a NumPy ``.npy`` file (axis 0 along x, axis 1 along y, values in m)."""
        heights = _check_heights(source, str(path), _read_npy(path, source, "a 2-D array (not .npz)"))
        return cls(heights, cell, center, source=source)

    # -- geometry ------------------------------------------------------------------------------------------

    def _locate(self, coord: np.ndarray, axis: int):
        """Cell index, fraction in [0, 1] and inside-mask of coordinates along one axis."""
        n = self._z.shape[axis]
        f = (coord - self._origin[axis]) / self.cell[axis]
        tol = 1e-9  # in cells: the sample points themselves count as inside despite rounding
        inside = (f >= -tol) & (f <= (n - 1) + tol)
        fc = np.where(inside, np.clip(f, 0.0, n - 1), 0.0)
        i = np.clip(np.floor(fc).astype(np.intp), 0, n - 2)
        return i, fc - i, inside

    def _corners(self, x, y):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        i, u, in_x = self._locate(x, 0)
        j, v, in_y = self._locate(y, 1)
        zf = self._zf
        corners = (zf[i, j], zf[i + 1, j], zf[i, j + 1], zf[i + 1, j + 1])
        valid = in_x & in_y & self._ok[i, j]
        return corners, u, v, valid

    def height(self, x, y):
        (z00, z10, z01, z11), u, v, valid = self._corners(x, y)
        z = (1.0 - u) * ((1.0 - v) * z00 + v * z01) + u * ((1.0 - v) * z10 + v * z11)
        return np.where(valid, z, np.inf)

    def slope(self, x, y):
        (z00, z10, z01, z11), u, v, valid = self._corners(x, y)
        hx, hy = self.cell
        dx = ((1.0 - v) * (z10 - z00) + v * (z11 - z01)) / hx
        dy = ((1.0 - u) * (z01 - z00) + u * (z11 - z10)) / hy
        return np.where(valid, dx, 0.0), np.where(valid, dy, 0.0)

    def _estimate_radius(self) -> float:
        z = self._z
        hx, hy = self.cell
        fallback = 0.5 * max((z.shape[0] - 1) * hx, (z.shape[1] - 1) * hy)
        i, j = np.unravel_index(np.argmin(np.where(np.isfinite(z), z, np.inf)), z.shape)
        radii = []
        for axis, (k, h) in enumerate(((i, hx), (j, hy))):
            line = z[:, j] if axis == 0 else z[i, :]
            n = line.size
            # a wide stencil (up to n/8 samples) smooths facets and roughness; narrow it until finite
            step = max(1, min(k, n - 1 - k, n // 8))
            while step > 0 and not (np.isfinite(line[k - step]) and np.isfinite(line[k + step])):
                step //= 2
            if step == 0 or k - step < 0 or k + step > n - 1:
                continue
            curvature = (line[k + step] - 2.0 * line[k] + line[k - step]) / (step * h) ** 2
            if np.isfinite(curvature) and curvature > 0.0:
                radii.append(1.0 / curvature)
        if not radii:
            return fallback
        return float(math.sqrt(radii[0] * radii[-1]))

    @property
    def radius_hint(self) -> float:
        """sqrt(Rx Ry) from discrete curvatures (second differences over up to 1/8 of the map) at the
        lowest sample (the one radius if only one is positive); half the larger extent if neither is."""
        return self._radius_hint


# ----------------------------------------------------------------------------------------------------------
# line contact (plane strain): profiles Z(x), the same for every y


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


@dataclass(frozen=True, eq=False)
class HeightProfile(Body):
    """A line-contact body given by sampled heights ``heights[i]`` (m) at spacing ``cell`` (m) along x,
    linearly interpolated, independent of y; Z = heights - min(heights), +inf outside the samples (and in
    a sample interval with a +inf end). The middle of the samples sits at the body's reference point."""

    heights: np.ndarray
    cell: float
    _: KW_ONLY
    source: InitVar[str] = PYTHON_SOURCE
    _map: HeightMap = field(init=False, repr=False)

    def __post_init__(self, source: str) -> None:
        label = f"<profile of shape {np.shape(self.heights)}>"
        line = np.asarray(self.heights, dtype=float) if np.ndim(self.heights) == 1 else None
        if line is None:
            raise SceneError(source, "[body] file", label, "line contact: the profile must be a 1-D array "
                             "of heights (m) along x")
        cell = _positive(source, "[body] cell", self.cell, "the profile's spacing in m")
        # the profile as a two-column height map (equal columns, any spacing along y): its x interpolation
        # is the profile's; y is always taken at the first column
        set_ = object.__setattr__
        set_(self, "_map", HeightMap(np.stack([line, line], axis=1), (cell, 1.0), source=source))
        set_(self, "heights", self._map.heights[:, 0])
        set_(self, "cell", cell)

    def height(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return self._map.height(x, np.full(x.shape, -0.5))

    def slope(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        return self._map.slope(x, np.full(x.shape, -0.5))[0], np.zeros(x.shape)

    @property
    def radius_hint(self) -> float:
        return self._map.radius_hint


# ----------------------------------------------------------------------------------------------------------
# triangle meshes


def _read_triangles(path: str | os.PathLike, source: str) -> tuple[np.ndarray, np.ndarray]:
    import meshio  # imported lazily: only mesh bodies need it

    try:
        mesh = meshio.read(os.fspath(path))
    except Exception as exc:  # noqa: BLE001 - any read failure is the user's file
        reason = str(exc) or type(exc).__name__
        raise SceneError(source, "[body] file", str(path), f"cannot read a surface mesh: {reason}") from None
    blocks = [np.asarray(block.data, dtype=np.intp) for block in mesh.cells if block.type == "triangle"]
    blocks = [block for block in blocks if block.size]
    if not blocks:
        raise SceneError(
            source, "[body] file", str(path),
            "the mesh has no triangles (other cell types are ignored)",
        )
    points = np.asarray(mesh.points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise SceneError(source, "[body] file", str(path), "the mesh must have 3-D points (x, y, z)")
    triangles = np.concatenate(blocks, axis=0)
    if not np.isfinite(points[np.unique(triangles)]).all():
        raise SceneError(
            source, "[body] file", str(path),
            "the mesh has points with NaN or infinite coordinates",
        )
    return points, triangles


_RASTER_CHUNK = 2_000_000  # candidate (triangle, grid point) pairs handled at once: bounds the memory


def mesh_height_map(
    path: str | os.PathLike, cell: tuple[float, float] | float, *, source: str = PYTHON_SOURCE
) -> HeightMap:
    """Rasterise the lowest surface of a triangle mesh (any format meshio reads; lengths in m) to a HeightMap.

    The body reference point is the x-y position of the mesh's lowest vertex (the first one if several
    share the lowest z), so a mesh of a sphere gives the same Z as :class:`Sphere`.  The grid has spacing
    ``cell`` = (hx, hy), contains that vertex as a grid point and covers the mesh's x-y bounding box.  A
    grid point takes the minimum over triangles whose x-y projection contains it of the barycentric z;
    points that no triangle covers get +inf (no surface).  Non-triangle cells and triangles with no x-y
    area (vertical walls) are ignored.
    """
    hx, hy = _cell_pair(source, cell)
    points, triangles = _read_triangles(path, source)
    used = np.unique(triangles)
    lowest = used[np.argmin(points[used, 2])]
    vx, vy = points[lowest, 0], points[lowest, 1]

    p = points[triangles]  # (m, 3 vertices, xyz)
    x, y, z = p[..., 0] - vx, p[..., 1] - vy, p[..., 2]
    det = (x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0])
    scale = (np.ptp(x, axis=1) + np.ptp(y, axis=1)) ** 2
    keep = np.abs(det) > 1e-12 * scale
    if not keep.any():
        raise SceneError(
            source, "[body] file", str(path),
            "the mesh has no triangle with a non-zero x-y area",
        )
    x, y, z, det = x[keep], y[keep], z[keep], det[keep]

    # grid points at k * h (k integer) around the lowest vertex, covering the x-y bounding box
    tol = 1e-9
    kx0 = math.ceil(x.min() / hx - tol)
    kx1 = math.floor(x.max() / hx + tol)
    ky0 = math.ceil(y.min() / hy - tol)
    ky1 = math.floor(y.max() / hy + tol)
    nx, ny = kx1 - kx0 + 1, ky1 - ky0 + 1
    if nx < 2 or ny < 2:
        raise SceneError(
            source,
            "[body] cell",
            cell,
            f"cell too large for the mesh: the grid would have {nx} x {ny} points, needs 2 x 2",
        )
    if nx * ny > 50_000_000:
        raise SceneError(
            source, "[body] cell", cell,
            f"cell too small for the mesh: the grid would have {nx} x {ny} points",
        )

    # index ranges (relative to the grid) of the grid points in each triangle's bounding box
    i0 = np.clip(np.ceil(x.min(axis=1) / hx - tol).astype(np.int64) - kx0, 0, nx - 1)
    i1 = np.clip(np.floor(x.max(axis=1) / hx + tol).astype(np.int64) - kx0, 0, nx - 1)
    j0 = np.clip(np.ceil(y.min(axis=1) / hy - tol).astype(np.int64) - ky0, 0, ny - 1)
    j1 = np.clip(np.floor(y.max(axis=1) / hy + tol).astype(np.int64) - ky0, 0, ny - 1)
    ni = np.maximum(i1 - i0 + 1, 0)
    nj = np.maximum(j1 - j0 + 1, 0)
    count = ni * nj

    grid = np.full(nx * ny, np.inf)
    chunk = _RASTER_CHUNK
    ends = np.cumsum(count)
    start_tri = 0
    while start_tri < len(count):
        # take triangles until about `chunk` candidate points (at least one triangle)
        base = ends[start_tri - 1] if start_tri else 0
        stop_tri = max(int(np.searchsorted(ends, base + chunk, side="right")), start_tri + 1)
        sel = slice(start_tri, stop_tri)
        start_tri = stop_tri
        counts = count[sel]
        total = int(counts.sum())
        if total == 0:
            continue
        tri = np.repeat(np.arange(sel.start, sel.stop), counts)
        first = np.repeat(np.cumsum(counts) - counts, counts)
        local = np.arange(total) - first
        nj_t = nj[tri]
        gi = i0[tri] + local // nj_t
        gj = j0[tri] + local % nj_t
        px = (gi + kx0) * hx
        py = (gj + ky0) * hy
        x0, y0 = x[tri, 0], y[tri, 0]
        dx, dy = px - x0, py - y0
        d = det[tri]
        l1 = (dx * (y[tri, 2] - y0) - (x[tri, 2] - x0) * dy) / d
        l2 = ((x[tri, 1] - x0) * dy - dx * (y[tri, 1] - y0)) / d
        l0 = 1.0 - l1 - l2
        eps = 1e-9
        inside = (l0 >= -eps) & (l1 >= -eps) & (l2 >= -eps)
        if not inside.any():
            continue
        zz = (l0 * z[tri, 0] + l1 * z[tri, 1] + l2 * z[tri, 2])[inside]
        flat = (gi * ny + gj)[inside]
        order = np.lexsort((zz, flat))
        flat, zz = flat[order], zz[order]
        head = np.ones(flat.size, dtype=bool)
        head[1:] = flat[1:] != flat[:-1]
        flat, zz = flat[head], zz[head]
        grid[flat] = np.minimum(grid[flat], zz)

    heights = grid.reshape(nx, ny)
    center = (0.5 * (kx0 + kx1) * hx, 0.5 * (ky0 + ky1) * hy)
    finite = np.isfinite(heights)
    if not (finite[:-1, :-1] & finite[1:, :-1] & finite[:-1, 1:] & finite[1:, 1:]).any():
        raise SceneError(
            source,
            "[body] cell",
            cell,
            "cell too large for the mesh: no grid cell lies fully on the mesh surface",
        )
    return HeightMap(heights, (hx, hy), center, source=source)


# ----------------------------------------------------------------------------------------------------------
# scene tables

BODY_KEYS: dict[str, dict[str, str]] = {
    "sphere": {
        "radius": "radius of the sphere, m (required)",
    },
    "ellipsoid": {
        "radius_x": "principal radius of curvature along x at the lowest point, m (required)",
        "radius_y": "principal radius of curvature along y at the lowest point, m (required)",
    },
    "cylinder": {
        "radius": "radius of the cylinder, m (required)",
        "width": "length of the cylinder along its axis, m (required)",
        "edge_radius": "radius of the rounded edges, m, 0 <= edge_radius <= width/2 (default 0: sharp edges)",
        "axis": 'direction of the cylinder axis, "x" or "y" (default "y": rolls along x)',
    },
    "heightmap": {
        "file": ".npy file of lower-surface heights in m, axis 0 along x, axis 1 along y; "
        "relative to the scene file (required)",
        "cell": "grid spacing of the map, m: a number or [hx, hy] (required)",
    },
    "mesh": {
        "file": "triangle surface mesh (any format meshio reads, e.g. .stl, .obj), lengths in m; "
        "relative to the scene file (required)",
        "cell": "spacing of the grid the lowest surface is rasterised on, m: a number or [hx, hy] (required)",
    },
}

LINE_BODY_KEYS: dict[str, dict[str, str]] = {
    "cylinder": {"radius": "radius of the cylinder, m (required; line contact: no width, edge_radius, axis)"},
    "heightmap": {
        "file": "line contact: .npy file of a 1-D profile of lower-surface heights in m along x, "
        "relative to the scene file (required)",
        "cell": "line contact: spacing of the profile along x, m (required)",
    },
}
"""The shapes and keys of a line-contact (plane-strain) scene's [body]."""

_DEFAULTS: dict[str, dict[str, object]] = {"cylinder": {"edge_radius": 0.0, "axis": "y"}}
_COMMON_KEYS = ("shape", "position")  # position is read by the scene reader, not here


def _profile_from_npy(path: pathlib.Path, cell: object, source: str) -> HeightProfile:
    """A :class:`HeightProfile` from a .npy file holding a 1-D array (SceneError naming [body] file)."""
    loaded = _read_npy(path, source, "a 1-D array of heights (m) along x")
    if loaded.ndim != 1:
        raise SceneError(source, "[body] file", str(path), "line contact: must be a .npy file holding one "
                         f"1-D array of heights (m) along x, got shape {getattr(loaded, 'shape', None)}")
    return HeightProfile(loaded, cell, source=source)


def _read_npy(path: str | os.PathLike, source: str, what: str) -> np.ndarray:
    """The array of a .npy file, or SceneError on "[body] file" (``what``: the array it must hold)."""
    try:
        loaded = np.load(path, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - any read failure is the user's file
        raise SceneError(source, "[body] file", str(path), f"cannot read a .npy file: {exc}") from None
    if not isinstance(loaded, np.ndarray):
        raise SceneError(source, "[body] file", str(path), f"must be a .npy file holding {what}")
    return loaded


def _resolve_file(source: str, value: object, base_dir: pathlib.Path) -> pathlib.Path:
    if not isinstance(value, (str, os.PathLike)) or not os.fspath(value):
        raise SceneError(source, "[body] file", value, f"must be a path string, not {_type_name(value)}")
    path = pathlib.Path(value)
    if not path.is_absolute():
        path = pathlib.Path(base_dir) / path
    return path


def make_body(table: dict, base_dir: pathlib.Path, source: str, line: bool = False) -> Body:
    """Build the body of a scene's ``[body]`` table (``shape`` plus that shape's keys, see BODY_KEYS).

    ``line``: a line-contact (plane-strain) scene: only the shapes of LINE_BODY_KEYS, as profiles Z(x).

    ``position`` may be present and is ignored here.  Relative file paths are resolved against
    ``base_dir``.  Raises SceneError for an unknown shape or key, a missing key, a wrong type or a bad value.
    """
    catalogue = LINE_BODY_KEYS if line else BODY_KEYS
    shapes = ", ".join(catalogue)
    if "shape" not in table:
        raise SceneError(source, "[body] shape", MISSING, f"required, one of: {shapes}")
    shape = table["shape"]
    if not isinstance(shape, str) or shape not in catalogue:
        where = " for line contact ([grid] without ny and y)" if line else ""
        raise SceneError(source, "[body] shape", shape, f"must be one of{where}: {shapes}")
    keys = catalogue[shape]
    for key in table:
        if key not in keys and key not in _COMMON_KEYS:
            allowed = ", ".join([*_COMMON_KEYS, *keys])
            where = " in line contact" if line else ""
            raise SceneError(
                source, f"[body] {key}", table[key],
                f"unknown key for shape {shape!r}{where}; allowed keys: {allowed}",
            )
    defaults = _DEFAULTS.get(shape, {})
    values = {}
    for key in keys:
        if key in table:
            values[key] = table[key]
        elif key in defaults:
            values[key] = defaults[key]
        else:
            raise SceneError(source, f"[body] {key}", MISSING, f"required for shape {shape!r}: {keys[key]}")

    if line and shape == "cylinder":
        return CylinderSection(values["radius"], source=source)
    if line:
        return _profile_from_npy(_resolve_file(source, values["file"], base_dir), values["cell"], source)
    if shape == "sphere":
        return Sphere(values["radius"], source=source)
    if shape == "ellipsoid":
        return Ellipsoid(values["radius_x"], values["radius_y"], source=source)
    if shape == "cylinder":
        return Cylinder(
            values["radius"], values["width"], values["edge_radius"], values["axis"], source=source
        )
    path = _resolve_file(source, values["file"], base_dir)
    cell = _cell_pair(source, values["cell"])
    if shape == "heightmap":
        return HeightMap.from_npy(path, cell, source=source)
    return mesh_height_map(path, cell, source=source)
