"""Benchmarks of rough contact on periodic grids (docs/benchmarks.md, docs/rough.md): tables printed and
written as CSV, never timed tests.

``petroll bench periodic [--out DIR]``: one application of the periodic operator (unpadded FFTs) against
one of the non-periodic DC-FFT operator on the same grid, 256^2 to 2048^2, in process (kernels built
first), median of repeated applications on this process's ranks (:func:`applications`,
``periodic.csv``); and petroll's periodic elastic contact on a random rough surface against Tamaas's
periodic solver (``PolonskyKeerRey`` on its spectral operator, the same kernel), same grid and load, both
solved to 1e-12, from the benchmark-only environment ``.venv-peers`` (:func:`tamaas`, ``tamaas.csv``); and
what an application costs inside a contact QP against a bare one, periodic and padded, 512^2 and 2048^2
(:func:`in_solve`, ``in-solve.csv``).

``petroll bench sliding [--out DIR]``: the closed forms of full contact of sliding sinusoids against the
steady sliding solve (:func:`closed_forms`, ``closed-forms.csv``); the steady sliding state of a 1024^2
rough surface on an SLS (:func:`rough_sliding`, ``sliding.csv``: wall time in process, iterations,
applications, friction, contact fraction); and a 20-point friction master curve mu(V) at 512^2 by
``petroll sweep`` (:func:`master_curve`, ``master-curve.csv``, wall time of the whole sweep in process).
With ``--ranks`` or ``--sides``: instead, the rough sliding solve at those sides on those rank counts,
as mpirun children, with every rank's peak memory (:func:`scale`, ``scale.csv``).
"""

from __future__ import annotations

import json
import math
import pathlib
import statistics
import sys
import time

import numpy as np
from mpi4py import MPI

from petroll.model.roughness import self_affine_heights
from petroll.model.scene import parse_scene
from petroll.studies.tables import write_table

