"""The rough-contact benchmarks (petroll.bench.rough) on tiny sizes: what they measure, never how
fast (the peer comparison with Tamaas needs .venv-peers, made by pip: run by `petroll bench periodic`)."""

import csv

import numpy as np
import pytest

from petroll.bench import rough as bench_rough

pytestmark = pytest.mark.serial


def read(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


def test_the_periodic_application_is_timed_beside_the_padded_one(tmp_path):
    rows = bench_rough.applications(tmp_path, sides=(16, 32), repeats=2)
    assert [r["cells"] for r in read(tmp_path / "periodic.csv")] == ["16x16", "32x32"]
    for row in rows:
        assert float(row["periodic_ms"]) > 0 and float(row["padded_ms"]) > 0
        assert float(row["ratio"]) == pytest.approx(float(row["periodic_ms"]) / float(row["padded_ms"]), rel=2e-3)


def test_an_application_inside_a_solve_is_counted_and_timed_beside_a_bare_one(tmp_path, monkeypatch):
    """Every row's applications are the window operator's calls during one solve (counted here by wrapping
    Convolution.__call__, apart from the solver's own count), its FFT pairs per application those calls'
    and the preconditioner's transforms in units of the window's, and its ratio the printed times'."""
    from mpi4py import MPI

    from petroll.solver.influence import Convolution

    calls = []
    original = Convolution.__call__
    monkeypatch.setattr(Convolution, "__call__", lambda conv, x: calls.append(conv) or original(conv, x))
    rows = bench_rough.in_solve(tmp_path, sides=(16,), repeats=1, show=False)
    assert [(r["case"], r["cells"]) for r in read(tmp_path / "in-solve.csv")] == [("periodic", "16x16"),
                                                                                  ("padded", "16x16")]
    for row, (case, solver, solve) in zip(rows, bench_rough.qp_cases(16, MPI.COMM_WORLD)):
        solve()  # the first solve builds the window's operators
        calls.clear()
        step = solve()
        window = solver.influence.window(step.window[1] - step.window[0], step.window[3] - step.window[2])
        assert row["case"] == case and int(row["applications"]) == step.applications > 0
        assert sum(conv is window for conv in calls) == step.applications
        pairs = sum(conv.cost for conv in calls) / window.cost
        assert float(row["fft_pairs_per_application"]) == pytest.approx(pairs / step.applications, abs=1e-3)
        assert float(row["fft_pairs_per_application"]) > 1  # the preconditioner's transforms come on top
        per = float(row["per_application_ms"])
        assert per == pytest.approx(float(row["solve_ms"]) / step.applications, rel=2e-3)
        assert float(row["ratio"]) == pytest.approx(per / float(row["bare_ms"]), rel=2e-3)


@pytest.mark.slow
def test_the_rough_sliding_solve_and_the_master_curve_agree_where_they_meet(tmp_path):
    """The master curve's point at the peak speed is the direct solve's (same scene, same steady state),
    and friction vanishes towards both ends of the curve (a relaxed and a glassy elastic contact)."""
    single = bench_rough.rough_sliding(tmp_path, cells=32)[0]
    curve = bench_rough.master_curve(tmp_path, cells=32, points=5)[:-1]
    speeds = np.array([float(r["speed"]) for r in curve])
    mu = np.array([float(r["mu_r"]) for r in curve])
    middle = int(np.argmin(np.abs(np.log(speeds / speeds[2]))))
    assert float(curve[middle]["mu_r"]) == pytest.approx(float(single["mu_r"]), rel=1e-5)
    assert mu[0] < 0.1 * mu.max() and mu[-1] < 0.1 * mu.max()
    assert len(read(tmp_path / "master-curve.csv")) == 6 and read(tmp_path / "sliding.csv")
