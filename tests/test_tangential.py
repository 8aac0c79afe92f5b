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
