"""The rolling benchmarks (petroll.bench.rolling, bench_mpi) on tiny sizes: what they measure, never how fast.

Serial only: the MPI benchmark starts its own mpirun children (ranks 1 and 2, compared inside the test).
"""

import csv
import math

import numpy as np
import pytest

from petroll.bench.mpi import mpi_scaling
from petroll.bench.rolling import growth, precision

pytestmark = pytest.mark.serial


def _order(coarse: dict, fine: dict, quantity: str = "force") -> float:
    """Observed order of convergence between two points of a dt ladder."""
    return math.log(coarse[f"{quantity}_error"] / fine[f"{quantity}_error"]) / math.log(
        fine["steps_per_cell"] / coarse["steps_per_cell"])


@pytest.mark.slow
def test_precision_orders_of_the_integrators_and_the_summary(tmp_path):
    runs, summary = precision(tmp_path, steps_per_cell=(0.25, 4, 8), reference=32, grids=(0.5, 1),
                              grid_scale=0.5, distance=2e-3, short=0)
    ladder = {name: [r for r in runs if r["kind"] == "dt" and r["integrator"] == name]
              for name in ("paper", "exponential", "relaxation")}
    assert math.isnan(ladder["paper"][0]["run_s"]) and "refused" in ladder["paper"][0]["note"]  # the guard
    assert not math.isnan(ladder["relaxation"][0]["run_s"])  # relaxation takes any step
    assert 1.6 < _order(*ladder["exponential"][1:]) < 3.0  # second order
    assert 0.7 < _order(*ladder["paper"][1:]) < 1.4  # first order
    reference = next(r for r in runs if r["kind"] == "dt reference" and r["note"])
    assert reference["force_error"] < 0.2 * ladder["exponential"][-1]["force_error"]  # a reference well below
    ratio = summary[-1]
    assert ratio["line"] == "paper / exponential" and ratio["seconds"] > 0 and ratio["relation"] != "?"
    with open(tmp_path / "precision.csv") as fh:
        assert len(list(csv.DictReader(fh))) == len(runs)
    assert (tmp_path / "precision.png").stat().st_size > 0


def test_growth_sizes_the_window_as_asked_and_writes_its_tables(tmp_path):
    growth(tmp_path, windows=(24, 32, 48), steps=6, track_window=16, track_steps=40, track_skip=10,
           track_span=10)
    with open(tmp_path / "growth.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["window", "requested", "first_cells", "cells", "grid", "timed_steps", "step_s",
                             "applications", "application_s", "convolution_share", "peak_rss_mib"]
    for row in rows:
        assert int(row["first_cells"]) == int(row["requested"]), row  # N x N cells at the first step
        assert 0.6 < float(row["cells"]) / float(row["requested"]) <= 1, row  # it shrinks as the body rolls
        assert int(row["timed_steps"]) == 3
    with open(tmp_path / "growth_track.csv") as fh:
        track = list(csv.DictReader(fh))
    assert [int(r["step"]) for r in track] == list(range(40))
    assert [int(r["step"]) for r in track if r["early_run_s"]] == list(range(10, 20))  # the second run's span
    assert (tmp_path / "growth.png").stat().st_size > 0


def test_mpi_forces_agree_between_rank_counts(tmp_path):
    rows = mpi_scaling(tmp_path, windows=(24,), ranks=(1, 2), steps=5, repeats=1)
    assert [r["ranks"] for r in rows] == [1, 2]
    assert rows[1]["force_difference"] < 1e-6  # the same answer on 2 ranks, to the solver's tolerance
    assert rows[0]["efficiency"] == 1.0 and rows[1]["efficiency"] == pytest.approx(rows[1]["speedup"] / 2)
    assert (tmp_path / "mpi.csv").exists() and (tmp_path / "mpi.png").exists()


def test_mpi_steady_solves_the_memory_scenes_steady_state_on_each_rank_count(tmp_path):
    """bench mpi --steady: the force of each rank count's steady solve is that of the scene run by
    petroll.run (serially, a second path through the driver)."""
    import petroll
    from petroll.bench.memory import memory_scene

    rows = mpi_scaling(tmp_path, ranks=(1, 2), repeats=1, steady=True, sides=(256,))
    direct = petroll.run(memory_scene(256, 0, steady=True), out=tmp_path / "direct").series["force"][-1]
    assert [r["ranks"] for r in rows] == [1, 2] and rows[0]["cells"] == 256 * 256
    assert all(abs(r["force"] / direct - 1) < 1e-9 for r in rows)
    assert (tmp_path / "mpi_steady.csv").exists() and not (tmp_path / "mpi.csv").exists()


