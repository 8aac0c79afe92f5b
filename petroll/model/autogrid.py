"""Grids petroll sizes itself: a scene without [grid], or with only ``[grid] cells_per_half_width`` or
``[grid] target_error`` (docs/accuracy.md#grids-petroll-sizes).

A smooth body (sphere, ellipsoid, 3-D cylinder; a measured roughness may ride on it) gets square cells of
the contact half-width over ``cells_per_half_width`` (default :data:`DEFAULT_CELLS`), the half-width
petroll.model.preflight counts cells on (``ContactSize.resolved``: the smallest over the material's glassy
and rubbery compliance; a steady rolling state under load control: the one at its speed, J(a/V)), and a
domain holding the region the body can interfere with over its whole path (``interference_box`` with the
most the contact may grow to: the rubbery penetration, or a steady rolling state's J(10 a/V); a layer's
bulge) widened by :data:`MARGIN` of its half-size and :data:`MARGIN_CELLS` cells on every side. A steady
solve's wake behind the grid is its own (petroll.solver.steady), so its grid is a window around the
contact; a transient's covers the track.

A generated rough surface (``shape = "rough"``) gets a periodic cell of :data:`ROUGH_PERIODS` rolloff
wavelengths (``rolloff`` and ``cutoff`` must be given) with cells of its cut-off over
:data:`ROUGH_CELLS` (twice the least, petroll.model.rough_contact.GOOD_CUTOFF_CELLS: friction within
0.4 %, area within 3 % of 16 cells per cut-off, docs/rough.md).

The contact is estimated on a provisional scene (the same keys on a coarse grid around the body, large
enough for any contact the body can make); the scene is then validated on the chosen grid.

``target_error`` is sized here as :data:`DEFAULT_CELLS`, the pilot's grid: the run chooses the cells per
half-width from a pilot on it (petroll.studies.target, which solves; this package does not).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import scipy.fft

from petroll.errors import MISSING, SceneError
from petroll.model.bodies import make_body
from petroll.model.clock import path
from petroll.model.preflight import contact_size, interference_box
from petroll.model.rough_contact import GOOD_CUTOFF_CELLS
from petroll.model.schema import MAX_CELLS, SCHEMA, Invalid

DEFAULT_CELLS = 16
"""Cells per contact half-width of a grid petroll sizes (force and mu_r within about 0.3 % on the
master curve's sphere, docs/accuracy.md)."""

MARGIN = 0.25
"""The domain's margin beyond the interference region, as a fraction of its half-size on each side."""

MARGIN_CELLS = 2
"""Cells added beyond the margin on every side (the solver refuses a window that reaches the edge cells)."""

PROVISIONAL_CELLS = 64
"""Cells per side of the provisional grid the contact is estimated on (its estimates do not depend on it:
they sample the body's own surface)."""

ROUGH_PERIODS = 4
"""A generated rough surface's periodic cell: this many rolloff wavelengths per side."""

ROUGH_CELLS = 2 * GOOD_CUTOFF_CELLS
"""Cells per short cut-off wavelength of a generated rough surface's automatic grid."""

SIZED_SHAPES = ("sphere", "ellipsoid", "cylinder", "rough")
"""The [body] shapes whose grid petroll can size."""

REQUEST_KEYS = ("cells_per_half_width", "target_error")
"""The [grid] keys of a grid petroll sizes."""


@dataclass(frozen=True)
class GridChoice:
    """A grid petroll chose: the [grid] table as written (``request``; empty when absent), the one chosen
    (``table``: nx, ny, x, y and periodic), and ``note``, one line saying what and why."""

    request: dict
    table: dict
    note: str


def automatic(table: object) -> bool:
    """Whether a scene's [grid] (None: absent) asks petroll to size the grid."""
    return table is None or (isinstance(table, dict) and set(table) <= set(REQUEST_KEYS))


def provisional(raw: dict, source: str, base_dir) -> dict:
    """The [grid] table of the provisional scene the contact is estimated on: PROVISIONAL_CELLS square
    cells on each side, 4 body radii (a cylinder: its width too) around [body] position. SceneError for a
    body petroll cannot size a grid for."""
    request = raw.get("grid") or {}
    if len(request) > 1:  # both REQUEST_KEYS
        raise SceneError(source, "[grid] target_error / cells_per_half_width", request,
                         "give one: target_error chooses the cells per half-width")
    body = raw.get("body", {})
    shape = body.get("shape") if isinstance(body, dict) else None
    if shape not in SIZED_SHAPES:
        raise SceneError(source, "[grid]", MISSING, f"required for [body] shape = {shape!r}: petroll sizes grids "
                         f"for shapes {', '.join(SIZED_SHAPES)} only (docs/accuracy.md)")
    roughness = body.get("roughness")
    if isinstance(roughness, dict) and "file" not in roughness:
        raise SceneError(source, "[grid]", MISSING, "required with a generated [body] roughness (its samples "
                         "are the grid's cells); give [grid], or a measured roughness (file)")
    if shape == "rough":
        return _rough_table(body, request, source)
    made = make_body(body, base_dir, source)
    reach = 2 * max(float(made.radius_hint), float(getattr(made, "width", 0.0)))
    try:
        position = SCHEMA["body"]["position"].check(body.get("position", [0.0, 0.0]))
    except Invalid as exc:
        raise SceneError(source, "[body] position", body["position"], f"{exc} (m)") from None
    if not math.isfinite(reach) or reach <= 0:
        raise SceneError(source, "[grid]", MISSING, "required: the body gives no size to size a grid from")
    return {"nx": PROVISIONAL_CELLS, "ny": PROVISIONAL_CELLS, "x": [position[0] - reach, position[0] + reach],
            "y": [position[1] - reach, position[1] + reach]}


def _rough_table(body: dict, request: dict, source: str) -> dict:
    """The periodic cell of a generated rough surface: ROUGH_PERIODS rolloff wavelengths, cells of the
    cut-off over ROUGH_CELLS (a fast FFT length)."""
    for key in REQUEST_KEYS:
        if key in request:
            raise SceneError(source, f"[grid] {key}", request[key], 'not for [body] shape = "rough": its grid '
                             f"has cells of its cutoff / {ROUGH_CELLS}; give [grid] nx, ny, x, y for another")
    for key in ("rolloff", "cutoff"):
        value = body.get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
            raise SceneError(source, f"[body] {key}", body.get(key, MISSING), "required (m, > 0) for a rough "
                             f"surface without [grid]: petroll makes its periodic cell {ROUGH_PERIODS} rolloff "
                             f"wavelengths wide with cells of cutoff / {ROUGH_CELLS}")
    side = ROUGH_PERIODS * float(body["rolloff"])
    cells = side / float(body["cutoff"]) * ROUGH_CELLS
    if cells**2 > MAX_CELLS:
        raise SceneError(source, "[body] cutoff", body["cutoff"], f"gives a periodic cell of {cells:.3g}^2 cells "
                         f"({ROUGH_PERIODS} rolloff wavelengths, cells of cutoff / {ROUGH_CELLS}), more than "
                         f"{MAX_CELLS}; give [grid] for a coarser one")
    n = scipy.fft.next_fast_len(math.ceil(cells), real=True)
    n += n % 2
    return {"nx": n, "ny": n, "x": [0.0, side], "y": [0.0, side], "periodic": True}


def choose(scene, request: dict) -> GridChoice:
    """The grid for ``scene`` (the provisional scene of :func:`provisional`, or a rough surface's scene on
    its own grid) and ``request`` ([grid] as written)."""
    g = scene.grid
    if g.topology.whole:  # a rough surface's periodic cell: already chosen
        table = {"nx": g.nx, "ny": g.ny, "x": [g.x0, g.x1], "y": [g.y0, g.y1], "periodic": True}
        note = (f"[grid] sized by petroll: a periodic cell of {ROUGH_PERIODS} rolloff wavelengths, "
                f"{g.x1 - g.x0:.4g} m, {g.nx} x {g.ny} cells of {g.dx:.4g} m ({ROUGH_CELLS} per cut-off)")
        return GridChoice(request, table, note)
    cells = request.get("cells_per_half_width", DEFAULT_CELLS)
    size = contact_size(scene)
    walked = path(scene)
    width = min(w for w in size.resolved if math.isfinite(w) and w > 0)
    h = width / cells
    bx0, bx1, by0, by1 = interference_box(scene, size, walked, glassy=False)
    extents = []
    for lo, hi, low, high in ((bx0, bx1, walked.sx.min(), walked.sx.max()),
                              (by0, by1, walked.sy.min(), walked.sy.max())):
        margin = MARGIN * (hi - lo) / 2 + MARGIN_CELLS * h
        start, end = low + lo - margin, high + hi + margin
        n = math.ceil((end - start) / h)
        middle = (start + end) / 2
        extents.append((n, [middle - n * h / 2, middle + n * h / 2]))
    (nx, x), (ny, y) = extents
    table = {"nx": nx, "ny": ny, "x": x, "y": y}
    what = ("at the steady speed, J(a/V)" if size.steady is not None else
            "the smallest over the compliance range" if scene.load is not None else "at the penetration")
    note = (f"[grid] sized by petroll: {nx} x {ny} square cells of {h:.4g} m over x [{x[0]:.4g}, {x[1]:.4g}], "
            f"y [{y[0]:.4g}, {y[1]:.4g}] m: {cells:g} cells per contact half-width {width:.4g} m ({what}), the "
            "region the body can press into over its "
            + ("path" if len(walked.t) > 1 else "contact") + f" and {MARGIN:.0%} more"
            + (f"; the pilot grid of target_error = {request['target_error']:g}" if "target_error" in request
               else ""))
    return GridChoice(request, table, note)
