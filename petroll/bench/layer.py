"""``petroll bench layer [--out DIR]`` (:func:`bench`): the cost per step of layer scenes against the same
half-space scene (the performance goal: at most 1.3x), on runs/sphere.toml and runs/conveyor-idler.toml
(docs/layer.md; the study itself: petroll.studies.layer).
"""

from __future__ import annotations

import math
import pathlib
import time

from mpi4py import MPI

from petroll.model.scene import load_scene, shipped_scene
from petroll.solver.simulation import Simulation
from petroll.studies.tables import write_table

BENCH_CASES = (("sphere.toml", math.sqrt(0.01 * 20e-6), ((4.0, "bonded"), (1.0, "bonded"), (0.25, "bonded"),
                                                         (1.0, "frictionless"))),
               ("conveyor-idler.toml", 1e-3, ((6.0, "bonded"), (2.0, "bonded"), (6.0, "frictionless"))))
"""Scenes of ``petroll bench layer``, the length unit of their thicknesses (the sphere's Hertz radius a,
1 mm for the idler) and the (thickness, base) pairs."""


def bench(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, repeats: int = 5,
          cases=BENCH_CASES) -> list[dict]:
    """Per-step cost of each layer case against its half-space scene, every step after the sudden start
    (which builds the kernels) to the steady state: CPU seconds per step (this process; the least of
    ``repeats`` runs, interleaved with the half-space's so that a loaded machine affects both alike),
    TAO iterations and operator applications per step. Writes ``layer-bench.csv``. ``cases``: as
    :data:`BENCH_CASES`."""
    rows = []
    for name, unit, layers in cases:
        scene = load_scene(shipped_scene(name))
        variants = {"half-space": scene.replace("material.layer", None)}
        for h, base in layers:
            variants[f"h = {h:g} {'a' if unit < 1e-3 else 'mm'} {base}"] = scene.replace(
                "material.layer", {"thickness": h * unit, "base": base})
        cost = {k: math.inf for k in variants}
        work = {}
        for _ in range(repeats):
            for key, variant in variants.items():
                steps = Simulation(variant, comm).steps()
                next(steps)
                start = time.process_time()
                records = list(steps)
                cost[key] = min(cost[key], (time.process_time() - start) / len(records))
                work[key] = (sum(r.iterations for r in records) / len(records),
                             sum(r.applications for r in records) / len(records), len(records))
        for key in variants:
            rows.append({"scene": name, "case": key, "steps": work[key][2],
                         "cpu_ms_per_step": f"{1e3 * cost[key]:.3g}",
                         "ratio": f"{cost[key] / cost['half-space']:.2f}",
                         "iterations_per_step": f"{work[key][0]:.3g}",
                         "applications_per_step": f"{work[key][1]:.3g}"})
    if comm.rank == 0:
        write_table(rows, pathlib.Path(out) / "layer-bench.csv")
    return rows
