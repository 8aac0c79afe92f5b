"""Scenes: TOML files read into frozen, validated objects.

Every key of every section is declared once in :data:`petroll.model.schema.SCHEMA`; this module reads a
scene's sections with it and checks the rules between keys and sections (one of penetration or load, a
material's keys, a steady scene's motion, the grid's size and scale). Every error is a
:class:`~petroll.errors.SceneError` naming the file, the key, the bad value and what is allowed. The solver
needs only consistent units; SI (m, Pa, N, s) is recommended.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import pathlib
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from petroll.errors import MISSING, SceneError
from petroll.model import materials
from petroll.model import motion
from petroll.model.autogrid import REQUEST_KEYS, GridChoice, automatic, choose, provisional
from petroll.model.bodies import Body, HeightMap, HeightProfile, make_body
from petroll.model.bodies.rough import samples_surface
from petroll.model.clock import TimeMode
from petroll.model.friction import Friction, friction_of, saved_fields
from petroll.model.grid import Grid, line_grid
from petroll.model.limits import MAGNITUDES, PetrollWarning, scale_message
from petroll.model.schema import BODY_LENGTHS, CELL_DIGITS, MAX_CELLS, MODEL_KEYS, SCHEMA, Invalid, out_of_scale
from petroll.model.toml_file import check_nesting, read_scene_file


# -- the validated scene ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Solver:
    tao_type: str
    tol: float
    integrator: str  # "relaxation", "exponential" or "paper"
    history_cutoff: float = 1e-9  # relative; see petroll/wake.py
    pressure_tol: float | None = None  # bound on each QP's relative L2 pressure error (None: tol alone)



@dataclass(frozen=True)
class Time:
    """Time stepping; ``dt`` and ``steps_per_cell`` both None: a single step at t = 0."""

    dt: float | None
    steps_per_cell: float | None
    end: float | None
    distance: float | None
    steady: float | None
    max_steps: int
    mode: TimeMode = TimeMode.TRANSIENT  # STEADY: the steady state solved directly (one step)
    allow_coarse: bool = False  # [time] allow_coarse: run below petroll.model.preflight.LEAST_STEPS


@dataclass(frozen=True)
class Scene:
    """A validated scene. ``raw`` is the parsed TOML (a deep copy), ``text`` the file's text."""

    source: str
    text: str
    raw: dict = field(repr=False)
    grid: Grid
    material: materials.Prony | materials.Tabulated  # surface creep compliance J(t), 1/Pa
    body: Body
    position: tuple[float, float]
    velocity: Any  # a vector program of petroll.model.motion, m/s
    penetration: Any  # a scalar program (m), or None under load control
    load: Any  # a scalar program (N), or None under displacement control
    time: Time
    solver: Solver
    output_dir: pathlib.Path
    every: int
    base_dir: pathlib.Path = field(repr=False)
    checkpoint_every: int = 0  # steps between checkpoints (0: none)
    keep: int = 2  # checkpoints kept
    fields: tuple[str, ...] = ("pressure",)  # saved at the saved steps ([output] fields)
    shift_factor: float = 1.0  # a_T at [material] temperature: material's times / their values at T_ref
    layer: materials.Layer | None = None  # [material] layer: a layer on a rigid base (None: a half-space)
    allow_coarse: bool = False  # [grid] allow_coarse: run below petroll.model.preflight.LEAST_CELLS
    friction: Friction | None = None  # [friction]: Coulomb friction (None: frictionless)
    sizing: GridChoice | None = None  # the grid petroll sized (raw and text hold it); None: [grid] as given

    def replace(self, changes: str | dict[str, Any], value: Any = None) -> "Scene":
        """A copy with keys changed, validated again: ``scene.replace("motion.penetration", 3e-5)`` or,
        for changes that are only valid together, ``scene.replace({"motion.penetration": None,
        "motion.load": 0.2})``; a key inside an inline table is written with one more dot
        (``material.layer.thickness``). A value of None removes the key. A scene whose grid petroll sized
        is sized again for the changed keys, unless they change [grid] nx, ny, x or y: those change the
        grid it chose.
        """
        if isinstance(changes, str):
            changes = {changes: value}
        raw = copy.deepcopy(self.raw)
        if self.sizing is not None and all(not key.startswith("grid.") or key[5:] in REQUEST_KEYS
                                           for key in changes):
            raw["grid"] = copy.deepcopy(self.sizing.request)
        for key, new in changes.items():
            *path, name = key.split(".")
            if not path or not all(path) or not name:
                raise SceneError(self.source, key, new, "must be written section.key, e.g. motion.load")
            table = raw
            for depth, part in enumerate(path):
                if depth > 0 and part not in table:  # an inline table the scene does not have
                    raise SceneError(self.source, key, new, f"the scene has no {'.'.join(path[:depth + 1])}: "
                                     f"write {'.'.join(path[:depth + 1])} = {{...}} whole")
                table = table.setdefault(part, {})
                if not isinstance(table, dict):
                    raise SceneError(self.source, key, new, f"{part} is not a table: write {part} itself")
            if new is None:
                table.pop(name, None)
            else:
                table[name] = new
        return parse_scene(raw, source=self.source, base_dir=self.base_dir, text=None)


