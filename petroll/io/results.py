"""results.h5: the per-step series and the saved fields of a run (layout: docs/results.md).

    /series/<name>        1-D datasets, one value per step (force, delta, area, p_max, iterations, ...)
    /fields/<field>       (n_saved, nx, ny) saved fields, axis 1 along X (``FIELD_UNITS``: pressure in Pa)
    /fields/step          (n_saved,) step number of each saved field
    /fields/x, /fields/y  cell-centre coordinates in m (material frame)
    /mesh/xy              ((nx + 1) (ny + 1), 2) cell-corner coordinates in m, for the XDMF file
    /xdmf/<field>/<k>     (nx, ny) virtual datasets (no data of their own): the k-th saved field, what
                          results.xdmf points at (every XDMF reader reads a whole dataset; hyperslabs of
                          /fields are not read alike by ParaView's two readers)
    /rough/<name>         a grid periodic along every axis: at each saved field, the contact's fraction of
                          the cell, the mean gap and the pressure's radially averaged spectrum (ROUGH_UNITS)
    attributes            scene (the scene's TOML text), scene_file (the path it was read from),
                          run_id, fingerprint (of the material and body as used: the files the
                          scene names included), petroll_version, format_version, complete
                          (False while the run goes on), steps_written, fields_written, last_step,
                          line_contact (True: a plane-strain run; fields (n_saved, nx, 1) on strips of
                          unit length, y = [0]; series per unit length, force_y and cop_y absent),
                          steady (True: the steady state solved directly, [time] mode = "steady": one
                          step, step 0 at t = 0)

The file grows as the run goes (:class:`ResultsFile`): its datasets are resizable and chunked, the series
and fields are appended, never rewritten, every rank writing its own rows of a field (parallel HDF5, or
through rank 0: :mod:`petroll.io.hdf5`). Between appends the file is closed; ``steps_written`` and
``fields_written`` say how far it is valid and readers cut the datasets there. Next to it,
``results.xdmf`` describes the saved fields as a time series for ParaView (docs/checkpoints.md).
"""

from __future__ import annotations

import functools
import math
import os
import pathlib
from dataclasses import dataclass

import h5py
import numpy as np

from petroll import __version__
from petroll.errors import PetrollError, reason
from petroll.io.hdf5 import RowFile, add_strings, chunk_rows, overgrown, reading_as, string_list
from petroll.io.journal import atomic_write, copy_committed, reading, sync_directory  # noqa: F401 - atomic_write: here too
from petroll.records import INTEGER_SERIES, SERIES, friction_units

FORMAT_VERSION = 1
RESULTS_FILE = "petroll results file"  # what the error that a damaged one gives calls it (reading_as)


class OutputError(PetrollError):
    """An output file or directory that cannot be written (the message names it and the reason)."""

SERIES_UNITS = {
    "step": "-", "t": "s", "sx": "m", "sy": "m", "delta": "m", "force": "N", "force_x": "N", "force_y": "N",
    "mu_r": "-", "area": "m^2", "p_max": "Pa", "cop_x": "m", "cop_y": "m", "lead": "m", "trail": "m",
    "dissipation": "W", "distance": "m", "iterations": "-", "applications": "-", "residual": "-",
    "solve_time": "s",
}
"""The series every run writes, with their units (attribute ``units`` of each dataset)."""

LINE_ABSENT = ("force_y", "cop_y")
"""Series a line-contact run does not write (nothing varies along Y)."""

LINE_SERIES_UNITS = {**{k: v for k, v in SERIES_UNITS.items() if k not in LINE_ABSENT},
                     "force": "N/m", "force_x": "N/m", "area": "m", "dissipation": "W/m"}
"""The series of a line-contact (plane-strain) run: per unit length; area is the contact width."""


