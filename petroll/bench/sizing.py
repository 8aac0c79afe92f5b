"""The measurements behind the resolution petroll asks of a rough surface and sizes for a smooth body
(docs/rough.md, docs/accuracy.md): tables printed and written as CSV.

``petroll bench cutoff [--out DIR]``: one self-affine surface (the spectrum of runs/rough-rubber.toml on a
2 mm cell) drawn at 16 cells per short cut-off wavelength and sampled at fewer by dropping its Fourier
modes above each grid's Nyquist frequency (every grid carries the same surface), the tread rubber of
runs/sphere-dma.toml sliding steadily on it at 10 mm/s under 0.2 MPa nominal: friction, area fraction and
penetration against those of 16 cells per cut-off (:func:`cutoff`, ``cutoff.csv``).

``petroll bench sized [--out DIR]``: the master curve's sphere and SLS (runs/master-curve.toml) under a
fixed load of 0.2 N, swept over speed on the grids petroll sizes (no [grid]) and on one hand-made grid of
320^2 square cells of 12.5 um: mu_r, penetration, area and peak pressure of each against the hand-made
grid's (:func:`sized`, ``sized.csv``; the sweeps' own files under ``sized-auto``, ``sized-fine``).
"""

from __future__ import annotations

import copy
import pathlib
import shutil
import warnings

import numpy as np
import scipy.fft
from mpi4py import MPI

from petroll.model.limits import PetrollWarning
from petroll.model.roughness import self_affine_heights
from petroll.model.scene import load_scene, parse_scene, shipped_scene
from petroll.studies.tables import write_table

CUTOFF = 62.5e-6
"""The short cut-off wavelength of the surface (m): runs/rough-rubber.toml's."""


def truncated(heights: np.ndarray, n: int) -> np.ndarray:
    """The periodic surface ``heights`` (N x N samples) sampled on n x n points of the same cell, sample 0
    on sample 0: its modes below n's Nyquist frequency along each axis kept, the rest dropped. (On the
    grids, each sample on a cell's centre, the coarser surface is the finer one moved by half a coarse
    cell less half a fine one: a translation, which a periodic cell's friction and area do not see.)"""
    size = heights.shape[0]
    spectrum = scipy.fft.rfft2(heights)
    kept = np.zeros((n, n // 2 + 1), dtype=complex)
    k = n // 2
    kept[:k, :k] = spectrum[:k, :k]
    kept[-k + 1:, :k] = spectrum[-k + 1:, :k]
    return scipy.fft.irfft2(kept, s=(n, n)) * (n / size) ** 2


def cutoff(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, cells=(8, 6, 4, 3, 2), reference: int = 16,
           side: float = 2e-3, speed: float = 0.01) -> list[dict]:
    """The rough surface's steady sliding at ``reference`` and ``cells`` cells per cut-off (module
    docstring), relative differences against ``reference``. Writes ``out/cutoff.csv``."""
    from petroll.driver import run

    base = load_scene(shipped_scene("rough-rubber.toml"))
    size = round(side / CUTOFF * reference)
    keys = {"hurst": 0.8, "rolloff": 1e-3, "cutoff": CUTOFF, "rms_slope": 0.08, "seed": 1}
    heights = self_affine_heights(keys, (size, size), (side / size,) * 2)
    found = {}
    for count in (reference, *cells):
        n = round(side / CUTOFF * count)
        path = out / f"cutoff-{n}.npy"
        if comm.rank == 0:
            out.mkdir(parents=True, exist_ok=True)
            np.save(path, truncated(heights, n))
        comm.Barrier()
        raw = copy.deepcopy(base.raw)
        raw["grid"] = {"nx": n, "ny": n, "x": [0.0, side], "y": [0.0, side], "periodic": True}
        raw["body"] = {"shape": "heightmap", "file": str(path.resolve()), "cell": side / n}
        raw["motion"] = {"velocity": [speed, 0.0], "load": 0.2e6 * side**2}
        raw.pop("output", None)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PetrollWarning)  # below 4 cells: what is measured
            s = run(parse_scene(raw), comm, out / f"cutoff-{n}", overwrite=True).series
        found[count] = (float(s["mu_r"][-1]), float(s["area"][-1]) / side**2, float(s["delta"][-1]))
    mu0, area0, delta0 = found[reference]
    rows = [dict(cells_per_cutoff=count, cells=f"{round(side / CUTOFF * count)}^2", mu=f"{mu:.5g}",
                 area_fraction=f"{area:.4f}", penetration=f"{delta:.5g}", mu_change=f"{mu / mu0 - 1:+.2%}",
                 area_change=f"{area / area0 - 1:+.2%}", penetration_change=f"{delta / delta0 - 1:+.3%}")
            for count, (mu, area, delta) in found.items()]
    if comm.rank == 0:
        write_table(rows, out / "cutoff.csv")
    return rows


def sized(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, speeds: str = "1e-4..1:log:9", fine: int = 320,
          half: float = 2e-3) -> list[dict]:
    """The fixed-load speed sweep on sized grids and on a ``fine``^2 grid over +-``half`` (m) (module
    docstring). Writes ``out/sized.csv``."""
    from petroll.studies.sweep import sweep

    raw = copy.deepcopy(load_scene(shipped_scene("master-curve.toml")).raw)
    raw["motion"] = {"velocity": [0.01, 0.0], "load": 0.2}
    raw.pop("output", None)
    tables = {}
    hand_made = {"nx": fine, "ny": fine, "x": [-half, half], "y": [-half, half]}
    for name, grid in (("auto", None), ("fine", hand_made)):
        if grid is None:
            raw.pop("grid")
        else:
            raw["grid"] = grid
        target = out / f"sized-{name}"
        if comm.rank == 0 and target.exists():
            shutil.rmtree(target)
        comm.Barrier()
        tables[name] = sweep(parse_scene(raw), f"motion.velocity={speeds}", target, comm, plot=False).columns
    a, f = tables["auto"], tables["fine"]
    rows = [dict(speed=f"{v:.4g}", v_tau_a=f"{va:.3g}", mu_r=f"{m:.5g}",
                 **{f"{q}_change": f"{a[q][k] / f[q][k] - 1:+.2%}" for q in ("mu_r", "delta", "area", "p_max")})
            for k, (v, va, m) in enumerate(zip(a["value"], a["v_tau_a"], a["mu_r"]))]
    if comm.rank == 0:
        write_table(rows, out / "sized.csv")
    return rows
