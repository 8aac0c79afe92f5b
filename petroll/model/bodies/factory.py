"""A scene's ``[body]`` table: the shapes, their keys (documented in docs/scene.md) and :func:`make_body`."""

from __future__ import annotations

import os
import pathlib

from petroll.errors import MISSING, SceneError
from petroll.model.bodies.analytic import Cylinder, CylinderSection, Ellipsoid, Sphere
from petroll.model.bodies.base import Body, cell_pair, point_pair, type_name
from petroll.model.bodies.maps import CellMap, HeightMap, HeightProfile, on_cells
from petroll.model.bodies.mesh import mesh_height_map
from petroll.model.bodies.rough import PeriodicSurface, RoughBody, grid_surface, samples_surface
from petroll.model.grid import Grid
from petroll.model.roughness import ROUGH_KEYS, self_affine_heights
from petroll.model.topography import FORMATS, UNITS, read_npy, read_topography

_ROUGHNESS = ("a rough surface riding on the body, its heights added, repeating beyond its samples: "
              "generated, {hurst, rolloff, cutoff, rms_height or rms_slope, seed} (a self-affine surface "
              "on the grid's cells and size), or measured, {file, cell, format, unit} (as a heightmap's "
              "keys); docs/rough.md")
_FILE_KEYS: dict[str, str] = {
    "file": "measured heights: .npy, a text matrix (.txt, .dat, .asc, .csv), an xyz list (.xyz) or an "
            "ISO 25178-72 .x3p file; relative to the scene file (required; docs/rough.md)",
    "cell": "spacing of the samples, m: a number or [hx, hy] (required for .npy and text matrices; xyz "
            "and x3p files give their own)",
    "format": "the file's format where its extension does not say it: " + ", ".join(FORMATS),
    "unit": "unit of the file's numbers (heights; xyz coordinates too): " + ", ".join(UNITS)
            + ' (default "m"; not for x3p: metres)',
}