@dataclass(frozen=True)
class SteadyState:
    """A run's final (steady-state) values with a measure of how converged they are.

    The values are those of the last step. Their convergence is measured over the last contact length of
    rolling, as ``[time] steady`` does: ``window`` = the last step's patch length along the motion
    (lead - trail), compared with the last step at least ``window`` earlier along the path (step 0, the
    sudden start, excluded). The changes are NaN when there is no such step (a run that did not roll one
    contact length, or lost contact). A steady state solved directly ([time] mode = "steady") has changes
    0 and ``reached`` True.
    """

    force: float  # normal force, N
    mu_r: float  # rolling-resistance coefficient, - (resisting force along the motion / normal force)
    delta: float  # penetration, m
    area: float  # contact area, m^2
    lead: float  # leading patch edge along the motion, relative to the body, m
    trail: float  # trailing patch edge along the motion, relative to the body, m
    p_max: float  # peak pressure, Pa
    step: int  # the last step's number
    t: float  # its time, s
    distance: float  # path length rolled, m
    window: float  # rolled length over which the changes are measured, m
    force_change: float  # |F - F_then| / |F|, -
    mu_r_change: float  # |mu_r - mu_r_then| / |mu_r|, - (inf when mu_r = 0 but mu_r_then is not)
    resisting_change: float  # |mu_r F - (mu_r F)_then| / |F|, - (with force_change: what [time] steady tests)
    reached: bool  # the run stopped on its [time] steady criterion, before its end or distance

    def converged(self, tol: float) -> bool:
        """The ``[time] steady`` test at tolerance ``tol``: force and resisting force changed by at most
        ``tol`` x force over the last contact length (False when that cannot be measured)."""
        return bool(self.force_change <= tol and self.resisting_change <= tol)


def steady_state(series: dict[str, np.ndarray], scene_text: str = "") -> SteadyState:
    """The :class:`SteadyState` of a run's series (``scene_text``: its scene, for ``reached``)."""
    import tomllib

    s = {name: np.asarray(values) for name, values in series.items()}
    last = len(s["t"]) - 1
    if last < 0:
        raise ValueError("no steps in the series")
    force, mu_r, distance = (float(s[name][last]) for name in ("force", "mu_r", "distance"))
    window = float(s["lead"][last] - s["trail"][last])
    changes = (math.nan, math.nan, math.nan)
    try:
        time = tomllib.loads(scene_text).get("time", {}) if scene_text else {}
    except (ValueError, RecursionError):  # TOMLDecodeError is a ValueError
        time = {}
    direct = time.get("mode") == "steady"  # solved directly: steady by construction
    if direct:
        changes = (0.0, 0.0, 0.0)
    elif math.isfinite(window) and force != 0:
        # a step exactly one window back counts (1e-9 of slack for round-off in the distances): with k
        # steps per cell it sits at the same place relative to the cells as the last one
        earlier = np.flatnonzero(s["distance"][1:last] <= distance - window * (1 - 1e-9))
        if earlier.size:
            k = int(earlier[-1]) + 1
            f0, m0 = float(s["force"][k]), float(s["mu_r"][k])
            dm = abs(mu_r - m0)
            changes = (abs(force - f0) / abs(force),
                       dm / abs(mu_r) if mu_r != 0 else (0.0 if dm == 0 else math.inf),
                       abs(mu_r * force - m0 * f0) / abs(force))
    end, length = time.get("end"), time.get("distance")
    reached = direct or bool("steady" in time and (
        (end is not None and float(s["t"][last]) < end * (1 - 1e-9))
        or (length is not None and distance < length * (1 - 1e-9))))
    return SteadyState(force=force, mu_r=mu_r, delta=float(s["delta"][last]), area=float(s["area"][last]),
                       lead=float(s["lead"][last]), trail=float(s["trail"][last]),
                       p_max=float(s["p_max"][last]), step=int(s["step"][last]), t=float(s["t"][last]),
                       distance=distance, window=window, force_change=changes[0], mu_r_change=changes[1],
                       resisting_change=changes[2], reached=reached)


