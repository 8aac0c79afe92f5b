"""Coulomb friction in a scene: [friction] coefficient, the tangential keys of [motion] and [body] material
read into one frozen :class:`Friction` (docs/friction.md).

A scene without [friction] has none (``Scene.friction`` None): frictionless, as before. With it, the
tangential problem of petroll.solver.tangential is solved after each step's normal one, with

- ``compliance`` c, the bodies' summed shear compliance 1/(2 G_1) + 1/(2 G_2) (1/Pa; a rigid body adds
  nothing), and ``nu`` the Poisson's ratio of their summed Cerruti kernel: Cerruti's kernel is linear in
  nu, so (1/(2 G_1)) K(nu_1) + (1/(2 G_2)) K(nu_2) = c K(nu) with nu = (nu_1/G_1 + nu_2/G_2)/(1/G_1 + 1/G_2);
- the normal problem's compliance is the bodies' summed (1 - nu_i^2)/E_i (``body_compliance``: the body's,
  added to the half-space's elastic material by the scene);
- the bodies quasi-identical, (1 - 2 nu_1)/G_1 = (1 - 2 nu_2)/G_2 (a body of the same material, or a rigid
  body on a half-space of nu = 1/2): the normal-tangential coupling then vanishes. Other pairs are
  refused in one line: the coupling's outer iteration is not modelled.

A viscoelastic half-space (an SLS or Prony material, no layer) and a body of its own material or a rigid
one: with a constant Poisson's ratio the shear creep function is the normal one's shape, the tangential
compliance c(t) = J(t)/(1 - nu) with J the bodies' summed surface creep compliance (a body of the same
material doubles J(t)), so ``memory`` = 1/(1 - nu) and ``compliance`` the relaxed c (the tangential history
runs through the scene's integrator: petroll.solver.friction.ShearMemory). Tabulated creep functions, a
layer and an elastic body on a viscoelastic half-space are refused in one line.

On a periodic grid friction is steady sliding's (:class:`Sliding`; [time] mode = "steady" only): full
slip, no tangential problem, the bodies quasi-identical.

Modes, from the motion: a body at rest is a quasi-static shift under ``force`` (applied from zero to its
value over the clock's steps, or in one step without [time]); a rolling body runs at the ``creepage`` (and
``spin``) or at the tangential ``force``, its creepage then found.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from petroll.errors import MISSING, SceneError
from petroll.model import materials, motion
from petroll.model.clock import TimeMode

FIELDS = ("traction_x", "traction_y", "slip")
"""The fields a run with friction saves beside the pressure (units in petroll.io.results.FIELD_UNITS); line
contact: no traction_y."""


def saved_fields(line: bool) -> tuple[str, ...]:
    """The friction fields a run saves (line contact: without traction_y)."""
    return tuple(f for f in FIELDS if not (line and f == "traction_y"))

MOTION_KEYS = ("creepage", "spin", "tangential_force")
"""The [motion] keys of friction (they need [friction])."""

QUASI_IDENTICAL = 1e-9
"""Two bodies are quasi-identical when their (1 - 2 nu)/G agree to this fraction of the larger."""


@dataclass(frozen=True)
class Friction:
    """A scene's friction (module docstring). ``creepage`` (xi, eta) and ``spin`` (1/m) of a rolling body
    under creepage control; ``force`` (Fx, Fy) (N; N/m in line contact), the force the half-space exerts
    on the body, under force control (None: creepage control); ``body`` "rigid", "same" or "elastic"."""

    coefficient: float
    compliance: float
    nu: float
    creepage: tuple[float, float] = (0.0, 0.0)
    spin: float = 0.0
    force: tuple[float, float] | None = None
    body: str = "rigid"
    ramp: float | None = None  # a shift's force grows as t / ramp up to the [time] end (None: at once)
    memory: float | None = None  # viscoelastic: c(t) = memory x J(t), J the scene's; None: elastic

    def force_at(self, t: float) -> np.ndarray | None:
        """The tangential force (N, a 2-vector) at time t (s): a shift's ramp, or the force; None: none."""
        if self.force is None:
            return None
        scale = 1.0 if self.ramp is None else min(t / self.ramp, 1.0)
        return scale * np.asarray(self.force, dtype=float)


@dataclass(frozen=True)
class Sliding:
    """A scene's friction in steady sliding ([time] mode = "steady" on a periodic grid, where the body
    slides at its velocity): full slip, the traction mu p opposing the sliding velocity at every cell in
    contact (petroll.solver.friction_loop.FullSlip). The bodies are quasi-identical (a rigid body on a
    half-space of nu = 1/2, or elastic bodies as :func:`_pair` allows), so the traction moves no surface
    normally and the pressure is the frictionless steady sliding one."""

    coefficient: float


