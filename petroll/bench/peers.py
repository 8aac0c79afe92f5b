"""``petroll bench peers [--out DIR]``: petroll against Tamaas and ContactMechanics on the same work.

Problems (:data:`PROBLEMS`, :func:`write_problem`): an N x N grid of square cells, non-periodic, centred on
the body, its heights above the lowest point at the cell centres (one array, written once, read by every
solver), a uniform pressure per cell in every solver's kernel, an elastic half-space, load control:

- ``hertz``: a sphere R = 10 mm on rubber (E = 10 MPa, nu = 0.5), the load of a 10 um penetration, the grid
  3.2 contact radii wide;
- ``wavy``: a sphere R = 100 with a ripple 0.002 cos(2 pi x / 0.25) cos(2 pi y / 0.25), given as a
  height map (petroll's radius hint is the one a height-map body estimates from it), E* = 1, the grid
  3 x 3 (non-periodic: the ripple does not repeat across its edges), the load 0.0115, the force of a 0.01
  penetration: about 124 contact islands at 512^2 (no start is privileged).

Every solver runs through its script (``scripts/peers/solve_<name>.py`` of a petroll checkout, beside
petroll/: petroll's with this Python, the peers' with .venv-peers'; common.py), from the same start: p = 0 (``zero``). petroll's cold start for smooth bodies,
Hertz's pressure for the radius (``hertz``), is a row of its own. Convergence: a reference solved by
petroll to tol 1e-12 on each grid; each solver and start at the loosest of :data:`TOLERANCES` whose
pressure lies within ``target`` (relative L2) of it, searched in one process; petroll from zero is held
to the smallest error any peer reached as well (so its answer is never the less accurate one). Every
answer's ``residual`` is computed here alike (:func:`residual`). Times: ``cold_s`` the whole process up to
its first answer (interpreter, imports, set-up, first solve: the process's wall time, timed here, less
the second solve), ``warm_s`` the second solve in that process (from the same start), timed by the script; medians of ``repeats`` runs; ratios petroll (zero) / solver (< 1: petroll faster).
The user's path is a row of its own (start ``scene``): the problem written as a scene
(:func:`write_scene`: the Hertz sphere as the analytic body, the wavy sphere as a height-map file) and run
by ``petroll run`` as a whole process, results written; its tolerance searched from the one petroll's
Hertz start needed (the same solve), held to the smallest error a peer reached as petroll (zero) is;
``cold_s`` that process's wall time, ``warm_s`` its step's solve time (results.h5's solve_time);
``scene_ratio``: its cold time over each row's.
Writes peers.csv and peers.png. The peers live in .venv-peers (created or completed on first use with
pip: they need numpy 2, which must not enter petroll's environment). The scripts are no part of an
install: run from one, the benchmark stops at once with a one-line error (:func:`peer_scripts`).
"""

from __future__ import annotations

import compileall
import json
import math
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from mpi4py import MPI

from petroll.errors import PetrollError
from petroll.studies.tables import new_figure, save_figure, write_table

PROBLEMS = ("hertz", "wavy")
SOLVERS = ("petroll", "tamaas", "contactmechanics")
"""The solvers ``petroll bench peers`` times, each by its script ``solve_<name>.py``."""
TOLERANCES = (1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9, 3e-10, 1e-10)
"""The tolerances tried, loosest first, until a solver's pressure is within the target of the reference."""
PEERS_VENV = pathlib.Path(".venv-peers")
PEER_SCRIPTS = pathlib.Path(__file__).resolve().parents[2] / "scripts" / "peers"
"""Where the solvers' scripts are: scripts/peers/ of the checkout this petroll is imported from."""
_PEER_PACKAGES = {"tamaas": "tamaas", "ContactMechanics": "ContactMechanics"}  # import name: pip name


