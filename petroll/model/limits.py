"""Physical limits of the formulation that no numerical fix removes: petroll refuses or warns, with why.

The half-space theory (Love's influence coefficients, Boussinesq) is linear and assumes small surface
slopes in the contact: its error grows like (a/R)^2 for a sphere. :func:`check_scene` estimates the
largest slope of the body's profile inside the contact (where Z <= delta / 2: the Hertz contact edge) at
the largest penetration the scene can reach, and

- warns (:class:`PetrollWarning`, shown by the command line as one ``petroll: warning:`` line) above
  ``SLOPE_WARN`` (a/R ~ 0.3 for a sphere: a few per cent from the finite-slope effects);
- refuses displacement control above ``SLOPE_MAX`` (45 degrees: a sphere's contact would reach its
  equator, where its profile Z stops being a graph); under load control the penetration is only
  estimated (relaxed Hertz for the body's equivalent radius), so it warns.

The stability suite (docs/stability.md) exercises both limits. Numbers with a unit (and a height map's
heights) must lie within ``MAGNITUDES``, whatever the units.
"""

from __future__ import annotations

import contextlib
import math
import warnings

import numpy as np

from petroll.errors import SceneError
from petroll.model import motion
from petroll.model.clock import TimeMode

SLOPE_WARN = 0.3
SLOPE_MAX = 1.0

MAGNITUDES = (1e-30, 1e30)
"""The smallest and largest non-zero magnitude of a number with a unit (a length, time, modulus, force,
...), whatever the units: the kernels and integrators form squares and products of a few of them, which
then stay far inside double precision (1e-308 ... 1e308). Scenes outside are refused: rescale the units."""


def scale_message(bad: float, unit: str) -> str:
    shown = f" {unit}" if unit not in ("-", "") else ""
    return (f"{bad:g}{shown} is outside what petroll computes with: non-zero magnitudes from "
            f"{MAGNITUDES[0]:g} to {MAGNITUDES[1]:g}; rescale the units (e.g. mm, MPa, ms)")


def heights_out_of_scale(heights: np.ndarray) -> str | None:
    """Why a map's finite heights (m) lie outside MAGNITUDES: the largest |height| above it, or a relief
    (highest - lowest) that is not zero but below it (a flat map is refused elsewhere, if at all); None
    when they lie within."""
    finite = np.isfinite(heights)
    if not finite.all():  # else the array itself: no copy of a whole map
        heights = heights[finite]
    if not heights.size:
        return None
    low, high = float(heights.min()), float(heights.max())
    largest, relief = max(high, -low), high - low
    if largest > MAGNITUDES[1]:
        return f"height {scale_message(largest, 'm')}"
    if 0 < relief < MAGNITUDES[0]:
        return f"relief (highest - lowest height) {scale_message(relief, 'm')}"
    return None


class PetrollWarning(UserWarning):
    """A scene that runs but lies where the formulation loses accuracy (the message says why)."""


@contextlib.contextmanager
def warnings_once():
    """Within the block, a PetrollWarning whose text was shown already is not shown again: a sweep's points
    that meet the same condition (a rough surface's resolution, a slope) warn once."""
    seen: set[str] = set()
    with warnings.catch_warnings():
        shown = warnings.showwarning

        def show(message, category, *args, **kwargs):
            if issubclass(category, PetrollWarning):
                if str(message) in seen:
                    return
                seen.add(str(message))
            shown(message, category, *args, **kwargs)

        warnings.showwarning = show
        yield


def contact_slope(scene, delta: float, points: int = 201) -> float:
    """The largest |grad Z| where the body, at its start position, lies within delta / 2 of its lowest
    point (the Hertz contact edge for a penetration delta).

    The profile is sampled on a ``points`` x ``points`` lattice (not the grid's cells, which may be coarser
    than the contact) over the part of the grid within 4 equivalent contact radii sqrt(2 R delta) of the
    body (R: its radius hint), its slopes on the part of the lattice around those points only: the cost is
    bounded whatever the grid."""
    g, (sx, sy) = scene.grid, scene.position
    reach = 4 * math.sqrt(2 * max(float(scene.body.radius_hint), 0.0) * delta)
    if not math.isfinite(reach) or reach <= 0:
        reach = max(g.x1 - g.x0, g.y1 - g.y0)
    x = np.linspace(max(g.x0, sx - reach), min(g.x1, sx + reach), points)[:, None] - sx
    y = np.linspace(max(g.y0, sy - reach), min(g.y1, sy + reach), points)[None, :] - sy
    with np.errstate(all="ignore"):
        z = scene.body.height(x, y)
        inside = z <= 0.5 * delta
        if not np.any(inside):
            return 0.0
        rows, cols = np.flatnonzero(inside.any(axis=1)), np.flatnonzero(inside.any(axis=0))
        box = slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)  # the lattice around the inside
        gx, gy = scene.body.slope(x[box[0]], y[:, box[1]])
        return float(np.max(np.hypot(gx, gy)[inside[box]]))


