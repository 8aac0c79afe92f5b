"""Rolling benchmarks: work-precision of the integrators, cost growth, what each saving is worth (the
scenes and the step-by-step timing that petroll.bench.mpi shares).

``petroll bench precision [--out DIR]``: the default scene (runs/sphere.toml, changed in memory: no
``[time] steady`` stop, so every run rolls the scene's whole track and ends at the same body position)
at a ladder of time steps (``steps_per_cell``) for each integrator on the scene's grid, and at a ladder of
grids (dx and dt refined together, ``steps_per_cell`` = 1). Errors of the last step's force and mu_r
(the steady values) against references, and the run time of each run (``petroll.run``, median of 3 for
runs under 1 s). Time-step errors are measured against a reference on the *same* grid, so that the grid's
error does not mask them: the default integrator (``relaxation``, second order) at ``reference`` steps per
cell; its change from half as many steps is reported and bounds its own error. The grid line is measured
against its finest grid, whose change from the next coarser grid is reported likewise. From the ladders:
the run time each integrator needs to reach ``target`` relative error in force (and in mu_r),
interpolated log-log between the bracketing points, and the ratio paper / exponential. A time step that
an integrator refuses (the step guard, docs/stability.md) is a row marked ``refused``.

``petroll bench growth [--out DIR]``: time per rolling step against the cells of the contact window (the
box of cells where the body interferes with the surface, on which each step's QP is posed), for windows
of N x N cells at the first step (N cells across the rigid interference diameter): the default scene's
sphere, material and speed on square cells, one cell per step (its ``steps_per_cell`` = 1), a few steps
from rest. Median of the warm steps (from ``skip`` on), operator applications per step, the share of the
time spent in the convolutions, peak RSS. The least-squares exponent of time per step against cells is
compared with that of cells log(cells) over the same range. Then a long track on a small window (time per
step against step number; the history of a Prony material is a fixed set of fields, so the cost must
stay flat): the ratio of the median of the last ``track_span`` steps to that of ``track_span`` steps from
``track_skip`` on (past the start-up transient) of a second run of the track, the two timed alternately
step by step, so that the (shared) machine's changes of speed hit both.

All functions are collective over ``comm``; rank 0 prints the tables and writes DIR/NAME.csv and
DIR/NAME.png (matplotlib, if installed).
"""

from __future__ import annotations

import math
import os
import pathlib
import resource
import shutil
import statistics
import tempfile
import time

import numpy as np
from mpi4py import MPI

from petroll.studies.tables import new_figure, save_figure, write_table
from petroll.errors import PetrollError
from petroll.model.scene import Scene, load_scene, shipped_scene
from petroll.driver import run
from petroll.solver.simulation import Simulation

SPHERE = shipped_scene("sphere.toml")
INTEGRATORS = ("paper", "exponential", "relaxation")
MARGIN = 3  # cells between the rigid interference region and the grid edge (growth scenes)


def sphere_scene(grid_scale: float = 1.0, distance: float | None = None) -> Scene:
    """runs/sphere.toml without its steady stop and with no saved fields between first and last; the
    grid's cell counts times ``grid_scale`` (same extent), the track ``distance`` (m, default the scene's)."""
    scene = load_scene(SPHERE)
    g = scene.grid
    changes = {"time.steady": None, "output.every": 0, "grid.nx": int(round(g.nx * grid_scale)),
               "grid.ny": int(round(g.ny * grid_scale))}
    if distance is not None:
        changes["time.distance"] = distance
    return scene.replace(changes)


