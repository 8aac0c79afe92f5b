"""Friction, phase 1: Cerruti's tangential kernels, their block convolution, the tangential QP on the
friction disks and its modes (shift, transient and steady rolling), against closed forms (Cattaneo-Mindlin,
Carter), Kalker's tables, dense references and quadrature."""

import math

import numpy as np
import pytest
from mpi4py import MPI

from petroll.solver.kernels.cerruti import (Tangential, TangentialStrips, cerruti_point, cerruti_table,
                                            coupling_table, rectangle_tangential, strip_coupling,
                                            strip_tangential)
from petroll.solver.kernels.love import love_coefficients, strip_coefficients
from petroll.solver.partition import RowPartition
from petroll.solver.tangential import BlockConvolution


# -- kernels -------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("nu", [0.0, 0.28, 0.5])
def test_a_square_cells_own_coefficient_is_the_closed_form(nu):
    """On a 2h x 2h cell: int int x^2/r^3 = int int y^2/r^3 = 4 h asinh(1) (half Love's 8 h asinh(1)), so
    K_xx(0, 0) = K_yy(0, 0) = (2 - nu) 4 h asinh(1)/pi, and K_xy(0, 0) = 0 (odd)."""
    h = 0.37
    xx, yy, xy = cerruti_table(np.array([0]), np.array([0]), 2 * h, 2 * h, nu)[:, 0, 0]
    assert xx == pytest.approx((2 - nu) * 4 * h * math.asinh(1) / math.pi, rel=1e-14)
    assert yy == pytest.approx(xx, rel=1e-14)
    assert xy == 0


def test_at_nu_zero_each_component_is_loves_kernel():
    dx, dy = 0.3, 0.7
    t = cerruti_table(np.arange(-5, 6), np.arange(-4, 5), dx, dy, 0.0)
    love = love_coefficients(6, 5, dx, dy)
    assert np.abs(t[0][5:, 4:] - love).max() <= 1e-15 * love[0, 0]
    assert np.abs(t[1][5:, 4:] - love).max() <= 1e-15 * love[0, 0]
    assert np.abs(t[2]).max() == 0


@pytest.mark.slow
@pytest.mark.parametrize("nu", [0.0, 0.3, 0.5])
@pytest.mark.parametrize("ox, oy", [(2, 3), (1, 0), (0, -2), (-3, 1)])
def test_rectangle_coefficients_against_quadrature_of_cerrutis_point_force(nu, ox, oy):
    """The closed forms equal a 2000 x 2000 midpoint quadrature of the point-force solution over a cell not
    containing the target (K_xx, K_yy, K_xy, and the coupling K_zx, K_zy = int int (x, y)/r^2 / pi)."""
    dx, dy = 1.0, 0.5
    x, y = ox * dx, oy * dy
    n = 2000
    s = (np.arange(n) + 0.5) / n - 0.5
    X, Y = x - s[:, None] * dx, y - s[None, :] * dy
    quad = cerruti_point(X, Y, nu).sum(axis=(1, 2)) * dx * dy / n**2
    table = cerruti_table(np.array([ox]), np.array([oy]), dx, dy, nu)[:, 0, 0]
    scale = table[0]
    assert np.abs(table - quad).max() <= 1e-6 * scale
    r2 = X * X + Y * Y
    coupling = np.array([(X / r2).sum(), (Y / r2).sum()]) * dx * dy / n**2 / math.pi
    assert np.abs(coupling_table(np.array([ox]), np.array([oy]), dx, dy)[:, 0, 0] - coupling).max() <= 1e-6 * scale


def test_far_field_is_cerrutis_point_force():
    dx, dy, nu = 0.5, 0.3, 0.3
    ox, oy = np.array([200, 0, 150, 400, -120]), np.array([0, 400, 230, 400, 77])
    t = cerruti_table(ox, oy, dx, dy, nu)
    for k in range(len(ox)):
        x, y = ox[k] * dx, oy[k] * dy
        point = cerruti_point(x, y, nu) * dx * dy
        r = math.hypot(x, y)
        assert np.abs(t[:, k, k] - point).max() <= 2 * (max(dx, dy) / r) ** 2 * point[0]


def test_symmetries_and_the_block_matrix_is_symmetric_positive_definite():
    """K_xx, K_yy even in each offset, K_xy odd in each (so even in the pair): the 2N x 2N matrix
    [[K_xx, K_xy], [K_xy, K_yy]] of a grid is symmetric, and positive definite (measured on 9 x 7 cells
    of 0.3 x 0.2: smallest eigenvalue 0.51, 0.47, 0.37 K_xx(0, 0) at nu = 0, 0.25, 0.5); K_zx odd in x
    and even in y, K_zy the transpose's."""
    dx, dy = 0.3, 0.2
    o = np.arange(-6, 7)
    t = cerruti_table(o, o, dx, dy, 0.4)
    assert np.array_equal(t[0], t[0][::-1]) and np.array_equal(t[0], t[0][:, ::-1])
    assert np.array_equal(t[1], t[1][::-1]) and np.array_equal(t[1], t[1][:, ::-1])
    assert np.allclose(t[2], -t[2][::-1], rtol=0, atol=1e-17) and np.allclose(t[2], -t[2][:, ::-1], atol=1e-17)
    c = coupling_table(o, o, dx, dy)
    assert np.allclose(c[0], -c[0][::-1], atol=1e-17) and np.allclose(c[0], c[0][:, ::-1], atol=1e-17)
    assert np.allclose(coupling_table(o, o, dy, dx)[1], c[0].T, atol=1e-16)
    for nu in (0.0, 0.25, 0.5):
        dense = dense_block(9, 7, dx, dy, nu)
        assert np.abs(dense - dense.T).max() <= 1e-15 * dense[0, 0]
        assert np.linalg.eigvalsh(dense).min() >= 0.3 * dense[0, 0]