def write_problem(name: str, n: int, path: pathlib.Path) -> None:
    """The problem file every solver reads (common.py describes its entries)."""
    if name == "hertz":
        radius, E, nu, delta = 0.01, 1e7, 0.5, 1e-5
        compliance = (1 - nu**2) / E
        side = 3.2 * math.sqrt(radius * delta)
        x = (np.arange(n) + 0.5) * side / n - side / 2
        r2 = x[:, None] ** 2 + x[None, :] ** 2
        heights = radius - np.sqrt(radius**2 - r2)
        load = 4 * math.sqrt(radius) * delta**1.5 / (3 * compliance)
        hint = radius
    elif name == "wavy":
        from petroll.model.bodies.maps import HeightMap

        radius, compliance, delta, side, load = 100.0, 1.0, 0.01, 3.0, 0.0115
        x = (np.arange(n) + 0.5) * side / n - side / 2
        X, Y = np.meshgrid(x, x, indexing="ij")
        heights = radius - np.sqrt(radius**2 - X**2 - Y**2) + 0.002 * np.cos(2 * np.pi * X / 0.25) * np.cos(
            2 * np.pi * Y / 0.25)
        heights -= heights.min()
        hint = HeightMap(heights, side / n).radius_hint
    else:
        raise PetrollError(f"bench peers: problem {name!r}: unknown; allowed: {', '.join(PROBLEMS)}")
    pressure = 2 * math.sqrt(delta / radius) / (math.pi * compliance)  # Hertz's p0 at delta
    np.savez(path, heights=heights, cell=side / n, compliance=compliance, load=load, radius=hint, delta=delta,
             pressure=pressure)


def residual(problem: pathlib.Path, pressure: np.ndarray) -> float:
    """max |min(p / p_max, gap / delta)| of a pressure (Pa) on the problem's grid, the gap from petroll's
    influence operator (exact: a zero-padded FFT of Love's coefficients), delta the penetration the
    pressure implies (the mean of height + displacement over the cells it loads)."""
    from petroll.model.grid import Grid
    from petroll.solver.influence import influence_operator

    data = np.load(problem)
    heights, cell, compliance = data["heights"], float(data["cell"]), float(data["compliance"])
    n = heights.shape[0]
    w = compliance * influence_operator(Grid(n, n, 0.0, n * cell, 0.0, n * cell)).window(n, n)(pressure)
    loaded = pressure > 0
    delta = float((heights + w)[loaded].mean())
    natural = np.minimum(pressure / pressure.max(), (heights + w - delta) / delta)
    return float(np.abs(natural).max())


def peers(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, problems=PROBLEMS, cells=(256, 512),
          repeats: int = 3, target: float = 1e-6, solvers=SOLVERS) -> list[dict]:
    """The benchmark (module docstring); rank 0 runs the scripts; the rows on every rank."""
    peer_scripts()  # on every rank (one file system): an install stops here, on all alike
    rows = _rows(pathlib.Path(out), problems, cells, repeats, target, solvers) if comm.rank == 0 else None
    return comm.bcast(rows)


