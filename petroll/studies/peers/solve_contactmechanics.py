"""Peer script for ``petroll bench peers``: the elastic Hertz step solved by ContactMechanics.

Run by the benchmark with the Python of ``.venv-peers`` (which also holds Tamaas; benchmark-only, it needs
numpy 2, which must not enter petroll's own environment). Imports no petroll. Like every peer script
(solve_petroll.py): a fresh process (its whole run is the cold time the benchmark measures) solves once
from p = 0 and saves the pressure, then solves again from p = 0 in the same process, timed here (warm).
Prints one JSON line.

    python solve_contactmechanics.py CELLS TOL R E NU DELTA WIDTH_IN_A PRESSURE.npy

Problem and conventions as in solve_petroll.py: N x N cells of side dx = WIDTH * a / N centred on the
sphere, heights at the cell centres, load control at the Hertz force. ``FreeFFTElasticHalfSpace`` takes
the contact modulus E* = E / (1 - nu^2) and the physical size of the N x N surface, and pads to 2N x 2N
itself (non-periodic, Hockney); its Green's function is that of a uniform pressure on each cell, as
petroll's and Tamaas's. ``constrained_conjugate_gradients`` (Polonsky & Keer) works in forces per cell (N,
negative = compressive); ``external_force`` (N) gives load control, its result ``jac`` is the compressive
force per cell, divided here by dx^2 to get Pa.

Tolerance: ContactMechanics has absolute criteria, set from the relative ``TOL``: penetration and
displacement change (``pentol``) TOL * delta in m, as petroll's gap residual (relative to the largest
interference, delta); tensile force outside contact (``forcetol``) TOL * p0 * dx^2 in N; relative change
of the rigid body's position between iterations (``thermotol``) TOL.
"""

import importlib.metadata
import json
import math
import sys
import time

import numpy as np
from ContactMechanics import FreeFFTElasticHalfSpace
from ContactMechanics.Optimization import constrained_conjugate_gradients
from SurfaceTopography import Topography


def main() -> None:
    n, tol, R, E, nu, delta, width = (int(sys.argv[1]), *map(float, sys.argv[2:8]))
    e_star = E / (1 - nu**2)
    a = math.sqrt(R * delta)
    side = width * a
    dx = side / n
    force = 4 / 3 * e_star * math.sqrt(R) * delta**1.5
    p0 = 2 * e_star / math.pi * math.sqrt(delta / R)
    x = (np.arange(n) + 0.5) * dx - side / 2
    X, Y = np.meshgrid(x, x, indexing="ij")
    # heights of the rigid surface, highest = first contact; the solver enforces u >= heights + offset
    topography = Topography(-(R - np.sqrt(R**2 - X**2 - Y**2)), physical_sizes=(side, side))
    substrate = FreeFFTElasticHalfSpace((n, n), e_star, (side, side))

    def solve() -> np.ndarray:
        result = constrained_conjugate_gradients(substrate, topography, external_force=force,
                                                 pentol=tol * delta, forcetol=tol * p0 * dx**2, thermotol=tol,
                                                 maxiter=100000)
        if not result.success:
            sys.exit(f"ContactMechanics: {result.message}")
        return np.asarray(result.jac) / dx**2  # compressive force per cell (N) -> pressure (Pa)

    p = solve()
    np.save(sys.argv[8], p)
    start = time.perf_counter()
    solve()
    seconds = time.perf_counter() - start
    print(json.dumps({"cells": n, "warm_s": seconds, "force_error": float(p.sum() * dx**2 / force - 1),
                      "version": importlib.metadata.version("ContactMechanics")}))


if __name__ == "__main__":
    main()
