"""stress.h5: the stresses below a saved pressure field of a run (``petroll stress``; docs/results.md), and
its tangential tractions with friction.

    /z                    (nz,) depths below the surface in m (z into the half-space)
    /x, /y                (nx,), (ny,) cell-centre coordinates in m (material frame), as in results.h5
    /sigma_xx ... /sigma_yz, /von_mises, /max_shear
                          (nz, nx, ny) in Pa at the cell centres, tension positive (the surface carries
                          sigma_zz = -p); max_shear is Tresca's: half the largest principal stress difference;
                          line contact (plane strain): (nz, nx)
    attributes            step, t (s), nu, source (the results file), motion_axis ("x" or "y": the section
                          of stress.png), line_contact, and for von_mises and max_shear: <name>_max (Pa)
                          with its location <name>_at = (x, y, z) in m (line contact: y = 0)

Written by rank 0 one depth at a time (each rank's rows gathered for that depth only) to a temporary name,
fsynced and renamed into place.
"""

from __future__ import annotations

import pathlib

import h5py
import numpy as np

from petroll.errors import PetrollError, reason
from petroll.io.journal import reading
from petroll.io.hdf5 import atomic_hdf5, reading_as
from petroll.io.results import RESULTS_FILE, OutputError
from petroll.io.rundir import clean_temporaries
from petroll.solver.partition import RowPartition, gather_field

STRESS_FILE = "petroll stress file"
"""What a stress file is called in the error that a damaged one gives."""

STRESS_DATASETS = ("sigma_xx", "sigma_yy", "sigma_zz", "sigma_xy", "sigma_xz", "sigma_yz", "von_mises",
                   "max_shear")
"""The (nz, nx, ny) datasets of stress.h5, in Pa."""


def read_saved_pressure(path: pathlib.Path, step: int | None, comm) -> dict:
    """This rank's rows (:class:`RowPartition` over ``comm``) of the pressure field saved at ``step`` (None:
    the last saved) of a results file, with what a stress computation needs: ``pressure`` (local rows, ny)
    Pa, ``rows`` (r0, r1), ``step``, ``t`` (s), ``x``, ``y`` (m), ``scene`` (its TOML text), ``sx``, ``sy``
    (the body's path, m), ``line`` (a line-contact run: ny = 1), ``traction`` (a run with friction: the
    tangential tractions on the body, (m, local rows, ny) Pa; None without). Collective in effect (every rank reads its rows). Raises PetrollError naming the
    file or the step (with the saved steps) when it cannot."""
    with reading_as(path, RESULTS_FILE), reading(path) as f:
        r0, r1 = RowPartition(len(f["fields/x"]), comm.size).range(comm.rank)
        steps = f["fields/step"][: int(f.attrs.get("fields_written", len(f["fields/step"])))]
        if len(steps) == 0:
            raise PetrollError(f"{path}: the file holds no saved pressure fields")
        k = len(steps) - 1 if step is None else np.flatnonzero(steps == step)
        if step is not None and len(k) == 0:
            shown = ", ".join(str(int(s)) for s in steps[:20]) + (", ..." if len(steps) > 20 else "")
            raise PetrollError(f"--step {step}: no pressure field saved at that step in {path}; saved "
                               f"steps: {shown} ([output] every sets them)")
        k = int(k) if step is None else int(k[0])
        series = f["series"]
        n = int(f.attrs.get("steps_written", len(series["step"])))  # a growing file: its valid part
        row = int(np.flatnonzero(series["step"][:n] == steps[k])[0])
        tangential = [f["fields"][name][k, r0:r1, :] for name in ("traction_x", "traction_y")
                      if name in f["fields"]]
        return {"pressure": f["fields/pressure"][k, r0:r1, :], "rows": (r0, r1), "step": int(steps[k]),
                "traction": np.stack(tangential) if tangential else None,
                "line": bool(f.attrs.get("line_contact", False)),
                "t": float(series["t"][row]), "x": f["fields/x"][()], "y": f["fields/y"][()],
                "scene": str(f.attrs["scene"]), "sx": series["sx"][:n], "sy": series["sy"][:n]}


