"""A grid sized for a target relative error: ``[grid] target_error`` (docs/accuracy.md#a-target-error).

petroll.model.autogrid sizes such a scene's grid at :data:`PILOT_CELLS` cells per contact half-width (the
pilot grid). The pilot solves it there and on the grids 2x coarser of the error estimate
(petroll.studies.estimate.coarser: the same extent, the body at the same phase of a cell, in 3-D two
alignments averaged), and takes each headline quantity's error at the pilot grid from the two grids with
the integrator's known order k (:func:`petroll.studies.estimate.richardson`, :func:`known_order`):
err(N) = err_pilot (PILOT_CELLS / N)^k, so the cells per half-width are

    N = ceil(PILOT_CELLS (err_pilot / target_error)^(1/k)),

the largest over the quantities, at least GOOD_CELLS (8) and at most 256 (more is refused, naming the N
needed). The run is then the scene sized at N cells per half-width; its text as run (results.h5) is headed
by a comment with the target, N and the pilot's predicted relative errors at N.

The headline quantities (:data:`HEADLINE`) are those the estimate extrapolates of the last step: the
force (under load control the penetration instead: its force is the load), mu_r and the peak pressure; a
quantity whose two grids agree to round-off (mu_r of a symmetric contact) has no error. The area and the
patch edges count cells, and are not sized for.
"""

from __future__ import annotations

import dataclasses
import math

from mpi4py import MPI

from petroll.errors import SceneError
from petroll.model.autogrid import DEFAULT_CELLS
from petroll.model.preflight import GOOD_CELLS, MOST_CELLS
from petroll.model.scene import Scene
from petroll.solver.simulation import Simulation
from petroll.studies.estimate import ROUND_OFF, coarser, end_time, known_order, last_values, richardson

PILOT_CELLS = DEFAULT_CELLS
"""Cells per contact half-width of the pilot grid (the grid petroll.model.autogrid sizes for a target)."""

MOST_TARGET_CELLS = MOST_CELLS // 4
"""The most cells per contact half-width a target may ask for (as ``cells_per_half_width``)."""

HEADLINE = ("force", "delta", "mu_r", "p_max")
"""The quantities whose relative error a target bounds: the force under penetration control, the penetration
``delta`` under load control (whose force is the load), mu_r and the peak pressure."""


def asks_target(scene: Scene) -> bool:
    """Whether ``scene``'s grid is to be chosen for ``[grid] target_error``."""
    return scene.sizing is not None and "target_error" in scene.sizing.request


@dataclasses.dataclass(frozen=True)
class Pilot:
    """The pilot of a target: the relative ``errors`` it estimates at PILOT_CELLS (name -> error), the
    ``orders`` taken (name -> k), and the cells per half-width each quantity needs (``needs``; inf: its
    value is 0 and its error is not, no relative error)."""

    errors: dict[str, float]
    orders: dict[str, float]
    needs: dict[str, float]

    def predicted(self, cells: int) -> dict[str, float]:
        """The relative errors the pilot predicts at ``cells`` per contact half-width."""
        return {name: e * (PILOT_CELLS / cells) ** self.orders[name] for name, e in self.errors.items()}


def pilot(scene: Scene, target: float, comm: MPI.Comm = MPI.COMM_WORLD) -> Pilot:
    """Solve ``scene`` (sized at PILOT_CELLS) and its 2x coarser grids, and estimate each headline
    quantity's relative error and the cells per half-width it needs for ``target`` (collective)."""
    names = ("delta" if scene.penetration is None else "force",) + HEADLINE[2:]
    fine = Simulation(scene, comm).last_step()
    end = end_time(scene, fine)
    shifts = (0.0,) if scene.grid.line else (0.0, 0.5)
    coarse = [last_values(Simulation(coarser(scene, 2, end, s), comm).last_step(), names) for s in shifts]
    orders = known_order(scene)
    errors, needs = {}, {}
    for name, value in last_values(fine, names).items():
        q = richardson(value, tuple(c[name] for c in coarse), None, orders[name],
                       round_off=ROUND_OFF.get(name, 0.0))
        errors[name] = 0.0 if q.error == 0 else q.error / abs(value) if value != 0 else math.inf
        needs[name] = (math.ceil(PILOT_CELLS * (errors[name] / target) ** (1 / orders[name]))
                       if math.isfinite(errors[name]) else math.inf)  # a value of 0 with an error
    return Pilot(errors, {name: orders[name] for name in names}, needs)


def targeted(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD) -> Scene:
    """``scene`` (:func:`asks_target`) on the grid its target error needs: the pilot, then the scene
    sized at that many cells per contact half-width, its text and note saying so (collective). SceneError
    where the target needs more than MOST_TARGET_CELLS."""
    target = scene.sizing.request["target_error"]
    found = pilot(scene, target, comm)
    name = max(found.needs, key=found.needs.get)
    cells = max(GOOD_CELLS, found.needs[name])
    if cells > MOST_TARGET_CELLS:
        raise SceneError(scene.source, "[grid] target_error", target,
                         f"needs {cells} cells per contact half-width (the pilot's relative error of {name} at "
                         f"{PILOT_CELLS}: {found.errors[name]:.3g}, order {found.orders[name]:g}), more than "
                         f"{MOST_TARGET_CELLS}: give a larger target_error, or [grid] nx, ny, x, y")
    sized = scene.replace({"grid.target_error": None, "grid.cells_per_half_width": cells})
    predicted = ", ".join(f"{n} {e:.2g}" for n, e in found.predicted(cells).items())
    said = (f"target_error = {target:g}: {cells} cells per contact half-width, predicted relative errors "
            f"{predicted} (a pilot at {PILOT_CELLS} and {PILOT_CELLS // 2})")
    choice = dataclasses.replace(sized.sizing, note=f"{sized.sizing.note}; {said}")
    return dataclasses.replace(sized, text=f"# [grid] {said}\n{sized.text}", sizing=choice,
                               output_dir=scene.output_dir)  # (replace forgets a scene file's default)
