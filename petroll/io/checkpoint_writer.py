"""Writing a restart checkpoint (the layout of petroll.io.checkpoint) atomically and collectively.

Every rank gives its own rows of each field; rank 0 writes them (petroll.io.hdf5.RowFile: parallel HDF5
when h5py has MPI, else the other ranks send their rows in blocks) into a temporary file in the same
directory, which is fsynced and renamed, then the directory is fsynced: a run killed at any moment leaves
every earlier checkpoint intact. Only the newest ``[output] keep`` are kept.
"""

from __future__ import annotations

import contextlib
import datetime
import math
import os
import pathlib

import h5py
import numpy as np
from mpi4py import MPI

from petroll import __version__
from petroll.errors import reason
from petroll.io.checkpoint import (FORMAT, FORMAT_VERSION, CheckpointError, checkpoint_path, digest_of,
                                   field_digest, list_checkpoints, root_digest, row_digests)
from petroll.io.hdf5 import RowFile, chunk_rows, seal, seal_broken
from petroll.io.journal import sync_directory
from petroll.io.results import PACKED
from petroll.records import FRICTION_SERIES, SERIES
from petroll.solver.partition import RowPartition


def write_checkpoint(directory: str | pathlib.Path, sim, t: float, next_dt: float | None,
                     field_steps: list[int], keep: int = 2, run_id: str = "", *, inputs: str) -> pathlib.Path:
    """Write the state of ``sim`` after its last step (time ``t``; ``next_dt`` the step that follows, None
    if none) with the steps of the fields saved so far (``field_steps``: they are in results.h5), the
    run's identifier ``run_id`` (as in its results.h5) and rank 0's ``inputs``, the fingerprint of the
    scene's material and body (petroll.io.checkpoint.fingerprint, made once per run: the scene does not
    change while it runs), then remove all but the newest ``keep`` checkpoints
    of earlier steps. Collective over ``sim.comm``: every rank gives its own rows of each field, rank 0
    writes them (petroll.io.hdf5.RowFile); returns the path. CheckpointError if the file cannot be written
    (every earlier checkpoint stays as it was).
    """
    comm, scene = sim.comm, sim.scene
    g, history = scene.grid, sim.history
    step = len(sim.records) - 1
    path = checkpoint_path(pathlib.Path(directory), step)
    sink = _Sink(path, comm, RowPartition(g.nx, comm.size), g.ny)
    prony = history.kind == "prony"
    sink.field("state/pressure", [history.pressure], stacked=False)
    sink.array("state/direction", np.asarray(sim.direction, dtype=float))
    recent = sim.warm.recent
    sink.field("state/recent", [r[0] for r in recent])
    sink.array("state/recent_position", np.array([r[1:] for r in recent], dtype=float).reshape(-1, 2))
    if prony:
        sink.field("state/q", list(history.q))
        if history.name == "relaxation":
            sink.field("state/displacement", [history.displacement], stacked=False)
    else:
        sink.array("state/times", np.asarray(history.times, dtype=float))
        sink.field("state/increments", list(history.increments))
    for name in SERIES:
        sink.array(f"series/{name}", np.array([getattr(r, name) for r in sim.records]))
    if sim.friction is not None:  # its stepping state and series (petroll.solver.friction_loop)
        parts, small = sim.friction.state()
        for name, components in parts.items():
            sink.field(f"state/{name}", components)
        sink.array("state/friction", small)
        for name in FRICTION_SERIES:
            sink.array(f"series/{name}", np.array([getattr(r, name) for r in sim.friction.records]))
    sink.array("fields/step", np.asarray(field_steps, dtype=np.int64))
    attrs = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "petroll_version": __version__,
        "ranks": comm.size, "step": step, "t": float(t),
        "next_dt": math.nan if next_dt is None else float(next_dt),
        "nx": g.nx, "ny": g.ny, "history": history.kind,
        "integrator": scene.solver.integrator, "scene": scene.text, "run_id": run_id,
        "scene_source": scene.source, "base_dir": str(pathlib.Path(scene.base_dir).resolve()),
        "fingerprint": comm.bcast(inputs if comm.rank == 0 else None, root=0),
        "created": comm.bcast(datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
                              if comm.rank == 0 else None, root=0),
    }
    sink.finish(attrs, keep)
    return path