# -- work-precision -----------------------------------------------------------------------------------------
def precision(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD,
              steps_per_cell: tuple[float, ...] = (0.25, 0.5, 1, 2, 4, 8, 16), reference: float = 64,
              grids: tuple[float, ...] = (0.5, 1, 2, 4, 8), grid_scale: float = 1.0,
              distance: float | None = None, target: float = 1e-3,
              short: float = 1.0) -> tuple[list[dict], list[dict]]:
    """Work-precision of the integrators and of grid refinement; returns (runs, summary), numeric rows.

    ``steps_per_cell``: the time-step ladder, coarse to fine, on the base grid (the scene's cell counts
    times ``grid_scale``); ``reference``: steps per cell of the same-grid reference (relaxation); ``grids``:
    the grid ladder, factors on the base grid's cell counts, coarse to fine; runs shorter than ``short``
    (s) are timed 3 times (median). Writes precision.csv, precision_summary.csv and precision.png (rank 0).
    """
    base = sphere_scene(grid_scale, distance)
    runs: list[dict] = []
    cache: dict[tuple, dict] = {}

    def point(kind: str, integrator: str, spc: float, factor: float = 1.0) -> dict:
        key = (integrator, spc, factor)
        if key not in cache:
            cache[key] = _precision_run(base, integrator, spc, factor, comm, short)
        runs.append(dict(cache[key], kind=kind))
        return runs[-1]

    ladders = {name: [point("dt", name, spc) for spc in steps_per_cell] for name in INTEGRATORS}
    check, ref = (point("dt reference", "relaxation", spc) for spc in (reference / 2, reference))
    grid_line = [point("grid", "relaxation", 1, f) for f in grids[:-1]]
    grid_ref = point("grid reference", "relaxation", 1, grids[-1])
    for row in runs:
        _errors(row, grid_ref if row["kind"].startswith("grid") else ref)
    for row, other in ((ref, check), (grid_ref, grid_line[-1])):
        _errors(row, other)
        row["note"] = f"reference: its change from {other['label']}"
    summary = []
    for name, ladder in [*ladders.items(), ("grid", grid_line)]:
        for quantity in ("force", "mu_r"):
            relation, seconds, between = time_to(ladder, quantity, target)
            summary.append(dict(line=name, quantity=quantity, target=target, relation=relation,
                                seconds=seconds, between=between))
    paper, expo = (next(s for s in summary if s["line"] == n and s["quantity"] == "force")
                   for n in ("paper", "exponential"))
    summary.append(dict(line="paper / exponential", quantity="force", target=target,
                        relation=_ratio_relation(paper["relation"], expo["relation"]),
                        seconds=paper["seconds"] / expo["seconds"], between="ratio of the times"))
    if comm.rank == 0:
        write_table([_precision_display(r) for r in runs], out / "precision.csv")
        print()
        write_table([dict(s, target=f"{s['target']:g}", seconds=f"{s['seconds']:.3f}") for s in summary],
                out / "precision_summary.csv")
        _plot_precision(runs, target, out / "precision.png")
    return runs, summary


def _precision_run(base: Scene, integrator: str, spc: float, factor: float, comm: MPI.Comm,
                   short: float) -> dict:
    """One run of the base scene with this integrator, steps per cell and grid factor (on its cell
    counts); the run time (s) is the median of 3 for runs under ``short`` s. A time step that the
    integrator's guard refuses gives a row with NaN values, marked refused."""
    g = base.grid
    scene = base.replace({"solver.integrator": integrator, "time.steps_per_cell": spc,
                          "time.allow_coarse": True,  # the ladder's coarse steps are what it measures
                          "grid.nx": int(round(g.nx * factor)), "grid.ny": int(round(g.ny * factor))})
    a = math.sqrt(scene.body.radius_hint * float(scene.penetration(0.0)))  # Hertz radius, m
    cell = scene.grid.cell
    dt = cell / (spc * float(np.hypot(*scene.velocity(0.0))))
    row = dict(label=f"{integrator} a/dx {a / cell:.0f} spc {spc:g}", integrator=integrator,
               cells_per_radius=a / cell, steps_per_cell=spc, dt_s=dt, steps=0, run_s=math.nan,
               force=math.nan, mu_r=math.nan, force_error=math.nan, mu_r_error=math.nan, note="")
    try:
        seconds, results = _timed_run(scene, comm)
    except PetrollError as exc:
        if "cannot hold a penetration" not in str(exc):
            raise
        row["note"] = f"refused by the step guard at dt = {dt:.3g} s"
        return row
    times = [seconds]
    if seconds < short:
        times += [_timed_run(scene, comm)[0] for _ in range(2)]
    s = results.series
    row.update(steps=len(s["force"]), run_s=statistics.median(times), force=float(s["force"][-1]),
               mu_r=float(s["mu_r"][-1]))
    return row


