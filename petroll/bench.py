"""Benchmarks that print tables and write CSV files (never timed unit tests).

``petroll bench peers [--out DIR]``: the elastic Hertz step under load control on the same grids, same
tolerance, solved by petroll (``pk``) and by Tamaas (``PolonskyKeerRey`` with its non-periodic ``dcfft``
operator), each checked against Hertz, timed side by side in one invocation (median of 3). Tamaas runs in
its own virtual environment, ``.venv-peers`` (created on first use with pip: it needs numpy 2, which must
not enter petroll's environment).

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

import numpy as np
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
        _report(rows, out / "tao_types.csv")
    return rows


PEERS_VENV = pathlib.Path(".venv-peers")


def peers(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, cells: tuple[int, ...] = (128, 256, 512),
          tol: float = 1e-8, repeats: int = 3) -> list[dict]:
    """petroll against Tamaas on the Hertz step (rank 0 runs Tamaas); writes ``out/peers.csv``."""
    import json
    import subprocess

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
        solver.influence.window(n, n)  # kernels built before timing, as Tamaas builds its own in set-up
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
            runs = []
            for _ in range(repeats):
                done = subprocess.run([python, str(pathlib.Path(__file__).with_name("bench_tamaas.py")), str(n),
                                       str(tol), str(_R), str(E), str(nu), str(_DELTA), str(width)],
                                      capture_output=True, text=True, check=True)
                runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
            theirs = statistics.median(r["seconds"] for r in runs)
            row.update(tamaas_s=f"{theirs:.3f}", tamaas_pressure_error=f"{runs[0]['pressure_error']:.3e}",
                       tamaas_force_error=f"{runs[0]['force_error']:+.1e}", ratio=f"{ours / theirs:.2f}")
        rows.append(row)
    if comm.rank == 0:
        _report(rows, out / "peers.csv")
    return rows


def _peers_python() -> str:
    """The Python of .venv-peers, created with Tamaas on first use."""
    import subprocess
    import sys

    python = PEERS_VENV / "bin" / "python"
    if not python.exists() or subprocess.run([str(python), "-c", "import tamaas"]).returncode:
        print(f"petroll bench: creating {PEERS_VENV} with tamaas (benchmark-only peer, pip)", file=sys.stderr)
        subprocess.run([sys.executable, "-m", "venv", "--clear", str(PEERS_VENV)], check=True)
        subprocess.run([str(python), "-m", "pip", "install", "-q", "tamaas"], check=True)
    return str(python)


def _report(rows: list[dict], path: pathlib.Path) -> None:
    """Write the rows as CSV to ``path`` and print them as a table."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    _print_table(rows)


def _print_table(rows: list[dict]) -> None:
    names = list(rows[0])
    widths = [max(len(n), *(len(str(r[n])) for r in rows)) for n in names]
    print(" | ".join(n.ljust(w) for n, w in zip(names, widths)))
    print("-|-".join("-" * w for w in widths))
    for r in rows:
        print(" | ".join(str(r[n]).ljust(w) for n, w in zip(names, widths)))
