"""``petroll bench steady [--out DIR]``: the direct steady solve ([time] mode = "steady") against the
transient run from rest, on the default scene (runs/sphere.toml: its grid cells, material, penetration,
one step per cell), at speeds V tau/a from 1e-3 to 1e3 (docs/benchmarks.md).

At each speed: the transient run on a track of up to ``track`` contact radii (the scene's grid lengthened
at the same cells), stopped by ``[time] steady = tol``; the direct solve on the scene's grid with the
fixed point stopped at ``tol``; both against a reference, the direct solve at tol 1e-10 (the exact
steady state of the transient's scheme: docs/rolling.md). The same stop for both: force and resisting
force changing by at most tol x force, over a contact length of rolling (transient) or from one
fixed-point iteration to the next (direct; or its memory's relative change below tol). Reported per
method: the solver's wall time (the steps' solve_time, file writes excluded; the direct solve's with its
set-up), its ratio (the headline), and beside it the work counted two ways: the QPs' operator
applications, and every convolution and correlation in window-application equivalents (petroll.solver.
fft_work: each FFT pair's cost, points x log2 length, over the cost of one application on the steady
contact's QP window: the QPs' applications and preconditioner, the transient's history convolutions, the
direct solve's wake-extended convolutions, memory correlations and far wake); the errors of the force and
of mu_r against the reference; the direct solve's fixed-point iterations, and for the transient the
steps, the distance rolled and whether its steady criterion was met. Rank 0 prints the table and writes
DIR/steady.csv.

``petroll bench steady-growth [--out DIR]``: how the direct solve's time grows with the grid: runs/sphere.toml
solved directly ([time] mode = "steady", the scene's tol) on its extent with 512 x 256, 1024 x 512 and
2048 x 1024 cells, the grids alternated over ``repeats`` rounds in this process (each a new Simulation:
kernels, TAO objects and memory built again). Per grid: the fastest and the median wall time of the solve
(set-up included), the ratio of the fastest to the first grid's, the fixed-point iterations, the QPs'
applications and the FFT work in equivalents of one application on the first grid's window, force and
mu_r. Writes DIR/steady_growth.csv.
"""

from __future__ import annotations

import math
import pathlib
import statistics
import time

from mpi4py import MPI

from petroll.model.scene import Scene, load_scene, shipped_scene
from petroll.solver.fft_work import FFTWork
from petroll.solver.influence import Convolution
from petroll.solver.simulation import Simulation
from petroll.studies.tables import write_table

SPEEDS = (1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3)
"""V tau / a of the benchmark (a: the Hertz radius sqrt(R delta), tau: the longest creep time)."""


def steady_scene(scene: Scene, speed: float) -> Scene:
    """``scene`` at constant speed ``speed`` (m/s) along its own direction, [time] mode = "steady"."""
    return scene.replace({"motion.velocity": [speed, 0.0], "time.mode": "steady", "time.distance": None,
                          "time.end": None, "time.steady": None, "time.max_steps": None, "output.every": None})


def transient_scene(scene: Scene, speed: float, distance: float, tol: float) -> Scene:
    """``scene`` at ``speed`` rolled ``distance`` (m) from rest on a grid lengthened to hold the track (same
    cells), stopped by [time] steady = ``tol``."""
    g = scene.grid
    start = scene.position[0]
    x1 = max(g.x1, start + distance + (start - g.x0))
    nx = round((x1 - g.x0) / g.dx)
    return scene.replace({"motion.velocity": [speed, 0.0], "time.distance": distance, "time.steady": tol,
                          "time.max_steps": 10 * nx, "grid.nx": nx, "grid.x": [g.x0, g.x0 + nx * g.dx],
                          "output.every": None})


