"""Rough bodies: a periodic surface given by samples, and roughness riding on a smooth body.

* :class:`PeriodicSurface`: heights sampled on an nx x ny lattice that repeats with the period
  (nx hx, ny hy); the surface of a periodic grid (a height map of the grid's size, or a generated
  self-affine surface, petroll.model.roughness), or the roughness a smooth body carries.
* :class:`RoughBody`: a smooth body (sphere, cylinder...) plus a periodic roughness; the heights add.

Interpolation: a periodic cubic B-spline through the samples (evaluated by scipy.ndimage.map_coordinates),
so heights at the sample points are the samples and the surface is twice continuously differentiable; the
slopes are the spectral derivative of the samples (exact for every Fourier mode the lattice carries),
interpolated the same way. The spline's coefficients are made by FFTs (the periodic prefilter and the
derivative are diagonal in Fourier space) for the sample rows a query needs only: evaluated on a rank's
rows of a grid, a surface holds those rows' coefficients, wherever the body has moved. Points that all lie
on samples (a periodic grid's cells with the body at a whole number of cells) need no spline: the heights
there are the samples, the slopes the spectral derivative's values.
"""

from __future__ import annotations

import functools
import math
from dataclasses import KW_ONLY, InitVar, dataclass, field

import numpy as np
import scipy.fft

from petroll.errors import SceneError
from petroll.model.bodies.base import ON_SAMPLE, PYTHON_SOURCE, Body
from petroll.model.grid import Grid

__all__ = ["PeriodicSurface", "RoughBody", "grid_surface", "samples_surface"]


ROWS_MARGIN = 16
"""Sample rows a periodic surface prepares beyond those a query needs (each side): a body moving a cell per
step needs new rows' coefficients once every this many steps."""

CHUNK_BYTES = 1 << 25
"""Size of the columns' spectra transformed at once while rows' coefficients are made (bytes)."""


