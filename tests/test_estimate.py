"""The error estimate (petroll.solver.estimate; docs/accuracy.md): Richardson extrapolation against exact
power laws, the coarser runs against the same scenes run on their own, results.h5's group, the summary
line and the sweep's columns; the estimate against the true error (a reference 4x finer)."""

import math

import numpy as np
import pytest

import petroll
from petroll.model.scene import load_scene, shipped_scene
from petroll.solver.estimate import KNOWN_ORDER, coarser, richardson
from petroll.solver.simulation import Simulation
from petroll.studies.accuracy import verify


# -- Richardson -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("order", [1.2, 2.0, 2.7])
def test_three_grids_recover_a_power_law_exactly(order):
    """f(h) = 1 + 0.3 h^p on h = 1, 2, 4: the observed order is p, the extrapolated value 1; the error of
    the fine value is |f(1) - 1| where p is at most the known order, smaller where it is above (the bound
    is taken with the known order)."""
    values = tuple(1 + 0.3 * h**order for h in (1, 2, 4))
    q = richardson(values, known=2.0)
    assert q.observed and q.order == pytest.approx(order, rel=1e-12)
    assert q.extrapolated == pytest.approx(1.0, rel=1e-12)
    true = 0.3
    expected = true if order <= 2 else 0.3 * (2**order - 1) / 3
    assert q.error == pytest.approx(expected, rel=1e-12)


def test_two_grids_use_the_known_order():
    values = (1 + 0.3, 1 + 0.3 * 4)  # h^2 on h = 1, 2
    q = richardson(values, known=2.0)
    assert not q.observed and q.order == 2.0
    assert q.extrapolated == pytest.approx(1.0, rel=1e-12) and q.error == pytest.approx(0.3, rel=1e-12)


@pytest.mark.parametrize("values", [(1.0, 1.1, 0.95), (1.0, 1.1, 1.15), (1.0, 1.1, 4.0)])
def test_grids_outside_the_asymptotic_range_give_no_bound(values):
    """The difference changes sign, shrinks, or gives an order far from the known one (here 4.9 against
    2): no error, no extrapolated value."""
    q = richardson(values, known=2.0)
    assert math.isnan(q.error) and math.isnan(q.extrapolated) and not q.asymptotic


def test_agreeing_grids_give_the_floor():
    q = richardson((0.5, 0.5, 0.6), known=1.0, floor=0.01)
    assert q.error == 0.01 and q.extrapolated == 0.5


# -- the run ---------------------------------------------------------------------------------------------
def roller():
    return load_scene(shipped_scene("roller-2d.toml"))


def test_a_run_with_its_estimate_writes_the_group_and_the_summary_line(comm, shared_dir, cli_main):
    """runs/roller-2d.toml with --estimate-error: results.h5's group error_estimate holds, per quantity, the
    fine value (the series' last), the coarser grids' values (the same scenes run on their own: the grid
    of 92 strips to the fine run's last time), and Richardson's extrapolation and error from them with the
    known order; the command prints them in one line."""
    scene = roller()
    results = petroll.run(scene, comm, out=shared_dir / "api", estimate_error=True)
    found = results.error_estimate
    assert [tuple(g) for g in found[""]["grids"]] == [(184, 1), (92, 1)] and found[""]["failed"] == ""
    t_end = float(results.series["t"][-1])
    coarse = list(Simulation(coarser(scene, 2, t_end), comm).steps())[-1]
    assert coarse.t == pytest.approx(t_end, rel=1e-12)
    for name in ("force", "delta", "mu_r", "p_max", "area", "lead", "trail"):
        q = found[name]
        assert q["value"] == results.series[name][-1]
        assert q["coarse"][0] == pytest.approx(getattr(coarse, name), rel=1e-9, abs=1e-15)
        floor = {"lead": 0.5 * scene.grid.dx, "trail": 0.5 * scene.grid.dx, "area": 0.5 * scene.grid.dx}
        expected = richardson((q["value"], getattr(coarse, name)), KNOWN_ORDER[name], floor.get(name, 0.0))
        assert q["error"] == pytest.approx(expected.error, rel=1e-6)
        assert q["extrapolated"] == pytest.approx(expected.extrapolated, rel=1e-9)
        assert q["order"] == KNOWN_ORDER[name]
    if comm.rank == 0:
        (shared_dir / "roller.toml").write_text(scene.text)
    comm.Barrier()
    code, out, err = cli_main(["run", str(shared_dir / "roller.toml"), "--out", str(shared_dir / "cli"),
                               "--quiet", "--estimate-error"])
    assert code == 0
    if comm.rank == 0:
        mu = found["mu_r"]
        assert f"mu_r {mu['value']:.4e} +- {mu['error']:.2g}" in out
        assert "(discretisation; grids 184 x 1, 92 x 1)" in out


def test_a_sweep_with_its_estimate_has_the_error_columns(comm, shared_dir):
    """petroll sweep --estimate-error on runs/master-curve.toml (steady solves): each point's mu_r_error is
    its results.h5's estimate; a sweep without has no such column."""
    from petroll.studies.sweep import sweep

    scene = load_scene(shipped_scene("master-curve.toml"))
    table = sweep(scene, "motion.velocity=0.01,0.03", shared_dir / "sweep", comm, plot=False,
                  estimate_error=True)
    for i, point in enumerate(table.points):
        found = petroll.Results.open(shared_dir / "sweep" / point / "results.h5").error_estimate
        assert table.columns["mu_r_error"][i] == found["mu_r"]["error"] > 0
    plain = sweep(scene, "motion.velocity=0.01", shared_dir / "plain", comm, plot=False)
    assert "mu_r_error" not in plain.columns


# -- against the true error ------------------------------------------------------------------------------
def test_the_estimate_is_within_3_of_the_true_error_and_extrapolation_gets_closer(comm):
    """runs/roller-2d.toml against a reference 4x finer (736 strips, 4x the steps): for the penetration,
    mu_r and the peak pressure the estimate is within a factor 3 of the true error and the extrapolated
    value is nearer the reference than the fine one; for the cell-counted area and patch edges the
    estimate bounds the true error (docs/verification.md has the other scenes)."""
    checks, found = verify(roller(), comm)
    assert found.failed is None
    by = {c.name: c for c in checks}
    for name in ("delta", "mu_r", "p_max"):
        assert by[name].within_3 and by[name].closer, by[name]
    for name in ("area", "lead", "trail"):
        assert by[name].estimated >= by[name].true, by[name]