@pytest.mark.slow
def test_warm_start_bench_same_answer_fewer_applications(tmp_path):
    from petroll.bench.solvers import warm_starts

    rows = {r["start"]: r for r in warm_starts(tmp_path, cells_per_radius=6, repeats=1)}
    assert list(rows) == ["cold", "carried", "extrapolated"]
    forces = [float(r["force"]) for r in rows.values()]
    assert max(forces) / min(forces) - 1 < 1e-6  # the first guess changes the cost, not the answer
    late = [float(r["apps_last_20"]) for r in rows.values()]
    assert late[0] > late[1] > late[2]  # cold > carried > extrapolated at steady state
    assert (tmp_path / "warm.csv").exists() and (tmp_path / "warm.png").stat().st_size > 0


@pytest.mark.slow
def test_skips_bench_each_saving_keeps_the_answer(tmp_path):
    from petroll.bench.rolling import skips

    rows = {r["saving"].split(" (")[0]: r for r in skips(tmp_path, track_cells=140, repeats=3)}
    assert set(rows) == {"QP on the interference window", "kernels built once per window shape",
                         "stop at steady state", "preceding displacement on a box"}
    window = rows["QP on the interference window"]["scene"]  # "... steady window AxB of CxD cells"
    a, b, c, d = map(int, window.split("window ")[1].replace(" of ", "x").split(" ")[0].split("x"))
    assert a * b < 0.2 * c * d  # the QP is posed on a small part of the grid
    counts = rows["stop at steady state"]["scene"].split(": ")[1].split(" steps")[0]  # "52 of 108"
    steps, total = map(int, counts.split(" of "))
    assert steps < total
    assert float(rows["preceding displacement on a box"]["change"].split(" ")[0]) < 1e-7  # within the tolerance
    assert (tmp_path / "skips.csv").exists()


def _bench_docs(tmp_path_factory, name: str) -> list[dict]:
    """The rows of results/bench/NAME that docs/benchmarks.md's blocks wrote (``petroll bench ... --quick``,
    run once a session by tests/test_docs.py): what the command wrote, checked without running it again."""
    from test_docs import ROOT, document_run

    with open(document_run(ROOT / "docs" / "benchmarks.md", tmp_path_factory) / "results" / "bench" / name) as fh:
        return list(csv.DictReader(fh))


@pytest.mark.slow
def test_tao_types_on_the_rolling_scene_agree(tmp_path_factory):
    """``petroll bench tao --quick``'s rolling part (docs/benchmarks.md): every TAO type and PC rolls the
    default scene to the same force."""
    rows = _bench_docs(tmp_path_factory, "tao_rolling.csv")
    forces = [float(r["force"]) for r in rows]  # a failed type would not parse
    assert len(rows) == 15 and max(forces) / min(forces) - 1 < 1e-6  # every solver and PC, the same answer
    assert [r["pc"] for r in rows if r["tao_type"] == "tron"] == ["circulant", "none"]
    assert [r["pc"] for r in rows if r["tao_type"] == "bncg"] == ["-"]
    assert int(rows[0]["steps"]) > 1 and all(r["steps"] == rows[0]["steps"] for r in rows)


@pytest.mark.slow
@pytest.mark.parametrize("steady", [False, True])
def test_memory_bench_reports_every_ranks_peak_and_the_same_force_on_1_and_2_ranks(tmp_path_factory, steady):
    """``petroll bench memory [--steady] --quick --sides 256 --ranks 1,2`` (docs/benchmarks.md) on a 256^2
    grid, rolled or its steady state solved directly: a peak above the fixed cost on every rank, rank 0 /
    mean near 1, and one answer whatever the rank count (the children run the same scene)."""
    rows = [r for r in _bench_docs(tmp_path_factory, f"memory{'_steady' if steady else ''}.csv")
            if r["side"] == "256"]
    rows = [next(r for r in rows if r["ranks"] == k) for k in ("1", "2")]
    assert all(int(r["cells"]) == 256 * 256 for r in rows)
    assert all(float(r["mean_mib"]) > float(r["fixed_mib"]) > 20 and float(r["run_mib"]) > 0 for r in rows), rows
    assert float(rows[1]["rank0_over_mean"]) < 1.15
    assert int(rows[0]["steps"]) == int(rows[1]["steps"]) == (1 if steady else 3)
    assert float(rows[1]["force"]) == pytest.approx(float(rows[0]["force"]), rel=1e-10 if steady else 1e-12)