def _timed_run(scene: Scene, comm: MPI.Comm):
    """(wall time of petroll.run in s, its Results), run into a temporary directory removed afterwards."""
    where = comm.bcast(tempfile.mkdtemp(prefix="petroll-bench-") if comm.rank == 0 else None, root=0)
    try:
        comm.Barrier()
        start = time.perf_counter()
        results = run(scene, comm, out=where)
        seconds = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    finally:
        comm.Barrier()
        if comm.rank == 0:
            shutil.rmtree(where, ignore_errors=True)
    return seconds, results


def _errors(row: dict, against: dict) -> None:
    """Relative errors of the row's force and mu_r against another row's."""
    for q in ("force", "mu_r"):
        row[f"{q}_error"] = abs(row[q] - against[q]) / abs(against[q])


def time_to(ladder: list[dict], quantity: str, target: float) -> tuple[str, float, str]:
    """(relation, seconds, bracket): the run time at which the relative error of ``quantity`` ("force" or
    "mu_r") reaches ``target``, interpolated log-log between the first two points of the ladder (coarse
    to fine, refused points left out) that bracket it: relation "=". When the coarsest point that ran is
    already within target, its time with "<="; when no point is, the finest's time with ">"."""
    ran = [r for r in ladder if not math.isnan(r["run_s"])]
    errors = [r[f"{quantity}_error"] for r in ran]
    hit = next((i for i, e in enumerate(errors) if e <= target), None)
    if hit is None:
        return ">", ran[-1]["run_s"], f"not reached by {ran[-1]['label']}"
    if hit == 0:
        return "<=", ran[0]["run_s"], f"already at {ran[0]['label']}"
    (e0, t0), (e1, t1) = ((errors[i], ran[i]["run_s"]) for i in (hit - 1, hit))
    share = math.log(e0 / target) / math.log(e0 / e1) if e1 > 0 else 1.0
    return "=", t0 * (t1 / t0) ** share, f"{ran[hit - 1]['label']} .. {ran[hit]['label']}"


def _ratio_relation(numerator: str, denominator: str) -> str:
    """How a ratio of two times relates to the true ratio, from the relations of the times ("=", "<=",
    ">"): "=", ">=" (a lower bound), "<=" (an upper bound) or "?"."""
    low = numerator in ("=", ">") and denominator in ("=", "<=")
    high = numerator in ("=", "<=") and denominator in ("=", ">")
    return "=" if low and high else ">=" if low else "<=" if high else "?"


def _precision_display(r: dict) -> dict:
    def err(v):
        return "-" if math.isnan(v) else f"{v:.2e}"

    return dict(kind=r["kind"], integrator=r["integrator"], a_dx=f"{r['cells_per_radius']:.1f}",
                steps_per_cell=f"{r['steps_per_cell']:g}", dt_s=f"{r['dt_s']:.3g}", steps=r["steps"],
                run_s="-" if math.isnan(r["run_s"]) else f"{r['run_s']:.3f}",
                force_N="-" if math.isnan(r["force"]) else f"{r['force']:.10g}",
                mu_r="-" if math.isnan(r["mu_r"]) else f"{r['mu_r']:.8g}",
                force_error=err(r["force_error"]), mu_r_error=err(r["mu_r_error"]), note=r["note"])


