"""Kill storms: runs killed at random instants, and what each left checked against the uninterrupted run.

A small scene that writes at every step (three saved fields, a checkpoint per step) is run to its end
once (the reference), then again and again, each run killed with SIGKILL at an instant drawn uniformly
over its duration. What a killed run left must hold without loss:

- results.h5 (if the run got as far as creating it) opens through petroll's reader, and its series and
  saved fields are, value for value, the reference's up to its ``steps_written``; if a kill cut a commit
  short (its journal is whole), ``petroll.io.journal.recover`` puts the file back and plain h5py reads the
  same steps;
- every checkpoint in ``checkpoints/`` is read and verified, and its series are the reference's;
- (for ``restarts`` trials spread over the storm) ``petroll restart`` from the newest checkpoint ends
  with the reference's results, bitwise.

Runs are forked from this process (``fork``: no start-up cost, one rank) or started as
``mpirun -n RANKS petroll run`` (``ranks`` > 0: every rank killed at once, as when a node fails). Each
forked run reports where it was when killed (outside an append, inside one, inside its commit), and may be
slowed inside appends (``slow`` seconds per disk write of results.h5) so that more kills land there.

Forked storms may also kill at every *kill point* first (``every_point``): what a run leaves on disk
changes only at its disk writes (``petroll.io.journal.write_all``) and at the os calls of DURABLE; a kill
point is one of them, named by the call, the file (digits folded: every step's checkpoint is one file) and
where the run was (PHASES). A run to its end lists them in order (``kill_points``); a trial is killed just
before the first call of each kill point (SIGKILL sent by the run to itself), so every way a kill can cut
a run's writes short is tried, whatever the machine's speed; the random trials then land between them,
later in the run too.
``scripts/kill-storm.py`` runs a storm and prints the table; tests/test_faults.py runs a small one. Fault
injection is a tool of the checkout's tests, not part of the installed package: this module lives beside
the tests (``from kills import ...``, the tests' folder is on sys.path under pytest; the script puts it
there).
"""

from __future__ import annotations

import math
import os
import pathlib
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field

import h5py
import numpy as np
from mpi4py import MPI

from petroll.driver import run
from petroll.io import journal
from petroll.io.checkpoint import list_checkpoints, read_checkpoint, restart_scene
from petroll.io.results import Results, ResultsFile
from petroll.model.scene import dumps, parse_scene

