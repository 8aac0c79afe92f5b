"""The discretisation error of a run's answer: the scene solved again on grids 2x (and 4x) coarser, and
Richardson extrapolation (``petroll run --estimate-error``, ``petroll.run(scene, estimate_error=True)``;
docs/accuracy.md).

The coarser grids cover the scene's extent with cells 2x (4x) as long along each axis, shifted so that the
body starts at the same fraction of a cell from a cell centre as on the fine grid; in 3-D the 2x grid is
solved twice, the second time shifted by half its cell along X and Y, and the two are averaged (a 3-D
answer depends on where the contact's edges fall in their cells: one coarse alignment alone can happen to
agree with the fine grid, or not). Where the scene's steps follow the cell (``steps_per_cell``, and the
steady solve's time step) the step grows with the cell, a fixed ``dt`` stays. They run to the fine run's
last time without the steady stop, so that all grids compare the same instant, and are diagnosed (force,
mu_r ...) at that last step only (:meth:`Simulation.last_step`). For each quantity q of the
last step, with f1 its fine value, f2 the 2x grids' (mean; s half their spread) and f4 the 4x grid's:

- d1 = f2 - f1, d2 = f4 - f2. Where the 4x grid was solved (it keeps at least ``THIRD_GRID_CELLS`` cells
  per contact half-width; in line contact ``SIGN_CELLS``), |d1| exceeds s (else d1 is the alignments'
  noise, and so would be its order: the known order is taken) and d2 does not have d1's sign and a larger
  size, the grids are not in the asymptotic range: no error and no extrapolated value (nan), rather than a
  false bound;
- the order p: observed, log2(d2 / d1), where the 4x grid resolves the contact (``THIRD_GRID_CELLS``) and
  that lies within a factor 2 of the method's known order (:func:`known_order`: 1 for the "paper"
  integrator where the step follows the cell (its peak pressure 1.5), else 2; else not asymptotic);
  otherwise the known order;
- extrapolated = f1 - d1 / (2^p - 1); the error of f1 is (|d1| + s) / (2^q - 1) with q = min(p, the known
  order) (an observed order above the known one does not shrink the bound).

A quantity whose asymptotic range no 4x grid checked (none solved: in 3-D below 16 cells per contact
half-width; or |d1| within s) has its error from the known order alone: it is marked (``checked`` False),
and so is the estimate (:attr:`ErrorEstimate.range_checked`; results.h5, the printed lines).

What counts cells (the area, the patch edges lead and trail) moves by whole cells, not by a power of the
cell: it is not extrapolated, and its error is the larger of its 2x grids' difference and its quantisation
(:func:`quantised`, :func:`_floor`).

A steady sliding solve's mu_r is the material's dissipated power over F V, and the lateral force's
coefficient (petroll.records.lateral_friction) is the same quantity discretised otherwise: their
difference on the fine grid, |mu_r - mu_lateral|, is added to mu_r's error (``lateral``; an error of
nan stays nan): the two converge to each other, and a grid on which they differ has not resolved mu_r to
better than that difference, whatever the coarser grids say.
"""

from __future__ import annotations

import dataclasses
import math
import time as clock
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from petroll.errors import PetrollError
from petroll.model.clock import TimeMode
from petroll.model.preflight import Preflight, check
from petroll.model.scene import Scene
from petroll.records import StepRecord, lateral_friction
from petroll.solver.simulation import Simulation

QUANTITIES = ("force", "mu_r", "p_max", "area", "lead", "trail")
"""The last step's values an estimate covers (plus the penetration ``delta`` under load control)."""

SPACE_ORDER = 2.0
"""The order in the cell size of the force, the penetration, mu_r and the peak pressure with the time step
held (the integrals and values of the piecewise-constant pressure on Love's rectangles)."""

KNOWN_ORDER = {
    "relaxation": {"force": 2.0, "delta": 2.0, "mu_r": 2.0, "p_max": 2.0},
    "exponential": {"force": 2.0, "delta": 2.0, "mu_r": 2.0, "p_max": 2.0},
    "paper": {"force": 1.0, "delta": 1.0, "mu_r": 1.0, "p_max": 1.5},
}
"""Each time integrator's order in the cell size, the cell and the step refined together ([solver]
integrator; "paper" is also the hereditary sum of a tabulated material), per quantity, measured by
``petroll bench accuracy`` (orders.csv, docs/accuracy.md): the second-order integrators 2 (observed 0.6 to
2.7, scattered by where the contact's edges fall in their cells; 1.7 to 2.4 in the step alone); "paper",
first order in its step, 1 (observed 0.9 to 1.3), except the peak pressure, whose observed orders fall
towards 1 only slowly (2.4, 1.5, 1.2 on the roller from 4 to 70 cells per half-width; 1.6, 1.4 on the
sphere): 1.5 keeps its estimate within a factor 3 of the true error over that range, where 1 makes it
3.3 to 3.8 times too large at the shipped grids."""