def _plot_precision(runs: list[dict], target: float, path: pathlib.Path) -> None:
    figure = new_figure(11, 4.8)
    if figure is None:
        return
    ref = next(r for r in runs if r["kind"] == "dt reference" and r["note"])
    grid_ref = next(r for r in runs if r["kind"] == "grid reference")
    grid = [r for r in runs if r["kind"] == "grid"]
    for ax, q, title in zip(figure.subplots(1, 2), ("force", "mu_r"), ("steady force", "steady mu_r")):
        for name, style in zip(INTEGRATORS, ("o-", "s-", "^-")):
            ladder = [r for r in runs if r["kind"] == "dt" and r["integrator"] == name]
            ran = [r for r in ladder if not math.isnan(r["run_s"])]
            refused = [f"{r['steps_per_cell']:g}" for r in ladder if math.isnan(r["run_s"])]
            label = f"{name}: dt ladder, spc {ran[0]['steps_per_cell']:g}..{ran[-1]['steps_per_cell']:g}"
            ax.loglog([r["run_s"] for r in ran], [r[f"{q}_error"] for r in ran], style,
                      label=label + (f" (spc {', '.join(refused)} refused)" if refused else ""))
        ax.loglog([r["run_s"] for r in grid], [r[f"{q}_error"] for r in grid], "kD--",
                  label=f"grid refinement, dx and dt together (a/dx {grid[0]['cells_per_radius']:.0f}.."
                  f"{grid[-1]['cells_per_radius']:.0f}), vs a/dx {grid_ref['cells_per_radius']:.0f}")
        ax.axhline(ref[f"{q}_error"], color="grey", ls=":", label="dt reference's own change (its floor)")
        ax.axhline(grid_ref[f"{q}_error"], color="k", ls=":", lw=0.8, label="grid reference's own change")
        ax.axhline(target, color="red", lw=0.8, label=f"target {target:g}")
        ax.set_xlabel("run time (s)")
        ax.set_ylabel(f"relative error of the {title}")
        ax.set_title(title)
        ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    figure.suptitle(f"runs/sphere.toml: dt ladders against the same grid's relaxation at spc "
                    f"{ref['steps_per_cell']:g}; grid line against a/dx {grid_ref['cells_per_radius']:.0f}",
                    fontsize=9)
    save_figure(figure, path)


# -- cost growth --------------------------------------------------------------------------------------------
def rolling_scene(window: int, steps: int) -> Scene:
    """The default scene's sphere, material, penetration and speed on square cells, ``window`` cells across
    the rigid interference diameter (the first step's contact window is window x window cells for an even
    window), rolled ``steps`` steps (the first at t = 0) of one cell each (``steps_per_cell`` = 1), with
    3 cells of margin around the rigid interference region over the whole track."""
    base = load_scene(SPHERE)
    r = math.sqrt(2 * base.body.radius_hint * float(base.penetration(0.0)))  # rigid interference radius, m
    h = 2 * r / window
    half = math.ceil(r / h - 1e-9) + MARGIN  # cells from the start position to the grid's edge
    nx = 2 * half + steps - 1
    return base.replace({"grid.nx": nx, "grid.ny": 2 * half, "grid.x": [-half * h, (nx - half) * h],
                         "grid.y": [-half * h, half * h], "time.steady": None, "time.steps_per_cell": 1,
                         "time.distance": (steps - 1) * h, "output.every": 0})


def roll(scene: Scene, comm: MPI.Comm) -> dict:
    """Run ``scene`` step by step (nothing written): per step the wall time and the part of it spent in the
    influence operator's convolutions (FFTs and, under MPI, their transposes; s, the slowest rank), the
    operator applications and the QP window's cells; with the last step's force (N) and mu_r."""
    sim = Simulation(scene, comm)
    windows, clock = [], [0.0]
    solve, window = sim.solver.solve_penetration, sim.solver.influence.window

    def solve_penetration(height, compliance, delta, warm=None):
        solution = solve(height, compliance, delta, warm)
        windows.append(solution.window)
        return solution

    sim.solver.solve_penetration = solve_penetration  # these instances only: record each QP's window
    sim.solver.influence.window = lambda *shape, **kind: _Timed(window(*shape, **kind), clock)  # time them
    seconds, convolution = [], []
    for _, elapsed in stepping(sim):
        seconds.append(elapsed)
        convolution.append(clock[0])
        clock[0] = 0.0
    slowest = np.empty((2, len(seconds)))
    comm.Allreduce(np.array([seconds, convolution]), slowest, op=MPI.MAX)
    return dict(seconds=slowest[0], convolution=slowest[1],
                applications=np.array([r.applications for r in sim.records]),
                cells=np.array([(b - a) * (d - c) for a, b, c, d in windows]), last_window=windows[-1],
                force=sim.records[-1].force,
                mu_r=sim.records[-1].mu_r, forces=[r.force for r in sim.records])


