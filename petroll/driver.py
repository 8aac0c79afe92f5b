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
import uuid
import warnings
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from petroll.errors import PetrollError, SceneError, SolverError, reason
from petroll.io.checkpoint import RunInterrupted, checkpoint_dir, fingerprint, run_directory
from petroll.io.checkpoint_writer import remove_foreign_checkpoints, write_checkpoint
from petroll.io.results import OutputError, Results, ResultsFile, results_identity
from petroll.io.rundir import DirectoryBusy, RunLock, clean_temporaries
from petroll.model.clock import TimeMode
from petroll.model.limits import PetrollWarning, negative_friction
from petroll.model.preflight import check_run
from petroll.model.scene import Scene
from petroll.records import StepRecord, series_rows
from petroll.solver.allocation import LargeBlocksMapped
from petroll.solver.rough import BINS
from petroll.solver.simulation import Simulation
from petroll.studies.target import asks_target, targeted


def run(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, out: str | pathlib.Path | None = None,
        progress: bool = False, restart=None, stop=None, on_step=None, steady_start=None,
        overwrite: bool = False, estimate_error: bool = False) -> Results:
    """Run a scene to its end and write ``<out>/results.h5`` (default out: the scene's [output] dir).

    Before step 1 the scene's contact is estimated and the grid's resolution of it checked
    (petroll.model.preflight.check_run: a PetrollWarning below 8 cells per contact half-width, SceneError
    below 2 unless [grid] allow_coarse = true), and its path: SceneError for a body that never presses or
    whose contact region would reach the grid's edge. Returns the results read back from the file, on every rank. ``progress`` prints a status line on
    rank 0's stderr after every step.

    results.h5 grows as the run goes (docs/results.md): the series and each saved field are appended when
    a field is saved, at every checkpoint and at the end. Checkpoints (docs/checkpoints.md): with
    ``[output] checkpoint_every`` = k > 0, after every k-th step and after the last one,
    ``<out>/checkpoints/step-NNNNNNNN.h5`` is written (after results.h5 is brought up to that step).
    ``restart`` (a :class:`petroll.io.checkpoint.Checkpoint` of a compatible scene, see ``restart_scene``)
    continues that run from its step: results.h5 of the checkpoint's run is continued (copied to ``out``
    first if that is another directory) and then holds the whole run, identical to an uninterrupted one;
    it must be that run's (same run id, scene, grid and series up to the step), or nothing is touched.
    ``stop`` (a :class:`petroll.io.checkpoint.StopRequest`) is agreed on by the ranks after every step:
    once set, the run writes a checkpoint and the results so far and raises
    :class:`petroll.io.checkpoint.RunInterrupted`. ``on_step(record)`` is called on every rank after every
    step. ``steady_start`` ([time] mode = "steady" only): the first guess of the steady solve, (whole-grid
    pressure in Pa, penetration in m), e.g. a neighbouring steady state (continuation).
    ``estimate_error``: after the run, solve the scene again on grids 2x (and 4x) coarser and write the
    discretisation error of the last step's force, mu_r, p_max, area, lead and trail to results.h5's group
    error_estimate (petroll.studies.estimate; ``Results.error_estimate``; docs/accuracy.md).
    A scene with ``[grid] target_error`` is first sized for it (petroll.studies.target.targeted: a pilot
    on coarser grids, then the scene on the grid chosen; SceneError where it needs too fine a grid).
    A step that fails (SolverError, e.g. a contact reaching the grid's edge; SceneError, [time] max_steps)
    raises :class:`RunFailed` naming the scene file, the step, its time and the distance rolled, after
    every step solved before it is written to results.h5 (complete = false).

    ``out`` is held by this run alone (``out/petroll.lock``, released on every rank when run returns or raises
    an error of the run; OutputError if another process holds it), and
    results of another scene there (or of the same scene text over a changed [material] file or [body]
    file; another run's, for a restart into another directory) are refused with
    OutputError unless ``overwrite``. A results file that cannot be written stops the run with OutputError
    on every rank, results.h5 holding the steps of its last complete append.
    """
    if restart is None and asks_target(scene):  # the cells its [grid] target_error needs, from a pilot
        scene = targeted(scene, comm)
    out = pathlib.Path(out) if out is not None else scene.output_dir
    # before anything is written: touching, path, resolution (petroll.model.preflight); kept for the estimate
    preflight = check_run(scene) if restart is None else None
    lock = claim_output(out, comm, f"petroll run {scene.source}" if restart is None else
                        f"petroll restart {restart.path}")
    collective = True  # raised on every rank alike (or returned): the ranks wait for the lock's release
    try:
        run_id, inputs = _run_identity(out, scene, comm, restart, overwrite)
        with LargeBlocksMapped(scene.grid.topology.whole):
            return _run(scene, comm, out, (run_id, inputs), progress, restart, stop, on_step, steady_start,
                        preflight, estimate_error)
    except BaseException as exc:
        collective = isinstance(exc, (PetrollError, RunInterrupted))
        raise
    finally:
        if lock is not None:
            lock.release()
        if collective:  # so that on return ``out`` is free (no petroll.lock) on every rank
            comm.Barrier()