def largest_penetration(scene) -> tuple[float, bool]:
    """(delta, exact): the largest penetration the scene prescribes, or under load control an estimate
    (relaxed Hertz for the peak load and the body's equivalent radius; a periodic grid's rough surface:
    the rubbery estimate from its spectrum and the load, petroll.model.rough_contact). Line contact (load
    per length P): a^2/R with a = sqrt(4 P R Jinf/pi) the relaxed Hertz half-width, the approach at which
    a parabola's Z <= delta/2 spans the same width (the penetration itself depends on a datum there)."""
    from petroll.model.rough_contact import rough_contact

    if scene.penetration is not None:
        return float(scene.penetration.largest()), True
    if (rough := rough_contact(scene)) is not None:
        return rough.penetration[1], False
    load = float(scene.load.largest())
    radius = float(scene.body.radius_hint)
    if not (load > 0 and radius > 0 and math.isfinite(radius)):
        return 0.0, False
    if scene.grid.line:
        return 4 * load * float(scene.material.Jinf) / math.pi, False
    return (3 * float(scene.material.Jinf) * load / (4 * math.sqrt(radius))) ** (2 / 3), False


LAYER_CELLS = 16
"""A layer thinner than 1/LAYER_CELLS of the largest cell side is warned about: its coefficients' Gauss
rule (petroll/solver/kernels/layer.py) then errs by more than about 1e-6 of the diagonal."""


def check_scene(scene) -> None:
    """Refuse (SceneError) or warn (PetrollWarning) for contact slopes beyond the linear theory, and warn
    for a layer too thin for the grid's cells."""
    g, layer = scene.grid, scene.layer
    side = g.dx if g.line else max(g.dx, g.dy)
    if layer is not None and layer.thickness < side / LAYER_CELLS:
        warnings.warn(PetrollWarning(f"{scene.source}: [material] layer: thickness {layer.thickness:g} m is "
                                     f"below 1/{LAYER_CELLS} of the cells' side {side:g} m: its influence "
                                     "coefficients lose accuracy (docs/layer.md); refine [grid]"),
                      stacklevel=2)
    delta, exact = largest_penetration(scene)
    if not delta > 0:
        return
    slope = contact_slope(scene, delta)
    key = "[motion] penetration" if exact else "[motion] load"
    value = scene.raw.get("motion", {}).get("penetration" if exact else "load")
    degrees = math.degrees(math.atan(slope))
    which = "the" if exact else "an estimated"
    at = (f"an estimated largest half-width {math.sqrt(delta * scene.body.radius_hint):.3g} m (line contact)"
          if scene.grid.line else f"{which} largest penetration {delta:.3g} m")
    reason = (f"the body's surface in the contact would slope up to {slope:.2g} ({degrees:.0f} degrees) at "
              f"{at}; the half-space theory assumes small slopes (its error grows like slope^2)")
    if slope > SLOPE_MAX and exact:
        raise SceneError(scene.source, key, value, f"too large: {reason}; allowed: slopes up to "
                         f"{SLOPE_MAX:g} (45 degrees): reduce the penetration")
    if slope > SLOPE_WARN:
        warnings.warn(PetrollWarning(f"{scene.source}: {key}: {reason}; results lose accuracy above "
                                     f"{SLOPE_WARN:g}"), stacklevel=2)


NEGATIVE_ROUND_OFF = 1e-12
"""A resisting-force coefficient (mu_r) below -NEGATIVE_ROUND_OFF is negative
beyond round-off (a symmetric contact's mu_r is a sum of terms that cancel to about 1e-18)."""


def negative_friction(scene, mu_r: float) -> str | None:
    """The warning (one line) for a resisting force that came out negative, ``mu_r`` < 0 beyond round-off,
    from a dissipative material (J0 < Jinf: its loss is > 0 at every frequency) at a steady state (a steady
    solve, or the last step of a transient at constant velocity, penetration or load): a body moving
    steadily over such a material loses energy to it, so the resisting force is > 0 and a negative one is
    numerical (a time step or grid too coarse for the contact, docs/accuracy.md). None otherwise (an
    elastic material, a body at rest, or a transient whose motion changes: energy stored earlier may push
    the body on). A steady sliding solve's mu_r, the dissipated power's (petroll.solver.sliding), is never
    negative."""
    material = scene.material
    moving = bool(np.any(np.asarray(scene.velocity(0.0), dtype=float)))
    if not (mu_r < -NEGATIVE_ROUND_OFF and moving and material.Jinf > material.J0 * (1 + 1e-9)):
        return None
    held = [p for p in (scene.velocity, scene.penetration, scene.load) if p is not None]
    if scene.time.mode is not TimeMode.STEADY and not all(isinstance(p, motion.Constant) for p in held):
        return None
    return (f"{scene.source}: mu_r = {mu_r:.4g} < 0 from a dissipative material at a steady state: the "
            "material can only resist a steady motion, so this value is wrong (a time step or grid too "
            "coarse for the contact: petroll check SCENE, docs/accuracy.md)")
