"""How accurate petroll's answers are, measured (docs/accuracy.md, docs/verification.md, docs/benchmarks.md).

- :func:`verify`: a scene's error estimate (petroll.studies.estimate) against its true error, the
  difference from a reference on a grid 4x finer (the time step 4x smaller where the steps follow the
  cell), both at the fine run's last time;
- :func:`bench_convergence`: the last step's values on grids of 2, 4, 8 ... cells per contact half-width
  against a reference with twice the finest's (``petroll bench accuracy``);
- :func:`bench_orders`: each time integrator's order in the cell size, the cell and the step refined
  together (``petroll bench accuracy``);
- :func:`cost`: the estimate's wall time against the fine run's (``petroll bench estimate``: the target
  is at most 25 %).

The scenes: the shipped sphere (runs/sphere.toml) and roller (runs/roller-2d.toml), the sphere as a height
map sampled on the cell centres, and the conveyor idler's belt cover (runs/conveyor-idler.toml, a layer);
the sphere and the roller with each other integrator ("exponential", "paper", and "paper" on the SLS given
as a tabulated J(t)).
"""

from __future__ import annotations

import math
import pathlib
import time as clock
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from petroll.model.clock import TimeMode
from petroll.model.scene import Scene, load_scene, parse_scene, shipped_scene
from petroll.studies.estimate import COUNTED, ErrorEstimate, end_time, estimate_error
from petroll.records import StepRecord
from petroll.solver.simulation import Simulation


def refined(scene: Scene, factor: float, end: float | None) -> Scene:
    """``scene`` with ``factor`` times the cells along each axis over the same extent (rounded), run to time
    ``end`` (s) without its steady stop (None: its own clock: one step or a steady solve)."""
    g = scene.grid
    changes: dict = {"grid.nx": max(1, round(g.nx * factor))}
    if not g.line:
        changes["grid.ny"] = max(1, round(g.ny * factor))
    if end is not None and scene.time.mode is not TimeMode.STEADY:
        changes.update({"time.steady": None, "time.distance": None, "time.end": end})
    return scene.replace(changes)


def last_record(scene: Scene, comm: MPI.Comm) -> tuple[StepRecord, float]:
    """The last step's record of ``scene`` run to its end, and the run's wall time (s; max over ranks)."""
    began = clock.perf_counter()
    record = list(Simulation(scene, comm).steps())[-1]
    return record, comm.allreduce(clock.perf_counter() - began, op=MPI.MAX)


@dataclass(frozen=True)
class Check:
    """One quantity of :func:`verify`: the fine value, the estimated error, the true error |fine - ref|,
    and the extrapolated value's distance from the reference (nan where the estimate gave none)."""

    name: str
    value: float
    reference: float
    estimated: float
    true: float
    extrapolated_off: float

    @property
    def ratio(self) -> float:
        """estimated / true error."""
        return self.estimated / self.true if self.true > 0 else math.inf

    @property
    def asymptotic(self) -> bool:
        """The estimate gave an error (else its grids were not in the asymptotic range)."""
        return math.isfinite(self.estimated)

    @property
    def within_3(self) -> bool:
        return self.asymptotic and self.true / 3 <= self.estimated <= 3 * self.true

    @property
    def bounds(self) -> bool:
        """The estimated error is at least the true one."""
        return self.asymptotic and self.estimated >= self.true * (1 - 1e-9)

    @property
    def closer(self) -> bool:
        """The extrapolated value is nearer the reference than the fine one."""
        return self.extrapolated_off < self.true


def verify(scene: Scene, comm: MPI.Comm = MPI.COMM_WORLD, reference: float = 4.0
           ) -> tuple[list[Check], ErrorEstimate]:
    """Run ``scene``, estimate its error, and compare with a reference ``reference`` times finer at the same
    time (4x: a first-order error is measured at 3/4 of its size, a second-order one at 15/16)."""
    record, _ = last_record(scene, comm)
    found = estimate_error(scene, record, comm)
    reference, _ = last_record(refined(scene, reference, end_time(scene, record)), comm)
    checks = []
    for name, q in found.quantities.items():
        ref = float(getattr(reference, name))
        checks.append(Check(name, q.value, ref, q.error, abs(q.value - ref), abs(q.extrapolated - ref)))
    return checks, found