def shipped_scene(name: str) -> pathlib.Path:
    """The path of a scene shipped in runs/ (installed as the package data ``petroll.scenes``)."""
    from importlib.resources import files

    return pathlib.Path(str(files("petroll.scenes").joinpath(name)))


def load_scene(path: str | pathlib.Path) -> Scene:
    """Read and validate a scene file (TOML)."""
    path = pathlib.Path(path)
    text, raw = read_scene_file(path)
    default_out = pathlib.Path("results") / path.stem
    return parse_scene(raw, source=str(path), base_dir=path.parent, text=text, default_output=default_out)


def parse_scene(raw: dict, source: str = "<python>", base_dir: str | pathlib.Path = ".",
                text: str | None = None, default_output: pathlib.Path | None = None) -> Scene:
    """Validate a scene given as a dict of sections (the parsed TOML); ``text`` defaults to its TOML."""
    if not isinstance(raw, dict):
        raise SceneError(source, "(scene)", raw, "must be a table of sections")
    check_nesting(raw, source)
    raw = copy.deepcopy(raw)
    base_dir = pathlib.Path(base_dir)
    for section in raw:
        if section not in SCHEMA:
            raise SceneError(source, f"[{section}]", raw[section],
                             "unknown section; allowed: " + ", ".join(f"[{s}]" for s in SCHEMA))
        if not isinstance(raw[section], dict):
            raise SceneError(source, f"[{section}]", raw[section], "must be a table of keys")
    if automatic(raw.get("grid") or None):
        return _sized_scene(raw, source, base_dir, default_output)
    line = _line_contact(raw.get("grid", {}), source)
    checked = _velocity_along_x(raw) if line else raw
    values = {name: _read_section(checked, name, source) for name in SCHEMA}

    g = values["grid"]
    for key in REQUEST_KEYS:  # they ask petroll to choose the grid
        if g[key] is not None:
            raise SceneError(source, f"[grid] {key}", raw["grid"][key], "sizes a grid petroll chooses: give "
                             "it without [grid] nx, ny, x, y (or leave it out)")
    if line:
        if g["periodic"] == (False, True):
            raise SceneError(source, "[grid] periodic", raw["grid"]["periodic"],
                             'a line-contact grid repeats along X only: true or ["x"]')
        grid = line_grid(g["nx"], *g["x"], periodic=g["periodic"][0])
    else:
        if g["nx"] * g["ny"] > MAX_CELLS:
            raise SceneError(source, "[grid] nx / ny", [g["nx"], g["ny"]], f"at most {MAX_CELLS} cells in "
                             "all (nx ny; PETSc's 32-bit indices)")
        grid = Grid(g["nx"], g["ny"], *g["x"], *g["y"], periodic=g["periodic"])
    _check_cells(grid, raw["grid"], source)
    material = _material(values["material"], raw.get("material", {}), base_dir, source)
    material, shift_factor = _temperature(values["material"], raw.get("material", {}), material, source)
    material, friction = friction_of(values, raw, material, line, any(g["periodic"]), source)
    for key in BODY_LENGTHS:
        if key in raw.get("body", {}) and (bad := out_of_scale(raw["body"][key])) is not None:
            raise SceneError(source, f"[body] {key}", raw["body"][key], scale_message(bad, "m"))
    body = periodic_body(make_body(raw.get("body", {}), base_dir, source, line=line, grid=grid), grid)
    m = values["motion"]
    if line:
        _check_line_motion(m, raw.get("motion", {}), source, grid.topology.whole)
    if (m["penetration"] is None) == (m["load"] is None):
        given = {k: v for k, v in raw.get("motion", {}).items() if k in ("penetration", "load")}
        raise SceneError(source, "[motion] penetration / load", given or MISSING,
                         "exactly one of penetration (m) or load (N) must be given")
    time = Time(**{**values["time"], "mode": TimeMode(values["time"]["mode"])})
    _check_time(time, raw.get("time", {}), source)
    integrator = values["solver"]["integrator"]
    if integrator is None:
        integrator = "relaxation" if isinstance(material, materials.Prony) else "paper"
    elif integrator in ("relaxation", "exponential") and not isinstance(material, materials.Prony):
        raise SceneError(source, "[solver] integrator", integrator,
                         'a tabulated material takes only "paper" (the hereditary sum)')
    out = values["output"]["dir"]
    output_dir = pathlib.Path(out) if out else (default_output or pathlib.Path("results") / "scene")
    scene = Scene(source=source, text=text if text is not None else dumps(raw), raw=raw, grid=grid,
                  material=material, body=body, position=values["body"]["position"],
                  velocity=m["velocity"], penetration=m["penetration"], load=m["load"], time=time,
                  solver=Solver(values["solver"]["tao_type"], values["solver"]["tol"], integrator,
                                values["solver"]["history_cutoff"], values["solver"]["pressure_tol"]),
                  output_dir=output_dir, every=values["output"]["every"], base_dir=base_dir,
                  checkpoint_every=values["output"]["checkpoint_every"], keep=values["output"]["keep"],
                  fields=values["output"]["fields"] + (saved_fields(line) if friction else ()), friction=friction,
                  shift_factor=shift_factor,
                  layer=_material_layer(values["material"], raw.get("material", {}), source),
                  allow_coarse=g["allow_coarse"])
    if time.mode is TimeMode.STEADY:
        _check_steady(scene)
    else:
        _check_steps(scene)
    _check_contact_inside(scene)
    from petroll.model.limits import check_scene  # slopes beyond the linear theory: refused or warned

    check_scene(scene)
    return scene