def friction_of(values: dict, raw: dict, material, line: bool, periodic: bool, source: str):
    """(material, Friction, Sliding or None) of a scene: ``values`` its sections read by the schema,
    ``raw`` its TOML, ``material`` the half-space's J (petroll.model.materials.Prony), to which a
    deformable body's compliance is added. A periodic grid's friction is steady sliding's (:class:`Sliding`).
    SceneError (one line) for friction's keys without [friction] or with what it does not model."""
    table, motion_values, body = raw.get("friction"), values["motion"], values["body"]["material"]
    if table is None:
        for key in MOTION_KEYS:
            if key in raw.get("motion", {}):
                raise SceneError(source, f"[motion] {key}", raw["motion"][key],
                                 "needs [friction] coefficient (friction is off without [friction])")
    m = values["material"]
    elastic = m["model"] == "elastic"
    if (table is not None or body is not None) and (m["model"] == "tabulated" or m["layer"] is not None):
        key, value = ("[friction]", table) if table is not None else ("[body] material", body)
        raise SceneError(source, key, value, 'needs a half-space of an elastic, SLS or Prony material '
                         "([material] model = \"elastic\", \"sls\" or \"prony\", without layer): "
                         "tabulated creep functions and layers are not modelled with friction or a body")
    if periodic and table is not None:
        _sliding_checks(values, raw, body, source)
    if body is not None and not elastic and body != "same":
        raise SceneError(source, "[body] material", raw["body"]["material"], "on a viscoelastic half-space: "
                         "\"same\" (a body of its material) or none (a rigid body); an elastic body on it "
                         "is not modelled")
    if body == "same":
        material = materials.Prony(2 * material.Jinf, tuple(2 * d for d in material.dJ), material.tau)
    elif body is not None:
        material = materials.Prony(material.Jinf + (1 - body[1] ** 2) / body[0])
    if table is None:
        return material, None
    if values["friction"]["coefficient"] is None:
        raise SceneError(source, "[friction] coefficient", MISSING, "required in [friction]: Coulomb's "
                         "friction coefficient mu (a number > 0)")
    written = raw.get("body", {}).get("material", MISSING)
    if periodic:  # steady sliding: the bodies quasi-identical, so that the traction leaves the pressure alone
        _pair(m["E"] / (2 * (1 + m["nu"])) if elastic else 1.0, m["nu"], body, written, source)
        return material, Sliding(values["friction"]["coefficient"])
    if elastic:
        pair, memory = _pair(m["E"] / (2 * (1 + m["nu"])), m["nu"], body, written, source), None
    else:
        memory = 1 / (1 - m["nu"])
        _pair(1.0, m["nu"], body, written, source)  # a rigid body needs nu = 1/2
        pair = (memory * material.Jinf, m["nu"], "same" if body == "same" else "rigid")
    return material, Friction(values["friction"]["coefficient"], *pair[:2], body=pair[2], memory=memory,
                              **_motion(motion_values, raw.get("motion", {}), values["time"], line,
                                       values["friction"]["coefficient"], source))


def _sliding_checks(values: dict, raw: dict, body, source: str) -> None:
    """SceneError (one line) for what steady sliding with friction does not take: another mode than
    [time] mode = "steady" on a periodic grid, a creepage or tangential force (full slip), a body of the
    same viscoelastic material (its own material does not stream through the contact)."""
    if TimeMode(values["time"]["mode"]) is not TimeMode.STEADY:
        raise SceneError(source, "[friction]", raw["friction"], 'on a periodic grid only in steady sliding '
                         '([time] mode = "steady": full slip); transient friction needs a non-periodic grid')
    for key in MOTION_KEYS:
        if key in raw.get("motion", {}):
            raise SceneError(source, f"[motion] {key}", raw["motion"][key], "not in steady sliding (a periodic "
                             "grid): the body slides at its velocity, full slip, the traction mu p")
    if body == "same" and values["material"]["model"] != "elastic":
        raise SceneError(source, "[body] material", raw["body"]["material"], "not in steady sliding on a "
                         "viscoelastic half-space: the sliding body's own material does not stream through "
                         "the contact (not modelled); give a rigid body ([material] nu = 0.5)")