def stepping(sim: Simulation):
    """``sim.steps()`` with each step's wall time (s): (StepRecord, seconds) pairs."""
    steps = sim.steps()
    while True:
        start = time.perf_counter()
        record = next(steps, None)
        if record is None:
            return
        yield record, time.perf_counter() - start


def track_steps_interleaved(scene: Scene, steps: int, comm: MPI.Comm, skip: int,
                            span: int) -> tuple[np.ndarray, ...]:
    """Wall times (s, slowest rank) and applications of every step of ``scene`` (``steps`` steps), and the
    times of steps ``skip`` .. ``skip + span - 1`` of a second run of it, timed alternately with the first
    run's last ``skip + span`` steps so that the machine's speed changes hit early and late steps alike."""
    late, early = (stepping(Simulation(scene, comm)) for _ in range(2))
    times, apps, early_times = [], [], []
    for record, elapsed in late:
        times.append(elapsed)
        apps.append(record.applications)
        if len(times) > steps - skip - span:
            early_times.append(next(early)[1])
    slowest = np.empty(len(times) + span)
    comm.Allreduce(np.array(times + early_times[skip:]), slowest, op=MPI.MAX)
    return slowest[: len(times)], np.array(apps), slowest[len(times) :]


class _Timed:
    """A :class:`petroll.solver.influence.Convolution` whose applications add their wall time (s) to clock[0]."""

    def __init__(self, conv, clock: list[float]):
        self.conv, self.clock = conv, clock

    def __getattr__(self, name):
        return getattr(self.conv, name)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        start = time.perf_counter()
        y = self.conv(x)
        self.clock[0] += time.perf_counter() - start
        return y


def growth(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD,
           windows: tuple[int, ...] = (64, 128, 256, 512, 1024), steps: int = 8, skip: int = 3,
           track_window: int = 24, track_steps: int = 1000, track_skip: int = 250,
           track_span: int = 50) -> dict:
    """Time per step against the window's cells, and against step number on a long track; returns
    {"rows", "exponent", "application_exponent", "nlogn_exponent", "track", "flatness", ...} (numeric).
    Steps from ``skip`` on are timed (the first ones start from rest and from no previous solution). The
    long track has ``track_steps`` steps on a ``track_window`` window; flatness: the median time of its
    last ``track_span`` steps over that of steps ``track_skip`` .. of a second run, timed alternately
    with them (:func:`track_steps_interleaved`). Writes growth.csv, growth_track.csv and growth.png
    (rank 0)."""
    rss0 = _peak_rss_mib(comm)
    rows = []
    for n in windows:
        scene = rolling_scene(n, steps)
        done = roll(scene, comm)
        warm = slice(skip, None)
        step_s = float(np.median(done["seconds"][warm]))
        apps = float(np.median(done["applications"][warm]))
        share = float(done["convolution"][warm].sum() / done["seconds"][warm].sum())
        rows.append(dict(window=f"{n}^2", requested=n * n, first_cells=int(done["cells"][0]),
                         cells=float(done["cells"][warm].mean()), grid=f"{scene.grid.nx}x{scene.grid.ny}",
                         timed_steps=len(done["seconds"][warm]), step_s=step_s, applications=apps,
                         application_s=step_s / apps, convolution_share=share,
                         peak_rss_mib=_peak_rss_mib(comm)))
    cells = np.array([r["cells"] for r in rows])
    exponent = _slope(cells, [r["step_s"] for r in rows])
    application_exponent = _slope(cells, [r["application_s"] for r in rows])
    nlogn = _slope(cells, cells * np.log(cells))
    # the long track: its last span against a second run's span from track_skip, timed alternately
    track_scene = rolling_scene(track_window, track_steps)
    seconds, apps, early = track_steps_interleaved(track_scene, track_steps, comm, track_skip, track_span)
    first, last = slice(track_skip, track_skip + track_span), slice(len(seconds) - track_span, None)
    flatness = float(np.median(seconds[last]) / np.median(early))
    track = [dict(step=i, step_s=float(s), applications=int(a), early_run_s=float(early[i - track_skip])
                  if first.start <= i < first.stop else "") for i, (s, a) in enumerate(zip(seconds, apps))]
    result = dict(rows=rows, exponent=exponent, application_exponent=application_exponent,
                  nlogn_exponent=nlogn, track=track, flatness=flatness,
                  track_applications=float(np.median(apps[last]) / np.median(apps[first])),
                  rss_per_cell=(rows[-1]["peak_rss_mib"] - rss0) * 2**20 / rows[-1]["cells"])
    if comm.rank == 0:
        write_table([dict(r, cells=f"{r['cells']:.0f}", step_s=f"{r['step_s']:.4f}",
                      applications=f"{r['applications']:.0f}", application_s=f"{r['application_s']:.2e}",
                      convolution_share=f"{r['convolution_share']:.0%}",
                      peak_rss_mib=f"{r['peak_rss_mib']:.0f}")
                 for r in rows], out / "growth.csv")
        write_table(track, out / "growth_track.csv", show=False)
        print(f"\ntime per step ~ cells^{exponent:.2f} (per application: cells^{application_exponent:.2f}); "
              f"cells log(cells) over the same range ~ cells^{nlogn:.2f}")
        print(f"peak RSS grew by {result['rss_per_cell']:.0f} bytes per window cell (at {windows[-1]}^2)")
        grid = track_scene.grid
        print(f"long track ({len(seconds)} steps, window {track_window}^2, grid {grid.nx}x{grid.ny}): median "
              f"step time of the last {track_span} steps / steps {track_skip}..{track_skip + track_span - 1} "
              f"(of a second run, timed alternately with them): {flatness:.3f} (applications: "
              f"{result['track_applications']:.3f})")
        _plot_growth(result, out / "growth.png")
    return result


