"""Rough bodies: a periodic surface given by samples, and roughness riding on a smooth body.

* :class:`PeriodicSurface`: heights sampled on an nx x ny lattice that repeats with the period
  (nx hx, ny hy); the surface of a periodic grid (a height map of the grid's size, or a generated
  self-affine surface, petroll.model.roughness), or the roughness a smooth body carries.
* :class:`RoughBody`: a smooth body (sphere, cylinder...) plus a periodic roughness; the heights add.

Interpolation: a periodic cubic B-spline through the samples (scipy.ndimage, ``mode="grid-wrap"``), so
heights at the sample points are the samples and the surface is twice continuously differentiable; the
slopes are the spectral derivative of the samples (exact for every Fourier mode the lattice carries),
interpolated the same way.
"""

from __future__ import annotations

import math
from dataclasses import KW_ONLY, InitVar, dataclass, field

import numpy as np
import scipy.fft

from petroll.errors import SceneError
from petroll.model.bodies.base import PYTHON_SOURCE, Body
from petroll.model.grid import Grid

__all__ = ["PeriodicSurface", "RoughBody", "grid_surface"]


def _spectral_slopes(heights: np.ndarray, cell: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(dh/dx, dh/dy) of the trigonometric interpolant of periodic samples, at the samples (Nyquist
    frequencies, whose derivative a real lattice cannot carry, left out)."""
    nx, ny = heights.shape
    kx = 2.0 * np.pi * scipy.fft.fftfreq(nx, cell[0])
    ky = 2.0 * np.pi * scipy.fft.rfftfreq(ny, cell[1])
    if nx % 2 == 0:
        kx[nx // 2] = 0.0
    if ny % 2 == 0:
        ky[-1] = 0.0
    spectrum = scipy.fft.rfft2(heights)
    return (scipy.fft.irfft2(1j * kx[:, None] * spectrum, s=heights.shape),
            scipy.fft.irfft2(1j * ky[None, :] * spectrum, s=heights.shape))


def _spline_minimum(samples: np.ndarray, coefficients: np.ndarray, candidates: int = 8) -> float:
    """The lowest value of the periodic cubic spline (its B-spline ``coefficients``) on a lattice of 1/16
    of a cell within a cell of each of the ``candidates`` lowest samples."""
    from scipy import ndimage  # here, not at the top: a scene without a periodic surface never imports it

    lowest = np.unravel_index(np.argsort(samples, axis=None)[:candidates], samples.shape)
    offsets = np.linspace(-1.0, 1.0, 33)
    u, v = np.broadcast_arrays(lowest[0][:, None, None] + offsets[None, :, None],
                               lowest[1][:, None, None] + offsets[None, None, :])
    values = ndimage.map_coordinates(coefficients, np.stack([u.ravel(), v.ravel()]), order=3,
                                     mode="grid-wrap", prefilter=False)
    return min(float(values.min()), float(samples.min()))


@dataclass(frozen=True, eq=False)
class PeriodicSurface(Body):
    """Heights ``heights[i, j]`` (m) at offsets ``origin`` + (i hx, j hy) from the body's reference point,
    ``cell`` = (hx, hy) m, repeated with the period (nx hx, ny hy) in both directions.

    Z = S - min S, S the periodic cubic spline through the samples and min S its lowest point, found on
    a lattice of 1/16 of a cell around the lowest samples (so Z >= 0 to within S's variation over 1/32 of
    a cell).
    """

    heights: np.ndarray
    cell: tuple[float, float]
    origin: tuple[float, float] = (0.0, 0.0)
    _: KW_ONLY
    source: InitVar[str] = PYTHON_SOURCE
    _coefficients: tuple[np.ndarray, np.ndarray, np.ndarray] = field(init=False, repr=False)
    _lowest: float = field(init=False, repr=False)
    _radius_hint: float = field(init=False, repr=False)

    def __post_init__(self, source: str) -> None:
        heights = np.array(self.heights, dtype=float)
        if heights.ndim != 2 or min(heights.shape) < 4 or not np.isfinite(heights).all():
            raise SceneError(source, "[body] heights", f"<array of shape {heights.shape}>",
                             "a periodic surface needs a 2-D array of at least 4 x 4 finite heights (m)")
        from scipy import ndimage

        cell = (float(self.cell[0]), float(self.cell[1]))
        slopes = _spectral_slopes(heights, cell)
        surface, *gradient = (ndimage.spline_filter(f, order=3, mode="grid-wrap") for f in (heights, *slopes))
        lowest = _spline_minimum(heights, surface)
        coefficients = (surface - lowest, *gradient)  # a constant passes the filter as it is
        heights.setflags(write=False)
        # the summits' radius of curvature ~ 1 / rms curvature (first guesses only)
        curvature = np.gradient(slopes[0], cell[0], axis=0) + np.gradient(slopes[1], cell[1], axis=1)
        rms = math.sqrt(float(np.mean(curvature**2)))
        set_ = object.__setattr__
        set_(self, "heights", heights)
        set_(self, "cell", cell)
        set_(self, "origin", (float(self.origin[0]), float(self.origin[1])))
        set_(self, "_coefficients", coefficients)
        set_(self, "_lowest", lowest)
        set_(self, "_radius_hint", 1.0 / rms if rms > 0.0 else max(heights.shape) * max(cell))

    @property
    def lowest(self) -> float:
        """min S (m), the spline's lowest point: Z = S - lowest, so Z = heights - lowest at the samples."""
        return self._lowest

    @property
    def period(self) -> tuple[float, float]:
        """(nx hx, ny hy) in m."""
        return (self.heights.shape[0] * self.cell[0], self.heights.shape[1] * self.cell[1])

    def _interpolate(self, which: int, x, y) -> np.ndarray:
        from scipy import ndimage

        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        coordinates = np.stack([(x - self.origin[0]) / self.cell[0], (y - self.origin[1]) / self.cell[1]])
        return ndimage.map_coordinates(self._coefficients[which], coordinates.reshape(2, -1), order=3,
                                       mode="grid-wrap", prefilter=False).reshape(x.shape)

    def height(self, x, y):
        return self._interpolate(0, x, y)

    def slope(self, x, y):
        return self._interpolate(1, x, y), self._interpolate(2, x, y)

    @property
    def radius_hint(self) -> float:
        """1 / (rms curvature of the samples): a summit's radius, for first guesses only."""
        return self._radius_hint


@dataclass(frozen=True, eq=False)
class RoughBody(Body):
    """A smooth ``body`` carrying a periodic ``roughness``: Z = Z_body + Z_roughness (+inf where the body
    has no surface), slopes added; the body's radius hint."""

    body: Body
    roughness: PeriodicSurface

    def height(self, x, y):
        return self.body.height(x, y) + self.roughness.height(x, y)

    def slope(self, x, y):
        (bx, by), (rx, ry) = self.body.slope(x, y), self.roughness.slope(x, y)
        surface = np.isfinite(self.body.height(x, y))
        return np.where(surface, bx + rx, 0.0), np.where(surface, by + ry, 0.0)

    @property
    def radius_hint(self) -> float:
        return self.body.radius_hint


def grid_surface(heights: np.ndarray, cell: tuple[float, float], grid: Grid, *, source: str = PYTHON_SOURCE,
                 label: object = "<heights>") -> PeriodicSurface:
    """The surface of a periodic ``grid``: its nx x ny samples at the grid's spacing, sample (i, j) on the
    centre of cell (i, j) while the body's reference point is at the origin (SceneError on ``[body] file``
    or ``[body] cell``, ``label`` the file, unless the samples are that many at that spacing)."""
    if heights.shape != (grid.nx, grid.ny):
        raise SceneError(source, "[body] file", label, f"on a periodic grid the surface has one sample per "
                         f"cell, {grid.nx} x {grid.ny}, not {heights.shape[0]} x {heights.shape[1]}")
    if not np.allclose(cell, (grid.dx, grid.dy), rtol=1e-9, atol=0.0):
        raise SceneError(source, "[body] cell", list(cell), f"on a periodic grid the samples are the cells: "
                         f"their spacing is the grid's, [{grid.dx!r}, {grid.dy!r}] m")
    return PeriodicSurface(heights, (grid.dx, grid.dy), (grid.x0 + 0.5 * grid.dx, grid.y0 + 0.5 * grid.dy),
                           source=source)
