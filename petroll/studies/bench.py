"""Benchmarks that print tables and write CSV files (never timed unit tests).

``petroll bench peers [--out DIR]``: the elastic Hertz step under load control on the same grids (N x N
cells over 3.2 contact radii, non-periodic), same tolerance, solved by petroll (``pk``), by Tamaas
(``PolonskyKeerRey`` with its non-periodic ``dcfft`` operator) and by ContactMechanics
(``constrained_conjugate_gradients`` on a ``FreeFFTElasticHalfSpace``), each checked against Hertz, timed
side by side in one invocation (median of 3; set-up such as kernels excluded for all three). Writes
``peers.csv`` and ``peers.png`` (time against cells). The peers run in their own virtual environment,
``.venv-peers`` (created or completed on first use with pip: they need numpy 2, which must not enter
petroll's environment), through the standalone scripts ``peers/tamaas.py`` and ``peers/contactmechanics.py``.

``petroll bench warm [--out DIR] [--quick]``: the rolling sphere of runs/sphere.toml on square cells at
a/dx = 16 (the Hertz radius over 16 cells), rolled one cell per step to steady state, with every step's QP
started from p = 0 (``cold``), from the last solution carried along with the body (``carried``) and from
the last three extrapolated in the body's frame (``extrapolated``, the default; petroll/solver/warm.py):
operator applications per step (all warm steps, and the last 20, at steady state), time per step, and the
steady force and mu_r (the guess changes the cost, not the answer). Writes warm.csv and warm.png
(applications per step). ``--quick``: a/dx = 6 and one repeat, a check that it runs (tests/test_install.py).

``petroll bench tao [--out DIR]``: every TAO type on the elastic Hertz step (sphere, displacement control)
at two resolutions, cold (from p = 0) and warm (from the solution at a 1 % smaller penetration): TAO
iterations, operator applications, median wall time of repeated solves, and the force error against Hertz.
Then every type on the default rolling scene (runs/sphere.toml to steady state): iterations,
applications and time per step (tao_rolling.csv). All types are measured side by side in one run, so
their ratios are meaningful on a noisy machine.
"""

from __future__ import annotations

import math
import pathlib
import statistics
import time

import numpy as np
from mpi4py import MPI

from petroll.model.bodies import Sphere
from petroll.model.scene import TAO_TYPES
from petroll.solver.contact import ContactSolver
from petroll.errors import PetrollError
from petroll.model.grid import Grid
from petroll.solver.warm import DEPTH, WarmStart
from petroll.studies.tables import new_figure, plot_lines, save_figure, write_table

_R, _J, _DELTA = 0.01, 7.5e-8, 1e-5  # m, 1/Pa, m: a steel ball on rubber (E = 10 MPa, nu = 0.5)


def tao_types(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, repeats: int = 3,
              cells_per_radius: tuple[int, ...] = (16, 48)) -> list[dict]:
    """Measure every TAO type; returns the rows and writes ``out/tao_types.csv`` (rank 0)."""
    a = math.sqrt(_R * _DELTA)
    force = 4 * math.sqrt(_R) * _DELTA**1.5 / (3 * _J)
    rows = []
    for ratio in cells_per_radius:
        half = 1.6 * a
        n = int(round(2 * half / (a / ratio)))
        grid = Grid(n, n, -half, half, -half, half)
        for kind in TAO_TYPES:
            solver = ContactSolver(grid, comm, tao_type=kind, tol=1e-8)
            height = Sphere(_R).height(grid.x[solver.r0 : solver.r1, None], grid.y[None, :])
            for start in ("cold", "warm"):
                times = []
                try:
                    warm = None
                    if start == "warm":  # the solution at a 1 % smaller penetration, as in a time step
                        warm = solver.solve_penetration(height, _J, 0.99 * _DELTA).pressure
                    for _ in range(repeats):
                        t0 = time.perf_counter()
                        step = solver.solve_penetration(height, _J, _DELTA, warm)
                        times.append(time.perf_counter() - t0)
                except PetrollError as exc:
                    rows.append(dict(cells=f"{n}x{n}", tao_type=kind, start=start, iterations="-",
                                     applications="-", seconds="-", force_error=f"failed: {exc}"))
                    continue
                rows.append(dict(cells=f"{n}x{n}", tao_type=kind, start=start, iterations=step.iterations,
                                 applications=step.applications, seconds=f"{statistics.median(times):.4f}",
                                 force_error=f"{step.force / force - 1:+.2e}"))
    if comm.rank == 0:
        write_table(rows, out / "tao_types.csv")
        _plot_tao(rows, out / "tao_types.png")
    rows += tao_types_rolling(out, comm)
    return rows


