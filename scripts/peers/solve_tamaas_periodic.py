"""Peer script for ``petroll bench periodic``: elastic contact of a periodic rough surface solved by Tamaas.

Run with the Python of the benchmark-only environment ``.venv-peers`` (Tamaas needs numpy 2); imports no
petroll. Prints one JSON line.

    python solve_tamaas_periodic.py HEIGHTS.npy LENGTH E NU MEAN_PRESSURE TOL PRESSURE.npy

HEIGHTS: n x n heights (m) of the body's surface above its lowest point, axis 0 along x, the samples of
one L x L periodic cell (LENGTH, m). Load control at the mean pressure (Pa) by ``PolonskyKeerRey`` with
Tamaas's default operator of a ``basic_2d`` model, its periodic spectral Boussinesq kernel 2 / (E* |q|)
(E* = E / (1 - nu^2)); the pressure (Pa) saved as an n x n array. The solve is timed (warm: the model
built, the process started).
"""

import json
import sys
import time

import numpy as np
import tamaas as tm


def main() -> None:
    heights = np.load(sys.argv[1])
    length, E, nu, mean, tol = map(float, sys.argv[2:7])
    n = heights.shape[0]
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [length, length], [n, n])
    model.E, model.nu = E, nu
    solver = tm.PolonskyKeerRey(model, np.ascontiguousarray(-heights), tol)  # Tamaas: the highest touches
    solver.max_iter = 100000
    start = time.perf_counter()
    solver.solve(mean)
    seconds = time.perf_counter() - start
    np.save(sys.argv[7], np.array(model.traction))
    print(json.dumps({"cells": n, "warm_s": seconds, "version": tm.__version__}))


if __name__ == "__main__":
    main()
