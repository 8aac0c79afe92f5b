"""results.h5: the per-step series and the saved pressure fields of a run (layout: docs/results.md).

    /series/<name>        1-D datasets, one value per step (force, delta, area, p_max, iterations, ...)
    /fields/pressure      (n_saved, nx, ny) pressure in Pa, axis 1 along X
    /fields/step          (n_saved,) step number of each saved field
    /fields/x, /fields/y  cell-centre coordinates in m (material frame)
    attributes            scene (the scene's TOML text), petroll_version, format_version

The file is written by rank 0 to a temporary name and renamed into place, so a reader never sees a
half-written file.
"""

from __future__ import annotations

import os
import pathlib
from dataclasses import dataclass

import h5py
import numpy as np

from petroll import __version__

FORMAT_VERSION = 1

SERIES_UNITS = {
    "step": "-", "t": "s", "sx": "m", "sy": "m", "delta": "m", "force": "N", "force_x": "N", "force_y": "N",
    "mu_r": "-", "area": "m^2", "p_max": "Pa", "cop_x": "m", "cop_y": "m", "lead": "m", "trail": "m",
    "dissipation": "W", "distance": "m", "iterations": "-", "applications": "-", "residual": "-",
    "solve_time": "s",
}
"""The series every run writes, with their units (attribute ``units`` of each dataset)."""


@dataclass
class Results:
    """A run's results as numpy arrays: ``series[name]`` (one value per step) and the saved fields."""

    path: pathlib.Path
    series: dict[str, np.ndarray]
    pressure: np.ndarray  # (n_saved, nx, ny), Pa
    field_steps: np.ndarray  # (n_saved,)
    x: np.ndarray  # (nx,) cell centres, m
    y: np.ndarray  # (ny,) cell centres, m
    scene_text: str

    @classmethod
    def open(cls, path: str | pathlib.Path) -> "Results":
        """Read a results file (any rank may call it)."""
        path = pathlib.Path(path)
        with h5py.File(path, "r") as f:
            series = {name: f["series"][name][()] for name in f["series"]}
            fields = f["fields"]
            return cls(path, series, fields["pressure"][()], fields["step"][()], fields["x"][()],
                       fields["y"][()], str(f.attrs["scene"]))


def write_results(path: pathlib.Path, series: dict[str, np.ndarray], pressure: np.ndarray,
                  field_steps: np.ndarray, x: np.ndarray, y: np.ndarray, scene_text: str) -> None:
    """Write a complete results file atomically (temporary file, fsync, rename). Call on one rank."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with h5py.File(tmp, "w") as f:
            f.attrs["scene"] = scene_text
            f.attrs["petroll_version"] = __version__
            f.attrs["format_version"] = FORMAT_VERSION
            group = f.create_group("series")
            for name, values in series.items():
                group.create_dataset(name, data=np.asarray(values)).attrs["units"] = SERIES_UNITS.get(name, "-")
            fields = f.create_group("fields")
            fields.create_dataset("pressure", data=pressure, compression="gzip", compression_opts=1,
                                  shuffle=True).attrs["units"] = "Pa"
            fields.create_dataset("step", data=field_steps)
            fields.create_dataset("x", data=x).attrs["units"] = "m"
            fields.create_dataset("y", data=y).attrs["units"] = "m"
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
