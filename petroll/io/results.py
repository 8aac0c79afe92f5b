"""results.h5: the per-step series and the saved pressure fields of a run (layout: docs/results.md).

    /series/<name>        1-D datasets, one value per step (force, delta, area, p_max, iterations, ...)
    /fields/pressure      (n_saved, nx, ny) pressure in Pa, axis 1 along X
    /fields/step          (n_saved,) step number of each saved field
    /fields/x, /fields/y  cell-centre coordinates in m (material frame)
    /mesh/xy              ((nx + 1) (ny + 1), 2) cell-corner coordinates in m, for the XDMF file
    attributes            scene (the scene's TOML text), petroll_version, format_version, complete
                          (False while the run goes on: written at a checkpoint), last_step,
                          line_contact (True: a plane-strain run; fields (n_saved, nx, 1) on strips of
                          unit length, y = [0]; series per unit length, force_y and cop_y absent)

The file is written by rank 0 to a temporary name and renamed into place, so a reader never sees a
half-written file, and a run killed at any moment leaves the previous complete file. Next to it,
``results.xdmf`` describes the saved pressure fields as a time series for ParaView (docs/checkpoints.md).
"""

from __future__ import annotations

import math
import os
import pathlib
from dataclasses import dataclass

import h5py
import numpy as np

from petroll import __version__
from petroll.errors import PetrollError, reason

FORMAT_VERSION = 1


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
    contact length, or lost contact).
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
    if math.isfinite(window) and force != 0:
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
    try:
        time = tomllib.loads(scene_text).get("time", {}) if scene_text else {}
    except tomllib.TOMLDecodeError:
        time = {}
    end, length = time.get("end"), time.get("distance")
    reached = bool("steady" in time and (
        (end is not None and float(s["t"][last]) < end * (1 - 1e-9))
        or (length is not None and distance < length * (1 - 1e-9))))
    return SteadyState(force=force, mu_r=mu_r, delta=float(s["delta"][last]), area=float(s["area"][last]),
                       lead=float(s["lead"][last]), trail=float(s["trail"][last]),
                       p_max=float(s["p_max"][last]), step=int(s["step"][last]), t=float(s["t"][last]),
                       distance=distance, window=window, force_change=changes[0], mu_r_change=changes[1],
                       resisting_change=changes[2], reached=reached)


@dataclass
class Results:
    """A run's results as numpy arrays: ``series[name]`` (one value per step) and the saved fields.

    Units: see :data:`SERIES_UNITS` (SI); ``pressure`` in Pa, ``x`` and ``y`` in m. ``steady`` gives the
    final values with their convergence measure (:class:`SteadyState`).
    """

    path: pathlib.Path
    series: dict[str, np.ndarray]
    pressure: np.ndarray  # (n_saved, nx, ny), Pa
    field_steps: np.ndarray  # (n_saved,)
    x: np.ndarray  # (nx,) cell centres, m
    y: np.ndarray  # (ny,) cell centres, m
    scene_text: str
    complete: bool = True  # False: written at a checkpoint of a run that goes on (or was interrupted)
    line: bool = False  # a line-contact (plane-strain) run: series per unit length, pressure (n, nx, 1)

    @classmethod
    def open(cls, path: str | pathlib.Path) -> "Results":
        """Read a results file (any rank may call it)."""
        path = pathlib.Path(path)
        with h5py.File(path, "r") as f:
            series = {name: f["series"][name][()] for name in f["series"]}
            fields = f["fields"]
            return cls(path, series, fields["pressure"][()], fields["step"][()], fields["x"][()],
                       fields["y"][()], str(f.attrs["scene"]), bool(f.attrs.get("complete", True)),
                       bool(f.attrs.get("line_contact", False)))

    @property
    def steady(self) -> SteadyState:
        """The last step's force (N), mu_r and other values, with their relative change over the last
        contact length of rolling (computed from the series: the same for a reopened file)."""
        return steady_state(self.series, self.scene_text)