def tao_types_rolling(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD,
                      distance: float | None = None) -> list[dict]:
    """Every TAO type on the default rolling scene (runs/sphere.toml, to steady state or ``distance`` m):
    TAO iterations, operator applications and wall time per step (means over the steps after the first),
    and the last step's force; writes ``out/tao_rolling.csv``."""
    from petroll.model.scene import load_scene, shipped_scene
    from petroll.solver.simulation import Simulation

    scene = load_scene(shipped_scene("sphere.toml")).replace("output.every", 0)
    if distance is not None:
        scene = scene.replace("time.distance", distance)
    rows = []
    for kind in TAO_TYPES:
        sim = Simulation(scene.replace("solver.tao_type", kind), comm)
        try:
            records = list(sim.steps())
        except PetrollError as exc:
            done = len(sim.records)
            rows.append(dict(tao_type=kind, steps=done, iterations="-", applications="-",
                             ms_per_step="-", force=f"failed at step {done}: {exc}"))
            continue
        warm = records[1:]
        rows.append(dict(tao_type=kind, steps=len(records),
                         iterations=f"{np.mean([r.iterations for r in warm]):.1f}",
                         applications=f"{np.mean([r.applications for r in warm]):.1f}",
                         ms_per_step=f"{1e3 * np.mean([r.solve_time for r in warm]):.2f}",
                         force=f"{records[-1].force:.7g}"))
    if comm.rank == 0:
        write_table(rows, out / "tao_rolling.csv")
    return rows


def _plot_tao(rows: list[dict], path: pathlib.Path) -> None:
    """Operator applications of each type, cold and warm, one panel per grid (failed solves left out)."""
    figure = new_figure(10, 3.6)
    if figure is None:
        return
    grids = list(dict.fromkeys(r["cells"] for r in rows))
    for ax, cells in zip(figure.subplots(1, len(grids), squeeze=False)[0], grids):
        for k, start in enumerate(("cold", "warm")):
            done = [r for r in rows
                    if r["cells"] == cells and r["start"] == start and r["applications"] != "-"]
            ax.bar([TAO_TYPES.index(r["tao_type"]) + 0.4 * k for r in done],
                   [r["applications"] for r in done], width=0.4, label=start)
        ax.set_xticks([i + 0.2 for i in range(len(TAO_TYPES))], TAO_TYPES, rotation=45)
        ax.set(yscale="log", ylabel="operator applications", title=f"Hertz step, {cells} cells")
        ax.legend()
    save_figure(figure, path)


WARM_STARTS = {"cold": 0, "carried": 1, "extrapolated": DEPTH}  # name: solutions kept (WarmStart depth)


def warm_starts(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, cells_per_radius: float = 16.0,
                repeats: int = 3) -> list[dict]:
    """Applications and time per rolling step for each first guess; writes ``out/warm.csv`` and warm.png."""
    from petroll.model.scene import load_scene, shipped_scene
    from petroll.solver.simulation import Simulation

    base = load_scene(shipped_scene("sphere.toml"))
    cell = math.sqrt(base.body.radius_hint * base.penetration(0.0)) / cells_per_radius
    (x0, x1), (y0, y1) = (base.grid.x0, base.grid.x1), (base.grid.y0, base.grid.y1)
    ny = 2 * round((y1 - y0) / (2 * cell))
    scene = base.replace({"grid.nx": round((x1 - x0) / cell), "grid.ny": ny, "grid.x": [x0, x0 + round(
        (x1 - x0) / cell) * cell], "grid.y": [-ny * cell / 2, ny * cell / 2], "output.every": 0})
    rows, series, per_step, last = [], {}, {name: [] for name in WARM_STARTS}, {}
    for _ in range(repeats):  # the variants in turn within each repeat: the machine's drift hits all
        for name, depth in WARM_STARTS.items():
            sim = Simulation(scene, comm)
            sim.warm = WarmStart(scene.grid, sim.solver.rows, comm, depth)
            records = list(sim.steps())
            per_step[name].append([r.solve_time for r in records[1:]])
            last[name] = records
    for name in WARM_STARTS:
        records = last[name]
        apps = [r.applications for r in records[1:]]
        series[name] = apps
        rows.append(dict(start=name, cells=f"{scene.grid.nx}x{scene.grid.ny}", steps=len(records),
                         apps_per_step=f"{np.mean(apps):.1f}", apps_last_20=f"{np.mean(apps[-20:]):.1f}",
                         ms_per_step=f"{1e3 * _median_total(per_step[name]) / len(apps):.2f}",
                         force=f"{records[-1].force:.7g}", mu_r=f"{records[-1].mu_r:.6g}"))
    if comm.rank == 0:
        write_table(rows, out / "warm.csv")
        plot_lines(series, out / "warm.png", "step", "operator applications",
                    f"rolling sphere, a/dx = {cells_per_radius:g}, one cell per step")
    return rows


def _median_total(runs: list[list[float]]) -> float:
    """The median over runs of each run's summed times (s)."""
    return statistics.median(sum(run) for run in runs)