def _write_dataset(f: h5py.File, name: str, data: np.ndarray) -> str:
    """One whole (small) dataset; returns its digest."""
    data = np.ascontiguousarray(data)
    f.create_dataset(name, data=data)
    return digest_of(name, data)


class _Sink:
    """The temporary file a checkpoint is written to (:class:`petroll.io.hdf5.RowFile`: rank 0 writes,
    the other ranks send their rows), and the first error met. Every rank calls every method in the same
    order; the ranks agree on errors after each dataset, and after one no rank writes more."""

    def __init__(self, path: pathlib.Path, comm: MPI.Comm, rows: RowPartition, ny: int):
        self.path, self.comm, self.rows, self.ny = path, comm, rows, ny
        pid = comm.bcast(os.getpid() if comm.rank == 0 else None, root=0)
        self.tmp = path.with_name(f".{path.name}.tmp{pid}")
        self.file, self.error, self.digests = None, None, {}
        self._guard(self._open)

    def _guard(self, action, *args) -> None:
        if self.error is None:
            try:
                action(*args)
            except Exception as exc:  # noqa: BLE001 - reported on every rank by finish()
                self.error = exc
            if self.error is None and self.file is not None and self.file.failure is not None:
                self.error = self.file.failure  # a disk write failed (rank 0): no more writing
        if self.comm.allreduce(self.error is not None, op=MPI.LOR) and self.error is None:
            self.error = CheckpointError("failed on another rank")

    def _open(self) -> None:
        if self.comm.rank == 0:
            with contextlib.suppress(OSError):  # if it fails, so does the opening, on every rank
                self.path.parent.mkdir(parents=True, exist_ok=True)
        self.file = RowFile(self.tmp, "w", self.comm, sealed=True)

    def array(self, name: str, data: np.ndarray) -> None:
        """A small dataset: rank 0's ``data``."""
        data = self.comm.bcast(np.asarray(data) if self.comm.rank == 0 else None, root=0)
        self._guard(self._array, name, data)

    def _array(self, name: str, data: np.ndarray) -> None:
        if self.file.writer:
            self.digests[name] = _write_dataset(self.file.file, name, data)

    def field(self, name: str, parts: list[np.ndarray], stacked: bool = True) -> None:
        """A (len(parts), nx, ny) dataset (``stacked``) or an (nx, ny) one (one part), each rank giving its
        rows of every slice."""
        self._guard(self._field, name, parts, stacked)

    def _field(self, name: str, parts: list[np.ndarray], stacked: bool) -> None:
        nx, ny = self.rows.n, self.ny
        r0 = self.rows.range(self.comm.rank)[0]
        shape = (len(parts), nx, ny) if stacked else (nx, ny)
        if self.file.writer:
            chunks = (1, min(nx, chunk_rows(ny)), ny) if stacked else (min(nx, chunk_rows(ny)), ny)
            packed = dict(PACKED, chunks=chunks) if np.prod(shape) else {}
            self.file.file.create_dataset(name, shape=shape, dtype=np.float64, **packed)
        parts = [np.ascontiguousarray(p, dtype=np.float64) for p in parts]
        for i, part in enumerate(parts):
            self.file.put(name, (i,) if stacked else (), r0, part)
        shares = self.comm.gather(row_digests(parts), root=0)
        digest = field_digest(name, shape, shares, len(parts)) if self.comm.rank == 0 else None
        self.digests[name] = self.comm.bcast(digest, root=0)

    def finish(self, attrs: dict, keep: int) -> None:
        self._guard(self._close, attrs)
        if self.comm.rank == 0 and self.error is None:
            self._guard_local(_prune, self.path, keep)
        if self.error is not None:
            self._discard()
        errors = self.comm.allgather(None if self.error is None else reason(self.error))
        first = next((e for e in errors if e and e != "failed on another rank"), None) or next(
            (e for e in errors if e), None)
        if first is not None:
            message = (f"{self.path}: cannot write the checkpoint ({first}); the earlier checkpoints in "
                       f"{self.path.parent} are unchanged")
            if self.error is not None and not isinstance(self.error, (OSError, CheckpointError)):
                raise CheckpointError(message) from self.error
            raise CheckpointError(message)

    def _guard_local(self, action, *args) -> None:
        try:
            action(*args)
        except Exception as exc:  # noqa: BLE001 - reported by finish()
            self.error = exc

    def _close(self, attrs: dict) -> None:
        digests = self.comm.bcast(self.digests if self.comm.rank == 0 else None, root=0)
        failure = None
        if self.file.writer:
            try:
                f = self.file.file
                for name, digest in digests.items():
                    f[name].attrs["sha256"] = digest
                for key, value in attrs.items():
                    f.attrs[key] = value
                f.attrs["sha256"] = root_digest(attrs, digests)
            except Exception as exc:  # noqa: BLE001 - this rank's; the ranks agree in _guard
                failure = exc
        file, self.file = self.file, None
        file.close(commit=failure is None)  # fsynced; an OSError on every rank if that failed
        if failure is not None:
            raise failure
        if self.comm.rank == 0:
            seal(self.tmp)  # an OSError here: reported by finish(), the file discarded
            os.replace(self.tmp, self.path)
            sync_directory(self.path.parent)

    def _discard(self) -> None:
        if self.file is not None:
            file, self.file = self.file, None
            with contextlib.suppress(OSError):
                file.close(commit=False)
        if self.comm.rank == 0:
            with contextlib.suppress(OSError):
                self.tmp.unlink()