def _sized_scene(raw: dict, source: str, base_dir: pathlib.Path, default_output: pathlib.Path | None) -> Scene:
    """The scene on the grid petroll sizes for it (petroll.model.autogrid): the contact estimated on a
    provisional grid (its warnings not shown), the scene validated on the grid chosen; its raw and text hold
    that grid (the text as run, headed by a comment saying so), ``sizing`` what was asked and chosen."""
    request = copy.deepcopy(raw.get("grid") or {})
    for key, value in request.items():
        try:
            SCHEMA["grid"][key].check(value)
        except Invalid as exc:
            raise SceneError(source, f"[grid] {key}", value, str(exc)) from None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)
        estimate = parse_scene({**raw, "grid": provisional(raw, source, base_dir)}, source, base_dir, "",
                               default_output)
    choice = choose(estimate, request)
    chosen = {**copy.deepcopy(raw), "grid": choice.table}
    scene = parse_scene(chosen, source, base_dir, f"# {choice.note}\n" + dumps(chosen), default_output)
    return dataclasses.replace(scene, sizing=choice)


def _line_contact(grid: dict, source: str) -> bool:
    """A [grid] without ny and y is a line-contact (plane-strain) scene; one of them alone is an error."""
    given = [key for key in ("ny", "y") if key in grid]
    if len(given) == 1:
        missing = "y" if given[0] == "ny" else "ny"
        raise SceneError(source, f"[grid] {missing}", MISSING, f"required with [grid] {given[0]}: give both ny "
                         "and y (3-D contact) or neither (line contact, plane strain)")
    return not given


def _velocity_along_x(raw: dict) -> dict:
    """A copy of ``raw`` whose [motion] velocity, if given as numbers (a number, or a program of numbers:
    line contact's motion along X), is written as [vx, 0] vectors; anything else is left to the checks."""
    velocity = raw.get("motion", {}).get("velocity")

    def vector(v: Any) -> Any:
        return [v, 0.0] if isinstance(v, (int, float)) and not isinstance(v, bool) else v

    if isinstance(velocity, dict):
        velocity = {k: ([vector(v) for v in value] if k == "value" and isinstance(value, list) else
                        value if k in ("kind", "t", "duration", "period", "phase") else vector(value))
                    for k, value in velocity.items()}
    elif velocity is not None:
        velocity = vector(velocity)
    else:
        return raw
    out = copy.deepcopy(raw)
    out["motion"]["velocity"] = velocity
    return out


