"""The error estimate (petroll.studies.estimate; docs/accuracy.md): Richardson extrapolation against exact
power laws, the coarser runs against the same scenes run on their own, results.h5's group, the summary
lines and the sweep's columns; the estimate against the true error (a reference 4x finer) on a sphere, a
roller, a roller given as a 1-D profile and a layer (docs/verification.md has the full table)."""

import math

import pytest
from mpi4py import MPI

import petroll
from petroll.model.clock import TimeMode
from petroll.model.scene import load_scene, shipped_scene
from petroll.studies.estimate import coarser, known_order, quantised, richardson
from petroll.solver.simulation import Simulation
from petroll.bench.accuracy import profile_roller, verify


# -- Richardson -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("order", [1.2, 2.0, 2.7])
def test_three_grids_recover_a_power_law_exactly(order):
    """f(h) = 1 + 0.3 h^p on h = 1, 2, 4: the observed order is p, the extrapolated value 1; the error of
    the fine value is |f(1) - 1| where p is at most the known order, larger where it is above (the bound
    is taken with the known order)."""
    f1, f2, f4 = (1 + 0.3 * h**order for h in (1, 2, 4))
    q = richardson(f1, (f2,), f4, known=2.0)
    assert q.observed and q.checked and q.order == pytest.approx(order, rel=1e-12)
    assert q.extrapolated == pytest.approx(1.0, rel=1e-12)
    expected = 0.3 if order <= 2 else 0.3 * (2**order - 1) / 3
    assert q.error == pytest.approx(expected, rel=1e-12)


def test_two_grids_use_the_known_order_and_say_the_range_was_not_checked():
    """h^2 with order 2 and h with order 1 on h = 1, 2: extrapolated exactly; what two grids give with
    order 2 for h (the "paper" integrator's error taken as second order) is 3x too small."""
    q = richardson(1 + 0.3, (1 + 0.3 * 4,), None, known=2.0)  # h^2 on h = 1, 2
    assert not q.observed and not q.checked and q.order == 2.0
    assert q.extrapolated == pytest.approx(1.0, rel=1e-12) and q.error == pytest.approx(0.3, rel=1e-12)
    q = richardson(1 + 0.3, (1 + 0.3 * 2,), None, known=1.0)  # h on h = 1, 2
    assert not q.checked and q.order == 1.0
    assert q.extrapolated == pytest.approx(1.0, rel=1e-12) and q.error == pytest.approx(0.3, rel=1e-12)
    assert richardson(1 + 0.3, (1 + 0.3 * 2,), None, known=2.0).error == pytest.approx(0.1, rel=1e-12)


def test_two_alignments_are_averaged_and_their_spread_bounds():
    """The 2x grid at two alignments, 1 + 0.3 * 4 -+ 0.12: their mean is extrapolated (to 1), their half
    spread added to the error (0.3 + 0.12 / 3)."""
    q = richardson(1.3, (1 + 1.2 - 0.12, 1 + 1.2 + 0.12), None, known=2.0)
    assert q.extrapolated == pytest.approx(1.0, rel=1e-12)
    assert q.error == pytest.approx(0.3 + 0.04, rel=1e-12)


@pytest.mark.parametrize("values", [(1.0, 1.1, 0.95), (1.0, 1.1, 1.15), (1.0, 1.1, 4.0)])
def test_grids_outside_the_asymptotic_range_give_no_bound(values):
    """The difference changes sign, shrinks, or gives an order far from the known one (here 4.9 against
    2): no error, no extrapolated value."""
    q = richardson(values[0], (values[1],), values[2], known=2.0)
    assert math.isnan(q.error) and math.isnan(q.extrapolated) and not q.asymptotic and q.checked


def test_a_coarse_fourth_grid_checks_the_range_only():
    """observe=False (the 4x grid too coarse for its order): a sign change still says not asymptotic; an
    agreeing sign leaves the known order, whatever the 4x value."""
    assert math.isnan(richardson(1.0, (1.1,), 0.95, known=2.0, observe=False).error)
    q = richardson(1.0, (1.3,), 9.0, known=2.0, observe=False)
    assert not q.observed and q.order == 2.0 and q.error == pytest.approx(0.1, rel=1e-12)


