"""Peer script for ``petroll bench peers``: ContactMechanics (``constrained_conjugate_gradients``, Polonsky
& Keer, on a ``FreeFFTElasticHalfSpace``: non-periodic, padded to 2N x 2N, a uniform pressure per cell),
load control (``external_force``), run with the Python of .venv-peers. Imports no petroll. Command line
and problem file: common.py; START ``zero``: no initial displacements or forces (it spreads the load
uniformly at its first step). Its criteria are absolute, set from the relative TOL with the problem's
scales: penetration and displacement change (``pentol``) TOL x delta (m), tensile force outside contact
(``forcetol``) TOL x pressure x cell^2 (N), relative change of the rigid body's position (``thermotol``)
TOL; its compressive forces per cell (N) are divided by cell^2 to give Pa. The count is its iterations."""

import numpy as np
from ContactMechanics import FreeFFTElasticHalfSpace
from ContactMechanics.Optimization import constrained_conjugate_gradients
from SurfaceTopography import Topography

from common import main, zero_start


def prepare(problem, start):
    heights, n, cell, side = zero_start(problem, start, "contactmechanics")
    topography = Topography(-np.ascontiguousarray(heights), physical_sizes=(side, side))
    substrate = FreeFFTElasticHalfSpace((n, n), 1.0 / float(problem["compliance"]), (side, side))
    load, delta, pressure = (float(problem[k]) for k in ("load", "delta", "pressure"))

    def solve(tol):
        result = constrained_conjugate_gradients(substrate, topography, external_force=load,
                                                 pentol=tol * delta, forcetol=tol * pressure * cell**2,
                                                 thermotol=tol, maxiter=100000)
        if not result.success:
            raise SystemExit(f"ContactMechanics: {result.message}")
        return np.asarray(result.jac) / cell**2, int(result.nit)

    return solve


if __name__ == "__main__":
    main(prepare)