def _check_line_motion(m: dict, table: dict, source: str, repeats: bool) -> None:
    """Line contact: load control only (penetration too on a grid that ``repeats``, whose displacements are
    taken from the deformed surface's mean plane), motion along X only."""
    if m["penetration"] is not None and not repeats:
        raise SceneError(source, "[motion] penetration", table["penetration"], "not allowed in line contact "
                         "([grid] without ny and y): in plane strain the displacement of a half-space is "
                         "logarithmic and has no zero far away, so a penetration is defined only relative "
                         "to an arbitrary datum; give [motion] load in N/m instead")
    program = m["velocity"]
    across = [np.asarray(v)[..., 1] for v in vars(program).values()
              if isinstance(v, np.ndarray) and v.shape and v.shape[-1] == 2]
    if any(np.any(v != 0) for v in across):
        raise SceneError(source, "[motion] velocity", table.get("velocity"), "line contact moves along X "
                         "only: a number, a program of numbers, or [vx, 0] (m/s)")


def _read_section(raw: dict, name: str, source: str) -> dict:
    table = raw.get(name, {})
    keys = SCHEMA[name]
    values = {}
    for key, spec in keys.items():
        if key not in table:
            if spec.default is MISSING:
                raise SceneError(source, f"[{name}] {key}", MISSING, f"required: {spec.doc} ({spec.unit})")
            values[key] = None if spec.default is None else spec.check(spec.default)
            continue
        try:
            values[key] = spec.check(table[key])
        except Invalid as exc:
            unit = f" ({spec.unit})" if spec.unit != "-" else ""
            raise SceneError(source, f"[{name}] {key}", table[key], f"{exc}{unit}") from None
        if spec.unit != "-" and (bad := out_of_scale(table[key])) is not None:
            raise SceneError(source, f"[{name}] {key}", table[key], scale_message(bad, spec.unit))
    if name != "body":  # [body] takes its shape's keys too: make_body checks them
        for key in table:
            if key not in keys:
                raise SceneError(source, f"[{name}] {key}", table[key],
                                 "unknown key; allowed: " + ", ".join(keys))
    return values


def _material(values: dict, table: dict, base_dir: pathlib.Path, source: str):
    """J(t) of the [material] table (keys already type-checked) after the per-model key rules."""
    model = values["model"]
    required, optional = MODEL_KEYS[model]
    for key in table:
        if key != "model" and key not in required | optional:
            allowed = ", ".join(sorted(required | optional))
            raise SceneError(source, f"[material] {key}", table[key], f"not a key of model {model!r}; "
                             f"allowed: {allowed}")
    for key in sorted(required):
        if key not in table:
            raise SceneError(source, f"[material] {key}", MISSING, f"required for model {model!r}: "
                             f"{SCHEMA['material'][key].doc} ({SCHEMA['material'][key].unit})")
    v = values
    if model == "elastic":
        return materials.elastic(v["E"], v["nu"])
    if model == "sls":
        if (v["tau_creep"] is None) == (v["tau_relax"] is None):
            raise SceneError(source, "[material] tau_creep / tau_relax", MISSING,
                             "exactly one of tau_creep or tau_relax (s) must be given for model 'sls'")
        if v["E0"] < v["Einf"]:
            raise SceneError(source, "[material] E0", v["E0"], f"must be >= Einf = {v['Einf']:g} (Pa): "
                             "the instantaneous modulus is the larger")
        _check_stiffness_ratio(v["E0"] / v["Einf"], "[material] E0", v["E0"], source)
        return materials.sls(v["E0"], v["Einf"], v["nu"], v["tau_creep"], v["tau_relax"])
    if model == "prony":
        terms = "compliances" if v["series"] == "kelvin" else "moduli"
        other = "moduli" if terms == "compliances" else "compliances"
        if v[other] is not None:
            raise SceneError(source, f"[material] {other}", table[other],
                             f"not a key of a {v['series']} series; give {terms}")
        if v[terms] is None or len(v[terms]) != len(v["times"]):
            raise SceneError(source, f"[material] {terms}", table.get(terms, MISSING),
                             f"required: one value per entry of times ({len(v['times'])})")
        ordered = sorted(v["times"])
        close = [(a, b) for a, b in zip(ordered, ordered[1:]) if b - a <= DISTINCT_TIMES * b]
        if close:
            a, b = close[0]
            same = f"{a!r} appears twice" if a == b else f"{a!r} and {b!r} are within {DISTINCT_TIMES:g} of each other"
            raise SceneError(source, "[material] times", table["times"],
                             f"must differ: {same}; merge terms of one time into one (add their {terms})")
        if terms == "moduli":
            ratio = 1.0 + sum(v["moduli"]) / v["Einf"]
        else:
            rest = 1.0 / v["Einf"] - math.fsum(v["compliances"])  # D(0), 1/Pa
            ratio = 1.0 / (v["Einf"] * rest) if rest > 0 else math.inf
        _check_stiffness_ratio(ratio, f"[material] {terms}", table[terms], source)
        build = materials.kelvin if terms == "compliances" else materials.maxwell
        return build(v["Einf"], v["nu"], v[terms], v["times"])
    return _tabulated_material(v, base_dir, source)