def known_order(scene: Scene) -> dict[str, float]:
    """The order in the cell size taken for the error of the force, penetration, mu_r and peak pressure
    where it is not observed (name -> order): the integrator's (:data:`KNOWN_ORDER`), at most
    :data:`SPACE_ORDER`, where the coarser grids' steps grow with their cells (``steps_per_cell``; a steady
    solve without ``dt``) and the material has a memory (J0 < Jinf); else the space's, 2 (a fixed ``dt``:
    its time error is the same on every grid, and not estimated; an elastic material: no time error)."""
    t = scene.time
    follows = t.steps_per_cell is not None or (t.mode is TimeMode.STEADY and t.dt is None)
    memory = scene.material.J0 < scene.material.Jinf
    orders = KNOWN_ORDER[scene.solver.integrator]
    return {name: min(SPACE_ORDER, order) if follows and memory else SPACE_ORDER
            for name, order in orders.items()}


ROUND_OFF = {"mu_r": 1e-15}
"""Differences below which a quantity's values agree whatever their size (absolute): mu_r of a symmetric
contact is a sum of terms p dZ/dX that cancel to about 1e-18 of the force, not a number to extrapolate.
Every quantity's differences below 1e-12 of its largest value count as round-off too."""

COUNTED = ("area", "lead", "trail")
"""What counts cells (the contact area, the patch edges): a value that moves by whole cells, not by a
power of the cell; :func:`quantised`."""

THIRD_GRID_CELLS = 4.0
"""Cells per contact half-width the 4x coarser grid must keep for the order observed on it to be used."""

SIGN_CELLS = 2.0
"""In line contact, cells per contact half-width the 4x coarser grid must keep to be solved at all (below,
the run itself would be refused); from here to THIRD_GRID_CELLS it checks the asymptotic range only (its
order misleads). In 3-D such a grid is not solved: where the contact's edges cross its cells along two axes
its values scatter with the alignment more than they trend (on the sphere as a height map at 3 cells per
half-width its mu_r has the other sign of error than the 2x grids', whose estimate is within 1.3 of the
true error)."""


@dataclass(frozen=True)
class QuantityEstimate:
    """One quantity's estimate: the fine ``value``, the ``extrapolated`` one, the estimated ``error`` of
    the fine value (>= 0; nan: not in the asymptotic range), the ``order`` used (observed on three grids or
    the known one), whether it was ``observed``, the coarser grids' values (``coarse``), and whether the
    asymptotic range was ``checked`` (False: the error rests on the known order alone, no 4x grid having
    compared its difference; True also where there is nothing to check: values that agree to round-off,
    what counts cells); ``lateral``: the part of the error that is the fine grid's |mu_r - mu_lateral| (a
    steady sliding solve's mu_r; else 0)."""

    value: float
    extrapolated: float
    error: float
    order: float
    observed: bool
    coarse: tuple[float, ...]
    checked: bool = True
    lateral: float = 0.0

    @property
    def asymptotic(self) -> bool:
        return not math.isnan(self.error)


def richardson(fine: float, twice: tuple[float, ...], four: float | None, known: float,
               observe: bool = True, round_off: float = 0.0) -> QuantityEstimate:
    """The estimate from a quantity's ``fine`` value, its values on the 2x coarser grid (``twice``: one, or
    two alignments: their mean is extrapolated, half their spread added to the error) and on the 4x grid
    (``four``; None: not solved); ``known``: the method's order; ``observe``: the order is observed on the
    4x grid (else that grid checks the asymptotic range only); ``round_off``: differences below it are none
    (:data:`ROUND_OFF`). See the module's text."""
    coarse = tuple(twice) + (() if four is None else (four,))
    scale = max(1e-12 * max(abs(v) for v in (fine,) + coarse), round_off)  # differences below: none
    f2 = float(np.mean(twice))
    spread = 0.5 * (max(twice) - min(twice)) if max(twice) - min(twice) > scale else 0.0
    d1 = f2 - fine if abs(f2 - fine) > scale else 0.0
    checked = four is not None and abs(d1) > spread  # a difference within the alignments' spread: noise
    observed = checked and observe
    order = known
    if checked:
        d2 = four - f2 if abs(four - f2) > scale else 0.0
        if not (d1 * d2 > 0 and abs(d2) > abs(d1)):
            return QuantityEstimate(fine, math.nan, math.nan, math.nan, observed, coarse)
        if observe:
            order = math.log2(d2 / d1)
            if not known / 2 <= order <= 2 * known:
                return QuantityEstimate(fine, math.nan, math.nan, order, True, coarse)
    trusted = min(order, known)
    extrapolated = fine - d1 / (2**order - 1)
    return QuantityEstimate(fine, extrapolated, (abs(d1) + spread) / (2**trusted - 1), order,
                            observed, coarse, checked or d1 == spread == 0)


