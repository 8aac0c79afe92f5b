"""Restart checkpoints: the complete state of a run in one HDF5 file, written atomically.

See docs/checkpoints.md.

A checkpoint ``DIR/checkpoints/step-NNNNNNNN.h5`` holds everything the time loop needs to continue after
step N exactly as if it had never stopped (format version 2, readable with plain h5py):

    attributes   format = "petroll-checkpoint", format_version, petroll_version, ranks (the rank count
                 that wrote it), step, t (s), next_dt (s; NaN: the run was over), nx, ny, history
                 ("prony" or "hereditary"), integrator (as resolved), scene (the TOML text),
                 scene_source, base_dir (for the
                 scene's relative files), fingerprint (of the material and body as used), created, sha256
    /state/pressure      (nx, ny)      pressure of step N, Pa (axis 0 along X)
    /state/q             (R, nx, ny)   the Prony state fields (history "prony", R terms): q_r of the creep
                                       form (integrators exponential, paper) or the Maxwell fields s_k of
                                       the relaxation form
    /state/displacement  (nx, ny)      W, the relaxation form's displacement in pressure space (integrator
                                       relaxation): kept as computed, so that the restart is bitwise
    /state/times         (n,)          times of all past steps, s        (history "hereditary")
    /state/increments    (n, nx, ny)   all past pressure increments, Pa  (history "hereditary")
    /state/direction     (2,)          the last direction of motion (for the diagnostics)
    /state/recent        (k, nx, ny)   the last k <= 12 solutions, Pa (3 per lag, petroll.solver.warm), and
                                       /state/recent_position (k, 2) the body's positions, m: the first
                                       guess of the next step
    /state/traction      (m, nx, ny)   [friction]: last tractions, Pa; traction_older, traction_recent (the
                                       next step's first guess), friction (a viscoelastic material: source,
                                       source_older, shear): FrictionLoop.state
    /series/<name>       (N + 1,)      the per-step series so far (as in results.h5)
    /fields/step         (n_saved,)    the steps of the fields saved so far (the fields are in results.h5)

Each dataset carries the SHA-256 of its contents (attribute ``sha256``); the file's ``sha256`` attribute
covers its other attributes and the datasets' digests, so any change of the content is found on reading.

Writing (petroll.io.checkpoint_writer: atomic) and reading are collective: every rank writes and reads
its own rows of each field (parallel HDF5 when h5py has MPI, else through rank 0 in blocks:
petroll.io.hdf5); no rank holds a whole field. A field's digest (format 2) is over the SHA-256 of each of
its rows, so that each rank hashes its own. This module reads and verifies checkpoints, finds them, and
says which scene and which results a checkpoint may continue.
"""

from __future__ import annotations

import contextlib
import hashlib
import pathlib
import re
import signal
import threading
import tomllib
from dataclasses import dataclass

import h5py
import numpy as np
from mpi4py import MPI

from petroll import __version__
from petroll.errors import MISSING, PetrollError, SceneError, reason
from petroll.records import SERIES, StepRecord
from petroll.solver.partition import RowPartition
from petroll.io.hdf5 import RowFile, chunk_rows, seal_broken

FORMAT = "petroll-checkpoint"
FORMAT_VERSION = 2
"""The checkpoint layout written here; files of a larger version are refused. Version 1 also held the
saved fields (/fields/pressure), which now live in results.h5 only; it is still read."""

SAFE_KEYS = {"time": {"end", "distance", "steady", "max_steps"},
             "output": {"dir", "every", "checkpoint_every", "keep"}}
"""Scene keys that a restart may change (everything else must equal the checkpoint's scene; [output]
fields may not: results.h5 holds the saved fields it was made for)."""

SAFE_TEXT = ("a restart may change only [time] end, distance, steady, max_steps and [output] dir, every, "
             "checkpoint_every, keep")
"""SAFE_KEYS, as the refusals say it."""

_NAME = re.compile(r"^step-(\d+)\.h5$")
_ATTRS = ("format", "format_version", "petroll_version", "ranks", "step", "t", "next_dt", "nx", "ny",
          "history", "integrator", "scene", "scene_source", "base_dir", "fingerprint", "created", "sha256")


