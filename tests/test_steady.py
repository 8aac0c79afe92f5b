"""The direct steady rolling solve (Simulation.solve_steady) against closed-form limits (Hertz with J0 and
with Jinf, the slow-rolling mu_r of formulation §7), the transient run rolled to steady state on the same
grid (a second algorithm), mirrored and transposed motion, and rank counts."""

import math

import pytest

from petroll.solver.simulation import Simulation
from test_viscoelastic import J0, JINF, R, TAU, run_series, scene

DELTA = 2e-5
A = math.sqrt(R * DELTA)
N, HALF = 32, 0.8e-3
DX = 2 * HALF / N


def steady(v_tau_a, comm, velocity=(1.0, 0.0), **motion):
    speed = v_tau_a * A / TAU
    v = [speed * velocity[0], speed * velocity[1]]
    sc = scene(half=HALF, n=N, motion={"velocity": v, **(motion or {"penetration": DELTA})},
               solver={"tol": 1e-10})
    return Simulation(sc, comm).solve_steady()


def hertz(compliance):
    return 4 * math.sqrt(R) * DELTA**1.5 / (3 * compliance)


def test_fast_rolling_is_hertz_with_j0_and_slow_rolling_hertz_with_jinf(comm):
    fast, slow = steady(1e4, comm), steady(1e-4, comm)
    assert fast.force == pytest.approx(hertz(J0), rel=2e-3)  # the grid's Hertz error (a/dx = 9)
    assert slow.force == pytest.approx(hertz(JINF), rel=2e-3)
    assert abs(fast.mu_r) < 2e-5 and 0 < slow.mu_r < 1e-5


def test_slow_rolling_resistance_is_v_tau_dJ_over_R(comm):
    r = steady(1e-2, comm)
    expected = 1e-2 * A * (1 - J0 / JINF) / R  # formulation §7
    assert r.mu_r == pytest.approx(expected, rel=0.08)  # the grid's (a/dx = 9) shift error


@pytest.mark.parametrize("velocity", [(-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)])
def test_every_direction_of_motion_gives_the_same_steady_state(velocity, comm):
    ref, other = steady(1.0, comm), steady(1.0, comm, velocity)
    assert other.force == pytest.approx(ref.force, rel=1e-9)
    assert other.mu_r == pytest.approx(ref.mu_r, rel=1e-7)
    lead = other.cop_x * velocity[0] + other.cop_y * velocity[1]
    assert lead == pytest.approx(ref.cop_x, rel=1e-7)


def test_load_control_meets_displacement_control(comm):
    by_delta = steady(1.0, comm)
    by_load = steady(1.0, comm, load=by_delta.force)
    assert by_load.force == pytest.approx(by_delta.force, rel=1e-8)
    assert by_load.delta == pytest.approx(DELTA, rel=1e-6)
    assert by_load.mu_r == pytest.approx(by_delta.mu_r, rel=1e-6)


PRONY = {"model": "prony", "series": "kelvin", "Einf": 2e6, "nu": 0.5, "compliances": [1e-7, 1.5e-7, 1e-7],
         "times": [0.0005, 0.005, 0.05]}  # 3 terms over two decades around TAU


