"""Before step 1: the contact a scene will make, whether its grid resolves it, how many steps and how
much memory the run takes (``petroll check``, :func:`check`; the run checks the same, :func:`check_run`).

Contact size. The body's curvature radii at first contact (Rx, Ry: second differences of Z through its
lowest point over the contact's own width, so that a map's roughness averages out; infinite along a flat
axis) and the material's compliance range, glassy J0 and rubbery Jinf, give an equivalent penetration
delta_e: the scene's largest penetration under penetration control; under load control Hertz's
a^2 / R for the largest load (3-D: a = (3 F R J / 4)^(1/3), R = sqrt(Rx Ry); a roller with a flat axis or
line contact: the line-contact form a = sqrt(4 P R J / pi) with P the load per length of the contact).
The contact half-widths are those of the region where the body lies within delta_e / 2 of its lowest
point, along X and Y (for a sphere exactly Hertz's radius: a^2 = R delta). Lengths in m.

Resolution. Cells per contact half-width along X and Y, the smaller over the compliance range (a steady
rolling state under load control: its contact at J(a/V), ContactSize.resolved): below
``GOOD_CELLS`` the run warns (one line naming the key and the value that gives ``GOOD_CELLS``), below
``LEAST_CELLS`` it is refused unless ``[grid] allow_coarse = true``, above ``MOST_CELLS`` (a contact
smaller than half the grid) it is refused (docs/accuracy.md: errors against cells per half-width).

Time step. Steps per contact half-width along the motion, checked like the cells
(petroll.model.timestep: below ``GOOD_STEPS`` a run warns, below ``LEAST_STEPS`` it is refused unless
``[time] allow_coarse = true``; steps longer than the grid, or too fine for a steady sliding solve, are
refused). ``petroll check`` prints the cells per step and the steps per half-width.

Rough surfaces. On a grid periodic along X and Y whose body is a rough surface (a generated one, or a height
map of the grid's cells), no curvature sizes the contact: petroll.model.rough_contact estimates its area
fraction and penetration from the surface's spectrum and the load (Persson), and the resolution is
counted in cells per short cut-off wavelength (below its ``GOOD_CUTOFF_CELLS`` a run warns); the time step
is weighed against the half-width of its single contacts.

Path. The body's reference point over the whole run (petroll.model.clock.path) carries the box of the
cells it can interfere with: where it lies within delta_e of its lowest point (rubbery delta_e under load
control; line contact: the contact, within delta_e / 2). A run whose box would reach the grid's edge cells
at some step is refused, saying where it leaves the grid and the extent it needs (along a periodic axis
the body wraps around: nothing to leave). A body that never presses (its largest penetration or load
<= 0), has no surface over the grid, or lies outside the grid (nowhere over it within the largest
penetration of its own lowest point, :func:`check_over_grid`) is refused, and so is, on a periodic grid,
whose contact problem covers every cell, a body without surface over some cells
(petroll.model.surface_check).
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass

import numpy as np

from petroll.errors import SceneError
from petroll.model.clock import Path, TimeMode, path
from petroll.model.limits import PetrollWarning, largest_penetration
from petroll.model.rough_contact import GOOD_CUTOFF_CELLS, RoughContact, rough_contact
from petroll.model.surface_check import check_surface
from petroll.model.timestep import GOOD_STEPS, TimeResolution, check_time, time_resolution

GOOD_CELLS = 8
"""Cells per contact half-width below which a run warns (about 1 % in force and mu_r: docs/accuracy.md)."""
LEAST_CELLS = 2
"""Cells per contact half-width below which a run is refused unless [grid] allow_coarse = true."""
MOST_CELLS = 1024
"""Cells per contact half-width above which a run is refused (a contact smaller than the grid): the error
falls as the square of the cell (2e-4 in force at 24 cells, docs/accuracy.md), about 1e-7 at 1024, below
the solver's tolerance, while every step costs more with every cell (nx = 100000 typed for hertz.toml's
64: 6.4 million cells, minutes per step)."""
BYTES_PER_CELL = 145
"""A rolling run's memory per grid cell, all ranks together (measured, `petroll bench memory`, an SLS)."""
FIXED_MIB = 96
"""A rank's memory before the scene is built: Python, numpy, PETSc, MPI (measured, MiB)."""