BODY_KEYS: dict[str, dict[str, str]] = {
    "sphere": {
        "radius": "radius of the sphere, m (required)",
        "roughness": _ROUGHNESS,
    },
    "ellipsoid": {
        "radius_x": "principal radius of curvature along x at the lowest point, m (required)",
        "radius_y": "principal radius of curvature along y at the lowest point, m (required)",
        "roughness": _ROUGHNESS,
    },
    "cylinder": {
        "radius": "radius of the cylinder, m (required)",
        "width": "length of the cylinder along its axis, m (required)",
        "edge_radius": "radius of the rounded edges, m, 0 <= edge_radius <= width/2 (default 0: sharp edges)",
        "axis": 'direction of the cylinder axis, "x" or "y" (default "y": rolls along x)',
        "roughness": _ROUGHNESS,
    },
    "heightmap": {
        **_FILE_KEYS,
        "file": "lower-surface heights, axis 0 along x (or row i at x_i): .npy, a text matrix (.txt, .dat, "
                ".asc, .csv), an xyz list (.xyz) or an ISO 25178-72 .x3p file; +inf: no surface there; "
                "relative to the scene file (required; docs/rough.md)",
    },
    "rough": ROUGH_KEYS,
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

_DEFAULTS: dict[str, dict[str, object]] = {
    "sphere": {"roughness": None},
    "ellipsoid": {"roughness": None},
    "cylinder": {"edge_radius": 0.0, "axis": "y", "roughness": None},
    "heightmap": {"cell": None, "format": None, "unit": "m"},
    "rough": {key: None for key in ROUGH_KEYS if key != "hurst"},  # absent: the generator's defaults
}
_COMMON_KEYS = ("shape", "position", "material")  # position, material: read by the scene reader, not here


def _profile_from_npy(path: pathlib.Path, cell: object, source: str) -> HeightProfile:
    """A :class:`HeightProfile` from a .npy file holding a 1-D array (SceneError naming [body] file)."""
    loaded = read_npy(path, source, "a 1-D array of heights (m) along x")
    if loaded.ndim != 1:
        raise SceneError(source, "[body] file", str(path), "line contact: must be a .npy file holding one "
                         f"1-D array of heights (m) along x, got shape {getattr(loaded, 'shape', None)}")
    return HeightProfile(loaded, cell, source=source)


def _resolve_file(source: str, value: object, base_dir: pathlib.Path,
                  key: str = "[body] file") -> pathlib.Path:
    if not isinstance(value, (str, os.PathLike)) or not os.fspath(value):
        raise SceneError(source, key, value, f"must be a path string, not {type_name(value)}")
    path = pathlib.Path(value)
    if not path.is_absolute():
        path = pathlib.Path(base_dir) / path
    return path


def _measured(values: dict, base_dir: pathlib.Path, source: str, prefix: str):
    """The Topography of a table's file keys (_FILE_KEYS), errors naming ``prefix`` + key."""
    path = _resolve_file(source, values["file"], base_dir, f"{prefix}file")
    cell = None if values.get("cell") is None else cell_pair(source, values["cell"], f"{prefix}cell")
    return read_topography(path, fmt=values.get("format"), cell=cell, unit=values.get("unit", "m"),
                           source=source, prefix=prefix)


def _roughness(table: object, grid: Grid | None, base_dir: pathlib.Path, source: str) -> PeriodicSurface:
    """A body's ``roughness``: generated (ROUGH_KEYS) on the grid's cells and size, or measured
    (_FILE_KEYS); sample (0, 0) at the body's reference point."""
    prefix = "[body] roughness."
    if not isinstance(table, dict):
        raise SceneError(source, "[body] roughness", table, "must be an inline table: " + _ROUGHNESS)
    if "file" in table:
        for key in table:
            if key not in _FILE_KEYS:
                raise SceneError(source, prefix + key, table[key], "unknown key for a measured roughness; "
                                 "allowed keys: " + ", ".join(_FILE_KEYS))
        topography = _measured(table, base_dir, source, prefix)
        return PeriodicSurface(topography.heights, topography.cell, source=source)
    if grid is None:
        raise SceneError(source, "[body] roughness", table, "a generated roughness needs the scene's grid")
    cell = (grid.dx, grid.dy)
    heights = self_affine_heights(table, (grid.nx, grid.ny), cell, source=source, prefix=prefix)
    return PeriodicSurface(heights, cell, source=source)


def _keys(table: dict, catalogue: dict, line: bool, source: str) -> dict:
    """The shape's keys with their defaults, or SceneError for an unknown shape, key or a missing key."""
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
    defaults = {} if line else _DEFAULTS.get(shape, {})
    values = {}
    for key in keys:
        if key in table:
            values[key] = table[key]
        elif key in defaults:
            values[key] = defaults[key]
        else:
            raise SceneError(source, f"[body] {key}", MISSING, f"required for shape {shape!r}: {keys[key]}")
    return values


def make_body(table: dict, base_dir: pathlib.Path, source: str, line: bool = False,
              grid: Grid | None = None) -> Body:
    """Build the body of a scene's ``[body]`` table (``shape`` plus that shape's keys, see BODY_KEYS).

    ``line``: a line-contact (plane-strain) scene: only the shapes of LINE_BODY_KEYS, as profiles Z(x).
    ``grid``: the scene's grid (a generated roughness takes its cells and size; a height map whose samples
    sit on its cells' centres with the body at the table's ``position``, m, is a :class:`CellMap`).

    Relative file paths are resolved against ``base_dir``.  Raises SceneError for an unknown shape or key,
    a missing key, a wrong type or a bad value.
    """
    values = _keys(table, LINE_BODY_KEYS if line else BODY_KEYS, line, source)
    shape = table["shape"]
    if line and shape == "cylinder":
        return CylinderSection(values["radius"], source=source)
    if line:
        return _profile_from_npy(_resolve_file(source, values["file"], base_dir), values["cell"], source)
    if shape == "heightmap":
        topography = _measured(values, base_dir, source, "[body] ")
        surface = None if grid is None else samples_surface(topography.heights, topography.cell, grid)
        if surface is not None:
            return surface
        position = point_pair(source, "[body] position", table.get("position", (0.0, 0.0)))
        if grid is not None and on_cells(topography.heights, topography.cell, grid, position):
            return CellMap(topography.heights, topography.cell, source=source)
        return HeightMap(topography.heights, topography.cell, source=source)
    if shape == "rough":
        if grid is None:
            raise SceneError(source, "[body] shape", shape, "a generated rough surface needs the scene's grid")
        cell = (grid.dx, grid.dy)
        rough = {key: value for key, value in table.items() if key in ROUGH_KEYS}
        heights = self_affine_heights(rough, (grid.nx, grid.ny), cell, source=source)
        return grid_surface(heights, cell, grid, source=source)
    if shape == "mesh":
        path = _resolve_file(source, values["file"], base_dir)
        return mesh_height_map(path, cell_pair(source, values["cell"]), source=source)
    if shape == "sphere":
        body = Sphere(values["radius"], source=source)
    elif shape == "ellipsoid":
        body = Ellipsoid(values["radius_x"], values["radius_y"], source=source)
    else:
        body = Cylinder(values["radius"], values["width"], values["edge_radius"], values["axis"],
                        source=source)
    if values["roughness"] is None:
        return body
    return RoughBody(body, _roughness(values["roughness"], grid, base_dir, source))