def test_a_difference_within_the_alignments_spread_takes_the_known_order():
    """The 2x grids' mean 50 from the fine value, their spread +-650 (runs/hertz.toml's peak pressure): d1
    is noise, so would be the order from the 4x grid (5.9 here): the known order bounds (50 + 650) / 3."""
    q = richardson(379420.0, (378719.0, 380020.0), 376433.0, known=2.0)
    assert not q.observed and not q.checked and q.order == 2.0
    assert q.error == pytest.approx((abs(0.5 * (378719 + 380020) - 379420) + 650.5) / 3, rel=1e-12)


def test_values_that_agree_to_round_off_have_no_error():
    """mu_r of a symmetric contact, 0 on the fine grid and round-off on the coarser ones (runs/hertz.toml:
    1.8e-18 and 0 on its 2x grids): an error of 0, not a sign change between round-offs."""
    for twice, four in (((1.8e-18, 0.0), 0.0), ((1.8e-18,), -5e-19)):
        q = richardson(0.0, twice, four, known=2.0, round_off=1e-15)
        assert q.error == 0 and q.extrapolated == 0 and q.checked  # nothing assumed
    assert math.isnan(richardson(0.0, (1.8e-18,), -5e-19, known=2.0).error)  # without: a false alarm


def test_what_counts_cells_is_bounded_not_extrapolated():
    q = quantised(0.5, (0.6, 0.45), floor=0.01)
    assert q.extrapolated == 0.5 and q.error == pytest.approx(0.1) and q.checked
    assert quantised(0.5, (0.5,), floor=0.01).error == 0.01


# -- the run ---------------------------------------------------------------------------------------------
def roller():
    return load_scene(shipped_scene("roller-2d.toml"))


@pytest.mark.slow
def test_a_run_with_its_estimate_writes_the_group_and_the_summary_lines(comm, shared_dir, cli_main):
    """runs/roller-2d.toml with --estimate-error: results.h5's group error_estimate holds, per quantity, the
    fine value (the series' last), the coarser grids' values (the same scenes run on their own: 92 and 46
    strips to the fine run's last time), and Richardson's extrapolation and error from them with the
    known order; the command prints them, one line each."""
    scene = roller()
    results = petroll.run(scene, comm, out=shared_dir / "api", estimate_error=True)
    found = results.error_estimate
    assert [tuple(g) for g in found[""]["grids"]] == [(184, 1), (92, 1), (46, 1)]
    assert found[""]["failed"] == ""
    assert found[""]["integrator"] == "relaxation"
    assert [found[name]["known_order"] for name in ("delta", "mu_r", "p_max", "area")] == [2.0, 2.0, 2.0, 1.0]
    assert found[""]["range_checked"] and found[""]["range_unchecked"] == ""
    t_end = float(results.series["t"][-1])
    twice, four = (list(Simulation(coarser(scene, k, t_end), comm).steps())[-1] for k in (2, 4))
    assert twice.t == pytest.approx(t_end, rel=1e-12) and four.t == pytest.approx(t_end, rel=1e-12)
    for name in ("force", "delta", "mu_r", "p_max", "area", "lead", "trail"):
        q = found[name]
        assert q["value"] == results.series[name][-1]
        assert q["coarse"][0] == pytest.approx(getattr(twice, name), rel=1e-9, abs=1e-15)
        if name in ("area", "lead", "trail"):
            expected = quantised(q["value"], (getattr(twice, name),), 0.5 * scene.grid.dx)
        else:
            assert q["coarse"][1] == pytest.approx(getattr(four, name), rel=1e-9, abs=1e-15)
            expected = richardson(q["value"], (getattr(twice, name),), getattr(four, name), 2.0,
                                  observe=False)
        assert q["error"] == pytest.approx(expected.error, rel=1e-6, abs=1e-12 * abs(q["value"]))
        assert q["extrapolated"] == pytest.approx(expected.extrapolated, rel=1e-9)
    if comm.rank == 0:
        (shared_dir / "roller.toml").write_text(scene.text)
    comm.Barrier()
    code, out, _ = cli_main(["run", str(shared_dir / "roller.toml"), "--out", str(shared_dir / "cli"),
                               "--quiet", "--estimate-error"])
    assert code == 0
    if comm.rank == 0:
        mu = found["mu_r"]
        assert f"\n  mu_r {mu['value']:.4e} +- {mu['error']:.1e} (discretisation)\n" in out
        assert ('error estimate of the last step (grids 184 x 1, 92 x 1, 46 x 1; integrator "relaxation": '
                'order 2, 1 for what counts cells, unless observed):\n  force') in out  # range checked