def _pair(G: float, nu: float, body, written, source: str) -> tuple[float, float, str]:
    """(compliance, nu, body kind) of the half-space (G, nu) and the body ([body] material: None, "same"
    or (E, nu)); SceneError unless quasi-identical."""
    if body is None:
        if nu != 0.5:
            raise SceneError(source, "[body] material", MISSING, f"a rigid body on a half-space of nu = {nu:g}: "
                             "the bodies are not quasi-identical ((1 - 2 nu)/G differs) and the normal-"
                             "tangential coupling is not modelled; give [body] material = \"same\", or "
                             "[material] nu = 0.5")
        return 1 / (2 * G), nu, "rigid"
    if body == "same":
        return 1 / G, nu, "same"
    E2, nu2 = body
    G2 = E2 / (2 * (1 + nu2))
    one, two = (1 - 2 * nu) / G, (1 - 2 * nu2) / G2
    if abs(one - two) > QUASI_IDENTICAL * max(abs(one), abs(two)):
        raise SceneError(source, "[body] material", written, f"(1 - 2 nu)/G = {two:.6g} 1/Pa, the half-space's "
                         f"{one:.6g} 1/Pa: the bodies are not quasi-identical and the normal-tangential "
                         "coupling of dissimilar materials is not modelled; give \"same\", or E and nu "
                         "with the half-space's (1 - 2 nu)/G")
    weights = 1 / G + 1 / G2
    return 0.5 * weights, (nu / G + nu2 / G2) / weights, "elastic"


def _motion(m: dict, table: dict, time: dict, line: bool, coefficient: float, source: str) -> dict:
    """The tangential motion's keyword arguments of Friction, checked against the velocity."""
    velocity = m["velocity"]
    rest = isinstance(velocity, motion.Constant) and not np.any(velocity.value)
    if m["creepage"] is not None and m["tangential_force"] is not None:
        raise SceneError(source, "[motion] creepage / tangential_force", [table["creepage"],
                         table["tangential_force"]], "at most one of them (creepage control or force control)")
    for key in ("creepage", "spin"):
        if rest and m[key] is not None:
            raise SceneError(source, f"[motion] {key}", table[key], "needs a rolling body ([motion] velocity); "
                             "a body at rest is shifted by [motion] tangential_force")
    if line:
        if m["spin"] is not None:
            raise SceneError(source, "[motion] spin", table["spin"], "not in line contact (no rotation about "
                             "the normal in plane strain)")
        for key in ("creepage", "tangential_force"):
            if m[key] is not None and m[key][1] != 0:
                raise SceneError(source, f"[motion] {key}", table[key], "line contact: along X only, a number "
                                 "or [x, 0]")
    out: dict = {"spin": m["spin"] or 0.0}
    if m["creepage"] is not None:
        out["creepage"] = m["creepage"]
    if m["tangential_force"] is not None:
        out["force"] = m["tangential_force"]
        load = m["load"].peak() if m["load"] is not None else None
        if load is not None and np.hypot(*out["force"]) > coefficient * load:
            raise SceneError(source, "[motion] tangential_force", table["tangential_force"], f"exceeds the "
                             f"friction bound mu x load = {coefficient * load:g} (N): the body would slide; "
                             "give a smaller force, or a creepage")
        if rest and time["end"] is not None:
            out["ramp"] = time["end"]
    return out


def creep_coefficient(scene, force: float, delta: float, traction) -> float:
    """Kalker's creep coefficient of a steady rolling run of ``scene`` as its traction curve's secant
    (docs/friction.md#traction-against-speed-and-temperature): the tangential force ``traction`` (N,
    (Fx, Fy)) against the scene's creepage xi, -F.xi / (G c^2 |xi|^2), G = 1/(the bodies' summed relaxed
    shear compliance) and c the Hertz radius: sqrt(R delta) under displacement control (any modulus's),
    (3 F R Jinf/4)^(1/3) the relaxed one at the normal ``force`` F (N) under load control (``delta`` the
    penetration, m). At a small creepage the initial slope: Kalker's C11 for an elastic pair rolling along
    X. NaN but for a sphere on a Prony (SLS, elastic) material under a non-zero creepage without spin."""
    from petroll.model.bodies import Sphere

    f = scene.friction
    if (not isinstance(f, Friction) or not isinstance(scene.body, Sphere) or f.force is not None or f.spin
            or not any(f.creepage) or not isinstance(scene.material, materials.Prony) or not force > 0):
        return float("nan")
    xi = np.asarray(f.creepage, dtype=float)
    if scene.load is None:  # Hertz's radius at the penetration, whatever the modulus
        c = np.sqrt(scene.body.radius * delta)
    else:
        c = (0.75 * force * scene.body.radius * scene.material.Jinf) ** (1 / 3)
    return float(-np.asarray(traction, dtype=float) @ xi / (c * c * (xi @ xi)) * f.compliance)