def _prune(path: pathlib.Path, keep: int) -> None:
    """Remove the checkpoints of steps before ``path``'s beyond the newest ``keep`` (``path`` included);
    those of later steps (left by an earlier run of the same directory) are not touched."""
    found = list_checkpoints(path.parent)
    older = found[: found.index(path)] if path in found else []
    for old in older[: max(len(older) - (keep - 1), 0)]:
        with contextlib.suppress(OSError):  # best effort: the new checkpoint is in place already
            old.unlink()


def _is(value, text: str) -> bool:
    """``value`` (an attribute read back, of any type: a damaged file's may be an array) is the string
    ``text``."""
    value = value.item() if isinstance(value, np.generic) else value
    return isinstance(value, str) and value == text


def remove_foreign_checkpoints(directory: str | pathlib.Path, run_id: str) -> list[pathlib.Path]:
    """Remove the checkpoints in ``directory`` of other runs than ``run_id``: once this run's results.h5 is
    in their directory, theirs is gone and they can no longer continue anything. Only files read as
    checkpoints (attribute format) whose run id differs are removed: one that cannot be read now (damaged,
    or a passing read error) is not known to be another run's, and is kept. One process (rank 0).
    Returns them."""
    removed = []
    for path in list_checkpoints(directory):
        try:
            if seal_broken(path):
                raise CheckpointError("damaged")  # not opened: HDF5 can crash on a damaged file
            with h5py.File(path, "r") as f:
                kept = not _is(f.attrs.get("format"), FORMAT) or _is(f.attrs.get("run_id", ""), run_id)
        except Exception:  # noqa: BLE001 - h5py reports a read failure as OSError, RuntimeError, KeyError, ...
            kept = True  # not known to be another run's
        if not kept:
            with contextlib.suppress(OSError):
                path.unlink()
                removed.append(path)
    return removed
