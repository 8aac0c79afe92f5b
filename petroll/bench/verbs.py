"""``petroll bench VERB``: the function each verb runs, with its sizes and its ``--quick`` sizes.

``--quick`` runs every verb at the smallest sizes that still go through all of its code paths and write all
of its files, in seconds: a check that the benchmark runs (from an install, in the docs test); it
measures nothing. ``bench peers --quick`` runs petroll's own solver only and ``bench periodic --quick``
leaves Tamaas out, so neither installs anything.
"""

from __future__ import annotations

import pathlib

from mpi4py import MPI

from petroll.errors import PetrollError

VERBS = ("tao", "warm", "skips", "peers", "precision", "growth", "mpi", "memory", "append", "layer", "steady",
         "steady-growth", "estimate", "accuracy", "periodic", "sliding", "friction", "cutoff", "sized")

QUICK = {
    "tao": dict(repeats=1, cells_per_radius=(6,), load_cells=48, rolling_distance=0.1e-3),
    "warm": dict(cells_per_radius=6, repeats=1),
    "skips": dict(track_cells=140, repeats=1),
    "peers": dict(cells=(24,), repeats=1, solvers=("petroll",)),
    "precision": dict(steps_per_cell=(0.25, 4), reference=8, grids=(0.5, 1), grid_scale=0.5, distance=0.5e-3,
                      short=0),
    "growth": dict(windows=(24, 32), steps=6, track_window=16, track_steps=40, track_skip=10, track_span=10),
    "mpi": dict(windows=(24,), steps=5, repeats=1, sides=(256,)),
    "memory": dict(sides=(256,), steps=2),
    "append": dict(side=16, steps=30, block=10),
    "layer": dict(repeats=1, cases=(("conveyor-idler.toml", 1e-3, ((6.0, "bonded"),)),)),
    "steady": dict(speeds=(1.0,), track=8),
    "steady-growth": dict(grids=((64, 32),), repeats=1),
    "estimate": dict(factors=(1,), repeats=1),
    "accuracy": dict(scenes=("roller-2d.toml",), factors=(0.5,), reference=2.0,
                     integrators=("roller-2d.toml, paper",), order_factors=(1.0, 2.0, 4.0)),
    "periodic": dict(sides=(32,), repeats=1, tamaas_sides=(), solve_sides=(32,)),
    "sliding": dict(cells=32, curve_cells=32, points=2),
    "friction": dict(quick=True),
    "cutoff": dict(cells=(2,), reference=4, side=0.5e-3),
    "sized": dict(speeds="0.01,1", fine=80),
}
"""Keyword arguments of each verb's function under ``--quick``."""


def run(which: str, out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, quick: bool = False,
        ranks: tuple[int, ...] | None = None, sides: tuple[int, ...] | None = None, steady: bool = False):
    """Run benchmark ``which`` (one of :data:`VERBS`) writing into ``out``; ``ranks`` (mpi, memory),
    ``sides`` and ``steady`` (memory) as on the command line. Returns the benchmark's rows."""
    if ranks is not None and which not in ("mpi", "memory", "sliding"):
        raise PetrollError(f"petroll bench {which}: --ranks applies to petroll bench mpi, memory and sliding "
                           "only")
    if sides is not None and which not in ("memory", "sliding", "mpi"):
        raise PetrollError(f"petroll bench {which}: --sides applies to petroll bench memory, sliding and mpi only")
    if sides is not None and which == "mpi" and not steady:
        raise PetrollError("petroll bench mpi: --sides applies with --steady only (the rolling windows are fixed)")
    if steady and which not in ("memory", "mpi"):
        raise PetrollError(f"petroll bench {which}: --steady applies to petroll bench memory and mpi only")
    if which == "sliding" and (ranks or sides):  # memory and time per rank of the rough sliding solve
        from petroll.bench import rough

        return rough.scale(out, sides or rough.SCALE_SIDES, ranks or (1, 2))
    options = dict(QUICK[which]) if quick else {}
    if ranks is not None:
        options["ranks"] = ranks
    elif quick and which == "memory":
        options["ranks"] = (1,)
    if sides is not None:
        options["sides"] = sides
    if steady:
        options["steady"] = True
    return _function(which)(out, comm, **options)


def _function(which: str):
    """The function of verb ``which`` (imported on use: each pulls in its own modules)."""
    if which in ("tao", "warm"):
        from petroll.bench import solvers

        return {"tao": solvers.tao_types, "warm": solvers.warm_starts}[which]
    if which == "peers":
        from petroll.bench.peers import peers

        return peers
    if which in ("periodic", "sliding"):
        from petroll.bench import rough

        return {"periodic": rough.periodic, "sliding": rough.sliding}[which]
    if which in ("estimate", "accuracy"):
        from petroll.bench import accuracy

        return {"estimate": accuracy.bench_cost, "accuracy": accuracy.bench}[which]
    if which in ("precision", "growth", "skips", "mpi"):
        from petroll.bench import mpi, rolling

        return {"precision": rolling.precision, "growth": rolling.growth, "skips": rolling.skips,
                "mpi": mpi.mpi_scaling}[which]
    if which in ("memory", "append"):
        from petroll.bench import memory

        return {"memory": memory.memory, "append": memory.append}[which]
    if which == "friction":
        from petroll.bench.friction import bench_friction

        return lambda out, comm, **options: bench_friction(out, comm=comm, **options)
    if which in ("cutoff", "sized"):
        from petroll.bench import sizing

        return {"cutoff": sizing.cutoff, "sized": sizing.sized}[which]
    if which == "layer":
        from petroll.bench.layer import bench as layer_bench

        return layer_bench
    from petroll.bench import steady

    return {"steady": steady.steady, "steady-growth": steady.growth}[which]
