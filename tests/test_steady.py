"""The direct steady rolling solve (Simulation.solve_steady) against closed-form limits (Hertz with J0 and
with Jinf, the slow-rolling mu_r of formulation §7), the transient run rolled to steady state on the same
grid (a second algorithm), mirrored and transposed motion, and rank counts."""

import math

import pytest

from petroll.solver.simulation import Simulation
from compare import assert_close
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


@pytest.mark.parametrize("v_tau_a, dt", [(1e-2, None), (1e-6, 1e-3), (1e-6, 1e-5)])
def test_slow_rolling_resistance_is_v_tau_dJ_over_R(v_tau_a, dt, comm):
    """Slow rolling, with one step per cell or an explicit [time] dt that crosses 2e-7 ... 2e-9 of a cell
    per step (the memory then spans the material's relaxation, not the grid: ceil(cells / c) would be
    5e8 ... 5e10 steps)."""
    time = {"mode": "steady", **({"dt": dt} if dt else {})}
    speed = v_tau_a * A / TAU
    sc = scene(half=HALF, n=N, motion={"velocity": [speed, 0.0], "penetration": DELTA},
               solver={"tol": 1e-10}, time=time)
    r = Simulation(sc, comm).solve_steady()
    expected = v_tau_a * A * (1 - J0 / JINF) / R  # formulation §7
    assert r.mu_r == pytest.approx(expected, rel=0.08)  # the grid's (a/dx = 9) shift error
    assert r.force == pytest.approx(hertz(JINF), rel=2e-3)  # the grid's Hertz error


@pytest.mark.parametrize("integrator, dt", [("relaxation", 1e-4), ("relaxation", 0.01), ("relaxation", 0.2),
                                            ("exponential", 0.01), ("paper", 1e-3)])
def test_the_memory_is_kept_until_the_material_has_relaxed_to_the_tolerance(integrator, dt):
    """memory_steps against the pulse response computed far beyond it: what it drops weighs at most tol of
    the whole (and it keeps no more than about twice what the slowest mode needs: exp(-dt/tau)^S = tol for
    the exponential and paper integrators)."""
    import numpy as np

    from petroll.solver.steady import memory_steps, pulse_response
    from test_viscoelastic import scene as make_scene

    material = make_scene(half=HALF, n=N, motion={"velocity": [1e-3, 0.0], "penetration": DELTA}).material
    for tol in (1e-4, 1e-8, 1e-12):
        kept = memory_steps(material, integrator, dt, tol)
        h = np.abs(pulse_response(material, integrator, dt, 4 * kept + 100))
        assert h[kept:].sum() <= tol * h.sum()
        assert kept <= 2 * math.log(1 / tol) * material.longest_time / dt + 3 or integrator == "relaxation"


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


@pytest.mark.slow
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
    assert_close(api.pressure, cli.pressure, 1e-12, "pressure")
    assert api.series["mu_r"][0] > 0.01


@pytest.mark.parallel
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
    ({"time.dt": 1e-9}, "[time] dt"),  # a memory of 1.4e9 steps of dt
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


def memory_of_the_default_material(n: int, behind: int = 0, v_tau_a: float = 1.0):
    """The memory (petroll.solver.memory.Memory) of the tests' SLS at V tau/a, one step per cell."""
    from petroll.solver.memory import Memory, memory_kernel, pulse_response
    from test_viscoelastic import scene as make_scene

    material = make_scene(half=HALF, n=N, motion={"velocity": [1e-3, 0.0], "penetration": DELTA}).material
    h = pulse_response(material, "relaxation", TAU * DX / (v_tau_a * A), n + behind + 1)
    kernel = memory_kernel(h, 1.0, n + behind)
    return Memory(kernel, n, behind), kernel


def dense_memory(kernel, n: int):
    """W on a line of n cells as a dense matrix, W[t, t + m] = H[m] (upper triangular): the oracle."""
    import numpy as np

    offsets = np.subtract.outer(np.arange(n), np.arange(n))
    return np.where(offsets <= 0, kernel[np.clip(-offsets, 0, n - 1)], 0.0)