def quantised(fine: float, twice: tuple[float, ...], floor: float) -> QuantityEstimate:
    """The estimate of what counts cells (:data:`COUNTED`): not extrapolated (its value jumps by cells),
    its error the larger of the 2x grids' farthest difference from ``fine`` and its quantisation
    ``floor``; order 1 (the cell's size)."""
    error = max(max(abs(v - fine) for v in twice), floor)
    return QuantityEstimate(fine, fine, error, 1.0, False, tuple(twice))


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
    cells along each axis. In line contact the grid is not shifted: its length is the penetration's datum.
    The solver's tolerance is :func:`coarse_tol`."""
    g, (sx, sy) = scene.grid, scene.position
    if g.line:  # the grid's length is the datum of the penetration (line-contact.md): kept, not shifted
        nx = math.ceil(g.nx / factor)  # (grown by less than a coarse cell where nx is not a multiple)
        x = [g.x0, g.x0 + nx * factor * g.dx]
    else:
        nx, x = _aligned(g.x0, g.x1, g.dx, g.nx, factor, sx, shift)
    steady = scene.time.mode is TimeMode.STEADY
    changes = {"grid.nx": nx, "grid.x": x, "solver.tol": coarse_tol(scene.solver.tol, steady)}
    if not g.line:
        ny, y = _aligned(g.y0, g.y1, g.dy, g.ny, factor, sy, shift)
        changes.update({"grid.ny": ny, "grid.y": y})
    if end is not None and scene.time.mode is not TimeMode.STEADY:
        changes.update({"time.steady": None, "time.distance": None, "time.end": end})
    return scene.replace(changes)


def coarse_tol(tol: float, steady: bool = False) -> float:
    """The coarser grids' solver tolerance: 1000 times the scene's ``tol``, but no looser than 1e-5 unless
    the scene's own is, for a transient; the scene's own for a steady solve (``steady``: [time] mode =
    "steady", whose fixed point stops at that tolerance too: a looser one moved the coarser grids' peak
    pressure by up to 23 % of their differences from the fine grid on runs/master-curve.toml, and saves
    nothing there). On the transients of ``petroll bench estimate`` the coarser grids' differences from the
    fine grid are 1e-4 to 1e-2 of the values; against solves to 1e-7, solves to 1e-5 move the coarser
    grids' force, mu_r, peak pressure and penetration by at most 1 % of those differences (1e-6: 0.7 %),
    with 14 % fewer operator applications than 1e-6 (docs/benchmarks.md)."""
    return tol if steady else max(tol, min(1000 * tol, 1e-5))


def end_time(scene: Scene, record: StepRecord) -> float | None:
    """The time (s) the coarser grids run to: that of ``record``, where the scene keeps a clock (its steps
    follow the cell or ``dt``) and has taken a step; None for a scene of one step or a steady solve."""
    clocked = scene.time.dt is not None or scene.time.steps_per_cell is not None
    timed = scene.time.mode is not TimeMode.STEADY and clocked
    return record.t if timed and record.t > 0 else None


def last_values(record: StepRecord, quantities: tuple[str, ...]) -> dict[str, float]:
    return {name: float(getattr(record, name)) for name in quantities}


def _floor(scene: Scene, fine: StepRecord, name: str) -> float:
    """The least error of a quantity that counts cells (m, m^2): half a cell along the motion for the patch
    edges (the most a cell edge is off an edge inside its cell), a quarter of a cell times the contact's
    perimeter for its area (the mean offset of edges that fall anywhere in their cells, over the perimeter:
    line contact its two edges, 3-D that of a disc of that area); 0 for the others."""
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
    (``grids``: (nx, ny) fine first), its wall time (s), where it could not be made ``failed`` (why), the
    ``integrator`` and the ``orders`` it takes where none is observed (:func:`known_order`), and why no 4x
    grid checked the asymptotic range (``unchecked``; "" where one was solved)."""

    quantities: dict[str, QuantityEstimate] = field(default_factory=dict)
    grids: list[tuple[int, int]] = field(default_factory=list)
    wall_s: float = 0.0
    failed: str | None = None
    integrator: str = ""
    orders: dict[str, float] = field(default_factory=dict)
    unchecked: str = ""

    @property
    def range_checked(self) -> bool:
        """Every quantity's asymptotic range was checked (:attr:`QuantityEstimate.checked`)."""
        return bool(self.quantities) and all(q.checked for q in self.quantities.values())