@dataclass(frozen=True)
class ContactSize:
    """Estimated contact half-widths at the scene's largest load or penetration (m; line contact: Y nan).

    ``radii``: the body's curvature radii at first contact along X and Y (m; inf along a flat axis);
    ``lowest``: its lowest point relative to its reference point (m); ``glassy`` / ``rubbery``: the
    half-widths along X and Y with J0 / Jinf (the same under penetration control); a steady rolling scene
    under load control (:func:`steady_rolling`): ``steady``, the half-widths with the compliance J(a / V)
    the material has over the time it takes to cross the contact, and ``compliance``, that J and the one
    that bounds its interference region (:func:`steady_compliance`)."""

    radii: tuple[float, float]
    lowest: tuple[float, float]
    glassy: tuple[float, float]
    rubbery: tuple[float, float]

    steady: tuple[float, float] | None = None  # steady rolling under load: the half-widths at J(a / V)
    compliance: tuple[float, float] | None = None  # and (J(a / V), J(STEADY_SETTLING a / V)), 1/Pa

    @property
    def smallest(self) -> tuple[float, float]:
        return (min(self.glassy[0], self.rubbery[0]), min(self.glassy[1], self.rubbery[1]))

    @property
    def resolved(self) -> tuple[float, float]:
        """The half-widths the cells are counted on: the smallest over the compliance range, or a steady
        rolling state's at its speed (the least contact a run makes)."""
        return self.steady if self.steady is not None else self.smallest

    @property
    def largest(self) -> tuple[float, float]:
        return (max(self.glassy[0], self.rubbery[0]), max(self.glassy[1], self.rubbery[1]))


def _axis_points(scene, lowest, axis: int, offsets: np.ndarray) -> np.ndarray:
    """Z at the body's lowest point moved by ``offsets`` (m) along ``axis`` (0: X, 1: Y)."""
    x = np.full(offsets.shape, lowest[0])
    y = np.full(offsets.shape, lowest[1])
    (x if axis == 0 else y)[...] += offsets
    return np.asarray(scene.body.height(x, y), dtype=float)


def wrapped_position(scene) -> tuple[float, float]:
    """[body] position (m) moved by whole periods into the grid along its periodic axes (the same body to
    the solver: its offsets wrap around them)."""
    return scene.grid.topology.wrapped(*scene.position)


def lowest_point(scene) -> tuple[float, float]:
    """The body's lowest point over the grid at its start, relative to its reference point (m): the
    lowest of a 401-point lattice per axis, refined on a lattice 20 times finer around it. SceneError if
    the body has no surface over the grid."""
    g, (sx, sy) = scene.grid, wrapped_position(scene)
    span = [(g.x0 - sx, g.x1 - sx), (0.0, 0.0) if g.line else (g.y0 - sy, g.y1 - sy)]
    for _ in range(2):
        x = np.linspace(*span[0], 401)[:, None]
        y = np.linspace(*span[1], 1 if g.line else 401)[None, :]
        with np.errstate(all="ignore"):
            z = np.asarray(scene.body.height(x, y), dtype=float)
        finite = np.isfinite(z)
        if not finite.any():
            raise SceneError(scene.source, "[body] position", list(scene.position),
                             "the body has no surface over the grid: it can never touch it")
        low = z[finite].min()
        # the middle of a flat bottom (a roller's): the lowest point nearest the centroid of the lowest ones
        ii, jj = np.nonzero(z <= low + 1e-9 * max(z[finite].max() - low, abs(low)))
        k = int(np.argmin((ii - ii.mean()) ** 2 + (jj - jj.mean()) ** 2))
        found = (float(x[ii[k], 0]), float(y[0, jj[k]]))
        step = [(b - a) / 400 for a, b in span]
        span = [(c - 10 * h, c + 10 * h) for c, h in zip(found, step)]
        if g.line:
            span[1] = (0.0, 0.0)
    return found


def curvature_radius(scene, lowest, axis: int, reach: float) -> float:
    """The body's radius of curvature (m) along ``axis`` at ``lowest``: the second difference of Z over
    +- ``reach`` (m), halved until the body has a surface there; inf where it does not curve upward."""
    z0 = float(_axis_points(scene, lowest, axis, np.zeros(1))[0])
    for _ in range(60):
        zm, zp = _axis_points(scene, lowest, axis, np.array([-reach, reach]))
        if np.isfinite(zm) and np.isfinite(zp):
            curvature = (zm + zp - 2 * z0) / reach**2
            return 1 / curvature if curvature > 0 else math.inf
        reach /= 2
    return math.inf