def test_the_memory_is_its_dense_toeplitz_matrix_on_the_grid_and_behind_it():
    """Memory.grid and Memory.extended (FFT correlations) against the dense matrix of H on a line of the
    extended grid (the field zero on the ``behind`` cells)."""
    import numpy as np

    n, behind = 23, 17
    memory, kernel = memory_of_the_default_material(n, behind)
    rng = np.random.default_rng(1)
    p = rng.standard_normal((5, n))
    whole = dense_memory(kernel, n + behind)[:, behind:]  # sources on the grid part only
    expected = p @ whole.T
    assert np.abs(memory.extended(p) - expected).max() <= 1e-12 * np.abs(expected).max()
    assert np.abs(memory.grid(p) - expected[:, behind:]).max() <= 1e-12 * np.abs(expected).max()


def test_the_memory_restricted_to_the_contact_is_inverted_exactly():
    """Memory.solve_restricted against numpy's dense solve of W's principal submatrix on a set of cells:
    one segment on some lines, several (up to 5, with single cells) on others, none on one; the field
    kept off the set. W from the kernel directly (dense_memory), not from the FFT."""
    import numpy as np

    n = 40
    memory, kernel = memory_of_the_default_material(n)
    W = dense_memory(kernel, n)
    rng = np.random.default_rng(5)
    on = np.zeros((7, n), dtype=bool)
    on[0, 5:30] = True  # one segment
    on[1, [3, 4, 5, 9, 10, 20, 30, 31, 39]] = True  # five, with single cells, one at the front
    on[2:6] = rng.random((4, n)) < 0.5  # scattered
    f = rng.standard_normal((7, n))
    expected = f.copy()
    for line in range(7):
        cells = np.flatnonzero(on[line])
        if len(cells):
            expected[line, cells] = np.linalg.solve(W[np.ix_(cells, cells)], f[line, cells])
    got = memory.solve_restricted(f, on)
    assert np.abs(got - expected).max() <= 1e-10 * np.abs(expected).max()
    assert np.array_equal(got[6], f[6])


def test_the_reciprocal_series_inverts_the_kernel():
    """inverse_series(h) g: the product series h g is 1, 0, 0, ... (dense convolution, not the FFT)."""
    import numpy as np

    from petroll.solver.memory import inverse_series

    _, kernel = memory_of_the_default_material(300)
    g = inverse_series(kernel, 300)
    product = np.convolve(kernel[:300], g)[:300]
    assert abs(product[0] - 1) < 1e-13 and np.abs(product[1:]).max() < 1e-12


@pytest.mark.ranks4
@pytest.mark.parametrize("axis, sign", [(0, 1), (0, -1), (1, 1), (1, -1)])
def test_lines_hold_whole_lines_along_the_motion_and_give_the_rows_back(axis, sign, comm):
    """Lines on ``comm`` (any rank count): a field known everywhere (value = its global cell index) moved
    from the grid's rows to the lines and back, and to the extended grid's rows; each against the
    indices it must hold."""
    import numpy as np

    from petroll.solver.memory import Lines
    from petroll.solver.partition import RowPartition

    nx, ny, behind = 11, 7, 5
    rows = RowPartition(nx, comm.size)
    r0, r1 = rows.range(comm.rank)
    lines = Lines(rows, ny, axis, sign, behind, comm)
    index = np.arange(nx * ny, dtype=float).reshape(nx, ny)
    got = lines.from_grid(index[r0:r1])
    whole = index if axis == 0 else index.T  # (along, across)
    whole = whole[::-1] if sign < 0 else whole  # t = 0 the rear row
    assert np.array_equal(got, whole[:, lines.a0 : lines.a1].T)
    assert np.array_equal(lines.to_grid(got), index[r0:r1])
    rows_of_extended = lines.to_extended(np.concatenate([np.full((got.shape[0], behind), -1.0), got], axis=1))
    whole_extended = np.concatenate([np.full((behind, whole.shape[1]), -1.0), whole])  # t order
    whole_extended = whole_extended[::-1] if sign < 0 else whole_extended
    whole_extended = whole_extended if axis == 0 else whole_extended.T  # the extended grid's (X, Y)
    e0, e1 = lines.extended_rows.range(comm.rank)
    assert whole_extended.shape == lines.extended
    assert np.array_equal(rows_of_extended, whole_extended[e0:e1])
    assert np.array_equal(lines.inside(rows_of_extended), index[r0:r1])