@pytest.mark.parametrize("v_tau_a, rolled_a, sign, load, material, integrator", [
    (0.01, 8, 1, None, None, "relaxation"),
    (1.0, 16, 1, None, None, "relaxation"),
    (1.0, 16, -1, None, None, "relaxation"),
    (1.0, 16, 1, 0.0384, None, "relaxation"),
    (0.01, 8, 1, 0.03, None, "relaxation"),
    (1.0, 24, 1, None, PRONY, "relaxation"),
    (1.0, 16, 1, None, None, "exponential"),
])
def test_the_long_transient_converges_to_the_direct_steady_state(v_tau_a, rolled_a, sign, load, material,
                                                                  integrator, comm):
    """The transient run at one step per cell (square cells), rolled 8-24 a, against the direct solve of
    the same grid and integrator with the body where the run ended: the direct solve is the exact fixed
    point of the run's scheme, so they agree to the QPs' tolerance (measured 1e-11 ... 1.5e-9; the
    steady solve's previous continuous-time memory differed from this run by 1.3e-4 in force and
    0.5 % in mu_r at V tau/a = 1)."""
    speed = v_tau_a * A / TAU
    length = round(rolled_a * A / DX) * DX
    motion = {"velocity": [sign * speed, 0.0], **({"load": load} if load else {"penetration": DELTA})}
    sc = scene(half=HALF, n=N, motion=motion, time={"steps_per_cell": 1, "distance": length}, length=length,
               solver={"tol": 1e-10, "history_cutoff": 0.0, "integrator": integrator}, **(material or {}))
    if sign < 0:
        sc = sc.replace("body.position", [length, 0.0])
    rolled = run_series(sc, comm).records[-1]
    still = sc.replace({"time.distance": None, "time.mode": "steady", "body.position": [rolled.sx, rolled.sy]})
    direct = Simulation(still, comm).solve_steady(tol=1e-10)
    assert direct.force == pytest.approx(rolled.force, rel=1e-7)
    assert direct.mu_r == pytest.approx(rolled.mu_r, rel=1e-7)
    assert direct.delta == pytest.approx(rolled.delta, rel=1e-7)
    assert abs(direct.mu_r) > 3e-4


