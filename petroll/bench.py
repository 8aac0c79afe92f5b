"""Benchmarks that print tables and write CSV files (never timed unit tests).

``petroll bench tao [--out DIR]``: every TAO type on the elastic Hertz step (sphere, displacement control)
at two resolutions, cold (from p = 0) and warm (from the solution at a 1 % smaller penetration): TAO
iterations, operator applications, median wall time of repeated solves, and the force error against Hertz.
All types are measured side by side in one run, so their ratios are meaningful on a noisy machine.
"""

from __future__ import annotations

import csv
import math
import pathlib
import statistics
import time

from mpi4py import MPI

from petroll.bodies import Sphere
from petroll.contact import TAO_TYPES, ContactSolver
from petroll.errors import PetrollError
from petroll.grid import Grid

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
            previous = solver.solve_penetration(height, _J, 0.99 * _DELTA).pressure
            for start, warm in (("cold", None), ("warm", previous)):
                times = []
                try:
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
        out.mkdir(parents=True, exist_ok=True)
        with open(out / "tao_types.csv", "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        _print_table(rows)
    return rows


def _print_table(rows: list[dict]) -> None:
    names = list(rows[0])
    widths = [max(len(n), *(len(str(r[n])) for r in rows)) for n in names]
    print(" | ".join(n.ljust(w) for n, w in zip(names, widths)))
    print("-|-".join("-" * w for w in widths))
    for r in rows:
        print(" | ".join(str(r[n]).ljust(w) for n, w in zip(names, widths)))
