"""Standalone peer script for ``petroll bench peers``: the elastic Hertz step solved by Tamaas.

Run by the benchmark with the Python of a separate virtual environment holding the ``tamaas`` wheel
(benchmark-only: it needs numpy 2, which must not enter petroll's own environment). Imports no petroll.
Prints one JSON line: cells, seconds, force error, max pressure error / p0.

    python tamaas.py CELLS TOL R E NU DELTA WIDTH_IN_A
"""

import json
import math
import sys
import time

import numpy as np
import tamaas as tm


def main() -> None:
    n, tol, R, E, nu, delta, width = (int(sys.argv[1]), *map(float, sys.argv[2:]))
    e_star = E / (1 - nu**2)
    a = math.sqrt(R * delta)
    side = width * a
    force = 4 / 3 * e_star * math.sqrt(R) * delta**1.5
    p0 = 2 * e_star / math.pi * math.sqrt(delta / R)
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [side, side], [n, n])
    model.E, model.nu = E, nu
    tm.ModelFactory.registerNonPeriodic(model, "dcfft")
    x = (np.arange(n) + 0.5) * side / n - side / 2
    X, Y = np.meshgrid(x, x, indexing="ij")
    surface = -(R - np.sqrt(R**2 - X**2 - Y**2))  # Tamaas: heights of the indenter, highest = first contact
    solver = tm.PolonskyKeerRey(model, surface, tol)
    solver.setIntegralOperator("dcfft")
    solver.max_iter = 10000
    start = time.perf_counter()
    solver.solve(force / side**2)  # load control: mean pressure over the domain
    seconds = time.perf_counter() - start
    p = np.array(model.traction)
    hertz = p0 * np.sqrt(np.clip(1 - (X**2 + Y**2) / a**2, 0, None))
    print(json.dumps({"cells": n, "seconds": seconds, "force_error": float(p.sum() * (side / n) ** 2 / force - 1),
                      "pressure_error": float(np.abs(p - hertz).max() / p0)}))


if __name__ == "__main__":
    main()
