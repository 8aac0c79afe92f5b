"""Benchmarks that print tables and write CSV files (never timed unit tests).

``petroll bench warm [--out DIR] [--quick]``: the rolling sphere of runs/sphere.toml on square cells at
a/dx = 16 (the Hertz radius over 16 cells), rolled one cell per step to steady state, with every step's QP
started from p = 0 (``cold``), from the last solution carried along with the body (``carried``) and from
the last three extrapolated in the body's frame (``extrapolated``, the default; petroll/solver/warm.py):
operator applications per step (all warm steps, and the last 20, at steady state), time per step, and the
steady force and mu_r (the guess changes the cost, not the answer). Writes warm.csv and warm.png
(applications per step). ``--quick``: a/dx = 6 and one repeat, a check that it runs (tests/test_install.py).

``petroll bench tao [--out DIR]``: every TAO type on the elastic Hertz step (sphere, displacement control)
at two resolutions, cold (from p = 0) and warm (from the solution at a 1 % smaller penetration), the types
that run a KSP on the Hessian with the inverse-circulant PC and without: TAO iterations, operator
applications, median wall time of repeated solves, and the force error against Hertz (tao_types.csv).
Then load control against displacement control (tao_load.csv, :func:`load_control`), and every type and
PC on the default rolling scene (runs/sphere.toml to steady state): iterations, applications and time
per step (tao_rolling.csv). All are measured side by side in one run, so their ratios are meaningful on
a noisy machine.
"""

from __future__ import annotations

import math
import pathlib
import statistics
import time

import numpy as np
from mpi4py import MPI

from petroll.model.bodies import Sphere
from petroll.model.tao import TAO_TYPES
from petroll.solver.contact import ContactSolver
from petroll.solver.petsc import KRYLOV_TYPES
from petroll.errors import PetrollError
from petroll.model.grid import Grid
from petroll.solver.warm import DEPTH, WarmStart
from petroll.studies.tables import new_figure, plot_lines, save_figure, write_table

_R, _J, _DELTA = 0.01, 7.5e-8, 1e-5  # m, 1/Pa, m: a steel ball on rubber (E = 10 MPa, nu = 0.5)


def tao_types(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, repeats: int = 3,
              cells_per_radius: tuple[int, ...] = (16, 48), load_cells: int = 256,
              rolling_distance: float | None = None) -> list[dict]:
    """Measure every TAO type; returns the rows and writes ``out/tao_types.csv`` (rank 0), then
    :func:`load_control` on ``load_cells`` and :func:`tao_types_rolling` to ``rolling_distance``."""
    a = math.sqrt(_R * _DELTA)
    force = 4 * math.sqrt(_R) * _DELTA**1.5 / (3 * _J)
    rows = []
    for ratio in cells_per_radius:
        half = 1.6 * a
        n = int(round(2 * half / (a / ratio)))
        grid = Grid(n, n, -half, half, -half, half)
        for kind, pc in _tao_variants():
            solver = ContactSolver(grid, comm, tao_type=kind, tol=1e-8, precondition=pc == "circulant")
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
                    rows.append(dict(cells=f"{n}x{n}", tao_type=kind, pc=pc, start=start, iterations="-",
                                     applications="-", seconds="-", force_error=f"failed: {exc}"))
                    continue
                rows.append(dict(cells=f"{n}x{n}", tao_type=kind, pc=pc, start=start,
                                 iterations=step.iterations, applications=step.applications,
                                 seconds=f"{statistics.median(times):.4f}",
                                 force_error=f"{step.force / force - 1:+.2e}"))
    if comm.rank == 0:
        write_table(rows, out / "tao_types.csv")
        _plot_tao(rows, out / "tao_types.png")
    rows += load_control(out, comm, load_cells)
    rows += tao_types_rolling(out, comm, rolling_distance)
    return rows