def half_width(scene, lowest, axis: int, depth: float) -> float:
    """Half the extent (m) along ``axis`` through ``lowest`` of the region where the body lies within
    ``depth`` (m) of its lowest point: the farthest such point on either side (a lattice over the grid's
    length, then bisection to 1e-6 of it), the two sides averaged."""
    g = scene.grid
    length = (g.x1 - g.x0) if axis == 0 else (g.y1 - g.y0)
    s = np.linspace(0.0, length, 4001)[1:]
    z0 = float(_axis_points(scene, lowest, axis, np.zeros(1))[0])
    sides = []
    for sign in (-1, 1):
        with np.errstate(all="ignore"):
            inside = _axis_points(scene, lowest, axis, sign * s) - z0 <= depth
        if not inside.any():
            lo, hi = 0.0, s[0]
        elif inside[-1]:
            sides.append(length)
            continue
        else:
            k = int(np.flatnonzero(inside)[-1])
            lo, hi = s[k], s[k + 1]
        while hi - lo > 1e-6 * length:
            mid = 0.5 * (lo + hi)
            if _axis_points(scene, lowest, axis, np.array([sign * mid]))[0] - z0 <= depth:
                lo = mid
            else:
                hi = mid
        sides.append(0.5 * (lo + hi))
    return 0.5 * (sides[0] + sides[1])


def _penetration(scene, radii, lowest, compliance: float, widths) -> float:
    """The equivalent penetration delta_e (m) for ``compliance`` (1/Pa), given the current half-widths."""
    delta, exact = largest_penetration(scene)
    if exact:
        return delta
    load = float(scene.load.largest())
    rx, ry = radii
    if scene.grid.line or not math.isfinite(ry) or not math.isfinite(rx):  # the line-contact form
        radius = rx if math.isfinite(rx) else ry
        per_length = load if scene.grid.line else load / (2 * (widths[1] if math.isfinite(rx) else widths[0]))
        a = math.sqrt(4 * per_length * radius * compliance / math.pi)
        return a * a / radius
    radius = math.sqrt(rx) * math.sqrt(ry)  # not rx * ry: radii up to 1e308 m (a nearly flat body)
    a = (3 * load * radius * compliance / 4) ** (1 / 3)
    return a * a / radius


def contact_size(scene) -> ContactSize:
    """The scene's :class:`ContactSize`: curvature radii and half-widths iterated three times from the
    body's radius hint (each pass measures the radii over the half-widths of the last; a roller's load per
    length is taken over the last pass's length along its flat axis); a steady rolling scene under load
    control also at its speed (:func:`steady_compliance`)."""
    lowest = lowest_point(scene)
    g, material = scene.grid, scene.material
    hint = float(scene.body.radius_hint)
    delta, _ = largest_penetration(scene)
    if not (delta > 0 and math.isfinite(hint) and hint > 0):
        delta = max(g.dx, g.cell) ** 2 / max(hint, g.dx)  # a contact of about one cell
    start = math.sqrt(hint * delta) if math.isfinite(hint) else g.dx

    def widths_for(compliance: float, widths: tuple[float, float]):
        for _ in range(3):
            reach = [w if math.isfinite(w) and w > 0 else g.dx for w in widths]
            radii = (curvature_radius(scene, lowest, 0, reach[0]),
                     math.inf if g.line else curvature_radius(scene, lowest, 1, reach[1]))
            if not g.line and math.isinf(radii[0]) and math.isinf(radii[1]):
                radii = (hint, hint)  # flat at the contact's scale: the body's own hint
            delta_e = _penetration(scene, radii, lowest, compliance, widths)
            widths = (half_width(scene, lowest, 0, delta_e / 2),
                      math.nan if g.line else half_width(scene, lowest, 1, delta_e / 2))
        return widths, radii

    glassy, radii = widths_for(material.J0, (start, math.nan if g.line else start))
    if scene.penetration is not None:  # penetration control: no compliance enters
        return ContactSize(radii, lowest, glassy, glassy)
    rubbery, radii = widths_for(material.Jinf, (start, math.nan if g.line else start))
    size = ContactSize(radii, lowest, glassy, rubbery)
    rolling = steady_rolling(scene)
    if rolling is None:
        return size
    axis, speed = rolling
    widths = rubbery
    for _ in range(3):  # a = a(J(a / V)): from the rubbery contact, shrinking toward the crossing's
        compliance = float(material(widths[axis] / speed))
        widths, _ = widths_for(compliance, widths)
    return dataclasses.replace(size, steady=widths, compliance=(compliance, steady_compliance(scene, widths)))