def test_line_contacts_strips_are_the_normal_strips_times_one_minus_nu():
    """Plane strain: u_x = -(1 - nu)/(pi G) ln|x| per unit line force, i.e. (1 - nu) times the normal
    strip kernel relative to 1/(2 G); checked against quadrature of the logarithm over a strip. The
    coupling |x + a| - |x - a| is the limit of the 3-D K_zx of a cell long along Y (x/r^2 integrated over
    all Y is pi sign(x))."""
    dx, datum, nu = 0.2, 7.0, 0.3
    table = strip_tangential(12, dx, datum, nu)
    assert np.array_equal(table, (1 - nu) * strip_coefficients(12, dx, datum))
    n = 20000
    s = ((np.arange(n) + 0.5) / n - 0.5) * dx
    for k in (0, 1, 5, 11):
        quad = -(1 - nu) * 2 / math.pi * np.mean(np.log(np.abs(k * dx - s) / datum)) * dx
        assert table[k] == pytest.approx(quad, rel=1e-5)
    ox = np.arange(-4, 5)
    long_y = 2000.0
    long = coupling_table(ox, np.array([0]), dx, long_y)[0, :, 0]
    # a cell of length 2 b leaves out (1/pi) int (2 x/b) dx of the infinite strip: 4 |x| dx/(pi 2 b)
    missing = 4 * np.abs(ox * dx) * dx / (math.pi * long_y)
    assert np.all(np.abs(long - strip_coupling(ox, dx)) <= 1.01 * missing + 1e-12 * dx)


def test_the_table_is_the_four_corner_formula_at_every_cell():
    """cerruti_table (each corner evaluated once, shared by neighbouring cells) equals the four-corner
    formula evaluated cell by cell (rectangle_tangential)."""
    dx, dy, nu = 0.3, 0.7, 0.35
    ox, oy = np.arange(-12, 13), np.arange(-9, 10)
    direct = rectangle_tangential(ox[:, None] * dx, oy[None, :] * dy, dx / 2, dy / 2, nu)
    table = cerruti_table(ox, oy, dx, dy, nu)
    assert np.abs(table - direct).max() <= 1e-13 * direct[0, 12, 9]


def dense_block(nx, ny, dx, dy, nu):
    """The (2 nx ny) x (2 nx ny) matrix of the tangential kernel from the four-corner formula at every
    pair of cells (a reference independent of the FFT convolution)."""
    ix, iy = np.divmod(np.arange(nx * ny), ny)
    blocks = rectangle_tangential((ix[:, None] - ix[None, :]) * dx, (iy[:, None] - iy[None, :]) * dy,
                                  dx / 2, dy / 2, nu)
    return np.block([[blocks[0], blocks[2]], [blocks[2], blocks[1]]])


@pytest.mark.ranks4
@pytest.mark.parametrize("nx, ny, workers", [(1, 1, 1), (2, 9, 1), (13, 7, 1), (16, 16, 2), (5, 24, 1), (9, 1, 1)])
def test_block_convolution_equals_the_dense_matrix(comm, nx, ny, workers, monkeypatch):
    """Every rank's rows of K q against the dense matrix, on 1, 2 and 4 ranks (the rows split over
    ``comm``), with FFT threads even on small transforms (Convolution.THREADED lowered)."""
    from petroll.solver.influence import Convolution

    monkeypatch.setattr(Convolution, "THREADED", 1)
    dx, dy, nu = 0.3, 0.2, 0.3
    rng = np.random.default_rng(7)
    q = rng.standard_normal((2, nx, ny))
    expected = (dense_block(nx, ny, dx, dy, nu) @ q.reshape(-1)).reshape(2, nx, ny)
    r0, r1 = RowPartition(nx, comm.size).range(comm.rank)
    conv = BlockConvolution(Tangential(dx, dy, nu), nx, ny, comm, workers=workers)
    assert np.abs(conv(q[:, r0:r1]) - expected[:, r0:r1]).max(initial=0.0) <= 1e-13 * np.abs(expected).max()


@pytest.mark.ranks4
def test_strip_convolution_equals_the_dense_matrix(comm):
    nx, dx, datum, nu = 23, 0.1, 5.0, 0.25
    table = strip_tangential(nx, dx, datum, nu)
    i = np.arange(nx)
    dense = table[np.abs(i[:, None] - i[None, :])]
    q = np.random.default_rng(3).standard_normal((1, nx, 1))
    expected = (dense @ q[0, :, 0])[None, :, None]
    r0, r1 = RowPartition(nx, comm.size).range(comm.rank)
    conv = BlockConvolution(TangentialStrips(dx, 1.0, nu, datum), nx, 1, comm)
    assert np.abs(conv(q[:, r0:r1]) - expected[:, r0:r1]).max(initial=0.0) <= 1e-13 * np.abs(expected).max()


@pytest.mark.ranks4
@pytest.mark.parametrize("nu", [0.0, 0.3, 0.5])
def test_the_inverse_block_circulant_is_symmetric_positive_definite_and_close_to_the_inverse(comm, nu):
    """The preconditioner R C^-1 R^T (C the block circulant of the kernel on a torus around the block) as a
    dense matrix, built by applying it to unit vectors: symmetric, positive definite, and a good
    approximation of the inverse (measured on 12 x 10 cells: M K's condition number 3.3, 3.5, 3.9 at
    nu = 0, 0.3, 0.5 against K's 19, 21, 26); at nu = 0 each component's is the normal problem's
    (petroll.solver.influence.Convolution's inverse)."""
    from petroll.solver.influence import Convolution

    nx, ny, dx, dy = 12, 10, 0.3, 0.2
    kernel = Tangential(dx, dy, nu)
    r0, r1 = RowPartition(nx, comm.size).range(comm.rank)
    inverse = BlockConvolution(kernel, nx, ny, comm, inverse=True, torus=(15, 10))
    n = nx * ny
    columns = []
    for k in range(2 * n):
        unit = np.zeros(2 * n)
        unit[k] = 1.0
        local = inverse(unit.reshape(2, nx, ny)[:, r0:r1])
        full = np.zeros((2, nx, ny))
        full[:, r0:r1] = local
        comm.Allreduce(MPI.IN_PLACE, full, op=MPI.SUM)
        columns.append(full.ravel())
    m = np.array(columns).T
    assert np.abs(m - m.T).max() <= 1e-12 * np.abs(m).max()
    k = dense_block(nx, ny, dx, dy, nu)
    assert np.linalg.eigvalsh(m).min() > 0
    eig = np.sort(np.linalg.eigvals(m @ k).real)
    plain = np.linalg.eigvalsh(k)
    assert eig[-1] / eig[0] < 4.5 and plain[-1] / plain[0] > 18
    if nu == 0:
        scalar = Convolution(love_coefficients(15, 10, dx, dy), nx, ny, comm, inverse=True, torus=(15, 10))
        v = np.random.default_rng(1).standard_normal((2, nx, ny))[:, r0:r1]
        assert np.abs(inverse(v)[0] - scalar(v[0])).max() <= 1e-12 * np.abs(scalar(v[0])).max()


