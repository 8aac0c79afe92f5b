"""Output files read for people and spreadsheets: which petroll file a path is (``petroll plot``), what a
run directory holds (``petroll info``), and a run's series or one saved field as CSV (``petroll export``).
Reading only: nothing here changes a run's files."""

from __future__ import annotations

import csv
import pathlib
from dataclasses import dataclass

import h5py
import numpy as np

from petroll.errors import PetrollError
from petroll.io.checkpoint import checkpoint_dir, list_checkpoints
from petroll.io.results import (
    FIELD_UNITS,
    LINE_SERIES_UNITS,
    SERIES_UNITS,
    OutputError,
    Results,
    atomic_write,
)

KINDS = {"results.h5": "run", "sweep.h5": "sweep", "stress.h5": "stress"}
"""The file a directory of each kind holds."""


def file_kind(path: str | pathlib.Path) -> tuple[str, pathlib.Path]:
    """("run" | "sweep" | "stress", the HDF5 file) for a run directory or its results.h5, a sweep directory
    or its sweep.h5, or a stress.h5 (a file is recognised by its content, whatever its name). PetrollError,
    one line, for anything else."""
    path = pathlib.Path(path)
    if path.is_dir():
        for name, kind in KINDS.items():
            if (path / name).is_file():
                return kind, path / name
        raise PetrollError(f"{path}: holds no results.h5, sweep.h5 or stress.h5 (a run directory, a sweep "
                           "directory or one of those files is expected)")
    if not path.is_file():
        raise PetrollError(f"{path}: no such file or directory")
    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") == "petroll-sweep":
                return "sweep", path
            if "series" in f and "scene" in f.attrs:
                return "run", path
            if "von_mises" in f and "z" in f:
                return "stress", path
    except Exception:  # noqa: BLE001 - h5py reports damage as OSError, KeyError, RuntimeError, ...
        pass
    raise PetrollError(f"{path}: not a petroll results.h5, sweep.h5 or stress.h5")


def open_results(path: str | pathlib.Path) -> Results:
    """The results of a run directory or of its results.h5 (PetrollError, one line, if it is neither)."""
    kind, file = file_kind(path)
    if kind != "run":
        raise PetrollError(f"{path}: a {kind} file, not a run's results.h5")
    return Results.open(file)


@dataclass(frozen=True)
class RunContents:
    """What a run directory holds: its results (series, saved fields, scene), its checkpoints (step,
    path; oldest first) and its other entries (names)."""

    directory: pathlib.Path
    results: Results
    checkpoints: list[tuple[int, pathlib.Path]]
    others: list[str]


def run_contents(path: str | pathlib.Path) -> RunContents:
    """Read what the run directory ``path`` (or the directory of the results.h5 ``path``) holds."""
    results = open_results(path)
    directory = results.path.parent
    found = list_checkpoints(checkpoint_dir(directory))
    checkpoints = [(int(p.stem.split("-")[1]), p) for p in found]
    others = sorted(p.name + ("/" if p.is_dir() else "") for p in directory.iterdir()
                    if p.name not in (results.path.name, "checkpoints") and not p.name.startswith("."))
    return RunContents(directory, results, checkpoints, others)


def write_series_csv(results: Results, path: str | pathlib.Path) -> pathlib.Path:
    """The series as CSV: one row per step, one column per series, headed ``name (unit)``."""
    units = LINE_SERIES_UNITS if results.line else SERIES_UNITS
    names = [name for name in units if name in results.series]
    columns = [results.series[name] for name in names]
    rows = [[_number(column[i]) for column in columns] for i in range(len(results.series["t"]))]
    return _write(path, [f"{name} ({units[name]})" for name in names], rows)


def write_field_csv(results: Results, name: str, step: int | None, path: str | pathlib.Path) -> pathlib.Path:
    """The field ``name`` saved at ``step`` (default: the last saved) as CSV: one row per cell, columns
    x (m), y (m) and the value (FIELD_UNITS), X the slower index."""
    if name not in results.fields:
        raise PetrollError(f"--field {name}: not saved by this run (saved: {', '.join(results.fields)}; "
                           "[output] fields chooses)")
    steps = [int(s) for s in results.field_steps]
    if step is None:
        step = steps[-1]
    if step not in steps:
        raise PetrollError(f"--step {step}: no {name} saved at this step (saved at steps "
                           f"{', '.join(map(str, steps))}; [output] every chooses)")
    values = results.field(name)[steps.index(step)]
    x, y = np.meshgrid(results.x, results.y, indexing="ij")
    rows = [[_number(a), _number(b), _number(c)] for a, b, c in zip(x.ravel(), y.ravel(), values.ravel())]
    return _write(path, ["x (m)", "y (m)", f"{name} ({FIELD_UNITS[name]})"], rows)


def _number(value) -> str:
    """A value as CSV text: integers as integers, floats to round-trip precision."""
    return str(int(value)) if isinstance(value, (int, np.integer)) else repr(float(value))


def _write(path: str | pathlib.Path, header: list[str], rows: list[list[str]]) -> pathlib.Path:
    path = pathlib.Path(path)

    def write(tmp: pathlib.Path) -> None:
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            out = csv.writer(fh)
            out.writerow(header)
            out.writerows(rows)

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, write)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write it ({exc.strerror})") from None
    return path