def _rows(out: pathlib.Path, problems, cells, repeats: int, target: float, solvers) -> list[dict]:
    """The rows (rank 0). petroll's modules are byte-compiled first, as an install leaves them (pip
    compiles the peers' in .venv-peers; a checkout run with PYTHONDONTWRITEBYTECODE set, as on the
    project's machine, would otherwise compile every petroll module in every timed process)."""
    compileall.compile_dir(pathlib.Path(__file__).parents[1], quiet=2)  # unwritable: silent
    runs = [(name, "zero") for name in solvers if name != "petroll"]
    if "petroll" in solvers:  # after the peers: held to their error; the scene from Hertz's start's tol
        runs = [*runs, ("petroll", "zero"), ("petroll", "hertz"), ("petroll", "scene")]
    python = {name: sys.executable if name == "petroll" else peers_python() for name, _ in runs}
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        where = pathlib.Path(scratch)
        problem, reference = where / "problem.npz", where / "reference.npy"
        for name in problems:
            for n in cells:
                write_problem(name, n, problem)
                peer_process(sys.executable, "petroll", [problem, "hertz", reference, "1e-12"])
                done = {}
                for solver, start in runs:
                    peer = min([target, *(float(r["difference"]) for (who, _), r in done.items()
                                          if who != "petroll")])
                    bound = peer if solver == "petroll" and start in ("zero", "scene") else target
                    if start == "scene":
                        tried = TOLERANCES[TOLERANCES.index(float(done["petroll", "hertz"]["tol"])):]
                        found, timed = scene_runs(name, problem, where / "scene", reference, tried, bound,
                                                  repeats)
                        field = where / "scene" / "pressure.npy"
                    else:
                        field = where / "pressure.npy"
                        found = peer_process(python[solver], solver, [problem, start, field,
                                                                      *map(str, TOLERANCES), "--reference",
                                                                      reference, "--target", bound])
                        timed = [peer_process(python[solver], solver, [problem, start, field, found["tol"]])
                                 for _ in range(repeats)]
                        for r in timed:  # the process up to its first answer: less the second solve it timed
                            r["cold_s"] -= r["warm_s"]
                    done[(solver, start)] = {
                        "problem": name, "cells": f"{n}x{n}", "solver": solver, "start": start,
                        "tol": f"{found['tol']:g}", "difference": f"{found['difference']:.2g}",
                        "within": int(found["difference"] <= bound),
                        "residual": f"{residual(problem, np.load(field)):.2g}",
                        "cold_s": statistics.median(r["cold_s"] for r in timed),
                        "warm_s": statistics.median(r["warm_s"] for r in timed),
                        "count": found["iterations"], "force_error": f"{timed[0]['force_error']:+.1e}"}
                    print(f"bench peers: {name} {n}^2 {solver} ({start}): tol {found['tol']:g}, "
                          f"{done[(solver, start)]['cold_s']:.2f} s cold", flush=True)
                ours, scene = done.get(("petroll", "zero")), done.get(("petroll", "scene"))
                for row in done.values():
                    if ours:
                        row["cold_ratio"] = f"{ours['cold_s'] / row['cold_s']:.3f}"
                        row["warm_ratio"] = f"{ours['warm_s'] / row['warm_s']:.3f}"
                    if scene:
                        row["scene_ratio"] = f"{scene['cold_s'] / row['cold_s']:.3f}"
                    rows.append(dict(row, cold_s=f"{row['cold_s']:.3g}", warm_s=f"{row['warm_s']:.3g}"))
    write_table(rows, out / "peers.csv")
    _plot(rows, out / "peers.png")
    return rows


def write_scene(name: str, problem: pathlib.Path, folder: pathlib.Path, tol: float) -> pathlib.Path:
    """The problem as the scene a user runs (``petroll run``): its grid, the elastic half-space of its
    compliance (E = 1 / J, nu = 0), its load, [solver] tol; the body the analytic sphere (``hertz``) or
    its heights as a height-map file on the cells (``wavy``: heights.npy beside the scene); results in
    ``folder``/out. Returns the scene file."""
    data = np.load(problem)
    heights, cell = data["heights"], float(data["cell"])
    half = heights.shape[0] * cell / 2
    folder.mkdir(parents=True, exist_ok=True)
    if name == "hertz":
        body = f'shape = "sphere"\nradius = {float(data["radius"])!r}'
    else:
        np.save(folder / "heights.npy", heights)
        body = f'shape = "heightmap"\nfile = "heights.npy"\ncell = {cell!r}'
    scene = folder / "scene.toml"
    scene.write_text(f"""[grid]
nx = {heights.shape[0]}
ny = {heights.shape[1]}
x = [{-half!r}, {half!r}]
y = [{-half!r}, {half!r}]

[material]
model = "elastic"
E = {1 / float(data["compliance"])!r}
nu = 0.0

[body]
{body}

[motion]
load = {float(data["load"])!r}

[solver]
tol = {tol!r}

[output]
dir = "{(folder / "out").as_posix()}"
""")
    return scene