# -- the tangential QP on the friction disks -----------------------------------------------------------------

def hertz_grid(n: int, margin: int = 4, line: bool = False):
    """A grid with n cells per contact radius (half-width) a = 1 and ``margin`` cells around the contact."""
    from petroll.model.grid import Grid, line_grid

    half = 1.0 + margin / n
    if line:
        return line_grid(2 * (n + margin), -half, half)
    return Grid(2 * (n + margin), 2 * (n + margin), -half, half, -half, half)


def hertz_pressure(grid, r0, r1, centre=0.0, p0=1.0):
    """Hertz's pressure p0 sqrt(1 - r^2) (a = 1; line contact: sqrt(1 - x^2)) at this rank's cell centres."""
    x = grid.x[r0:r1, None] - centre
    r2 = x * x if grid.line else x * x + grid.y[None, :] ** 2
    return p0 * np.sqrt(np.clip(1 - r2, 0.0, None))


def total(comm, field, grid):
    return comm.allreduce(float(field.sum())) * grid.cell_area


def dense_tangential_qp(q0, g, b, c):
    """The reference: the QP min 1/2 q^T C q + b^T q, |q_I| <= g_I by projected block Gauss-Seidel on the
    dense matrix C (each cell's 2 x 2 diagonal block is a multiple of the identity, so its exact minimiser
    with the others held is the projection of the unconstrained one onto its disk), swept to round-off."""
    n = len(g)
    q = q0.copy()
    for sweep in range(20000):
        biggest = 0.0
        for i in range(n):
            r = c[[i, n + i]] @ q + b[[i, n + i]]
            trial = q[[i, n + i]] - r / c[i, i]
            norm = math.hypot(*trial)
            new = trial * (min(1.0, g[i] / norm) if norm > 0 else 1.0)
            biggest = max(biggest, abs(new - q[[i, n + i]]).max())
            q[[i, n + i]] = new
        if biggest <= 1e-15 * max(g):
            return q
    raise AssertionError("the reference did not converge")


@pytest.mark.parametrize("nu", [0.0, 0.3])
def test_the_disk_qp_equals_a_dense_projected_gauss_seidel(comm, nu):
    """The distributed projected CG's tractions on a small Hertz contact under a rigid slip with a spin part
    (traction directions turning across the contact) equal a dense projected block Gauss-Seidel's."""
    from petroll.solver.tangential import TangentialSolver

    grid = hertz_grid(4, 1)
    solver = TangentialSolver(grid, comm, nu, 0.5, tol=1e-12)
    r0, r1 = solver.r0, solver.r1
    mu, p = 0.3, hertz_pressure(grid, r0, r1)
    x, y = grid.x[:, None], grid.y[None, :]
    rigid = np.stack(np.broadcast_arrays(0.02 - 0.05 * y, 0.01 + 0.05 * x)) * solver.compliance
    found = solver.solve(mu * p, rigid[:, r0:r1])
    c = solver.compliance * dense_block(grid.nx, grid.ny, grid.dx, grid.dy, nu)
    g = (mu * hertz_pressure(grid, 0, grid.nx)).ravel()
    expected = dense_tangential_qp(np.zeros(2 * g.size), g, rigid.reshape(-1), c).reshape(2, grid.nx, grid.ny)
    assert np.abs(found.traction - expected[:, r0:r1]).max(initial=0.0) <= 1e-8 * mu
    assert comm.allreduce(int(found.stick.sum())) > 0 and comm.allreduce(int((~found.stick & (p > 0)).sum())) > 0


CATTANEO = {0.2: (3.3e-3, 1.4e-2), 0.5: (2.4e-3, 1.7e-2), 0.875: (2.1e-3, 1.7e-2)}
"""Q/(mu P): the measured relative errors (shift, stick radius) at 16 cells per contact radius, nu = 0.3."""


@pytest.mark.parametrize("ratio", sorted(CATTANEO))
def test_cattaneo_mindlin_shift_and_stick_radius(comm, ratio):
    """A rigid sphere shifted from rest by a tangential force Q < mu P in one step (force control: the
    shift is the constraint's multiplier): the shift 3 mu P (2 - nu)/(16 G a) (1 - (1 - Q/(mu P))^(2/3))
    and the stick radius a (1 - Q/(mu P))^(1/3) (Johnson 1985, 7.3; sqrt(stick area/pi), the stick area
    the cells with |q| < mu p) within 2 % at 16 cells per contact radius (measured: CATTANEO); P the
    cell-centred pressure's force. The traction on the body opposes the shift (+x for a force -Q)."""
    from petroll.solver.friction import Stepping
    from petroll.solver.tangential import TangentialSolver

    nu, shear, mu = 0.3, 2.0, 0.3
    grid = hertz_grid(16)
    solver = TangentialSolver(grid, comm, nu, 1 / (2 * shear), tol=1e-10)
    p = hertz_pressure(grid, solver.r0, solver.r1, p0=5.0)
    force = total(comm, p, grid)
    stepping = Stepping(solver)
    solution = stepping.shift(mu * p, force=[-ratio * mu * force, 0.0])
    shift = 3 * mu * force * (2 - nu) / (16 * shear) * (1 - (1 - ratio) ** (2 / 3))
    assert stepping.shift_total[0] == pytest.approx(shift, rel=1.5 * CATTANEO[ratio][0])
    assert abs(stepping.shift_total[1]) <= 1e-9 * shift
    stick = comm.allreduce(int(solution.stick.sum())) * grid.cell_area
    assert math.sqrt(stick / math.pi) == pytest.approx((1 - ratio) ** (1 / 3), rel=min(2e-2, 1.3 * CATTANEO[ratio][1]))
    assert solution.force == pytest.approx([-ratio * mu * force, 0.0], abs=1e-9 * force)


