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