def _material_layer(values: dict, table: dict, source: str) -> materials.Layer | None:
    """The [material] layer with the material's nu (required with a layer, even for quantity = "J")."""
    if values["layer"] is None:
        return None
    if values["nu"] is None:
        raise SceneError(source, "[material] nu", MISSING, "required with [material] layer: the layer's "
                         "response depends on Poisson's ratio (-1 < nu <= 0.5)")
    return materials.Layer(*values["layer"], values["nu"])


DISTINCT_TIMES = 1e-9
"""The least relative difference between two times of a Prony series: the creep and relaxation forms
(materials.maxwell, relaxation_series) put one root between each pair of neighbouring times."""

MAX_STIFFNESS_RATIO = 1e7
"""The largest E0/Einf = Jinf/J0 of a Prony material: J0 = Jinf - sum dJ then keeps its digits to about
2e-9 (1e7 x the float's 2.2e-16), below the solver's default tolerance."""


def _check_stiffness_ratio(ratio: float, key: str, value: Any, source: str) -> None:
    """SceneError unless the instantaneous over the relaxed modulus, E0/Einf (inf: the creep compliances
    leave no instantaneous one), is at most MAX_STIFFNESS_RATIO."""
    if ratio <= MAX_STIFFNESS_RATIO:
        return
    what = ("leaves no instantaneous compliance (the compliances must sum to less than 1/Einf)"
            if ratio == math.inf and key.endswith("compliances") else f"gives E0/Einf = {ratio:.3g}")
    raise SceneError(source, key, value, f"{what}; allowed: E0/Einf <= {MAX_STIFFNESS_RATIO:g}, beyond which "
                     "J0 = Jinf - sum dJ loses its digits in double precision")


def _temperature(values: dict, table: dict, material, source: str):
    """(material at [material] temperature, a_T): every time multiplied by a_T (1 without temperature)."""
    T, law = values["temperature"], values["shift"]
    if T is None and law is None:
        return material, 1.0
    if T is None or law is None:
        given, missing = ("temperature", "shift") if law is None else ("shift", "temperature")
        raise SceneError(source, f"[material] {given}", table[given], f"needs [material] {missing} too: "
                         f"temperature (K) and shift = {materials.SHIFT_FORMS} go together")
    try:
        factor = materials.shift_factor(law, T)
    except ValueError as exc:
        raise SceneError(source, "[material] temperature", table["temperature"], str(exc)) from None
    material = materials.shifted(material, factor)
    times = material.tau if isinstance(material, materials.Prony) else material.t[1:]
    if times and out_of_scale(list(times)) is not None:
        raise SceneError(source, "[material] temperature", table["temperature"], f"gives a_T = {factor:.4g}, "
                         f"which takes the material's times outside {MAGNITUDES[0]:g} ... {MAGNITUDES[1]:g} "
                         "s; a temperature nearer T_ref is needed")
    return material, factor


