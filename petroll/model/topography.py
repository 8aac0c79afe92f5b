"""Measured topographies read from files: heights on a regular grid with their lateral spacing.

Formats (chosen by the file's extension, or ``fmt``):

* ``npy``: a NumPy ``.npy`` file holding a 2-D array, axis 0 along x, axis 1 along y;
* ``matrix``: a plain-text matrix (``.txt``, ``.dat``, ``.asc``, ``.csv``; whitespace or commas, ``#``
  comments), row i the heights at x_i, column j at y_j (as ``numpy.savetxt`` writes a ``.npy``'s array);
* ``xyz``: a plain-text list of points ``x y z`` (``.xyz``), one a line, in any order, on a regular grid
  (every grid point once); the spacing is read from the coordinates;
* ``x3p``: ISO 25178-72 (``.x3p``: a zip of ``main.xml`` and binary data), read with the ``x3pio``
  library; lengths are in metres by the standard, the spacing is the file's, and the file's x axis is
  axis 0 (x3p stores rows along y).

The numbers of ``npy``, ``matrix`` and ``xyz`` files are in ``unit`` (``"m"``, ``"mm"``, ``"um"`` or
``"nm"``, heights and xyz's coordinates alike); ``cell`` (the spacing of ``npy`` and ``matrix`` files) is
in m like every scene length. A point that is not measured (NaN, or a grid point missing from an xyz list)
is refused: petroll needs every height, so fill such points before (e.g. ``scipy.interpolate.griddata``);
+inf means "no surface there" (a body's height map, docs/scene.md).
Every failure is a :class:`~petroll.errors.SceneError` naming the key after ``prefix`` (default
``[body] ``; ``[body] roughness.`` for a body's roughness).
"""

from __future__ import annotations

import os
import pathlib
from dataclasses import dataclass

import numpy as np

from petroll.errors import SceneError, reason
from petroll.model.limits import heights_out_of_scale

__all__ = ["FORMATS", "UNITS", "Topography", "read_npy", "read_topography"]

NPY_MAGIC = b"\x93NUMPY"
"""The first bytes of every .npy file."""

UNITS: dict[str, float] = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "nm": 1e-9}
"""Length units of a file's numbers, in m."""

FORMATS: dict[str, tuple[str, ...]] = {
    "npy": (".npy",),
    "matrix": (".txt", ".dat", ".asc", ".csv"),
    "xyz": (".xyz",),
    "x3p": (".x3p",),
}
"""The formats and the extensions that select them."""

_GRID_TOLERANCE = 1e-3  # an xyz coordinate may miss its grid line by this fraction of the spacing


@dataclass(frozen=True, eq=False)
class Topography:
    """Heights (m) on a regular grid: ``heights[i, j]`` at x = i hx, y = j hy, ``cell`` = (hx, hy) m."""

    heights: np.ndarray
    cell: tuple[float, float]

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    @property
    def size(self) -> tuple[float, float]:
        """The extent of the samples as a periodic cell, (nx hx, ny hy) in m."""
        return (self.heights.shape[0] * self.cell[0], self.heights.shape[1] * self.cell[1])


def _format_of(path: pathlib.Path, fmt: str | None, source: str, prefix: str) -> str:
    key = f"{prefix}file"
    if fmt is not None:
        if fmt not in FORMATS:
            raise SceneError(source, f"{prefix}format", fmt,
                             "must be one of: " + ", ".join(FORMATS))
        return fmt
    suffix = path.suffix.lower()
    for name, suffixes in FORMATS.items():
        if suffix in suffixes:
            return name
    known = ", ".join(s for suffixes in FORMATS.values() for s in suffixes)
    raise SceneError(source, key, str(path), f"unknown extension {suffix!r}: one of {known}, or give the "
                     "format (" + ", ".join(FORMATS) + ")")


