"""A scene's ``[body]`` table: the shapes, their keys (documented in docs/scene.md) and :func:`make_body`."""

from __future__ import annotations

import os
import pathlib

from petroll.errors import MISSING, SceneError
from petroll.model.bodies.analytic import Cylinder, CylinderSection, Ellipsoid, Sphere
from petroll.model.bodies.base import Body, cell_pair, type_name
from petroll.model.bodies.maps import HeightMap, HeightProfile, read_npy
from petroll.model.bodies.mesh import mesh_height_map

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
    loaded = read_npy(path, source, "a 1-D array of heights (m) along x")
    if loaded.ndim != 1:
        raise SceneError(source, "[body] file", str(path), "line contact: must be a .npy file holding one "
                         f"1-D array of heights (m) along x, got shape {getattr(loaded, 'shape', None)}")
    return HeightProfile(loaded, cell, source=source)


def _resolve_file(source: str, value: object, base_dir: pathlib.Path) -> pathlib.Path:
    if not isinstance(value, (str, os.PathLike)) or not os.fspath(value):
        raise SceneError(source, "[body] file", value, f"must be a path string, not {type_name(value)}")
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
    cell = cell_pair(source, values["cell"])
    if shape == "heightmap":
        return HeightMap.from_npy(path, cell, source=source)
    return mesh_height_map(path, cell, source=source)
