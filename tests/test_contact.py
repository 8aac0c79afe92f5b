"""One contact step against independent oracles: Hertz, plane-strain Hertz, a dense projected Gauss-Seidel."""

import math

import numpy as np
import pytest
from mpi4py import MPI

from petroll.model.bodies import Cylinder, Sphere
from petroll.solver.contact import ContactSolver
from petroll.errors import SolverError
from petroll.model.grid import Grid
from petroll.model.tao import DEFAULT_TAO_TYPE, TAO_TYPES
from petroll.solver.influence import dense_influence
from petroll.solver.kernels.love import love_coefficients
from petroll.solver.partition import gather_field

R, J = 0.01, 7.5e-8  # sphere radius (m) and surface compliance (1/Pa) of rubber, E = 10 MPa, nu = 0.5


def hertz(delta):
    """Contact radius, force and peak pressure of a sphere pressed delta into an elastic half-space."""
    return math.sqrt(R * delta), 4 * math.sqrt(R) * delta**1.5 / (3 * J), 2 * math.sqrt(delta / R) / (math.pi * J)


def sphere_setup(comm, cells_per_radius, delta=1e-5, tao_type=DEFAULT_TAO_TYPE, tol=1e-8):
    a = hertz(delta)[0]
    half = 1.6 * a
    n = int(round(2 * half / (a / cells_per_radius)))
    grid = Grid(n, n, -half, half, -half, half)
    solver = ContactSolver(grid, comm, tao_type=tao_type, tol=tol)
    height = Sphere(R).height(grid.x[solver.r0 : solver.r1, None], grid.y[None, :])
    return grid, solver, height


@pytest.mark.parametrize("cells_per_radius, force_rel, peak_rel", [(8, 2e-3, 5e-3), (16, 2e-4, 1e-3)])
def test_hertz_displacement_control(comm, cells_per_radius, force_rel, peak_rel):
    """The default TAO type against Hertz, to the grid's error (measured: force 1.1e-3 and 6.6e-5, peak
    pressure 2.8e-3 and 3.4e-4 at a/dx = 8 and 16)."""
    delta = 1e-5
    grid, solver, height = sphere_setup(comm, cells_per_radius, delta)
    step = solver.solve_penetration(height, J, delta)
    a, force, p0 = hertz(delta)
    assert step.force == pytest.approx(force, rel=force_rel)
    assert comm.allreduce(step.pressure.max(initial=0), op=MPI.MAX) == pytest.approx(p0, rel=peak_rel)
    assert step.residual <= 1e-8
    assert np.all(step.pressure >= 0)


def test_hertz_load_control(comm):
    """The load to 10 tol = 1e-7, at the penetration whose displacement-controlled solve carries that
    load to the same 1e-7 (measured 2.4e-9 and 3.9e-9); Hertz's radius within a cell, its penetration to
    the grid's error (measured 3.6e-4 at a/dx = 10)."""
    a_ref, load, _ = hertz(1e-5)
    grid, solver, height = sphere_setup(comm, 10)
    step = solver.solve_load(height, J, load, radius_hint=2 * R)  # a poor first guess on purpose
    assert step.force == pytest.approx(load, rel=1e-7)
    assert solver.solve_penetration(height, J, step.delta).force == pytest.approx(load, rel=1e-7)
    cells = comm.allreduce(int(np.count_nonzero(step.pressure > 0)))
    assert abs(math.sqrt(cells * grid.cell_area / math.pi) - a_ref) <= grid.dx
    assert step.delta == pytest.approx(1e-5, rel=1e-3)


