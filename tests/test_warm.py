"""The first guess of a time step (petroll/warm.py) against fields whose next step is known exactly."""

import numpy as np
import pytest
from mpi4py import MPI

import petroll
from petroll.model.grid import Grid
from petroll.solver.partition import RowPartition, shift_field
from petroll.solver.simulation import Simulation
from petroll.solver.warm import WarmStart

GRID = Grid(40, 24, 0.0, 4.0, -1.2, 1.2)  # dx = dy = 0.1


def field(x, y):
    """A smooth patch (Pa) centred at the origin, zero outside radius 0.6."""
    return np.clip(0.36 - x**2 - y**2, 0.0, None) * 1e5


def transient(x, y):
    """A second shape that fades geometrically, also zero outside radius 0.6."""
    return np.clip(0.36 - (x - 0.2) ** 2 - y**2, 0.0, None) * 3e4


def rows_of(comm):
    rows = RowPartition(GRID.nx, comm.size)
    r0, r1 = rows.range(comm.rank)
    return rows, GRID.x[r0:r1, None], GRID.y[None, :]


def moving(x, y, n, step, rho):
    """Step n of a patch moving by ``step`` (m, m) per step with a transient decaying as rho**n."""
    cx, cy = 1.0 + n * step[0], n * step[1]
    return field(x - cx, y - cy) + rho**n * transient(x - cx, y - cy)


@pytest.mark.parametrize("step", [(0.1, 0.0), (0.0, -0.1), (0.2, 0.1), (0.0, 0.0)])
def test_extrapolation_is_exact_for_a_geometric_transient_moving_by_whole_cells(comm, step):
    rows, x, y = rows_of(comm)
    warm = WarmStart(GRID, rows, comm)
    assert warm.guess(1.0, 0.0) is None  # first step: start from p = 0
    rho = 0.6
    for n in range(3):
        warm.record(moving(x, y, n, step, rho), 1.0 + n * step[0], n * step[1])
    guess = warm.guess(1.0 + 3 * step[0], 3 * step[1])
    exact = moving(x, y, 3, step, rho)
    assert comm.allreduce(float(np.abs(guess - exact).max(initial=0.0)), op=MPI.MAX) <= 1e-9 * 1e5
    # with only the newest solution the guess is that one carried along, off by the transient's decay
    single = WarmStart(GRID, rows, comm)
    single.record(moving(x, y, 2, step, rho), 1.0 + 2 * step[0], 2 * step[1])
    carried = single.guess(1.0 + 3 * step[0], 3 * step[1])
    off = comm.allreduce(float(np.abs(carried - exact).max(initial=0.0)), op=MPI.MAX)
    assert off == pytest.approx(rho**2 * (1 - rho) * (0.36 - 2 * 0.05**2) * 3e4, rel=1e-9)  # nearest centres


@pytest.mark.parametrize("lag", [2, 4])
def test_a_body_moving_part_of_a_cell_per_step_extrapolates_every_kth_solution(comm, lag):
    rows, x, y = rows_of(comm)
    warm = WarmStart(GRID, rows, comm)
    step, rho = (0.1 / lag, 0.0), 0.8
    for n in range(3 * lag + 2):  # more than the 3 k solutions kept
        warm.record(moving(x, y, n, step, rho), 1.0 + n * step[0], 0.0)
    assert len(warm.recent) == 3 * lag
    n = 3 * lag + 2
    guess = warm.guess(1.0 + n * step[0], 0.0)
    exact = moving(x, y, n, step, rho)
    assert comm.allreduce(float(np.abs(guess - exact).max(initial=0.0)), op=MPI.MAX) <= 1e-9 * 1e5


def test_a_move_by_part_of_a_cell_carries_the_newest_whole_cell_solution_or_rounds(comm):
    rows, x, y = rows_of(comm)
    warm = WarmStart(GRID, rows, comm)
    p = [moving(x, y, n, (0.05, 0.0), 1.0) for n in range(3)]  # half a cell per step
    for n in range(3):
        warm.record(p[n], 1.0 + 0.05 * n, 0.0)
    # at 1.15 the solution two steps back (at 1.05) is one whole cell away; the newest is half a cell
    assert np.array_equal(warm.guess(1.15, 0.0), shift_field(p[1], 1, 0, rows, comm))
    # at 1.13 none is a whole number of cells away: the newest, moved by round(0.3) = 0 cells
    assert np.array_equal(warm.guess(1.13, 0.0), p[2])


@pytest.mark.slow
def test_rolling_converges_to_the_same_answer_and_cheaper_in_steady_state(comm):
    """The guess changes the cost, not the answer: the default scene (square cells, one cell per step)
    against the same run started every step from the plain carried solution (extrapolation off)."""
    scene = petroll.load_scene("runs/sphere.toml").replace({"time.distance": 2e-3, "time.steady": None})
    plain, extrapolated = [], []
    for records, depth in ((plain, 1), (extrapolated, 3)):
        sim = Simulation(scene, comm)
        sim.warm = WarmStart(scene.grid, sim.solver.rows, comm, depth)
        records.extend(sim.steps())
    forces = np.array([[a.force, b.force] for a, b in zip(plain, extrapolated)])
    assert len(plain) == len(extrapolated) == 55
    assert np.abs(forces[:, 0] / forces[:, 1] - 1).max() < 1e-7  # 10 tol: both solved to tol = 1e-8
    late = slice(len(plain) - 10, None)  # measured: 10.1 against 17.6 applications per step
    assert (np.mean([r.applications for r in extrapolated[late]])
            < 0.7 * np.mean([r.applications for r in plain[late]]))