NU = 0.5
SLS = {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": NU, "tau_relax": 2e-3}
"""The standard linear solid of the closed-form checks (Pa, s)."""

PRONY = {"model": "prony", "series": "maxwell", "Einf": 1e6, "moduli": [3e6, 10e6, 30e6],
         "times": [1e-1, 1e-3, 1e-5], "nu": NU}
"""The three-term Prony series (Maxwell form) of the closed-form checks (Pa, s)."""

RUBBER = {"model": "sls", "E0": 100e6, "Einf": 5e6, "nu": NU, "tau_relax": 1e-4}
"""The rubber of the rough sliding benchmarks (Pa, s): glassy over rubbery modulus 20."""


def maxwell_modulus(table: dict, omega) -> np.ndarray:
    """E*(omega) / (1 - nu^2) (Pa) of an SLS or Maxwell-form Prony [material] table, from its relaxation
    form: Einf + sum_r E_r i omega T_r / (1 + i omega T_r); independent of petroll's creep series."""
    if table["model"] == "sls":
        moduli, times, einf = [table["E0"] - table["Einf"]], [table["tau_relax"]], table["Einf"]
    else:
        moduli, times, einf = table["moduli"], table["times"], table["Einf"]
    w = 1j * np.asarray(omega, dtype=float)
    return (einf + sum(e * w * t / (1 + w * t) for e, t in zip(moduli, times))) / (1 - table["nu"] ** 2)


def sinusoid_raw(heights_file: pathlib.Path, material: dict, speed: float, two_d: bool = False,
                 n: int = 128, amplitude: float = 1e-6, wavelength: float = 1e-3,
                 steps_per_cell: float | None = None) -> tuple[dict, float, float, np.ndarray]:
    """(scene dict, mean pressure Pa, |k| rad/m, heights m) of D (1 - cos kx) (invariant along y, 4 cells
    across) or D (1 - cos kx cos ky) (a square cell) sliding at ``speed`` along X, steady state solved
    directly, pressed to twice the mean pressure of full contact at the glassy modulus; the scene reads
    its heights from ``heights_file``, where the caller writes them (:func:`write_heights`)."""
    x = (np.arange(n) + 0.5) * wavelength / n
    wave = np.cos(2 * np.pi * x / wavelength)
    z = amplitude * (1 - np.outer(wave, wave)) if two_d else np.repeat((amplitude * (1 - wave))[:, None], 4, 1)
    width = wavelength if two_d else 4 * wavelength / n
    k = 2 * np.pi / wavelength * (math.sqrt(2) if two_d else 1)
    mean = k * amplitude * abs(maxwell_modulus(material, 1e12))
    time_table = {"mode": "steady"} if steps_per_cell is None else {"mode": "steady",
                                                                      "steps_per_cell": steps_per_cell}
    raw = {"grid": {"nx": n, "ny": z.shape[1], "x": [0, wavelength], "y": [0, width], "periodic": True},
           "material": material, "motion": {"load": mean * wavelength * width, "velocity": [speed, 0.0]},
           "body": {"shape": "heightmap", "file": str(heights_file), "cell": wavelength / n},
           "time": time_table}
    return raw, mean, k, z


def write_heights(path: pathlib.Path, heights: np.ndarray, comm: MPI.Comm) -> str:
    """``heights`` saved to ``path`` (.npy) by rank 0, the others waiting; the path as a string."""
    if comm.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.save(path, heights)
    comm.Barrier()
    return str(path)


def closed_forms(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD) -> list[dict]:
    """Full contact of D (1 - cos kx) and D (1 - cos kx cos ky) sliding on the SLS and the Prony series at
    V tau / lambda = 0.1, 1, 10, at 128 cells per wavelength, one and 100 integrator steps per cell: the
    errors of mu_r and of the pressure field (relative to the harmonic's amplitude) against the closed
    forms of docs/rough.md. Writes ``out/closed-forms.csv``."""
    from petroll.solver.simulation import Simulation

    rows = []
    for name, material in (("sls", SLS), ("prony", PRONY)):
        tau = material["tau_relax"] if name == "sls" else material["times"][1]
        for two_d in (False, True):
            for ratio in (0.1, 1.0, 10.0):
                speed = ratio * 1e-3 / tau
                for steps in (1, 100):
                    raw, mean, k, z = sinusoid_raw(out / "sinusoid.npy", material, speed, two_d,
                                                   steps_per_cell=steps)
                    write_heights(out / "sinusoid.npy", z, comm)
                    sim = Simulation(parse_scene(raw), comm)
                    record = next(sim.steps())
                    kx = 2 * np.pi / 1e-3
                    modulus = maxwell_modulus(material, kx * speed)
                    mu = (k * kx if two_d else k * k) * 1e-12 * modulus.imag / ((8 if two_d else 4) * mean)
                    x = sim.scene.grid.x[sim.solver.r0 : sim.solver.r1]
                    across = np.cos(kx * sim.scene.grid.x)[None, :] if two_d else 1.0
                    harmonic = (np.cos(kx * x)[:, None] * modulus.real + np.sin(kx * x)[:, None] * modulus.imag)
                    exact = mean + k * 1e-6 / 2 * harmonic * across
                    error = comm.allreduce(float(np.abs(sim.pressure - exact).max()), op=MPI.MAX)
                    rows.append(dict(material=name, surface="2-D" if two_d else "1-D",
                                     v_tau_per_wavelength=ratio, steps_per_cell=steps,
                                     mu_r_error=f"{record.mu_r / mu - 1:+.2e}",
                                     pressure_error=f"{error / (k * 1e-6 / 2 * abs(modulus)):.2e}"))
    if comm.rank == 0:
        write_table(rows, out / "closed-forms.csv")
    return rows


def rough_raw(heights_file: pathlib.Path, n: int, comm: MPI.Comm, speed: float | None = None,
              seed: int = 1) -> dict:
    """The rough sliding benchmark's scene (dict): a 1 mm periodic cell of n x n cells, a self-affine
    surface (Hurst 0.8, rolloff 0.25 mm, cut-off 4 cells, rms slope 0.3) made and written to
    ``heights_file`` by rank 0 alone, the RUBBER SLS, nominal pressure 0.5 MPa, sliding along X at
    ``speed`` (default: rolloff / (2 pi tau), near the friction peak), steady state solved directly at one
    step per cell ([time] allow_coarse: 1 step per single contact's half-width, below the 2 a run asks
    for, docs/accuracy.md; the benchmark times the solve, whose cost does not depend on the step)."""
    length, dx = 1e-3, 1e-3 / n
    keys = {"hurst": 0.8, "rolloff": length / 4, "cutoff": 4 * dx, "rms_slope": 0.3, "seed": seed}
    z = self_affine_heights(keys, (n, n), (dx, dx)) if comm.rank == 0 else None  # rank 0 writes it
    speed = speed if speed is not None else length / 4 / (2 * np.pi * RUBBER["tau_relax"])
    return {"grid": {"nx": n, "ny": n, "x": [0, length], "y": [0, length], "periodic": True},
            "material": RUBBER,
            "body": {"shape": "heightmap", "file": write_heights(heights_file, z, comm), "cell": dx},
            "motion": {"load": 0.5e6 * length**2, "velocity": [speed, 0.0]},
            "time": {"mode": "steady", "allow_coarse": True}}


def rough_sliding(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, cells: int = 1024,
                  show: bool = True) -> list[dict]:
    """The steady sliding state of the rough benchmark scene at ``cells``^2 on this process's ranks, timed
    in process (imports done; kernels, TAO objects and the surface's spline built inside the time): wall
    time, fixed-point iterations, QP operator applications, mu_r, contact fraction. Writes
    ``out/sliding.csv``."""
    import warnings

    from petroll.model.limits import PetrollWarning
    from petroll.solver.simulation import Simulation

    raw = rough_raw(out / f"rough-{cells}.npy", cells, comm)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)  # the surface's slopes: the benchmark's choice
        scene = parse_scene(raw)
    comm.Barrier()
    start = time.perf_counter()
    sim = Simulation(scene, comm)
    record = next(sim.steps())
    seconds = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    rows = [dict(cells=f"{cells}x{cells}", ranks=comm.size, seconds=f"{seconds:.2f}",
                 iterations=sim.fixed_point_iterations, applications=record.applications,
                 mu_r=f"{record.mu_r:.5f}", area_fraction=f"{record.area / 1e-6:.4f}")]
    if comm.rank == 0:
        write_table(rows, out / "sliding.csv", show=show)
    return rows