class CheckpointError(PetrollError):
    """A checkpoint that cannot be written or used; the message names the file and what is wrong."""


class RunInterrupted(Exception):
    """The run stopped early on a signal after writing ``checkpoint`` (step ``step``, time ``t``; None: a
    steady solve, which keeps none: it is run again). ``estimating``: during its error estimate, after its
    last step (a restart from ``checkpoint`` with --estimate-error makes it)."""

    def __init__(self, signum: int, step: int, t: float, checkpoint: pathlib.Path | None,
                 estimating: bool = False):
        self.signum, self.step, self.t, self.checkpoint = int(signum), step, t, checkpoint
        self.estimating = estimating
        where = "during the error estimate, " if estimating else ""
        kept = f"checkpoint {checkpoint}" if checkpoint is not None else "no checkpoint (a steady solve keeps none)"
        super().__init__(f"interrupted by {self.signal_name} {where}after step {step} (t = {t:.6g} s); {kept}")

    @property
    def signal_name(self) -> str:
        try:
            return signal.Signals(self.signum).name
        except ValueError:
            return f"signal {self.signum}"

    @property
    def exit_code(self) -> int:
        """128 + the signal number, as a shell reports a process ended by that signal (143, 130)."""
        return 128 + self.signum


class StopRequest:
    """A request to stop after the current step, set by SIGTERM/SIGINT (``handling()``) or by ``request``.

    The ranks agree on it once per step (``agreed``: a max-reduction), so all stop after the same step
    even when the signal reached only some of them.
    """

    def __init__(self) -> None:
        self.signum = 0

    def request(self, signum: int = signal.SIGTERM) -> None:
        if not self.signum:
            self.signum = int(signum)

    def agreed(self, comm: MPI.Comm) -> int:
        """The signal number some rank received (0: none). Collective."""
        return int(comm.allreduce(self.signum, op=MPI.MAX))

    @contextlib.contextmanager
    def handling(self, signals=(signal.SIGTERM, signal.SIGINT)):
        """Within the block, the first SIGTERM or SIGINT sets the request; a second one acts as it did
        before (SIGTERM kills, SIGINT raises KeyboardInterrupt). Outside the main thread: nothing."""
        if threading.current_thread() is not threading.main_thread():
            yield self
            return
        previous = {s: signal.getsignal(s) for s in signals}

        def handler(signum, frame):
            self.request(signum)
            signal.signal(signum, previous[signum])

        for s in signals:
            signal.signal(s, handler)
        try:
            yield self
        finally:
            for s, h in previous.items():
                signal.signal(s, h)


# -- where checkpoints live -------------------------------------------------------------------------------
def checkpoint_dir(out: str | pathlib.Path) -> pathlib.Path:
    """The checkpoints of a run writing to ``out``."""
    return pathlib.Path(out) / "checkpoints"


def checkpoint_path(directory: pathlib.Path, step: int) -> pathlib.Path:
    return pathlib.Path(directory) / f"step-{step:08d}.h5"


def list_checkpoints(directory: str | pathlib.Path) -> list[pathlib.Path]:
    """The checkpoint files of ``directory``, oldest step first (temporary files of a killed writer are
    not checkpoints and are left out)."""
    directory = pathlib.Path(directory)
    if not directory.is_dir():
        return []
    found = [(int(m.group(1)), p) for p in directory.iterdir() if (m := _NAME.match(p.name)) and p.is_file()]
    return [p for _, p in sorted(found)]


def latest_checkpoint(path: str | pathlib.Path) -> pathlib.Path:
    """``path`` itself if it is a file, else the newest checkpoint of a run directory (or of its
    checkpoints directory); CheckpointError if there is none."""
    path = pathlib.Path(path)
    if not path.is_dir():
        return path
    for directory in (checkpoint_dir(path), path):
        found = list_checkpoints(directory)
        if found:
            return found[-1]
    raise CheckpointError(f"{path}: no checkpoint (step-NNNNNNNN.h5) in this directory or in its "
                          "checkpoints/")


def run_directory(checkpoint: str | pathlib.Path) -> pathlib.Path:
    """The output directory of the run that wrote ``checkpoint`` (the parent of its checkpoints/)."""
    parent = pathlib.Path(checkpoint).resolve().parent
    return parent.parent if parent.name == "checkpoints" else parent


