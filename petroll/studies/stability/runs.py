"""Running the map: one case checked (:func:`run_case`), the refinement and scaling studies, the whole
sweep, its CSV and Markdown tables, and ``petroll stability``."""

from __future__ import annotations

import copy
import csv
import datetime
import math
import pathlib
import time as clock

import numpy as np
from mpi4py import MPI

from petroll.errors import PetrollError
from petroll.studies.stability.cases import Case, cases
from petroll.studies.stability.checks import Checker, Row, check_series
from petroll.studies.stability.scenes import (
    DELTA,
    E0,
    NU,
    A,
    R,
    T,
    hertz_force,
    load_scene,
    rolling_scene,
    scaled,
    scene,
    sls,
)


def run_case(case: Case, comm: MPI.Comm = MPI.COMM_WORLD, integrator: str | None = None,
             guard: bool = True) -> Row:
    """Run one case on ``comm`` (collective) and check it; never raises for what the run does.
    ``integrator``: use this one where the case does not choose; ``guard=False``: accept every step."""
    return run_checked(case, comm, integrator, guard)[0]


def run_checked(case: Case, comm: MPI.Comm, integrator: str | None = None, guard: bool = True):
    """(row, records, scene) of one case; records and scene are None where it did not run."""
    import warnings

    from petroll.model.limits import PetrollWarning
    from petroll.model.materials import Prony
    from petroll.model.scene import parse_scene
    from petroll.solver.simulation import Simulation

    row = Row(case.axis, case.name)
    start = clock.perf_counter()
    records = []
    checker = scene = None
    raw = copy.deepcopy(case.raw)
    if integrator and "integrator" not in raw["solver"] and raw["material"]["model"] != "tabulated":
        raw["solver"]["integrator"] = integrator
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PetrollWarning)
            scene = parse_scene(raw, source=f"<{case.name}>")
        for w in caught:
            if issubclass(w.category, PetrollWarning):
                row.note = "warning: " + str(w.message).split(": ", 1)[1]
        sim = Simulation(scene, comm)
        sim.history.guard = guard
        reference = scene.penetration is not None and isinstance(scene.material, Prony)
        checker = Checker(sim, reference)
        for record in sim.steps(dts=case.dts):
            records.append(record)
            checker.after_step(record)
            if sim.dt_next is not None and len(records) >= case.max_steps:
                raise RuntimeError(f"more than {case.max_steps} steps: too long a case for the suite")
    except PetrollError as exc:
        message = " ".join(str(exc).split())
        row.steps, row.note = len(records), message
        row.wall = clock.perf_counter() - start
        if case.refuse:
            row.status = "refused"
            missing = [w for w in case.refuse if w not in message]
            if missing:
                row.failures.append(f"refused without naming {missing}")
        else:
            row.failures.append("error: " + message)
        return row.finish(), None, None
    except Exception as exc:  # a crash: recorded, so that the sweep goes on
        row.steps, row.wall = len(records), clock.perf_counter() - start
        row.failures.append(f"crash: {type(exc).__name__}: {' '.join(str(exc).split())}")
        return row.finish(), None, None
    row.wall, row.steps = clock.perf_counter() - start, len(records)
    if case.refuse:
        row.failures.append(f"not refused (expected an error naming {list(case.refuse)})")
    if case.warn and not row.note.startswith("warning"):
        row.failures.append("no warning (expected one)")
    check_series(case, scene, checker, records, row)
    return row.finish(), records, scene


# -- refinement and scaling studies -------------------------------------------------------------------------
def _series(case: Case, comm, name: str) -> tuple[Row, np.ndarray | None]:
    row, records, _ = run_checked(case, comm)
    return row, None if records is None else np.array([getattr(r, name) for r in records])


def _study_row(axis: str, name: str, rows: list[Row], errors: list[float], what: str, need_decrease: bool,
               limit: float | None = None) -> Row:
    """A study's row: the runs' own failures, and the errors (which must decrease, or stay below limit)."""
    out = Row(axis, name, steps=sum(r.steps for r in rows), wall=sum(r.wall for r in rows))
    for r in rows:
        out.failures += [f"{r.case}: {f}" for f in r.failures]
    e = np.array(errors)
    orders = np.log2(e[:-1] / e[1:]) if need_decrease and len(e) > 1 and np.all(e > 0) else np.array([])
    out.note = f"{what}: " + ", ".join(f"{v:.2e}" for v in e) + (
        " (observed orders " + ", ".join(f"{o:.2f}" for o in orders) + ")" if orders.size else "")
    if need_decrease and not np.all(np.diff(e) < 0):
        out.failures.append(f"errors do not decrease under refinement: {out.note}")
    if limit is not None and not e.max() <= limit:
        out.failures.append(f"errors above {limit:g}: {out.note}")
    return out.finish()


