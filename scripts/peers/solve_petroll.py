"""Peer script for ``petroll bench peers``: petroll itself (``pk``, one rank, its FFTs on the machine's
cores), load control (``ContactSolver.solve_load``: the force held inside the QP). Command line and problem
file: common.py. START ``zero``: the QP from p = 0 (pk then spreads the load uniformly over its QP window, the
interference's box at a penetration guessed from the radius); ``hertz``: from Hertz's pressure for the radius,
centred on the interference's centroid (petroll's cold start for smooth bodies). The count is the operator
applications."""

import numpy as np

from common import main


def prepare(problem, start):
    from petroll.model.grid import Grid
    from petroll.solver.contact import ContactSolver  # petroll.solver first: it sets how MPI starts

    from mpi4py import MPI

    heights = problem["heights"]
    n, cell = heights.shape[0], float(problem["cell"])
    half = n * cell / 2
    solver = ContactSolver(Grid(n, n, -half, half, -half, half), MPI.COMM_SELF, tao_type="pk")
    compliance, load, radius = (float(problem[k]) for k in ("compliance", "load", "radius"))

    def solve(tol):
        solver.tol = tol
        warm = np.zeros_like(heights) if start == "zero" else None
        step = solver.solve_load(heights, compliance, load, radius, None, warm)
        return step.pressure, step.applications

    return solve


if __name__ == "__main__":
    main(prepare)