STEADY_SETTLING = 10
"""The contact of a steady rolling state under load control is taken to lie inside the interference
region of J(STEADY_SETTLING a / V), a the half-width along the motion at J(a / V) (the time a point of the
surface takes to cross it): the pressure behind the contact's centre has acted longer than a / V, not
indefinitely (docs/accuracy.md)."""


def steady_rolling(scene) -> tuple[int, float] | None:
    """(axis, speed): a steady rolling scene's ([time] mode = "steady" on a grid not periodic along both
    axes, under load control) direction of motion (0: X, 1: Y) and speed (m/s); None for any other."""
    g = scene.grid
    if scene.time.mode is not TimeMode.STEADY or scene.load is None or g.topology.whole or g.line:
        return None
    velocity = np.asarray(scene.velocity(0.0), dtype=float)
    return int(np.argmax(np.abs(velocity))), float(np.hypot(*velocity))


def steady_compliance(scene, widths: tuple[float, float]) -> float:
    """The compliance (1/Pa) whose interference region holds a steady rolling contact of half-widths
    ``widths`` (m) at J(a / V): J(STEADY_SETTLING a / V) (:data:`STEADY_SETTLING`)."""
    axis, speed = steady_rolling(scene)
    return float(scene.material(STEADY_SETTLING * widths[axis] / speed))


def interference_depth(scene, size: ContactSize, glassy: bool = True) -> tuple[float, bool]:
    """(depth, exact): the body interferes with the surface where it lies less than ``depth`` (m) above its
    lowest point: the largest penetration (``exact``), or under load control the equivalent penetration
    with the glassy (``glassy``: the least the run will have at its largest load) or the rubbery
    compliance (a steady rolling state: the compliance that bounds it, ContactSize.compliance); line
    contact: half of it, the contact (the solver checks the contact there)."""
    delta, exact = largest_penetration(scene)
    if not exact:
        if glassy:
            compliance, widths = scene.material.J0, size.glassy
        elif size.compliance is not None:
            compliance, widths = size.compliance[1], size.steady
        else:
            compliance, widths = scene.material.Jinf, size.rubbery
        delta = _penetration(scene, size.radii, size.lowest, compliance, widths)
    return (delta / 2 if scene.grid.line else delta), exact


def interference_box(scene, size: ContactSize, walked: Path, glassy: bool = True) -> tuple[float, float, float,
                                                                                           float]:
    """(x0, x1, y0, y1): the box (m, relative to the body's reference point) of the region where the body
    lies within delta_e of its lowest point (line contact: delta_e / 2, the contact), delta_e the largest
    penetration or, under load control, the glassy or rubbery one (:func:`interference_depth`): the cells a
    run's QPs can be posed on. Sampled
    on a 201-point lattice per axis over 3 largest half-widths around the lowest point (the box widened by
    a lattice step) and on a 401-point lattice over all of the body that comes over the grid along
    ``walked`` (a second contact far from the first). A layer's surface bulges up around the load, so its
    contact reaches beyond the interference (up to sqrt(2) times for a thin incompressible bonded layer,
    docs/layer.md): unless ``glassy`` (the least region the run will need), under penetration control in
    3-D its box is widened by sqrt(2) about the lowest point (under load control the half-space's
    penetration overestimates a layer's, and line contact's box is the contact)."""
    g, (lx, ly) = scene.grid, size.lowest
    depth, exact = interference_depth(scene, size, glassy)
    sx = 3 * max(size.largest[0], g.dx)
    sy = 0.0 if g.line else 3 * max(size.largest[1], g.dy)
    near = (lx + np.linspace(-sx, sx, 201), ly + np.linspace(-sy, sy, 1 if g.line else 201))
    whole = (np.linspace(g.x0 - walked.sx.max(), g.x1 - walked.sx.min(), 401),
             np.zeros(1) if g.line else np.linspace(g.y0 - walked.sy.max(), g.y1 - walked.sy.min(), 401))
    box = [lx, lx, ly, ly]
    for (x, y), widen in ((near, (2 * sx / 200, 2 * sy / 200)), (whole, (0.0, 0.0))):
        with np.errstate(all="ignore"):
            inside = np.asarray(scene.body.height(x[:, None], y[None, :]), dtype=float) < depth
        ii, jj = np.nonzero(inside)
        if ii.size:
            box = [min(box[0], x[ii.min()] - widen[0]), max(box[1], x[ii.max()] + widen[0]),
                   min(box[2], y[jj.min()] - widen[1]), max(box[3], y[jj.max()] + widen[1])]
    if scene.layer is not None and exact and not g.line and not glassy:
        grow = math.sqrt(2)
        box = [lx + grow * (box[0] - lx), lx + grow * (box[1] - lx), ly + grow * (box[2] - ly),
               ly + grow * (box[3] - ly)]
    return tuple(float(b) for b in box)