def write_results(path: pathlib.Path, series: dict[str, np.ndarray], pressure: np.ndarray,
                  field_steps: np.ndarray, x: np.ndarray, y: np.ndarray, scene_text: str,
                  complete: bool = True, line: bool = False) -> None:
    """Write a complete results file and its ``.xdmf`` companion atomically (temporary file, fsync,
    rename). Call on one rank. Raises :class:`OutputError` (the previous files are left as they were).
    ``line``: a line-contact run (the series of LINE_SERIES_UNITS only, with their units)."""
    units = LINE_SERIES_UNITS if line else SERIES_UNITS
    path = pathlib.Path(path)
    nx, ny = len(x), len(y)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)

        def fill(f):
            f.attrs["scene"] = scene_text
            f.attrs["petroll_version"] = __version__
            f.attrs["format_version"] = FORMAT_VERSION
            f.attrs["complete"] = bool(complete)
            steps = np.asarray(series.get("step", []))
            f.attrs["last_step"] = int(steps[-1]) if steps.size else -1
            f.attrs["line_contact"] = bool(line)
            group = f.create_group("series")
            for name, values in series.items():
                if line and name in LINE_ABSENT:
                    continue
                dataset = group.create_dataset(name, data=np.asarray(values))
                dataset.attrs["units"] = units.get(name, "-")
            fields = f.create_group("fields")
            data = np.asarray(pressure, dtype=float).reshape(-1, nx, ny)
            packed = {}
            if len(data):
                packed = dict(compression="gzip", compression_opts=1, shuffle=True, chunks=(1, nx, ny))
            fields.create_dataset("pressure", data=data, **packed).attrs["units"] = "Pa"
            fields.create_dataset("step", data=np.asarray(field_steps, dtype=np.int64))
            fields.create_dataset("x", data=x).attrs["units"] = "m"
            fields.create_dataset("y", data=y).attrs["units"] = "m"
            f.create_group("mesh").create_dataset("xy", data=cell_corners(x, y), compression="gzip",
                                                  compression_opts=1).attrs["units"] = "m"

        atomic_write(path, lambda tmp: _write_hdf5(tmp, fill))
        times = np.asarray(series["t"])[np.asarray(field_steps, dtype=int)] if len(field_steps) else []
        text = xdmf_text(path.name, nx, ny, list(np.asarray(field_steps, dtype=int)), list(times))
        atomic_write(path.with_suffix(".xdmf"), lambda tmp: tmp.write_text(text, encoding="utf-8"))
    except OSError as exc:
        raise OutputError(f"{path}: cannot write the results ({reason(exc)}); the previous results file, if "
                          "any, is unchanged") from None


def _write_hdf5(tmp: pathlib.Path, fill) -> None:
    with h5py.File(tmp, "w") as f:
        fill(f)


def atomic_write(path: pathlib.Path, write) -> None:
    """Write ``path`` as a whole or not at all: ``write(tmp)`` fills a temporary file in the same directory,
    which is fsynced and renamed over ``path`` (the directory is fsynced too). On any failure the temporary
    file is removed and ``path`` keeps its previous contents."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        write(tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        sync_directory(path.parent)
    finally:
        if tmp.exists():
            tmp.unlink()


def sync_directory(directory: pathlib.Path) -> None:
    """fsync a directory, so that a rename in it survives a crash of the machine (where the OS allows it)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def cell_corners(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """((nx + 1) (ny + 1), 2) corner coordinates of the cells centred at x, y (uniform), the last axis
    (Y) varying fastest: the geometry of a 2DSMesh whose cell (i, j) is pressure[i, j]."""
    dx = (x[-1] - x[0]) / (len(x) - 1) if len(x) > 1 else 1.0
    dy = (y[-1] - y[0]) / (len(y) - 1) if len(y) > 1 else 1.0
    xe = np.concatenate([x - dx / 2, [x[-1] + dx / 2]])
    ye = np.concatenate([y - dy / 2, [y[-1] + dy / 2]])
    X, Y = np.meshgrid(xe, ye, indexing="ij")
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def xdmf_text(h5_name: str, nx: int, ny: int, field_steps: list[int], times: list[float]) -> str:
    """XDMF 2 describing the saved pressure fields of ``h5_name`` (same directory) as a temporal collection
    of structured grids over the HDF5 datasets: no data is copied. ParaView: File > Open results.xdmf."""
    n = len(field_steps)
    corners = f"{(nx + 1) * (ny + 1)} 2"
    lines = ['<?xml version="1.0" ?>', '<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>',
             '<Xdmf Version="2.0">', "  <Domain>",
             '    <Grid Name="pressure" GridType="Collection" CollectionType="Temporal">']
    for k, (step, t) in enumerate(zip(field_steps, times)):
        lines += [
            f'      <Grid Name="step {int(step)}" GridType="Uniform">',
            f'        <Time Value="{float(t)!r}"/>',
            f'        <Topology TopologyType="2DSMesh" Dimensions="{nx + 1} {ny + 1}"/>',
            '        <Geometry GeometryType="XY">',
            f'          <DataItem Dimensions="{corners}" NumberType="Float" Precision="8" Format="HDF">'
            f"{h5_name}:/mesh/xy</DataItem>",
            "        </Geometry>",
            '        <Attribute Name="pressure" AttributeType="Scalar" Center="Cell">',
            f'          <DataItem ItemType="HyperSlab" Dimensions="1 {nx} {ny}" Type="HyperSlab">',
            f'            <DataItem Dimensions="3 3" Format="XML">{k} 0 0 1 1 1 1 {nx} {ny}</DataItem>',
            f'            <DataItem Dimensions="{n} {nx} {ny}" NumberType="Float" Precision="8" Format="HDF">'
            f"{h5_name}:/fields/pressure</DataItem>",
            "          </DataItem>",
            "        </Attribute>",
            "      </Grid>",
        ]
    lines += ["    </Grid>", "  </Domain>", "</Xdmf>", ""]
    return "\n".join(lines)