def estimate_error(scene: Scene, fine: StepRecord, comm: MPI.Comm = MPI.COMM_WORLD,
                   preflight: Preflight | None = None, after_step=None) -> ErrorEstimate:
    """Solve ``scene`` on the 2x (and, where it still has THIRD_GRID_CELLS cells per contact half-width,
    in line contact SIGN_CELLS, 4x) coarser grids to the time of the fine run's last record ``fine`` and
    estimate the error of that record's values (collective). ``preflight``: the scene's checks
    (:func:`petroll.model.preflight.check`) where the run made them (else made here). A 2x run that fails
    (its contact at the coarser grid's edge) leaves ``failed`` set and no quantities; a 4x run that fails
    is left out. ``after_step()``: called on every rank after each step of the coarser runs
    (Simulation.last_step), e.g. to stop on a signal by raising (the exception goes through)."""
    began = clock.perf_counter()
    g = scene.grid
    end = end_time(scene, fine)
    cells = min((preflight or check(scene)).cells) / 4  # on the 4x grid
    names = QUANTITIES + (("delta",) if scene.penetration is None else ())
    orders = known_order(scene)
    found = ErrorEstimate(grids=[(g.nx, g.ny)], integrator=scene.solver.integrator, orders=orders)
    solved: dict[tuple[int, float], dict[str, float]] = {}
    least = SIGN_CELLS if g.line else THIRD_GRID_CELLS
    fourth = cells >= least
    if not fourth:
        found.unchecked = (f"no grid 4x coarser: it would keep {cells:.1f} cells per contact half-width, "
                           f"{least:g} needed")
    runs = [(2, 0.0)] + ([] if g.line else [(2, 0.5)]) + ([(4, 0.0)] if fourth else [])
    for factor, shift in runs:
        coarse = coarser(scene, factor, end, shift)
        try:
            record = Simulation(coarse, comm).last_step(after_step)  # diagnosed at the last step only
        except PetrollError as exc:
            if factor == 4:
                found.unchecked = f"the grid 4x coarser ({coarse.grid.nx} x {coarse.grid.ny}) failed: {exc}"
                break
            found.failed = f"the grid {factor}x coarser ({coarse.grid.nx} x {coarse.grid.ny}) failed: {exc}"
            found.wall_s = comm.allreduce(clock.perf_counter() - began, op=MPI.MAX)
            return found
        found.grids.append((coarse.grid.nx, coarse.grid.ny))
        solved[factor, shift] = last_values(record, names)
    for name, value in last_values(fine, names).items():
        twice = tuple(v[name] for (factor, _), v in solved.items() if factor == 2)
        four = solved[4, 0.0][name] if (4, 0.0) in solved else None
        found.quantities[name] = (
            quantised(value, twice, _floor(scene, fine, name)) if name in COUNTED else
            richardson(value, twice, four, orders[name], observe=cells >= THIRD_GRID_CELLS,
                       round_off=ROUND_OFF.get(name, 0.0)))
    if scene.time.mode is TimeMode.STEADY and g.topology.whole:
        found.quantities["mu_r"] = with_lateral(found.quantities["mu_r"], fine, scene)
    found.wall_s = comm.allreduce(clock.perf_counter() - began, op=MPI.MAX)
    return found


def with_lateral(estimate: QuantityEstimate, fine: StepRecord, scene: Scene) -> QuantityEstimate:
    """A steady sliding solve's mu_r ``estimate`` with the fine record's |mu_r - mu_lateral| added to its
    error (the module's text)."""
    velocity = np.asarray(scene.velocity(0.0), dtype=float)
    lateral = abs(fine.mu_r - lateral_friction(fine, velocity / np.hypot(*velocity)))
    return dataclasses.replace(estimate, error=estimate.error + lateral, lateral=lateral)


def as_attributes(found: ErrorEstimate) -> tuple[dict[str, dict], dict]:
    """(per quantity: value, extrapolated, error, order, observed, coarse, range_checked, known_order (what
    counts cells: 1), and mu_r's lateral_difference (QuantityEstimate.lateral); the group's attributes):
    what results.h5's group error_estimate holds (docs/results.md)."""
    per = {name: {"value": q.value, "extrapolated": q.extrapolated, "error": q.error, "order": q.order,
                  "observed_order": q.observed, "coarse": np.array(q.coarse), "range_checked": q.checked,
                  "known_order": found.orders.get(name, 1.0)}
           | ({"lateral_difference": q.lateral} if name == "mu_r" else {})
           for name, q in found.quantities.items()}
    attrs = {"grids": np.array(found.grids), "wall_s": found.wall_s, "failed": found.failed or "",
             "integrator": found.integrator, "range_checked": found.range_checked,
             "range_unchecked": found.unchecked}
    return per, attrs
