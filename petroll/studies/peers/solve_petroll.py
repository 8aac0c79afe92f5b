"""Peer script for ``petroll bench peers``: the elastic Hertz step solved by petroll itself (``pk``, one
rank), run like the other peers' scripts: a fresh process (its whole run is the cold time the benchmark
measures), one solve from p = 0 whose pressure is saved, then a second solve from p = 0 in the same
process, timed here (warm: imports, kernels and TAO objects ready). Prints one JSON line.

    python solve_petroll.py CELLS TOL R E NU DELTA WIDTH_IN_A PRESSURE.npy

Problem and conventions as in the other peers' scripts: N x N cells of side WIDTH * a / N centred on the sphere, heights
at the cell centres, load control at the Hertz force; the pressure (Pa) saved as an N x N array, index
[i, j] the cell at x_i, y_j.
"""

import json
import math
import sys
import time

import numpy as np


def main() -> None:
    n, tol, R, E, nu, delta, width = (int(sys.argv[1]), *map(float, sys.argv[2:8]))
    from mpi4py import MPI

    from petroll.model.bodies import Sphere
    from petroll.model.grid import Grid
    from petroll.solver.contact import ContactSolver

    J = (1 - nu**2) / E
    a = math.sqrt(R * delta)
    force = 4 * math.sqrt(R) * delta**1.5 / (3 * J)
    grid = Grid(n, n, -width * a / 2, width * a / 2, -width * a / 2, width * a / 2)
    solver = ContactSolver(grid, MPI.COMM_SELF, tao_type="pk", tol=tol)
    height = Sphere(R).height(grid.x[:, None], grid.y[None, :])
    step = solver.solve_load(height, J, force, R)
    np.save(sys.argv[8], step.pressure)
    start = time.perf_counter()
    again = solver.solve_load(height, J, force, R)
    seconds = time.perf_counter() - start
    print(json.dumps({"cells": n, "warm_s": seconds, "force_error": step.force / force - 1,
                      "applications": step.applications, "warm_applications": again.applications}))


if __name__ == "__main__":
    main()
