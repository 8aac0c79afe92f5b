"""``petroll bench memory`` and ``petroll bench append``: what a run costs in memory per rank as the grid
grows, and what writing results.h5 costs per saved step as the run grows.

memory: the rolling sphere of runs/sphere.toml on square grids of ``side`` x ``side`` cells (32 cells per
contact radius, the grid extent growing with the side), rolled ``steps`` cells with every field saved and a
checkpoint at the end (``--steady``: its steady state solved directly, [time] mode = "steady"), run as
``mpirun -n K`` children (more ranks than cores is fine: memory is what is measured). Each rank reports its
peak resident memory (``ru_maxrss``) and its resident memory before the scene is built (the interpreter,
numpy, PETSc and MPI: the fixed cost of a rank); the table gives rank 0's peak, the mean and the largest over
ranks, rank 0 / mean, the peak above that fixed cost summed over ranks (the run's own memory) and the wall
time per step. Writes memory.csv and memory.png (``--steady``: memory_steady.csv and .png).

append: a :class:`petroll.io.results.ResultsFile` grown by ``steps`` appends of one field each (a
``side`` x ``side`` field, its rows on each rank); the time of every append (collective, max over ranks)
against the step number. Writes append.csv (medians per block of 100 steps) and append.png.
"""

from __future__ import annotations

import json
import os
import pathlib
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np
from mpi4py import MPI

from petroll.errors import PetrollError
from petroll.studies.tables import new_figure, save_figure, write_table

SIDES = (1024, 2048, 4096)
RANKS = (1, 2, 4)
CELLS_PER_RADIUS = 32


def memory_scene(side: int, steps: int, steady: bool = False):
    """runs/sphere.toml on a side x side grid of square cells (CELLS_PER_RADIUS per Hertz radius), rolled
    ``steps`` cells (one step per cell), every field saved, a checkpoint at the end; ``steady``: its steady
    state solved directly instead ([time] mode = "steady", the fields saved)."""
    from petroll.model.scene import load_scene, shipped_scene

    scene = load_scene(shipped_scene("sphere.toml"))
    radius = (scene.body.radius_hint * float(scene.penetration(0.0))) ** 0.5
    dx = radius / CELLS_PER_RADIUS
    length = side * dx
    grid = {"grid.nx": side, "grid.ny": side, "grid.x": [-length / 4, 3 * length / 4],
            "grid.y": [-length / 2, length / 2], "time.steady": None}
    if steady:
        return scene.replace({**grid, "time.mode": "steady", "time.distance": None, "output.every": None})
    return scene.replace({**grid, "time.distance": steps * dx, "output.every": 1,
                          "output.checkpoint_every": steps, "output.keep": 1})


def rss_mib() -> float:
    """This process's resident memory now, MiB (Linux /proc)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def peak_mib() -> float:
    """This process's peak resident memory so far (ru_maxrss), MiB."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def measure(side: int, steps: int, out: pathlib.Path, comm: MPI.Comm, steady: bool = False) -> dict:
    """Run the memory scene on ``comm`` into ``out``; every rank's fixed and peak memory, time per step."""
    from petroll.driver import run

    fixed = rss_mib()
    scene = memory_scene(side, steps, steady)
    comm.Barrier()
    start = time.perf_counter()
    results = run(scene, comm, out)
    wall = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    n = len(results.series["t"])
    peaks, fixeds = comm.gather(peak_mib(), root=0), comm.gather(fixed, root=0)
    return dict(side=side, cells=side * side, ranks=comm.size, steps=n, step_s=wall / n,
                peak_mib=peaks, fixed_mib=fixeds, force=float(results.series["force"][-1]))