PEERS_VENV = pathlib.Path(".venv-peers")
PEERS = {"tamaas": "tamaas.py", "contactmechanics": "contactmechanics.py"}  # CSV prefix: script in peers/
_PEER_PACKAGES = {"tamaas": "tamaas", "ContactMechanics": "ContactMechanics"}  # import name: pip name


def peers(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, cells: tuple[int, ...] = (128, 256, 512),
          tol: float = 1e-8, repeats: int = 3) -> list[dict]:
    """petroll against Tamaas and ContactMechanics on the Hertz step (rank 0 runs the peers).

    Times in s (median of ``repeats`` solves, kernels built before timing), pressure error = max |p - p_Hertz|
    / p0 over the cell centres, force error = F / F_Hertz - 1. Columns ``ratio`` (petroll / Tamaas, the
    original name) and ``ratio_contactmechanics`` (petroll / ContactMechanics): < 1 means petroll is faster.
    Writes ``out/peers.csv`` and ``out/peers.png``.
    """
    width = 3.2  # grid side in contact radii
    nu, E = 0.5, 1e7
    J = (1 - nu**2) / E
    a = math.sqrt(_R * _DELTA)
    force = 4 * math.sqrt(_R) * _DELTA**1.5 / (3 * J)
    p0 = 2 * math.sqrt(_DELTA / _R) / (math.pi * J)
    python = _peers_python() if comm.rank == 0 else None
    rows = []
    for n in cells:
        grid = Grid(n, n, -width * a / 2, width * a / 2, -width * a / 2, width * a / 2)
        solver = ContactSolver(grid, comm, tao_type="pk", tol=tol)
        height = Sphere(_R).height(grid.x[solver.r0 : solver.r1, None], grid.y[None, :])
        solver.solve_load(height, J, force, _R)  # untimed: builds the kernels of the windows it uses, as
        # the peers build theirs in set-up (each timed solve below starts from p = 0 all the same)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            step = solver.solve_load(height, J, force, _R)
            times.append(time.perf_counter() - t0)
        r = np.hypot(grid.x[solver.r0 : solver.r1, None], grid.y[None, :])
        hertz = p0 * np.sqrt(np.clip(1 - r**2 / a**2, 0, None))
        error = comm.allreduce(float(np.abs(step.pressure - hertz).max()), op=MPI.MAX) / p0
        ours = statistics.median(times)
        row = dict(cells=f"{n}x{n}", petroll_s=f"{ours:.3f}", petroll_pressure_error=f"{error:.3e}",
                   petroll_force_error=f"{step.force / force - 1:+.1e}")
        if comm.rank == 0:
            args = [str(v) for v in (n, tol, _R, E, nu, _DELTA, width)]
            for name, script in PEERS.items():
                run = _peer(python, script, args, repeats)
                row.update({f"{name}_s": f"{run['seconds']:.3f}",
                            f"{name}_pressure_error": f"{run['pressure_error']:.3e}",
                            f"{name}_force_error": f"{run['force_error']:+.1e}"})
                row["ratio" if name == "tamaas" else f"ratio_{name}"] = f"{ours / run['seconds']:.2f}"
        rows.append(row)
    if comm.rank == 0:
        write_table(rows, out / "peers.csv")
        _plot_peers(rows, out / "peers.png")
    return rows


def _peer(python: str, script: str, args: list[str], repeats: int) -> dict:
    """Run a peer script ``repeats`` times; its first JSON answer with the median time in s."""
    import importlib.resources
    import json
    import subprocess

    runs = []
    for _ in range(repeats):
        with importlib.resources.as_file(importlib.resources.files("petroll.studies.peers") / script) as path:
            done = subprocess.run([python, str(path), *args], capture_output=True, text=True, check=True)
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    return dict(runs[0], seconds=statistics.median(r["seconds"] for r in runs))


def _plot_peers(rows: list[dict], path: pathlib.Path) -> None:
    """Log-log plot of the solve time (s) against the number of cells N^2, one line per solver."""
    figure = new_figure(5, 4)
    if figure is None:
        return
    ax = figure.subplots()
    cells = [int(r["cells"].split("x")[0]) ** 2 for r in rows]
    for key, label in (("petroll_s", "petroll (pk)"), ("tamaas_s", "Tamaas"),
                       ("contactmechanics_s", "ContactMechanics")):
        ax.loglog(cells, [float(r[key]) for r in rows], "o-", label=label)
    ax.set_xticks(cells, [r["cells"] for r in rows], minor=False)
    ax.set_xticks([], minor=True)
    ax.set(xlabel="cells", ylabel="solve time (s)", title="Hertz step, load control, tol 1e-8")
    ax.legend()
    save_figure(figure, path)


def _peers_python() -> str:
    """The Python of .venv-peers, created on first use; installs whichever peer it lacks (pip, PyPI).

    Tamaas and ContactMechanics share it: both install from wheels against numpy 2 (checked with pip check).
    """
    import subprocess
    import sys

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