@dataclass
class Results:
    """A run's results: ``series[name]`` (one value per step, numpy arrays) and its saved fields.

    Units: see :data:`SERIES_UNITS` (SI); ``pressure`` in Pa, ``x`` and ``y`` in m. ``steady`` gives the
    final values with their convergence measure (:class:`SteadyState`). The saved fields are read from
    the file when first used (``pressure``, or ``field(name)``), not when it is opened.
    """

    path: pathlib.Path
    series: dict[str, np.ndarray]
    field_steps: np.ndarray  # (n_saved,)
    x: np.ndarray  # (nx,) cell centres, m
    y: np.ndarray  # (ny,) cell centres, m
    scene_text: str
    complete: bool = True  # False: the run goes on (or was interrupted); the file holds steps_written steps
    line: bool = False  # a line-contact (plane-strain) run: series per unit length, pressure (n, nx, 1)
    fields: tuple[str, ...] = ("pressure",)  # the saved fields in the file (keys of FIELD_UNITS)
    solved_steady: bool = False  # the steady state solved directly ([time] mode = "steady"; attribute steady)
    scene_file: str = ""  # the path the scene was read from ("" in files of petroll 0.1.0)
    version: str = ""  # the petroll version that wrote the file
    run_id: str = ""  # the run's identifier, shared with its checkpoints ("" in files written before them)
    error_estimate: dict | None = None  # group error_estimate: {quantity: {attribute: value}, "": group attrs}
    rough: dict[str, np.ndarray] | None = None  # a periodic grid's group rough (ROUGH_UNITS), per saved field
    warnings: tuple[str, ...] = ()  # the run's warnings (attribute warnings), one line each

    @classmethod
    def open(cls, path: str | pathlib.Path) -> "Results":
        """Read a results file's series and coordinates (any rank may call it), up to ``steps_written``."""
        path = pathlib.Path(path)
        with reading_as(path, RESULTS_FILE), reading(path) as f:
            n = int(f.attrs.get("steps_written", len(f["series/t"])))
            k = int(f.attrs.get("fields_written", len(f["fields/step"])))
            series = {name: f["series"][name][:n] for name in f["series"]}
            line = bool(f.attrs.get("line_contact", False))
            short = [s for s in (LINE_SERIES_UNITS if line else SERIES_UNITS) if len(series.get(s, ())) != n]
            if short:  # a damaged file's series may be gone or cut short
                raise PetrollError(f"{path}: not a readable {RESULTS_FILE} (series {short[0]}: "
                                   f"{len(series.get(short[0], ()))} values for the {n} steps written)")
            fields = f["fields"]
            rough = {name: f["rough"][name][:k] for name in f["rough"]} if "rough" in f else None
            estimate = None
            if "error_estimate" in f:
                group = f["error_estimate"]
                estimate = {name: dict(group[name].attrs) for name in group} | {"": dict(group.attrs)}
            return cls(path, series, fields["step"][:k], fields["x"][()], fields["y"][()], str(f.attrs["scene"]),
                       bool(f.attrs.get("complete", True)), line,
                       tuple(name for name in FIELD_UNITS if name in fields), bool(f.attrs.get("steady", False)),
                       str(f.attrs.get("scene_file", "")), str(f.attrs.get("petroll_version", "")),
                       str(f.attrs.get("run_id", "")), estimate, rough, string_list(f, "warnings"))

    def field(self, name: str) -> np.ndarray:
        """The saved fields ``name`` (a key of FIELD_UNITS), (n_saved, nx, ny), read from the file."""
        with reading_as(self.path, RESULTS_FILE), reading(self.path) as f:
            return f["fields"][name][: len(self.field_steps)]

    @functools.cached_property
    def pressure(self) -> np.ndarray:
        """(n_saved, nx, ny) saved pressure fields, Pa (read on first use)."""
        return self.field("pressure")

    @property
    def steady(self) -> SteadyState:
        """The last step's force (N), mu_r and other values, with their relative change over the last
        contact length of rolling (computed from the series: the same for a reopened file)."""
        return steady_state(self.series, self.scene_text)


ROUGH_UNITS = {"area_fraction": "-", "mean_gap": "m", "q": "rad/m", "spectrum": "Pa^2 m^2", "modes": "-",
               "mu_lateral": "-"}
"""The group rough of a run on a grid periodic along every axis (petroll.records.RoughOutputs), one
row per saved field: area_fraction, mean_gap and mu_lateral (n_saved,); q, spectrum and modes (n_saved,
bins). Files written before mu_lateral lack it."""

ROUGH_SCALARS = ("area_fraction", "mean_gap", "mu_lateral")
"""The group rough's datasets of one value per saved field."""