def test_the_known_order_follows_the_integrator(comm, shared_dir):
    """1 for "paper" (a Prony series or a tabulated J, a transient or a steady solve) where the step follows
    the cell, its peak pressure 1.5; 2 for "relaxation" and "exponential", for a fixed dt (the same time
    error on every grid) and for an elastic material (no memory)."""
    from petroll.bench.accuracy import tabulated

    second = {"force": 2.0, "delta": 2.0, "mu_r": 2.0, "p_max": 2.0}
    first = {"force": 1.0, "delta": 1.0, "mu_r": 1.0, "p_max": 1.5}
    base = roller()
    paper = base.replace({"solver.integrator": "paper"})
    steady = load_scene(shipped_scene("master-curve.toml"))
    assert steady.time.mode is TimeMode.STEADY and steady.time.dt is None
    for name in ("relaxation", "exponential"):
        assert known_order(base.replace({"solver.integrator": name})) == second
    assert known_order(paper) == first and known_order(tabulated(base, shared_dir, comm)) == first
    assert known_order(steady.replace({"solver.integrator": "paper"})) == first
    assert known_order(steady) == second
    assert known_order(paper.replace({"time.steps_per_cell": None, "time.dt": 0.005})) == second
    elastic = {"material.model": "elastic", "material.E": 1e7, "material.E0": None, "material.Einf": None,
               "material.tau_relax": None}
    assert known_order(paper.replace(elastic)) == second


@pytest.mark.slow
def test_for_the_paper_integrator_the_estimate_is_within_3_of_the_true_error(comm):
    """runs/roller-2d.toml with the first-order "paper" integrator (that of tabulated materials) against a
    reference 8x finer (1472 strips, 8x the steps): the penetration's and mu_r's estimates within a factor
    1.5 of their true errors (1.22 and 1.15; with the order 2 taken before, 0.41 and 0.38), extrapolated
    closer; the peak pressure's with its order 1.5 within 3 (1.9; with 1, 3.4). The 4x grid is refused
    (its step beyond the scheme's stability limit): the range is not checked, and the estimate says so."""
    scene = roller().replace({"solver.integrator": "paper"})
    checks, found = verify(scene, comm, reference=8.0)
    assert found.failed is None and found.orders["mu_r"] == 1.0 and len(found.grids) == 2
    assert not found.range_checked and found.unchecked.startswith("the grid 4x coarser (46 x 1) failed: ")
    by = {c.name: c for c in checks}
    for name in ("delta", "mu_r"):
        c = by[name]
        assert c.true / 1.5 <= c.estimated <= 1.5 * c.true and c.closer, c
        assert not found.quantities[name].checked
        assert c.estimated / 3 < c.true / 1.5  # what order 2 gives: more than 1.5x too small
    assert by["p_max"].within_3 and found.orders["p_max"] == 1.5, by["p_max"]
    assert by["p_max"].estimated * (2**1.5 - 1) > 3 * by["p_max"].true  # what order 1 gives: above 3x