def load_control(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, cells: int = 256,
                 types: tuple[str, ...] = ("pk", "tron")) -> list[dict]:
    """The cost of load control against displacement control on the Hertz step (N x N cells over 3.2
    contact radii, cold): operator applications of ``solve_penetration`` at delta and of ``solve_load`` at
    the force it found, their ratio, and the penetration found (relative to delta). pk holds the force
    inside its QP; TAO's own types run the secant on the penetration. Writes ``out/tao_load.csv``."""
    a = math.sqrt(_R * _DELTA)
    grid = Grid(cells, cells, -1.6 * a, 1.6 * a, -1.6 * a, 1.6 * a)
    rows = []
    for kind in types:
        solver = ContactSolver(grid, comm, tao_type=kind, tol=1e-8)
        height = Sphere(_R).height(grid.x[solver.r0 : solver.r1, None], grid.y[None, :])
        shifted = ContactSolver(grid, comm, tao_type=kind, tol=1e-8)  # its own kernels and TAOs: both cold
        by_delta = solver.solve_penetration(height, _J, _DELTA)
        by_load = shifted.solve_load(height, _J, by_delta.force, _R)
        rows.append(dict(cells=f"{cells}x{cells}", tao_type=kind, displacement_applications=by_delta.applications,
                         load_applications=by_load.applications,
                         ratio=f"{by_load.applications / by_delta.applications:.2f}",
                         delta_error=f"{by_load.delta / _DELTA - 1:+.1e}"))
    if comm.rank == 0:
        write_table(rows, out / "tao_load.csv")
    return rows


def tao_types_rolling(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD,
                      distance: float | None = None) -> list[dict]:
    """Every TAO type on the default rolling scene (runs/sphere.toml, to steady state or ``distance`` m):
    TAO iterations, operator applications and wall time per step (means over the steps after the first),
    the applications per step over the last 20 (steady rolling), and the last step's force; writes
    ``out/tao_rolling.csv``."""
    from petroll.model.scene import load_scene, shipped_scene
    from petroll.solver.simulation import Simulation

    scene = load_scene(shipped_scene("sphere.toml")).replace("output.every", 0)
    if distance is not None:
        scene = scene.replace("time.distance", distance)
    rows = []
    for kind, pc in _tao_variants():
        sim = Simulation(scene.replace("solver.tao_type", kind), comm)
        sim.solver.precondition = pc == "circulant"  # read when each window's TAO is built
        try:
            records = list(sim.steps())
        except PetrollError as exc:
            done = len(sim.records)
            rows.append(dict(tao_type=kind, pc=pc, steps=done, iterations="-", applications="-",
                             ms_per_step="-", force=f"failed at step {done}: {exc}"))
            continue
        warm = records[1:]
        rows.append(dict(tao_type=kind, pc=pc, steps=len(records),
                         iterations=f"{np.mean([r.iterations for r in warm]):.1f}",
                         applications=f"{np.mean([r.applications for r in warm]):.1f}",
                         apps_last_20=f"{np.mean([r.applications for r in warm[-20:]]):.1f}",
                         ms_per_step=f"{1e3 * np.mean([r.solve_time for r in warm]):.2f}",
                         force=f"{records[-1].force:.7g}"))
    if comm.rank == 0:
        write_table(rows, out / "tao_rolling.csv")
    return rows


def _tao_variants() -> list[tuple[str, str]]:
    """(TAO type, PC) pairs measured: every type, those that run a KSP on the Hessian with the
    inverse-circulant PC and without (``none``); the others have none to set (``-``)."""
    return [(kind, pc) for kind in TAO_TYPES
            for pc in (("circulant", "none") if kind in KRYLOV_TYPES else ("-",))]


def _plot_tao(rows: list[dict], path: pathlib.Path) -> None:
    """Operator applications of each type (and PC), cold and warm, one panel per grid (failed solves left
    out)."""
    figure = new_figure(12, 3.8)
    if figure is None:
        return
    variants = _tao_variants()
    labels = [kind if pc in ("-", "circulant") else f"{kind}, no PC" for kind, pc in variants]
    grids = list(dict.fromkeys(r["cells"] for r in rows))
    for ax, cells in zip(figure.subplots(1, len(grids), squeeze=False)[0], grids):
        for k, start in enumerate(("cold", "warm")):
            done = [r for r in rows
                    if r["cells"] == cells and r["start"] == start and r["applications"] != "-"]
            ax.bar([variants.index((r["tao_type"], r["pc"])) + 0.4 * k for r in done],
                   [r["applications"] for r in done], width=0.4, label=start)
        ax.set_xticks([i + 0.2 for i in range(len(variants))], labels, rotation=60, fontsize=7)
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
