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


def test_the_transient_run_rolls_into_the_direct_steady_state(comm):
    """V tau / a = 1 rolled 8 V tau at 4 steps per cell. The transient itself moves by 1e-4 in force and
    5e-3 in mu_r between 4 and 16 steps per cell (sub-cell body positions vs the steady solve's linear
    interpolation along the motion), which bounds the agreement on this grid."""
    speed = A / TAU
    length = round(8 * A / DX) * DX
    rolled = run_series(scene(half=HALF, n=N, motion={"velocity": [speed, 0.0], "penetration": DELTA},
                              time={"steps_per_cell": 4, "distance": length}, length=length,
                              solver={"tol": 1e-10}), comm).records[-1]
    direct = steady(1.0, comm)
    assert direct.force == pytest.approx(rolled.force, rel=3e-4)
    assert direct.mu_r == pytest.approx(rolled.mu_r, rel=8e-3)
    assert direct.mu_r > 0.01
