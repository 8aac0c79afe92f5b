"""The discretisation error of a run's answer: the scene solved again on grids 2x (and 4x) coarser, and
Richardson extrapolation (``petroll run --estimate-error``, ``petroll.run(scene, estimate_error=True)``;
docs/accuracy.md).

The coarser grids cover the scene's extent with cells 2x (4x) as long along each axis, shifted so that the
body starts at the same fraction of a cell from a cell centre as on the fine grid (3-D); where the scene's
steps follow the cell (``steps_per_cell``, and the steady solve's time step) the step grows with the cell,
a fixed ``dt`` stays. They run to the fine run's last
time without the steady stop, so that all grids compare the same instant. For each quantity q of the
last step, with f1, f2, f4 its values on the fine, 2x and 4x grids:

- three grids: where the differences d1 = f2 - f1 and d2 = f4 - f2 have one sign and the observed order
  p = log2(d2 / d1) lies within a factor 2 of the known one, p is used; otherwise the grids are not in the
  asymptotic range and no error is given (nan): a sign change, or an order far from the method's, says the
  error is not yet a power of the cell (d1 = 0, the two finer grids agree: the error is the floor below);
- two grids: the method's known order for q (:data:`KNOWN_ORDER`);
- extrapolated = f1 - d1 / (2^p - 1); the error of the fine value |d1| / (2^q - 1) with q = min(p, the
  known order) (an observed order above the known one is not trusted to shrink the bound); for what counts
  cells at least its quantisation (:func:`_floor`: half a cell for the patch edges lead and trail, a quarter
  cell times the perimeter for the area).

The 4x grid is used where it still has ``THIRD_GRID_CELLS`` cells per contact half-width (estimated,
petroll.model.preflight): a grid coarser than that is outside the asymptotic range and its order misleads.
"""

from __future__ import annotations

import math
import time as clock
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from petroll.errors import PetrollError
from petroll.model.preflight import check
from petroll.model.scene import Scene
from petroll.solver.simulation import Simulation, StepRecord

QUANTITIES = ("force", "mu_r", "p_max", "area", "lead", "trail")
"""The last step's values an estimate covers (plus the penetration ``delta`` under load control)."""

KNOWN_ORDER = {"force": 2.0, "mu_r": 1.0, "p_max": 2.0, "delta": 2.0, "area": 1.0, "lead": 1.0, "trail": 1.0}
"""The order in the cell size taken for each quantity's error with two grids: 2 for the force, the
penetration and the peak pressure (the integrals and values of the piecewise-constant pressure on Love's
rectangles), 1 for mu_r (its resisting force weighs the contact's edges, which move by whole cells: measured
orders 1.2 to 3 between successive grids, so the lower bound is taken) and for what counts cells (the area,
the patch edges). Measured: docs/accuracy.md."""

THIRD_GRID_CELLS = 4.0
"""Cells per contact half-width the 4x coarser grid must keep for its values to be used."""


@dataclass(frozen=True)
class QuantityEstimate:
    """One quantity's estimate: the fine ``value``, the ``extrapolated`` one, the estimated ``error`` of
    the fine value (>= 0; nan: not in the asymptotic range), the ``order`` used (observed on three grids or
    the known one), whether it was ``observed``, and the coarser grids' values (``coarse``)."""

    value: float
    extrapolated: float
    error: float
    order: float
    observed: bool
    coarse: tuple[float, ...]

    @property
    def asymptotic(self) -> bool:
        return not math.isnan(self.error)