def _checked(heights: np.ndarray, path: pathlib.Path, source: str, key: str) -> np.ndarray:
    """A 2-D float array of at least 2 x 2 heights, none NaN or -inf (+inf: no surface there), within
    petroll.model.limits.MAGNITUDES, or SceneError."""
    if heights.ndim != 2 or min(heights.shape) < 2:
        raise SceneError(source, key, str(path), "must hold a 2-D array of heights with at least 2 samples "
                         f"along each axis, got shape {heights.shape}")
    bad = int(np.count_nonzero(np.isnan(heights) | np.isneginf(heights)))
    if bad:
        raise SceneError(source, key, str(path), f"{bad} of {heights.size} heights are NaN or -inf (points "
                         "not measured?): fill them first, e.g. with scipy.interpolate.griddata")
    if (why := heights_out_of_scale(heights)) is not None:
        raise SceneError(source, key, str(path), why)
    return heights


def read_npy(path: str | os.PathLike, source: str, what: str, key: str = "[body] file") -> np.ndarray:
    """The array of a .npy file, or SceneError on ``key`` (``what``: the array it must hold, of real
    numbers)."""
    try:
        with open(path, "rb") as fh:
            magic = fh.read(len(NPY_MAGIC))
        array = np.load(path, allow_pickle=False) if magic == NPY_MAGIC else None
    except Exception as exc:  # noqa: BLE001 - any read failure is the user's file
        raise SceneError(source, key, str(path), f"cannot read a .npy file: {reason(exc)}") from None
    if array is None:
        raise SceneError(source, key, str(path), "is not a .npy file (those begin with the bytes \\x93NUMPY; "
                         f"a text file of numbers is read as format = \"matrix\" where allowed); it must hold "
                         f"{what}")
    if isinstance(array, np.ndarray) and np.iscomplexobj(array):
        raise SceneError(source, key, str(path), f"holds complex numbers ({array.dtype}); it must hold {what}, "
                         "real numbers (np.real(...) if the real part is meant)")
    if not isinstance(array, np.ndarray) or not np.issubdtype(array.dtype, np.number):
        raise SceneError(source, key, str(path), f"must be a .npy file holding {what}")
    if np.issubdtype(array.dtype, np.floating):  # a signalling NaN (random bytes) warns in arithmetic or a
        array[np.isnan(array)] = np.nan  # cast (FE_INVALID); a quiet one is refused as NaN where it is read
    return array


def _read_text(path: pathlib.Path, source: str, key: str, what: str) -> np.ndarray:
    """The numbers of a text file as a 2-D array (whitespace or commas between them, # comments)."""
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(source, key, str(path), f"cannot read {what}: {reason(exc)}") from None
    lines = [line.split("#", 1)[0] for line in text.splitlines()]
    lines = [line for line in lines if line.strip()]
    if not lines:
        raise SceneError(source, key, str(path), f"holds no numbers (empty, or comments only); it must hold {what}")
    delimiter = "," if any("," in line for line in lines) else None
    try:
        array = np.loadtxt(lines, delimiter=delimiter, ndmin=2)
    except ValueError as exc:
        raise SceneError(source, key, str(path), f"is not {what}: {reason(exc)}") from None
    return array


def _grid_axis(values: np.ndarray, path: pathlib.Path, source: str, key: str, axis: str):
    """(index of each coordinate on its grid line, count, spacing) of one xyz coordinate column."""
    low, high = float(values.min()), float(values.max())
    distinct = np.unique(values)
    gaps = np.diff(distinct)
    span = high - low
    lines = 1 + int(np.count_nonzero(gaps > _GRID_TOLERANCE * span / max(len(distinct), 1)))
    if lines < 2:
        raise SceneError(source, key, str(path), f"an xyz list needs at least 2 distinct {axis} values")
    spacing = span / (lines - 1)
    index = np.rint((values - low) / spacing)
    if np.abs((values - low) / spacing - index).max() > _GRID_TOLERANCE:
        raise SceneError(source, key, str(path), f"the points are not on a regular grid along {axis} "
                         f"({lines} distinct values over {span!r}); resample them onto one first")
    return index.astype(np.intp), lines, spacing