def memory(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, sides: tuple[int, ...] = SIDES,
           ranks: tuple[int, ...] = RANKS, steps: int = 4, steady: bool = False) -> list[dict]:
    """Peak memory per rank for every grid side and rank count (``mpirun -n K`` children of this single
    process); ``steady``: the steady state solved directly (one step). Returns the rows; writes
    memory.csv and memory.png (steady: memory_steady.csv and .png)."""
    if comm.size != 1:
        raise PetrollError(f"petroll bench memory starts its own mpirun children: run it as one process, not "
                           f"under mpirun -n {comm.size}")
    rows = []
    for side in sides:
        for k in ranks:
            m = _mpirun(k, ["memory", str(side), str(steps), "steady" if steady else "transient"])
            peaks, fixed = np.array(m["peak_mib"]), np.array(m["fixed_mib"])
            rows.append(dict(side=side, cells=m["cells"], ranks=k, steps=m["steps"], step_s=m["step_s"],
                             rank0_mib=peaks[0], mean_mib=peaks.mean(), max_mib=peaks.max(),
                             rank0_over_mean=peaks[0] / peaks.mean(), fixed_mib=fixed.mean(),
                             run_mib=float((peaks - fixed).sum()), force=m["force"]))
            print(f"bench memory: {side}^2 on {k} ranks: peak {peaks.round(0).tolist()} MiB, "
                  f"{m['step_s']:.2f} s/step", flush=True)
    for r in rows:
        one = next((s for s in rows if s["side"] == r["side"] and s["ranks"] == 1), None)
        r["per_rank_vs_1"] = (r["mean_mib"] - r["fixed_mib"]) * r["ranks"] / (one["mean_mib"] - one["fixed_mib"]) \
            if one else float("nan")
    write_table([dict(r, step_s=f"{r['step_s']:.3f}", rank0_mib=f"{r['rank0_mib']:.0f}",
                  mean_mib=f"{r['mean_mib']:.0f}", max_mib=f"{r['max_mib']:.0f}",
                  rank0_over_mean=f"{r['rank0_over_mean']:.3f}", fixed_mib=f"{r['fixed_mib']:.0f}",
                  run_mib=f"{r['run_mib']:.0f}", per_rank_vs_1=f"{r['per_rank_vs_1']:.3f}",
                  force=f"{r['force']:.17g}") for r in rows], out / f"memory{'_steady' if steady else ''}.csv")
    _plot_memory(rows, out / f"memory{'_steady' if steady else ''}.png")
    return rows


def _plot_memory(rows: list[dict], path: pathlib.Path) -> None:
    figure = new_figure(10, 4.2)
    if figure is None:
        return
    left, right = figure.subplots(1, 2)
    for k in sorted({r["ranks"] for r in rows}):
        mine = [r for r in rows if r["ranks"] == k]
        cells = [r["cells"] for r in mine]
        left.loglog(cells, [r["mean_mib"] for r in mine], "o-", label=f"{k} rank{'s' if k > 1 else ''}: mean")
        left.loglog(cells, [r["rank0_mib"] for r in mine], "x:", color=left.lines[-1].get_color(),
                    label=f"{k}: rank 0")
        right.semilogx(cells, [r["step_s"] for r in mine], "o-", label=f"{k} rank{'s' if k > 1 else ''}")
    left.set(xlabel="grid cells", ylabel="peak resident memory per rank (MiB)",
             title="peak memory per rank (ru_maxrss)")
    right.set(xlabel="grid cells", ylabel="wall time per step (s)", title="time per rolling step")
    left.legend(fontsize=7)
    right.legend(fontsize=8)
    save_figure(figure, path)


# -- results.h5 appends ----------------------------------------------------------------------------------
def append_times(side: int, steps: int, path: pathlib.Path, comm: MPI.Comm) -> list[float]:
    """Seconds of each of ``steps`` appends (a side x side field each) to a new results file at path."""
    from petroll.io.results import ResultsFile
    from petroll.solver.partition import RowPartition
    from petroll.records import INTEGER_SERIES, SERIES, StepRecord

    x = np.linspace(0.0, 1.0, side)
    writer = ResultsFile(path, "", x, x, comm)
    r0, r1 = RowPartition(side, comm.size).range(comm.rank)
    rng = np.random.default_rng(comm.rank)
    local = np.zeros((r1 - r0, side))  # a contact patch's worth of non-zero values, like a pressure field
    patch = min(64, r1 - r0)
    records, seconds = [], []
    for step in range(steps):
        records.append(StepRecord(**{k: step if k in INTEGER_SERIES else 0.0 for k in SERIES}))
        local[:patch, :64] = rng.random((patch, min(64, side)))
        comm.Barrier()
        start = time.perf_counter()
        writer.append(records, {"pressure": local}, describe=False)
        seconds.append(comm.allreduce(time.perf_counter() - start, op=MPI.MAX))
    return seconds