def test_a_body_of_the_same_material_doubles_the_shift_and_steps_add_up(comm):
    """Quasi-identical bodies of one material: the compliance doubles, the tractions do not change and the
    shift doubles (Johnson: twice the rigid sphere's). Loading in four steps to the same force ends where one
    step does (monotonic loading: the slip annulus only grows; to 1e-4 of the shift: the
    discrete slip directions differ by their small y components; measured 7e-6)."""
    from petroll.solver.friction import Stepping
    from petroll.solver.tangential import TangentialSolver

    grid = hertz_grid(8)
    results = []
    for compliance, steps in ((0.25, 1), (0.5, 1), (0.25, 4)):
        solver = TangentialSolver(grid, comm, 0.3, compliance, tol=1e-11)
        p = hertz_pressure(grid, solver.r0, solver.r1)
        q_total = 0.6 * 0.3 * total(comm, p, grid)
        stepping = Stepping(solver)
        for k in range(1, steps + 1):
            solution = stepping.shift(0.3 * p, force=[-q_total * k / steps, 0.0])
        results.append((stepping.shift_total[0], solution.traction))
    assert results[1][0] == pytest.approx(2 * results[0][0], rel=1e-8)
    assert np.abs(results[1][1] - results[0][1]).max(initial=0.0) <= 1e-8 * 0.3
    assert results[2][0] == pytest.approx(results[0][0], rel=1e-4)


def carter(x, frac, mu_p0):
    """Carter's steady traction (a = 1) at the creepage |xi| R/(mu a) = frac < 1 (negative creepage, rolling
    towards +x: the stick zone of half-width c = 1 - frac at the leading edge)."""
    c = 1 - frac
    outer = np.sqrt(np.clip(1 - x * x, 0.0, None))
    inner = c * np.sqrt(np.clip(1 - ((x - (1 - c)) / c) ** 2, 0.0, None))
    return mu_p0 * (outer - inner)


CARTER = {0.1: (5.8e-3, 2.2e-3), 0.3: (6.0e-3, 4.8e-3), 0.6: (6.4e-3, 4.3e-3), 0.9: (4.4e-3, 4.3e-3)}
"""|xi| R/(mu a): the measured creep force error and L1 traction error (over mu P) at 16 cells per half-width,
order 2."""


@pytest.mark.parametrize("frac", sorted(CARTER))
def test_carter_creep_force_and_tractions(comm, frac):
    """Line contact, a rigid cylinder (R = 100 a) rolling steadily on a nu = 1/2 half-space (no coupling),
    the Hertz pressure at the cell centres, creepage xi = -frac mu a/R: the creep force
    Q/(mu P) = 1 - (1 - frac)^2 and the tractions (L1 error over mu P) within 1 % at 16 cells per
    half-width (measured: CARTER; the traction at the cell across the stick zone's trailing edge, where
    Carter's traction has a square-root kink, is 2-3 % off)."""
    from petroll.solver.friction import SteadyRolling
    from petroll.solver.tangential import TangentialSolver

    nu, shear, radius, mu = 0.5, 1.0, 100.0, 0.3
    grid = hertz_grid(16, margin=16, line=True)
    compliance = (1 - nu) / (2 * shear)
    force = math.pi / (4 * radius * compliance)
    p0 = 2 * force / math.pi
    solver = TangentialSolver(grid, comm, nu, 1 / (2 * shear), tol=1e-10)
    p = hertz_pressure(grid, solver.r0, solver.r1, p0=p0)
    steady = SteadyRolling(solver, 0, 1).solve(mu * p, creepage=(-frac * mu / radius, 0.0))
    discrete = total(comm, p, grid)
    assert steady.solution.force[0] / (mu * discrete) == pytest.approx(1 - (1 - frac) ** 2, rel=1e-2)
    exact = carter(grid.x[solver.r0 : solver.r1, None], frac, mu * p0)
    l1 = total(comm, np.abs(steady.solution.traction[0] - exact), grid) / (mu * discrete)
    assert l1 <= 1e-2
    assert l1 <= 1.3 * CARTER[frac][1]


@pytest.mark.parametrize("nu", [0.0, 0.25, 0.5])
def test_kalkers_linear_creep_coefficients_of_a_circular_contact(comm, nu):
    """Two bodies of one material (compliance 1/G) rolling steadily along +x at small creepage (mu p0 10^3
    times G xi: adhesion but for the trailing edge): F_x = -G a^2 C11 xi, F_y = -G a^2 (C22 eta + a C23 phi)
    within 3 % of Kalker's Table E.3 (Three-dimensional elastic bodies in rolling contact, 1990; a/b = 1:
    C11 = 3.40, 4.12, 5.20, C22 = 3.40, 3.67, 3.98, C23 = 1.33, 1.47, 1.63 at nu = 0, 0.25, 0.5) at 16 cells
    per radius (measured: within -0.3 % to -1.1 %)."""
    from petroll.solver.friction import SteadyRolling
    from petroll.solver.tangential import TangentialSolver

    table = {0.0: (3.40, 3.40, 1.33), 0.25: (4.12, 3.67, 1.47), 0.5: (5.20, 3.98, 1.63)}[nu]
    shear, mu = 1.0, 1.0
    grid = hertz_grid(16)
    solver = TangentialSolver(grid, comm, nu, 1 / shear, tol=1e-9)
    p = hertz_pressure(grid, solver.r0, solver.r1)
    rolling = SteadyRolling(solver, 0, 1)
    creepage = 1e-3 * mu / shear
    c11 = -rolling.solve(mu * p, creepage=(creepage, 0.0)).solution.force[0] / (shear * creepage)
    c22 = -rolling.solve(mu * p, creepage=(0.0, creepage)).solution.force[1] / (shear * creepage)
    c23 = -rolling.solve(mu * p, spin=creepage).solution.force[1] / (shear * creepage)
    assert [c11, c22, c23] == pytest.approx(table, rel=3e-2)
    assert [c11, c22, c23] == pytest.approx(table, rel=1.2e-2)