def master_curve(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, cells: int = 512,
                 points: int = 20) -> list[dict]:
    """mu(V) of the rough benchmark scene at ``cells``^2 over ``points`` speeds (1e-3 to 1e3 times the
    peak's, geometric) by petroll sweep (each point from the previous one's steady state), timed in
    process as a whole (results files included). Writes ``out/master-curve.csv`` (speed, mu_r, contact
    fraction) and the sweep's own files under ``out/master-curve``."""
    import shutil
    import warnings

    from petroll.model.limits import PetrollWarning
    from petroll.studies.sweep import sweep

    raw = rough_raw(out / f"rough-{cells}.npy", cells, comm)
    peak = raw["motion"]["velocity"][0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)
        scene = parse_scene(raw)
        target = out / "master-curve"
        if comm.rank == 0 and target.exists():
            shutil.rmtree(target)
        comm.Barrier()
        start = time.perf_counter()
        table = sweep(scene, f"motion.velocity={peak * 1e-3}..{peak * 1e3}:log:{points}", target, comm,
                      plot=False)
        seconds = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
    c = table.columns
    rows = [dict(speed=f"{v:.4g}", mu_r=f"{m:.5f}", area_fraction=f"{a / 1e-6:.4f}")
            for v, m, a in zip(c["value"], c["mu_r"], c["area"])]
    rows.append(dict(speed=f"{points} points", mu_r=f"{seconds:.1f} s", area_fraction=f"{cells}^2"))
    if comm.rank == 0:
        write_table(rows, out / "master-curve.csv")
    return rows


def sliding(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, cells: int = 1024, curve_cells: int = 512,
            points: int = 20) -> None:
    """``petroll bench sliding``: the closed forms, the ``cells``^2 solve and the ``curve_cells``^2 master
    curve over ``points`` speeds."""
    closed_forms(out, comm)
    rough_sliding(out, comm, cells)
    master_curve(out, comm, curve_cells, points)