FIELD_UNITS = {"pressure": "Pa", "displacement": "m", "gap": "m", "traction_x": "Pa", "traction_y": "Pa",
               "slip": "m/s"}
"""The fields a run can save (name: unit), each as /fields/<name> (n_saved, nx, ny): the contact pressure,
the surface displacement (into the half-space; line contact: relative to the datum) and the gap between
the body and the deformed surface ([output] fields); with [friction] the tangential tractions on the body
and the slip velocity's magnitude (0 in stick and outside the contact; docs/results.md)."""


class ResultsFile:
    """``results.h5`` of a running simulation, appended to as it goes (layout: docs/results.md).

    Collective: every rank of ``comm`` calls every method alike, with its own rows (RowPartition of nx)
    of the fields. The file is closed between calls: each :meth:`append` opens it, extends the series and
    the fields, sets ``steps_written``/``fields_written`` last and closes it; a process killed while no
    append is under way leaves a file holding every step up to the last append. ``fields`` names the
    fields a run saves (keys of FIELD_UNITS); ``line``: a line-contact run; ``steady``: a direct steady
    solve (attribute steady); ``rough``: the number of spectrum bins of a run on a periodic grid (group
    rough; None: none); ``fingerprint``: rank 0's petroll.io.checkpoint.fingerprint of the scene
    (attribute fingerprint). Raises :class:`OutputError` (on every rank).
    """

    def __init__(self, path: str | pathlib.Path, scene_text: str, x: np.ndarray, y: np.ndarray, comm,
                 fields: tuple[str, ...] = ("pressure",), line: bool = False, steady: bool = False,
                 source: str = "", run_id: str = "", rough: int | None = None, fingerprint: str = "",
                 friction: bool = False):
        from petroll.solver.partition import RowPartition

        self.path, self.scene_text, self.comm = pathlib.Path(path), scene_text, comm
        self.source = source  # the scene file's path (attribute scene_file)
        self.run_id = run_id  # the run's identifier (attribute run_id), shared with its checkpoints
        self.fingerprint = fingerprint  # of the material and body as used (attribute fingerprint)
        self.x, self.y, self.fields = np.asarray(x, dtype=float), np.asarray(y, dtype=float), tuple(fields)
        self.rows = RowPartition(len(self.x), comm.size)
        self.steady = bool(steady)
        self.rough = rough
        self.line = bool(line)  # a line-contact run: the series of LINE_SERIES_UNITS, with their units
        self.names = [n for n in SERIES if not (line and n in LINE_ABSENT)]
        self.friction_units = friction_units(line) if friction else {}  # a run with [friction]: its series
        self.names += list(self.friction_units)
        self.steps = 0  # series rows in the file
        self.field_steps: list[int] = []  # the steps of the fields in the file
        self.started = False  # the file exists (create or resume); the first append creates it otherwise

    # -- starting ---------------------------------------------------------------------------------------
    def create(self, then=None) -> None:
        """A new file with empty series and fields (atomically replacing a results.h5 already there);
        ``then(f)`` (a RowFile) adds to it before it replaces the old one."""
        nx, ny = len(self.x), len(self.y)
        r0, r1 = self.rows.range(self.comm.rank)
        tmp = self.path.with_name(f".{self.path.name}.tmp{self._pid()}")

        def build(f: RowFile):
            if f.writer:
                h = f.file
                h.attrs.update(scene=self.scene_text, scene_file=self.source, petroll_version=__version__,
                               format_version=FORMAT_VERSION, line_contact=self.line, steady=self.steady,
                               run_id=self.run_id, fingerprint=self.fingerprint)
                units = LINE_SERIES_UNITS if self.line else SERIES_UNITS
                group = h.create_group("series")
                for name in self.names:
                    group.create_dataset(name, shape=(0,), maxshape=(None,), chunks=(SERIES_CHUNK,),
                                         dtype=series_dtype(name)).attrs["units"] = units.get(
                                             name, self.friction_units.get(name, "-"))
                fields = h.create_group("fields")
                chunks = (1, min(nx, chunk_rows(ny)), ny)
                for name in self.fields:
                    fields.create_dataset(name, shape=(0, nx, ny), maxshape=(None, nx, ny), chunks=chunks,
                                          dtype=np.float64, **PACKED).attrs["units"] = FIELD_UNITS[name]
                fields.create_dataset("step", shape=(0,), maxshape=(None,), chunks=(SERIES_CHUNK,),
                                      dtype=np.int64)
                if self.rough is not None:
                    group = h.create_group("rough")
                    for name, unit in ROUGH_UNITS.items():
                        shape = () if name in ROUGH_SCALARS else (self.rough,)
                        group.create_dataset(name, shape=(0, *shape), maxshape=(None, *shape),
                                             chunks=(64, *shape), dtype=np.int64 if name == "modes" else
                                             np.float64).attrs["units"] = unit
                fields.create_dataset("x", data=self.x).attrs["units"] = "m"
                fields.create_dataset("y", data=self.y).attrs["units"] = "m"
                h.create_group("mesh").create_dataset(
                    "xy", shape=((nx + 1) * (ny + 1), 2), dtype=np.float64,
                    chunks=(min((nx + 1) * (ny + 1), chunk_rows(2) // 2), 2), **PACKED).attrs["units"] = "m"
                self._mark(h, 0, 0, complete=False)
            last = r1 + 1 if r1 == nx else r1  # the last rank writes the corners' last row too
            f.put_rows("mesh/xy", r0, last, ny + 1, lambda a, b: cell_corners(self.x, self.y, a, b))
            if then is not None:
                then(f)

        self._guarded(lambda: self._write(tmp, "w", build), tmp)
        self._guarded(lambda: self._replace(tmp), tmp)
        self.steps, self.field_steps, self.started = 0, [], True

    def resume(self, source: str | pathlib.Path, steps: int, field_steps: list[int], check=None) -> None:
        """Continue ``source`` (the results.h5 of the run a checkpoint came from): its first ``steps`` series
        values and the fields of ``field_steps`` are kept, what it holds beyond them is dropped. A source
        elsewhere than this file is copied here first (atomically). ``check(f, source)`` (rank 0, the source
        open with h5py as ``f``) says why it is not the checkpoint's run's (None: it is). Nothing is written before the
        source passes: OutputError on every rank otherwise."""
        source = pathlib.Path(source)
        message = None
        if self.comm.rank == 0:
            message = _resumable(source, steps, field_steps, check)
        message = self.comm.bcast(message, root=0)
        if message is not None:
            raise OutputError(message)
        if source.resolve() != self.path.resolve():
            tmp = self.path.with_name(f".{self.path.name}.tmp{self._pid()}")
            self._guarded(lambda: self._copy(source, tmp), tmp)
            self._guarded(lambda: self._replace(tmp), tmp)

        def cut(f: RowFile):
            if f.writer:
                h = f.file
                for name in h["series"]:
                    h["series"][name].resize((steps,))
                for name in (*self.fields, "step"):
                    h["fields"][name].resize(len(field_steps), axis=0)
                _field_views(h, self.fields, len(field_steps))
                for name in h.get("rough", ()):
                    h["rough"][name].resize(len(field_steps), axis=0)
                h.attrs["run_id"] = self.run_id
                self._mark(h, steps, len(field_steps), complete=False)

        self._guarded(lambda: self._write(self.path, "r+", cut))
        self.steps, self.field_steps, self.started = steps, [int(s) for s in field_steps], True

    # -- growing ----------------------------------------------------------------------------------------
    def append(self, records: list, saved: dict[str, np.ndarray] | None = None, complete: bool = False,
               describe: bool = False, rough=None, warnings=()) -> None:
        """Append the series of ``records`` (StepRecords) not yet in the file and, with ``saved`` ({field
        name: this rank's rows}), the fields of the last record's step (and with them, on a periodic grid,
        ``rough``: its petroll.records.RoughOutputs) and rank 0's ``warnings`` lines not there yet
        (attribute warnings); then mark the file (``complete``: the run is over). ``describe`` rewrites
        results.xdmf too (atomically). The first append of a file neither created nor resumed creates it
        with these records (so a run failing in its first step leaves none)."""
        first = not self.started
        if first:
            self.steps, self.field_steps = 0, []
        names = self.names
        new = records[self.steps:]
        n = self.steps + len(new)
        k = len(self.field_steps) + (saved is not None)
        step = int(records[-1].step)
        r0 = self.rows.range(self.comm.rank)[0]

        def grow(f: RowFile):
            h = f.file
            if f.writer:
                for name in names:
                    h["series"][name].resize((n,))
            mine = self.comm.rank == 0  # rank 0's series (solve_time differs between ranks)
            for name in names:
                values = np.array([getattr(r, name) for r in new] if mine else [], dtype=series_dtype(name))
                f.put(f"series/{name}", (), self.steps, values)
            if saved is not None:
                if f.writer:
                    for name in (*self.fields, "step"):
                        h["fields"][name].resize(k, axis=0)
                for name in self.fields:
                    f.put(f"fields/{name}", (k - 1,), r0, np.asarray(saved[name], dtype=np.float64))
                f.put("fields/step", (), k - 1, np.array([step] if mine else [], dtype=np.int64))
                if self.rough is not None:
                    self._put_rough(f, k, rough, mine)
                if f.writer:
                    _field_views(h, self.fields, k)
            if f.writer:
                add_strings(h, "warnings", warnings)  # the run's warnings so far, each once
                h.flush()  # the data first, then the marks that make them count
                self._mark(h, n, k, complete)

        if first:
            self.create(grow)
        else:
            self._guarded(lambda: self._write(self.path, "r+", grow))
        self.steps = n
        if saved is not None:
            self.field_steps.append(step)
        if describe and self.comm.rank == 0:
            times = {int(r.step): float(r.t) for r in records}
            text = xdmf_text(self.path.name, len(self.x), len(self.y), self.field_steps,
                             [times[s] for s in self.field_steps], self.fields)
            xdmf = self.path.with_suffix(".xdmf")
            self._guarded(lambda: atomic_write(xdmf, lambda tmp: tmp.write_text(text, encoding="utf-8")),
                          local=True, what=xdmf)
        if describe:
            self._agree()

    # -- helpers ----------------------------------------------------------------------------------------
    def _put_rough(self, f: RowFile, k: int, rough, mine: bool) -> None:
        """Row k - 1 of the group rough: the saved step's RoughOutputs (rank 0 writes). A file written before
        mu_lateral (a restart) gets it, NaN at its earlier rows."""
        if f.writer:
            group = f.file["rough"]
            for name in set(ROUGH_SCALARS) - set(group):
                group.create_dataset(name, shape=(0,), maxshape=(None,), chunks=(64,), dtype=np.float64,
                                     fillvalue=np.nan).attrs["units"] = ROUGH_UNITS[name]
            for name in ROUGH_UNITS:
                f.file["rough"][name].resize(k, axis=0)
        for name in ROUGH_SCALARS:
            value = [getattr(rough, name)] if mine else []
            f.put(f"rough/{name}", (), k - 1, np.array(value, dtype=np.float64))
        for name in ("q", "spectrum", "modes"):
            dtype = np.int64 if name == "modes" else np.float64
            f.put(f"rough/{name}", (k - 1,), 0, np.asarray(getattr(rough, name) if mine else [], dtype=dtype))

    def write_error_estimate(self, quantities: dict[str, dict], attrs: dict, complete: bool = False) -> None:
        """The group ``error_estimate`` (replaced if present): ``attrs`` on the group, one subgroup per
        quantity with its attributes (value, extrapolated, error, order, ...; docs/results.md); with
        ``complete``, the file marked complete in the same commit (a run with an estimate is finished once
        it is written). Journaled like an append; collective (OutputError on every rank)."""
        def work(f: RowFile):
            if f.writer:
                h = f.file
                if "error_estimate" in h:
                    del h["error_estimate"]
                group = h.create_group("error_estimate")
                group.attrs.update(attrs)
                for name, values in quantities.items():
                    group.create_group(name).attrs.update(values)
                h.attrs["complete"] = complete or bool(h.attrs["complete"])  # one commit: estimate and mark

        self._guarded(lambda: self._write(self.path, "r+", work))

    @staticmethod
    def _mark(h: h5py.File, steps: int, fields: int, complete: bool) -> None:
        """The attributes saying how far the file is valid: ``steps`` series values, ``fields`` fields."""
        h.attrs.update(complete=bool(complete), steps_written=int(steps), fields_written=int(fields),
                       last_step=int(steps) - 1)

    def _pid(self) -> int:
        return self.comm.bcast(os.getpid() if self.comm.rank == 0 else None, root=0)

    def _write(self, path: pathlib.Path, mode: str, work) -> None:
        """``work(f)`` on the file opened for writing (a RowFile, collective), committed (fsynced) after."""
        if self.comm.rank == 0:
            path.parent.mkdir(parents=True, exist_ok=True)
        with RowFile(path, mode, self.comm) as f:
            work(f)

    def _replace(self, tmp: pathlib.Path) -> None:
        if self.comm.rank == 0:
            os.replace(tmp, self.path)
            sync_directory(self.path.parent)

    @staticmethod
    def _copy(source: pathlib.Path, tmp: pathlib.Path) -> None:
        tmp.parent.mkdir(parents=True, exist_ok=True)
        copy_committed(source, tmp)

    _error = None

    def _guarded(self, action, tmp: pathlib.Path | None = None, local: bool = False,
                 what: pathlib.Path | None = None) -> None:
        """Run ``action`` (collective unless ``local``: rank 0 only); an error on any rank becomes an
        OutputError on every rank naming ``what`` (default results.h5; a temporary file is removed)."""
        try:
            if not local or self.comm.rank == 0:
                action()
        except (OSError, RuntimeError, KeyError, ValueError) as exc:
            why = exc.strerror if isinstance(exc, OSError) and exc.strerror else reason(exc)  # the file: named
            self._error = f"{what or self.path}: cannot write the results ({why})"
        if not local:
            self._agree(tmp)

    def _agree(self, tmp: pathlib.Path | None = None) -> None:
        errors = [e for e in self.comm.allgather(self._error) if e]
        self._error = None
        if errors:
            if tmp is not None and self.comm.rank == 0 and tmp.exists():
                tmp.unlink()
            raise OutputError(errors[0])


PACKED = dict(compression="gzip", compression_opts=1, shuffle=True)
"""How fields are stored: gzip (in every HDF5 build) after byte shuffling, fast level."""

SERIES_CHUNK = 128
"""Values per chunk of a series (and of fields/step): an append rewrites the last, partly filled chunk of
each, so its size is what an append rewrites (and journals) per series: 1 KiB."""


def series_dtype(name: str):
    """The stored type of series ``name``."""
    return np.int64 if name in INTEGER_SERIES else np.float64


def _resumable(source: pathlib.Path, steps: int, field_steps: list[int], check=None) -> str | None:
    """Why ``source`` cannot be continued at ``steps`` steps with ``field_steps`` saved (None: it can)."""
    fix = "; restart from an earlier checkpoint, or run the scene again from its start"
    try:
        with reading(source) as f:
            if "steps_written" not in f.attrs or f["series/t"].maxshape != (None,):
                return f"{source}: written by an older petroll (not appendable); run the scene again"
            n, k = int(f.attrs["steps_written"]), int(f.attrs["fields_written"])
            have = [int(s) for s in f["fields/step"][:k]]
            if (odd := overgrown(f, {"series": n, "fields": k, "rough": k})) is not None:  # cut: a hang
                return f"{source}: damaged ({odd}){fix}"
            other = check(f, source) if check is not None else None
    except Exception as exc:  # noqa: BLE001 - h5py reports damage as OSError, KeyError, RuntimeError, ...
        return f"{source}: cannot continue the results of the checkpoint's run ({reason(exc)}){fix}"
    if other is not None:
        return other
    if n < steps or have[: len(field_steps)] != [int(s) for s in field_steps]:
        return (f"{source}: holds {n} steps and fields of steps {have[:6]}{'...' if len(have) > 6 else ''}; "
                f"the checkpoint needs {steps} steps and fields of steps "
                f"{list(field_steps)[:6]}{'...' if len(field_steps) > 6 else ''}{fix}")
    return None


def results_identity(path: str | pathlib.Path) -> dict | None:
    """Of a results file: its ``scene`` text, ``run_id`` and ``fingerprint`` ("" if it has none), whether
    it is ``complete`` and whether it holds an ``error_estimate``; None if it cannot be read as one."""
    try:
        with reading(path) as f:
            return {"scene": str(f.attrs["scene"]), "run_id": str(f.attrs.get("run_id", "")),
                    "fingerprint": str(f.attrs.get("fingerprint", "")),
                    "complete": bool(f.attrs.get("complete", True)), "estimated": "error_estimate" in f}
    except Exception:  # noqa: BLE001 - h5py reports damage as OSError, KeyError, RuntimeError, ...
        return None


def cell_corners(x: np.ndarray, y: np.ndarray, i0: int = 0, i1: int | None = None) -> np.ndarray:
    """((i1 - i0) (ny + 1), 2) corner coordinates of the cells centred at x, y (uniform), corner rows
    i0 <= i <= nx below i1 (default: all nx + 1), the last axis (Y) varying fastest: rows i0:i1 of the
    geometry of a 2DSMesh whose cell (i, j) is pressure[i, j]."""
    nx = len(x)
    i1 = nx + 1 if i1 is None else i1
    dx = (x[-1] - x[0]) / (nx - 1) if nx > 1 else 1.0
    dy = (y[-1] - y[0]) / (len(y) - 1) if len(y) > 1 else 1.0
    rows = np.arange(i0, i1)
    xe = np.where(rows < nx, x[np.minimum(rows, nx - 1)] - dx / 2, x[-1] + dx / 2)
    ye = np.concatenate([y - dy / 2, [y[-1] + dy / 2]])
    X, Y = np.meshgrid(xe, ye, indexing="ij")
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def _field_views(h: h5py.File, fields: tuple[str, ...], count: int) -> None:
    """/xdmf/<name>/<k> for k < ``count``: virtual datasets viewing /fields/<name>[k] (made where missing,
    dropped beyond ``count``); the source is this file (".", so the file may move)."""
    for name in fields:
        group = h.require_group(f"xdmf/{name}")
        source = h["fields"][name]
        for key in [key for key in group if int(key) >= count]:
            del group[key]
        for k in range(count):
            if str(k) not in group:
                layout = h5py.VirtualLayout(shape=source.shape[1:], dtype=source.dtype)
                layout[...] = h5py.VirtualSource(source)[k]
                group.create_virtual_dataset(str(k), layout)


def xdmf_text(h5_name: str, nx: int, ny: int, field_steps: list[int], times: list[float],
              fields: tuple[str, ...] = ("pressure",)) -> str:
    """XDMF 2 describing the saved ``fields`` of ``h5_name`` (same directory) as a temporal collection of
    structured grids, one cell attribute per field, each the virtual dataset /xdmf/<field>/<k>: no data is
    copied. ParaView's default (XDMF 3) and XDMF (v2) readers read it alike (tests/test_paraview.py)."""
    corners = f"{(nx + 1) * (ny + 1)} 2"
    lines = ['<?xml version="1.0" ?>', '<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>',
             '<Xdmf Version="2.0">', "  <Domain>",
             '    <Grid Name="fields" GridType="Collection" CollectionType="Temporal">']
    for k, (step, t) in enumerate(zip(field_steps, times)):
        lines += [
            f'      <Grid Name="step {int(step)}" GridType="Uniform">',
            f'        <Time Value="{float(t)!r}"/>',
            f'        <Topology TopologyType="2DSMesh" Dimensions="{nx + 1} {ny + 1}"/>',
            '        <Geometry GeometryType="XY">',
            f'          <DataItem Dimensions="{corners}" NumberType="Float" Precision="8" Format="HDF">'
            f"{h5_name}:/mesh/xy</DataItem>",
            "        </Geometry>",
        ]
        for name in fields:
            lines += [
                f'        <Attribute Name="{name}" AttributeType="Scalar" Center="Cell">',
                f'          <DataItem Dimensions="{nx} {ny}" NumberType="Float" Precision="8" Format="HDF">'
                f"{h5_name}:/xdmf/{name}/{k}</DataItem>",
                "        </Attribute>",
            ]
        lines.append("      </Grid>")
    lines += ["    </Grid>", "  </Domain>", "</Xdmf>", ""]
    return "\n".join(lines)