def scene_process(scene: pathlib.Path) -> dict:
    """One whole ``petroll run --overwrite`` of ``scene`` (this Python's petroll command): its wall time
    (``cold_s``), the last saved pressure (Pa), its step's solve time (``warm_s``) and applications."""
    import h5py

    command = pathlib.Path(sys.executable).with_name("petroll")
    start = time.perf_counter()
    done = subprocess.run([str(command), "run", "--overwrite", str(scene)], capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if done.returncode:
        last = (done.stderr or done.stdout).strip().splitlines()[-1:]
        raise PetrollError(f"bench peers: petroll run {scene} failed: {last}")
    with h5py.File(scene.parent / "out" / "results.h5", "r") as h5:
        return {"cold_s": seconds, "pressure": h5["fields/pressure"][-1],
                "warm_s": float(h5["series/solve_time"][-1]),
                "iterations": int(h5["series/applications"][-1])}


def scene_runs(name: str, problem: pathlib.Path, folder: pathlib.Path, reference: pathlib.Path,
               tolerances, bound: float, repeats: int) -> tuple[dict, list[dict]]:
    """The scene row's search and timing: the first of ``tolerances`` whose ``petroll run`` pressure lies
    within ``bound`` (relative L2) of the reference (the last if none), its pressure saved in
    ``folder``/pressure.npy; then ``repeats`` timed runs at it. Returns (found: tol, difference,
    iterations; the timed runs)."""
    want = np.load(reference)
    for tol in tolerances:
        scene = write_scene(name, problem, folder, tol)
        run = scene_process(scene)
        difference = float(np.linalg.norm(run["pressure"] - want) / np.linalg.norm(want))
        if difference <= bound:
            break
    np.save(folder / "pressure.npy", run["pressure"])
    found = {"tol": tol, "difference": difference, "iterations": run["iterations"]}
    timed = [scene_process(scene) for _ in range(repeats)]
    for r in timed:
        r["force_error"] = float(r.pop("pressure").sum() * float(np.load(problem)["cell"]) ** 2
                                 / float(np.load(problem)["load"]) - 1)
    return found, timed


def peer_scripts() -> pathlib.Path:
    """:data:`PEER_SCRIPTS`, or PetrollError (one line) where this petroll is an install without them."""
    if not (PEER_SCRIPTS / "common.py").is_file():
        raise PetrollError(f"petroll bench: the peers' scripts are not in {PEER_SCRIPTS}: they come with a "
                           f"petroll checkout (scripts/peers/), not with an install; run the benchmark from "
                           f"a checkout")
    return PEER_SCRIPTS


def peer_process(python: str, name: str, args: list) -> dict:
    """One whole run of ``solve_<name>.py`` (:func:`peer_scripts`) with ``python``: its JSON answer, with the
    process's wall time as cold_s."""
    path = peer_scripts() / f"solve_{name}.py"
    start = time.perf_counter()
    done = subprocess.run([python, str(path), *map(str, args)], capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if done.returncode:
        last = (done.stderr or done.stdout).strip().splitlines()[-1:]
        raise PetrollError(f"bench peers: {name} failed: {last}")
    return dict(json.loads(done.stdout.strip().splitlines()[-1]), cold_s=seconds)


def _plot(rows: list[dict], path: pathlib.Path) -> None:
    """The cold and warm times (s) of every solver and start against the cells, one panel per problem."""
    problems = list(dict.fromkeys(r["problem"] for r in rows))
    figure = new_figure(5 * len(problems), 4)
    if figure is None:
        return
    axes = figure.subplots(1, len(problems), squeeze=False)[0]
    for ax, problem in zip(axes, problems):
        mine = [r for r in rows if r["problem"] == problem]
        for solver, start in dict.fromkeys((r["solver"], r["start"]) for r in mine):
            line = [r for r in mine if (r["solver"], r["start"]) == (solver, start)]
            cells = [int(r["cells"].split("x")[0]) ** 2 for r in line]
            for key, style in (("cold_s", "o-"), ("warm_s", "x:")):
                ax.loglog(cells, [float(r[key]) for r in line], style,
                          label=f"{solver} ({start}), {key[:-2]}")
        ax.set(xlabel="cells", ylabel="time (s)", title=f"{problem}: cold = whole process, warm = 2nd solve")
        ax.legend(fontsize=7)
    save_figure(figure, path)


def peers_python() -> str:
    """The Python of .venv-peers, created on first use; installs whichever peer it lacks (pip, PyPI).

    Tamaas and ContactMechanics share it: both install from wheels against numpy 2 (checked with pip check).
    """
    python = PEERS_VENV / "bin" / "python"
    if not python.exists():
        subprocess.run([sys.executable, "-m", "venv", "--clear", str(PEERS_VENV)], check=True)
    missing = [pip for module, pip in _PEER_PACKAGES.items()
               if subprocess.run([str(python), "-c", f"import {module}"], capture_output=True).returncode]
    if missing:
        print(f"petroll bench: installing {' '.join(missing)} into {PEERS_VENV} (benchmark-only peers, pip)",
              file=sys.stderr)
        subprocess.run([str(python), "-m", "pip", "install", "-q", *missing], check=True)
    return str(python)