def steady(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, speeds=SPEEDS, tol: float = 1e-4,
           track: float = 40.0, scene: Scene | None = None) -> list[dict]:
    """The benchmark (module docstring); returns the rows (every rank)."""
    scene = scene or load_scene(shipped_scene("sphere.toml"))
    a = math.sqrt(scene.body.radius_hint * float(scene.penetration(0.0)))
    tau = scene.material.longest_time
    rows = []
    for v_tau_a in speeds:
        speed = v_tau_a * a / tau
        still = steady_scene(scene, speed)
        reference = Simulation(still, comm).solve_steady(tol=1e-10)
        direct_sim = Simulation(still, comm)
        work = FFTWork.total
        direct = direct_sim.solve_steady(tol=tol, steady=tol)
        direct_work, work = FFTWork.total - work, FFTWork.total
        sim = Simulation(transient_scene(scene, speed, track * a, tol), comm)
        records = list(sim.steps())
        transient_work = FFTWork.total - work
        i0, i1, j0, j1 = direct_sim.window
        unit = Convolution(None, i1 - i0, j1 - j0).cost  # one application on the steady contact's window
        last = records[-1]
        row = {"v_tau_a": v_tau_a, "speed": f"{speed:.4g}"}
        for name, r, apps, seconds, fft in (
                ("direct", direct, direct.applications, direct.solve_time, direct_work),
                ("transient", last, sum(x.applications for x in records), sum(x.solve_time for x in records),
                 transient_work)):
            row.update({f"{name}_s": f"{seconds:.3g}", f"{name}_applications": apps,
                        f"{name}_equivalents": f"{fft / unit:.0f}",
                        f"{name}_force_error": f"{abs(r.force / reference.force - 1):.2g}",
                        f"{name}_mu_r_error": f"{abs(r.mu_r / reference.mu_r - 1):.2g}"})
        row.update({"direct_iterations": direct_sim.fixed_point_iterations, "transient_steps": len(records),
                    "rolled_a": f"{last.distance / a:.3g}", "transient_steady": int(sim.steady()),
                    "time_ratio": f"{float(row['transient_s']) / float(row['direct_s']):.3g}",
                    "applications_ratio": f"{row['transient_applications'] / row['direct_applications']:.3g}",
                    "equivalents_ratio": f"{transient_work / direct_work:.3g}",
                    "mu_r": f"{reference.mu_r:.5g}", "force": f"{reference.force:.6g}"})
        rows.append(row)
    if comm.rank == 0:
        write_table(rows, pathlib.Path(out) / "steady.csv")
    return rows


GROWTH_GRIDS = ((512, 256), (1024, 512), (2048, 1024))
"""The grids of ``petroll bench steady-growth`` (runs/sphere.toml's extent)."""


def growth(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, grids=GROWTH_GRIDS, repeats: int = 3,
           scene: Scene | None = None) -> list[dict]:
    """The direct solve's time against the grid (module docstring); returns the rows (every rank)."""
    scene = scene or load_scene(shipped_scene("sphere.toml"))
    runs: dict[tuple[int, int], list] = {grid: [] for grid in grids}
    for _ in range(repeats):
        for nx, ny in grids:
            still = steady_scene(scene.replace({"grid.nx": nx, "grid.ny": ny}), float(scene.velocity(0.0)[0]))
            sim = Simulation(still, comm)
            work = FFTWork.total
            comm.Barrier()
            start = time.perf_counter()
            record = sim.solve_steady(tol=still.solver.tol)
            seconds = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
            work = FFTWork.total - work
            runs[(nx, ny)].append((seconds, record, sim.fixed_point_iterations, work, sim.window))
    first = min(r[0] for r in runs[grids[0]])
    i0, i1, j0, j1 = runs[grids[0]][0][4]
    unit = Convolution(None, i1 - i0, j1 - j0).cost
    rows = []
    for (nx, ny), done in runs.items():
        seconds = sorted(r[0] for r in done)
        _, record, iterations, work, _ = done[0]
        rows.append({"grid": f"{nx}x{ny}", "cells": nx * ny, "ranks": comm.size,
                     "fastest_s": f"{seconds[0]:.3g}", "median_s": f"{statistics.median(seconds):.3g}",
                     "ratio": f"{seconds[0] / first:.2f}",
                     "iterations": iterations, "applications": record.applications,
                     "equivalents": f"{work / unit:.0f}", "force": f"{record.force:.8g}",
                     "mu_r": f"{record.mu_r:.6g}"})
    if comm.rank == 0:
        write_table(rows, pathlib.Path(out) / "steady_growth.csv")
    return rows
