"""Bodies from sampled data: height maps Z(x, y) (.npy files, rasterised meshes) and, for line contact,
profiles Z(x)."""

from __future__ import annotations

import math
import os
from dataclasses import KW_ONLY, InitVar, dataclass, field

import numpy as np

from petroll.errors import SceneError
from petroll.model.bodies.base import ON_SAMPLE, PYTHON_SOURCE, Body, cell_pair, point_pair, positive, type_name
from petroll.model.limits import heights_out_of_scale
from petroll.model.topography import read_npy



def check_heights(source: str, label: object, heights: object) -> np.ndarray:
    """Heights as a 2-D float array (own copy) within petroll.model.limits.MAGNITUDES, or SceneError on
    "[body] file" (``label`` is its value)."""
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
    if (why := heights_out_of_scale(array)) is not None:
        raise SceneError(source, key, label, why)
    finite = np.isfinite(array)
    if not (finite[:-1, :-1] & finite[1:, :-1] & finite[:-1, 1:] & finite[1:, 1:]).any():
        raise SceneError(
            source, key, label,
            "height map has no grid cell with four finite corners (no surface at all)",
        )
    return array


@dataclass(frozen=True, eq=False)
class HeightMap(Body):
    """A body given by sampled heights, interpolated by a bicubic spline.

    ``heights[i, j]`` (m, positive upward) is the lower-surface height at grid point i along x, j along y,
    spacing ``cell`` = (hx, hy) m (a number means hx = hy).  The midpoint of the map's extent (the box
    spanned by its sample points) sits at offset ``center`` (m) from the body reference point.

    Z = S - min S, S the interpolating tensor-product cubic spline of the samples (scipy's
    RectBivariateSpline with s = 0: not-a-knot ends; quadratic or linear along an axis of 3 or 2 samples),
    min S its lowest point (found by a bounded minimisation around the lowest samples on the spline's local
    pieces, so that Z >= 0 wherever the samples fall); the slope is S's derivative.  S is twice continuously
    differentiable, so heights and slopes do not depend on where the points they are evaluated at fall
    between the samples (cubic polynomials are reproduced exactly; on a smooth surface heights are accurate
    to O(h^4) and slopes to O(h^3)).  +inf outside the extent.  Entries equal to +inf mean "no surface there"
    (as produced by :func:`mesh_height_map` where no triangle covers a point): Z is +inf in every grid cell
    with such a corner (the spline is fitted with them replaced by their nearest finite sample).  NaN and
    -inf are refused.

    Cost: heights asked for at the samples themselves (within :data:`ON_SAMPLE` of a cell) are the samples
    (less the lowest point), slopes there the splines' through the lines of samples they lie on
    (:func:`spline_slopes`, one banded solve per axis, kept); the spline is fitted on first use elsewhere
    (FITPACK, O(samples) once), slopes on a lattice over a small part of the map (:data:`SMALL_BOX`) are
    read from its local piece there, and its derivatives' splines are made on the first slopes asked for
    over more; every evaluation after that is local (each point reads its 4 x 4 coefficients).
    """

    heights: np.ndarray
    cell: tuple[float, float] | float
    center: tuple[float, float] = (0.0, 0.0)
    _: KW_ONLY
    source: InitVar[str] = PYTHON_SOURCE
    _splines: dict = field(init=False, repr=False)  # (dx, dy): S's spline or its derivative's, once made;
    # ("at samples", axis): S's slopes at every sample
    _lowest: float = field(init=False, repr=False)
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
        nx, ny = heights.shape
        origin = (center[0] - 0.5 * (nx - 1) * cell[0], center[1] - 0.5 * (ny - 1) * cell[1])
        set_ = object.__setattr__
        set_(self, "heights", heights)
        set_(self, "cell", cell)
        set_(self, "center", center)
        set_(self, "_splines", {})
        set_(self, "_ok", finite[:-1, :-1] & finite[1:, :-1] & finite[:-1, 1:] & finite[1:, 1:])
        set_(self, "_origin", origin)
        set_(self, "_lowest", self._lowest_point())
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

    def _cells(self, u: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Along one axis, for coordinates ``u`` (m) from the first sample: the sample interval's index, the
        coordinate clipped to the samples' span, and the inside mask."""
        n, h = self.heights.shape[axis], self.cell[axis]
        f = u / h  # the sample points themselves count as inside despite rounding
        inside = (f >= -ON_SAMPLE) & (f <= (n - 1) + ON_SAMPLE)
        clipped = np.clip(np.where(inside, u, 0.0), 0.0, (n - 1) * h)
        return np.clip(np.floor(clipped / h).astype(np.intp), 0, n - 2), clipped, inside

    def _evaluate(self, x, y, dx: int, dy: int) -> tuple[np.ndarray, np.ndarray]:
        """S's derivative of orders (dx, dy) at (x, y) m from the reference point (broadcast; 0 where the
        map has no surface) and where it has one. Heights at the samples themselves are the samples. Points
        on a grid (x a column, y a row, both sorted where inside the map) are evaluated as a tensor
        product, about 30 times faster than point by point."""
        u = np.asarray(x, dtype=float) - self._origin[0]
        v = np.asarray(y, dtype=float) - self._origin[1]
        i, uc, in_x = self._cells(u, 0)
        j, vc, in_y = self._cells(v, 1)
        valid = in_x & in_y & self._ok[i, j]
        values = np.zeros(valid.shape)
        if not valid.any():
            return values, valid
        if dx + dy <= 1 and (at := self._at_samples(uc, vc, in_x, in_y)) is not None:
            if not (dx or dy):
                return np.where(valid, self.heights[at], 0.0), valid
            if (slopes := self._slopes_at_samples(at, 0 if dx else 1)) is not None:
                return np.where(valid, slopes, 0.0), valid
        if (u.ndim == 2 and v.ndim == 2 and u.shape[1] == 1 and v.shape[0] == 1
                and np.all(np.diff(uc[in_x[:, 0], 0]) >= 0) and np.all(np.diff(vc[0, in_y[0]]) >= 0)):
            rows, cols = in_x[:, 0], in_y[0]
            values[np.ix_(rows, cols)] = self._spline_at(uc[rows, 0], vc[0, cols], dx, dy, grid=True)
            values[~valid] = 0.0
        else:
            uc, vc = np.broadcast_arrays(uc, vc)
            values[valid] = self._spline_at(uc[valid], vc[valid], dx, dy, grid=False)
        return values, valid

    def _at_samples(self, uc: np.ndarray, vc: np.ndarray, in_x: np.ndarray, in_y: np.ndarray) -> tuple | None:
        """The samples' indices (a pair of arrays that broadcast like the points) where every coordinate
        (``uc``, ``vc``) from the first sample inside the map along its axis (``in_x``, ``in_y``) lies on a
        sample (within :data:`ON_SAMPLE` of a cell), else None."""
        index = []
        for w, inside, h, axis in ((uc, in_x, self.cell[0], 0), (vc, in_y, self.cell[1], 1)):
            f = w / h
            nearest = np.rint(f)
            if (np.abs(f - nearest) > ON_SAMPLE)[inside].any():
                return None
            index.append(np.clip(nearest.astype(np.intp), 0, self.heights.shape[axis] - 1))
        return tuple(index)

    def _slopes_at_samples(self, at: tuple, axis: int) -> np.ndarray | None:
        """S's slope along ``axis`` at the samples ``at`` (a pair of index arrays that broadcast), or None
        where that axis has fewer than 4 samples (S not cubic along it). On a line of samples along ``axis``
        S is the not-a-knot cubic spline through that line's samples (a missing sample takes its nearest
        finite one's, as for the whole spline), so its slopes there come from :func:`spline_slopes`: no
        spline of the whole map and no derivative spline; made for every sample on first use and kept (as a
        derivative's spline would be: a step's resisting force asks for them at every step)."""
        if self.heights.shape[axis] < 4:
            return None
        key = ("at samples", axis)
        if key not in self._splines:
            self._splines[key] = spline_slopes(self._filled(self.heights), self.cell[axis], axis)
        return self._splines[key][at]

    def _filled(self, heights: np.ndarray) -> np.ndarray:
        """``heights`` (the map's samples) with every missing (+inf) sample replaced by its nearest finite
        one's, for the splines; the array itself when none is missing."""
        finite = np.isfinite(heights)
        if finite.all():
            return heights
        from scipy import ndimage  # here, not at the top: only maps with holes need it

        nearest = ndimage.distance_transform_edt(~finite, return_distances=False, return_indices=True)
        return heights[tuple(nearest)]

    def _spline(self, dx: int, dy: int):
        """S's spline (scipy's RectBivariateSpline, on coordinates from the first sample; a missing sample
        takes its nearest finite one's), or its derivative's of orders (dx, dy) (equal degrees along both
        axes): made on first use and kept."""
        if (dx, dy) in self._splines:
            return self._splines[dx, dy]
        if (dx, dy) != (0, 0):
            made = self._spline(0, 0).partial_derivative(dx, dy)
        else:
            from scipy.interpolate import RectBivariateSpline  # here: a scene without a map never imports it

            (hx, hy), (nx, ny) = self.cell, self.heights.shape
            heights = self._filled(self.heights)
            made = RectBivariateSpline(np.arange(nx) * hx, np.arange(ny) * hy, heights,
                                       kx=min(3, nx - 1), ky=min(3, ny - 1), s=0)
        self._splines[dx, dy] = made
        return made

    def _spline_at(self, u, v, dx: int, dy: int, grid: bool) -> np.ndarray:
        """S's derivative of orders (dx, dy) <= 1 at coordinates (u, v) from the first sample; along an axis
        of two samples (S linear there, which FITPACK cannot differentiate) the difference of its ends."""
        kx, ky = self._spline(0, 0).degrees
        if dx and kx == 1:
            end = (self.heights.shape[0] - 1) * self.cell[0]
            spline = self._spline(0, dy)
            return (spline(end, v, grid=grid) - spline(0.0, v, grid=grid)) / end
        if dy and ky == 1:
            end = (self.heights.shape[1] - 1) * self.cell[1]
            spline = self._spline(dx, 0)
            return (spline(u, end, grid=grid) - spline(u, 0.0, grid=grid)) / end
        if kx != ky:  # scipy's derivative splines need equal degrees: FITPACK's derivative, O(samples) a call
            return self._spline(0, 0)(u, v, dx, dy, grid=grid)
        if (dx or dy) and grid and (dx, dy) not in self._splines:
            (hx, hy), (nx, ny) = self.cell, self.heights.shape
            bounds = [(int(u[0] // hx), min(int(u[-1] // hx) + 1, nx - 1)),
                      (int(v[0] // hy), min(int(v[-1] // hy) + 1, ny - 1))]
            if (bounds[0][1] - bounds[0][0] + 1) * (bounds[1][1] - bounds[1][0] + 1) * SMALL_BOX <= nx * ny:
                from scipy.interpolate import bisplev

                return np.reshape(bisplev(u, v, self._local_tck(bounds)[0], dx, dy), (len(u), len(v)))
        return self._spline(dx, dy)(u, v, grid=grid)

    def height(self, x, y):
        values, valid = self._evaluate(x, y, 0, 0)
        return np.where(valid, values - self._lowest, np.inf)

    def slope(self, x, y):
        return self._evaluate(x, y, 1, 0)[0], self._evaluate(x, y, 0, 1)[0]

    def _lowest_point(self) -> float:
        """min S: :meth:`_spline_minimum`."""
        return self._spline_minimum()

    def _corners(self) -> np.ndarray:
        """Where a sample is a corner of a cell with a surface."""
        nx, ny = self.heights.shape
        corner = np.zeros(self.heights.shape, dtype=bool)
        for di in (0, 1):
            for dj in (0, 1):
                corner[di : nx - 1 + di, dj : ny - 1 + dj] |= self._ok
        return corner

    def _spline_minimum(self, candidates: int = 8) -> float:
        """min S over the cells with a surface: a bounded minimisation (L-BFGS-B, in cell units, heights
        scaled by their spread around the start) from each of the lowest ``candidates`` samples that are
        corners of such a cell (equal ones in the order of their places), within the cells around it, on the
        spline's local piece there (:meth:`_patch`: each evaluation reads 4 x 4 coefficients); the lowest
        sample if lower."""
        from scipy import optimize

        heights, (hx, hy) = self.heights, self.cell
        nx, ny = heights.shape
        corner = self._corners()
        masked = np.where(corner, heights, np.inf)
        count = min(candidates, masked.size)
        # the lowest ``count`` in the order of a stable sort (ties: by place), without sorting them all
        lowest = np.flatnonzero(masked <= np.partition(masked, count - 1, axis=None)[count - 1])
        order = lowest[np.argsort(masked.flat[lowest], kind="stable")][:count]
        best = float(heights.flat[order[0]])
        for i, j in zip(*np.unravel_index(order, heights.shape)):
            if not corner[i, j]:
                break
            near = heights[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2]
            z0 = float(heights[i, j])
            scale = float(np.max(near[np.isfinite(near)]) - z0)
            if scale <= 0.0:
                continue
            bounds = [(max(i - 1, 0), min(i + 1, nx - 1)), (max(j - 1, 0), min(j + 1, ny - 1))]
            piece = self._patch(bounds)

            def scaled(point, z0=z0, scale=scale, piece=piece):
                value, gx, gy = piece(point[0] * hx, point[1] * hy)
                return (value - z0) / scale, np.array([gx * hx, gy * hy]) / scale

            found = optimize.minimize(scaled, [i, j], jac=True, method="L-BFGS-B", bounds=bounds,
                                      options={"ftol": 1e-15, "gtol": 1e-12})
            a, b = found.x
            ci, cj = min(int(a), nx - 2), min(int(b), ny - 2)
            if self._ok[ci, cj]:
                best = min(best, z0 + scale * float(found.fun))
        return best

    def _patch(self, bounds):
        """S on the box ``bounds`` ((i0, i1), (j0, j1), in samples) from its local piece: the knots and
        coefficients of the spline's polynomial pieces over the box only, the same polynomials. Returns
        (u, v) -> (S, dS/du, dS/dv) at a point of the box (coordinates from the first sample); along an
        axis of two samples (S linear) the derivative is the difference of its ends."""
        from scipy.interpolate import bisplev

        tck, ends = self._local_tck(bounds)
        kx, ky = tck[3:]

        def piece(u: float, v: float) -> tuple[float, float, float]:
            value = float(bisplev(u, v, tck))
            if kx > 1:
                gx = float(bisplev(u, v, tck, 1, 0))
            else:
                gx = (float(bisplev(ends[0][1], v, tck)) - float(bisplev(ends[0][0], v, tck))) / (
                    ends[0][1] - ends[0][0])
            if ky > 1:
                gy = float(bisplev(u, v, tck, 0, 1))
            else:
                gy = (float(bisplev(u, ends[1][1], tck)) - float(bisplev(u, ends[1][0], tck))) / (
                    ends[1][1] - ends[1][0])
            return value, gx, gy

        return piece

    def _local_tck(self, bounds) -> tuple[list, list]:
        """S's local piece over the box ``bounds`` ((i0, i1), (j0, j1), in samples): FITPACK's (tx, ty, c, kx,
        ky) of the knots and coefficients of the spline's polynomial pieces over the box only (the same
        polynomials there), and each axis's (start, end) of those pieces (coordinates from the first
        sample)."""
        spline = self._spline(0, 0)
        knots, (kx, ky) = spline.get_knots(), spline.degrees  # the whole knot vectors, ends repeated
        c = spline.get_coeffs().reshape(len(knots[0]) - kx - 1, len(knots[1]) - ky - 1)
        local, ends = [], []
        for (lo, hi), t, k, h in zip(bounds, knots, (kx, ky), self.cell):
            # the pieces [t_l, t_l+1] that meet the box, l from first to last; each uses coefficients l-k..l
            first = int(np.clip(np.searchsorted(t, lo * h, "right") - 1, k, len(t) - k - 2))
            last = int(np.clip(np.searchsorted(t, hi * h, "left") - 1, k, len(t) - k - 2))
            local.append((first, last))
            ends.append((t[first], t[last + 1]))
        (fx, lx), (fy, ly) = local
        tck = [knots[0][fx - kx : lx + kx + 2], knots[1][fy - ky : ly + ky + 2],
               c[fx - kx : lx + 1, fy - ky : ly + 1].ravel(), kx, ky]
        return tck, ends

    def _estimate_radius(self) -> float:
        heights, (hx, hy) = self.heights, self.cell
        fallback = 0.5 * max((heights.shape[0] - 1) * hx, (heights.shape[1] - 1) * hy)
        i, j = np.unravel_index(np.argmin(heights), heights.shape)  # +inf (no surface) is never the least
        lowest = heights[i, j]
        radii = []
        for axis, (k, h) in enumerate(((i, hx), (j, hy))):
            line = (heights[:, j] if axis == 0 else heights[i, :]) - lowest  # Z along the line
            n = line.size
            # a wide stencil (up to n/8 samples) smooths facets and roughness; narrow it until finite
            step = min(k, n - 1 - k, max(1, n // 8))  # 0 at the map's edge
            while step > 0 and not (np.isfinite(line[k - step]) and np.isfinite(line[k + step])):
                step //= 2
            if step == 0:
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



SMALL_BOX = 4
"""Slopes asked for on a lattice whose samples' box holds at most 1/SMALL_BOX of the map's samples are read
from the spline's local piece over that box (O(box)); larger ones make and keep S's derivative's spline."""


def spline_slopes(values: np.ndarray, h: float, axis: int) -> np.ndarray:
    """The slopes at the samples of the not-a-knot cubic splines through ``values`` (finite, at spacing ``h``,
    at least 4 along ``axis``) along ``axis``, each line of samples its own spline: the same values as the
    derivative of FITPACK's interpolating spline there (to round-off), from one banded solve for all lines.

    With y_i the samples of a line and m_i the slopes, the C2 conditions at the inner samples are
    m_(i-1) + 4 m_i + m_(i+1) = 3 (y_(i+1) - y_(i-1)) / h, and not-a-knot (equal third derivatives
    6 (h (m_i + m_(i+1)) - 2 (y_(i+1) - y_i)) / h^3 on the first two and on the last two intervals) closes
    them: m_0 - m_2 = 2 (2 y_1 - y_0 - y_2) / h and m_(n-1) - m_(n-3) = 2 (y_(n-1) - 2 y_(n-2) + y_(n-3)) / h.
    (scipy's CubicSpline solves the same system but then builds every interval's four coefficients: several
    times the work and the memory on a whole map.)"""
    from scipy.linalg import solve_banded

    y = np.asfortranarray(np.moveaxis(values, axis, 0))  # LAPACK's layout: each line contiguous
    n = y.shape[0]
    rhs = np.empty(y.shape, order="F")
    np.subtract(y[2:], y[:-2], out=rhs[1:-1])
    rhs[1:-1] *= 3.0 / h
    rhs[0] = 2.0 * (2.0 * y[1] - y[0] - y[2]) / h
    rhs[-1] = 2.0 * (y[-1] - 2.0 * y[-2] + y[-3]) / h
    band = np.zeros((5, n))  # band[2 + i - j, j] = A[i, j]
    band[1, 2:] = 1.0  # A[i, i + 1], i = 1 ... n - 2
    band[2] = 4.0  # A[i, i]
    band[3, :-2] = 1.0  # A[i, i - 1], i = 1 ... n - 2
    band[2, [0, -1]] = 1.0  # A[0, 0], A[n-1, n-1]
    band[1, 1] = 0.0  # A[0, 1]
    band[0, 2] = -1.0  # A[0, 2]
    band[3, -2] = 0.0  # A[n-1, n-2]
    band[4, -3] = -1.0  # A[n-1, n-3]
    return np.moveaxis(solve_banded((2, 2), band, rhs, overwrite_b=True, check_finite=False), 0, axis)


LOCAL_FIT = 8
"""A map on the cells (:class:`CellMap`) refines its lowest sample with the spline through the samples up to
this many away along each axis."""


class CellMap(HeightMap):
    """A height map whose samples sit on the centres of a grid's cells (:func:`on_cells`): what a run asks
    for at the cell centres is the samples, so no spline is fitted and no minimum searched to set it up.

    As :class:`HeightMap` (the same spline S between the samples, fitted on first use there; its slopes),
    but Z = S - m with m the lowest sample refined by a small local fit: the lowest point of the spline
    through the samples up to :data:`LOCAL_FIT` away from it (the lowest sample itself where the spline
    does not dip below it). The local and the whole map's splines differ there by a small fraction of the
    samples' deviation from a cubic (the influence of a sample on a not-a-knot cubic spline decays by
    2 - sqrt(3) per sample)."""

    def _lowest_point(self) -> float:
        heights, k = self.heights, LOCAL_FIT
        i, j = np.unravel_index(np.argmin(np.where(self._corners(), heights, np.inf)), heights.shape)
        window = heights[max(i - k, 0) : i + k + 1, max(j - k, 0) : j + k + 1]
        return min(float(heights[i, j]), HeightMap(window, self.cell)._lowest)


def on_cells(heights: np.ndarray, cell: tuple[float, float], grid, position: tuple[float, float]) -> bool:
    """Whether the samples ``heights`` (spacing ``cell``, m; their extent's midpoint on the body's reference
    point), the body at ``position`` (m), sit on the centres of ``grid``'s cells: the grid's spacing (to
    1e-9 relative) and an offset of a whole number of cells (to :data:`ON_SAMPLE` of a cell) along each
    axis."""
    if heights.ndim != 2 or not np.allclose(cell, (grid.dx, grid.dy), rtol=1e-9, atol=0.0):
        return False
    for n, h, start, at in ((heights.shape[0], grid.dx, grid.x0, position[0]),
                            (heights.shape[1], grid.dy, grid.y0, position[1])):
        first = (at - 0.5 * (n - 1) * h - start) / h - 0.5  # the first sample's place, in cells
        if abs(first - round(first)) > ON_SAMPLE:
            return False
    return True


@dataclass(frozen=True, eq=False)
class HeightProfile(Body):
    """A line-contact body given by sampled heights ``heights[i]`` (m) at spacing ``cell`` (m) along x,
    interpolated by a cubic spline (not-a-knot), independent of y; Z = S - min S as for :class:`HeightMap`,
    +inf outside the samples (and in a sample interval with a +inf end). The middle of the samples sits at
    the body's reference point."""

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
        # the profile as a two-column height map (equal columns, linear along y, so any y gives the
        # profile's spline along x); y is always taken at the first column
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
