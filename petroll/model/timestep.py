"""The time step against the contact, checked like the grid (petroll.model.preflight; docs/accuracy.md).

The body moves by some length over each step of the run (its path's, petroll.model.clock.moves; a steady
solve's: V times its integrator's step, petroll.model.clock.steady_dt), which the contact must resolve as
the grid does: steps per contact half-width along the motion (the smallest half-widths along X and Y, a
steady rolling state's at its speed under load control (petroll.model.preflight.ContactSize.resolved),
combined along each step's direction; on a rough periodic surface no more than the half-width of its
single contacts, PeriodicSurface.contact_scale), the fewest over the run. Below ``GOOD_STEPS`` a run warns
(one line naming [time] steps_per_cell or dt and the value that gives ``GOOD_STEPS``), below
``LEAST_STEPS`` it is refused unless ``[time] allow_coarse = true``; a step longer than the grid is refused
always, and so is a steady sliding step below ``FINEST_SLIDE`` of the grid's longer side (round-off).
Lengths in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from petroll.errors import SceneError
from petroll.model.bodies.rough import PeriodicSurface, RoughBody
from petroll.model.clock import Path, TimeMode, moves

GOOD_STEPS = 8
"""Steps per contact half-width along the motion below which a run warns (measured, docs/accuracy.md: about
1 % in mu_r on runs/sphere.toml, transient or steady, 0.4 % on a rough surface sliding)."""
LEAST_STEPS = 2
"""Steps per contact half-width below which a run is refused unless [time] allow_coarse = true (there
mu_r is 4 to 20 % off, docs/accuracy.md)."""
FINEST_SLIDE = 1e-10
"""A steady sliding step (a periodic grid) must move the body at least this fraction of the grid's longer
side: with finer steps the integrator's response to the longest modes loses its digits (measured: mu_r off
by 1e-5 at 1.6e-14, by 2e-3 at 1.6e-16, by 20 % at 1.6e-18; docs/accuracy.md)."""


@dataclass(frozen=True)
class TimeResolution:
    """How a run's time step resolves its contact: ``steps``, the fewest steps per contact half-width
    along the motion over the run (at the step that moves the body across the most of a half-width),
    ``width`` that half-width (m), ``cells`` the longest step over min(dx, dy), ``length`` its length (m);
    ``key`` and ``value``: the [time] key that sets the step ("[time] steps_per_cell" or "[time] dt") and
    its value (a steady solve without either: steps_per_cell, 1); ``unit``: the longest step the key gives
    per unit of it (steps_per_cell: min(dx, dy) in m, the step at 1 step per cell; dt: the peak speed,
    m/s), from which the value giving a step of a chosen length follows (:meth:`giving`, :meth:`at_most`)."""

    steps: float
    width: float
    cells: float
    length: float
    key: str
    value: float
    unit: float

    @property
    def per_cell(self) -> bool:
        return self.key == "[time] steps_per_cell"

    def at_most(self, length: float, fine: bool = False) -> str:
        """'steps_per_cell >= K' or 'dt <= T': the values whose steps are at most ``length`` (m) long;
        ``fine``: at least that long ('steps_per_cell <= K', 'dt >= T'). 3 significant digits, rounded
        the safe way."""
        if self.per_cell:
            return f"steps_per_cell {'<=' if fine else '>='} {_rounded(self.unit / length, up=not fine):.3g}"
        return f"dt {'>=' if fine else '<='} {_rounded(length / self.unit, up=fine):.3g}"

    def giving(self, steps: float) -> str:
        """The values of the key that give at least ``steps`` steps per half-width (:meth:`at_most`)."""
        return self.at_most(self.width / steps)


def _rounded(value: float, up: bool) -> float:
    """``value`` to 3 significant digits, rounded up (``up``) or down."""
    if not (math.isfinite(value) and value > 0):
        return value
    scale = 10.0 ** (math.floor(math.log10(value)) - 2)
    return (math.ceil(value / scale * (1 - 1e-12)) if up else math.floor(value / scale * (1 + 1e-12))) * scale


def contact_scale(body) -> float:
    """The half-width (m) of a rough surface's single contacts (PeriodicSurface.contact_scale, of the
    surface or of the roughness a smooth body carries); inf for a smooth body."""
    surface = body.roughness if isinstance(body, RoughBody) else body
    return surface.contact_scale if isinstance(surface, PeriodicSurface) else math.inf


def time_resolution(scene, size, walked: Path) -> TimeResolution | None:
    """The run's :class:`TimeResolution`: each step's move (petroll.model.clock.moves) against the smallest
    contact half-widths along X and Y of ``size`` (petroll.model.preflight.ContactSize), combined along the
    move's direction (an ellipse's radius; a rough surface's no wider than :func:`contact_scale`); None for
    a run of one step at t = 0 or a body at rest."""
    d = moves(scene, walked)
    if not len(d):
        return None
    g, scale = scene.grid, contact_scale(scene.body)
    widths = []
    for w, cell in zip(size.resolved, (g.dx, g.dy)):
        w = math.inf if math.isnan(w) else (w if w > 0 else cell)
        widths.append(min(w, scale))
    crossed = np.hypot(d[:, 0] / widths[0], d[:, 1] / widths[1])  # half-widths crossed per step
    n = int(np.argmax(crossed))
    if not crossed[n] > 0:
        return None
    length = float(np.hypot(*d[n]))
    tm = scene.time
    if tm.dt is not None:
        key, value = "[time] dt", tm.dt
        unit = float(np.hypot(*scene.velocity(0.0))) if tm.mode is TimeMode.STEADY else float(scene.velocity.peak())
    else:
        key, value, unit = "[time] steps_per_cell", tm.steps_per_cell or 1.0, g.cell
    longest = float(np.max(np.hypot(d[:, 0], d[:, 1])))
    return TimeResolution(1.0 / float(crossed[n]), length / float(crossed[n]), longest / g.cell, length, key,
                          float(value), unit)


def check_time(scene, found: TimeResolution | None) -> str | None:
    """Refuse (SceneError) a time step that does not resolve the contact: fewer than LEAST_STEPS steps per
    half-width unless [time] allow_coarse = true; whatever it says, a step longer than the grid, or a
    steady sliding step below FINEST_SLIDE of the grid's longer side. The warning's text where there are
    fewer than GOOD_STEPS (None: none)."""
    if found is None:
        return None
    g, key, value = scene.grid, found.key, found.value
    shown = f"{key} = {value:g}" + (" (the default)" if key.endswith("steps_per_cell")
                                    and scene.time.steps_per_cell is None else "")
    longest = max(g.x1 - g.x0, 0.0 if g.line else g.y1 - g.y0)
    step = f"the body moves {found.cells:.3g} cell{'s' * (f'{found.cells:.3g}' != '1')} per step"
    if found.cells * g.cell > longest:
        raise SceneError(scene.source, key, value, f"{step}, {found.cells * g.cell:.3g} m, farther than the grid "
                         f"is long ({longest:.3g} m): no run can use such a step; {found.at_most(longest)} keeps "
                         f"it within the grid, {found.giving(GOOD_STEPS)} gives {GOOD_STEPS} steps per contact "
                         "half-width (docs/accuracy.md)")
    if scene.time.mode is TimeMode.STEADY and g.topology.whole and found.length < FINEST_SLIDE * longest:
        raise SceneError(scene.source, key, value, f"the steady sliding step moves the body {found.length:.3g} m, "
                         f"{found.length / longest:.2g} of the grid's longer side: below {FINEST_SLIDE:g} of it "
                         "the solve loses its digits to round-off; "
                         f"{found.at_most(FINEST_SLIDE * longest, fine=True)} (docs/accuracy.md)")
    if found.steps >= GOOD_STEPS:
        return None
    resolution = (f"gives {found.steps:.2g} steps per contact half-width along the motion ({step}; estimated "
                  f"half-width {found.width:.3g} m)")
    if found.steps < LEAST_STEPS and not scene.time.allow_coarse:
        raise SceneError(scene.source, key, value, f"{resolution}; at least {LEAST_STEPS} are needed: "
                         f"{found.giving(GOOD_STEPS)} gives {GOOD_STEPS}, or set [time] allow_coarse = true to "
                         "run anyway (docs/accuracy.md)")
    return f"{shown} {resolution}; {found.giving(GOOD_STEPS)} gives {GOOD_STEPS}"