def cost(scene: Scene, out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD,
         repeats: int = 3) -> dict[str, float]:
    """Wall times (s, warm, in this process, best of ``repeats``) of ``petroll.run(scene, out=out,
    estimate_error=True)`` as results.h5 records them: the run itself (with its output), its estimate, and
    their ratio."""
    from petroll.driver import run

    runs, estimates = [], []
    for _ in range(repeats):
        group = run(scene, comm, out, estimate_error=True).error_estimate[""]
        runs.append(float(group["run_wall_s"]))
        estimates.append(float(group["wall_s"]))
    fine, extra = min(runs), min(estimates)
    return {"fine_s": fine, "estimate_s": extra, "ratio": extra / fine}


def heightmap_sphere(directory: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD) -> Scene:
    """runs/sphere.toml with its sphere as a height map sampled on the grid's cell centres (one cell per
    step: the samples stay on the centres), written to ``directory``/sphere.npy."""
    from petroll.model.bodies import Sphere

    base = load_scene(shipped_scene("sphere.toml"))
    g = base.grid
    position = (float(g.x[26]), float(g.y[26]))
    k = (np.arange(-60, 61)) * g.dx
    if comm.rank == 0:
        directory.mkdir(parents=True, exist_ok=True)
        np.save(directory / "sphere.npy", Sphere(base.body.radius_hint).height(k[:, None], k[None, :]))
    comm.Barrier()
    raw = dict(base.raw, body={"shape": "heightmap", "file": "sphere.npy", "cell": g.dx,
                               "position": list(position)})
    return parse_scene(raw, source="sphere.toml as a height map", base_dir=directory)


def profile_roller(directory: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD) -> Scene:
    """runs/roller-2d.toml with its roller as a 1-D profile (a height map in line contact) sampled on the
    grid's cell centres, written to ``directory``/roller.npy."""
    from petroll.model.bodies import CylinderSection

    base = load_scene(shipped_scene("roller-2d.toml"))
    h = base.grid.dx
    k = (np.arange(-60, 60) + 0.5) * h
    if comm.rank == 0:
        directory.mkdir(parents=True, exist_ok=True)
        np.save(directory / "roller.npy", CylinderSection(base.body.radius_hint).height(k, 0.0 * k))
    comm.Barrier()
    raw = dict(base.raw, body={"shape": "heightmap", "file": "roller.npy", "cell": h})
    return parse_scene(raw, source="roller-2d.toml as a profile", base_dir=directory)


def tabulated(scene: Scene, directory: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD) -> Scene:
    """``scene`` with its material's J(t) as a table (``directory``/J.csv: t = 0 and 4000 times spaced
    evenly in log from 1e-6 to 100 times its longest time, linear between them: within 3e-6 of J0 - Jinf
    for an SLS), which only the "paper" integrator (the hereditary sum) takes."""
    material = scene.material
    t = np.concatenate([[0.0], np.geomspace(1e-6, 100.0, 4000) * material.longest_time])
    if comm.rank == 0:
        directory.mkdir(parents=True, exist_ok=True)
        np.savetxt(directory / "J.csv", np.c_[t, material(t)], delimiter=",")
    comm.Barrier()
    raw = dict(scene.raw, material={"model": "tabulated", "file": "J.csv", "quantity": "J"})
    raw["solver"] = dict(raw.get("solver", {}), integrator="paper")
    return parse_scene(raw, source=f"{scene.source} with a tabulated J", base_dir=directory)


def with_integrator(name: str, integrator: str) -> Scene:
    """The shipped scene ``name`` with [solver] integrator = ``integrator``."""
    return load_scene(shipped_scene(name)).replace({"solver.integrator": integrator})


VERIFICATION = ("sphere.toml", "roller-2d.toml", "sphere.toml, height map", "roller-2d.toml, 1-D profile",
                "conveyor-idler.toml (layer)")
"""The labels of the verification scenes (:func:`verification_scenes`) of the default integrator."""

INTEGRATORS = ("sphere.toml, exponential", "sphere.toml, paper", "sphere.toml, tabulated J (paper)",
               "roller-2d.toml, exponential", "roller-2d.toml, paper", "roller-2d.toml, tabulated J (paper)")
"""The labels of the verification scenes with the other integrators (:func:`verification_scenes`)."""