def test_a_two_grid_estimate_says_its_asymptotic_range_was_not_checked(comm, shared_dir, cli_main):
    """runs/sphere.toml (3-D, 11.9 cells per contact half-width: no 4x grid, which would keep 3.0) with
    --estimate-error: results.h5's group error_estimate says that the range was not checked and why, and
    each extrapolated quantity is marked; ``petroll run`` prints it in a line of its own and on each
    quantity's line, ``petroll info`` likewise."""
    scene = load_scene(shipped_scene("sphere.toml"))
    if comm.rank == 0:
        (shared_dir / "sphere.toml").write_text(scene.text)
    comm.Barrier()
    out = shared_dir / "sphere"
    code, printed, err = cli_main(["run", str(shared_dir / "sphere.toml"), "--out", str(out), "--quiet",
                                   "--estimate-error"])
    assert code == 0, err
    found = petroll.Results.open(out / "results.h5").error_estimate
    group = found[""]
    assert len(group["grids"]) == 3 and not group["range_checked"]
    note = "no grid 4x coarser: it would keep 3.0 cells per contact half-width, 4 needed"
    assert group["range_unchecked"] == note and found["mu_r"]["known_order"] == 2.0
    for name in ("force", "mu_r", "p_max"):
        assert not found[name]["range_checked"] and math.isfinite(found[name]["error"])
    for name in ("area", "lead", "trail"):
        assert found[name]["range_checked"]
    lines = [f"  the asymptotic range was not checked ({note}): the errors assume the orders above "
             "(docs/accuracy.md)"]
    for name in ("force", "mu_r", "p_max"):
        q = found[name]
        lines.append(f"  {name} {q['value']:.4e} +- {q['error']:.1e} (discretisation, asymptotic range not "
                     "checked)")
    area = found["area"]
    lines.append(f"  area {area['value']:.4e} +- {area['error']:.1e} (discretisation)")
    if comm.rank == 0:
        assert "\n".join(lines) in printed
    code, info, err = cli_main(["info", str(out)])
    assert code == 0, err
    if comm.rank == 0:
        assert "\n".join("  " + line for line in lines) in info
        assert ('\n  error estimate of the last step (grids 160 x 54, 81 x 28, 81 x 27; integrator '
                '"relaxation": order 2, 1 for what counts cells, unless observed):\n') in info


@pytest.mark.slow
def test_a_restart_with_the_estimate_gives_the_uninterrupted_runs(comm, shared_dir, cli_main):
    """``petroll restart --estimate-error`` from a checkpoint halfway through runs/roller-2d.toml writes the
    error_estimate group of the same run made in one go with its estimate."""
    scene = roller().replace({"output.checkpoint_every": 10, "output.keep": 100})
    whole = petroll.run(scene, comm, out=shared_dir / "whole", estimate_error=True).error_estimate
    steps = len(petroll.Results.open(shared_dir / "whole" / "results.h5").series["t"])
    halfway = shared_dir / "whole" / "checkpoints" / f"step-{10 * (steps // 20):08d}.h5"
    code, _, err = cli_main(["restart", str(halfway), "--out", str(shared_dir / "again"), "--quiet",
                             "--estimate-error"])
    assert code == 0, err
    again = petroll.Results.open(shared_dir / "again" / "results.h5").error_estimate
    assert [tuple(g) for g in again[""]["grids"]] == [tuple(g) for g in whole[""]["grids"]]
    for name in ("force", "delta", "mu_r", "p_max", "area", "lead", "trail"):
        for key in ("value", "extrapolated", "error"):
            assert again[name][key] == pytest.approx(whole[name][key], rel=1e-9, abs=1e-15), (name, key)


@pytest.mark.slow
def test_where_the_4x_grid_resolves_the_contact_its_order_is_observed(comm, shared_dir):
    """runs/roller-2d.toml at 2x its strips (17.5 cells per half-width; the 4x grid 4.4): the penetration's,
    mu_r's and the peak pressure's orders are observed, log2(d2 / d1) from the coarser grids' values,
    within a factor 2 of 2; the summary line states them."""
    from petroll.cli import estimate_lines
    from petroll.bench.accuracy import refined

    results = petroll.run(refined(roller(), 2, None), comm, out=shared_dir / "fine", estimate_error=True)
    found = results.error_estimate
    assert [tuple(g) for g in found[""]["grids"]] == [(368, 1), (184, 1), (92, 1)]
    for name in ("delta", "mu_r", "p_max"):
        q = found[name]
        (f2, f4), f1 = q["coarse"], q["value"]
        assert q["observed_order"] and q["order"] == pytest.approx(math.log2((f4 - f2) / (f2 - f1)), rel=1e-9)
        assert 1 <= q["order"] <= 4
        line = f"+- {q['error']:.1e} (discretisation, observed order {q['order']:.2f})"
        assert line in "\n".join(estimate_lines(found))