def check_touching(scene) -> None:
    """SceneError unless the body presses into the surface at some time: the largest penetration or load
    must be > 0 (at 0 or below the run would report nothing at every step)."""
    control = "penetration" if scene.penetration is not None else "load"
    peak = float((scene.penetration if scene.penetration is not None else scene.load).largest())
    if not peak > 0:
        value = scene.raw.get("motion", {}).get(control)
        raise SceneError(scene.source, f"[motion] {control}", value,
                         f"is never > 0 (largest {peak:g}): the body never presses into the surface; give a "
                         f"{control} > 0 ({'m' if control == 'penetration' else 'N'}) at some time")


def check_over_grid(scene, lowest: tuple[float, float]) -> None:
    """SceneError for a body placed outside its grid: at its start, the lowest it comes over the grid
    (``lowest``: that point, m from its reference point, :func:`lowest_point`) is no nearer to its own
    lowest point than the largest penetration (under load control the relaxed Hertz estimate, the most it
    can press): it would touch no cell, and a run would report no contact (force 0) as if it were one."""
    depth, exact = largest_penetration(scene)
    with np.errstate(all="ignore"):
        above = float(np.asarray(scene.body.height(np.array(lowest[0]), np.array(lowest[1])), dtype=float))
    if above < depth:
        return
    g = scene.grid
    extent = f"[{g.x0:g}, {g.x1:g}]" + ("" if g.line else f" x [{g.y0:g}, {g.y1:g}]")
    what = "the largest penetration" if exact else "the penetration its largest load could reach (estimate)"
    raise SceneError(scene.source, "[body] position", list(scene.position),
                     f"the body lies outside the grid {extent} m: over the grid it comes no nearer than "
                     f"{above:.4g} m to its own lowest point, more than {what} {depth:.4g} m, so it touches no "
                     "cell; place the body over the grid (or move [grid] x, y to it)")


def _edge_cells_reached(scene, depth: float, sx: float, sy: float) -> bool:
    """Whether the body at (sx, sy) interferes (lies below ``depth`` over its lowest point) with a cell
    centre of the grid's edge rows or columns (line contact: its end strips) along its non-periodic axes:
    the solver's condition."""
    g = scene.grid
    x, y = g.offsets(g.x, g.y, sx, sy)  # along a periodic axis: to the nearest image
    points = g.topology.edge_points(x, y)
    with np.errstate(all="ignore"):
        return any(bool(np.any(np.asarray(scene.body.height(px, py), dtype=float) < depth)) for px, py in points)


def path_leaves(scene, size: ContactSize, walked: Path, glassy: bool = True) -> tuple[str, str] | None:
    """The first step at which the body's interference region (:func:`interference_depth`) reaches a cell
    of the grid's edge rows or columns along ``walked``: (the axis, "x" or "y"; a sentence saying where and
    the extent the whole run needs); None if it never does. ``glassy``: the least region the run will
    need (under load control the glassy penetration), else the most it may (the rubbery one; a layer's
    bulge). Steps whose :func:`interference_box` comes within a cell of the edge cells are checked at the
    edge cells' centres, as the solver does (a layer's box widened for its bulge is taken as it is). A
    periodic axis has no edge: a body wraps around it; on a grid periodic along every axis, None."""
    g = scene.grid
    if not g.topology.edge_axes:
        return None
    depth, exact = interference_depth(scene, size, glassy)
    bx0, bx1, by0, by1 = interference_box(scene, size, walked, glassy)
    along = {0: ("x", walked.sx + bx0, walked.sx + bx1, g.x0, g.x1, g.dx),
             1: ("y", walked.sy + by0, walked.sy + by1, g.y0, g.y1, g.dy)}
    axes = [along[axis] for axis in g.topology.edge_axes]
    near = np.zeros(len(walked.t), dtype=bool)
    for _, lo, hi, start, end, cell in axes:
        near |= (lo <= start + 1.5 * cell) | (hi >= end - 1.5 * cell)
    widened = scene.layer is not None and exact and not g.line and not glassy
    for n in np.flatnonzero(near):
        if widened or _edge_cells_reached(scene, depth, walked.sx[n], walked.sy[n]):
            break
    else:
        return None
    axis, lo, hi, start, end, _ = max(axes, key=lambda a: max(a[3] - a[1][n], a[2][n] - a[4]))
    how = (f"to [time] distance = {scene.time.distance:g} m" if scene.time.distance is not None
           else f"to [time] end = {scene.time.end:g} s" if scene.time.end is not None else "one step")
    where = ("at the start" if n == 0 else
             f"at step {n} (t = {walked.t[n]:.4g} s, after {walked.distance[n]:.4g} m of rolling)")
    which = ("" if glassy else " (with a layer's bulge)") if exact else \
        f" ({'glassy' if glassy else 'rubbery'} estimate)"
    return axis, (f"the body's contact region{which} reaches the grid's edge cells {where}: over the whole run "
                  f"({how}) it spans {axis} from {lo.min():.4g} to {hi.max():.4g} m, beyond the grid's "
                  f"[{start:g}, {end:g}] less its edge cells; enlarge [grid] {axis} or shorten the run")


