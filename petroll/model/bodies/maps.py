"""Bodies from sampled data: height maps Z(x, y) (.npy files, rasterised meshes) and, for line contact,
profiles Z(x)."""

from __future__ import annotations

import math
import os
from dataclasses import KW_ONLY, InitVar, dataclass, field

import numpy as np

from petroll.errors import SceneError
from petroll.model.bodies.base import PYTHON_SOURCE, Body, cell_pair, point_pair, positive, type_name


def check_heights(source: str, label: object, heights: object) -> np.ndarray:
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
            label = f"<heights {type_name(self.heights)}>"
        heights = check_heights(source, label, self.heights)
        cell = cell_pair(source, self.cell)
        center = point_pair(source, "[body] center", self.center)
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
    ) -> HeightMap:
        """Load ``heights`` from a NumPy ``.npy`` file (axis 0 along x, axis 1 along y, values in m)."""
        heights = check_heights(source, str(path), read_npy(path, source, "a 2-D array (not .npz)"))
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
        cell = positive(source, "[body] cell", self.cell, "the profile's spacing in m")
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


def read_npy(path: str | os.PathLike, source: str, what: str) -> np.ndarray:
    """The array of a .npy file, or SceneError on "[body] file" (``what``: the array it must hold)."""
    try:
        loaded = np.load(path, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - any read failure is the user's file
        raise SceneError(source, "[body] file", str(path), f"cannot read a .npy file: {exc}") from None
    if not isinstance(loaded, np.ndarray):
        raise SceneError(source, "[body] file", str(path), f"must be a .npy file holding {what}")
    return loaded


