"""Peer script for ``petroll bench peers``: Tamaas (``PolonskyKeerRey`` on its non-periodic ``dcfft``
operator, load control: the mean pressure over the domain held), run with the Python of .venv-peers
(benchmark-only: it needs numpy 2, which must not enter petroll's environment). Imports no petroll.
Command line and problem file: common.py; START ``zero``: the traction and displacement fields zeroed
before every solve. Tamaas's surface is the indenter's height, highest = first contact (-heights); its
E* = E / (1 - nu^2) is 1 / compliance (E = E*, nu = 0). No count: its Python interface does not report its
iterations."""

import numpy as np
import tamaas as tm

from common import main, zero_start


def prepare(problem, start):
    heights, n, _, side = zero_start(problem, start, "tamaas")
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [side, side], [n, n])
    model.E, model.nu = 1.0 / float(problem["compliance"]), 0.0
    tm.ModelFactory.registerNonPeriodic(model, "dcfft")
    surface = -np.ascontiguousarray(heights)
    mean = float(problem["load"]) / side**2

    def solve(tol):
        model.traction[...] = 0.0
        model.displacement[...] = 0.0
        solver = tm.PolonskyKeerRey(model, surface, tol)
        solver.setIntegralOperator("dcfft")
        solver.max_iter = 100000
        solver.solve(mean)
        return np.array(model.traction), None

    return solve


if __name__ == "__main__":
    main(prepare)