@dataclass(frozen=True)
class Preflight:
    """What :func:`check` found: the contact size, cells per half-width (X, Y; ContactSize.resolved; a
    periodic rough surface: per short cut-off wavelength), the run's path and steps, and the predicted
    memory per rank (MiB)."""

    scene: object
    contact: ContactSize
    cells: tuple[float, float]
    path: Path
    ranks: int
    memory_mib: float
    leaves: tuple[str, str] | None  # (axis, where) the path's contact region reaches the grid's edge
    creeping: tuple[str, str] | None = None  # the same as the contact may grow (load: rubbery; layer: bulge)
    time: TimeResolution | None = None  # the time step against the contact (None: one step, or at rest)
    warned: str | None = None  # the warning check_run gave (one line), None: none
    rough: RoughContact | None = None  # a periodic rough surface's estimates (cells: per cut-off wavelength)

    def verdict(self) -> str:
        """What a run makes of the resolution: fine, warned or refused."""
        fewest = min(self.cells)
        if self.rough is not None:
            return (f"at least {GOOD_CUTOFF_CELLS}, fine" if self.rough.cells >= GOOD_CUTOFF_CELLS else
                    f"fewer than {GOOD_CUTOFF_CELLS}: a run warns") + " (docs/rough.md)"
        if self.too_fine():
            return f"more than {MOST_CELLS}: a run is refused (docs/accuracy.md)"
        if fewest >= GOOD_CELLS:
            return f"at least {GOOD_CELLS}, fine (docs/accuracy.md)"
        if fewest >= LEAST_CELLS or self.scene.allow_coarse:
            return f"fewer than {GOOD_CELLS}: a run warns (docs/accuracy.md)"
        return (f"fewer than {LEAST_CELLS}: a run is refused unless [grid] allow_coarse = true "
                "(docs/accuracy.md)")

    def too_fine(self) -> list[tuple[str, float]]:
        """The axes (name, cells per contact half-width) along which a contact smaller than the grid has
        more than MOST_CELLS cells per half-width (a run refuses them)."""
        g, small = self.scene.grid, self.contact.resolved
        if self.rough is not None:
            return []  # its cells count wavelengths: a contact of many spots spreads over the cell
        extents = {"x": g.x1 - g.x0, "y": g.y1 - g.y0}
        return [(axis, n) for axis, n, width in zip("xy", self.cells, small)
                if n > MOST_CELLS and width < extents[axis] / 2]

    def time_verdict(self) -> str:
        """What a run makes of the time step (:func:`check_time`): fine, warned or refused (and why)."""
        try:
            warned = check_time(self.scene, self.time)
        except SceneError as exc:
            return f"a run is refused: {exc.allowed}"
        if warned is None:
            return f"at least {GOOD_STEPS}, fine (docs/accuracy.md)"
        return (f"fewer than {GOOD_STEPS}: a run warns; {self.time.giving(GOOD_STEPS)} gives {GOOD_STEPS} "
                "(docs/accuracy.md)")

    def lines(self) -> list[str]:
        """The report of ``petroll check``, one fact per line."""
        g, c = self.scene.grid, self.contact
        control = "penetration" if self.scene.penetration is not None else "load"
        axes = ("x",) if g.line else ("x", "y")
        radii = " x ".join(f"{r:.4g}" for r in (c.radii[:1] if g.line else c.radii))
        glassy = " x ".join(f"{w:.4g}" for w in c.glassy[: len(axes)])
        rubbery = " x ".join(f"{w:.4g}" for w in c.rubbery[: len(axes)])
        cells = ", ".join(f"{n:.1f} along {a} ([grid] n{a} = {getattr(g, 'n' + a)})"
                          for n, a in zip(self.cells, axes))
        steps = (f"{self.path.steps} after the start" if self.path.complete
                 else f"more than [time] max_steps = {self.scene.time.max_steps}")
        if self.scene.time.steady is not None and self.path.steps:
            steps += " (fewer if [time] steady stops the run first)"
        if self.rough is not None:
            contact = self.rough.lines(max(g.dx, g.dy))
        else:
            contact = [f"body: curvature radii at first contact {radii} m ({'x' if g.line else 'x, y'}), lowest "
                       f"point at ({c.lowest[0]:.4g}, {c.lowest[1]:.4g}) m from the reference point",
                       f"contact half-widths ({control} control, largest {control}): {glassy} m glassy (J0), "
                       f"{rubbery} m rubbery (Jinf)" + ("" if c.steady is None else
                                                        f", {' x '.join(f'{w:.4g}' for w in c.steady)} m at the "
                                                        f"steady speed (J(a/V) = {c.compliance[0]:.4g} 1/Pa)"),
                       f"cells per contact half-width: {cells}: {self.verdict()}"]
        sizing = getattr(self.scene, "sizing", None)  # a grid petroll sized: what it chose
        return [f"{self.scene.source}: checked, nothing run",
                *([] if sizing is None else [sizing.note.replace("[grid] sized by petroll: ", "grid sized by "
                                                                 "petroll (docs/accuracy.md): ")]),
                *contact,
                f"steps: {steps}",
                *([] if self.time is None else [
                    f"time step: {self.time.cells:.3g} cells per step at most ({self.time.key} = "
                    f"{self.time.value:g}), {self.time.steps:.3g} steps per contact half-width along the motion "
                    f"(estimated half-width {self.time.width:.3g} m): {self.time_verdict()}"]),
                "path: " + (self.leaves[1] if self.leaves else f"the body's reference point goes from ({self.path.sx[0]:.4g}, "
                            f"{self.path.sy[0]:.4g}) to ({self.path.sx[-1]:.4g}, {self.path.sy[-1]:.4g}) m; "
                            "its contact region stays inside the grid"
                            + (f", but as it grows it may not: {self.creeping[1]}" if self.creeping else "")),
                f"memory: about {self.memory_mib:.0f} MiB per rank on {self.ranks} rank{'s' * (self.ranks != 1)}"
                f" ({g.nx * g.ny} cells at {BYTES_PER_CELL} bytes per cell, a rolling run's, plus {FIXED_MIB} MiB "
                "per rank)"]