def _slope(x, y) -> float:
    """Least-squares slope of log y against log x."""
    return float(np.polyfit(np.log(np.asarray(x, dtype=float)), np.log(np.asarray(y, dtype=float)), 1)[0])


def _peak_rss_mib(comm: MPI.Comm) -> float:
    """This process's peak resident set size so far (MiB; Linux reports KiB), the largest over ranks."""
    return comm.allreduce(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, op=MPI.MAX)


def _plot_growth(result: dict, path: pathlib.Path) -> None:
    figure = new_figure(11, 4.4)
    if figure is None:
        return
    left, right = figure.subplots(1, 2)
    rows = result["rows"]
    cells = np.array([r["cells"] for r in rows])
    step_s = np.array([r["step_s"] for r in rows])
    left.loglog(cells, step_s, "o", label="median warm step")
    fit = np.exp(np.polyval(np.polyfit(np.log(cells), np.log(step_s), 1), np.log(cells)))
    left.loglog(cells, fit, "-", label=f"fit: cells^{result['exponent']:.2f}")
    nlogn = cells * np.log(cells)
    left.loglog(cells, nlogn * step_s[0] / nlogn[0], "k:", label="cells log(cells)")
    left.set_xlabel("cells in the contact window")
    left.set_ylabel("time per rolling step (s)")
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=8)
    track = result["track"]
    right.plot([t["step"] for t in track], [t["step_s"] for t in track], ".", ms=3, label="the track's run")
    early = [t for t in track if t["early_run_s"] != ""]
    right.plot([t["step"] for t in early], [t["early_run_s"] for t in early], ".", ms=3,
               label="a second run, timed alternately with the last steps")
    right.legend(fontsize=8)
    right.set_xlabel("step")
    right.set_ylabel("time per step (s)")
    right.set_title(f"long track, SLS: median of the last steps / of the second run's = "
                    f"{result['flatness']:.3f}", fontsize=9)
    right.grid(True, alpha=0.3)
    save_figure(figure, path)