def test_the_coarser_3d_grids_keep_the_body_at_the_same_place_in_its_cell():
    """runs/sphere.toml: on the 2x and 4x grids (and the 2x grid shifted by half its cell) the body starts
    at the same fraction of a cell from a cell centre as on the fine grid (plus the half cell), and the
    grids cover the fine grid's extent."""
    scene = load_scene(shipped_scene("sphere.toml"))
    g, (sx, sy) = scene.grid, scene.position
    fine = ((sx - g.x0) / g.dx - 0.5) % 1.0, ((sy - g.y0) / g.dy - 0.5) % 1.0  # past a cell centre
    for factor, shift in ((2, 0.0), (4, 0.0), (2, 0.5)):
        c = coarser(scene, factor, 0.1, shift).grid
        assert c.dx == pytest.approx(factor * g.dx, rel=1e-12)
        assert c.dy == pytest.approx(factor * g.dy, rel=1e-12)
        assert c.x0 <= g.x0 + 1e-12 and c.x1 >= g.x1 - 1e-12 and c.y0 <= g.y0 + 1e-12 and c.y1 >= g.y1 - 1e-12
        phase = ((sx - c.x0) / c.dx - 0.5 - shift) % 1.0, ((sy - c.y0) / c.dy - 0.5 - shift) % 1.0
        for a, b in zip(phase, fine):
            assert math.isclose(a, b, abs_tol=1e-9) or abs(abs(a - b) - 1) < 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("name, velocity", [("sphere.toml", None), ("roller-2d.toml", None),
                                            ("master-curve.toml", 10.0)])
def test_the_coarser_grids_tolerance_moves_them_little_against_their_differences(comm, monkeypatch, name,
                                                                                velocity):
    """The estimate with its coarser grids solved to coarse_tol, against the same grids solved to 1e-10
    (a second, tight solve): their values within 2 % of their difference from the fine value, the
    estimated errors and extrapolated values within 2 % of that difference (penetration control in 3-D at
    two alignments; load control in line contact with the 4x grid; a steady solve at V tau/a = 1000, whose
    fixed point stops at the solver's tolerance too: at 1e-5 its coarser grids' peak pressure moved 23 % of
    their difference)."""
    import numpy as np

    import petroll.studies.estimate as estimate

    scene = load_scene(shipped_scene(name))
    if velocity is not None:
        scene = scene.replace({"motion.velocity": [velocity, 0.0]})
    fine = list(Simulation(scene, comm).steps())[-1]
    found = estimate.estimate_error(scene, fine, comm)
    monkeypatch.setattr(estimate, "coarse_tol", lambda tol, steady=False: 1e-10)
    tight = estimate.estimate_error(scene, fine, comm)
    names = ("force", "mu_r", "p_max") if scene.penetration is not None else ("delta", "mu_r", "p_max")
    for q in names:
        a, b = found.quantities[q], tight.quantities[q]
        d1 = abs(float(np.mean(b.coarse[: 1 if scene.grid.line else 2])) - b.value)  # the 2x grids'
        assert d1 > 1e-5 * abs(b.value)  # differences well above round-off
        assert np.max(np.abs(np.subtract(a.coarse, b.coarse))) <= 0.02 * d1, q
        assert abs(a.error - b.error) <= 0.02 * d1 and abs(a.extrapolated - b.extrapolated) <= 0.02 * d1, q