# -- digests ----------------------------------------------------------------------------------------------
def digest_of(name: str, data: np.ndarray) -> str:
    h = _hasher(name, data.dtype, data.shape)
    h.update(np.ascontiguousarray(data).tobytes())
    return h.hexdigest()


def _hasher(name: str, dtype, shape):
    return hashlib.sha256(f"{name}|{np.dtype(dtype).str}|{tuple(int(n) for n in shape)}|".encode())


def row_digests(parts: list[np.ndarray]) -> bytes:
    """The SHA-256 of every row of every part (in order), concatenated: a rank's share of a field digest."""
    return b"".join(hashlib.sha256(np.ascontiguousarray(row).tobytes()).digest() for part in parts
                    for row in part)


def field_digest(name: str, shape, shares: list[bytes], count: int) -> str:
    """A distributed field's digest (format 2): SHA-256 of its name, type, shape and of the SHA-256 of each
    of its rows, slice by slice (``shares``: each rank's row_digests, in rank order, ``count`` slices)."""
    h = _hasher(name, np.float64, shape)
    sizes = [len(share) // max(count, 1) for share in shares]
    for i in range(count):
        for share, size in zip(shares, sizes):
            h.update(share[i * size : (i + 1) * size])
    return h.hexdigest()


def root_digest(attrs: dict, digests: dict[str, str]) -> str:
    plain = sorted((k, _plain(v)) for k, v in attrs.items() if k != "sha256")
    return hashlib.sha256(repr((plain, sorted(digests.items()))).encode()).hexdigest()


def _same_digest(stored, digest: str) -> bool:
    """Whether a digest read from a file (of any type, if the file is damaged) is ``digest``."""
    return isinstance(stored, str) and stored == digest


def _plain(value):
    """An attribute as a plain Python value (str, int, float, bool), however h5py returned it."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.generic):
        return value.item()
    return value


def fingerprint(scene) -> str:
    """A digest of the material (and its layer) and of the body's heights on the grid: what a restart must
    find unchanged even when it comes from files ([material] file, [body] file) that the scene text only
    names. The heights are computed and hashed a block of rows at a time (no whole-grid array)."""
    g = scene.grid
    h = hashlib.sha256(repr(scene.material).encode())
    if scene.layer is not None:
        h.update(repr(scene.layer).encode())
    block = chunk_rows(g.ny)
    for i in range(0, g.nx, block):
        x = g.x[i : i + block, None] - scene.position[0]
        heights = scene.body.height(x, g.y[None, :] - scene.position[1])
        h.update(np.ascontiguousarray(np.broadcast_to(heights, (len(x), g.ny)), dtype=float).tobytes())
    return h.hexdigest()


# -- reading ----------------------------------------------------------------------------------------------
FIELDS = ("state/pressure", "state/displacement", "state/q", "state/recent", "state/increments",
          "state/traction", "state/traction_older", "state/traction_recent", "state/source", "state/source_older",
          "state/shear")
"""The checkpoint's grid fields: (nx, ny) or (k, nx, ny), each rank reading and writing its own rows."""


@dataclass
class Checkpoint:
    """A checkpoint read and verified (collectively). ``state`` holds this rank's rows of the fields
    (RowPartition of nx over the communicator it was read on: restore it on one of the same size):
    pressure and displacement (rows, ny), q, recent and increments lists of them; recent_position (k, 2)."""

    path: pathlib.Path
    attrs: dict
    series: dict[str, np.ndarray]
    field_steps: np.ndarray
    direction: np.ndarray
    times: np.ndarray | None
    state: dict

    @property
    def step(self) -> int:
        return int(self.attrs["step"])

    @property
    def t(self) -> float:
        return float(self.attrs["t"])

    @property
    def ranks(self) -> int:
        return int(self.attrs["ranks"])

    @property
    def scene_text(self) -> str:
        return str(self.attrs["scene"])

    @property
    def run_id(self) -> str:
        """The identifier of the run that wrote it ("" in checkpoints written before run ids)."""
        return str(self.attrs.get("run_id", ""))

    def matches(self, f: h5py.File, where: pathlib.Path) -> str | None:
        """Why the results file ``where`` (open with h5py as ``f``) is not the one this checkpoint continues,
        None if it is: the same run id (where both have one), scene (but for the keys a restart may
        change), grid and series, value for value, up to the checkpoint's step."""
        theirs, mine = str(f.attrs.get("run_id", "")), self.run_id
        fix = (f"; a checkpoint continues only the results of its own run: restart from a checkpoint of "
               f"that run, or run the scene again")
        if theirs and mine and theirs != mine:
            return f"{self.path}: belongs to another run than {where} (run id {mine[:12]}, the file's {theirs[:12]}){fix}"
        try:
            old = tomllib.loads(str(f.attrs["scene"]))
        except (ValueError, RecursionError):  # TOMLDecodeError is a ValueError
            return f"{where}: its scene text is not TOML{fix}"
        for key, then, now in _changes(old, tomllib.loads(self.scene_text)):
            return f"{self.path}: belongs to another scene than {where} ({key} = {now!r}, the file's {then!r}){fix}"
        shape = (len(f["fields/x"]), len(f["fields/y"]))
        if shape != (int(self.attrs["nx"]), int(self.attrs["ny"])):
            return (f"{self.path}: holds a {self.attrs['nx']} x {self.attrs['ny']} grid, {where} a "
                    f"{shape[0]} x {shape[1]} one{fix}")
        n = len(self.series["step"])
        for name in SERIES:
            if name == "solve_time" or name not in f["series"]:
                continue
            theirs_, mine_ = np.asarray(f["series"][name][:n]), np.asarray(self.series[name])
            if len(theirs_) < n:
                break  # too short: told with the steps it holds (_resumable)
            if not np.array_equal(theirs_, mine_, equal_nan=True):
                k = int(np.flatnonzero(~((theirs_ == mine_) | (np.isnan(theirs_) & np.isnan(mine_))))[0])
                return (f"{self.path}: its steps differ from those of {where} ({name} at step {k}: "
                        f"{mine_[k]!r}, the file's {theirs_[k]!r}){fix}")
        return None

    # -- the state back into a simulation ---------------------------------------------------------------
    def restore(self, sim) -> tuple[float, list[int]]:
        """Put the state into ``sim`` (a fresh Simulation of a compatible scene, any rank count; read on a
        communicator of sim's size) and return (t, field_steps) for the time loop: the time and the steps of
        the fields saved up to the checkpoint (they are in the run's results.h5). Collective."""
        g, history, state = sim.scene.grid, sim.history, self.state
        nx, ny = int(self.attrs["nx"]), int(self.attrs["ny"])
        kind = history.kind
        if (nx, ny) != (g.nx, g.ny) or kind != self.attrs["history"]:
            raise CheckpointError(f"{self.path}: holds a {nx} x {ny} grid with a {self.attrs['history']} "
                                  f"history, the scene a {g.nx} x {g.ny} grid with a {kind} history")
        pressure = state["pressure"]
        sim.pressure = pressure.copy()
        if kind == "prony":
            q = state["q"]
            if len(q) != len(history.q):
                raise CheckpointError(f"{self.path}: holds {len(q)} Prony state fields, the scene's material "
                                      f"has {len(history.q)} terms")
            stored = "displacement" in state
            if stored != (history.name == "relaxation"):
                raise CheckpointError(f"{self.path}: written for another integrator than the scene's "
                                      f"({sim.scene.solver.integrator})")
            if stored:  # W as computed, not rebuilt from p and s_k (which differs in the last bits)
                history.restore(pressure, q, state["displacement"])
            else:
                history.restore(pressure, q)
        else:
            history.pressure = pressure
            history.times = [float(v) for v in self.times]
            history.increments = list(state["increments"])
        sim.direction = np.array(self.direction, dtype=float)
        sim.records = [StepRecord.from_series(self.series, i) for i in range(len(self.series["step"]))]
        if (sim.friction is not None) != ("friction" in state):
            raise CheckpointError(f"{self.path}: its friction state and the scene's [friction] disagree")
        if sim.friction is not None:
            sim.friction.restore(state, self.series)
        positions = state.get("recent_position")
        if positions is None:  # a checkpoint written before the guesses were kept: carry the last pressure
            sim.warm.record(sim.pressure, sim.records[-1].sx, sim.records[-1].sy)
        else:
            sim.warm.recent = [(state["recent"][k], *xy) for k, xy in enumerate(positions.tolist())]
        return self.t, [int(s) for s in self.field_steps]


def scatter_rows(whole: np.ndarray | None, nx: int, ny: int, comm: MPI.Comm) -> np.ndarray:
    """This rank's rows (RowPartition of nx over comm) of the (nx, ny) field ``whole`` given on rank 0
    (format-1 checkpoints, read whole by rank 0)."""
    rows = RowPartition(nx, comm.size)
    counts = [int(c) * ny for c in rows.counts]
    displs = [int(s) * ny for s in rows.starts[:-1]]
    local = np.empty((int(rows.counts[comm.rank]), ny))
    send = None
    if comm.rank == 0:
        send = [np.ascontiguousarray(whole, dtype=float).ravel(), counts, displs, MPI.DOUBLE]
    comm.Scatterv(send, local, root=0)
    return local


def read_checkpoint(path: str | pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD) -> Checkpoint:
    """Read and verify a checkpoint (collective: rank 0 checks its attributes and small datasets, every
    rank reads its own rows of the fields and their digests are checked). CheckpointError with one line
    naming the file and what is wrong if it is missing, not HDF5, not a checkpoint, of a newer format,
    truncated or corrupted. Nothing is written."""
    path = pathlib.Path(path)
    loaded, message = None, None
    if comm.rank == 0:
        try:
            loaded = _load(path)
        except CheckpointError as exc:
            message = str(exc)
    message = comm.bcast(message, root=0)
    if message is not None:
        raise CheckpointError(message)
    whole = loaded.pop("whole") if loaded else None  # format 1: the fields, read whole on rank 0
    shared = comm.bcast(loaded, root=0)
    nx, ny = int(shared["attrs"]["nx"]), int(shared["attrs"]["ny"])
    fields = {}
    for name, shape in shared["fields"].items():
        stacked = len(shape) == 3
        count = shape[0] if stacked else 1
        if shared["attrs"]["format_version"] == 1:
            parts = [scatter_rows((whole[name][i] if stacked else whole[name]) if comm.rank == 0 else None,
                                  nx, ny, comm) for i in range(count)]
        else:
            parts = _read_field(path, name, shape, shared["digests"][name], comm)
        fields[name.split("/")[1]] = parts if stacked else parts[0]
    state = dict(fields, **shared["small"])
    return Checkpoint(path=path, attrs=shared["attrs"], series=shared["series"],
                      field_steps=shared["field_steps"], direction=shared["direction"], times=shared["times"],
                      state=state)


def _read_field(path: pathlib.Path, name: str, shape: tuple, digest: str, comm: MPI.Comm) -> list[np.ndarray]:
    """This rank's rows of every slice of a format-2 field, checked against its digest (collective)."""
    stacked = len(shape) == 3
    count, nx = (shape[0], shape[1]) if stacked else (1, shape[0])
    r0, r1 = RowPartition(nx, comm.size).range(comm.rank)
    parts, failure = [], None
    try:
        with RowFile(path, "r", comm) as f:
            for i in range(count):
                parts.append(f.get(name, (i,) if stacked else (), r0, r1 - r0))
    except Exception as exc:  # noqa: BLE001 - h5py reports damage as OSError, RuntimeError, ...
        failure = reason(exc)
    failures = [e for e in comm.allgather(failure) if e]
    if failures:
        what = "truncated" if "truncated" in failures[0].lower() else "corrupted"
        raise CheckpointError(f"{path}: {what}, cannot be read as a checkpoint ({failures[0]})")
    shares = comm.gather(row_digests(parts), root=0)
    good = _same_digest(digest, field_digest(name, shape, shares, count)) if comm.rank == 0 else None
    good = comm.bcast(good, root=0)
    if not good:
        raise CheckpointError(f"{path}: corrupted (the data of {name} do not match their checksum)")
    return parts


def _load(path: pathlib.Path) -> dict:
    """Rank 0: the attributes and small datasets, checked; the fields' shapes and digests (format 2), or
    the fields themselves (format 1, under "whole")."""
    if not path.exists():
        raise CheckpointError(f"{path}: no such checkpoint file")
    if not path.is_file():
        raise CheckpointError(f"{path}: not a file (give a checkpoint step-NNNNNNNN.h5)")
    try:
        broken = seal_broken(path)  # before HDF5 parses a damaged file, which can crash it (SIGSEGV)
        is_hdf5 = h5py.is_hdf5(str(path))
    except Exception as exc:  # noqa: BLE001 - any failure to read is the file's problem
        raise CheckpointError(f"{path}: cannot be read ({reason(exc)})") from None
    if broken:
        raise CheckpointError(f"{path}: {broken}")
    if not is_hdf5:
        what = ("empty" if path.stat().st_size == 0
                else "not an HDF5 file (corrupted, or another kind of file)")
        raise CheckpointError(f"{path}: {what}; not a petroll checkpoint")
    try:
        with h5py.File(path, "r") as f:
            attrs = {k: _plain(v) for k, v in f.attrs.items()}
            if not (isinstance(attrs.get("format"), str) and attrs["format"] == FORMAT):  # any type if damaged
                what = ("a petroll results file" if "series" in f and "fields" in f and "state" not in f
                        else "an HDF5 file")
                raise CheckpointError(f"{path}: not a petroll checkpoint ({what} without the attribute "
                                      f"format = {FORMAT!r})")
            version = attrs.get("format_version")
            if isinstance(version, int) and not isinstance(version, bool) and version > FORMAT_VERSION:
                raise CheckpointError(f"{path}: written in checkpoint format {version} (petroll "
                                      f"{attrs.get('petroll_version', '?')}); this petroll {__version__} "
                                      f"reads format {FORMAT_VERSION} and older: use a newer petroll")
            if not isinstance(version, int) or version not in (1, FORMAT_VERSION):
                raise CheckpointError(f"{path}: corrupted (format_version {version!r} is not a known "
                                      "version)")
            missing = [k for k in _ATTRS if k not in attrs]
            if missing:
                raise CheckpointError(f"{path}: corrupted (attribute {missing[0]!r} is missing)")
            data, digests, shapes = {}, {}, {}

            def visit(name, obj):
                if isinstance(obj, h5py.Dataset):
                    digests[name] = _plain(obj.attrs.get("sha256", ""))
                    if name in FIELDS and version > 1:
                        shapes[name] = tuple(int(n) for n in obj.shape)
                    else:
                        data[name] = obj[()]

            f.visititems(visit)
    except CheckpointError:
        raise
    except Exception as exc:  # noqa: BLE001 - h5py reports damage as OSError, KeyError, RuntimeError, ...
        why = reason(exc)
        what = "truncated" if "truncated" in why.lower() else "corrupted"
        raise CheckpointError(f"{path}: {what}, cannot be read as a checkpoint ({why})") from None
    try:
        return _checked(path, attrs, data, digests, shapes, version)
    except CheckpointError:
        raise
    except Exception as exc:  # noqa: BLE001 - a damaged file's names and values can be of any type
        raise CheckpointError(f"{path}: corrupted, cannot be read as a checkpoint ({reason(exc)})") from None


def _checked(path: pathlib.Path, attrs: dict, data: dict, digests: dict, shapes: dict, version) -> dict:
    """:func:`_load`'s checks of what it read: digests, the datasets a restart needs."""
    for name, value in sorted(data.items()):
        if not _same_digest(digests[name], digest_of(name, np.asarray(value))):
            raise CheckpointError(f"{path}: corrupted (the data of {name} do not match their checksum)")
    if not _same_digest(attrs["sha256"], root_digest(attrs, digests)):
        raise CheckpointError(f"{path}: corrupted (its attributes or list of datasets do not match the "
                              f"checksum)")
    prony = attrs["history"] == "prony"
    needed = ["state/pressure", "state/direction", "fields/step",
              *(f"series/{n}" for n in SERIES),
              *(["state/q"] if prony else ["state/times", "state/increments"])]
    absent = [n for n in needed if n not in data and n not in shapes]
    if absent:
        raise CheckpointError(f"{path}: incomplete (dataset {absent[0]} is missing)")
    whole = {n: data.pop(n) for n in FIELDS if n in data}
    if version > 1:
        fields = shapes
    else:
        fields = {n: tuple(v.shape) for n, v in whole.items()}
    if "state/recent" in fields and "state/recent_position" not in data:
        del fields["state/recent"]
    small = {"recent_position": data["state/recent_position"]} if "state/recent" in fields else {}
    small.update({"friction": data["state/friction"]} if "state/friction" in data else {})  # [friction]'s
    return {"attrs": attrs, "series": {n[7:]: data[n] for n in data if n.startswith("series/")},
            "field_steps": data["fields/step"], "direction": data["state/direction"],
            "times": None if prony else data["state/times"], "fields": fields, "digests": digests,
            "small": small, "whole": whole}


# -- the scene of a restart -------------------------------------------------------------------------------
def restart_scene(checkpoint: Checkpoint, new_scene: str | pathlib.Path | None = None):
    """The scene to continue ``checkpoint`` with: its own, or ``new_scene`` (a TOML file) if that differs
    only in SAFE_KEYS. SceneError naming the first other key that differs; CheckpointError if the
    material's or body's files changed since the checkpoint was written."""
    from petroll.model.scene import load_scene, parse_scene

    stored = checkpoint.scene_text
    try:
        raw = tomllib.loads(stored)
    except (ValueError, RecursionError) as exc:  # TOMLDecodeError is a ValueError
        raise CheckpointError(f"{checkpoint.path}: corrupted (its scene text is not TOML: {exc})") from None
    if new_scene is None:
        try:
            scene = parse_scene(raw, source=str(checkpoint.attrs["scene_source"]),
                                base_dir=str(checkpoint.attrs["base_dir"]), text=stored)
        except SceneError as exc:
            raise CheckpointError(f"{checkpoint.path}: its scene no longer loads ({exc})") from None
    else:
        scene = load_scene(new_scene)
        if scene.solver.integrator != checkpoint.attrs["integrator"]:
            raise SceneError(scene.source, "[solver] integrator", scene.solver.integrator,
                             f"differs from the integrator of checkpoint {checkpoint.path} "
                             f"({checkpoint.attrs['integrator']!r}); {SAFE_TEXT}")
        for key, old, new in _changes(raw, scene.raw):
            raise SceneError(scene.source, key, new, f"differs from the scene of checkpoint "
                             f"{checkpoint.path} ({old!r}); {SAFE_TEXT}")
    if fingerprint(scene) != checkpoint.attrs["fingerprint"]:
        raise CheckpointError(f"{checkpoint.path}: the material or body of the scene ({scene.source}) "
                              f"differs from the one the checkpoint was computed with: a file named by "
                              f"[material] file or [body] file changed")
    return scene


def _changes(old: dict, new: dict):
    """(key, old value, new value) of every scene key outside SAFE_KEYS whose value differs (a key left
    out counts as its schema default)."""
    from petroll.model.schema import SCHEMA

    for section in sorted(set(old) | set(new) | set(SCHEMA)):
        a, b = old.get(section, {}), new.get(section, {})
        for key in sorted(set(a) | set(b)):
            if key in SAFE_KEYS.get(section, ()) or (section, key) == ("solver", "integrator"):
                continue  # the integrator is compared as resolved (its default depends on the material)
            default = SCHEMA.get(section, {}).get(key)
            fallback = default.default if default is not None and _simple(default.default) else MISSING
            va, vb = a.get(key, fallback), b.get(key, fallback)
            if _normal(va) != _normal(vb):
                yield f"[{section}] {key}", va, vb


def _simple(value) -> bool:
    return value is None or isinstance(value, (bool, int, float, str)) or (
        isinstance(value, (list, tuple)) and all(isinstance(v, (int, float, str)) for v in value))


def _normal(value):
    if isinstance(value, tuple):
        return [_normal(v) for v in value]
    if isinstance(value, list):
        return [_normal(v) for v in value]
    if isinstance(value, dict):
        return {k: _normal(v) for k, v in value.items()}
    return value