@pytest.mark.ranks4
@pytest.mark.parametrize("axis, sign", [(0, 1), (1, -1)])
def test_the_far_wake_interpolated_along_the_motion_is_its_direct_sum(axis, sign, comm):
    """FarWake (block means, Chebyshev interpolation along the motion, FFT across, frequencies split over
    the ranks) against the direct double sum over blocks and source lines of the line sources' formula at
    every target cell (no interpolation, no FFT). Measured: 4e-13 with 12 points over 120 rows."""
    import numpy as np

    from petroll.solver.memory import FarWake, Lines
    from petroll.solver.partition import RowPartition

    nx, ny, along, across = (120, 9, 2.0, 1.5) if axis == 0 else (9, 120, 1.5, 2.0)
    near, far = 240, 2400
    memory, kernel = memory_of_the_default_material(120 + near + far, v_tau_a=30.0)  # a wake of 270 a
    rows = RowPartition(nx, comm.size)
    r0, r1 = rows.range(comm.rank)
    lines = Lines(rows, ny, axis, sign, near, comm)
    wake = FarWake(kernel, lines, near, far, along, across)
    rng = np.random.default_rng(2)
    p = rng.random((nx, ny))
    got = wake(lines.from_grid(p[r0:r1]))
    q = p if axis == 0 else p.T  # (along, across), then the rear row first
    q = q[::-1] if sign < 0 else q
    n, m = q.shape
    blocks = wake.mean @ q  # (blocks, across)
    edges = [near + 1]
    while edges[-1] <= near + far:
        edges.append(min(max(edges[-1] + 1, round(edges[-1] * 1.05)), near + far + 1))
    e = np.array(edges)
    u = np.zeros((n, m))
    for k in range(n):
        for b in range(len(e) - 1):
            x1 = (k + e[b] - 0.5) * along
            x2 = x1 + (e[b + 1] - e[b]) * along
            dy = np.subtract.outer(np.arange(m), np.arange(m)) * across
            source = across / np.pi * np.log((x2 + np.hypot(x2, dy)) / (x1 + np.hypot(x1, dy)))
            u[k] += source @ blocks[b]
    u = u[::-1] if sign < 0 else u
    expected = (u if axis == 0 else u.T)[r0:r1]
    assert np.abs(got - expected).max() <= 1e-10 * np.abs(expected).max()


@pytest.mark.ranks4
@pytest.mark.parallel
def test_anderson_on_vectors_split_over_ranks_is_anderson_on_the_whole(comm):
    """The mixing of a linear fixed point x = B x + c split over ``comm`` (each rank its rows, some ranks
    none) against the same mixing of the whole vectors on one rank (COMM_SELF): the same iterates."""
    import numpy as np
    from mpi4py import MPI

    from petroll.solver.partition import RowPartition
    from petroll.solver.steady import Anderson

    n = 9
    rng = np.random.default_rng(4)
    B = 0.5 * rng.standard_normal((n, n)) / 3
    c = rng.standard_normal(n)
    c[5:7] = 0.0
    r0, r1 = RowPartition(n, comm.size).range(comm.rank)
    whole, split = Anderson(MPI.COMM_SELF, depth=3), Anderson(comm, depth=3)
    x, y = np.zeros(n), np.zeros(r1 - r0)
    for _ in range(7):
        x = whole.next(x, B @ x + c)
        full = np.concatenate(comm.allgather(y))
        y = split.next(y, (B @ full + c)[r0:r1])
        assert np.abs(y - x[r0:r1]).max() <= 1e-12 * np.abs(x).max()


@pytest.mark.ranks4
@pytest.mark.parallel
@pytest.mark.parametrize("velocity, motion", [((1.0, 0.0), {"penetration": DELTA}),
                                              ((0.0, -1.0), {"load": 0.03}),
                                              ((-10.0, 0.0), {"penetration": DELTA})])
