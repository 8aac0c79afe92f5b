"""MPI scaling of the rolling step and of the direct steady solve.

``petroll bench mpi [--ranks 1,2] [--out DIR]``: time per rolling step (median of the warm steps) and
the convolutions' share of it on the growth scenes of windows 256^2 and 1024^2 cells; ``--steady
[--sides 2048]``: the time of the direct steady solve of ``bench memory --steady``'s scene (runs/sphere.toml
on side x side cells, [time] mode = "steady"), DIR/mpi_steady.csv and .png. Without
``--ranks``: on the current communicator (``mpirun -n K petroll bench mpi``). With ``--ranks``: rank
counts side by side, each an ``mpirun -n K`` child of this process, alternating the counts over the
repeats so that machine noise hits all of them; speedup T1 / TK, parallel efficiency T1 / (K TK), and the
largest relative difference of any step's force from that on the first rank count.

All functions are collective over ``comm``; rank 0 prints the table and writes DIR/mpi.csv and
DIR/mpi.png (matplotlib, if installed).
"""

from __future__ import annotations

import json
import os
import pathlib
import statistics
import subprocess
import sys

import numpy as np
from mpi4py import MPI

from petroll.errors import PetrollError
from petroll.bench.rolling import roll, rolling_scene
from petroll.studies.tables import new_figure, save_figure, write_table


def mpi_steps(windows: tuple[int, ...], steps: int, skip: int, comm: MPI.Comm,
              steady: bool = False) -> list[dict]:
    """Time per warm rolling step on ``comm`` for each window size (collective): the wall times of the
    steps from ``skip`` on (s, slowest rank), their median applications, the convolutions' share of the
    time, the force of every step (N) and the last mu_r. ``steady``: the direct steady solve (one step)
    of a grid of each side instead (petroll.bench.memory.memory_scene)."""
    from petroll.bench.memory import memory_scene

    out = []
    for n in windows:
        done = roll(memory_scene(n, 0, steady=True) if steady else rolling_scene(n, steps), comm)
        seconds = done["seconds"][skip:]
        out.append(dict(window=n, cells=float(n * n) if steady else float(done["cells"][skip:].mean()),
                        seconds=[float(s) for s in seconds],
                        applications=float(np.median(done["applications"][skip:])),
                        convolution_share=float(done["convolution"][skip:].sum() / seconds.sum()),
                        forces=done["forces"], mu_r=float(done["mu_r"])))
    return out


