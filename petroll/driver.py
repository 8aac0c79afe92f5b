"""Run a scene to its end with its files: the time loop of :mod:`petroll.solver` with the results and
checkpoints of :mod:`petroll.io` (``petroll.run`` and ``petroll run``); and the stresses below a saved
pressure field (``petroll.stress`` and ``petroll stress``).

All functions are collective over ``comm``: every rank calls them with the same scene.
"""

from __future__ import annotations

import math
import os
import pathlib
import sys
import time as clock
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from petroll.errors import PetrollError
from petroll.io.checkpoint import RunInterrupted, checkpoint_dir, run_directory, write_checkpoint
from petroll.io.results import OutputError, Results, ResultsFile
from petroll.model.scene import Scene
from petroll.solver.simulation import Simulation, StepRecord


def run(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, out: str | pathlib.Path | None = None,
        progress: bool = False, restart=None, stop=None, on_step=None, steady_start=None) -> Results:
    """Run a scene to its end and write ``<out>/results.h5`` (default out: the scene's [output] dir).

    Returns the results read back from the file, on every rank. ``progress`` prints a status line on
    rank 0's stderr after every step.

    results.h5 grows as the run goes (docs/results.md): the series and each saved field are appended when
    a field is saved, at every checkpoint and at the end. Checkpoints (docs/checkpoints.md): with
    ``[output] checkpoint_every`` = k > 0, after every k-th step and after the last one,
    ``<out>/checkpoints/step-NNNNNNNN.h5`` is written (after results.h5 is brought up to that step).
    ``restart`` (a :class:`petroll.io.checkpoint.Checkpoint` of a compatible scene, see ``restart_scene``)
    continues that run from its step: results.h5 of the checkpoint's run is continued (copied to ``out``
    first if that is another directory) and then holds the whole run, identical to an uninterrupted one. ``stop`` (a :class:`petroll.io.checkpoint.StopRequest`)
    is agreed on by the ranks after every step: once set, the run writes a checkpoint and the results so
    far and raises :class:`petroll.io.checkpoint.RunInterrupted`. ``on_step(record)`` is called on every rank
    after every step. ``steady_start`` ([time] mode = "steady" only): the first guess of the steady solve,
    (whole-grid pressure in Pa, penetration in m), e.g. a neighbouring steady state (continuation).
    """
    out = pathlib.Path(out) if out is not None else scene.output_dir
    prepare_output(out, comm)
    sim = Simulation(scene, comm)
    sim.steady_start = steady_start
    g = scene.grid
    steady = scene.time.mode == "steady"
    results = ResultsFile(out / "results.h5", scene.text, g.x, g.y, comm, fields=scene.fields, line=g.line,
                          steady=steady, source=str(scene.source))
    if restart is not None:
        t, field_steps = restart.restore(sim)
        results.resume(run_directory(restart.path) / "results.h5", len(sim.records), field_steps)
    else:
        t = 0.0
    resumed = restart is not None  # the first record is the restored step's, not solved again
    wall = clock.perf_counter()
    for record in sim.steps(t):
        stop_now = sim.dt_next is None
        save = not resumed and (stop_now or record.step == 0
                                or bool(scene.every and record.step % scene.every == 0))
        if on_step is not None:
            on_step(record)
        signum = stop.agreed(comm) if stop is not None else 0
        interrupted = bool(signum) and not stop_now
        every = 0 if steady else scene.checkpoint_every  # a steady solve is one step: nothing to resume
        due = every and not resumed and ((record.step > 0 and record.step % every == 0) or stop_now)
        if progress and comm.rank == 0:
            _show_progress(scene, record, clock.perf_counter() - wall)
        if save or due or interrupted or stop_now:  # the results first: a checkpoint's fields are in them
            results.append(sim.records, saved_fields(sim) if save else None, complete=stop_now,
                           describe=bool(due or interrupted or stop_now))
        if due or interrupted:
            path = write_checkpoint(checkpoint_dir(out), sim, sim.t, sim.dt_next, results.field_steps,
                                    scene.keep)
            if interrupted:
                if progress and comm.rank == 0:
                    print(file=sys.stderr)
                raise RunInterrupted(signum, record.step, record.t, path)
        resumed = False
    if progress and comm.rank == 0:
        print(file=sys.stderr)
    return Results.open(results.path)