def verification_scenes(directory: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD,
                        only: tuple[str, ...] = VERIFICATION) -> dict[str, Scene]:
    """The scenes of the verification table (those of ``only``): runs/sphere.toml, runs/roller-2d.toml, the
    sphere as a height map (:func:`heightmap_sphere`), the roller as a 1-D profile (:func:`profile_roller`)
    and the conveyor idler's belt cover (a layer, runs/conveyor-idler.toml); the sphere and the roller with
    the integrators "exponential" and "paper" and with their SLS as a table (:func:`tabulated`)."""
    make = {"sphere.toml": lambda: load_scene(shipped_scene("sphere.toml")),
            "roller-2d.toml": lambda: load_scene(shipped_scene("roller-2d.toml")),
            "sphere.toml, height map": lambda: heightmap_sphere(directory, comm),
            "roller-2d.toml, 1-D profile": lambda: profile_roller(directory, comm),
            "conveyor-idler.toml (layer)": lambda: load_scene(shipped_scene("conveyor-idler.toml"))}
    for name in ("sphere.toml", "roller-2d.toml"):
        for integrator in ("exponential", "paper"):
            make[f"{name}, {integrator}"] = lambda n=name, i=integrator: with_integrator(n, i)
        make[f"{name}, tabulated J (paper)"] = lambda n=name: tabulated(
            load_scene(shipped_scene(n)), directory / n.removesuffix(".toml"), comm)
    return {label: make[label]() for label in only}


def bench(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, scenes: tuple[str, ...] = VERIFICATION,
          factors: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0), reference: float = 4.0,
          integrators: tuple[str, ...] = INTEGRATORS,
          order_factors: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0)) -> list[dict]:
    """``petroll bench accuracy``: :func:`bench_verify` on ``scenes`` and ``integrators`` (labels of
    :data:`VERIFICATION`, :data:`INTEGRATORS`), :func:`bench_convergence` on ``scenes``, then
    :func:`bench_orders` on the sphere and roller among ``scenes`` and on ``integrators``; returns the three
    tables' rows."""
    plain = tuple(label for label in scenes if label in ("sphere.toml", "roller-2d.toml"))
    return (bench_verify(out, comm, scenes + integrators)
            + bench_convergence(out, comm, factors, reference, scenes)
            + bench_orders(out, comm, plain + integrators, order_factors))


def bench_verify(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD,
                 scenes: tuple[str, ...] = VERIFICATION + INTEGRATORS) -> list[dict]:
    """``petroll bench accuracy``'s first table: each verification scene's estimate against its true error
    (reference 4x finer), the order it took and whether its asymptotic range was checked; writes
    ``out/estimate_verification.csv``."""
    from petroll.studies.tables import print_table, write_table

    rows = []
    for label, scene in verification_scenes(out / "bodies", comm, scenes).items():
        checks, found = verify(scene, comm)
        grids = " / ".join(f"{nx}x{ny}" if ny > 1 else f"{nx}" for nx, ny in found.grids)
        for c in checks:
            if c.name in ("force", "delta") and c.true <= 1e-12 * abs(c.reference):
                continue  # the controlled one
            counted = c.name in COUNTED
            verdict = ("not asymptotic" if not c.asymptotic else
                       ("bounds" if c.bounds else "below") if counted else
                       "within 3" if c.within_3 else "not within 3")
            q = found.quantities[c.name]
            rows.append({"scene": label, "grids": grids, "quantity": c.name, "fine": f"{c.value:.6g}",
                         "reference": f"{c.reference:.6g}", "estimated": f"{c.estimated:.2g}",
                         "true": f"{c.true:.2g}", "ratio": f"{c.ratio:.2f}", "estimate": verdict,
                         "order": f"{q.order:.2f}" + (" observed" if q.observed else ""),
                         "range_checked": q.checked,
                         "extrapolated_closer": "-" if counted or not c.asymptotic else c.closer})
    if comm.rank == 0:
        write_table(rows, out / "estimate_verification.csv", show=False)
        print_table(rows)
    return rows