def applications(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, sides=(256, 512, 1024, 2048),
                 repeats: int = 20) -> list[dict]:
    """One application of the periodic operator against the non-periodic one on the same n x n grid (1 mm
    cells' side), in process after both kernels are built, alternating the two (so that a busy machine
    slows both alike), median of ``repeats`` each on this process's ranks (FFT threads: petroll's
    default). Writes ``out/periodic.csv``."""
    from petroll.model.grid import Grid
    from petroll.solver.influence import influence_operator, spare_cores

    rows = []
    workers = spare_cores(comm)
    for n in sides:
        convs = {periodic: influence_operator(Grid(n, n, 0.0, 1e-3, 0.0, 1e-3, periodic=(periodic, periodic)),
                                              comm, workers=workers).window(n, n) for periodic in (True, False)}
        field = np.random.default_rng(n).random((convs[True].r1 - convs[True].r0, n))
        runs = {True: [], False: []}
        for _ in range(repeats):
            for periodic, conv in convs.items():
                comm.Barrier()
                start = time.perf_counter()
                conv(field)
                runs[periodic].append(comm.allreduce(time.perf_counter() - start, op=MPI.MAX))
        times = {k: statistics.median(v) for k, v in runs.items()}
        rows.append(dict(cells=f"{n}x{n}", ranks=comm.size, periodic_ms=f"{1e3 * times[True]:.4g}",
                         padded_ms=f"{1e3 * times[False]:.4g}", ratio=f"{times[True] / times[False]:.4g}"))
    if comm.rank == 0:
        write_table(rows, out / "periodic.csv")
    return rows


def in_solve(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, sides=(512, 2048), repeats: int = 3,
             show: bool = True) -> list[dict]:
    """What an operator application costs inside a contact QP against one bare application of the same
    operator: on a periodic n x n grid (a self-affine rough surface under load control, pk from p = 0's
    summits start; :func:`qp_cases`) and a padded (windowed half-space) one (a sphere at a penetration whose
    interference, hence the QP's window, spans n x n cells), for each n of ``sides``. In process, after a
    first solve built the TAO objects and kernels; each of ``repeats`` rounds times the same solve from the
    same start (ContactSolver.solve_load / solve_penetration: its QPs with their set-up and
    read-out) and, alternating with it, one bare application of the QP window's operator (median of 5, on
    a random field); medians over the rounds. Times are CPU times of the process (the largest over the
    ranks; its FFT threads' included): on a shared machine what the work costs, which a busy neighbour's
    processes do not stretch as they do the wall time. Columns: the solve's iterations and counted applications
    (StepSolution.applications: the Hessian's mults, gradient evaluations included), FFT pairs of the
    window's size (the tally of petroll.solver.fft_work, the preconditioner's included) per application,
    the solve's time per application and its ratio to the bare one. Writes ``out/in-solve.csv``."""
    from petroll.solver.fft_work import FFTWork

    rows = []
    for n in sides:
        for case, solver, solve in qp_cases(n, comm):
            first = solve()  # builds the window's TAO objects and spectra
            i0, i1, j0, j1 = first.window
            conv = solver.influence.window(i1 - i0, j1 - j0)
            field = np.random.default_rng(n).random((conv.r1 - conv.r0, j1 - j0))
            solves, bare, pairs = [], [], []
            for _ in range(repeats):
                comm.Barrier()
                work, start = FFTWork.total, time.process_time()
                step = solve()
                solves.append(comm.allreduce(time.process_time() - start, op=MPI.MAX))
                pairs.append((FFTWork.total - work) / conv.cost)
                for _ in range(5):
                    comm.Barrier()
                    start = time.process_time()
                    conv(field)
                    bare.append(comm.allreduce(time.process_time() - start, op=MPI.MAX))
            seconds, one = statistics.median(solves), statistics.median(bare)
            contact = comm.allreduce(int(np.count_nonzero(step.pressure))) / ((i1 - i0) * (j1 - j0))
            per = 1e3 * seconds / step.applications
            rows.append(dict(case=case, cells=f"{i1 - i0}x{j1 - j0}", ranks=comm.size,
                             contact=f"{contact:.3f}", iterations=step.iterations,
                             applications=step.applications,
                             fft_pairs_per_application=f"{statistics.median(pairs) / step.applications:.3f}",
                             solve_ms=f"{1e3 * seconds:.4g}", per_application_ms=f"{per:.4g}",
                             bare_ms=f"{1e3 * one:.4g}", ratio=f"{per / (1e3 * one):.3f}"))
    if comm.rank == 0:
        write_table(rows, out / "in-solve.csv", show=show)
    return rows