def _run(scene: Scene, comm: MPI.Comm, out: pathlib.Path, identity: tuple[str, str], progress: bool, restart,
         stop, on_step, steady_start, preflight, estimate_error: bool) -> Results:
    """The time loop of :func:`run`, its output directory claimed; ``identity``: the run id and the
    fingerprint of the material and body (rank 0's; :func:`_run_identity`); ``preflight``: the scene's
    checks (petroll.model.preflight.Preflight) where the run made them, for the error estimate."""
    run_id, inputs = identity
    warned = [preflight.warned] if preflight is not None and preflight.warned else []  # stored in results.h5
    sim = Simulation(scene, comm)
    sim.steady_start = steady_start
    g = scene.grid
    steady = scene.time.mode is TimeMode.STEADY
    rough = BINS if g.topology.statistics else None  # the group rough of a 3-D grid periodic along both axes
    results = ResultsFile(out / "results.h5", scene.text, g.x, g.y, comm, fields=scene.fields, line=g.line,
                          steady=steady, source=str(scene.source), run_id=run_id, rough=rough,
                          fingerprint=inputs, friction=scene.friction is not None)
    if restart is not None:
        t, field_steps = restart.restore(sim)
        results.resume(run_directory(restart.path) / "results.h5", len(sim.records), field_steps,
                       check=restart.matches)
    else:
        t = 0.0
    resumed = restart is not None  # the first record is the restored step's, not solved again
    newest = restart.path if restart is not None else None  # this run's newest checkpoint
    wall = clock.perf_counter()
    steps = sim.steps(t)
    while True:
        try:
            record = next(steps, None)
        except (SolverError, SceneError) as exc:  # a step failed (on every rank alike): keep what was solved
            raise _failure(scene, sim, results, newest, exc, progress) from None
        if record is None:
            break
        stop_now = sim.dt_next is None
        save = not resumed and (stop_now or record.step == 0
                                or bool(scene.every and record.step % scene.every == 0))
        if stop_now and (negative := negative_friction(scene, record.mu_r)) is not None:
            warnings.warn(PetrollWarning(negative), stacklevel=2)
            warned.append(negative)
        if on_step is not None:
            on_step(record)
        signum = stop.agreed(comm) if stop is not None else 0
        interrupted = bool(signum) and not stop_now
        every = 0 if steady else scene.checkpoint_every  # a steady solve is one step: nothing to resume
        due = every and not resumed and ((record.step > 0 and record.step % every == 0) or stop_now)
        # a run with an error estimate keeps its last step's checkpoint: the estimate can be resumed from it
        due = due or (estimate_error and stop_now and not steady and not resumed)
        if progress and comm.rank == 0:
            _show_progress(scene, record, clock.perf_counter() - wall)
        if save or due or interrupted or stop_now:  # the results first: a checkpoint's fields are in them
            # with an error estimate the run is complete once the estimate is written, not before
            _append(results, sim, save, stop_now and not estimate_error, bool(due or interrupted or stop_now),
                    newest, warned)
        if (record.step == 0 or resumed) and comm.rank == 0:  # results.h5 is this run's now: so are they
            remove_foreign_checkpoints(checkpoint_dir(out), run_id)
        if due or interrupted:
            newest = write_checkpoint(checkpoint_dir(out), sim, sim.t, sim.dt_next, results.field_steps,
                                      scene.keep, run_id=run_id, inputs=inputs)
            if interrupted:
                if progress and comm.rank == 0:
                    print(file=sys.stderr)
                raise RunInterrupted(signum, record.step, record.t, newest)
        resumed = False
    if progress and comm.rank == 0:
        print(file=sys.stderr)
    if estimate_error:
        from petroll.studies.estimate import as_attributes
        from petroll.studies.estimate import estimate_error as estimate

        run_wall = clock.perf_counter() - wall  # the run alone: its steps and output, not the estimate
        last = sim.records[-1]

        def agreed_stop():  # after each step of the coarser runs, as after each of the run's
            signum = stop.agreed(comm) if stop is not None else 0
            if signum:
                raise RunInterrupted(signum, last.step, last.t, newest, estimating=True)

        per, attrs = as_attributes(estimate(scene, last, comm, preflight, after_step=agreed_stop))
        results.write_error_estimate(per, {**attrs, "run_wall_s": run_wall}, complete=True)
    return Results.open(results.path)