def check(scene, ranks: int = 1) -> Preflight:
    """Estimate, without running: contact size, resolution, the path and steps, memory per rank on
    ``ranks`` ranks (``petroll check``). Raises SceneError only for a body that never touches
    (:func:`check_touching`, no surface over the grid, :func:`check_over_grid`) or, on a periodic grid,
    has no surface over some cells (petroll.model.surface_check); :func:`check_run` refuses the rest."""
    g = scene.grid
    check_touching(scene)
    check_over_grid(scene, lowest_point(scene))
    walked = path(scene)
    check_surface(scene, walked)
    rough = rough_contact(scene)
    if rough is not None:  # many small spots: their half-width, the cells per cut-off wavelength
        size = ContactSize((math.inf, math.inf), lowest_point(scene), (rough.spot,) * 2, (rough.spot,) * 2)
        cells = (rough.cutoff / g.dx, rough.cutoff / g.dy)
    else:
        size = contact_size(scene)
        small = size.resolved
        cells = (small[0] / g.dx,) if g.line else (small[0] / g.dx, small[1] / g.dy)
    memory = FIXED_MIB + BYTES_PER_CELL * g.nx * g.ny / ranks / 2**20
    leaves = path_leaves(scene, size, walked)
    growing = scene.load is not None or (scene.layer is not None and not g.line)  # load: creep; layer: bulge
    creeping = path_leaves(scene, size, walked, glassy=False) if leaves is None and growing else None
    return Preflight(scene, size, cells, walked, ranks, memory, leaves, creeping,
                     time_resolution(scene, size, walked), rough=rough)


