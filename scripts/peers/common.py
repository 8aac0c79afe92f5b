"""What every peer script of ``petroll bench peers`` shares: the problem file, the command line, the
tolerance search and the timing. Imports no petroll (the peers' scripts run in .venv-peers); a script runs
with its own folder first on sys.path, so ``import common`` finds this file.

    python solve_<name>.py PROBLEM.npz START PRESSURE.npy TOL [TOL ...] [--reference REF.npy --target T]

PROBLEM.npz (written by petroll.bench.peers.write_problem): ``heights`` (N x N, m, the rigid body's
height above its lowest point at the cell centres, index [i, j] the cell at x_i, y_j), ``cell`` (its side,
m; the grid is N cells wide, centred on 0), ``compliance`` (J = (1 - nu^2) / E, 1/Pa), ``load`` (N: every
solver holds the force), ``radius`` (m, petroll's radius hint), ``delta`` and ``pressure`` (a penetration,
m, and a pressure, Pa, that scale the problem: for solvers whose criteria are absolute). START: ``zero``
(p = 0, every solver) or ``hertz`` (petroll only: Hertz's pressure for the radius).

Without --reference: solves at TOL, saves the pressure (Pa), solves again from the same start in the same
process, timed (warm: imports, kernels and plans ready), and prints one JSON line (``warm_s``,
``iterations``: the solver's own count of its work). With --reference: solves at each TOL in turn, loosest
first, until the pressure lies within T (relative L2) of REF; saves that one and prints its ``tol`` and
``difference`` (a search: nothing timed).
"""

import json
import sys
import time

import numpy as np


def main(prepare) -> None:
    """Run a peer: ``prepare(problem, start)`` returns ``solve(tol)`` -> (pressure (N, N) in Pa, count)."""
    args = sys.argv[1:]
    reference = target = None
    if "--reference" in args:
        at = args.index("--reference")
        reference, target = np.load(args[at + 1]), float(args[at + 3])
        args = args[:at]
    problem_path, start, out, *tolerances = args
    problem = {key: value for key, value in np.load(problem_path).items()}
    solve = prepare(problem, start)
    if reference is None:
        tol = float(tolerances[0])
        pressure, count = solve(tol)
        np.save(out, pressure)
        began = time.perf_counter()
        solve(tol)
        print(json.dumps({"warm_s": time.perf_counter() - began, "iterations": count,
                          "force_error": float(pressure.sum() * problem["cell"] ** 2 / problem["load"] - 1)}))
        return
    scale = np.linalg.norm(reference)
    for tol in map(float, tolerances):
        pressure, count = solve(tol)
        difference = float(np.linalg.norm(pressure - reference) / scale)
        if difference <= target:
            break
    np.save(out, pressure)
    print(json.dumps({"tol": tol, "difference": difference, "iterations": count}))


def zero_start(problem, start, name: str) -> tuple[np.ndarray, int, float, float]:
    """For a peer that starts from zero only (START ``hertz`` refused, naming the peer): the problem's
    heights, N, cell side (m) and grid side N x cell (m)."""
    if start != "zero":
        raise SystemExit(f"{name}: start {start!r}: only zero")
    heights = problem["heights"]
    n, cell = heights.shape[0], float(problem["cell"])
    return heights, n, cell, n * cell


def centres(problem) -> np.ndarray:
    """The cell centres (m) along either axis: N cells of side ``cell`` centred on 0."""
    n, cell = problem["heights"].shape[0], float(problem["cell"])
    return (np.arange(n) + 0.5) * cell - n * cell / 2