def test_a_steady_solve_on_any_rank_count_is_the_one_rank_solve(velocity, motion, comm):
    """The rows and lines split over ``comm`` (1, 2 or 4 ranks) against every rank's own COMM_SELF solve:
    force, mu_r, penetration and pressure to 1e-10 (V tau/a = 1 and 10: the far wake in blocks)."""
    import numpy as np
    from mpi4py import MPI

    from petroll.solver.partition import RowPartition

    speed = A / TAU
    sc = scene(half=HALF, n=N, motion={"velocity": [speed * velocity[0], speed * velocity[1]], **motion},
               solver={"tol": 1e-10})
    both, alone = Simulation(sc, comm), Simulation(sc, MPI.COMM_SELF)
    a, b = both.solve_steady(tol=1e-10), alone.solve_steady(tol=1e-10)
    for name in ("force", "mu_r", "delta", "p_max", "area", "lead", "trail"):
        assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-10, abs=1e-30), name
    r0, r1 = RowPartition(N, comm.size).range(comm.rank)
    assert np.abs(both.pressure - alone.pressure[r0:r1]).max() <= 1e-10 * b.p_max
    assert both.fixed_point_iterations == alone.fixed_point_iterations


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


def test_the_fft_tally_counts_every_application_and_correlation_once(comm):
    """petroll.solver.fft_work's tally (what petroll bench steady counts; differences of a growing total, to
    1e-6): a QP without the preconditioner
    adds its applications times one padded window transform pair; the steady memory's correlation adds
    one batch of 1-D pairs over all the lines (whatever the rank count)."""
    import numpy as np

    from petroll.model.bodies import Sphere
    from petroll.model.grid import Grid
    from petroll.solver.contact import ContactSolver
    from petroll.solver.fft_work import FFTWork, fft_cost
    from petroll.solver.influence import Convolution
    from petroll.solver.memory import Lines
    from petroll.solver.partition import RowPartition

    grid = Grid(40, 40, -HALF, HALF, -HALF, HALF)
    solver = ContactSolver(grid, comm, tol=1e-8, precondition=False)
    height = Sphere(R).height(grid.x[solver.r0 : solver.r1, None], grid.y[None, :])
    before = FFTWork.total
    step = solver.solve_penetration(height, JINF, DELTA)
    i0, i1, j0, j1 = step.window
    applied = step.applications * Convolution(None, i1 - i0, j1 - j0).cost
    assert FFTWork.total - before == pytest.approx(applied, rel=1e-6)
    memory, _ = memory_of_the_default_material(40, 9)
    lines = Lines(RowPartition(40, comm.size), 40, 0, 1, 9, comm)
    memory.n_across = 40
    before = FFTWork.total
    memory.extended(lines.from_grid(np.ones(solver.local_shape)))
    assert FFTWork.total - before == pytest.approx(fft_cost(40 * memory.long, memory.long), rel=1e-6)


def test_a_transient_runs_tally_is_every_padded_transform_pair_it_did(comm, monkeypatch):
    """A rolling run's steps (history of the default integrator, preconditioned QPs): the tally equals the
    cost of every forward transform of a convolution the run actually performed (Convolution.forward,
    counted independently of the tally), and there are more of them than the QPs' Hessian applications
    (the preconditioner's and each step's history convolution are counted too)."""
    from petroll.solver.fft_work import FFTWork, fft_cost
    from petroll.solver.influence import Convolution

    done = []
    forward = Convolution.forward

    def counted(self, x, into=None):
        done.append(fft_cost(self.lx * self.ly, self.lx * self.ly))
        return forward(self, x, into)

    monkeypatch.setattr(Convolution, "forward", counted)
    monkeypatch.setattr(FFTWork, "total", 0.0)  # a tally grown by earlier tests would round the difference
    speed = A / TAU
    sc = scene(half=HALF, n=N, length=8 * DX, motion={"velocity": [speed, 0.0], "penetration": DELTA},
               time={"distance": 6 * DX, "steps_per_cell": 1}, solver={"tol": 1e-8})
    before = FFTWork.total
    records = list(Simulation(sc, comm).steps())
    assert FFTWork.total - before == pytest.approx(sum(done), rel=1e-12)
    assert len(done) > sum(r.applications for r in records) + len(records) - 1