def append(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, side: int = 512, steps: int = 1000,
           block: int = 100) -> list[dict]:
    """Time per append against the step number (on ``comm``); writes append.csv and append.png."""
    where = pathlib.Path(comm.bcast(tempfile.mkdtemp(prefix="petroll-bench-") if comm.rank == 0 else None))
    try:
        seconds = append_times(side, steps, where / "results.h5", comm)
        size = (where / "results.h5").stat().st_size if comm.rank == 0 else 0
    finally:
        comm.Barrier()
        if comm.rank == 0:
            shutil.rmtree(where, ignore_errors=True)
    rows = [dict(steps=f"{b}-{min(b + block, steps) - 1}", field=f"{side}x{side}", ranks=comm.size,
                 median_ms=1e3 * statistics.median(seconds[b : b + block]),
                 max_ms=1e3 * max(seconds[b : b + block])) for b in range(0, steps, block)]
    if comm.rank == 0:
        first, last = rows[0]["median_ms"], rows[-1]["median_ms"]
        print(f"bench append: median {first:.2f} ms per append over the first {block} steps, {last:.2f} ms "
              f"over the last {block} (ratio {last / first:.2f}); file {size / 2**20:.1f} MiB")
        write_table([dict(r, median_ms=f"{r['median_ms']:.3f}", max_ms=f"{r['max_ms']:.3f}") for r in rows],
                out / "append.csv")
        figure = new_figure(6, 4)
        if figure is not None:
            ax = figure.subplots()
            ax.plot(np.arange(steps), 1e3 * np.array(seconds), ",", alpha=0.5, label="each append")
            ax.plot([block * (i + 0.5) for i in range(len(rows))], [r["median_ms"] for r in rows], "o-",
                    label=f"median per {block} steps")
            ax.set(xlabel="step (appends so far)", ylabel="append time (ms)", ylim=(0, None),
                   title=f"results.h5: one {side}x{side} field per step, {comm.size} rank(s)")
            ax.legend()
            save_figure(figure, out / "append.png")
    return rows


def _mpirun(k: int, args: list[str]) -> dict:
    """This module's child (``args``) under ``mpirun -n k``; its JSON line."""
    return mpirun_child(k, "petroll.bench.memory", args, "bench memory")


def mpirun_child(k: int, module: str, args: list[str], what: str) -> dict:
    """``python -m module args DIR`` under ``mpirun -n k`` (DIR a temporary directory, removed after):
    its last line, JSON. PetrollError naming ``what`` if it fails."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_btl_vader_single_copy_mechanism="none")
    where = tempfile.mkdtemp(prefix="petroll-bench-")
    command = ["mpirun", "-n", str(k), *(["--oversubscribe"] if k > (os.cpu_count() or 1) else []),
               sys.executable, "-m", module, *args, where]
    try:
        done = subprocess.run(command, env=env, capture_output=True, text=True)
    finally:
        shutil.rmtree(where, ignore_errors=True)
    if done.returncode != 0:
        tail = " ".join((done.stderr or done.stdout).strip().splitlines()[-3:])
        raise PetrollError(f"{what}: mpirun -n {k} failed (exit {done.returncode}): {tail}")
    return json.loads(done.stdout.strip().splitlines()[-1])


if __name__ == "__main__":  # the child of ``bench memory``: memory SIDE STEPS MODE DIR, one JSON line on rank 0
    import petsc4py

    petsc4py.init([])
    measured = measure(int(sys.argv[2]), int(sys.argv[3]), pathlib.Path(sys.argv[5]), MPI.COMM_WORLD,
                       steady=sys.argv[4] == "steady")
    if MPI.COMM_WORLD.rank == 0:
        print(json.dumps(measured))