def richardson(values: tuple[float, ...], known: float, floor: float = 0.0,
               shifted: float | None = None) -> QuantityEstimate:
    """The estimate from a quantity's values on grids 1x, 2x (and 4x) coarse (see the module's text);
    ``floor``: the least error reported (half a cell for a cell edge); ``shifted``: the value on the 2x grid
    shifted by half its cell: the two 2x values' mean is extrapolated, the larger difference bounds."""
    scale = 1e-12 * max(abs(v) for v in values)  # differences below it are round-off: none
    f1 = values[0]
    f2 = values[1] if shifted is None else 0.5 * (values[1] + shifted)
    spread = 0.0 if shifted is None else 0.5 * abs(values[1] - shifted)
    d1 = f2 - f1 if abs(f2 - f1) > scale else 0.0
    observed = len(values) > 2
    order = known
    if observed:
        d2 = values[2] - f2 if abs(values[2] - f2) > scale else 0.0
        if d1 == 0:
            order = math.nan  # the fine grids agree: nothing to extrapolate
        elif d1 * d2 > 0 and abs(d2) > abs(d1) and known / 2 <= math.log2(d2 / d1) <= 2 * known:
            order = math.log2(d2 / d1)
        else:
            return QuantityEstimate(f1, math.nan, math.nan, math.nan, True, tuple(values[1:]))
    coarse = tuple(values[1:]) + (() if shifted is None else (shifted,))
    if d1 == 0 and spread == 0:
        return QuantityEstimate(f1, f1, floor, order, observed, coarse)
    trusted = known if math.isnan(order) else min(order, known)
    extrapolated = f1 - d1 / (2**order - 1) if d1 else f1
    return QuantityEstimate(f1, extrapolated, max((abs(d1) + spread) / (2**trusted - 1), floor), order,
                            observed, coarse)


def _aligned(start: float, end: float, cell: float, count: int, factor: int, at: float,
             shift: float = 0.0) -> tuple[int, list[float]]:
    """The coarser grid along one axis: cells ``factor`` times ``cell`` long, placed so that the point
    ``at`` (the body's start) lies at the same fraction of a cell from a cell centre as on the fine grid
    (plus ``shift`` coarse cells), shifted from [start, end] by less than a coarse cell towards ``start``
    and covering it."""
    big = factor * cell
    phase = ((at - start) / cell - 0.5 + shift) % 1.0  # where ``at`` lies between two fine cell centres
    first = at - big * (phase + 0.5)  # a coarse cell edge with ``at`` at that phase of its cell
    first -= big * math.ceil((first - start) / big - 1e-9)  # the last such edge at or before ``start``
    n = max(math.ceil(count / factor), math.ceil((end - first) / big - 1e-9))
    return n, [first, first + n * big]


def coarser(scene: Scene, factor: int, end: float | None, shift: float = 0.0) -> Scene:
    """``scene`` on a grid ``factor`` times coarser along each axis, covering the same extent, run to time
    ``end`` (s; None: a scene of one step or a steady solve keeps its clock) without its steady stop. The
    coarse grid is shifted (by less than a coarse cell) so that the body starts at the same fraction of a
    cell from a cell centre on every grid: the error that depends on that fraction (an alignment the grids
    would not share) is not taken for a discretisation error; ``shift``: moved by that many more coarse
    cells along each axis. In line contact the grid is not shifted: its length is the penetration's datum."""
    g, (sx, sy) = scene.grid, scene.position
    if g.line:  # the grid's length is the datum of the penetration (line-contact.md): kept, not shifted
        nx = math.ceil(g.nx / factor)
        nx, x = nx, [g.x0, g.x0 + nx * factor * g.dx]
    else:
        nx, x = _aligned(g.x0, g.x1, g.dx, g.nx, factor, sx, shift)
    changes = {"grid.nx": nx, "grid.x": x}
    if not g.line:
        ny, y = _aligned(g.y0, g.y1, g.dy, g.ny, factor, sy, shift)
        changes.update({"grid.ny": ny, "grid.y": y})
    if end is not None and scene.time.mode != "steady":
        changes.update({"time.steady": None, "time.distance": None, "time.end": end})
    return scene.replace(changes)


def last_values(record: StepRecord, quantities: tuple[str, ...]) -> dict[str, float]:
    return {name: float(getattr(record, name)) for name in quantities}