def write_stress(path: pathlib.Path, z: np.ndarray, x: np.ndarray, y: np.ndarray, depths, attrs,
                 comm, line: bool = False) -> None:
    """Write stress.h5 atomically; collective. ``depths`` yields, for each z in turn, this rank's rows of
    the eight fields (8, local rows, ny) in the order of :data:`STRESS_DATASETS`; ``attrs()`` (collective:
    called once on every rank after the last depth) gives the file's attributes. ``line``: a line-contact
    run (ny = 1), whose fields are written (nz, nx). Raises OutputError on every rank when the file cannot
    be written (after computing every depth: the ranks stay in step)."""
    nx, ny = len(x), len(y)
    shape = (len(z), nx) if line else (len(z), nx, ny)
    message, done = None, []

    def attributes() -> dict:
        done.append(True)
        return attrs()

    def fill(f, failed):
        f.create_dataset("z", data=z).attrs["units"] = "m"
        f.create_dataset("x", data=x).attrs["units"] = "m"
        f.create_dataset("y", data=y).attrs["units"] = "m"
        sets = [f.create_dataset(name, shape, dtype=float, chunks=(1, *shape[1:])) for name in
                STRESS_DATASETS]
        for d in sets:
            d.attrs["units"] = "Pa"
        for k, local in enumerate(depths):
            for d, field in zip(sets, local):
                whole = gather_field(field, nx, comm)
                if failed() is None:  # after a failed disk write: computing on with the other ranks only
                    d[k] = whole[:, 0] if line else whole
        for key, value in attributes().items():
            f.attrs[key] = value

    if comm.rank == 0:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            clean_temporaries(path.parent, [path.name])  # of a writer killed earlier
            atomic_hdf5(path, fill)
        except OSError as exc:
            message = f"{path}: cannot write the stresses ({exc.strerror or reason(exc)})"
            _drain(depths, nx, comm)  # the depths not yet computed: the other ranks wait for them
            if not done:
                attributes()
    else:
        _drain(depths, nx, comm)
        attributes()
    message = comm.bcast(message, root=0)
    if message is not None:
        raise OutputError(message)


def _drain(depths, nx: int, comm) -> None:
    """Compute (collectively) and gather the depths still to come, writing nothing."""
    for local in depths:
        for field in local:
            gather_field(field, nx, comm)


def stress_section(path: str | pathlib.Path, name: str, index: int) -> np.ndarray:
    """Dataset ``name`` of a stress file on the section along the motion (attribute motion_axis) through
    cell ``index`` across it: (nz, cells along the motion), Pa."""
    path = pathlib.Path(path)
    with reading_as(path, STRESS_FILE), h5py.File(path, "r") as f:
        d = f[name]
        return d[:, :, index] if f.attrs["motion_axis"] == "x" else d[:, index, :]


def stress_planes(path: str | pathlib.Path, name: str) -> dict:
    """For figures: dataset ``name`` (von_mises or max_shear) of a stress file at its maximum's depth:
    ``map`` (nx, ny) (line contact: the (nx,) profile, and ``section``: the whole (nz, nx) field); with
    ``z``, ``x``, ``y`` (m), ``peak`` (Pa), ``at`` (x, y, z of the maximum, m) and ``attrs``. Reads only
    that plane; :func:`stress_section` reads a section along the motion."""
    path = pathlib.Path(path)
    with reading_as(path, STRESS_FILE), h5py.File(path, "r") as f:
        attrs = dict(f.attrs)
        z, x, y = f["z"][()], f["x"][()], f["y"][()]
        at = np.asarray(attrs[f"{name}_at"], dtype=float)
        k = int(np.argmin(np.abs(z - at[2])))
        d = f[name]
        planes = {"map": d[k], "z": z, "x": x, "y": y, "peak": float(attrs[f"{name}_max"]), "at": at,
                  "attrs": attrs}
        if d.ndim == 2:  # line contact: the whole (nz, nx) section, a profile at the maximum's depth
            planes["section"] = d[()]
        return planes
