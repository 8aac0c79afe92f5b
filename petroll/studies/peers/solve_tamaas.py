"""Peer script for ``petroll bench peers``: the elastic Hertz step solved by Tamaas.

Run by the benchmark with the Python of a separate virtual environment holding the ``tamaas`` wheel
(benchmark-only: it needs numpy 2, which must not enter petroll's own environment). Imports no petroll.
Like every peer script (solve_petroll.py): a fresh process (its whole run is the cold time the benchmark
measures) solves once from p = 0 and saves the pressure, then solves again from p = 0 in the same process,
timed here (warm: imports, model and FFT plans ready). Prints one JSON line.

    python solve_tamaas.py CELLS TOL R E NU DELTA WIDTH_IN_A PRESSURE.npy

Problem and conventions as in solve_petroll.py: N x N cells of side WIDTH * a / N centred on the sphere,
heights at the cell centres, load control at the Hertz force (Tamaas: mean pressure over the domain),
``PolonskyKeerRey`` on the non-periodic ``dcfft`` operator; the pressure (Pa) saved as an N x N array.
"""

import json
import math
import sys
import time

import numpy as np
import tamaas as tm


def main() -> None:
    n, tol, R, E, nu, delta, width = (int(sys.argv[1]), *map(float, sys.argv[2:8]))
    e_star = E / (1 - nu**2)
    a = math.sqrt(R * delta)
    side = width * a
    force = 4 / 3 * e_star * math.sqrt(R) * delta**1.5
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [side, side], [n, n])
    model.E, model.nu = E, nu
    tm.ModelFactory.registerNonPeriodic(model, "dcfft")
    x = (np.arange(n) + 0.5) * side / n - side / 2
    X, Y = np.meshgrid(x, x, indexing="ij")
    surface = -(R - np.sqrt(R**2 - X**2 - Y**2))  # Tamaas: heights of the indenter, highest = first contact

    def solve() -> tuple[np.ndarray, int]:
        model.traction[...] = 0.0  # from p = 0, as the first solve
        model.displacement[...] = 0.0
        solver = tm.PolonskyKeerRey(model, surface, tol)
        solver.setIntegralOperator("dcfft")
        solver.max_iter = 100000
        solver.solve(force / side**2)
        return np.array(model.traction)

    p = solve()
    np.save(sys.argv[8], p)
    start = time.perf_counter()
    solve()
    seconds = time.perf_counter() - start
    print(json.dumps({"cells": n, "warm_s": seconds, "force_error": float(p.sum() * (side / n) ** 2 / force - 1),
                      "version": tm.__version__}))


if __name__ == "__main__":
    main()