@pytest.mark.slow
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
def assert_verified(checks, not_asymptotic=()):
    """force (penetration under load control), mu_r and p_max: the estimate within a factor 3 of the true
    error and the extrapolated value nearer the reference than the fine one, except ``not_asymptotic``,
    reported with no bound where a two-grid bound would have been false; the cell-counted area and patch
    edges: the estimate bounds the true error."""
    by = {c.name: c for c in checks}
    for name in ("force", "delta", "mu_r", "p_max"):
        c = by.get(name)
        if c is None or c.true <= 1e-12 * abs(c.reference):  # the controlled one
            continue
        if name in not_asymptotic:
            assert not c.asymptotic, c
        else:
            assert c.within_3 and c.closer, c
    for name in ("area", "lead", "trail"):
        assert by[name].bounds, by[name]


@pytest.mark.slow
def test_on_the_roller_the_estimate_is_within_3_of_the_true_error(comm):
    """runs/roller-2d.toml against a reference 4x finer (736 strips, 4x the steps)."""
    checks, found = verify(roller(), comm)
    assert found.failed is None
    assert_verified(checks)


@pytest.mark.slow
def test_on_a_profile_roller_the_estimate_is_within_3_of_the_true_error(comm, shared_dir):
    """runs/roller-2d.toml with the roller as a 1-D profile (a height map) sampled on the cell centres."""
    checks, found = verify(profile_roller(shared_dir, comm), comm)
    assert found.failed is None
    assert_verified(checks)


@pytest.mark.slow
def test_on_a_layer_the_estimate_says_where_its_grids_are_not_asymptotic(comm):
    """runs/conveyor-idler.toml (a 6 mm layer on a rigid base, 10.8 cells per contact half-width): mu_r is
    estimated within 3; the penetration and the peak pressure are reported as not in the asymptotic range
    (between the 4x and 2x grids their error changes sign: the 2x grid, 5.4 cells per half-width, is
    closer to the fine one than a power law says, and a two-grid bound would be 9x too small for the
    penetration, 6x too large for the peak pressure)."""
    checks, found = verify(load_scene(shipped_scene("conveyor-idler.toml")), comm)
    assert found.failed is None
    assert_verified(checks, not_asymptotic=("delta", "p_max"))
    by = {c.name: c for c in checks}
    for name in ("delta", "p_max"):  # what two grids would have said
        two = richardson(by[name].value, (found.quantities[name].coarse[0],), None, 2.0).error
        assert not by[name].true / 3 <= two <= 3 * by[name].true


@pytest.mark.slow
def test_on_the_sphere_the_estimate_is_within_3_of_the_true_error(comm):
    """runs/sphere.toml (3-D; two 2x alignments) against a reference 4x finer (640 x 216 cells)."""
    checks, found = verify(load_scene(shipped_scene("sphere.toml")), comm)
    assert found.failed is None and len(found.grids) == 3  # the fine grid, the 2x grid at two alignments
    assert_verified(checks)


def test_the_cost_bench_times_the_run_and_its_estimate_as_results_h5_records_them(comm, shared_dir):
    """petroll bench estimate's measure on runs/roller-2d.toml: the run's and the estimate's wall times as
    results.h5 records them, and their ratio."""
    from petroll.bench.accuracy import cost

    found = cost(roller(), shared_dir / "cost", comm, repeats=1)
    group = petroll.Results.open(shared_dir / "cost" / "results.h5").error_estimate[""]
    assert found["fine_s"] == group["run_wall_s"] > 0 and found["estimate_s"] == group["wall_s"] > 0
    assert found["ratio"] == pytest.approx(found["estimate_s"] / found["fine_s"], rel=1e-12)


@pytest.mark.slow
def test_the_run_s_wall_time_leaves_its_estimate_out(comm, shared_dir, monkeypatch):
    """results.h5's run_wall_s is the run's alone: an estimate made to last 1 s longer (a pause before the
    real one) leaves it at least 1 s below the whole call's wall time."""
    import time

    import petroll.studies.estimate as estimate

    real = estimate.estimate_error

    def slow(*args, **kwargs):
        time.sleep(1.0)
        return real(*args, **kwargs)

    monkeypatch.setattr(estimate, "estimate_error", slow)
    began = time.perf_counter()
    results = petroll.run(roller(), comm, shared_dir / "slow", estimate_error=True)
    elapsed = comm.allreduce(time.perf_counter() - began, op=MPI.MAX)
    assert 0 < results.error_estimate[""]["run_wall_s"] <= elapsed - 1.0


