"""A periodic grid's contact problem covers every cell: the body must have a surface (Z finite) over each
(:func:`check_surface`, part of petroll.model.preflight's checks)."""

from __future__ import annotations

import numpy as np

from petroll.errors import SceneError
from petroll.model.clock import Path

SURFACE_POINTS = 2**22
"""Body heights evaluated at most by the check that a periodic grid's body has a surface over every cell
(:func:`surface_gaps`): the grid at the start and at steps spread over the path."""


def surface_gaps(scene, walked: Path) -> tuple[int, int, float, float] | None:
    """On a periodic grid, whose contact problem covers every cell: (cells, step, x, y) at the first step
    of ``walked`` where the body has no surface (Z = +inf) over some cells' centres (how many; the
    centre (x, y) in m of the first); None where it has one over every cell (or the grid is not
    periodic). Checked at the start and at steps spread evenly over the path, at most SURFACE_POINTS
    heights in all. A periodic surface through samples (roughness) has a surface everywhere: what it
    rides on is checked."""
    from petroll.model.bodies.rough import PeriodicSurface, RoughBody

    g, body = scene.grid, scene.body
    while isinstance(body, RoughBody):
        body = body.body
    if not g.topology.whole or isinstance(body, PeriodicSurface):
        return None
    count = len(walked.t)
    steps = np.unique(np.linspace(0, count - 1, min(count, max(1, SURFACE_POINTS // (g.nx * g.ny))))
                      .round().astype(int))
    rows = max(1, SURFACE_POINTS // g.ny)
    y = g.y[None, :]
    for k in steps:
        total, first = 0, None
        for i0 in range(0, g.nx, rows):  # by blocks of rows: at most SURFACE_POINTS heights at once
            x = g.x[i0:i0 + rows, None]
            with np.errstate(all="ignore"):
                z = np.asarray(body.height(*g.offsets(x, y, walked.sx[k], walked.sy[k])), dtype=float)
            gaps = ~np.isfinite(np.broadcast_to(z, (len(x), g.ny)))
            if first is None and gaps.any():
                i, j = np.argwhere(gaps)[0]
                first = (float(g.x[i0 + i]), float(g.y[j]))
            total += int(np.count_nonzero(gaps))
        if total:
            return total, int(k), *first
    return None


def check_surface(scene, walked: Path) -> None:
    """SceneError on [grid] periodic where the body has no surface over some of a periodic grid's cells
    (:func:`surface_gaps`): the contact problem covers the whole periodic cell, and a cell without surface
    has no gap to put in it."""
    found = surface_gaps(scene, walked)
    if found is None:
        return
    cells, k, x, y = found
    g = scene.grid
    when = "at the start" if k == 0 else f"at step {k} (t = {walked.t[k]:.4g} s)"
    where = f"x = {x:.4g} m" if g.line else f"(x, y) = ({x:.4g}, {y:.4g}) m"
    raise SceneError(scene.source, "[grid] periodic", scene.raw.get("grid", {}).get("periodic"),
                     f"the body has no surface (Z = +inf) over {cells} of the grid's {g.nx * g.ny} cells "
                     f"{when}, e.g. at {where}, and a periodic grid's contact covers every cell: give the body a "
                     "surface over the whole grid (a cylinder as long as the grid along its axis, a height "
                     "map without +inf samples as large as the grid) or set [grid] periodic = false")