def saved_fields(sim: Simulation) -> dict[str, np.ndarray]:
    """The fields of ``[output] fields`` at the newest step, this rank's rows: pressure (Pa) and, when
    asked, the surface displacement and the gap (m, from ``Simulation.surface``: one more convolution)."""
    fields = {"pressure": sim.pressure}
    if len(sim.scene.fields) > 1:
        fields["displacement"], fields["gap"] = sim.surface()
    return fields


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


def _show_progress(scene: Scene, r: StepRecord, wall: float) -> None:
    tm = scene.time
    done = (r.t / tm.end if tm.end else r.distance / tm.distance if tm.distance else 1.0) or 1e-12
    left = wall * (1 / done - 1) if done > 0 else math.nan
    print(f"\rstep {r.step:6d}  t {r.t:.4g} s  distance {r.distance:.4g} m  force {r.force:.5g} "
          f"{'N/m' if scene.grid.line else 'N'}  "
          f"mu_r {r.mu_r:+.4e}  left ~{left:.0f} s   ", end="", file=sys.stderr, flush=True)




AUTO_DEPTHS = 41
"""Depths of ``depths="auto"``: 0 to twice the contact's smaller half-width, evenly spaced (a/20 apart)."""


@dataclass(frozen=True)
class StressSummary:
    """What ``petroll stress`` computed: stress.h5's path and the maxima over the depths computed.

    Locations are (x, y, z) in m (x, y in the material frame, z the depth); stresses in Pa."""

    path: pathlib.Path
    step: int
    t: float  # s
    z: np.ndarray  # depths, m
    nu: float
    von_mises_max: float
    von_mises_at: tuple[float, float, float]
    max_shear_max: float  # Tresca: half the largest principal stress difference
    max_shear_at: tuple[float, float, float]
    p_max: float  # the surface pressure's peak, Pa


def stress(run_dir: str | pathlib.Path, step: int | None = None, depths=None, nu: float | None = None,
           comm: MPI.Comm = MPI.COMM_WORLD) -> StressSummary:
    """The stresses below the pressure saved at ``step`` (None: the last saved field) of the run in
    ``run_dir``, written to ``run_dir/stress.h5`` (layout: petroll/io/stress.py, docs/results.md).

    ``depths``: the depths z >= 0 in m, or None / "auto" (0 to twice the contact's smaller half-width, 41
    depths). ``nu``: Poisson's ratio, default the scene's [material] nu (a constant nu makes the stresses of a
    viscoelastic half-space the elastic ones of the current pressure). Collective over ``comm`` (rows split);
    returns the same summary on every rank.
    """
    import tomllib

    from petroll.io.stress import read_saved_pressure, write_stress
    from petroll.solver.stress import SubsurfaceStress, max_shear, von_mises

    run_dir = pathlib.Path(run_dir)
    path = run_dir / "results.h5"
    if not path.is_file():
        raise PetrollError(f"{path}: no results file (is {run_dir} the output directory of a run?)")
    saved = read_saved_pressure(path, step, comm)
    raw = tomllib.loads(saved["scene"])
    nu = _poisson_ratio(raw, nu)
    x, y, p = saved["x"], saved["y"], saved["pressure"]
    g, line = raw["grid"], saved["line"]
    dx = (g["x"][1] - g["x"][0]) / g["nx"]
    dy = 1.0 if line else (g["y"][1] - g["y"][0]) / g["ny"]
    r0, r1 = saved["rows"]
    z = _depths(depths, p, x[r0:r1], y, dx, dy, saved["step"], comm, line)
    solver = SubsurfaceStress(len(x), len(y), dx, dy, nu, comm, line)
    best = {"von_mises": (-1.0, (0.0, 0.0, 0.0)), "max_shear": (-1.0, (0.0, 0.0, 0.0))}

    def fields():
        for depth in z:
            s = solver.at(p, float(depth))
            out = np.concatenate([s, von_mises(s)[None], max_shear(s)[None]])
            for name, field in (("von_mises", out[6]), ("max_shear", out[7])):
                if field.size:
                    i, j = np.unravel_index(int(np.argmax(field)), field.shape)
                    if field[i, j] > best[name][0]:
                        best[name] = (float(field[i, j]), (float(x[r0 + i]), float(y[j]), float(depth)))
            yield out

    d = np.array([saved["sx"][-1] - saved["sx"][0], saved["sy"][-1] - saved["sy"][0]])
    attrs = {"step": saved["step"], "t": saved["t"], "nu": nu, "source": str(path), "line_contact": line,
             "motion_axis": "y" if abs(d[1]) > abs(d[0]) else "x"}
    target = run_dir / "stress.h5"

    top = {}

    def attributes() -> dict:  # collective: the maxima over all ranks (ties: the lowest rank's first)
        for name, value in best.items():
            top[name] = max(comm.allgather(value), key=lambda v: v[0])
        return {**attrs, **{f"{name}_max": value for name, (value, _) in top.items()},
                **{f"{name}_at": np.array(at) for name, (_, at) in top.items()}}

    write_stress(target, z, x, y, fields(), attributes, comm, line)
    p_max = comm.allreduce(float(p.max(initial=0.0)), op=MPI.MAX)
    return StressSummary(target, saved["step"], saved["t"], z, nu, top["von_mises"][0], top["von_mises"][1],
                         top["max_shear"][0], top["max_shear"][1], p_max)