@pytest.mark.slow
def test_a_steady_sliding_friction_s_error_holds_its_difference_from_the_lateral_force_s(comm, shared_dir):
    """runs/rough-rubber.toml on 32^2 cells (its cut-off at 4 cells as shipped) with its estimate: mu_r's
    error includes the fine grid's |mu_r - mu_lateral| (attribute lateral_difference, the printed line),
    mu_lateral being results.h5's rough/mu_lateral; the other quantities carry none; the run's summary
    gives both."""
    from petroll.cli import estimate_lines

    scene = load_scene(shipped_scene("rough-rubber.toml"))
    scene = scene.replace({"grid.nx": 32, "grid.ny": 32, "body.cutoff": 4 * scene.grid.dx * 256 / 32})
    results = petroll.run(scene, comm, out=shared_dir / "rough", estimate_error=True)
    mu, lateral = results.series["mu_r"][-1], results.rough["mu_lateral"][-1]
    q = results.error_estimate["mu_r"]
    assert q["lateral_difference"] == pytest.approx(abs(mu - lateral), rel=1e-12)
    assert q["lateral_difference"] > 1e-4 * mu and q["error"] >= q["lateral_difference"]
    assert "lateral_difference" not in results.error_estimate["force"]
    line = next(text for text in estimate_lines(results.error_estimate) if text.startswith("  mu_r"))
    assert f"{q['lateral_difference']:.1e} of it |mu_r - mu_lateral|" in line
    from petroll.cli import summary

    text = summary(scene, results, wall=1.0)  # the run's paragraph names both
    assert f"friction mu {mu:.4e} (from the dissipation; the lateral force's {lateral:.4e})" in text


def test_the_lateral_difference_is_added_to_a_sliding_friction_s_error_and_printed():
    """petroll.studies.estimate.with_lateral on a steady sliding record: the error grows by |mu_r -
    (force_x, force_y) . e / force| (e the scene's direction of motion, here along X and Y), an error of nan
    stays nan; as_attributes stores it on mu_r alone and estimate_lines says how much of the error it is."""
    from petroll.cli import estimate_lines
    from petroll.records import StepRecord
    from petroll.studies.estimate import ErrorEstimate, QuantityEstimate, as_attributes, with_lateral

    scene = load_scene(shipped_scene("rough-rubber.toml")).replace({"motion.velocity": [0.006, 0.008]})
    values = dict.fromkeys(StepRecord.__dataclass_fields__, 0)
    fine = StepRecord(**{**values, "force": 2.0, "force_x": 0.05, "force_y": 0.02, "mu_r": 0.04})
    lateral = abs(0.04 - (0.05 * 0.6 + 0.02 * 0.8) / 2.0)  # 0.017
    q = with_lateral(QuantityEstimate(0.04, 0.041, 1e-3, 2.0, False, (0.039,)), fine, scene)
    assert q.lateral == pytest.approx(lateral, rel=1e-12) and q.error == pytest.approx(1e-3 + lateral, rel=1e-12)
    assert math.isnan(with_lateral(QuantityEstimate(0.04, math.nan, math.nan, math.nan, True, (0.03, 0.05)),
                                   fine, scene).error)
    force = QuantityEstimate(2.0, 2.0, 0.0, 2.0, False, (2.0,))
    per, attrs = as_attributes(ErrorEstimate({"force": force, "mu_r": q}, [(32, 32), (16, 16)],
                                             integrator="relaxation", orders={"force": 2.0, "mu_r": 2.0}))
    assert per["mu_r"]["lateral_difference"] == q.lateral and "lateral_difference" not in per["force"]
    lines = estimate_lines({**per, "": attrs})
    assert any(line.startswith("  mu_r 4.0000e-02 +- 1.8e-02 (discretisation") and
               line.endswith(", 1.7e-02 of it |mu_r - mu_lateral|)") for line in lines), lines
    assert not any("mu_lateral" in line for line in lines if line.startswith("  force"))