SCENE = {
    "grid": {"nx": 20, "ny": 16, "x": [-0.8e-3, 1.2e-3], "y": [-0.8e-3, 0.8e-3]},
    "material": {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
    "body": {"shape": "sphere", "radius": 0.01},
    "motion": {"velocity": [0.05, 0.0], "penetration": 2e-5},
    "time": {"steps_per_cell": 1, "distance": 0.4e-3},
    "solver": {"tol": 1e-9},
    "output": {"every": 1, "checkpoint_every": 1, "keep": 3, "fields": ["pressure", "displacement", "gap"]},
}
"""A sphere rolling 4 cells (5 steps), every step saving three fields and writing a checkpoint."""

PHASES = ("outside", "append", "commit")
"""Where a forked run was when killed: outside any append, inside one (HDF5 writing), inside its commit."""

DURABLE = ("fsync", "replace", "unlink", "ftruncate", "truncate")
"""The os calls after which what a run left on disk may differ (besides petroll.io.journal.write_all)."""


@dataclass
class Trial:
    """One killed run: when (s after its start), where (one of PHASES, "?" for mpirun runs), what it left
    (steps and saved fields in results.h5, checkpoints, a journal cut short) and what was lost (none!)."""

    index: int
    after: float  # NaN: killed at a kill point
    phase: str = "?"
    point: str = ""  # the kill point it was killed before ("write results.h5 commit"), "" if at an instant
    steps: int = 0
    fields: int = 0
    checkpoints: int = 0
    torn: bool = False  # results.h5's commit was cut short: its journal was whole
    restarted: bool = False
    lost: list[str] = field(default_factory=list)


def storm(directory: str | pathlib.Path, trials: int, seed: int = 0, slow: float = 0.0, restarts: int = 0,
          ranks: int = 0, log=None, every_point: bool = False) -> list[Trial]:
    """Run ``trials`` killed runs in ``directory`` (see the module docstring), after (``every_point``,
    forked runs only) one killed just before the first call of each kill point; each
    trial's directory is removed once checked unless something was lost. ``log(trial)`` after each."""
    directory = pathlib.Path(directory).resolve()  # mpirun's runs start in it: their --out must be absolute
    directory.mkdir(parents=True, exist_ok=True)
    scene = parse_scene(SCENE, source="kill-storm.toml", base_dir=directory)
    (directory / "kill-storm.toml").write_text(dumps(SCENE), encoding="utf-8")
    if ranks:
        reference, duration = _mpirun_reference(directory, ranks)
    else:
        reference = run(scene, MPI.COMM_SELF, directory / "reference", overwrite=True)
        shutil.rmtree(directory / "timing", ignore_errors=True)
        start = time.perf_counter()
        _kill_fork(scene, directory / "timing", None, slow)  # a whole run, as the trials run (slowed)
        duration = time.perf_counter() - start
    expected = _contents(reference)
    if every_point and ranks:
        raise ValueError("kill points are forked runs' (ranks=0)")
    points = kill_points(scene, directory / "points") if every_point else []
    chosen = sorted({points.index(point) for point in points})  # the first call of each
    rng = np.random.default_rng(seed)
    total = len(chosen) + trials
    due = 0.0  # restarts spread over the storm: the first trial from here on that left a checkpoint
    done = []
    for index in range(total):
        out = directory / f"trial-{index:04d}"
        shutil.rmtree(out, ignore_errors=True)
        if index < len(chosen):
            trial = Trial(index, math.nan, point=points[chosen[index]])
            trial.phase = _kill_fork(scene, out, None, 0.0, kill_at=chosen[index])
        else:
            after = float(rng.uniform(0.0, duration))
            trial = Trial(index, after)
            if ranks:
                _kill_mpirun(directory, out, ranks, after)
            else:
                trial.phase = _kill_fork(scene, out, after, slow)
        _inspect(out, expected, trial)
        if restarts and index >= due and trial.checkpoints and not trial.lost:
            _restart(out, expected, trial, ranks, directory)
            due += total / restarts
        if not trial.lost:
            shutil.rmtree(out, ignore_errors=True)
        done.append(trial)
        if log is not None:
            log(trial)
    return done


# -- killing ----------------------------------------------------------------------------------------------
def kill_points(scene, out: pathlib.Path) -> list[str]:
    """The kill points of a run of ``scene`` into ``out`` (removed after), in the order it reaches them, one
    entry per call: "CALL FILE PHASE" ("write results.h5 commit", "replace step-N.h5 outside")."""
    listing = out.with_name(out.name + ".txt")
    _kill_fork(scene, out, None, 0.0, listing=listing)
    points = listing.read_text(encoding="utf-8").splitlines()
    shutil.rmtree(out, ignore_errors=True)
    listing.unlink()
    return points


def _kill_fork(scene, out: pathlib.Path, after: float | None, slow: float, kill_at: int | None = None,
               listing: pathlib.Path | None = None) -> str:
    """Fork a run of ``scene`` into ``out``, SIGKILL it ``after`` seconds later (None: let it end) or just
    before its kill point number ``kill_at`` (it kills itself), or list its kill points in ``listing``;
    where it was (PHASES)."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the run: tells the parent where it is, one byte per change
        try:
            os.close(read)
            points = _instrument(write, slow, kill_at, out)
            run(scene, MPI.COMM_SELF, out)
            if listing is not None:
                listing.write_text("".join(f"{point}\n" for point in points), encoding="utf-8")
        finally:
            os._exit(0)
    os.close(write)
    if after is not None:
        time.sleep(after)
        os.kill(pid, signal.SIGKILL)
    os.waitpid(pid, 0)
    marks = b""
    while chunk := os.read(read, 65536):
        marks += chunk
    os.close(read)
    last = marks[-1:] if marks else b"o"
    return {b"o": "outside", b"a": "append", b"c": "commit"}[last]


def _instrument(pipe: int, slow: float, kill_at: int | None, out: pathlib.Path) -> list[str]:
    """In a forked run: mark entering and leaving each append and commit on ``pipe``; slow results.h5's
    disk writes by ``slow`` seconds each; SIGKILL the run just before its kill point number ``kill_at``.
    Returns the list that its kill points are added to as it reaches them."""
    append, commit, write_all = ResultsFile.append, journal.Session.commit, journal.write_all
    phase = [b"o"]
    points: list[str] = []

    def mark(byte: bytes) -> None:
        phase[0] = byte
        os.write(pipe, byte)

    def marked_append(self, *args, **kwargs):
        mark(b"a")
        try:
            return append(self, *args, **kwargs)
        finally:
            mark(b"o")

    def marked_commit(self):  # results.h5's in an append, a checkpoint's outside
        before = phase[0]
        mark(b"c")
        try:
            return commit(self)
        finally:
            mark(before)

    def point(call: str, target) -> None:
        """Before a call that may change what is on disk: a kill point, the run killed if it is the one."""
        if isinstance(target, int):
            target = os.readlink(f"/proc/self/fd/{target}")
        name = "DIR" if pathlib.Path(target) == out else re.sub(r"(?<=tmp)\d+|(?<=-)\d+", "N",
                                                                 pathlib.Path(target).name)
        if len(points) == kill_at:
            os.kill(os.getpid(), signal.SIGKILL)
        points.append(f"{call} {name} {PHASES['oac'.index(phase[0].decode())]}")

    def slowed(fd, data, at):
        point("write", fd)
        if slow and os.readlink(f"/proc/self/fd/{fd}").endswith("results.h5"):
            time.sleep(slow)
        write_all(fd, data, at)

    def durable(call: str, function):
        def before(*args, **kwargs):
            point(call, args[-1] if call == "replace" else args[0])
            return function(*args, **kwargs)
        return before

    ResultsFile.append, journal.Session.commit, journal.write_all = marked_append, marked_commit, slowed
    for call in DURABLE:
        setattr(os, call, durable(call, getattr(os, call)))
    return points


def _mpirun_reference(directory: pathlib.Path, ranks: int) -> tuple[Results, float]:
    """The scene run to its end on ``ranks`` ranks (the reference of an mpirun storm) and its duration
    from the moment its results.h5 appeared (kills are drawn over that span)."""
    out = directory / "reference-mpirun"
    shutil.rmtree(out, ignore_errors=True)
    proc = _start(directory, out, ranks)
    _wait_for(out / "results.h5", proc)
    start = time.perf_counter()
    if proc.wait() != 0:
        raise RuntimeError(f"the reference run on {ranks} ranks failed: {proc.stderr.read()}")
    return Results.open(out / "results.h5"), time.perf_counter() - start


def _start(directory: pathlib.Path, out: pathlib.Path, ranks: int) -> subprocess.Popen:
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    return subprocess.Popen(["mpirun", "-n", str(ranks), sys.executable, "-m", "petroll.cli", "run",
                             "kill-storm.toml", "--out", str(out), "--quiet"], cwd=directory, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)


def _wait_for(path: pathlib.Path, proc: subprocess.Popen) -> None:
    while not path.exists() and proc.poll() is None:
        time.sleep(0.002)


def _kill_mpirun(directory: pathlib.Path, out: pathlib.Path, ranks: int, after: float) -> None:
    """Start the run on ``ranks`` ranks, and once its results.h5 exists wait ``after`` seconds and SIGKILL
    every rank at once (then mpirun)."""
    from petroll.launch import ranks_of

    proc = _start(directory, out, ranks)
    _wait_for(out / "results.h5", proc)
    time.sleep(after)
    for pid in ranks_of(proc.pid):
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    proc.kill()
    proc.wait()


# -- checking ---------------------------------------------------------------------------------------------
def _contents(results: Results) -> dict:
    """What a run's results hold, to compare with: series (but the wall times), field steps, fields."""
    return {"series": {k: v for k, v in results.series.items() if k != "solve_time"},
            "steps": list(results.field_steps), "fields": {name: results.field(name) for name in results.fields}}


def _inspect(out: pathlib.Path, expected: dict, trial: Trial) -> None:
    """What the killed run left in ``out``, checked; anything wrong goes to ``trial.lost``."""
    path = out / "results.h5"
    if path.exists():
        try:
            found = Results.open(path)
            n, k = len(found.series["t"]), len(found.field_steps)
            trial.steps, trial.fields = n, k
            for name, values in expected["series"].items():
                if not np.array_equal(found.series[name], values[:n], equal_nan=True):
                    trial.lost.append(f"results.h5: series {name} differs from the uninterrupted run's")
            if list(found.field_steps) != expected["steps"][:k]:
                trial.lost.append("results.h5: saved steps differ")
            for name, values in expected["fields"].items():
                if not np.array_equal(found.field(name), values[:k]):
                    trial.lost.append(f"results.h5: field {name} differs")
        except Exception as exc:  # noqa: BLE001 - any failure to read is a loss
            trial.lost.append(f"results.h5 does not open ({type(exc).__name__}: {exc})")
        trial.torn = journal.read_journal(path) is not None
        if trial.torn and not trial.lost:
            journal.recover(path)
            with h5py.File(path, "r") as f:  # plain h5py, once the old bytes are back
                if int(f.attrs["steps_written"]) != trial.steps:
                    trial.lost.append("results.h5 after recovery: another number of steps")
    for checkpoint in list_checkpoints(out / "checkpoints"):
        trial.checkpoints += 1
        try:
            check = read_checkpoint(checkpoint, MPI.COMM_SELF)
        except Exception as exc:  # noqa: BLE001
            trial.lost.append(f"{checkpoint.name} is not readable ({exc})")
            continue
        n = len(check.series["t"])
        if not all(np.array_equal(check.series[name], values[:n], equal_nan=True)
                   for name, values in expected["series"].items()):
            trial.lost.append(f"{checkpoint.name}: its series differ from the uninterrupted run's")


def _restart(out: pathlib.Path, expected: dict, trial: Trial, ranks: int, directory: pathlib.Path) -> None:
    """Continue the killed run from its newest checkpoint; its results must end as the reference's."""
    found = list_checkpoints(out / "checkpoints")
    if not found:
        return
    if ranks:
        env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                   OMPI_MCA_rmaps_base_oversubscribe="1")
        done = subprocess.run(["mpirun", "-n", str(ranks), sys.executable, "-m", "petroll.cli", "restart",
                               str(found[-1]), "--quiet"], cwd=directory, env=env, capture_output=True, text=True)
        if done.returncode:
            trial.lost.append(f"restart failed: {done.stderr.strip()}")
            return
    else:
        check = read_checkpoint(found[-1], MPI.COMM_SELF)
        run(restart_scene(check), MPI.COMM_SELF, out, restart=check)
    trial.restarted = True
    final = _contents(Results.open(out / "results.h5"))
    if not all(np.array_equal(final["series"][name], values, equal_nan=True)
               for name, values in expected["series"].items()):
        trial.lost.append("after the restart: series differ from the uninterrupted run's")
    if final["steps"] != expected["steps"] or not all(np.array_equal(final["fields"][name], values)
                                                      for name, values in expected["fields"].items()):
        trial.lost.append("after the restart: saved fields differ from the uninterrupted run's")


def summary(trials: list[Trial]) -> dict:
    """Counts over a storm: trials, where the kills landed, files left, restarts, and losses."""
    return {"trials": len(trials), "kill points": len({t.point for t in trials if t.point}),
            **{f"killed {p}": sum(t.phase == p for t in trials) for p in PHASES},
            "results.h5 left": sum(t.steps > 0 for t in trials), "torn commits": sum(t.torn for t in trials),
            "checkpoints checked": sum(t.checkpoints for t in trials),
            "restarted": sum(t.restarted for t in trials), "trials with a loss": sum(bool(t.lost) for t in trials)}