def refinement(comm: MPI.Comm = MPI.COMM_WORLD, fast: bool = False) -> list[Row]:
    """dt and dx refinement where the scene is smooth; the errors must decrease."""
    out = []
    # dt: rolling from rest at V T/a = 1 (a/dx = 4), force and resisting force at t = T against dt = T/128
    steps = (4, 8, 16, 32) if fast else (4, 8, 16, 32, 64)
    finest = 2 * steps[-1]
    runs, values = [], []
    for k in (*steps, finest):
        raw = scene(length=1.5, motion={"velocity": [A / T, 0.0], "penetration": DELTA},
                    time={"dt": T / k, "end": T})
        row, records, _ = run_checked(Case("refine", f"rolling, dt = T/{k}", raw), comm)
        runs.append(row)
        values.append((records[-1].force, records[-1].force_x) if records else (math.nan, math.nan))
    ref = values[-1]
    errors = [abs(f - ref[0]) / abs(ref[0]) + abs(fx - ref[1]) / abs(ref[1]) for f, fx in values[:-1]]
    out.append(_study_row("refine", f"dt: rolling V T/a = 1, force and F_x at t = T, dt = T/{steps[0]} .. "
                          f"T/{steps[-1]} against T/{finest}", runs, errors, "relative errors", True))
    # dx: an elastic sphere against Hertz, a/dx = 2 .. 16
    cells = (2, 4, 8) if fast else (2, 4, 8, 16)
    runs, errors = [], []
    for c in cells:
        row, force = _series(Case("refine", f"Hertz a/dx = {c}", scene(n=4 * c, material=sls(1))), comm,
                             "force")
        runs.append(row)
        hertz = hertz_force(DELTA, (1 - NU**2) / E0)
        errors.append(abs(force[-1] / hertz - 1) if force is not None else math.nan)
    out.append(_study_row("refine", f"dx: elastic sphere against Hertz's force, a/dx = {cells[0]} .. "
                          f"{cells[-1]}", runs, errors, "relative errors", True))
    # dx: a held penetration relaxing (Lee-Radok: F(t) = Hertz with the modulus G(t)) at t = T
    from petroll.model.materials import relaxation_series
    from petroll.model.materials import sls as make_sls

    Ginf, dG, theta = relaxation_series(make_sls(E0, E0 / 5, NU, tau_creep=T))
    exact = hertz_force(DELTA, 1.0 / (Ginf + sum(d * math.exp(-T / th) for d, th in zip(dG, theta))))
    runs, errors = [], []
    for c in cells:
        raw = scene(n=4 * c, time={"dt": T / 4, "end": T})
        row, force = _series(Case("refine", f"Lee-Radok a/dx = {c}", raw), comm, "force")
        runs.append(row)
        errors.append(abs(force[-1] / exact - 1) if force is not None else math.nan)
    out.append(_study_row("refine", f"dx: held penetration (SLS, E0/Einf = 5) against Lee-Radok at t = T, "
                          f"dt = T/4, a/dx = {cells[0]} .. {cells[-1]}", runs, errors, "relative errors",
                          True))
    return out


def scaling(comm: MPI.Comm = MPI.COMM_WORLD, fast: bool = False) -> list[Row]:
    """The same dimensionless scene at other moduli, radii and time scales: F / (E0 R^2), mu_r, delta / R
    and area / R^2 must agree with the reference run to round-off (1e-6 allowed: the solver tolerance)."""
    combos = [(1e-3, 1e-6, 1.0), (1e12, 10.0, 1.0)] if fast else [
        (1e-3, 1e-6, 1.0), (1e-3, 10.0, 1.0), (1e12, 1e-6, 1.0), (1e12, 10.0, 1.0), (E0, R, 1e-6),
        (E0, R, 1e6), (1.0, 1.0, 1.0)]
    out = []
    for label, base in (("rolling V T/a = 1 (displacement control)", rolling_scene(1.0)),
                        ("held load (load control)", load_scene(hertz_force(DELTA, (1 - NU**2) / E0),
                                                                 end=T / 2))):
        ref_row, ref, _ = run_checked(Case("scale", "reference", base), comm)
        tol = base["solver"]["tol"]
        runs, errors = [ref_row], []
        for modulus, radius, time_scale in combos:
            k, lam = modulus / E0, radius / R
            case = Case("scale", f"E0 = {modulus:g} Pa, R = {radius:g} m, T x {time_scale:g}",
                        scaled(base, modulus, radius, time_scale))
            row, records, _ = run_checked(case, comm)
            runs.append(row)
            if records is None or ref is None or len(records) != len(ref):
                errors.append(math.inf)
                continue
            worst = 0.0
            for a, b in zip(ref, records):
                pairs = [(a.force, b.force / (k * lam**2)), (a.delta, b.delta / lam),
                         (a.area, b.area / lam**2), (a.t, b.t / time_scale)]
                # mu_r of a symmetric patch (the held load at rest) is zero only to the solver's tolerance:
                # compared where it is larger than that, else it must stay below it
                if abs(a.mu_r) > tol:
                    pairs.append((a.mu_r, b.mu_r))
                elif abs(b.mu_r) > tol:
                    worst = math.inf
                for x, y in pairs:
                    if x != 0:
                        worst = max(worst, abs(x - y) / abs(x))
            errors.append(worst)
        names = ", ".join(f"({m:g} Pa, {r:g} m, T x {t:g})" for m, r, t in combos)
        out.append(_study_row("scale", f"{label} at (E0, R, time scale) = {names}", runs, errors,
                              "largest relative deviation from the reference", False, limit=1e-6))
    return out


