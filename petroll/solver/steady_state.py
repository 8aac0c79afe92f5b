"""A steady state solved directly ([time] mode = "steady"): the protocol every such solve implements, so that
the time loop (petroll.solver.simulation) runs any of them as its one step without knowing which.

- rolling on a grid with edges (petroll.solver.steady.SteadySolve): the fixed point over elastic QPs in
  the body's frame, its memory along the motion;
- sliding where the contact QP covers the whole grid, a grid that repeats along the motion
  (petroll.solver.sliding.SteadySliding): the complex operator of the integrator's transfer function;
- next, the tangential steady state of friction (petroll.solver.steady_friction), once a scene can ask
  for it.

Each is made for one scene, with the scene's contact solver (its grid rows, operator and TAO objects), the
fixed point's tolerance ``tol`` and ``steady`` (a stop once the forces agree to it; None: none), and
collective over the solver's comm.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from petroll.solver.contact import ContactSolver, StepSolution
from petroll.solver.sliding import SteadySliding
from petroll.solver.steady import SteadySolve


class SteadyState(Protocol):
    """What the time loop needs of a steady solve."""

    iterations: int
    """The fixed point's iterations of the last :meth:`solve`."""
    velocity: np.ndarray
    """The body's constant velocity (m/s, [vx, vy])."""
    direction: np.ndarray
    """Its direction (a unit vector)."""
    speed: float
    """Its magnitude (m/s)."""
    profile: np.ndarray
    """The body's heights Z (m) on this rank's grid rows, the body at [body] position."""

    def solve(self, start: tuple[np.ndarray, float | None] | None = None,
              max_iterations: int = 500) -> tuple[StepSolution, np.ndarray]:
        """The steady state from the first guess ``start`` (a pressure, Pa, on the whole grid or this
        rank's rows, and its penetration, m, or None): the last contact QP's solution, whose pressure is
        the steady state's on this rank's rows, and the surface displacement w (m, this rank's rows).
        SolverError after ``max_iterations`` iterations."""
        ...

    def dissipated(self, pressure: np.ndarray) -> float | None:
        """The power (W) the material dissipates under the steady ``pressure`` (this rank's rows) from its
        own response, the run's resisting force being that power over the speed (sliding); None where
        the resisting force is the pressure's on the body's slope (rolling). Collective."""
        ...


def steady_state(scene, solver: ContactSolver, tol: float, steady: float | None = None) -> SteadyState:
    """The steady solve of ``scene`` on its grid: sliding where the contact QP covers the whole grid
    (petroll.model.topology: a grid that repeats), rolling elsewhere."""
    kind = SteadySliding if scene.grid.topology.whole else SteadySolve
    return kind(scene, solver, tol, steady)