def bench_convergence(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD,
                      factors: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0), reference: float = 4.0,
                      scenes: tuple[str, ...] = VERIFICATION) -> list[dict]:
    """``petroll bench accuracy``'s second table: the last step's relative errors against cells per contact
    half-width (each verification scene at ``factors`` times its cells per axis, against ``reference``
    times, all to the time of the shipped resolution's last step); writes ``out/convergence.csv``."""
    from petroll.model.preflight import check
    from petroll.studies.tables import print_table, write_table

    rows = []
    for label, scene in verification_scenes(out / "bodies", comm, scenes).items():
        record, _ = last_record(scene, comm)
        end = end_time(scene, record)
        truth, _ = last_record(refined(scene, reference, end), comm)
        for factor in factors:
            grid = refined(scene, factor, end)
            got, _ = last_record(grid, comm)
            row = {"scene": label, "cells": f"{min(check(grid).cells):.1f}"}
            for name in ("force", "delta", "mu_r", "p_max", "area"):
                ref = float(getattr(truth, name))
                row[name] = f"{abs(getattr(got, name) / ref - 1):.1e}" if ref else "-"
            rows.append(row)
    if comm.rank == 0:
        write_table(rows, out / "convergence.csv", show=False)
        print_table(rows)
    return rows


ORDER_QUANTITIES = ("force", "delta", "mu_r", "p_max")
"""The quantities whose order :func:`bench_orders` observes (not what counts cells)."""


def bench_orders(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD,
                 scenes: tuple[str, ...] = ("sphere.toml", "roller-2d.toml") + INTEGRATORS,
                 factors: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0)) -> list[dict]:
    """``petroll bench accuracy``'s third table: the order in the cell size of each scene's integrator, the
    cell and the step refined together as the error estimate's coarser grids do: each scene (labels of
    :data:`VERIFICATION` and :data:`INTEGRATORS`) at ``factors`` times its cells per axis, all to the time
    of the shipped resolution's last step; for each quantity the orders log2(d_k / d_k+1) of the
    differences d_k between successive grids (no reference needed; "-" where the differences change sign
    or vanish, e.g. the controlled quantity). Writes ``out/orders.csv``."""
    from petroll.model.preflight import check
    from petroll.studies.tables import print_table, write_table

    rows = []
    for label, scene in verification_scenes(out / "bodies", comm, scenes).items():
        record, _ = last_record(scene, comm)
        end = end_time(scene, record)
        grids = [refined(scene, factor, end) for factor in factors]
        values = [last_record(grid, comm)[0] for grid in grids]
        for k in range(len(factors) - 2):
            row = {"scene": label, "integrator": scene.solver.integrator,
                   "cells": " / ".join(f"{min(check(g).cells):.1f}" for g in grids[k:k + 3])}
            for name in ORDER_QUANTITIES:
                d1, d2 = (float(getattr(values[k + i], name) - getattr(values[k + i + 1], name))
                          for i in (0, 1))
                scale = 1e-12 * abs(float(getattr(values[-1], name)))
                row[name] = (f"{math.log2(d1 / d2):.2f}" if d1 * d2 > 0 and min(abs(d1), abs(d2)) > scale
                             else "-")
            rows.append(row)
    if comm.rank == 0:
        write_table(rows, out / "orders.csv", show=False)
        print_table(rows)
    return rows


def bench_cost(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, factors: tuple[int, ...] = (1, 2, 4),
               repeats: int = 3) -> list[dict]:
    """``petroll bench estimate``: the estimate's wall time against the run's (:func:`cost`, best of
    ``repeats``), runs/sphere.toml at ``factors`` times its cells per axis (the estimate's cost is a fixed
    part per step plus a part per cell), runs/roller-2d.toml and runs/conveyor-idler.toml; writes ``out/estimate_cost.csv``.
    The target: at most 25 %."""
    from petroll.studies.tables import print_table, write_table

    rows = []
    sphere = load_scene(shipped_scene("sphere.toml"))
    cases = [(f"sphere.toml, {k}x cells" if k > 1 else "sphere.toml", refined(sphere, k, None)) for k in factors]
    cases += [("roller-2d.toml", load_scene(shipped_scene("roller-2d.toml"))),
              ("conveyor-idler.toml", load_scene(shipped_scene("conveyor-idler.toml")))]
    for k, (label, scene) in enumerate(cases):
        found = cost(scene, out / f"runs-{k}", comm, repeats)
        g = scene.grid
        rows.append({"scene": label, "grid": f"{g.nx}x{g.ny}", "fine_s": f"{found['fine_s']:.3f}",
                     "estimate_s": f"{found['estimate_s']:.3f}", "ratio": f"{found['ratio']:.3f}",
                     "target_met": found["ratio"] <= 0.25})
    if comm.rank == 0:
        write_table(rows, out / "estimate_cost.csv", show=False)
        print_table(rows)
    return rows