def test_steady_growth_times_the_direct_solve_on_each_grid(tmp_path):
    """bench steady-growth on two small grids of runs/sphere.toml (one round): a row per grid, the first
    grid's ratio 1, iterations and applications counted, and the refined grid's force within the first's
    discretisation error (1 %)."""
    from petroll.bench.steady import growth

    rows = growth(tmp_path, grids=((80, 27), (160, 54)), repeats=1)
    assert [r["grid"] for r in rows] == ["80x27", "160x54"] and rows[0]["ratio"] == "1.00"
    assert all(r["iterations"] > 1 and r["applications"] > r["iterations"] for r in rows)
    assert all(int(r["equivalents"]) > r["applications"] for r in rows)
    assert float(rows[1]["force"]) == pytest.approx(float(rows[0]["force"]), rel=0.01)
    assert (tmp_path / "steady_growth.csv").exists()


def test_append_bench_times_every_append(tmp_path):
    from petroll.bench.memory import append

    rows = append(tmp_path, side=16, steps=30, block=10)
    assert [r["steps"] for r in rows] == ["0-9", "10-19", "20-29"]
    assert all(0 < r["median_ms"] <= r["max_ms"] for r in rows)


def test_peers_bench_converges_each_solver_to_the_reference(tmp_path):
    """petroll alone (the peers need their own environment), from zero, from Hertz's pressure and as a
    scene run by `petroll run` (a whole process, its results read back): the tolerance chosen is one
    whose pressure is within the target of the 1e-12 reference, tighter than the loosest tried, with a
    residual to match; times and ratios filled."""
    from petroll.bench.peers import TOLERANCES, peers

    rows = peers(tmp_path, problems=("hertz",), cells=(24,), repeats=1, target=1e-8, solvers=("petroll",))
    assert [(r["solver"], r["start"]) for r in rows] == [("petroll", "zero"), ("petroll", "hertz"),
                                                         ("petroll", "scene")]
    for row in rows:
        assert float(row["difference"]) <= 1e-8 and row["within"] == 1, row
        assert float(row["tol"]) in TOLERANCES and float(row["tol"]) < TOLERANCES[0]
        assert 0 < float(row["residual"]) <= 10 * float(row["tol"])
        assert float(row["cold_s"]) > float(row["warm_s"]) > 0 and row["count"] > 0
    assert rows[0]["cold_ratio"] == "1.000" and rows[2]["scene_ratio"] == "1.000"
    assert (tmp_path / "peers.csv").exists() and (tmp_path / "peers.png").stat().st_size > 0


def test_without_the_peers_scripts_bench_peers_stops_in_one_line(cli_main, comm, shared_dir, monkeypatch):
    """As from an install (the scripts are in the checkout's scripts/peers/ only): exit status 2, one line
    naming where they were looked for, nothing written (tests/test_install.py: from a real install)."""
    import petroll.bench.peers as bench_peers

    assert (bench_peers.PEER_SCRIPTS / "solve_petroll.py").is_file()  # this checkout's
    monkeypatch.setattr(bench_peers, "PEER_SCRIPTS", shared_dir / "elsewhere" / "scripts" / "peers")
    code, out, err = cli_main(["bench", "peers", "--quick", "--out", str(shared_dir / "bench")])
    assert code == 2
    if comm.rank == 0:
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
        assert str(shared_dir / "elsewhere" / "scripts" / "peers") in err and "checkout" in err
    assert not (shared_dir / "bench" / "peers.csv").exists()


def test_the_peers_residual_is_the_dense_gap_of_the_pressure(tmp_path):
    """residual() (the FFT operator) against the gap computed with the assembled influence matrix of the
    problem's grid, for a pressure near the solution and a perturbed one."""
    import numpy as np

    from petroll.model.grid import Grid
    from petroll.solver.contact import ContactSolver
    from petroll.solver.influence import dense_influence
    from petroll.solver.kernels.love import love_coefficients
    from petroll.bench.peers import residual, write_problem
    from mpi4py import MPI

    n = 20
    write_problem("wavy", n, tmp_path / "p.npz")
    data = np.load(tmp_path / "p.npz")
    heights, cell, compliance = data["heights"], float(data["cell"]), float(data["compliance"])
    solver = ContactSolver(Grid(n, n, 0, n * cell, 0, n * cell), MPI.COMM_SELF, tol=1e-6)
    pressure = solver.solve_penetration(heights, compliance, 0.01).pressure
    A = dense_influence(love_coefficients(n, n, cell, cell))
    for p in (pressure, pressure * (1 + 0.1 * np.random.default_rng(0).random((n, n)))):
        w = compliance * (A @ p.ravel()).reshape(n, n)
        delta = (heights + w)[p > 0].mean()
        expected = np.abs(np.minimum(p / p.max(), (heights + w - delta) / delta)).max()
        assert residual(tmp_path / "p.npz", p) == pytest.approx(expected, rel=1e-9)
    assert residual(tmp_path / "p.npz", pressure) < 1e-5 < expected