def test_wide_cylinder_mid_section_is_plane_strain_hertz(comm):
    """A roller 25 contact half-widths wide: its mid-section is Hertz's plane-strain profile for its own a.

    The half-width comes from the mid-section's line load P (a = sqrt(4 P R J / pi)), the peak from
    p0 = a / (2 R J). Cells whose centre lies within one cell of the patch edge are left out: there the
    exact profile's infinite slope is beyond any cell-centred discretisation (3 % off at a/dx = 6 and 12).
    """
    grid = Grid(40, 100, -0.5e-3, 0.5e-3, -2.5e-3, 2.5e-3)
    solver = ContactSolver(grid, comm, tol=1e-8)
    body = Cylinder(R, 4e-3, edge_radius=1e-3)
    step = solver.solve_penetration(body.height(grid.x[solver.r0 : solver.r1, None], grid.y[None, :]), J, 5e-6)
    field = gather_field(step.pressure, grid.nx, comm)
    if comm.rank == 0:
        mid = field[:, grid.ny // 2]
        a = math.sqrt(4 * mid.sum() * grid.dx * R * J / math.pi)
        assert 4e-3 / a >= 10
        p0 = a / (2 * R * J)
        exact = p0 * np.sqrt(np.clip(1 - grid.x**2 / a**2, 0, None))
        interior = np.abs(grid.x) <= a - grid.dx
        assert np.abs(mid - exact)[interior].max() <= 0.02 * p0
        assert np.abs(mid - exact).max() <= 0.035 * p0
        assert abs(np.ptp(grid.x[mid > 0]) / 2 + grid.dx / 2 - a) <= grid.dx


@pytest.mark.parametrize("other_type", [t for t in TAO_TYPES if t != DEFAULT_TAO_TYPE])
def test_two_tao_types_agree(comm, other_type):
    """Every TAO type a scene may name gives the default type's pressure (both to tol = 1e-8)."""
    grid, solver, height = sphere_setup(comm, 8)
    other = ContactSolver(grid, comm, tao_type=other_type, tol=1e-8)
    p1 = solver.solve_penetration(height, J, 1e-5).pressure
    p2 = other.solve_penetration(height, J, 1e-5).pressure
    scale = comm.allreduce(p1.max(initial=0), op=MPI.MAX)
    assert comm.allreduce(np.abs(p1 - p2).max(initial=0), op=MPI.MAX) <= 1e-6 * scale


def projected_gauss_seidel(matrix, rhs, sweeps=20000):
    """min 1/2 p.Mp + p.rhs, p >= 0, by projected Gauss-Seidel: an independent, dense, slow oracle. It
    asserts its own convergence: the sweeps stop changing p, and p meets the optimality conditions
    min(p, Mp + rhs) = 0 to 1e-12 of their scales."""
    p = np.zeros_like(rhs)
    for _ in range(sweeps):
        old = p.copy()
        for i in range(len(p)):
            p[i] = max(0.0, p[i] - (matrix[i] @ p + rhs[i]) / matrix[i, i])
        if np.abs(p - old).max() <= 1e-15 * np.abs(p).max():
            break
    else:
        raise AssertionError(f"projected Gauss-Seidel did not settle in {sweeps} sweeps")
    gap = matrix @ p + rhs
    assert np.abs(np.minimum(p / p.max(), gap / np.abs(rhs).max())).max() <= 1e-12
    return p


@pytest.mark.slow
@pytest.mark.parametrize("nx,ny,window", [(14, 12, (10, 9)), (19, 14, (14, 12))])
def test_window_qp_equals_the_whole_grid_dense_solution(comm, nx, ny, window):
    """Posing the QP on the interference window only is exact: compare with the whole-grid dense problem.
    On the 19 x 14 grid the interference's bounding box, 13 x 11 cells, is grown to 14 x 12 (fast FFT
    lengths for the preconditioner)."""
    grid = Grid(nx, ny, -1.0, 1.0, -0.9, 0.9)
    solver = ContactSolver(grid, comm, tol=1e-9)
    body = Sphere(3.0)
    height_all = body.height(grid.x[:, None] - 0.1, grid.y[None, :] + 0.05)
    delta, compliance = 0.08, 2.0
    step = solver.solve_penetration(height_all[solver.r0 : solver.r1], compliance, delta)
    assert (step.window[1] - step.window[0], step.window[3] - step.window[2]) == window
    matrix = compliance * dense_influence(love_coefficients(grid.nx, grid.ny, grid.dx, grid.dy))
    reference = projected_gauss_seidel(matrix, (height_all - delta).ravel()).reshape(grid.nx, grid.ny)
    ours = step.pressure
    assert np.abs(ours - reference[solver.r0 : solver.r1]).max(initial=0) <= 1e-6 * reference.max()


@pytest.mark.parallel
def test_rank_count_does_not_change_the_answer(comm):
    """The same load-controlled step on all ranks and on one rank (COMM_SELF) agrees to 1e-10 (solved to
    1e-13: iterates differ by round-off between rank counts, so only converged answers can agree)."""
    results = []
    for c in (comm, MPI.COMM_SELF):
        grid, solver, height = sphere_setup(c, 8, tol=1e-13)
        step = solver.solve_load(height, J, 0.5 * hertz(1e-5)[1], radius_hint=R)
        field = gather_field(step.pressure, grid.nx, c) if c is comm else step.pressure
        results.append((step.force, step.delta, field))
    if comm.rank == 0:
        (f1, d1, p1), (f2, d2, p2) = results
        assert f1 == pytest.approx(f2, rel=1e-10)
        assert d1 == pytest.approx(d2, rel=1e-10)
        assert np.abs(p1 - p2).max() <= 1e-10 * p2.max()


def test_contact_reaching_the_grid_edge_is_refused(comm):
    grid, solver, height = sphere_setup(comm, 8)
    with pytest.raises(SolverError, match=r"\[grid\].*reaches the grid edge"):
        solver.solve_penetration(height, J, 4e-5)


def test_no_contact_gives_zero_pressure(comm):
    grid, solver, height = sphere_setup(comm, 8)
    step = solver.solve_penetration(height, J, -1e-6)
    assert step.force == 0 and not np.any(step.pressure)


@pytest.mark.parametrize("holes", [[(7, 6)], [(6, 6), (8, 7), (9, 5)]])
def test_cells_without_surface_inside_the_contact_cannot_touch(comm, holes):
    """A body with no surface (Z = +inf: a hole in a height map) at cells inside its contact window: they
    carry no pressure and the rest is the contact problem's solution (was TAO error 83, Inf or NaN, issue
    35). Oracle: the whole-grid dense problem by projected Gauss-Seidel, those cells given a gap 10 times
    the largest other one (no displacement closes it)."""
    grid = Grid(16, 14, -1.0, 1.0, -0.9, 0.9)
    solver = ContactSolver(grid, comm, tol=1e-10)
    height_all = Sphere(3.0).height(grid.x[:, None] - 0.05, grid.y[None, :] + 0.02)
    matrix = 2.0 * dense_influence(love_coefficients(grid.nx, grid.ny, grid.dx, grid.dy))
    whole = projected_gauss_seidel(matrix, (height_all - 0.08).ravel()).reshape(grid.nx, grid.ny)
    assert all(whole[i, j] > 0.1 * whole.max() for i, j in holes)  # in the contact of the body without holes
    for i, j in holes:
        height_all[i, j] = np.inf
    delta, compliance = 0.08, 2.0
    step = solver.solve_penetration(height_all[solver.r0 : solver.r1], compliance, delta)
    gaps = height_all - delta
    finite = np.isfinite(gaps)
    gaps[~finite] = 10 * np.abs(gaps[finite]).max()
    reference = projected_gauss_seidel(matrix, gaps.ravel()).reshape(grid.nx, grid.ny)
    assert all(reference[i, j] == 0 for i, j in holes) and (reference > 0).sum() > 20
    assert np.abs(step.pressure - reference[solver.r0 : solver.r1]).max(initial=0) <= 1e-6 * reference.max()
    assert all(step.pressure[i - solver.r0, j] == 0 for i, j in holes if solver.r0 <= i < solver.r1)