def _spectral_slope(heights: np.ndarray, cell: tuple[float, float], axis: int) -> np.ndarray:
    """dh/dx (``axis`` 0) or dh/dy (1) of the trigonometric interpolant of the periodic samples ``heights``
    at the samples (the Nyquist frequency, whose derivative a real lattice cannot carry, left out): 1-D
    transforms along ``axis``, :data:`CHUNK_BYTES` of spectra at a time; beside the result no field-sized
    array."""
    n, across = heights.shape[axis], heights.shape[1 - axis]
    multiplier = 2j * np.pi * scipy.fft.rfftfreq(n, cell[axis])
    if n % 2 == 0:
        multiplier[-1] = 0.0
    if axis == 0:
        multiplier = multiplier[:, None]
    out = np.empty(heights.shape)
    width = max(1, CHUNK_BYTES // (16 * n))
    for start in range(0, across, width):
        block = (slice(None), slice(start, start + width)) if axis == 0 else slice(start, start + width)
        spectrum = scipy.fft.rfft(heights[block], axis=axis)
        spectrum *= multiplier
        out[block] = scipy.fft.irfft(spectrum, n=n, axis=axis)
    return out


def _multipliers(n: int, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Along an axis of n periodic samples h m apart, on the half spectrum (rfft's frequencies): the
    periodic cubic B-spline's prefilter 1 / B (B = (2 + cos theta) / 3, the spline's values at the samples
    from unit coefficients) and the spectral derivative's i k / B (rad/m; Nyquist's k taken as 0)."""
    theta = 2.0 * np.pi * scipy.fft.rfftfreq(n)
    k = 2.0 * np.pi * scipy.fft.rfftfreq(n, h)
    if n % 2 == 0:
        k[-1] = 0.0
    inverse = 3.0 / (2.0 + np.cos(theta))
    return inverse, 1j * k * inverse


def _row_coefficients(heights: np.ndarray, cell: tuple[float, float], rows: np.ndarray) -> np.ndarray:
    """The periodic cubic B-spline coefficients of the samples ``heights``, of their spectral dh/dx and of
    their dh/dy (m, -, -), on the sample rows ``rows`` only: shape (3, len(rows), ny). The diagonal
    multipliers of :func:`_multipliers`, along X column block by column block (the whole column is
    transformed, only ``rows`` kept), then along Y on those rows; a row's values do not depend on which
    other rows are asked for."""
    nx, ny = heights.shape
    fx, dx = _multipliers(nx, cell[0])
    fy, dy = _multipliers(ny, cell[1])
    along_x = np.empty((2, len(rows), ny))
    width = max(1, CHUNK_BYTES // (16 * nx))
    for j in range(0, ny, width):
        spectrum = scipy.fft.rfft(heights[:, j : j + width], axis=0)
        for out, multiplier in zip(along_x, (fx, dx)):
            out[:, j : j + width] = scipy.fft.irfft(spectrum * multiplier[:, None], n=nx, axis=0)[rows]
    smooth = scipy.fft.rfft(along_x[0], axis=1)
    out = np.empty((3, len(rows), ny))
    out[0] = scipy.fft.irfft(smooth * fy, n=ny, axis=1)
    out[1] = scipy.fft.irfft(scipy.fft.rfft(along_x[1], axis=1) * fy, n=ny, axis=1)
    out[2] = scipy.fft.irfft(smooth * dy, n=ny, axis=1)
    return out


@dataclass(frozen=True, eq=False)
class PeriodicSurface(Body):
    """Heights ``heights[i, j]`` (m) at offsets ``origin`` + (i hx, j hy) from the body's reference point,
    ``cell`` = (hx, hy) m, repeated with the period (nx hx, ny hy) in both directions.

    Z = S - min S, S the periodic cubic spline through the samples and min S its lowest point, found on
    a lattice of 1/16 of a cell around the lowest samples (so Z >= 0 to within S's variation over 1/32 of
    a cell).

    Memory: the samples (8 bytes each) and the spline coefficients of the heights and slopes (24 bytes per
    sample) of only the sample rows the last large query needed, :data:`ROWS_MARGIN` rows each side (and
    those of smaller queries since): a rank that evaluates the surface on its rows of a grid holds those
    rows' coefficients (from its construction, which finds the lowest point, and after a whole-grid query,
    the whole grid's, until a rank's query replaces them); a large query whose points all lie on samples
    needs none and lets them go (a steady periodic solve holds the samples alone). The samples' half
    spectrum is made where asked for and not kept.
    """

    heights: np.ndarray
    cell: tuple[float, float]
    origin: tuple[float, float] = (0.0, 0.0)
    _: KW_ONLY
    source: InitVar[str] = PYTHON_SOURCE
    _prepared: dict = field(init=False, repr=False)  # "rows": sorted sample rows; "values": coefficients
    _lowest: float = field(init=False, repr=False)
    _radius_hint: float = field(init=False, repr=False)

    def __post_init__(self, source: str) -> None:
        heights = np.array(self.heights, dtype=float)
        if heights.ndim != 2 or min(heights.shape) < 4 or not np.isfinite(heights).all():
            raise SceneError(source, "[body] heights", f"<array of shape {heights.shape}>",
                             "a periodic surface needs a 2-D array of at least 4 x 4 finite heights (m)")
        cell = (float(self.cell[0]), float(self.cell[1]))
        heights.setflags(write=False)
        set_ = object.__setattr__
        set_(self, "heights", heights)
        set_(self, "cell", cell)
        set_(self, "origin", (float(self.origin[0]), float(self.origin[1])))
        set_(self, "_prepared", {"rows": np.zeros(0, dtype=np.intp), "values": None})
        set_(self, "_lowest", 0.0)
        set_(self, "_lowest", self._spline_minimum())
        # the summits' radius of curvature ~ 1 / rms curvature (first guesses only)
        curvature = (np.gradient(_spectral_slope(heights, cell, 0), cell[0], axis=0)
                     + np.gradient(_spectral_slope(heights, cell, 1), cell[1], axis=1))
        rms = math.sqrt(float(np.mean(curvature**2)))
        set_(self, "_radius_hint", 1.0 / rms if rms > 0.0 else max(heights.shape) * max(cell))

    def _spline_minimum(self, candidates: int = 8) -> float:
        """The lowest value of S on a lattice of 1/16 of a cell within a cell of each of the ``candidates``
        lowest samples (the lowest sample if lower). Every sample row's coefficients are prepared for it:
        they cost one pass of the columns' transforms whichever rows are kept, and the pre-flight's
        queries that follow (lines across the whole grid) need them all; a run's first whole-grid query,
        on the samples, lets them go."""
        samples = self.heights
        self._prepare(np.arange(samples.shape[0]), False)
        count = min(candidates, samples.size)
        lowest = np.unravel_index(np.argpartition(samples, count - 1, axis=None)[:count], samples.shape)
        offsets = np.linspace(-1.0, 1.0, 33)
        u, v = np.broadcast_arrays(lowest[0][:, None, None] + offsets[None, :, None],
                                   lowest[1][:, None, None] + offsets[None, None, :])
        x, y = self.origin[0] + u * self.cell[0], self.origin[1] + v * self.cell[1]
        return min(float(self._interpolate(0, x, y).min()), float(samples.min()))

    @property
    def lowest(self) -> float:
        """min S (m), the spline's lowest point: Z = S - lowest, so Z = heights - lowest at the samples."""
        return self._lowest

    @property
    def period(self) -> tuple[float, float]:
        """(nx hx, ny hy) in m."""
        return (self.heights.shape[0] * self.cell[0], self.heights.shape[1] * self.cell[1])

    @property
    def rows_held(self) -> int:
        """How many sample rows' spline coefficients the surface holds now (of nx)."""
        return len(self._prepared["rows"])

    def _prepare(self, needed: np.ndarray, every_column: bool) -> dict:
        """The prepared rows, holding the sample rows ``needed`` (sorted, within 0 ... nx - 1). A query of
        at least an eighth of the rows whose stencils take ``every_column`` of the samples (a rank's rows
        of a grid) keeps only the needed rows and :data:`ROWS_MARGIN` around each (cut from those held
        where they hold them, else made); any other query (a probe, a lattice over part of the surface) keeps what is
        held, adding its rows if missing. Coefficients are made only for rows not held: a row's do not
        depend on which other rows are made with it."""
        nx = self.heights.shape[0]
        wanted = np.unique((needed[:, None] + np.arange(-ROWS_MARGIN, ROWS_MARGIN + 1)) % nx)
        prepared = self._prepared
        held = np.isin(needed, prepared["rows"]).all()
        big = every_column and 8 * len(needed) >= nx
        if held and not (big and len(prepared["rows"]) > len(wanted)):
            return prepared
        if big and np.isin(wanted, prepared["rows"]).all():  # held, with more: keep these only
            prepared["values"] = prepared["values"][:, np.searchsorted(prepared["rows"], wanted)]
            prepared["rows"] = wanted
            return prepared
        rows = wanted if big else np.union1d(prepared["rows"], wanted)
        prepared["values"] = None  # the old rows go before the new ones come
        prepared["values"] = _row_coefficients(self.heights, self.cell, rows)
        prepared["rows"] = rows
        return prepared

    def _on_samples(self, x, y) -> tuple[np.ndarray, np.ndarray] | None:
        """The samples' indices (a pair of arrays that broadcast like the points) where every point at
        offsets (x, y) m lies on a sample (within :data:`ON_SAMPLE` of a cell along each axis), else None."""
        index = []
        for w, origin, h, n in zip((x, y), self.origin, self.cell, self.heights.shape):
            f = (np.asarray(w, dtype=float) - origin) / h
            nearest = np.rint(f)
            if np.any(np.abs(f - nearest) > ON_SAMPLE):
                return None
            index.append(nearest.astype(np.intp) % n)
        return index[0], index[1]

    def _at_samples(self, which, at: tuple[np.ndarray, np.ndarray]):
        """:meth:`_interpolate`'s values on the samples ``at`` (:meth:`_on_samples`): the samples less
        ``lowest``, the spectral slopes there (which the slopes' spline passes through; each slope made on
        the whole lattice, then gathered: one field-sized array at a time)."""
        nx, ny = self.heights.shape
        i, j = at
        whole = (i.shape == (nx, 1) and j.shape == (1, ny) and np.array_equal(i[:, 0], np.arange(nx))
                 and np.array_equal(j[0], np.arange(ny)))  # the whole lattice in order: no gather
        out = []
        for w in np.atleast_1d(which):
            if w == 0:
                out.append(self.heights - self._lowest if whole else self.heights[i, j] - self._lowest)
            else:
                slope = _spectral_slope(self.heights, self.cell, w - 1)
                out.append(slope if whole else slope[i, j])
        return out[0] if np.ndim(which) == 0 else tuple(out)

    def _interpolate(self, which, x, y):
        """The spline of coefficients ``which`` (0: heights less ``lowest``, 1: dh/dx, 2: dh/dy; a tuple:
        each) at offsets (x, y) m, from the sample rows the points' stencils need; on samples alone, their
        values (:meth:`_at_samples`), a query of at least an eighth of the rows letting the held rows go."""
        from scipy import ndimage

        nx = self.heights.shape[0]
        if (at := self._on_samples(x, y)) is not None:
            if 8 * np.unique(at[0]).size >= nx and np.unique(at[1]).size == self.heights.shape[1]:
                self._prepared.update(rows=np.zeros(0, dtype=np.intp), values=None)
            return self._at_samples(which, at)
        u = (np.asarray(x, dtype=float) - self.origin[0]) / self.cell[0]
        u = u - nx * np.floor(u / nx)  # in [0, nx]
        base = np.floor(u).astype(np.intp)
        stencil = np.unique(np.unique(base)[:, None] + np.arange(-1, 3))  # rows -1 ... nx + 2, unwrapped
        ny = self.heights.shape[1]
        v = (np.asarray(y, dtype=float) - self.origin[1]) / self.cell[1]
        columns = np.unique((np.unique(np.floor(v))[:, None] + np.arange(-1, 3)) % ny)  # the stencils'
        prepared = self._prepare(np.unique(stencil % nx), columns.size == ny)
        whole = len(prepared["rows"]) == nx  # all rows: the spline wraps around by itself
        if not whole:  # the stencils' rows in order, each point's row numbered among them
            index = np.searchsorted(prepared["rows"], stencil % nx)
            u = u - (base - np.searchsorted(stencil, base))
        u, v = np.broadcast_arrays(u, v)
        coordinates = np.stack([u, v]).reshape(2, -1)
        out = []
        for w in np.atleast_1d(which):
            values = prepared["values"][w] if whole else prepared["values"][w][index]
            value = ndimage.map_coordinates(values, coordinates, order=3, mode="grid-wrap", prefilter=False)
            out.append(value.reshape(u.shape) - (self._lowest if w == 0 else 0.0))
        return out[0] if np.ndim(which) == 0 else tuple(out)

    def height(self, x, y):
        return self._interpolate(0, x, y)

    def slope(self, x, y):
        return self._interpolate((1, 2), x, y)

    @property
    def radius_hint(self) -> float:
        """1 / (rms curvature of the samples): a summit's radius, for first guesses only."""
        return self._radius_hint

    def _spectrum(self) -> np.ndarray:
        """scipy.fft.rfft2 of the samples (the radius hint, :meth:`spectrum`, the slopes on the samples),
        made where asked for: not kept (8 bytes per sample)."""
        return scipy.fft.rfft2(self.heights)

    @functools.cached_property
    def contact_scale(self) -> float:
        """sqrt(<|grad h|^2> / <|lap h|^2>) (m) of the samples' trigonometric interpolant (from their
        spectrum: sqrt(sum q^2 |h_q|^2 / sum q^4 |h_q|^2)): the rms slope over the rms curvature, about the
        half-width of one of the surface's single contacts (a sinusoid of wavelength L: L / 2 pi; a
        self-affine surface: 0.2 to 0.3 times its short cut-off); inf for a flat surface. What the time
        step is weighed against on a rough surface (petroll.model.preflight, docs/accuracy.md)."""
        q, power = self.spectrum()
        curvature = float(np.sum(q**4 * power))
        return math.sqrt(float(np.sum(q**2 * power)) / curvature) if curvature > 0.0 else math.inf

    def spectrum(self) -> tuple[np.ndarray, np.ndarray]:
        """(|q| in rad/m, |h_q|^2 in m^2) of every mode of the samples' trigonometric interpolant, flattened:
        the half spectrum's columns weighted for their conjugates, the mean's power 0, so that the powers
        sum to the mean square height."""
        nx, ny = self.heights.shape
        qx = 2.0 * np.pi * scipy.fft.fftfreq(nx, self.cell[0])
        qy = 2.0 * np.pi * scipy.fft.rfftfreq(ny, self.cell[1])
        weight = np.full(len(qy), 2.0)  # the half spectrum: a column stands for its conjugate too
        weight[0] = 1.0
        if ny % 2 == 0:
            weight[-1] = 1.0
        power = np.abs(self._spectrum()) ** 2 * weight / (nx * ny) ** 2
        power[0, 0] = 0.0
        return np.hypot(qx[:, None], qy[None, :]).ravel(), power.ravel()


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
    return _on_cells(heights, (grid.dx, grid.dy), grid, source)


def samples_surface(heights: np.ndarray, cell: tuple[float, float], grid: Grid) -> PeriodicSurface | None:
    """On a periodic ``grid``, the periodic surface of samples that are its cells (as many as its nx x ny,
    or nx for a line grid's profile, at its spacing, all finite): sample (i, j) on the centre of cell
    (i, j) while the body is at [body] position [0, 0]. None for samples that are not."""
    if not grid.topology.whole or heights.ndim != 2:
        return None
    if (heights.shape[0] != grid.nx or (not grid.line and heights.shape[1] != grid.ny)
            or not np.allclose(cell, (grid.dx, grid.dy), rtol=1e-9, atol=0.0)
            or not np.isfinite(heights).all()):
        return None
    return _on_cells(heights, cell, grid, PYTHON_SOURCE)


def _on_cells(heights: np.ndarray, cell: tuple[float, float], grid: Grid, source: str) -> PeriodicSurface:
    """The periodic surface whose sample (i, j) lies on the centre of ``grid``'s cell (i, j) while the body
    is at [body] position [0, 0]."""
    return PeriodicSurface(heights, cell, (grid.x0 + 0.5 * grid.dx, grid.y0 + 0.5 * grid.dy), source=source)