def _read_xyz(path: pathlib.Path, scale: float, source: str, key: str) -> Topography:
    points = _read_text(path, source, key, "an xyz list (columns x y z)")
    if points.shape[1] != 3:
        raise SceneError(source, key, str(path), f"an xyz list has 3 columns (x y z), not {points.shape[1]}")
    if not np.isfinite(points[:, :2]).all():
        raise SceneError(source, key, str(path), "an xyz list has a non-finite x or y coordinate")
    i, nx, hx = _grid_axis(points[:, 0], path, source, key, "x")
    j, ny, hy = _grid_axis(points[:, 1], path, source, key, "y")
    heights = np.full((nx, ny), np.nan)
    count = np.zeros((nx, ny), dtype=np.intp)
    np.add.at(count, (i, j), 1)
    if (count > 1).any():
        twice = int(np.count_nonzero(count > 1))
        raise SceneError(source, key, str(path), f"{twice} grid points appear more than once in the xyz list")
    heights[i, j] = points[:, 2]
    return Topography(_checked(heights * scale, path, source, key), (hx * scale, hy * scale))


def _read_x3p(path: pathlib.Path, source: str, key: str) -> Topography:
    try:
        import x3pio  # imported lazily: only .x3p files need it
    except ImportError:
        raise SceneError(source, key, str(path), "reading .x3p needs the x3pio package (Python >= 3.11): "
                         "pip install x3pio") from None
    try:
        data = x3pio.read(path)
    except (OSError, x3pio.X3pError) as exc:
        raise SceneError(source, key, str(path), f"cannot read an x3p file: {reason(exc)}") from None
    if not isinstance(data, x3pio.Surface) or len(data.layers) != 1:
        raise SceneError(source, key, str(path), f"must hold one surface layer, found {type(data).__name__} "
                         f"with {len(data.layers)} layer(s)")
    layer = data.layers[0]
    if not layer.is_regular_grid:
        raise SceneError(source, key, str(path), "the x3p surface is not on a regular grid (axis type A)")
    heights = np.asarray(layer.z, dtype=float).T  # x3p: rows along y; petroll: axis 0 along x
    cell = (float(data.header.x.increment), float(data.header.y.increment))
    return Topography(_checked(heights, path, source, key), cell)


def read_topography(path: str | os.PathLike, *, fmt: str | None = None,
                    cell: tuple[float, float] | None = None, unit: str = "m", source: str = "<python>",
                    prefix: str = "[body] ") -> Topography:
    """Read a measured topography (see the module's docstring for the formats and units).

    ``cell``: the spacing (hx, hy) in m of ``npy`` and ``matrix`` files (required for them; refused for
    ``xyz`` and ``x3p``, whose files carry it). ``unit``: the unit of the file's numbers (not for ``x3p``).
    ``prefix``: what the errors put before the keys' names (file, format, cell, unit).
    """
    path = pathlib.Path(path)
    key, unit_key, cell_key = f"{prefix}file", f"{prefix}unit", f"{prefix}cell"
    fmt = _format_of(path, fmt, source, prefix)
    if unit not in UNITS:
        raise SceneError(source, unit_key, unit, "must be one of: " + ", ".join(UNITS))
    if fmt == "x3p" and unit != "m":
        raise SceneError(source, unit_key, unit, "an x3p file is in metres by its standard: leave unit out")
    if fmt in ("xyz", "x3p"):
        if cell is not None:
            raise SceneError(source, cell_key, cell, f"a {fmt} file gives its own spacing: leave cell out")
        return _read_x3p(path, source, key) if fmt == "x3p" else _read_xyz(path, UNITS[unit], source, key)
    if cell is None:
        raise SceneError(source, cell_key, cell, f"required for a {fmt} file: the spacing in m, a number or "
                         "[hx, hy]")
    if fmt == "npy":
        heights = read_npy(path, source, "one 2-D numeric array (not .npz)", key).astype(float, copy=False)
    else:
        heights = _read_text(path, source, key, "a matrix of heights")
    if UNITS[unit] != 1.0:  # metres: the array as read (a map's samples are copied once, by the body)
        heights = heights * UNITS[unit]
    return Topography(_checked(heights, path, source, key), (float(cell[0]), float(cell[1])))