def _append(results: ResultsFile, sim: Simulation, save: bool, complete: bool, describe: bool,
            newest: pathlib.Path | None, warned=()) -> None:
    """Bring results.h5 up to the newest step, with the run's warnings so far (``warned``, one line each:
    the attribute warnings); a failure (OutputError, every rank) says what the file holds and how the run
    continues (``newest``: this run's newest checkpoint)."""
    try:
        rough = sim.rough_outputs() if save and results.rough is not None else None
        results.append(_rows(sim), saved_fields(sim) if save else None, complete=complete, describe=describe,
                       rough=rough, warnings=warned)
    except OutputError as exc:
        n = results.steps
        kept = f"results.h5 holds steps 0 to {n - 1}" if n else "no results file was written"
        then = (f"free space (or fix the cause) and continue with: petroll restart {newest}" if newest else
                "free space (or fix the cause) and run the scene again")
        raise OutputError(f"{exc}; {kept}; {then}") from None


def _rows(sim: Simulation) -> list:
    """The rows of ``sim``'s series: its StepRecords, joined with their FrictionRecords with [friction]."""
    return series_rows(sim.records, None if sim.friction is None else sim.friction.records)


class RunFailed(PetrollError):
    """A step failed after ``steps`` >= 1 steps were solved: results.h5 (``results``) holds them, marked
    complete = false; ``checkpoint``: the newest checkpoint (or None)."""

    def __init__(self, message: str, results: pathlib.Path, steps: int, checkpoint: pathlib.Path | None):
        super().__init__(message)
        self.results, self.steps, self.checkpoint = results, steps, checkpoint


def _failure(scene: Scene, sim: Simulation, results: ResultsFile, checkpoint, exc: Exception,
             progress: bool) -> Exception:
    """Write every step solved before ``exc`` to results.h5 (complete = false) and say where the run
    stopped (scene file, step, time, distance) and what it kept (collective): the RunFailed to raise
    (``exc`` itself where no step was solved)."""
    if progress and sim.comm.rank == 0:
        print(file=sys.stderr)
    done = len(sim.records)
    if not done:  # nothing solved, nothing kept: the error as it is
        return exc
    results.append(_rows(sim), None, complete=False, describe=True)
    t, rolled = sim.t + (sim.dt_next or 0.0), sim.records[-1].distance
    kept = f"{results.path} holds the {done} step{'s' * (done != 1)} solved before it (complete = false)"
    kept += f"; last checkpoint: {checkpoint}" if checkpoint is not None else "; no checkpoint"
    cause = f"{exc.key} = {exc.value!r}: {exc.allowed}" if isinstance(exc, SceneError) else str(exc)
    message = (f"{scene.source}: step {done} (t = {t:.6g} s, {rolled:.6g} m rolled) failed: "
               f"{' '.join(cause.split())}. {kept}")
    return RunFailed(message, results.path, done, checkpoint)


def saved_fields(sim: Simulation) -> dict[str, np.ndarray]:
    """The fields of ``[output] fields`` at the newest step, this rank's rows: pressure (Pa) and, when
    asked, the surface displacement and the gap (m, from ``Simulation.surface``: one more convolution); with
    friction the tangential tractions (Pa) and the slip velocity (m/s)."""
    fields = {"pressure": sim.pressure, **(sim.friction.fields if sim.friction is not None else {})}
    if "displacement" in sim.scene.fields:
        fields["displacement"], fields["gap"] = sim.surface()
    return fields


def prepare_output(out: pathlib.Path, comm: MPI.Comm) -> None:
    """Create the output directory and check that files can be made in it (collective): OutputError with
    one line otherwise, before any step is computed."""
    message = _writable(out) if comm.rank == 0 else None
    message = comm.bcast(message, root=0)
    if message is not None:
        raise OutputError(message)


def _writable(out: pathlib.Path) -> str | None:
    """Why files cannot be written in ``out`` (made if missing), or None."""
    probe = out / f".petroll-write-test.tmp{os.getpid()}"
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        return f"{out}: cannot write to the output directory ({exc.strerror or exc})"
    return None


def claim_output(out: pathlib.Path, comm: MPI.Comm, what: str) -> RunLock | None:
    """Make ``out`` writable (as :func:`prepare_output`) and lock it for this run (rank 0 holds the lock,
    returned there; None elsewhere); the temporary files of writers killed earlier are removed. Collective:
    OutputError on every rank if the directory cannot be written or another process holds it."""
    lock, message = None, None
    if comm.rank == 0:
        message = _writable(out)
        if message is None:
            lock = RunLock(out, what)
            try:
                lock.acquire()
                for directory in (out, checkpoint_dir(out)):
                    clean_temporaries(directory)
            except DirectoryBusy as exc:
                message, lock = str(exc), None
            except OSError as exc:
                message, lock = f"{out}: cannot lock the output directory ({reason(exc)})", None
    message = comm.bcast(message, root=0)
    if message is not None:
        raise OutputError(message)
    return lock