def _floor(scene: Scene, fine: StepRecord, name: str) -> float:
    """The least error of a quantity that counts cells: half a cell along the motion for the patch edges
    (cell edges), a quarter of a cell times the contact's perimeter for its area (line contact: its two
    edges; 3-D: the perimeter of a disc of that area), the mean error of edges that fall anywhere in their
    cells; 0 for the others."""
    g = scene.grid
    along = g.dx if g.line or abs(fine.sx - scene.position[0]) >= abs(fine.sy - scene.position[1]) else g.dy
    if name in ("lead", "trail"):
        return 0.5 * along
    if name == "area":
        return 0.5 * g.dx if g.line else 0.25 * math.sqrt(g.dx * g.dy) * 2 * math.sqrt(math.pi * fine.area)
    return 0.0


@dataclass
class ErrorEstimate:
    """The estimate of a run: ``quantities`` (name -> QuantityEstimate), the grids' cell counts
    (``grids``: (nx, ny) fine first), its wall time (s) and, where it could not be made, ``failed`` (why)."""

    quantities: dict[str, QuantityEstimate] = field(default_factory=dict)
    grids: list[tuple[int, int]] = field(default_factory=list)
    wall_s: float = 0.0
    failed: str | None = None


def estimate_error(scene: Scene, fine: StepRecord, comm: MPI.Comm = MPI.COMM_WORLD) -> ErrorEstimate:
    """Solve ``scene`` on the 2x (and, where it resolves the contact, 4x) coarser grids to the time of the
    fine run's last record ``fine`` and estimate the error of that record's values (collective). A coarse
    run that fails (its contact at the coarser grid's edge) leaves ``failed`` set, no quantities."""
    began = clock.perf_counter()
    g = scene.grid
    timed = scene.time.mode != "steady" and (scene.time.dt is not None or scene.time.steps_per_cell is not None)
    end = fine.t if timed and fine.t > 0 else None
    factors = [2, 4] if min(check(scene).cells) >= 4 * THIRD_GRID_CELLS else [2]
    names = QUANTITIES + (("delta",) if scene.penetration is None else ())
    values = {name: [v] for name, v in last_values(fine, names).items()}
    shifted = {}
    found = ErrorEstimate(grids=[(g.nx, g.ny)])
    runs = [(2, 0.0)] + ([] if g.line else [(2, 0.5)]) + ([(4, 0.0)] if 4 in factors else [])
    for factor, shift in runs:
        coarse = coarser(scene, factor, end, shift)
        try:
            record = list(Simulation(coarse, comm).steps())[-1]
        except PetrollError as exc:
            found.failed = f"the grid {factor}x coarser ({coarse.grid.nx} x {coarse.grid.ny}) failed: {exc}"
            found.wall_s = clock.perf_counter() - began
            return found
        found.grids.append((coarse.grid.nx, coarse.grid.ny))
        for name, v in last_values(record, names).items():
            (shifted.__setitem__(name, v) if shift else values[name].append(v))
    for name in names:
        found.quantities[name] = richardson(tuple(values[name]), KNOWN_ORDER[name], _floor(scene, fine, name),
                                            shifted.get(name))
    found.wall_s = comm.allreduce(clock.perf_counter() - began, op=MPI.MAX)
    return found


def as_attributes(found: ErrorEstimate) -> tuple[dict[str, dict], dict]:
    """(per quantity: value, extrapolated, error, order, observed, coarse; the group's attributes):
    what results.h5's group error_estimate holds (docs/results.md)."""
    per = {name: {"value": q.value, "extrapolated": q.extrapolated, "error": q.error, "order": q.order,
                  "observed_order": q.observed, "coarse": np.array(q.coarse)}
           for name, q in found.quantities.items()}
    attrs = {"grids": np.array(found.grids), "wall_s": found.wall_s, "failed": found.failed or ""}
    return per, attrs
