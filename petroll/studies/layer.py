"""The conveyor-idler study (docs/layer.md): indentation rolling resistance of a roller on a viscoelastic
cover of finite thickness, against the half-space and the Winkler model of conveyor design.

For each cover thickness h the scene runs/conveyor-idler.toml (line contact: forces per unit length of the
idler) is run to its steady state on the layer (bonded and frictionless base), once on the half-space,
and the Winkler model is solved in its steady state directly (:func:`winkler_rolling`). Run as

    .venv/bin/python -m petroll.studies.layer [--out docs/img/layer] [--fast]

which writes ``layer.csv`` and ``rolling-resistance.png``, ``contact.png``, ``pressure.png`` in the output
directory.

Its benchmark, ``petroll bench layer``, is petroll.bench.layer.
"""

from __future__ import annotations

import argparse
import math
import pathlib

import numpy as np
from mpi4py import MPI

from petroll.model.materials import relaxation_series
from petroll.model.scene import load_scene, shipped_scene
from petroll.solver.simulation import Simulation
from petroll.studies.tables import new_figure, write_table

COLUMNS = ("delta", "force_x", "mu_r", "lead", "trail", "steps", "seconds")
"""The values of a row after its thickness (mm) and model: delta (m, absolute on a layer, to the datum on
the half-space), F_x (N/m), mu_r, the contact's front and rear edges (m), and for petroll's runs the steps
to the steady state and their solve time (s)."""

THICKNESSES = (1e-3, 2e-3, 3e-3, 4e-3, 6e-3, 10e-3, 20e-3, 40e-3)
"""Cover thicknesses of the sweep (m)."""


def winkler_rolling(material, nu: float, thickness: float, radius: float, speed: float, load: float,
                    cells: int = 4000) -> dict:
    """Steady rolling of a rigid cylinder (``radius``, m) at ``speed`` (m/s) under ``load`` (N/m) on a bed of
    independent springs (the Winkler model): each column of the cover, of ``thickness`` h, carries
    sigma = (1/h) int E(t - s) dw(s), E the uniaxial relaxation modulus of ``material`` (a Prony J(t); its
    relaxation series from :func:`petroll.model.materials.relaxation_series` times 1 - nu^2),
    w = delta - x^2/(2R) its compression from the front edge x = sqrt(2 R delta) until sigma falls to 0
    behind. Returns the penetration delta (m), the resisting force F_x = int sigma x/R dx (N/m), mu_r =
    F_x/load, the front and rear edges (m, relative to the axis), and the contact's "x" (m, relative to
    the axis) and "pressure" sigma (Pa). This is the model of the conveyor
    literature (a Winkler foundation of viscoelastic springs of modulus E/h: Jonkers 1980, Lodewijks 1996)
    as petroll solves it; their closed forms were not checked here."""
    ginf, dg, theta = relaxation_series(material)
    scale = 1.0 - nu**2  # the surface modulus 1/J times 1 - nu^2: Young's modulus
    einf, moduli, times = ginf * scale, np.asarray(dg) * scale, np.asarray(theta)

    def solve(delta: float):
        front = math.sqrt(2 * radius * delta)
        x = np.linspace(front, -front, cells + 1)
        w = delta - x * x / (2 * radius)
        dt = (x[0] - x[1]) / speed
        decay = np.exp(-dt / times)
        weight = times / dt * (1 - decay)  # exact for w linear over a step
        q = np.zeros(len(times))
        sigma = np.zeros_like(x)
        for i in range(1, len(x)):
            q = decay * q + weight * (w[i] - w[i - 1])
            sigma[i] = (einf * w[i] + moduli @ q) / thickness
        ends = np.flatnonzero(sigma[1:] <= 0)
        last = ends[0] + 1 if len(ends) else len(x)
        xs, ss = x[:last], np.maximum(sigma[:last], 0)
        force = float(np.trapz(ss, -xs))
        return force, float(np.trapz(ss * xs / radius, -xs)), front, float(xs[-1]), xs, ss

    lo, hi = 0.0, 1e-6
    while solve(hi)[0] < load:
        lo, hi = hi, 2 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if solve(mid)[0] < load else (lo, mid)
    delta = 0.5 * (lo + hi)
    force, force_x, front, rear, x, sigma = solve(delta)
    return {"delta": delta, "force_x": force_x, "mu_r": force_x / force, "lead": front, "trail": rear,
            "x": x, "pressure": sigma}


