"""The scene schema: every key of every section declared once in :data:`SCHEMA` (type, unit, default,
allowed values, one line of documentation) with the check that converts its value or says what is
allowed. docs/scene.md is generated from it (``petroll keys``, petroll/model/reference.py); the rules
between keys and sections live with the parser (petroll/model/scene.py). Units: any consistent set; SI
(m, Pa, N, s) is recommended and is what the units given here assume.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from petroll.errors import MISSING
from petroll.model import materials
from petroll.model import motion
from petroll.model.limits import MAGNITUDES, scale_message
from petroll.model.bodies import BODY_KEYS
from petroll.model.tao import DEFAULT_TAO_TYPE, TAO_TYPES

DEFAULT_STEADY = 1e-3
"""The [time] steady tolerance a sweep gives a scene that has none (docs/sweep.md)."""

SAVED_FIELDS = ("pressure", "displacement", "gap")
"""The fields a run can save at its saved steps ([output] fields; units in petroll.io.results.FIELD_UNITS);
a run with [friction] saves friction's too (petroll.model.friction.FIELDS)."""


@dataclass(frozen=True)
class Key:
    """One scene key: ``kind`` names its type for the docs, ``check(value) -> converted or raise``."""

    kind: str
    doc: str
    check: Callable[[Any], Any]
    default: Any = MISSING  # as written in TOML, checked like a given value; None: unset; MISSING: required
    unit: str = "-"
    fields: tuple[tuple[str, str], ...] = ()  # an inline table's (key, unit) where the unit is not "-"


class Invalid(ValueError):
    """Raised by a check with the text of what is allowed."""