# -- [time] mode = "steady": the scene key, the run, results.h5 -------------------------------------------
RAW = {
    "grid": {"nx": 32, "ny": 32, "x": [-0.8e-3, 0.8e-3], "y": [-0.8e-3, 0.8e-3]},
    "material": {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
    "body": {"shape": "sphere", "radius": 0.01},
    "motion": {"velocity": [0.01, 0.0], "penetration": 2e-5},
    "time": {"mode": "steady"},
    "solver": {"tol": 1e-10},
    "output": {"fields": ["pressure", "displacement", "gap"]},
}


def test_a_steady_scene_runs_as_one_step_with_the_series_and_fields_of_a_run(comm, api_and_cli):
    """petroll run and petroll.run: results.h5 holds step 0 at t = 0, attribute steady = true, every series
    and the saved fields; the values are those of Simulation.solve_steady, the gap is >= 0 and 0 under
    pressure (to the tolerance), and the steady values report no change."""
    import h5py
    import numpy as np

    import petroll
    from petroll.io.results import SERIES_UNITS

    api, cli, out = api_and_cli(RAW)
    if comm.rank == 0:
        assert "the steady state solved directly" in out
    scene = petroll.parse_scene(RAW)
    direct = Simulation(scene, comm).solve_steady(tol=1e-10)
    for results in (api, cli):
        s = results.series
        assert set(s) == set(SERIES_UNITS)
        assert list(s["step"]) == [0] and list(s["t"]) == [0.0] and list(results.field_steps) == [0]
        assert results.solved_steady and results.fields == ("pressure", "displacement", "gap")
        for name in ("force", "mu_r", "force_x", "area", "p_max", "lead", "trail", "dissipation", "cop_x"):
            assert s[name][0] == pytest.approx(getattr(direct, name), rel=1e-9), name
        assert s["applications"][0] > 0 and s["iterations"][0] > 0 and s["solve_time"][0] > 0
        p, gap = results.pressure[0], results.field("gap")[0]
        assert p.sum() * (1.6e-3 / 32) ** 2 == pytest.approx(s["force"][0], rel=1e-12)
        assert gap.min() > -1e-9 * 2e-5 and np.abs(gap[p > 0]).max() < 1e-8 * 2e-5
        st = results.steady
        assert st.reached and st.force_change == 0 and st.mu_r_change == 0 and st.force == s["force"][0]
        with h5py.File(results.path, "r") as f:
            assert f.attrs["steady"] and f.attrs["complete"] and f.attrs["steps_written"] == 1
    assert np.array_equal(api.pressure, cli.pressure)
    assert api.series["mu_r"][0] > 0.01


def test_a_steady_run_on_two_ranks_is_the_one_rank_run(comm, tmp_path, shared_dir):
    """The rows split over ``comm`` (2 ranks under mpirun) against every rank's own COMM_SELF run."""
    import numpy as np

    import petroll
    from mpi4py import MPI

    scene = petroll.parse_scene({**RAW, "motion": {"velocity": [0.0, -0.01], "load": 0.04}})
    both = petroll.run(scene, comm, out=shared_dir / "both")
    alone = petroll.run(scene, MPI.COMM_SELF, out=tmp_path / f"alone-{comm.rank}")
    for name in ("force", "mu_r", "delta", "force_y", "p_max", "area", "lead", "trail"):
        assert both.series[name][0] == pytest.approx(alone.series[name][0], rel=1e-9, abs=1e-18), name
    assert np.allclose(both.pressure, alone.pressure, rtol=0, atol=1e-8 * alone.pressure.max())
    assert both.field("displacement") == pytest.approx(alone.field("displacement"), rel=1e-9)


@pytest.mark.serial  # the one line is printed by rank 0 (test_bad_input checks that under mpirun)
@pytest.mark.parametrize("changes, key", [
    ({"motion.velocity": {"kind": "ramp", "start": [0.0, 0.0], "end": [0.01, 0.0], "duration": 1.0}},
     "[motion] velocity"),
    ({"motion.velocity": [0.01, 0.01]}, "[motion] velocity"),
    ({"motion.velocity": [0.0, 0.0]}, "[motion] velocity"),
    ({"motion.velocity": None}, "[motion] velocity"),
    ({"motion.penetration": {"kind": "sinusoidal", "mean": 2e-5, "amplitude": 1e-6, "period": 1.0}},
     "[motion] penetration"),
    ({"motion.penetration": None, "motion.load": {"kind": "ramp", "start": 0.0, "end": 0.04, "duration": 1.0}},
     "[motion] load"),
    ({"time.distance": 1e-3}, "[time] distance"),
    ({"time.steady": 1e-3}, "[time] steady"),
    ({"time.mode": "stationary"}, "[time] mode"),
    ({"material.model": "tabulated", "material.E0": None, "material.Einf": None, "material.tau_relax": None,
      "material.file": "j.csv", "material.quantity": "J"}, "[material] model"),
])
def test_a_steady_scene_that_is_not_steady_is_refused_with_one_line(changes, key, tmp_path, capsys):
    """Through the command line: exit code 2, one line naming the key and the value, no traceback, and no
    results written."""
    from petroll.cli import main
    from petroll.model.scene import dumps

    raw = {section: dict(table) for section, table in RAW.items()}
    for name, value in changes.items():
        section, _, k = name.partition(".")
        if value is None:
            raw[section].pop(k, None)
        else:
            raw[section][k] = value
    (tmp_path / "j.csv").write_text("0,5e-8\n0.01,1e-7\n1,3.75e-7\n")
    (tmp_path / "s.toml").write_text(dumps(raw), encoding="utf-8")
    capsys.readouterr()
    try:
        code = main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--quiet"])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert key in lines[0] and "s.toml" in lines[0], lines[0]
    assert not (tmp_path / "out" / "results.h5").exists()


@pytest.mark.parametrize("v_tau_a", [1.0, 10.0])
def test_the_far_wake_in_blocks_is_the_wake_on_a_long_grid(v_tau_a, comm):
    """A 16 x 16 window: the wake from 64 cells (14 a) to 30 V tau behind is lumped in geometric blocks
    (FarWake). Oracle: the same solve on a grid extended 30 V tau behind the body, where the whole wake is
    convolved cell by cell. Measured: 4.1e-6 (force), 1.2e-6 (mu_r) at V tau/a = 10;
    7e-12 at V tau/a = 1."""
    speed, n, half = v_tau_a * A / TAU, 16, HALF
    cell = 2 * half / n
    motion = {"velocity": [speed, 0.0], "penetration": DELTA}
    window = Simulation(scene(half=half, n=n, motion=motion, time={"mode": "steady"}, solver={"tol": 1e-10}),
                        comm).solve_steady(tol=1e-10)
    behind = math.ceil(30 * speed * TAU / cell)
    long = scene(half=half, n=n, motion=motion, time={"mode": "steady"}, solver={"tol": 1e-10})
    long = long.replace({"grid.nx": n + behind, "grid.x": [-half - behind * cell, half]})
    whole = Simulation(long, comm).solve_steady(tol=1e-10)
    assert window.force == pytest.approx(whole.force, rel=1e-5)
    assert window.mu_r == pytest.approx(whole.mu_r, rel=1e-5)
    assert window.mu_r > 5e-3


def test_anderson_solves_a_linear_fixed_point_and_survives_repeated_residuals():
    """Anderson mixing of x = B x + c (B a contraction) reaches the solution of (I - B) x = c (numpy's
    solve, the oracle) within depth + 2 steps in exact arithmetic; a step whose residual repeats the last
    one (a singular least-squares problem: the difference is zero) gives a finite iterate, not an error."""
    import numpy as np

    from petroll.solver.steady import Anderson

    rng = np.random.default_rng(3)
    B = 0.5 * rng.standard_normal((5, 5)) / math.sqrt(5)
    c = rng.standard_normal(5)
    exact = np.linalg.solve(np.eye(5) - B, c)
    mixer, x = Anderson(depth=6), np.zeros(5)
    for _ in range(8):
        x = mixer.next(x, B @ x + c)
    assert np.abs(x - exact).max() < 1e-10 * np.abs(exact).max()
    repeated = Anderson(depth=1)  # the last two residuals alone: both zero below
    y = repeated.next(np.zeros(3), np.ones(3))
    z = repeated.next(y, y)  # converged: residual 0
    w = repeated.next(z, z)  # residual 0 again: the difference of residuals is zero
    assert np.array_equal(w, np.ones(3)) and np.array_equal(z, np.ones(3))


@pytest.mark.parametrize("axis, sign", [(0, 1), (0, -1), (1, 1), (1, -1)])
def test_the_memory_restricted_to_the_contact_is_inverted_exactly(axis, sign):
    """SteadyMemory.solve_restricted against numpy's dense solve of W's principal submatrix on a set of
    cells, contiguous along the motion on some lines (a patch), scattered on others (W's columns from the
    FFT correlation, __call__: an independent path), the field kept off the set."""
    import numpy as np

    from petroll.solver.steady import SteadyMemory
    from test_viscoelastic import scene as make_scene

    material = make_scene(half=HALF, n=N, motion={"velocity": [1e-3, 0.0], "penetration": DELTA}).material
    shape = (12, 7) if axis == 0 else (7, 12)
    memory = SteadyMemory(material, "relaxation", 0.02, 1.0, 1.0, axis, sign, 40)
    columns = np.stack([memory(e.reshape(shape)).ravel() for e in np.eye(math.prod(shape))], axis=1)
    rng = np.random.default_rng(5)
    along = rng.random((12, 7)) < 0.6  # (along the motion, across): lines 0-3 a patch, 4-6 scattered
    along[:, :4] = False
    along[3:9, :4] = True
    along[2:11, 2] = True
    on = along if axis == 0 else along.T
    f = rng.standard_normal(shape)
    cells = np.flatnonzero(on)
    expected = f.ravel().copy()
    expected[cells] = np.linalg.solve(columns[np.ix_(cells, cells)], f.ravel()[cells])
    got = memory.solve_restricted(f, on).ravel()
    assert np.abs(got - expected).max() <= 1e-9 * np.abs(expected).max()


def test_a_failed_qp_inside_the_steady_solve_leaves_the_solver_as_it_was(comm):
    """The fixed point loosens the QPs' tolerance while its memory still moves; a QP that fails (here the
    second one, after the tolerance was loosened) raises its SolverError and leaves the solver's tolerance
    at the scene's, as does running out of iterations."""
    from petroll.errors import SolverError

    speed = A / TAU
    sc = scene(half=HALF, n=N, motion={"velocity": [speed, 0.0], "penetration": DELTA}, solver={"tol": 1e-10})
    sim = Simulation(sc, comm)
    solve, seen = sim.solver.solve_penetration, []

    def failing(*args, **kwargs):
        seen.append(sim.solver.tol)
        if len(seen) == 2:
            raise SolverError("TAO did not converge (a test's failure)")
        return solve(*args, **kwargs)

    sim.solver.solve_penetration = failing
    with pytest.raises(SolverError, match="a test's failure"):
        sim.solve_steady(tol=1e-10)
    assert len(seen) == 2 and seen[1] > 1e-10 and sim.solver.tol == 1e-10
    sim.solver.solve_penetration = solve
    with pytest.raises(SolverError, match="did not converge within 2 iterations"):
        sim.solve_steady(tol=1e-10, max_iterations=2)
    assert sim.solver.tol == 1e-10
