"""Scenes: TOML files read into frozen, validated objects.

Every key of every section is declared once in :data:`SCHEMA` (type, unit, default, allowed values, one
line of documentation); docs/scene.md is generated from it (``petroll keys``), and a test checks the two
agree. Every error is a :class:`~petroll.errors.SceneError` naming the file, the key, the bad value and
what is allowed. The solver needs only consistent units; SI (m, Pa, N, s) is recommended.
"""

from __future__ import annotations

import copy
import math
import pathlib
import tomllib
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from petroll.bodies import BODY_KEYS, Body, make_body
from petroll.contact import DEFAULT_TAO_TYPE, TAO_TYPES
from petroll.errors import MISSING, SceneError
from petroll.grid import Grid


# -- key declarations -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Key:
    """One scene key: ``kind`` names its type for the docs, ``check(value) -> converted or raise``."""

    kind: str
    doc: str
    check: Callable[[Any], Any]
    default: Any = MISSING  # MISSING: required
    unit: str = "-"


class _Invalid(ValueError):
    """Raised by a check with the text of what is allowed."""


def _number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise _Invalid("must be a finite number")
    return float(value)


def _positive(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise _Invalid("must be a finite number > 0")
    return float(value)


def _count(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise _Invalid("must be an integer >= 1")
    return int(value)


def _interval(value: Any) -> tuple[float, float]:
    allowed = "must be a pair [min, max] of finite numbers with min < max"
    if not isinstance(value, list) or len(value) != 2:
        raise _Invalid(allowed)
    try:
        lo, hi = _number(value[0]), _number(value[1])
    except _Invalid:
        raise _Invalid(allowed) from None
    if not lo < hi:
        raise _Invalid(allowed)
    return lo, hi


def _point(value: Any) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise _Invalid("must be a pair [x, y] of finite numbers")
    try:
        return _number(value[0]), _number(value[1])
    except _Invalid:
        raise _Invalid("must be a pair [x, y] of finite numbers") from None


def _poisson(value: Any) -> float:
    nu = _number(value)
    if not -1.0 < nu <= 0.5:
        raise _Invalid("must be a number with -1 < nu <= 0.5")
    return nu


def _tolerance(value: Any) -> float:
    tol = _positive(value)
    if not 1e-15 <= tol <= 1e-1:
        raise _Invalid("must be a number between 1e-15 and 0.1")
    return tol


def _choice(*options: str) -> Callable[[Any], str]:
    def check(value: Any) -> str:
        if not isinstance(value, str) or value not in options:
            raise _Invalid("must be one of: " + ", ".join(repr(o) for o in options))
        return value

    return check


def _text(value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise _Invalid("must be a non-empty string")
    return value


SCHEMA: dict[str, dict[str, Key]] = {
    "grid": {
        "nx": Key("integer", "number of cells along X", _count),
        "ny": Key("integer", "number of cells along Y", _count),
        "x": Key("[min, max]", "extent of the grid along X in the material frame", _interval, unit="m"),
        "y": Key("[min, max]", "extent of the grid along Y in the material frame", _interval, unit="m"),
    },
    "material": {
        "model": Key("string", 'constitutive model: "elastic"', _choice("elastic")),
        "E": Key("number > 0", "Young's modulus (model elastic)", _positive, unit="Pa"),
        "nu": Key("number", "Poisson's ratio, -1 < nu <= 0.5", _poisson),
    },
    "body": {
        "shape": Key("string", "body shape: " + ", ".join(BODY_KEYS) + " (its own keys: see below)",
                     _choice(*BODY_KEYS)),
        "position": Key("[x, y]", "position of the body's reference point at t = 0", _point,
                        default=(0.0, 0.0), unit="m"),
    },
    "motion": {
        "penetration": Key("number > 0", "penetration delta of the body's lowest point below the "
                           "undeformed surface (displacement control; exactly one of penetration, load)",
                           _positive, default=None, unit="m"),
        "load": Key("number > 0", "total normal force F (load control; exactly one of penetration, load)",
                    _positive, default=None, unit="N"),
    },
    "solver": {
        "tao_type": Key("string", "TAO bound-constrained solver for each contact QP (command line: "
                        "-petroll_tao_type)", _choice(*TAO_TYPES), default=DEFAULT_TAO_TYPE),
        "tol": Key("number", "relative tolerance on the contact conditions: max |min(p, gap)| in units "
                   "of the largest interference (gap) and its pressure (p)", _tolerance, default=1e-8),
    },
    "output": {
        "dir": Key("string", "output directory, relative to the current directory (command line: --out); "
                   "default results/<scene file name without .toml>", _text, default=None),
    },
}
"""Every section and key of a version-1 scene. [body] also takes the keys of its shape (BODY_KEYS)."""


# -- the validated scene ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Elastic:
    """A linear elastic half-space; ``compliance`` is the surface compliance J = (1 - nu^2)/E in 1/Pa."""

    E: float
    nu: float

    @property
    def compliance(self) -> float:
        return (1.0 - self.nu**2) / self.E


@dataclass(frozen=True)
class Solver:
    tao_type: str
    tol: float


@dataclass(frozen=True)
class Scene:
    """A validated scene. ``raw`` is the parsed TOML (a deep copy), ``text`` the file's text."""

    source: str
    text: str
    raw: dict = field(repr=False)
    grid: Grid
    material: Elastic
    body: Body
    position: tuple[float, float]
    penetration: float | None
    load: float | None
    solver: Solver
    output_dir: pathlib.Path
    base_dir: pathlib.Path = field(repr=False)

    def replace(self, key: str, value: Any) -> "Scene":
        """A copy with one key changed, e.g. ``scene.replace("motion.load", 2.0)``; validated again.

        A value of None removes the key.
        """
        raw = copy.deepcopy(self.raw)
        section, _, name = key.partition(".")
        if not name:
            raise SceneError(self.source, key, value, "must be written section.key, e.g. motion.load")
        table = raw.setdefault(section, {})
        if value is None:
            table.pop(name, None)
        else:
            table[name] = value
        return parse_scene(raw, source=self.source, base_dir=self.base_dir, text=None)


def load_scene(path: str | pathlib.Path) -> Scene:
    """Read and validate a scene file (TOML)."""
    path = pathlib.Path(path)
    source = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SceneError(source, "(file)", str(path), f"must be a readable scene file ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise SceneError(source, "(file)", str(path), "must be a UTF-8 text file (TOML)") from None
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(source, "(syntax)", str(exc), "must be valid TOML") from None
    default_out = pathlib.Path("results") / path.stem
    return parse_scene(raw, source=source, base_dir=path.parent, text=text, default_output=default_out)


def parse_scene(raw: dict, source: str = "<python>", base_dir: str | pathlib.Path = ".",
                text: str | None = None, default_output: pathlib.Path | None = None) -> Scene:
    """Validate a scene given as a dict of sections (the parsed TOML); ``text`` defaults to its TOML."""
    raw = copy.deepcopy(raw)
    base_dir = pathlib.Path(base_dir)
    for section in raw:
        if section not in SCHEMA:
            raise SceneError(source, f"[{section}]", raw[section],
                             "unknown section; allowed: " + ", ".join(f"[{s}]" for s in SCHEMA))
        if not isinstance(raw[section], dict):
            raise SceneError(source, f"[{section}]", raw[section], "must be a table of keys")
    values = {name: _read_section(raw, name, source) for name in SCHEMA}

    g = values["grid"]
    grid = Grid(g["nx"], g["ny"], *g["x"], *g["y"])
    m = values["material"]
    material = Elastic(m["E"], m["nu"])
    body = make_body(raw.get("body", {}), base_dir, source)
    motion = values["motion"]
    if (motion["penetration"] is None) == (motion["load"] is None):
        given = {k: v for k, v in raw.get("motion", {}).items() if k in ("penetration", "load")}
        raise SceneError(source, "[motion] penetration / load", given or MISSING,
                         "exactly one of penetration (m) or load (N) must be given")
    out = values["output"]["dir"]
    output_dir = pathlib.Path(out) if out else (default_output or pathlib.Path("results") / "scene")
    scene = Scene(source=source, text=text if text is not None else dumps(raw), raw=raw, grid=grid,
                  material=material, body=body, position=values["body"]["position"],
                  penetration=motion["penetration"], load=motion["load"],
                  solver=Solver(**values["solver"]), output_dir=output_dir, base_dir=base_dir)
    _check_contact_inside(scene)
    return scene


def _read_section(raw: dict, name: str, source: str) -> dict:
    table = raw.get(name, {})
    keys = SCHEMA[name]
    values = {}
    for key, spec in keys.items():
        if key not in table:
            if spec.default is MISSING:
                raise SceneError(source, f"[{name}] {key}", MISSING, f"required: {spec.doc} ({spec.unit})")
            values[key] = spec.default
            continue
        try:
            values[key] = spec.check(table[key])
        except _Invalid as exc:
            unit = f" ({spec.unit})" if spec.unit != "-" else ""
            raise SceneError(source, f"[{name}] {key}", table[key], f"{exc}{unit}") from None
    if name != "body":  # [body] takes its shape's keys too: make_body checks them
        for key in table:
            if key not in keys:
                raise SceneError(source, f"[{name}] {key}", table[key],
                                 "unknown key; allowed: " + ", ".join(keys))
    return values


def _check_contact_inside(scene: Scene) -> None:
    """Refuse a penetration whose rigid interference region reaches the grid's edge cells."""
    if scene.penetration is None:
        return  # load control: checked at each solve, once the penetration is known
    g, (sx, sy) = scene.grid, scene.position
    edges = [(g.x[[0, -1]][:, None], g.y[None, :]), (g.x[:, None], g.y[[0, -1]][None, :])]
    for x, y in edges:
        if np.any(scene.penetration - scene.body.height(x - sx, y - sy) > 0):
            raise SceneError(scene.source, "[grid] x / y", [[g.x0, g.x1], [g.y0, g.y1]],
                             "must contain the contact region: the body interferes with the surface up to "
                             "the grid's edge; enlarge the grid or reduce [motion] penetration")


def dumps(raw: dict) -> str:
    """A TOML text for a scene dict (sections of scalars and flat lists): what ``results.h5`` stores."""
    lines = []
    for section, table in raw.items():
        lines.append(f"[{section}]")
        lines += [f"{key} = {_toml_value(value)}" for key, value in table.items()]
        lines.append("")
    return "\n".join(lines)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + "}"
    return repr(value)