def qp_cases(n: int, comm: MPI.Comm):
    """The two QPs of :func:`in_solve` at side n: (name, ContactSolver, a function solving it), periodic
    then padded. Periodic: a 1 mm cell of n x n cells, the self-affine surface of :func:`tamaas` (seed 3,
    rms slope 0.1), compliance 1e-7 1/Pa, mean pressure 50 kPa (about 10 % contact). Padded: a sphere of
    radius 10 mm on (n + 8)^2 cells of 1/n mm, at the penetration whose interference has a 1 mm radius
    (its window n x n cells), compliance 1e-9 1/Pa."""
    from petroll.model.grid import Grid
    from petroll.solver.contact import ContactSolver

    length, dx = 1e-3, 1e-3 / n
    grid = Grid(n, n, 0.0, length, 0.0, length, periodic=(True, True))
    solver = ContactSolver(grid, comm)
    keys = {"hurst": 0.8, "rolloff": length / 4, "cutoff": 4 * dx, "rms_slope": 0.1, "seed": 3}
    z = self_affine_heights(keys, (n, n), (dx, dx))[solver.r0 : solver.r1]
    yield "periodic", solver, lambda: solver.solve_load(z, 1e-7, 5e4 * length**2, length)
    radius, half = 1e-2, 0.5 * (n + 8) * dx
    grid = Grid(n + 8, n + 8, -half, half, -half, half)
    solver = ContactSolver(grid, comm)
    sphere = (grid.x[solver.r0 : solver.r1, None] ** 2 + grid.y[None, :] ** 2) / (2 * radius)
    yield "padded", solver, lambda: solver.solve_penetration(sphere, 1e-9, (0.5 * length) ** 2 / (2 * radius))


def tamaas(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, sides=(128, 256, 512),
           tol: float = 1e-12) -> list[dict]:
    """petroll's periodic elastic contact (the default pk, load control) against Tamaas's periodic solver on
    the same random rough surfaces (Hurst 0.8, rolloff a quarter of the cell, cut-off 4 cells, rms slope
    0.1; ~4 % contact), same samples, load and kernel, both to ``tol``: the largest pressure difference
    relative to the peak pressure, the relative L2 difference, the contact fractions. Tamaas runs in
    .venv-peers (its script peers/solve_tamaas_periodic.py). Writes ``out/tamaas.csv``."""
    import warnings

    from petroll.model.limits import PetrollWarning
    from petroll.solver.simulation import Simulation
    from petroll.bench.peers import peer_process, peer_scripts, peers_python

    peer_scripts()  # every rank: from an install, a one-line error before anything is solved or installed
    python = peers_python() if comm.rank == 0 else None
    rows = []
    for n in sides:
        length, E = 1e-3, 10e6
        dx = length / n
        z = self_affine_heights({"hurst": 0.8, "rolloff": length / 4, "cutoff": 4 * dx, "rms_slope": 0.1,
                                 "seed": 3}, (n, n), (dx, dx))
        z = z - z.min()
        mean = 0.01 * E / (1 - NU**2) * 0.1
        raw = {"grid": {"nx": n, "ny": n, "x": [0, length], "y": [0, length], "periodic": True},
               "material": {"model": "elastic", "E": E, "nu": NU},
               "body": {"shape": "heightmap", "file": write_heights(out / f"tamaas-{n}.npy", z, comm), "cell": dx},
               "motion": {"load": mean * length**2}, "solver": {"tol": tol}}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PetrollWarning)
            sim = Simulation(parse_scene(raw), comm)
        comm.Barrier()
        start = time.perf_counter()
        next(sim.steps())
        seconds = comm.allreduce(time.perf_counter() - start, op=MPI.MAX)
        ours = np.concatenate(comm.allgather(sim.pressure))
        if comm.rank == 0:
            answer = peer_process(python, "tamaas_periodic", [str(out / f"tamaas-{n}.npy"), str(length),
                                                                str(E), str(NU), repr(mean), f"{tol:g}",
                                                                str(out / "tamaas-pressure.npy")])
            theirs = np.load(out / "tamaas-pressure.npy")
            rows.append(dict(cells=f"{n}x{n}", tol=f"{tol:g}",
                             max_difference=f"{np.abs(ours - theirs).max() / ours.max():.1e}",
                             l2_difference=f"{np.linalg.norm(ours - theirs) / np.linalg.norm(ours):.1e}",
                             contact_petroll=f"{np.mean(ours > 0):.4f}", contact_tamaas=f"{np.mean(theirs > 0):.4f}",
                             petroll_s=f"{seconds:.2f}", tamaas_s=f"{answer['warm_s']:.2f}",
                             tamaas=answer["version"]))
    rows = comm.bcast(rows)
    if comm.rank == 0:
        write_table(rows, out / "tamaas.csv")
    return rows