def test_load_control_bench_finds_the_same_penetration(tmp_path):
    from petroll.bench.solvers import load_control

    rows = load_control(tmp_path, cells=48)
    assert [r["tao_type"] for r in rows] == ["pk", "tron"]
    for row in rows:
        assert abs(float(row["delta_error"])) < 1e-6  # the force of delta gives delta back
        assert float(row["ratio"]) == pytest.approx(row["load_applications"] / row["displacement_applications"],
                                                   abs=0.006)
    assert (tmp_path / "tao_load.csv").exists()


def test_steady_compares_the_direct_solve_with_the_transient_run(tmp_path):
    """bench steady on a 32 x 32 window (a/dx = 9): both methods against the exact steady state (the direct
    solve at 1e-10), the direct one far cheaper in operator applications at the same tolerance, every
    convolution counted beside them."""
    from petroll.model.scene import parse_scene
    from petroll.bench.steady import steady

    scene = parse_scene({
        "grid": {"nx": 32, "ny": 32, "x": [-0.8e-3, 0.8e-3], "y": [-0.8e-3, 0.8e-3]},
        "material": {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
        "body": {"shape": "sphere", "radius": 0.01},
        "motion": {"velocity": [0.01, 0.0], "penetration": 2e-5},
        "time": {"steps_per_cell": 1, "distance": 1e-3, "steady": 1e-3},
    })
    rows = steady(tmp_path, speeds=(0.01, 1.0), track=16, scene=scene)
    for row in rows:
        # a change-based stop (both methods): errors of the order of the tolerance, 1e-4; it tests the
        # resisting force against the force, so mu_r's error is small in absolute terms
        assert float(row["direct_force_error"]) < 1e-3, row
        assert float(row["direct_mu_r_error"]) * float(row["mu_r"]) < 1e-4, row
        assert row["transient_steady"] == 1 and float(row["transient_force_error"]) < 1e-3, row
        assert row["direct_applications"] < row["transient_applications"], row
        # every convolution counted: the direct solve's wake-extended convolutions and memory correlations
        # add to its QPs' applications, the transient's history convolutions and preconditioner to its own
        assert int(row["direct_equivalents"]) > row["direct_applications"] + row["direct_iterations"], row
        assert int(row["transient_equivalents"]) > row["transient_applications"], row
        assert float(row["time_ratio"]) > 0 and float(row["equivalents_ratio"]) > 0
    with open(tmp_path / "steady.csv") as fh:
        assert [float(r["v_tau_a"]) for r in csv.DictReader(fh)] == pytest.approx([0.01, 1.0], rel=1e-9)


def test_a_surface_sampled_coarser_keeps_its_modes():
    """petroll bench cutoff's coarser grids carry the same surface: a sum of modes below the coarse grid's
    Nyquist frequency, sampled at 64^2, dropped to 16^2, equals its own samples at 16^2."""
    from petroll.bench.sizing import truncated

    def surface(n):  # sample j at x = j / n: the coarse samples are every fourth of the fine ones
        x = np.arange(n) / n
        return (np.cos(2 * np.pi * (3 * x[:, None] + 2 * x[None, :])) + 0.3 * np.sin(2 * np.pi * 5 * x[:, None])
                + 0.1 * np.cos(2 * np.pi * 7 * x[None, :] - 0.4))

    assert np.abs(truncated(surface(64), 16) - surface(16)).max() < 1e-12


@pytest.mark.slow
def test_the_resolution_benches_measure_against_their_reference(tmp_path_factory):
    """``petroll bench cutoff --quick`` and ``bench sized --quick`` (docs/benchmarks.md): the reference row is
    the reference, the coarser one the same surface (penetration within 3 %), the sized grid within a few
    per cent of the fine one."""
    rows = _bench_docs(tmp_path_factory, "cutoff.csv")
    assert [r["cells_per_cutoff"] for r in rows] == ["4", "2"] and rows[0]["mu_change"] == "+0.00%"
    assert abs(float(rows[1]["penetration_change"].rstrip("%"))) < 3
    row = next(r for r in _bench_docs(tmp_path_factory, "sized.csv") if r["speed"] == "0.01")
    assert all(abs(float(row[f"{q}_change"].rstrip("%"))) < 3 for q in ("mu_r", "delta", "area", "p_max")), row