# -- the sweep and its table -------------------------------------------------------------------------------
def sweep(fast: bool = False, comm: MPI.Comm = MPI.COMM_WORLD, integrator: str | None = None,
          guard: bool = True, progress=None) -> list[Row]:
    """Every case of the map (``fast``: the CI subset), then the refinement and scaling studies."""
    rows = []
    for case in cases():
        if fast and not case.fast:
            continue
        rows.append(run_case(case, comm, integrator, guard))
        if progress:
            progress(rows[-1])
    if integrator is None:
        for row in (*refinement(comm, fast), *scaling(comm, fast)):
            rows.append(row)
            if progress:
                progress(row)
    return rows


COLUMNS = ("axis", "case", "status", "steps", "its", "contact", "p_min", "dissipation", "bounds",
           "resistance", "smooth", "force", "mu_r", "wall", "note")


def _cell(value) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.3g}"
    return str(value)


def write_map(rows: list[Row], out: pathlib.Path, title: str = "petroll stability map") -> tuple[pathlib.Path,
                                                                                                pathlib.Path]:
    """DIR/stability.csv (every column) and DIR/stability.md (one table per axis). Call on one rank."""
    out.mkdir(parents=True, exist_ok=True)
    path_csv, path_md = out / "stability.csv", out / "stability.md"
    with open(path_csv, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow([*COLUMNS, "failures"])
        for r in rows:
            writer.writerow([_cell(getattr(r, c)) for c in COLUMNS] + ["; ".join(r.failures)])
    path_md.write_text(markdown(rows, title), encoding="utf-8")
    return path_csv, path_md


AXES = {
    "dt": "Time step (T: the creep time; SLS E0/Einf = 5 unless said)",
    "ratio": "Stiffness ratio and Prony spreads",
    "speed": "Speed (V T / a; a the Hertz radius) and reversal",
    "load": "Penetration and load programs",
    "grid": "Grids",
    "large": "Large penetrations",
    "scale": "Extreme magnitudes (moduli 1e-3 ... 1e12 Pa, radii 1e-6 ... 10 m)",
    "refine": "Refinement",
}


def markdown(rows: list[Row], title: str = "petroll stability map") -> str:
    """The map as Markdown tables, one per axis (columns: docs/stability.md)."""
    date = datetime.date.today().isoformat()
    failed = sum(r.status == "FAIL" for r in rows)
    lines = [f"<!-- {title}, generated {date} by `petroll stability` -->",
             f"{len(rows)} runs: {sum(r.status == 'ok' for r in rows)} ok, "
             f"{sum(r.status == 'refused' for r in rows)} refused as expected, {failed} failed.", ""]
    head = ("| case | status | steps | its | contact/tol | dissipation | bounds | V.F_res | smooth "
            "| force (N) | mu_r | note |")
    for axis, title_axis in AXES.items():
        mine = [r for r in rows if r.axis == axis]
        if not mine:
            continue
        lines += [f"#### {title_axis}", "", head, "|" + "---|" * 12]
        for r in mine:
            note = "; ".join(r.failures) if r.failures else r.note
            note = note.replace("|", "/")
            if len(note) > 220:
                note = note[:217] + "..."
            status = "**FAIL**" if r.status == "FAIL" else r.status
            cells = [r.case, status, str(r.steps), str(r.its), _cell(r.contact), _cell(r.dissipation),
                     r.bounds, _cell(r.resistance), _cell(r.smooth), _cell(r.force), r.mu_r, note]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def command(out: str | pathlib.Path, fast: bool = False, comm: MPI.Comm = MPI.COMM_WORLD) -> int:
    """``petroll stability``: run the sweep, write the map, print its summary; 0 when nothing failed."""
    import sys

    def progress(row: Row) -> None:
        if comm.rank == 0:
            print(f"{row.axis:7s} {row.status:8s} {row.wall:6.2f} s  {row.case}", file=sys.stderr, flush=True)

    rows = sweep(fast, comm, progress=progress)
    failed = [r for r in rows if r.status == "FAIL"]
    if comm.rank == 0:
        paths = write_map(rows, pathlib.Path(out))
        print(f"petroll: stability: {len(rows)} runs, {len(failed)} failed; wrote {paths[0]} and {paths[1]}")
        for r in failed:
            print(f"petroll: FAIL {r.axis} / {r.case}: {'; '.join(r.failures)}")
    return 1 if failed else 0