def _poisson_ratio(raw: dict, nu: float | None) -> float:
    """Poisson's ratio for the stresses: ``nu`` if given, else the scene's [material] nu (checked). A
    layer on a rigid base ([material] layer) is refused: the stresses computed are a half-space's."""
    if "layer" in raw.get("material", {}):
        raise PetrollError(f"[material] layer = {raw['material']['layer']!r}: petroll stress computes the "
                           "stresses of a half-space only, not of a layer on a rigid base")
    if nu is None:
        nu = raw.get("material", {}).get("nu")
        if nu is None:
            raise PetrollError("[material] nu: the run's scene gives no Poisson's ratio (a tabulated J); the "
                               "stresses need one: give --nu (-1 < nu <= 0.5)")
    if isinstance(nu, bool) or not isinstance(nu, (int, float)) or not -1 < nu <= 0.5:
        raise PetrollError(f"--nu {nu!r}: Poisson's ratio must be a number with -1 < nu <= 0.5")
    return float(nu)


def _depths(depths, p: np.ndarray, x: np.ndarray, y: np.ndarray, dx: float, dy: float, step: int,
            comm: MPI.Comm, line: bool = False) -> np.ndarray:
    """The depths (m, sorted) for :func:`stress`: the given ones (each finite, >= 0), or for None / "auto"
    ``AUTO_DEPTHS`` from 0 to twice the smaller half-width of the contact (cells with p > 0, all ranks;
    line contact: its half-width)."""
    if depths is not None and not (isinstance(depths, str) and depths == "auto"):
        if isinstance(depths, str):
            raise PetrollError(f"--depths {depths!r}: only 'auto' is allowed (or give --depth z1,z2,...)")
        z = np.asarray(depths, dtype=float).ravel()
        if z.size == 0 or not np.all(np.isfinite(z)) or np.any(z < 0):
            raise PetrollError(f"--depth {','.join(f'{v:g}' for v in z)}: depths must be finite numbers >= 0 "
                               "(m, below the surface)")
        return np.unique(z)
    ix, iy = np.nonzero(p > 0)
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    comm.Allreduce(np.array([x[ix].min(), y[iy].min()]) if ix.size else lo.copy(), lo, op=MPI.MIN)
    comm.Allreduce(np.array([x[ix].max(), y[iy].max()]) if ix.size else hi.copy(), hi, op=MPI.MAX)
    if not np.all(np.isfinite(lo)):
        raise PetrollError(f"step {step}: no contact (the pressure is 0 everywhere), so --depths auto has no "
                           "contact size to go by; give --depth z1,z2,... (m)")
    half = (hi[0] - lo[0] + dx) / 2 if line else min((hi[0] - lo[0] + dx) / 2, (hi[1] - lo[1] + dy) / 2)
    return np.linspace(0.0, 2 * half, AUTO_DEPTHS)