def steady(scene, comm: MPI.Comm) -> dict:
    """The last record of a line-contact run to its steady state ([time] steady) as a dict, with its
    pressure "pressure" (Pa, every cell) at "x" (m, relative to the body)."""
    sim = Simulation(scene, comm)
    records = list(sim.steps())
    r = records[-1]
    return {"delta": r.delta, "force_x": r.force_x, "mu_r": r.mu_r, "lead": r.lead, "trail": r.trail,
            "steps": len(records), "seconds": sum(x.solve_time for x in records),
            "x": scene.grid.x - r.sx, "pressure": np.concatenate(comm.allgather(sim.pressure[:, 0]))}


def sweep(comm: MPI.Comm = MPI.COMM_WORLD, thicknesses=THICKNESSES, path=None) -> list[dict]:
    """Rows (thickness_mm, model, delta, force_x, mu_r, lead, trail, ...) of the study; model one of
    "layer bonded", "layer frictionless", "half-space", "winkler E/h"."""
    scene = load_scene(path or shipped_scene("conveyor-idler.toml"))
    radius, speed, load = scene.body.radius_hint, float(scene.velocity(0.0)[0]), float(scene.load(0.0))
    rows = []

    def row(h, model, values):
        rows.append({"thickness_mm": round(h * 1e3, 6), "model": model,
                     **{k: f"{values[k]:.6g}" if k in values else "" for k in COLUMNS}})

    half_space = steady(scene.replace("material.layer", None), comm)
    for h in thicknesses:
        for base in ("bonded", "frictionless"):
            row(h, f"layer {base}", steady(scene.replace("material.layer", {"thickness": h, "base": base}),
                                           comm))
        row(h, "half-space", half_space)
        row(h, "winkler E/h", winkler_rolling(scene.material, scene.layer.nu, h, radius, speed, load))
    return rows


def figures(rows: list[dict], out: pathlib.Path) -> None:
    """rolling-resistance.png (mu_r against h) and contact.png (contact length against h)."""
    models = ("layer bonded", "layer frictionless", "half-space", "winkler E/h")
    for name, key, label in (("rolling-resistance.png", "mu_r", "rolling resistance F_x / F"),
                             ("contact.png", None, "contact length (mm)")):
        fig = new_figure(6.0, 4.0)
        if fig is None:
            return
        ax = fig.add_subplot()
        for model in models:
            mine = [r for r in rows if r["model"] == model]
            h = [r["thickness_mm"] for r in mine]
            y = [float(r[key]) if key else (float(r["lead"]) - float(r["trail"])) * 1e3 for r in mine]
            ax.plot(h, y, "o-" if model.startswith("layer") else "--", label=model)
        ax.set_xscale("log")
        ax.set_xlabel("cover thickness h (mm)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(out / name, dpi=110)


def profiles(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, path=None) -> None:
    """pressure.png: the steady pressure under the idler on its own cover (the scene's thickness), bonded
    and frictionless, on the half-space and on the Winkler bed."""
    scene = load_scene(path or shipped_scene("conveyor-idler.toml"))
    h = scene.layer.thickness
    curves = {f"layer bonded, h = {h * 1e3:g} mm": steady(
                  scene.replace("material.layer", {"thickness": h, "base": "bonded"}), comm),
              f"layer frictionless, h = {h * 1e3:g} mm": steady(
                  scene.replace("material.layer", {"thickness": h, "base": "frictionless"}), comm),
              "half-space": steady(scene.replace("material.layer", None), comm),
              "winkler E/h": winkler_rolling(scene.material, scene.layer.nu, h, scene.body.radius_hint,
                                             float(scene.velocity(0.0)[0]), float(scene.load(0.0)))}
    fig = new_figure(6.0, 4.0) if comm.rank == 0 else None
    if fig is None:
        return
    ax = fig.add_subplot()
    for label, c in curves.items():
        ax.plot(np.asarray(c["x"]) * 1e3, np.asarray(c["pressure"]) / 1e6, "--" if "winkler" in label else "-",
                label=label)
    ax.set_xlim(-8, 8)
    ax.set_xlabel("x relative to the idler's axis (mm; rolling towards +x)")
    ax.set_ylabel("pressure (MPa)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "pressure.png", dpi=110)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(prog="python -m petroll.studies.layer",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="docs/img/layer", help="output directory")
    parser.add_argument("--fast", action="store_true", help="three thicknesses only")
    args = parser.parse_args(argv)
    out = pathlib.Path(args.out)
    rows = sweep(thicknesses=(2e-3, 6e-3, 20e-3) if args.fast else THICKNESSES)
    if MPI.COMM_WORLD.rank == 0:
        write_table(rows, out / "layer.csv")
        figures(rows, out)
    profiles(out)


if __name__ == "__main__":
    main()