def check_run(scene) -> Preflight:
    """The checks a run makes before step 1: :func:`check` (a body that never touches refused); SceneError
    (naming the [grid] key) below LEAST_CELLS cells per contact half-width unless [grid] allow_coarse =
    true, and above MOST_CELLS (:meth:`Preflight.too_fine`); SceneError for a path that leaves the grid
    (naming [grid] x or y; under load control with the glassy penetration, the least the run will have); SceneError (naming [time] max_steps) for a run
    whose clock takes more than max_steps steps, unless a [time] steady stop may end it sooner (it needs
    one contact length of rolling, two smallest half-widths, within them; else the run would stop there
    unfinished); the time step's refusals (:func:`check_time`,
    naming [time] steps_per_cell or dt); a warning (PetrollWarning, one line, kept in the returned
    Preflight's ``warned``) where a contact half-width has fewer than GOOD_CELLS cells along an axis or
    GOOD_STEPS steps along the motion, or where under load control the rubbery contact would leave the grid
    (the run may stop there as its contact creeps)."""
    found = check(scene)
    g = scene.grid
    for axis, n in found.too_fine():
        key, count = f"[grid] n{axis}", getattr(g, f"n{axis}")
        most = math.floor(MOST_CELLS * count / n)
        raise SceneError(scene.source, key, count,
                         f"gives {n:.0f} cells per contact half-width along {axis} (estimated half-width "
                         f"{found.contact.resolved['xy'.index(axis)]:.3g} m); more than {MOST_CELLS} refine "
                         f"nothing a run can resolve (errors fall below 1e-6; docs/accuracy.md) and only cost "
                         f"time: n{axis} <= {most} gives {MOST_CELLS}")
    short = []
    if found.rough is not None and (coarse := found.rough.warning(scene.source, max(g.dx, g.dy))):
        short.append(coarse.partition(": ")[2])
    for axis, n in zip(("x", "y"), found.cells):
        if n >= GOOD_CELLS or found.rough is not None:
            continue
        key, count = f"[grid] n{axis}", getattr(g, f"n{axis}")
        extent = (g.x1 - g.x0) if axis == "x" else (g.y1 - g.y0)
        width = found.contact.resolved[0 if axis == "x" else 1]
        good = math.ceil(GOOD_CELLS * extent / width)
        if n < LEAST_CELLS and not scene.allow_coarse:
            raise SceneError(scene.source, key, count,
                             f"gives {n:.1f} cells per contact half-width along {axis} (estimated half-width "
                             f"{width:.3g} m); at least {LEAST_CELLS} are needed: n{axis} >= {good} gives "
                             f"{GOOD_CELLS}, or set [grid] allow_coarse = true to run anyway "
                             "(docs/accuracy.md)")
        short.append(f"{key} = {count} gives {n:.1f} cells per contact half-width along {axis}; "
                     f"n{axis} >= {good} gives {GOOD_CELLS}")
    if found.leaves is not None:
        axis, where = found.leaves
        raise SceneError(scene.source, f"[grid] {axis}", [g.x0, g.x1] if axis == "x" else [g.y0, g.y1], where)
    if found.creeping is not None:
        why = "as the contact creeps under the load" if scene.load is not None else "as the layer bulges"
        short.append(f"[grid] {found.creeping[0]}: {why} {found.creeping[1]}")
    patch = 2 * min(w for w in found.contact.smallest if not math.isnan(w))  # the steady stop's least rolling
    if not found.path.complete and (scene.time.steady is None or found.path.distance[-1] < patch):
        tm = scene.time  # it would stop at max_steps, unfinished: no steady stop can come before
        step = f"[time] dt = {tm.dt:g}" if tm.dt is not None else f"[time] steps_per_cell = {tm.steps_per_cell:g}"
        to = f"[time] end = {tm.end:g} s" if tm.end is not None else f"[time] distance = {tm.distance:g} m"
        raise SceneError(scene.source, "[time] max_steps", tm.max_steps,
                         f"the run to {to} with {step} takes more steps (its clock walked: more than "
                         f"{tm.max_steps}); it would stop there unfinished: raise max_steps or the time step")
    coarse_time = check_time(scene, found.time)
    if coarse_time is not None:
        short.append(coarse_time)
    if not short:
        return found
    text = f"{scene.source}: {'; '.join(short)} (docs/accuracy.md)"
    warnings.warn(PetrollWarning(text), stacklevel=2)
    return dataclasses.replace(found, warned=text)
