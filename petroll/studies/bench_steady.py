"""``petroll bench steady [--out DIR]``: the direct steady solve ([time] mode = "steady") against the
transient run from rest, on the default scene (runs/sphere.toml: its grid cells, material, penetration,
one step per cell), at speeds V tau/a from 1e-3 to 1e3 (docs/benchmarks.md).

At each speed: the transient run on a track of up to ``track`` contact radii (the scene's grid lengthened
at the same cells), stopped by ``[time] steady = tol``; the direct solve on the scene's grid with the
fixed point stopped at ``tol``; both against a reference, the direct solve
at tol 1e-10 (the exact steady state of the transient's scheme: docs/rolling.md). The same stop for
both: force and resisting force changing by at most tol x force, over a contact length of rolling
(transient) or from one fixed-point iteration to the next (direct; or its memory's relative change below
tol). Reported per method:
operator applications (the direct solve's QPs only: each of its ``direct_qps`` fixed-point iterations
also convolves A on the grid extended by the wake, and the memory along the motion twice), solver wall
time (the steps' solve_time; file writes excluded), the errors of the force and of mu_r against the
reference, and for the transient the steps, the distance rolled and whether its steady criterion was
met. Rank 0 prints the table and writes DIR/steady.csv.
"""

from __future__ import annotations

import math
import pathlib

from mpi4py import MPI

from petroll.model.scene import Scene, load_scene, shipped_scene
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
        direct = direct_sim.solve_steady(tol=tol, steady=tol)
        sim = Simulation(transient_scene(scene, speed, track * a, tol), comm)
        records = list(sim.steps())
        last = records[-1]
        row = {"v_tau_a": v_tau_a, "speed": f"{speed:.4g}"}
        for name, r, apps, seconds in (
                ("direct", direct, direct.applications, direct.solve_time),
                ("transient", last, sum(x.applications for x in records), sum(x.solve_time for x in records))):
            row.update({f"{name}_applications": apps, f"{name}_s": f"{seconds:.3g}",
                        f"{name}_force_error": f"{abs(r.force / reference.force - 1):.2g}",
                        f"{name}_mu_r_error": f"{abs(r.mu_r / reference.mu_r - 1):.2g}"})
        row.update({"direct_qps": direct_sim.fixed_point_iterations, "transient_steps": len(records),
                    "rolled_a": f"{last.distance / a:.3g}",
                    "transient_steady": int(sim.steady()),
                    "applications_ratio": f"{row['transient_applications'] / row['direct_applications']:.3g}",
                    "time_ratio": f"{float(row['transient_s']) / float(row['direct_s']):.3g}",
                    "mu_r": f"{reference.mu_r:.5g}", "force": f"{reference.force:.6g}"})
        rows.append(row)
    if comm.rank == 0:
        write_table(rows, pathlib.Path(out) / "steady.csv")
    return rows