def mpi_scaling(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, windows: tuple[int, ...] = (256, 1024),
                ranks: tuple[int, ...] | None = None, steps: int = 6, skip: int = 3,
                repeats: int = 2, steady: bool = False, sides: tuple[int, ...] = (2048,)) -> list[dict]:
    """Time per rolling step against the rank count; returns the rows (numeric). ``ranks`` None: on
    ``comm``; otherwise each count runs as ``mpirun -n K`` children of this (single) process, ``repeats``
    times, the counts alternating in order. Times are medians over all timed steps of all repeats; the
    force difference is the largest relative one over all steps from the first rank count's. Writes
    mpi.csv and mpi.png (rank 0). ``steady``: the direct steady solves of grids of ``sides`` instead
    (``windows``, ``steps`` and ``skip`` unused), written to mpi_steady.csv and .png."""
    if steady:
        windows, skip = sides, 0
    if ranks is None:
        measured = {comm.size: [mpi_steps(windows, steps, skip, comm, steady)]}
        ranks = (comm.size,)
    else:
        if comm.size != 1:
            raise PetrollError(f"petroll bench mpi --ranks starts its own mpirun children: run it as one "
                               f"process, not under mpirun -n {comm.size}")
        measured = {k: [] for k in ranks}
        for repeat in range(repeats):
            for k in (ranks if repeat % 2 == 0 else ranks[::-1]):
                measured[k].append(_mpirun_steps(k, windows, steps, skip, steady))
    rows = []
    for i, n in enumerate(windows):
        runs = {k: [m[i] for m in measured[k]] for k in ranks}  # the repeats of each rank count
        t = {k: statistics.median(s for r in runs[k] for s in r["seconds"]) for k in ranks}
        k0, forces0 = ranks[0], np.array(runs[ranks[0]][0]["forces"])
        for k in ranks:
            first = runs[k][0]
            difference = max(float(np.max(np.abs(np.array(r["forces"]) / forces0 - 1))) for r in runs[k])
            rows.append(dict(window=f"{n}^2", cells=first["cells"], ranks=k,
                             timed_steps=sum(len(r["seconds"]) for r in runs[k]), step_s=t[k],
                             applications=first["applications"],
                             convolution_share=statistics.median(r["convolution_share"] for r in runs[k]),
                             speedup=t[k0] / t[k], efficiency=t[k0] * k0 / (k * t[k]),
                             force=first["forces"][-1], force_difference=difference, mu_r=first["mu_r"]))
    if comm.rank == 0:
        write_table([dict(r, cells=f"{r['cells']:.0f}", step_s=f"{r['step_s']:.4f}",
                      applications=f"{r['applications']:.0f}", speedup=f"{r['speedup']:.2f}",
                      convolution_share=f"{r['convolution_share']:.0%}", efficiency=f"{r['efficiency']:.0%}",
                      force=f"{r['force']:.10g}", force_difference=f"{r['force_difference']:.1e}",
                      mu_r=f"{r['mu_r']:.8g}") for r in rows], out / f"mpi{'_steady' if steady else ''}.csv")
        _plot_mpi(rows, out / f"mpi{'_steady' if steady else ''}.png", steady)
    return rows


def _mpirun_steps(k: int, windows: tuple[int, ...], steps: int, skip: int, steady: bool) -> list[dict]:
    """:func:`mpi_steps` on ``k`` ranks, an ``mpirun -n k`` child running this module."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_btl_vader_single_copy_mechanism="none")
    command = ["mpirun", "-n", str(k), *(["--oversubscribe"] if k > (os.cpu_count() or 1) else []),
               sys.executable, "-m", "petroll.bench.mpi", ",".join(map(str, windows)), str(steps),
               str(skip), "steady" if steady else "transient"]
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    if done.returncode != 0:
        tail = " ".join((done.stderr or done.stdout).strip().splitlines()[-3:])
        raise PetrollError(f"bench mpi: mpirun -n {k} failed (exit {done.returncode}): {tail}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def _plot_mpi(rows: list[dict], path: pathlib.Path, steady: bool) -> None:
    figure = new_figure(5.5, 4.2)
    if figure is None:
        return
    ax = figure.subplots()
    for window in dict.fromkeys(r["window"] for r in rows):
        pts = [r for r in rows if r["window"] == window]
        ax.plot([r["ranks"] for r in pts], [r["step_s"] for r in pts], "o-",
                label=f"{'grid' if steady else 'window'} {window} cells")
        ideal = [pts[0]["step_s"] * pts[0]["ranks"] / r["ranks"] for r in pts]
        ax.plot([r["ranks"] for r in pts], ideal, "k:", lw=0.8)
    ax.set_xlabel("MPI ranks")
    ax.set_ylabel("time of the steady solve (s)" if steady else "time per rolling step (s)")
    ax.set_yscale("log")
    ax.set_xticks(sorted({r["ranks"] for r in rows}))
    ax.set_title(f"{'steady solve' if steady else 'median warm step'} (dotted: ideal)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(figure, path)


if __name__ == "__main__":  # the child of ``bench mpi --ranks``: WINDOWS STEPS SKIP steady|transient, one JSON line

    import petsc4py

    petsc4py.init([])
    measured = mpi_steps(tuple(int(w) for w in sys.argv[1].split(",")), int(sys.argv[2]), int(sys.argv[3]),
                         MPI.COMM_WORLD, sys.argv[4] == "steady")
    if MPI.COMM_WORLD.rank == 0:
        print(json.dumps(measured))