def test_full_slip_at_large_creepage(comm):
    """Beyond saturation every cell slips (stick area 0). Line contact: the traction is mu p against the
    creepage everywhere, |F| = mu P exactly (to the solver's tolerance). 3-D: the displacements' own slip
    turns each cell's slip a little off the rigid one, so |F| < mu P by an amount falling like the creepage
    squared (measured 2.3e-4, 2.3e-6, 2.3e-8 at 1, 10, 100 times a creepage of 0.5 with mu p0 c = 0.2): it
    tends to mu P. Under force control the QP refuses a force above mu P (the body slides) in one line."""
    from petroll.errors import SolverError
    from petroll.solver.friction import SteadyRolling, Stepping
    from petroll.solver.tangential import TangentialSolver

    mu = 0.4
    for line, creepages in ((True, [(0.5, 0.0)]), (False, [(30.0, -40.0), (300.0, -400.0)])):
        grid = hertz_grid(8, line=line)
        solver = TangentialSolver(grid, comm, 0.3, 0.5, tol=1e-10)
        p = hertz_pressure(grid, solver.r0, solver.r1)
        force = total(comm, p, grid)
        deficits = []
        for creepage in creepages:
            steady = SteadyRolling(solver, 0, 1).solve(mu * p, creepage=creepage)
            direction = -np.asarray(creepage[: solver.m]) / np.linalg.norm(creepage[: solver.m])
            assert comm.allreduce(int(steady.solution.stick.sum())) == 0
            deficits.append(1 - np.linalg.norm(steady.solution.force) / (mu * force))
            assert steady.solution.force @ direction == pytest.approx(np.linalg.norm(steady.solution.force),
                                                                     rel=1e-5)
        if line:
            expected = mu * p[None] * direction[:, None, None]
            assert np.abs(steady.solution.traction - expected).max(initial=0.0) <= 1e-9 * mu
            assert abs(deficits[0]) <= 1e-9
        else:
            assert 0 < deficits[1] <= 1e-7 and deficits[0] / deficits[1] == pytest.approx(100, rel=0.05)
        with pytest.raises(SolverError, match="exceeds the friction bound"):
            Stepping(solver).shift(mu * p, force=1.001 * mu * force * direction)
        with pytest.raises(SolverError, match="exceeds the friction bound"):
            SteadyRolling(solver, 0, 1).solve(mu * p, force=1.001 * mu * force * direction)


def test_steady_force_control_finds_the_creepage_of_creepage_control(comm):
    """A steady solve at the force a creepage-controlled solve gave finds that creepage (and the same
    tractions), spin included (the spin given, the creepage found)."""
    from petroll.solver.friction import SteadyRolling
    from petroll.solver.tangential import TangentialSolver

    grid = hertz_grid(8)
    solver = TangentialSolver(grid, comm, 0.3, 1.0, tol=1e-10)
    p = hertz_pressure(grid, solver.r0, solver.r1)
    rolling = SteadyRolling(solver, 1, -1)
    given = rolling.solve(0.3 * p, creepage=(0.05, 0.08), spin=0.1, centre=(0.0, 0.0))
    found = rolling.solve(0.3 * p, force=given.solution.force, spin=0.1, centre=(0.0, 0.0))
    assert found.creepage == pytest.approx([0.05, 0.08], rel=1e-7)
    assert np.abs(found.solution.traction - given.solution.traction).max(initial=0.0) <= 1e-7 * 0.3


@pytest.mark.slow
@pytest.mark.parametrize("control", ["force", "creepage"])
def test_the_onset_of_rolling_from_a_cattaneo_shift_reaches_the_steady_state(control):
    """A sphere shifted by Q = mu P/2 (Cattaneo), then rolled one cell a step along +x (BDF2 slip), at that
    force (the creepage found each step) or at the steady state's creepage, against the steady state solved
    directly (8 cells per radius). Force control: after two contact lengths the creepage and the traction
    field are within 0.2 % (of the creepage, of mu p0; measured 0.007 % and 0.06 %). Creepage control:
    the force approaches the steady one geometrically, by a factor of about 0.15 a contact length (the same
    at 16 cells per radius: the elastic field's memory, not the grid's): within 1 % after two contact
    lengths and 0.2 % after three (measured 0.68 % and 0.11 %). Under force control the tractions agree to
    1e-4 mu p0 after three lengths and converge to the same discrete problem (measured 8e-6; 3e-7 after
    four). Each rank runs it alone (COMM_SELF): 48 steps of small distributed FFTs cost a minute under
    an oversubscribed mpirun; the ranks' agreement on rolling steps is test_two_ranks_agree_with_one's."""
    comm = MPI.COMM_SELF
    from petroll.model.grid import Grid
    from petroll.solver.friction import SteadyRolling, Stepping
    from petroll.solver.partition import shift_field
    from petroll.solver.tangential import TangentialSolver

    n, mu = 8, 0.3
    dx = 1.0 / n
    grid = Grid(6 * n + 2 * n + 8, 2 * n + 8, -1 - 4 * dx, -1 - 4 * dx + (8 * n + 8) * dx, -(n + 4) * dx,
                (n + 4) * dx)
    solver = TangentialSolver(grid, comm, 0.3, 1.0, tol=1e-10)

    def bound(centre):
        return mu * hertz_pressure(grid, solver.r0, solver.r1, centre)

    force = np.array([-0.5 * total(comm, bound(0.0), grid), 0.0])
    steady = SteadyRolling(solver, 0, 1).solve(bound(0.0), force=force)
    stepping = Stepping(solver)
    stepping.shift(bound(0.0), force=force)
    for k in range(1, 6 * n + 1):
        centre = k * dx
        if control == "force":
            solution = stepping.roll(bound(centre), (centre, 0.0), dx, (1.0, 0.0), force=force)
            if k == 4 * n:  # two contact lengths
                moved = np.stack([shift_field(f, k, 0, solver.rows, comm) for f in steady.solution.traction])
                assert stepping.creepage[0] == pytest.approx(steady.creepage[0], rel=2e-3)
                assert np.abs(solution.traction - moved).max(initial=0.0) <= 2e-3 * mu
        else:
            solution = stepping.roll(bound(centre), (centre, 0.0), dx, (1.0, 0.0), creepage=steady.creepage)
            if k in (4 * n, 6 * n):
                assert solution.force[0] == pytest.approx(force[0], rel=1e-2 if k == 4 * n else 2e-3)
    if control == "force":
        moved = np.stack([shift_field(f, 6 * n, 0, solver.rows, comm) for f in steady.solution.traction])
        assert np.abs(solution.traction - moved).max(initial=0.0) <= 1e-4 * mu


