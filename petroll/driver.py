"""Run a scene to its end with its files: the time loop of :mod:`petroll.solver` with the results and
checkpoints of :mod:`petroll.io` (``petroll.run`` and ``petroll run``).

All functions are collective over ``comm``: every rank calls them with the same scene.
"""

from __future__ import annotations

import math
import os
import pathlib
import sys
import time as clock

import numpy as np
from mpi4py import MPI

from petroll.io.checkpoint import RunInterrupted, checkpoint_dir, write_checkpoint
from petroll.io.results import OutputError, Results, write_results
from petroll.model.scene import Scene
from petroll.solver.partition import gather_field
from petroll.solver.simulation import Simulation, StepRecord


def run(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, out: str | pathlib.Path | None = None,
        progress: bool = False, restart=None, stop=None, on_step=None) -> Results:
    """Run a scene to its end and write ``<out>/results.h5`` (default out: the scene's [output] dir).

    Returns the results read back from the file, on every rank. ``progress`` prints a status line on
    rank 0's stderr after every step.

    Checkpoints (docs/checkpoints.md): with ``[output] checkpoint_every`` = k > 0, after every k-th step
    and after the last one, ``<out>/checkpoints/step-NNNNNNNN.h5`` is written and results.h5 is rewritten
    (atomically) with the series and fields so far. ``restart`` (a :class:`petroll.io.checkpoint.Checkpoint`
    of a compatible scene, see ``restart_scene``) continues that run from its step: the results then hold
    the whole run, identical to an uninterrupted one. ``stop`` (a :class:`petroll.io.checkpoint.StopRequest`)
    is agreed on by the ranks after every step: once set, the run writes a checkpoint and the results so
    far and raises :class:`petroll.io.checkpoint.RunInterrupted`. ``on_step(record)`` is called on every rank
    after every step.
    """
    out = pathlib.Path(out) if out is not None else scene.output_dir
    prepare_output(out, comm)
    sim = Simulation(scene, comm)
    g = scene.grid
    if restart is not None:
        t, fields, field_steps = restart.restore(sim)
    else:
        t, fields, field_steps = 0.0, [], []
    resumed = restart is not None  # the first record is the restored step's, not solved again
    wall = clock.perf_counter()
    for record in sim.steps(t):
        stop_now = sim.dt_next is None
        if not resumed and (stop_now or record.step == 0 or (scene.every and record.step % scene.every == 0)):
            fields.append(gather_field(sim.pressure, g.nx, comm))
            field_steps.append(record.step)
        if on_step is not None:
            on_step(record)
        signum = stop.agreed(comm) if stop is not None else 0
        interrupted = bool(signum) and not stop_now
        every = scene.checkpoint_every
        due = every and not resumed and ((record.step > 0 and record.step % every == 0) or stop_now)
        if progress and comm.rank == 0:
            _show_progress(scene, record, clock.perf_counter() - wall)
        if due or interrupted:
            path = write_checkpoint(checkpoint_dir(out), sim, sim.t, sim.dt_next, fields, field_steps,
                                    scene.keep)
            if not stop_now:
                _write_results(out, sim, fields, field_steps, complete=False)
            if interrupted:
                if progress and comm.rank == 0:
                    print(file=sys.stderr)
                raise RunInterrupted(signum, record.step, record.t, path)
        resumed = False
    if progress and comm.rank == 0:
        print(file=sys.stderr)
    return Results.open(_write_results(out, sim, fields, field_steps, complete=True))


def prepare_output(out: pathlib.Path, comm: MPI.Comm) -> None:
    """Create the output directory and check that files can be made in it (collective): OutputError with
    one line otherwise, before any step is computed."""
    message = None
    if comm.rank == 0:
        probe = out / f".petroll-write-test.{os.getpid()}"
        try:
            out.mkdir(parents=True, exist_ok=True)
            probe.write_bytes(b"")
            probe.unlink()
        except OSError as exc:
            message = f"{out}: cannot write to the output directory ({exc.strerror or exc})"
    message = comm.bcast(message, root=0)
    if message is not None:
        raise OutputError(message)


def _write_results(out: pathlib.Path, sim: Simulation, fields: list, field_steps: list[int],
                   complete: bool) -> pathlib.Path:
    """Rank 0 writes ``out/results.h5`` (and results.xdmf) atomically; collective, errors on every rank."""
    comm, g = sim.comm, sim.scene.grid
    path = out / "results.h5"
    message = None
    if comm.rank == 0:
        series = {name: np.array([getattr(r, name) for r in sim.records])
                  for name in StepRecord.__annotations__}
        try:
            write_results(path, series, np.array(fields).reshape(-1, g.nx, g.ny), np.array(field_steps), g.x,
                          g.y, sim.scene.text, complete=complete, line=g.line)
        except OutputError as exc:
            message = str(exc)
    message = comm.bcast(message, root=0)
    if message is not None:
        raise OutputError(message)
    return path


def _show_progress(scene: Scene, r: StepRecord, wall: float) -> None:
    tm = scene.time
    done = (r.t / tm.end if tm.end else r.distance / tm.distance if tm.distance else 1.0) or 1e-12
    left = wall * (1 / done - 1) if done > 0 else math.nan
    print(f"\rstep {r.step:6d}  t {r.t:.4g} s  distance {r.distance:.4g} m  force {r.force:.5g} N  "
          f"mu_r {r.mu_r:+.4e}  left ~{left:.0f} s   ", end="", file=sys.stderr, flush=True)