def periodic(out: pathlib.Path, comm: MPI.Comm = MPI.COMM_WORLD, sides=(256, 512, 1024, 2048),
             repeats: int = 20, tamaas_sides=(128, 256, 512), solve_sides=(512, 2048)) -> None:
    """``petroll bench periodic``: the operator's cost against the non-periodic one on ``sides``, an
    application inside a QP against a bare one on ``solve_sides``, and Tamaas on ``tamaas_sides`` (none:
    Tamaas is not run, nothing installed)."""
    applications(out, comm, sides, repeats)
    in_solve(out, comm, solve_sides, min(repeats, 3))
    if tamaas_sides:
        tamaas(out, comm, tamaas_sides)


SCALE_SIDES = (2048, 4096)
"""Grid sides of ``petroll bench sliding --ranks/--sides`` by default."""


def scale(out: pathlib.Path, sides=SCALE_SIDES, ranks=(1, 2)) -> list[dict]:
    """The rough sliding benchmark at ``sides``^2 on each rank count as ``mpirun -n K`` children of this
    single process: every rank's peak resident memory (ru_maxrss) and its memory before the scene is
    built (the interpreter, numpy, PETSc, MPI), the wall time, the friction (the same on every rank
    count). ``per_rank_vs_1``: the run's own memory (peak - fixed) times the ranks over one rank's.
    Writes ``out/scale.csv``."""
    from petroll.bench.memory import mpirun_child

    rows = []
    for side in sides:
        for k in ranks:
            m = mpirun_child(k, "petroll.bench.rough", [str(side)], "bench sliding scale")
            peaks, fixed = np.array(m["peak_mib"]), np.array(m["fixed_mib"])
            rows.append(dict(cells=f"{side}x{side}", ranks=k, seconds=f"{m['seconds']:.1f}",
                             peak_mib=" ".join(f"{v:.0f}" for v in peaks), fixed_mib=f"{fixed.mean():.0f}",
                             run_mib=float((peaks - fixed).mean()), mu_r=m["mu_r"]))
            print(f"bench sliding scale: {side}^2 on {k} ranks: peak {peaks.round(0).tolist()} MiB, "
                  f"{m['seconds']:.1f} s", flush=True)
    for r in rows:
        one = next((s for s in rows if s["cells"] == r["cells"] and s["ranks"] == 1), None)
        r["per_rank_vs_1"] = r["run_mib"] * r["ranks"] / one["run_mib"] if one else math.nan
    rows = [dict(r, run_mib=f"{r['run_mib']:.0f}", per_rank_vs_1=f"{r['per_rank_vs_1']:.3f}") for r in rows]
    write_table(rows, out / "scale.csv")
    return rows


if __name__ == "__main__":  # the child of ``scale``: SIDE DIR; one JSON line on rank 0
    import petsc4py

    petsc4py.init([])
    from petroll.bench.memory import peak_mib, rss_mib

    world, fixed = MPI.COMM_WORLD, rss_mib()
    row = rough_sliding(pathlib.Path(sys.argv[2]), world, cells=int(sys.argv[1]), show=False)[0]
    peaks, fixeds = world.gather(peak_mib(), root=0), world.gather(fixed, root=0)
    if world.rank == 0:
        print(json.dumps(dict(seconds=float(row["seconds"]), mu_r=row["mu_r"], peak_mib=peaks, fixed_mib=fixeds)))
