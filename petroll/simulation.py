"""Running a scene: build the grid, body heights and contact solver, solve, write results.h5.

All functions here are collective over ``comm``: every rank calls them with the same scene.
"""

from __future__ import annotations

import pathlib
import time

import numpy as np
from mpi4py import MPI

from petroll.contact import ContactSolver, StepSolution
from petroll.results import Results, write_results
from petroll.scene import Scene


def solve_static(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD) -> tuple[StepSolution, ContactSolver]:
    """Solve the scene's single contact step on an elastic half-space; pressure on this rank's rows."""
    solver = ContactSolver(scene.grid, comm, tao_type=scene.solver.tao_type, tol=scene.solver.tol)
    height = body_height(scene, solver)
    compliance = scene.material.compliance
    if scene.penetration is not None:
        return solver.solve_penetration(height, compliance, scene.penetration), solver
    return solver.solve_load(height, compliance, scene.load, scene.body.radius_hint), solver


def body_height(scene: Scene, solver: ContactSolver, position: tuple[float, float] | None = None):
    """Z(X - sx, Y - sy) on this rank's rows (m), the body at ``position`` (default: the scene's)."""
    sx, sy = position if position is not None else scene.position
    g = scene.grid
    return scene.body.height(g.x[solver.r0 : solver.r1, None] - sx, g.y[None, :] - sy)


def run(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, out: str | pathlib.Path | None = None) -> Results:
    """Run a scene and write ``<out>/results.h5`` (default out: the scene's [output] dir).

    Returns the results read back from the file, on every rank.
    """
    out = pathlib.Path(out) if out is not None else scene.output_dir
    start = time.perf_counter()
    solution, solver = solve_static(scene, comm)
    elapsed = time.perf_counter() - start
    g = scene.grid
    cells = comm.allreduce(int(np.count_nonzero(solution.pressure > 0)))
    p_max = comm.allreduce(float(solution.pressure.max(initial=0.0)), op=MPI.MAX)
    series = {
        "step": [0], "delta": [solution.delta], "force": [solution.force], "area": [cells * g.cell_area],
        "p_max": [p_max], "iterations": [solution.iterations], "applications": [solution.applications],
        "residual": [solution.residual], "solve_time": [elapsed],
    }
    field = gather_field(solution.pressure, g.nx, comm)
    path = out / "results.h5"
    if comm.rank == 0:
        write_results(path, series, field[None], np.array([0]), g.x, g.y, scene.text)
    comm.Barrier()
    return Results.open(path)


def gather_field(local: np.ndarray, nx: int, comm: MPI.Comm) -> np.ndarray | None:
    """The whole (nx, ny) field on rank 0 (None elsewhere), from each rank's rows. For output only."""
    counts = comm.gather(local.size, root=0)
    if comm.rank != 0:
        comm.Gatherv(np.ascontiguousarray(local), None, root=0)
        return None
    whole = np.empty(sum(counts))
    comm.Gatherv(np.ascontiguousarray(local), [whole, counts], root=0)
    return whole.reshape(nx, -1)