def _run_identity(out: pathlib.Path, scene: Scene, comm: MPI.Comm, restart, overwrite: bool
                  ) -> tuple[str, str]:
    """The run id of this run (a new one, or the checkpoint's run's) and, on rank 0 ("" on the others), the
    fingerprint of its material and body (petroll.io.checkpoint.fingerprint), after checking that ``out``
    holds no results that it would replace without ``overwrite``: another scene's (a new run: another
    scene text, or the same text naming a [material] file or [body] file that changed since), another
    run's (a restart into another directory than its run's). Collective; OutputError on every rank."""
    message, run_id, inputs = None, None, ""
    if comm.rank == 0:
        path = out / "results.h5"
        held = results_identity(path) if path.is_file() else None
        inputs = fingerprint(scene)
        if restart is None:
            run_id = uuid.uuid4().hex
            state = "complete" if held is not None and held["complete"] else "unfinished"
            if held is not None and held["scene"] != scene.text and not overwrite:
                message = (f"{out}: holds the {state} results of another scene ({path}); give --overwrite "
                           "(Python: overwrite=True) to replace them, or another output directory")
            elif held is not None and held["fingerprint"] not in ("", inputs) and not overwrite:
                message = (f"{out}: holds the {state} results of this scene with another material or body "
                           f"({path}): a file it names ([material] file or [body] file) has changed since; "
                           "give --overwrite (Python: overwrite=True) to replace them, or another output "
                           "directory")
        else:
            run_id = restart.run_id  # "" for a checkpoint written before run ids: kept so
            elsewhere = out.resolve() != run_directory(restart.path)
            same = held is not None and held["run_id"] == restart.run_id and (
                restart.run_id or held["scene"] == restart.scene_text)  # files without run ids: the scene
            if elsewhere and held is not None and not same and not overwrite:
                message = (f"{out}: holds the {'complete' if held['complete'] else 'unfinished'} results of "
                           f"another run ({path}), not of checkpoint {restart.path}'s; give --overwrite "
                           "(Python: overwrite=True) to replace them, or another --out")
    message, run_id = comm.bcast((message, run_id), root=0)
    if message is not None:
        raise OutputError(message)
    return run_id, inputs


def _show_progress(scene: Scene, r: StepRecord, wall: float) -> None:
    tm = scene.time
    done = (r.t / tm.end if tm.end else r.distance / tm.distance if tm.distance else 1.0) or 1e-12
    left = wall * (1 / done - 1) if done > 0 else math.nan
    print(f"\rstep {r.step:6d}  t {r.t:.4g} s  distance {r.distance:.4g} m  force {r.force:.5g} "
          f"{'N/m' if scene.grid.line else 'N'}  "
          f"mu_r {r.mu_r:+.4e}  left ~{left:.0f} s   ", end="", file=sys.stderr, flush=True)




AUTO_DEPTHS = 41
MAX_DEPTHS = 1000
"""The most depths ``petroll stress --depth`` takes (stress.h5 holds 8 fields of the grid's size per depth)."""
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
    """The stresses below the pressure (with friction: and the tangential tractions) saved at ``step``
    (None: the last saved field) of the run in
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
    try:
        raw = tomllib.loads(saved["scene"])
        g = dict(raw["grid"])
    except (ValueError, RecursionError, KeyError, TypeError):  # TOMLDecodeError is a ValueError
        raise PetrollError(f"{path}: not a readable petroll results file (its scene text is no scene)") from None
    if g.get("periodic", False):
        raise PetrollError(f"{path}: [grid] periodic = {g['periodic']!r}: the stresses below a "
                           "periodic surface are not computed (petroll stress sums an isolated pressure "
                           "field)")
    nu = _poisson_ratio(raw, nu)
    x, y, p = saved["x"], saved["y"], saved["pressure"]
    line = saved["line"]
    dx = (g["x"][1] - g["x"][0]) / g["nx"]
    dy = 1.0 if line else (g["y"][1] - g["y"][0]) / g["ny"]
    r0, r1 = saved["rows"]
    z = _depths(depths, p, x[r0:r1], y, dx, dy, saved["step"], comm, line)
    solver = SubsurfaceStress(len(x), len(y), dx, dy, nu, comm, line)
    traction = None if saved["traction"] is None else -saved["traction"]  # the body's on the half-space
    best = {"von_mises": (-1.0, (0.0, 0.0, 0.0)), "max_shear": (-1.0, (0.0, 0.0, 0.0))}

    def fields():
        for depth in z:
            s = solver.at(p, float(depth), traction)
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
        if z.size > MAX_DEPTHS:
            raise PetrollError(f"--depth: {z.size} depths; at most {MAX_DEPTHS} (each one a field of the grid's "
                               "size in stress.h5)")
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