def _number(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise Invalid("must be a finite number")
    return float(value)


def _positive(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise Invalid("must be a finite number > 0")
    return float(value)


def _count(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise Invalid("must be an integer >= 1")
    return int(value)


BODY_LENGTHS = ("radius", "radius_x", "radius_y", "width", "edge_radius", "cell")
"""[body] keys that are lengths (m), held to MAGNITUDES like the schema's keys with units."""

CELL_DIGITS = 1e-9
"""A cell narrower than this fraction of the grid's largest coordinate is refused: its centre (and the
body's position on it) would keep fewer than 7 of double precision's digits."""


def out_of_scale(value: Any) -> float | None:
    """The first non-zero number in ``value`` (a number, or lists and inline tables of them; a program's
    ``phase`` and strings left out) whose magnitude lies outside MAGNITUDES; None if there is none."""
    if isinstance(value, bool) or isinstance(value, str):
        return None
    if isinstance(value, (int, float)):
        return float(value) if value and not MAGNITUDES[0] <= abs(value) <= MAGNITUDES[1] else None
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, item in items:
        if key != "phase" and (bad := out_of_scale(item)) is not None:
            return bad
    return None


MAX_CELLS_AXIS, MAX_CELLS = 2**24, 2**31 - 1
"""Grid size limits: PETSc's 32-bit indices number at most 2^31 - 1 cells; 2^24 per axis keeps the
coordinate arrays small (a grid that long is never needed)."""


MAX_STEPS = 10**6
"""The largest [time] max_steps: the run's clock is walked before step 1 (petroll check), tens of seconds
for a million steps, and a million steps take hours at the least."""


def _steps(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_STEPS:
        raise Invalid(f"must be an integer >= 1, at most {MAX_STEPS}")
    return int(value)


def _cells(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_CELLS_AXIS:
        raise Invalid(f"must be an integer >= 1, at most {MAX_CELLS_AXIS} (2^24)")
    return int(value)


PERIODIC_FORM = 'true (X and Y; a line-contact grid: X), false, or a list of axes: ["x"], ["y"], ["x", "y"]'
"""What [grid] periodic may be written as."""


def _periodic(value: Any) -> tuple[bool, bool]:
    """[grid] periodic: (along X, along Y); a line-contact grid's true is (True, False) (parse_scene)."""
    if isinstance(value, bool):
        return (value, value)
    if (isinstance(value, list) and value and len(set(map(str, value))) == len(value)
            and all(v in ("x", "y") for v in value)):
        return ("x" in value, "y" in value)
    raise Invalid(f"must be {PERIODIC_FORM}")


def _interval(value: Any) -> tuple[float, float]:
    allowed = "must be a pair [min, max] of finite numbers with min < max"
    if not isinstance(value, list) or len(value) != 2:
        raise Invalid(allowed)
    try:
        lo, hi = _number(value[0]), _number(value[1])
    except Invalid:
        raise Invalid(allowed) from None
    if not lo < hi:
        raise Invalid(allowed)
    return lo, hi


def _point(value: Any) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise Invalid("must be a pair [x, y] of finite numbers")
    try:
        return _number(value[0]), _number(value[1])
    except Invalid:
        raise Invalid("must be a pair [x, y] of finite numbers") from None


def _flag(value: Any) -> bool:
    if not isinstance(value, bool):
        raise Invalid("must be true or false")
    return value


def _poisson(value: Any) -> float:
    nu = _number(value)
    if not -1.0 < nu <= 0.5:
        raise Invalid("must be a number with -1 < nu <= 0.5")
    return nu


def _tolerance(value: Any) -> float:
    tol = _positive(value)
    if not 1e-15 <= tol <= 1e-1:
        raise Invalid("must be a number between 1e-15 and 0.1")
    return tol


def _cutoff(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value <= 1e-2:
        raise Invalid("must be a number between 0 and 0.01")
    return float(value)


def _choice(*options: str) -> Callable[[Any], str]:
    def check(value: Any) -> str:
        if not isinstance(value, str) or value not in options:
            raise Invalid("must be one of: " + ", ".join(repr(o) for o in options))
        return value

    return check


def _fields(value: Any) -> tuple[str, ...]:
    """[output] fields: names of SAVED_FIELDS, pressure always saved (first), each once."""
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) and v in SAVED_FIELDS for v in value):
        raise Invalid("must be a list of field names among " + ", ".join(repr(f) for f in SAVED_FIELDS))
    return ("pressure", *(f for f in SAVED_FIELDS[1:] if f in value))


def _count0(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise Invalid("must be an integer >= 0")
    return int(value)


def _numbers(value: Any) -> tuple[float, ...]:
    if not isinstance(value, list) or not value:
        raise Invalid("must be a non-empty list of finite numbers")
    try:
        return tuple(_number(v) for v in value)
    except Invalid:
        raise Invalid("must be a non-empty list of finite numbers") from None


def _positives(value: Any) -> tuple[float, ...]:
    numbers = _numbers(value)
    if min(numbers) <= 0:
        raise Invalid("must be a non-empty list of numbers > 0")
    return numbers


def _program(vector: bool, positive: bool) -> Callable[[Any], Any]:
    """A program in time (petroll.model.motion): a value, or {kind = "ramp" | "sinusoidal" | "tabulated", ...}
    with the keys of motion.PROGRAMS."""
    what = "[x, y]" if vector else "a number"
    tables = [f"{{kind = \"{name}\", " + ", ".join(
        key + (f" = {kind.optional[key]:g}" if key in kind.optional else "") for key in kind.keys) + "}"
        for name, kind in motion.PROGRAMS.items() if kind.keys]
    forms = f"{what}, or an inline table {', '.join(tables[:-1])} or {tables[-1]}"

    def keys_of(kind: str, keys: set) -> bool:
        spec = motion.PROGRAMS[kind]
        return set(spec.keys) - set(spec.optional) <= keys <= set(spec.keys)

    def value_of(v: Any) -> np.ndarray:
        out = np.array(_point(v)) if vector else np.array(_number(v))
        if positive and not vector and out <= 0:
            raise Invalid("must be > 0")
        return out

    def check(value: Any):
        try:
            if not isinstance(value, dict):
                return motion.Constant(value_of(value))
            kind, keys = value.get("kind"), set(value) - {"kind"}
            if kind == "ramp" and keys_of(kind, keys):
                start = np.array(_point(value["start"])) if vector else np.array(_number(value["start"]))
                if positive and not vector and start < 0:  # a load ramp may start from 0, never below
                    raise Invalid(f"start = {float(start):g} must be >= 0 (a pulling load needs adhesion, "
                                   "which petroll does not model)")
                return motion.Ramp(start, value_of(value["end"]), _positive(value["duration"]))
            if kind == "sinusoidal" and keys_of(kind, keys):
                amplitude = np.array(_point(value["amplitude"])) if vector else np.array(
                    _number(value["amplitude"]))
                mean = value_of(value["mean"])
                if positive and not vector and mean - abs(amplitude) < 0:
                    raise Invalid(f"mean - |amplitude| = {float(mean - abs(amplitude)):g} must be >= 0 (a "
                                   "pulling load needs adhesion, which petroll does not model)")
                return motion.Sinusoidal(mean, amplitude, _positive(value["period"]),
                                         _number(value.get("phase", motion.PROGRAMS[kind].optional["phase"])))
            if kind == "tabulated" and keys_of(kind, keys):
                times = np.array(_numbers(value["t"]))
                rows = value["value"]
                values = np.array([value_of(v) for v in rows]) if isinstance(rows, list) else None
                if values is None or len(values) != len(times) or times[0] < 0 or np.any(np.diff(times) <= 0):
                    raise Invalid("")
                return motion.Tabulated(times, values)
        except Invalid as exc:
            raise Invalid(f"{exc}; allowed: {forms}" if str(exc) else f"must be {forms}") from None
        raise Invalid(f"must be {forms}")

    return check


def _creepage(value: Any) -> tuple[float, float]:
    """[motion] creepage: [xi, eta] (line contact: a number, or [xi, 0]), each within [-1, 1]."""
    allowed = "must be a pair [xi, eta] of numbers between -1 and 1 (line contact: a number)"
    pair = _tangential(value, allowed)
    if max(abs(pair[0]), abs(pair[1])) > 1:
        raise Invalid(allowed)
    return pair


def _tangential(value: Any, allowed: str = "must be a pair [Fx, Fy] of finite numbers (line contact: a "
                "number)") -> tuple[float, float]:
    """A tangential vector: [x, y] or a number (line contact's [x, 0])."""
    try:
        return (_number(value), 0.0) if not isinstance(value, list) else _point(value)
    except Invalid:
        raise Invalid(allowed) from None


BODY_MATERIAL_FORM = '"same" (the half-space\'s) or an inline table {E = Young\'s modulus (Pa), nu = Poisson\'s ratio}'
"""What [body] material may be written as."""


def _body_material(value: Any) -> str | tuple[float, float]:
    """[body] material: "same", or (E, nu) of an elastic body."""
    if value == "same":
        return value
    if not isinstance(value, dict) or set(value) != {"E", "nu"}:
        raise Invalid(f"must be {BODY_MATERIAL_FORM}")
    try:
        E, nu = _positive(value["E"]), _poisson(value["nu"])
    except Invalid as exc:
        raise Invalid(f"{exc}; allowed: {BODY_MATERIAL_FORM}") from None
    if out_of_scale(E) is not None:
        raise Invalid(f"E: {scale_message(E, 'Pa')}")
    return E, nu


MAX_FRICTION = 100.0
"""The largest [friction] coefficient (dry rubber reaches 3 to 4; beyond 100 mu p is no friction)."""


def _coefficient(value: Any) -> float:
    mu = _positive(value)
    if mu > MAX_FRICTION:
        raise Invalid(f"must be a number > 0, at most {MAX_FRICTION:g}")
    return mu


def _text(value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise Invalid("must be a non-empty string")
    return value


def _shift(value: Any):
    try:
        return materials.make_shift(value)
    except ValueError as exc:
        raise Invalid(str(exc)) from None


TEMPERATURE_KEYS = {"temperature", "shift"}
"""[material] keys of time-temperature superposition, taken by every model with material times."""

LAYER_FORM = '{thickness = h (m, > 0), base = "bonded" or "frictionless"}'
"""What [material] layer may be written as."""


def _layer(value: Any) -> tuple[float, str]:
    """[material] layer: (thickness, base); nu is added once the model's keys are known."""
    if not isinstance(value, dict) or set(value) != {"thickness", "base"}:
        raise Invalid(f"must be an inline table {LAYER_FORM}")
    try:
        thickness = _positive(value["thickness"])
    except Invalid:
        raise Invalid(f"thickness = {value['thickness']!r} must be a finite number > 0 (m); allowed: "
                       f"{LAYER_FORM}") from None
    if value["base"] not in materials.LAYER_BASES:
        raise Invalid(f"base = {value['base']!r} must be one of: "
                       + ", ".join(repr(b) for b in materials.LAYER_BASES) + f"; allowed: {LAYER_FORM}")
    return thickness, value["base"]

MODEL_KEYS: dict[str, tuple[set[str], set[str]]] = {
    "elastic": ({"E", "nu"}, {"layer"}),
    "sls": ({"E0", "Einf", "nu"}, {"tau_creep", "tau_relax", "layer"} | TEMPERATURE_KEYS),
    "prony": ({"series", "Einf", "nu", "times"}, {"compliances", "moduli", "layer"} | TEMPERATURE_KEYS),
    "tabulated": ({"file", "quantity"}, {"nu", "layer"} | TEMPERATURE_KEYS),
}
"""Per model: the [material] keys it requires, and those it may take."""


def _cells_per_half_width(value: Any) -> float:
    from petroll.model.preflight import GOOD_CELLS, MOST_CELLS

    number = not isinstance(value, bool) and isinstance(value, (int, float))
    if not number or not GOOD_CELLS <= value <= MOST_CELLS / 4:
        raise Invalid(f"must be a number from {GOOD_CELLS} (below, a run warns) to {MOST_CELLS // 4}")
    return float(value)


SCHEMA: dict[str, dict[str, Key]] = {
    "grid": {
        "nx": Key("integer", "number of cells along X, 1 ... 2^24 (nx ny at most 2^31 - 1); a scene without "
                  "[grid], or with only cells_per_half_width, has its grid sized by petroll "
                  "(docs/accuracy.md)", _cells),
        "ny": Key("integer", "number of cells along Y, 1 ... 2^24 (nx ny at most 2^31 - 1); omit ny and y "
                  "for line contact (plane strain, docs/line-contact.md)", _cells, default=None),
        "x": Key("[min, max]", "extent of the grid along X in the material frame", _interval, unit="m"),
        "y": Key("[min, max]", "extent of the grid along Y in the material frame (omitted: line contact)",
                 _interval, default=None, unit="m"),
        "periodic": Key("bool or list", "the grid is one cell of a surface that repeats: " + PERIODIC_FORM
                        + "; the influence operator is then periodic along those axes, a body's offsets "
                        "wrap around, a height map of nx x ny samples at the grid's spacing is the periodic "
                        "surface (docs/rough.md)", _periodic, default=False),
        "cells_per_half_width": Key("number", "without nx, ny, x, y: petroll sizes the grid (square cells, "
                                    "this many per estimated contact half-width; the domain from the contact, "
                                    "the load or penetration, the material's compliance and the path; a "
                                    "generated rough surface: docs/rough.md), prints it and stores it in "
                                    "results.h5; a scene without [grid] gets 16 (docs/accuracy.md)",
                                    _cells_per_half_width, default=None),
        "allow_coarse": Key("boolean", "run even with fewer than 2 cells per estimated contact half-width "
                            "(refused otherwise; below 8 a run warns: docs/accuracy.md)", _flag, default=False),
    },
    "material": {
        "model": Key("string", 'constitutive model: "elastic", "sls", "prony" or "tabulated"',
                     _choice(*MODEL_KEYS)),
        "nu": Key("number", "Poisson's ratio, -1 < nu <= 0.5 (all models; with quantity = \"J\" unused)",
                  _poisson, default=None),
        "E": Key("number > 0", "Young's modulus (elastic)", _positive, default=None, unit="Pa"),
        "E0": Key("number > 0", "instantaneous Young's modulus (sls), Einf <= E0 <= 1e7 Einf", _positive,
                  default=None, unit="Pa"),
        "Einf": Key("number > 0", "relaxed (long-time) Young's modulus (sls, prony)", _positive,
                    default=None, unit="Pa"),
        "tau_creep": Key("number > 0", "retardation time of the creep compliance (sls; or tau_relax)",
                         _positive, default=None, unit="s"),
        "tau_relax": Key("number > 0", "relaxation time of the modulus, = tau_creep Einf/E0 (sls; or "
                         "tau_creep)", _positive, default=None, unit="s"),
        "series": Key("string", 'prony: "kelvin" (creep: D(t) = 1/Einf - sum compliances_r exp(-t/times_r)) '
                      'or "maxwell" (relaxation: E(t) = Einf + sum moduli_r exp(-t/times_r))',
                      _choice("kelvin", "maxwell"), default=None),
        "times": Key("list of numbers > 0", "retardation (kelvin) or relaxation (maxwell) times (prony)",
                     _positives, default=None, unit="s"),
        "compliances": Key("list of numbers > 0", "creep compliance of each Kelvin term (prony, kelvin)",
                           _positives, default=None, unit="1/Pa"),
        "moduli": Key("list of numbers > 0", "modulus of each Maxwell term (prony, maxwell)", _positives,
                      default=None, unit="Pa"),
        "file": Key("string", "CSV file of two columns t (s), value, t starting at 0, relative to the scene "
                    "file (tabulated)", _text, default=None),
        "quantity": Key("string", 'what the table holds (tabulated): "D" (creep compliance, 1/Pa; J = (1 - '
                        'nu^2) D) or "J" (surface compliance, 1/Pa)', _choice("D", "J"), default=None),
        "temperature": Key("number > 0", "temperature of the material (sls, prony, tabulated; with shift): "
                           "every relaxation and retardation time (a table's time axis) is multiplied by "
                           "a_T(temperature); the other keys give the material at shift's T_ref "
                           "(docs/materials.md)", _positive, default=None, unit="K"),
        "shift": Key("inline table", 'time-temperature shift law a_T (with temperature): {law = "wlf", C1, '
                     'C2 (K), T_ref (K)}: log10 a_T = -C1 (T - T_ref)/(C2 + T - T_ref), or {law = '
                     '"arrhenius", Ea (J/mol), T_ref (K)}: ln a_T = (Ea/R)(1/T - 1/T_ref), R = 8.314462618 '
                     'J/(mol K), or {law = "table", T = [...] (K, increasing), log10_aT = [...]}: log10 a_T '
                     "interpolated between the listed temperatures (PCHIP: monotone piecewise cubic), "
                     "refused outside them (what petroll material fit --shift auto writes)", _shift,
                     default=None, fields=(("C2", "K"), ("T_ref", "K"), ("Ea", "J/mol"), ("T", "K"))),
        "layer": Key("inline table", "the material is a layer of this thickness on a rigid base, its bottom "
                     'bonded to it or sliding freely on it: {thickness = h (m), base = "bonded" or '
                     '"frictionless"} (all models; needs nu; absent: a half-space; docs/layer.md)', _layer,
                     default=None, fields=(("thickness", "m"),)),
    },
    "body": {
        "shape": Key("string", "body shape: " + ", ".join(BODY_KEYS) + " (its own keys: see below; rough: "
                     "a generated self-affine surface, one sample per cell, sample (i, j) on cell (i, j) at "
                     "position [0, 0]: the surface of a periodic grid; docs/rough.md)",
                     _choice(*BODY_KEYS)),
        "position": Key("[x, y]", "position of the body's reference point at t = 0", _point,
                        default=[0.0, 0.0], unit="m"),
        "material": Key("string or inline table", "the body is elastic: " + BODY_MATERIAL_FORM + "; the "
                        "bodies' compliances add (absent: a rigid body); with [friction] the pair must be "
                        "quasi-identical, (1 - 2 nu)/G equal (a rigid body: [material] nu = 0.5); on a viscoelastic "
                        "half-space (sls, prony) only \"same\" (its creep function doubled); no layer or "
                        "tabulated material (docs/friction.md)", _body_material, default=None,
                        fields=(("E", "Pa"),)),
    },
    "motion": {
        "velocity": Key("[vx, vy] or program", "velocity of the body over the half-space (its path s(t) "
                        "starts at [body] position); line contact: along X only, a number, a program of "
                        "numbers, or [vx, 0]", _program(vector=True, positive=False),
                        default=[0.0, 0.0], unit="m/s"),
        "penetration": Key("number or program", "penetration delta of the body's lowest point below the "
                           "undeformed surface (displacement control; exactly one of penetration, load; not in line "
                           "contact unless periodic); on a periodic grid below the deformed surface's mean "
                           "plane, the mean gap mean(Z) - delta > 0 (docs/rough.md)",
                           _program(vector=False, positive=False), default=None, unit="m"),
        "load": Key("number > 0 or program", "total normal force F (load control; exactly one of "
                    "penetration, load); line contact: force per unit length, N/m; a periodic grid: the "
                    "force on its cell (the mean pressure is load / cell area)",
                    _program(vector=False, positive=True), default=None, unit="N"),
        "creepage": Key("[xi, eta]", "with [friction]: the rigid slip velocity of the body relative to the "
                        "half-space over the rolling speed, along X and Y, each within [-1, 1] (line contact: "
                        "a number); creepage control, default [0, 0] (free rolling); needs a velocity",
                        _creepage, default=None),
        "spin": Key("number", "with [friction]: the body's rigid angular velocity relative to the half-space "
                    "about the normal (counter-clockwise from X to Y) over the rolling speed, about the "
                    "body's reference point; not in line contact", _number, default=None, unit="1/m"),
        "tangential_force": Key("[Fx, Fy]", "with [friction]: the tangential force the half-space exerts on "
                                "the body (line contact: a number, N/m), held (force control; the creepage "
                                "found); a body at rest is shifted by it (Cattaneo), from zero to it over "
                                "[time] end, or at once without [time]; at most mu x the normal force",
                                _tangential, default=None, unit="N"),
    },
    "time": {
        "mode": Key("string", '"transient" (march from the start in time steps) or "steady" (the steady '
                    "rolling state at constant velocity solved directly, one step: constant non-zero velocity "
                    "along X or Y (a periodic grid: the steady sliding state, any direction along its "
                    "periodic axes), constant penetration or load, a Prony/SLS/elastic material; takes "
                    "steps_per_cell or dt only, the integrator's step, default 1 step per cell; "
                    'docs/rolling.md, docs/rough.md)', _choice("transient", "steady"), default="transient"),
        "dt": Key("number > 0", "time step (or steps_per_cell); without [time]: one step at t = 0",
                  _positive, default=None, unit="s"),
        "steps_per_cell": Key("number > 0", "time step tied to the motion: dt = min(dx, dy) / (|V| "
                              "steps_per_cell) (line contact: dx / (|V| steps_per_cell))", _positive,
                              default=None),
        "end": Key("number > 0", "end time (one of end, distance)", _positive, default=None, unit="s"),
        "distance": Key("number > 0", "stop after the body has rolled this far along its path (one of end, "
                        "distance)", _positive, default=None, unit="m"),
        "steady": Key("number > 0", "stop early once force and mu_r change by less than this (relative) "
                      "over one contact length of rolling", _positive, default=None),
        "max_steps": Key("integer", f"refuse scenes that would take more steps (at most {MAX_STEPS})", _steps,
                         default=100000),
        "allow_coarse": Key("boolean", "run even with fewer than 2 steps per estimated contact half-width "
                            "along the motion (refused otherwise; below 8 a run warns: docs/accuracy.md)",
                            _flag, default=False),
    },
    "solver": {
        "tao_type": Key("string", "TAO bound-constrained solver for each contact QP (command line: "
                        "-petroll_tao_type)", _choice(*TAO_TYPES), default=DEFAULT_TAO_TYPE),
        "integrator": Key("string", 'time integrator: "relaxation" (Prony/SLS, the default: second order, '
                          'exact for a held penetration), "exponential" (Prony/SLS, creep form, second '
                          'order) or "paper" (J frozen at J(0) over the newest step; the only one for '
                          'tabulated); steps at which one cannot hold a penetration are refused '
                          '(docs/stability.md)',
                          _choice("relaxation", "exponential", "paper"), default=None),
        "tol": Key("number", "relative tolerance on the contact conditions: max |min(p, gap)| in units "
                   "of the largest interference (gap) and its pressure (p)", _tolerance, default=1e-8),
        "history_cutoff": Key("number", "history fields below this fraction of their largest value are "
                              "left out of the preceding displacement (the fading wake behind a rolling "
                              "body); changes it by at most this fraction of its scale; 0: keep all "
                              "(docs/design.md)", _cutoff, default=1e-9),
    },
    "friction": {
        "coefficient": Key("number > 0", "Coulomb's friction coefficient mu: tangential tractions |q| <= mu p, "
                           "stick and slip (docs/friction.md); [friction] absent: frictionless; needs an "
                           "elastic, SLS or Prony half-space; on a periodic grid steady sliding only, full slip "
                           "(required in [friction]); at most 100",
                           _coefficient,
                           default=None),
    },
    "output": {
        "dir": Key("string", "output directory, relative to the current directory (command line: --out); "
                   "default results/<scene file name without .toml>", _text, default=None),
        "every": Key("integer", "save the pressure field every this many steps (0: first and last only)",
                     _count0, default=0),
        "checkpoint_every": Key("integer", "write a restart checkpoint to DIR/checkpoints every this many "
                                "steps and at the end (0: none; SIGTERM/SIGINT always write one; "
                                "docs/checkpoints.md)", _count0, default=0),
        "keep": Key("integer", "number of newest checkpoints kept in DIR/checkpoints", _count, default=2),
        "fields": Key("list of strings", "the fields saved at the saved steps: \"pressure\" (Pa, always saved), "
                      "\"displacement\" (the surface's, m, into the half-space) and \"gap\" (m) "
                      "(docs/results.md)", _fields, default=["pressure"]),
    },
}
"""Every section and key of a version-1 scene. [body] also takes the keys of its shape (BODY_KEYS)."""