def _tabulated_material(v: dict, base_dir: pathlib.Path, source: str) -> materials.Tabulated:
    path = base_dir / v["file"]
    try:
        table = np.loadtxt(path, delimiter=",", ndmin=2, comments="#")
    except (OSError, ValueError) as exc:
        raise SceneError(source, "[material] file", v["file"], f"must be a readable CSV of numbers t, value "
                         f"({exc})") from None
    allowed = ("must hold two columns t (s), value (1/Pa) with t increasing from 0 and values > 0, "
               "non-decreasing")
    if table.shape[1] != 2 or table.shape[0] < 1:
        raise SceneError(source, "[material] file", v["file"], allowed)
    t, value = table[:, 0], table[:, 1]
    if (not np.all(np.isfinite(table)) or t[0] != 0 or np.any(np.diff(t) <= 0) or np.any(value <= 0)
            or np.any(np.diff(value) < 0)):
        raise SceneError(source, "[material] file", v["file"], allowed)
    if v["quantity"] == "D":
        if v["nu"] is None:
            raise SceneError(source, "[material] nu", MISSING, 'required with quantity = "D"')
        value = value * (1 - v["nu"] ** 2)
    return materials.Tabulated(tuple(t), tuple(value))


STEADY_TIME_KEYS = ("mode", "steps_per_cell", "dt", "allow_coarse")
"""The [time] keys a scene with mode = "steady" may give (the integrator's step; no clock)."""


def _check_time(time: Time, table: dict, source: str) -> None:
    if not table:
        return
    if time.mode is TimeMode.STEADY:
        for key in table:
            if key not in STEADY_TIME_KEYS:
                raise SceneError(source, f"[time] {key}", table[key], 'not with mode = "steady" (one step, the '
                                 "steady state, no clock); allowed with it: " + ", ".join(STEADY_TIME_KEYS))
        if time.dt is not None and time.steps_per_cell is not None:
            raise SceneError(source, "[time] dt / steps_per_cell", [time.dt, time.steps_per_cell],
                             'at most one of dt (s) or steps_per_cell with mode = "steady"')
        return
    if (time.dt is None) == (time.steps_per_cell is None):
        raise SceneError(source, "[time] dt / steps_per_cell", MISSING, "exactly one of dt (s) or "
                         "steps_per_cell must be given")
    if (time.end is None) == (time.distance is None):
        raise SceneError(source, "[time] end / distance", MISSING, "exactly one of end (s) or distance (m) "
                         "must be given")
    if time.dt is not None and time.end is not None and time.end / time.dt > time.max_steps + 1:
        raise SceneError(source, "[time] dt", time.dt, f"too small: end / dt = {time.end / time.dt:.3g} "
                         f"steps, more than [time] max_steps = {time.max_steps}; raise max_steps or the "
                         "time step")


def _check_cells(grid: Grid, table: dict, source: str) -> None:
    """Refuse cells too narrow for the grid's coordinates to keep their digits (CELL_DIGITS)."""
    for axis, side, lo, hi in (("x", grid.dx, grid.x0, grid.x1), ("y", grid.dy, grid.y0, grid.y1)):
        if axis == "y" and grid.line:
            continue
        if side < CELL_DIGITS * max(abs(lo), abs(hi)):
            raise SceneError(source, f"[grid] {axis}", table[axis], f"cells {side:.3g} m wide at coordinates "
                             f"up to {max(abs(lo), abs(hi)):.3g} m: a cell must be at least {CELL_DIGITS:g} "
                             "of the largest coordinate, or positions on it lose their digits; move the "
                             "grid's origin nearer to it")


def _check_steps(scene: Scene) -> None:
    """Refuse a run to [time] distance that would take more than [time] max_steps steps at least, as a run
    to [time] end is (each step covers at most the peak speed times dt, or a cell / steps_per_cell), and
    one that never rolls its distance (a body at rest)."""
    tm, source = scene.time, scene.source
    if tm.distance is None or (tm.dt is None and tm.steps_per_cell is None):
        return
    peak = float(scene.velocity.peak())
    if peak == 0:
        raise SceneError(source, "[time] distance", tm.distance, "a body at rest never rolls it: give [motion] "
                         "velocity, or [time] end")
    per_step = peak * tm.dt if tm.dt is not None else scene.grid.cell / tm.steps_per_cell
    steps = tm.distance / per_step
    if steps > tm.max_steps + 1:
        key, value = ("[time] dt", tm.dt) if tm.dt is not None else ("[time] steps_per_cell", tm.steps_per_cell)
        how = ("distance / (peak speed x dt)" if tm.dt is not None else "distance / cell x steps_per_cell")
        raise SceneError(source, key, value, f"too many steps: {how} = {steps:.3g} steps at least, more than "
                         f"[time] max_steps = {tm.max_steps}; raise max_steps or the time step")