@pytest.mark.parallel
def test_two_ranks_agree_with_one(comm):
    """A shift, transient rolling steps and a steady solve (3-D with spin, force control; line contact) on
    the rows split over 2 ranks against every rank's own COMM_SELF run: tractions within 1e-10 mu p0,
    shift and creepage within 1e-10 relative."""
    from petroll.model.grid import Grid
    from petroll.solver.friction import SteadyRolling, Stepping
    from petroll.solver.tangential import TangentialSolver

    n = 6
    dx = 1.0 / n
    grid = Grid(5 * n, 2 * n + 6, -1 - 3 * dx, -1 - 3 * dx + 5 * n * dx, -(n + 3) * dx, (n + 3) * dx)
    results = []
    for c in (comm, MPI.COMM_SELF):
        solver = TangentialSolver(grid, c, 0.3, 1.0, tol=1e-13)

        def bound(centre):
            return 0.3 * hertz_pressure(grid, solver.r0, solver.r1, centre)

        force = np.array([-0.4 * total(c, bound(0.0), grid), 0.1 * total(c, bound(0.0), grid)])
        stepping = Stepping(solver)
        stepping.shift(bound(0.0), force=force)
        for k in range(1, 4):
            rolled = stepping.roll(bound(k * dx), (k * dx, 0.0), dx, (1.0, 0.0), spin=0.05, force=force)
        steady = SteadyRolling(solver, 0, 1).solve(bound(0.0), force=force, spin=0.05)
        fields = [rolled.traction, steady.solution.traction]
        whole = [np.zeros((2, grid.nx, grid.ny)) for _ in fields]
        for w, f in zip(whole, fields):
            w[:, solver.r0 : solver.r1] = f
            c.Allreduce(MPI.IN_PLACE, w, op=MPI.SUM)
        results.append((whole, stepping.shift_total, stepping.creepage, steady.creepage))
    (many, *values), (one, *alone) = results
    for a, b in zip(many, one):
        assert np.abs(a - b).max() <= 1e-10 * 0.3
    for a, b in zip(values, alone):
        assert np.asarray(a) == pytest.approx(np.asarray(b), rel=1e-10, abs=1e-20)
    line = hertz_grid(12, line=True)
    forces = []
    for c in (comm, MPI.COMM_SELF):
        solver = TangentialSolver(line, c, 0.5, 0.5, tol=1e-13)
        p = hertz_pressure(line, solver.r0, solver.r1)
        steady = SteadyRolling(solver, 0, 1).solve(0.3 * p, creepage=(-1e-3, 0.0))
        forces.append(steady.solution.force[0])
    assert forces[0] == pytest.approx(forces[1], rel=1e-10)


def test_the_friction_benchmark_and_the_solvers_comparison_run(comm, shared_dir):
    """``bench_friction(quick=True)`` (4 cells per radius, five contact lengths, a 3-point curve) runs, writes
    friction.csv on rank 0 and reports every case; ``compare_solvers`` at 4 cells per radius (each rank
    alone: FISTA's hundreds of iterations are slow under an oversubscribed mpirun) reports every solver,
    the projected CG converging (the measured numbers: docs/friction.md)."""
    from petroll.bench.friction import bench_friction, compare_solvers

    rows = bench_friction(shared_dir, quick=True, comm=comm)
    assert len(rows) == 14 and all(row["applications"] > 0 for row in rows)
    if comm.rank == 0:
        assert (shared_dir / "friction.csv").read_text().count("\n") == 15
    table = compare_solvers(MPI.COMM_SELF, n=4)
    assert {row["solver"] for row in table} >= {"DiskPCG", "FISTA (restarted)", "TAO pk"}
    assert all(row["applications"] for row in table if row["solver"].startswith("DiskPCG ("))


