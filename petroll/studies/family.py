"""Families of sweeps and the ``petroll sweep`` command (docs/sweep.md#families-of-curves)::

    petroll sweep SCENE.toml --vary KEY=SPEC [--vary KEY2=SPEC2] [--out DIR]

One ``--vary``: a sweep (petroll.studies.sweep). Two: a family of curves, one sweep of the first key per
value of the second (traction curves at several speeds or temperatures, a creep coefficient against the
speed at several temperatures: docs/friction.md#traction-against-speed-and-temperature). Output in DIR:
KEY2=VALUE/ (each curve a sweep directory), family.csv (every curve's rows, the second key's value first)
and family.png (petroll.plot.sweep.plot_family).

Collective over ``comm`` as the sweeps are.
"""

from __future__ import annotations

import pathlib
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from mpi4py import MPI

from petroll.io.results import atomic_write
from petroll.io.rundir import clean_temporaries
from petroll.model.limits import warnings_once
from petroll.model.scene import Scene
from petroll.studies.sweep import (FORMS, SweepError, SweepInterrupted, SweepTable, Vary, csv_rows, key_unit,
                                   on_rank0, parse_vary, point_name, point_scene, sweep, valued_scene)


@dataclass
class Family:
    """A family of sweeps (:func:`family`): one :class:`SweepTable` (a curve over its ``curve`` key) per
    value of ``key`` (in ``unit``), written under ``directory``. Returned on every rank."""

    key: str
    unit: str
    values: tuple[float, ...]
    tables: list[SweepTable]
    directory: pathlib.Path

    @property
    def csv(self) -> pathlib.Path:
        return self.directory / "family.csv"

    @property
    def png(self) -> pathlib.Path:
        return self.directory / "family.png"

    @property
    def computed(self) -> int:
        """The points run by this call (the others were found finished)."""
        return sum(len(t.computed) for t in self.tables)


def family(scene: Scene, curve: Vary | str, across: Vary | str, out: str | pathlib.Path | None = None,
           comm: MPI.Comm = MPI.COMM_WORLD, progress: bool = False, stop=None,
           log: Callable[[str], None] | None = None, plot: bool = True, transient: bool = False) -> Family:
    """A family of curves: for every value of ``across`` (a :class:`Vary` or its text) the sweep of
    ``curve`` (:func:`sweep`) on the scene with that value, into ``out``/KEY=VALUE (default ``out``: the
    scene's output directory + ``-sweep``); then family.csv (every curve's rows, the value of ``across``
    first) and family.png (petroll.plot.sweep.plot_family: the curves on one figure). Traction curves at
    several speeds or temperatures (``curve`` motion.creepage), creep coefficients against the speed at
    several temperatures (docs/sweep.md#families-of-curves). Every point's scene is built before the first
    runs; each curve resumes as a sweep does. Collective."""
    curve = parse_vary(curve) if isinstance(curve, str) else curve
    across = parse_vary(across) if isinstance(across, str) else across
    if curve.key == across.key:
        raise SweepError(f"--vary {across.key} given twice; a family varies two different keys ({FORMS})")
    if out is None:
        out = scene.output_dir.with_name(scene.output_dir.name + "-sweep")
    out = pathlib.Path(out)
    scenes = [valued_scene(scene, across.key, v) for v in across.values]
    for member in scenes:  # every point of every curve checked before the first run
        for v in curve.values:
            point_scene(member, curve.key, v, transient)
    names = [point_name(across.key, v) for v in across.values]
    if len(set(names)) != len(names):
        raise SweepError(f"--vary {across.spec or across.key}: values closer than 10 significant digits")
    unit = key_unit(scene, across.key)
    tables = []
    for value, member, name in zip(across.values, scenes, names):
        label = f"{across.key} = {value:.6g}" + (f" {unit}" if unit != "-" else "")
        say = None if log is None else (lambda line, label=label: log(f"{label}: {line}"))
        tables.append(sweep(member, curve, out / name, comm, progress, stop, say, plot, transient))
    result = Family(across.key, unit, across.values, tables, out)

    def write() -> None:
        lines = []
        for value, table in zip(result.values, tables):
            header, rows = csv_rows(table, (across.key, unit, value))
            lines += rows if lines else [header, *rows]
        clean_temporaries(out, [result.csv.name])
        atomic_write(result.csv, lambda tmp: tmp.write_text("\n".join(lines) + "\n", encoding="utf-8"))

    on_rank0(comm, write)
    if plot:
        on_rank0(comm, lambda: _plot(result))
    return result


def _plot(result: Family) -> None:
    """family.png (without matplotlib nothing: the curves' sweeps have warned of it)."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return
    from petroll.plot import plot_family

    plot_family(result, result.png)


def command(scene_path: str, vary_text: Sequence[str], out: str | None, quiet: bool, comm: MPI.Comm,
            transient: bool = False, estimate_error: bool = False) -> int:
    """``petroll sweep``: a sweep (one ``vary_text``) or a family (two); every rank; prints one line per
    point and a summary on rank 0."""
    from petroll.io.checkpoint import StopRequest
    from petroll.model.scene import load_scene

    if not 1 <= len(vary_text) <= 2:
        raise SweepError(f"--vary given {len(vary_text)} times; a sweep varies one key, a family of curves "
                         f"two (the curves' key first: docs/sweep.md#families-of-curves) ({FORMS})")
    if estimate_error and len(vary_text) == 2:
        raise SweepError("--estimate-error: with one --vary only (a sweep, not a family of curves)")
    vary = parse_vary(vary_text[0])
    across = parse_vary(vary_text[1]) if len(vary_text) == 2 else None
    start = time.perf_counter()
    stop = StopRequest()
    say = (lambda line: print(f"petroll: {line}", flush=True))
    progress = not quiet and sys.stderr.isatty()
    try:
        with stop.handling(), warnings_once():
            scene = load_scene(scene_path)
            if across is None:
                table = sweep(scene, vary, out, comm, progress=progress, stop=stop, log=say,
                              transient=transient, estimate_error=estimate_error)
            else:
                curves = family(scene, vary, across, out, comm, progress=progress, stop=stop, log=say,
                                transient=transient)
    except SweepInterrupted as exc:
        if comm.rank == 0:
            print(f"petroll: {scene.source}: sweep {exc}", file=sys.stderr, flush=True)
        return exc.exit_code
    wall = time.perf_counter() - start
    if comm.rank == 0 and across is None:
        n, ran = len(table.points), len(table.computed)
        print(f"petroll: {scene.source}: sweep of {vary.key} over {n} values ({ran} run, {n - ran} kept from "
              f"an earlier call; wall time {wall:.1f} s). Table: {table.csv}, {table.h5}; plot: {table.png}")
    elif comm.rank == 0:
        n = sum(len(t.points) for t in curves.tables)
        print(f"petroll: {scene.source}: {len(curves.tables)} curves of {vary.key} at {across.key} = "
              f"{', '.join(f'{v:.6g}' for v in across.values)} ({n} points, {curves.computed} run; wall "
              f"time {wall:.1f} s). Table: {curves.csv}; plot: {curves.png}")
    return 0