# -- what each saving is worth ------------------------------------------------------------------------------
def skips(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, track_cells: int = 1000,
          repeats: int = 20) -> list[dict]:
    """Each saving of docs/design.md measured on and off side by side: time with and without it (s), and
    how much it changes the answer. Writes ``out/skips.csv``."""
    from petroll.solver.influence import Convolution, influence_operator

    scene = sphere_scene()
    g = scene.grid
    window = influence_operator(g, comm)
    i0, i1, j0, j1 = roll(scene, comm)["last_window"]
    shapes = {"window": (i1 - i0, j1 - j0), "grid": (g.nx, g.ny)}
    application = {k: _median_application(window.window(*shape), repeats, comm) for k, shape in shapes.items()}
    start = time.perf_counter()  # the two kernels a pk step's window needs: A's and its preconditioner's
    for inverse in (False, True):
        Convolution(window.coefficients(*shapes["window"]), *shapes["window"], comm, inverse)
    build = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    rows = [dict(saving="QP on the interference window", scene=f"runs/sphere.toml, steady window "
                 f"{shapes['window'][0]}x{shapes['window'][1]} of {g.nx}x{g.ny} cells",
                 with_s=application["window"], without_s=application["grid"], unit="per application",
                 change="0 (exact)"),
            dict(saving="kernels built once per window shape", scene="the same window",
                 with_s=application["window"], without_s=application["window"] + build,
                 unit="per application", change="0 (exact)")]

    steady_s, steady = _timed_run(load_scene(SPHERE).replace("output.every", 0), comm)
    full_s, full = _timed_run(scene, comm)
    change = max(abs(steady.series["force"][-1] / full.series["force"][-1] - 1),
                 abs(steady.series["mu_r"][-1] / full.series["mu_r"][-1] - 1))
    rows.append(dict(saving="stop at steady state ([time] steady = 1e-3)",
                     scene=f"runs/sphere.toml: {len(steady.series['t'])} of {len(full.series['t'])} steps",
                     with_s=steady_s, without_s=full_s, unit="per run",
                     change=f"{change:.1e} (force, mu_r at the end)"))

    track = scene.replace({"grid.nx": track_cells, "grid.x": [g.x0, g.x0 + track_cells * g.dx],
                           "time.distance": (track_cells - 2 * round(1e-3 / g.dx)) * g.dx})
    boxed, whole = Simulation(track, comm), Simulation(track, comm)
    whole.wake.displacement = lambda v, profile, reach: whole.solver.influence.window(track_cells, g.ny)(v)
    times = {"boxed": [], "whole": []}
    forces = {"boxed": [], "whole": []}
    for (a, ta), (b, tb) in zip(stepping(boxed), stepping(whole)):  # alternately: the same machine state
        times["boxed"].append(ta)
        times["whole"].append(tb)
        forces["boxed"].append(a.force)
        forces["whole"].append(b.force)
    late = slice(2 * len(times["boxed"]) // 3, None)
    change = max(abs(x / y - 1) for x, y in zip(forces["boxed"], forces["whole"]))
    rows.append(dict(saving="preceding displacement on a box (history_cutoff 1e-9)",
                     scene=f"runs/sphere.toml on a {track_cells}-cell track ({len(times['boxed'])} steps)",
                     with_s=statistics.median(times["boxed"][late]), without_s=statistics.median(
                         times["whole"][late]), unit="per step (last third)", change=f"{change:.1e} (force)"))
    for row in rows:
        row["factor"] = f"{row['without_s'] / row['with_s']:.2f}"
        row["with_s"], row["without_s"] = f"{row['with_s']:.3g}", f"{row['without_s']:.3g}"
    if comm.rank == 0:
        write_table(rows, out / "skips.csv")
    return rows


def _median_application(conv, repeats: int, comm: MPI.Comm) -> float:
    """Median wall time (s, slowest rank) of one application of ``conv`` to a random field."""
    x = np.random.default_rng(0).random((conv.r1 - conv.r0, conv.ny))
    times = []
    for _ in range(repeats):
        comm.Barrier()
        start = time.perf_counter()
        conv(x)
        times.append(comm.allreduce(time.perf_counter() - start, op=MPI.MAX))
    return statistics.median(times)