@pytest.mark.slow
@pytest.mark.ranks4
@pytest.mark.parametrize("nx, ny", [(9, 7), (16, 5), (1, 6), (12, 1)])
def test_the_coupling_convolution_and_its_transpose_equal_the_dense_matrix(comm, nx, ny):
    """The normal-tangential coupling (odd kernels: complex spectra) on 1, 2 and 4 ranks against the dense
    matrix of the closed forms (each entry from its own offset), and its transpose against the matrix's;
    line contact's strips (ny = 1 grids with the strip kernel) too."""
    from petroll.solver.kernels.cerruti import Coupling
    from petroll.solver.tangential import CouplingConvolution

    dx, dy = 0.3, 0.2
    line = ny == 1
    kernel = Coupling(dx, dy, line)
    ix, iy = np.divmod(np.arange(nx * ny), ny)
    ox, oy = ix[:, None] - ix[None, :], iy[:, None] - iy[None, :]
    if line:
        blocks = strip_coupling(ox, dx)[None]
    else:
        blocks = np.stack([coupling_table(np.array([a]), np.array([b]), dx, dy)[:, 0, 0]
                           for a, b in zip(ox.ravel(), oy.ravel())], axis=1).reshape(2, nx * ny, nx * ny)
    dense = np.concatenate(list(blocks), axis=1)  # (n, m n): normal from the traction's components
    rng = np.random.default_rng(5)
    t = rng.standard_normal((kernel.components, nx, ny))
    p = rng.standard_normal((nx, ny))
    r0, r1 = RowPartition(nx, comm.size).range(comm.rank)
    conv = CouplingConvolution(kernel, nx, ny, comm)
    normal = (dense @ t.reshape(-1)).reshape(nx, ny)
    tangential = (dense.T @ p.ravel()).reshape(kernel.components, nx, ny)
    assert np.abs(conv.normal(t[:, r0:r1]) - normal[r0:r1]).max(initial=0.0) <= 1e-13 * np.abs(normal).max()
    assert np.abs(conv.tangential(p[r0:r1]) - tangential[:, r0:r1]).max(initial=0.0) <= 1e-13 * np.abs(tangential).max()


def test_the_last_tractions_displacement_inside_the_qps_gradient_is_the_convolved_one(comm):
    """A step's u' = c K X of the last tractions X given as ``earlier`` (inside the QP's gradient, on the box
    of the contact and of X, the step's compliance c_s != c) against u' convolved on its own and given as
    ``previous``: tractions within 1e-10 mu p0, the shift found within 1e-10 relative (measured 1e-12,
    3e-13): the same QP."""
    from petroll.solver.tangential import TangentialSolver

    grid = hertz_grid(8, margin=6)
    solver = TangentialSolver(grid, comm, 0.3, 1.0, tol=1e-12)
    mu, dx = 0.3, grid.dx
    earlier = solver.solve(mu * hertz_pressure(grid, solver.r0, solver.r1),
                           force=[-0.4 * total(comm, mu * hertz_pressure(grid, solver.r0, solver.r1), grid), 0.0])
    bound = mu * hertz_pressure(grid, solver.r0, solver.r1, 2 * dx)
    force = np.array([-0.5 * total(comm, bound, grid), 0.05 * total(comm, bound, grid)])
    x = earlier.traction
    box = solver.box((bound > 0) | np.any(x != 0, axis=0))
    inside = solver.solve(bound, earlier=x, force=force, compliance=0.7)
    convolved = solver.solve(bound, previous=solver.displacement(x, box), force=force, compliance=0.7)
    assert np.abs(inside.traction - convolved.traction).max(initial=0.0) <= 1e-10 * mu
    assert inside.shift == pytest.approx(convolved.shift, rel=1e-10)
    assert np.abs(inside.traction).max() > 0.1 * mu  # a problem with tractions to compare


def test_first_guesses_carried_at_two_steps_per_cell_change_the_start_only(comm):
    """Transient rolling at 2 steps per cell under force control, 2 contact lengths after a shift, with the
    tractions 2, 4 and 6 steps back carried as first guesses (TractionWarmStart) against every step started
    from zero (depth 0): the tractions and the creepage found within 2e-9 of mu p0 and relative (tol 1e-10;
    measured 1.1e-10, 6.7e-11),
    at under 3/4 of the applications over the second contact length (measured: 297 against 517)."""
    from petroll.model.grid import Grid
    from petroll.solver.friction import Stepping
    from petroll.solver.tangential import TangentialSolver
    from petroll.solver.warm import TractionWarmStart

    n, mu = 6, 0.3
    dx = 1.0 / n
    grid = Grid(6 * n + 8, 2 * n + 8, -1 - 4 * dx, -1 - 4 * dx + (6 * n + 8) * dx, -(n + 4) * dx, (n + 4) * dx)
    results = []
    for depth in (3, 0):
        solver = TangentialSolver(grid, comm, 0.3, 1.0, tol=1e-10)

        def bound(centre):
            return mu * hertz_pressure(grid, solver.r0, solver.r1, centre)

        force = np.array([-0.5 * total(comm, bound(0.0), grid), 0.0])
        stepping = Stepping(solver)
        stepping.warm = TractionWarmStart(grid, solver.rows, comm, depth)
        stepping.shift(bound(0.0), force=force)
        applications = 0
        for k in range(1, 8 * n + 1):
            solution = stepping.roll(bound(k * dx / 2), (k * dx / 2, 0.0), dx / 2, (1.0, 0.0), force=force)
            applications += solution.applications if k > 4 * n else 0
        results.append((solution.traction, stepping.creepage[0], applications))
    (guessed, creepage, fewer), (cold, creepage_cold, more) = results
    assert np.abs(guessed - cold).max(initial=0.0) <= 2e-9 * mu
    assert creepage == pytest.approx(creepage_cold, rel=2e-9)
    assert 4 * fewer < 3 * more