def _check_steady(scene: Scene) -> None:
    """[time] mode = "steady": a constant, non-zero velocity along X or Y (on a periodic grid: in any
    direction along its periodic axes), a constant penetration or load and a Prony (SLS, elastic)
    material; anything else refused naming its key."""
    raw, source = scene.raw.get("motion", {}), scene.source
    velocity = scene.velocity
    value = np.asarray(getattr(velocity, "value", (0.0, 0.0)), dtype=float)
    allowed, wrong = scene.grid.topology.steady_velocity(value)
    if not isinstance(velocity, motion.Constant):
        raise SceneError(source, "[motion] velocity", raw.get("velocity"), f"varies in time; {allowed}")
    if wrong:
        raise SceneError(source, "[motion] velocity", raw.get("velocity", [0.0, 0.0]), allowed)
    for key in ("penetration", "load"):
        if getattr(scene, key) is not None and not isinstance(getattr(scene, key), motion.Constant):
            raise SceneError(source, f"[motion] {key}", raw[key], 'varies in time; with [time] mode = '
                             '"steady" it must be a constant number')
    if not isinstance(scene.material, materials.Prony):
        raise SceneError(source, "[material] model", scene.raw["material"].get("model"), 'with [time] mode = '
                         '"steady" it must be "elastic", "sls" or "prony" (a tabulated J needs mode = '
                         '"transient")')


def periodic_body(body: Body, grid: Grid) -> Body:
    """On a periodic grid, a height map (a line-contact profile) of as many samples as the grid has cells,
    at the grid's spacing, becomes the periodic surface through its samples (petroll.model.bodies.rough): with
    the body at [body] position [0, 0], sample (i, j) on the centre of cell (i, j). Any other body as it is
    (its offsets wrap around the periodic axes: Grid.offsets)."""
    if not grid.topology.whole:
        return body
    if isinstance(body, HeightProfile):
        surface = samples_surface(np.repeat(body.heights[:, None], 4, axis=1), (body.cell, grid.dy), grid)
    elif isinstance(body, HeightMap):
        surface = samples_surface(body.heights, body.cell, grid)
    else:
        return body
    return body if surface is None else surface


def _check_contact_inside(scene: Scene) -> None:
    """Refuse a start whose rigid interference region reaches the grid's edge cells (displacement control)
    along an axis that does not repeat."""
    if scene.penetration is None:
        return  # load control: checked at each solve, once the penetration is known
    g, (sx, sy) = scene.grid, scene.position
    delta = float(scene.penetration(0.0))
    for x, y in g.topology.edge_points(g.x, g.y):
        if np.any(delta - scene.body.height(*g.offsets(x, y, sx, sy)) > 0):
            raise SceneError(scene.source, "[grid] x / y", [[g.x0, g.x1], [g.y0, g.y1]],
                             "must contain the contact region: the body interferes with the surface up to "
                             "the grid's edge; enlarge the grid or reduce [motion] penetration")


def dumps(raw: dict) -> str:
    """A TOML text for a scene dict (written by tomli-w; numpy values as plain Python): what ``results.h5``
    stores and ``petroll material fit`` writes. Inline tables come out as sub-tables ([material.layer]):
    the same scene to a TOML reader."""
    import tomli_w

    return tomli_w.dumps(_plain(raw))


def toml_value(value: Any) -> str:
    """``value`` (not a table) written as one line of TOML, tomli-w's text of it without its line breaks:
    the defaults of the scene reference."""
    import tomli_w

    lines = tomli_w.dumps({"v": _plain(value)}).strip().partition(" = ")[2].splitlines()
    return " ".join(line.strip() for line in lines).replace("[ ", "[").replace(", ]", "]")


def _plain(value: Any) -> Any:
    """``value`` with numpy arrays and scalars as Python lists and numbers, tuples as lists."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_plain(v) for v in value]
    return value.item() if isinstance(value, np.generic) else value