@pytest.mark.parametrize("line", [False, True])
def test_a_shift_from_rest_starts_from_cattaneo_mindlins_tractions(comm, line):
    """`cattaneo_mindlin` on Hertz's bound (16 cells per radius or half-width), Q = mu P/2: its tractions
    carry the force within 2 % (the cells' sampling; the other dimension's exponent, 1/3 against 1/2, is
    26-29 % off) and vanish in the stick zone's complement only where Cattaneo's do (|q| = g outside
    a k, k = 1/2^(1/3), line contact 1/2^(1/2), to a cell); a shift from rest started from them
    (Stepping.shift) equals the same QP started from zero within 1e-9 of mu p0 (tol 1e-11) at fewer
    applications (measured 17 against 22 in 3-D at tol 1e-8)."""
    from petroll.model.grid import Grid, line_grid
    from petroll.solver.friction import Stepping, cattaneo_mindlin
    from petroll.solver.tangential import TangentialSolver

    n, mu = 16, 0.3
    dx = 1.0 / n
    if line:
        grid = line_grid(2 * n + 8, -1 - 4 * dx, 1 + 4 * dx)
    else:
        grid = Grid(2 * n + 8, 2 * n + 8, -1 - 4 * dx, 1 + 4 * dx, -1 - 4 * dx, 1 + 4 * dx)
    solver = TangentialSolver(grid, comm, 0.3, 1.0, tol=1e-11)
    bound = mu * hertz_pressure(grid, solver.r0, solver.r1)
    force = 0.5 * total(comm, bound, grid) * (np.array([1.0]) if line else np.array([-0.6, 0.8]))
    guess = cattaneo_mindlin(bound, force, grid.cell_area, comm)
    carried = np.array([total(comm, component, grid) for component in guess])
    assert np.abs(carried - force).max() <= 0.02 * np.hypot.reduce(force)
    k = 0.5 ** (1 / (2 if line else 3))
    x = grid.x[solver.r0 : solver.r1, None]
    r = np.abs(x) if line else np.hypot(x, grid.y[None, :])
    at_bound = np.isclose(np.sqrt((guess * guess).sum(axis=0)), bound, rtol=1e-12, atol=0.0) & (bound > 0)
    assert np.all(at_bound[(r > k + dx) & (bound > 0)]) and not np.any(at_bound[r < k - dx])
    cold = solver.solve(bound, force=force)
    started = Stepping(solver).shift(bound, force=force)
    assert np.abs(started.traction - cold.traction).max() <= 1e-9 * mu
    assert started.applications < cold.applications


def test_the_traction_guess_extrapolates_in_the_body_and_the_material_frame(comm):
    """TractionWarmStart at one cell per step: fields q_j = B(x - s_j) + M(x) + j C(x - s_j) (Gaussians:
    one moving with the body, one fixed in the material, one growing in the body's frame) recorded at
    s_1..s_3 give q_4 to round-off (the body's frame alone, 2 T q_3 - T^2 q_2, is off by 1e-2); with
    two recorded: B + M exactly. On a bound equal to |2 T q_3 - T^2 q_2| in some cells (a slip zone
    moving with the body), the guess there has that size and the exact guess's direction."""
    from petroll.model.grid import Grid
    from petroll.solver.partition import RowPartition, shift_field
    from petroll.solver.warm import TractionWarmStart

    n = 40
    grid = Grid(n, 20, 0.0, float(n), 0.0, 20.0)  # unit cells
    rows = RowPartition(grid.nx, comm.size)
    r0, r1 = rows.range(comm.rank)
    x, y = grid.x[r0:r1, None], grid.y[None, :]

    def bump(cx, cy, w):
        return np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / w**2)

    def field(j, parts=(1, 1, 1)):
        s = float(j)
        b = np.stack([bump(18 + s, 10, 3), -0.5 * bump(19 + s, 9, 2)])
        m = np.stack([0.3 * bump(23, 11, 2), 0.2 * bump(22, 9, 3)])
        c = np.stack([0.01 * bump(17 + s, 10, 2), 0.02 * bump(18 + s, 11, 3)])
        return parts[0] * b + parts[1] * m + j * parts[2] * c

    warm = TractionWarmStart(grid, rows, comm)
    for j in (1, 2, 3):
        warm.record(field(j), float(j), 0.0)
    exact = field(4)
    assert np.abs(warm.guess(4.0, 0.0) - exact).max() <= 1e-12
    body = np.stack([2 * shift_field(a, 1, 0, rows, comm) - shift_field(b, 2, 0, rows, comm)
                     for a, b in zip(field(3), field(2))])  # carried one and two cells
    assert comm.allreduce(float(np.abs(body - exact).max()), op=MPI.MAX) > 1e-2
    two = TractionWarmStart(grid, rows, comm)
    for j in (2, 3):
        two.record(field(j, (1, 1, 0)), float(j), 0.0)
    assert np.abs(two.guess(4.0, 0.0) - field(4, (1, 1, 0))).max() <= 1e-12
    slip = x + 0 * y > 22  # the bound of the body's frame alone there, large elsewhere
    bound = np.where(slip, np.sqrt((body * body).sum(axis=0)), 10.0)
    guess = warm.guess(4.0, 0.0, bound)
    size = np.sqrt((guess * guess).sum(axis=0))
    assert np.allclose(size[slip], bound[slip], rtol=1e-12, atol=0.0)
    direction = exact / np.sqrt((exact * exact).sum(axis=0))
    assert np.allclose(guess[:, slip], (direction * size)[:, slip], rtol=0.0, atol=1e-12)
    assert np.abs(guess - exact)[:, ~slip].max(initial=0.0) <= 1e-12


def test_the_free_sets_condition_numbers_are_built_from_the_solvers_sets():
    """`free_set_conditioning` at 4 cells per radius: the free directions' matrix preconditioned by its own
    inverse has condition number 1 (to 1e-10: the dense operator, the sets and the directions fit
    together), its stick and slip counts are the shift's (cells inside the contact with |q| below or on
    the bound), and every other condition number is >= 1 (measured at 16 cells per radius in
    docs/friction.md: 8.5 with DiskPCG's preconditioner)."""
    from petroll.bench.friction import free_set_conditioning, hertz_case
    from petroll.solver.friction import Stepping

    numbers = free_set_conditioning(4)
    assert numbers["exact"] == pytest.approx(1.0, abs=1e-10)
    grid, solver, bound = hertz_case(4, MPI.COMM_SELF)
    g = bound()
    shift = Stepping(solver).shift(g, force=np.array([-0.5 * total(MPI.COMM_SELF, g, grid), 0.0]))
    size = np.sqrt((shift.traction**2).sum(axis=0))
    on_bound = (g > 0) & (size >= g * (1 - 1e-9))
    assert (numbers["stick"], numbers["slip"]) == (int(np.count_nonzero((g > 0) & ~on_bound)),
                                                   int(np.count_nonzero(on_bound)))
    assert min(v for k, v in numbers.items() if k not in ("stick", "slip")) >= 1 - 1e-12
