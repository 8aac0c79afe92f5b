"""The influence operator: Love's coefficients, the DC-FFT convolution and its PETSc shell matrix."""

import numpy as np
import pytest
from mpi4py import MPI

from petroll.solver.partition import RowPartition, columns_to_rows, move_rows, rows_to_columns
from petroll.solver.influence import Convolution, InfluenceOperator, dense_influence
from petroll.solver.petsc import shell_matrix
from petroll.solver.kernels.love import Rectangles, love_coefficients, rectangle_displacement
from compare import assert_close


def test_centre_of_a_square_cell():
    h = 0.37
    assert love_coefficients(1, 1, 2 * h, 2 * h)[0, 0] == pytest.approx(8 * h * np.arcsinh(1) / np.pi, rel=1e-14)
    assert love_coefficients(1, 1, 2 * h, 2 * h)[0, 0] == pytest.approx(2.2444 * h, rel=1e-4)


def test_the_table_is_loves_formula_at_every_cell():
    """love_coefficients (each corner term evaluated once, shared by neighbouring cells) equals Love's
    four-term formula evaluated cell by cell (rectangle_displacement), for a whole table and for rows."""
    dx, dy = 0.3, 0.7
    ix, iy = np.arange(37)[:, None], np.arange(23)[None, :]
    direct = rectangle_displacement(ix * dx, iy * dy, dx / 2, dy / 2)
    scale = direct[0, 0]
    assert np.abs(love_coefficients(37, 23, dx, dy) - direct).max() <= 1e-13 * scale
    rows = np.array([36, 0, 5, 5])
    assert np.abs(love_coefficients(37, 23, dx, dy, rows=rows) - direct[rows]).max() <= 1e-13 * scale


def test_far_field_is_a_point_load():
    dx, dy = 0.5, 0.3
    table = love_coefficients(401, 401, dx, dy)
    for ix, iy in [(200, 0), (0, 400), (150, 230), (400, 400)]:
        r = np.hypot(ix * dx, iy * dy)
        # the point-load value dx dy / (pi r) is reached to second order in the cell size / distance
        assert table[ix, iy] == pytest.approx(dx * dy / (np.pi * r), rel=2 * (max(dx, dy) / r) ** 2)


def test_rectangle_against_numerical_quadrature():
    """Love's closed form equals a direct 2-D quadrature of 1/(pi r) over a cell not containing the point."""
    dx, dy, x, y = 1.0, 0.5, 2.0, 1.5
    n = 2000
    s = (np.arange(n) + 0.5) / n
    xi, eta = (s - 0.5) * dx, (s - 0.5) * dy
    quad = np.sum(1 / np.hypot(x - xi[:, None], y - eta[None, :])) * dx * dy / n**2 / np.pi
    assert love_coefficients(5, 5, dx, dy)[2, 3] == pytest.approx(quad, rel=1e-6)


def dense_reference(nx, ny, dx, dy, x):
    return (dense_influence(love_coefficients(nx, ny, dx, dy)) @ x.ravel()).reshape(nx, ny)


@pytest.mark.ranks4
@pytest.mark.parametrize("nx,ny,workers", [(1, 1, 1), (2, 9, 1), (13, 7, 1), (16, 16, 1), (5, 24, 1), (16, 16, 2),
                                           (37, 11, 3)])
def test_convolution_equals_dense_matrix(comm, nx, ny, workers, monkeypatch):
    """On ``workers`` threads even where the transforms are small (Convolution.THREADED lowered: below it
    they run on one)."""
    monkeypatch.setattr(Convolution, "THREADED", 1)
    dx, dy = 0.3, 0.2
    x = np.random.default_rng(nx * 100 + ny).random((nx, ny))
    conv = Convolution(love_coefficients(nx, ny, dx, dy), nx, ny, comm, workers=workers)
    assert conv.workers == workers
    ref = dense_reference(nx, ny, dx, dy, x)
    y = conv(x[conv.r0 : conv.r1])
    assert np.abs(y - ref[conv.r0 : conv.r1]).max(initial=0.0) <= 1e-12 * np.abs(ref).max()


@pytest.mark.ranks4
@pytest.mark.parametrize("cap", [None, 0])
@pytest.mark.parametrize("aliased", [None, 1])
def test_applications_in_the_kept_work_array_keep_their_results(comm, cap, aliased, monkeypatch):
    """Applications of convolutions of three shapes, each applied twice, their results all kept: each equals
    the dense matrix's product, whether the spectra are transformed in the kept work array (default) or,
    above Convolution.WORKSPACE (cap 0), in arrays of their own, and whether their rows are padded
    (partition.ALIASED 1: every row one value longer than its columns, as rows of 256 values are)."""
    if cap is not None:
        monkeypatch.setattr(Convolution, "WORKSPACE", cap)
    if aliased is not None:
        monkeypatch.setattr("petroll.solver.partition.ALIASED", aliased)
    dx, dy = 0.3, 0.2
    results = []
    for nx, ny in [(13, 7), (5, 24), (13, 7), (9, 1)]:
        x = np.random.default_rng(nx * ny + len(results)).random((nx, ny))
        conv = Convolution(love_coefficients(nx, ny, dx, dy), nx, ny, comm)
        results.append((conv(x[conv.r0 : conv.r1]), dense_reference(nx, ny, dx, dy, x)[conv.r0 : conv.r1]))
    for y, ref in results:
        assert np.abs(y - ref).max(initial=0.0) <= 1e-12 * np.abs(ref).max()


@pytest.mark.ranks4
@pytest.mark.parametrize("nx,ny", [(13, 7), (5, 24)])
def test_a_block_beyond_the_kept_table_computes_each_ranks_kernel_rows_from_loves_formula(comm, nx, ny):
    """Blocks larger than TABLE_CELLS get their kernel from Love's formula, row by row as each rank needs
    them: the same operator as the dense matrix."""
    dx, dy = 0.3, 0.2
    op = InfluenceOperator(Rectangles(dx, dy), comm)
    op.TABLE_CELLS = 10
    conv = op.window(nx, ny)
    x = np.random.default_rng(nx + ny).random((nx, ny))
    ref = dense_reference(nx, ny, dx, dy, x)
    y = conv(x[conv.r0 : conv.r1])
    assert np.abs(y - ref[conv.r0 : conv.r1]).max(initial=0.0) <= 1e-12 * np.abs(ref).max()
    assert conv.diagonal == pytest.approx(love_coefficients(1, 1, dx, dy)[0, 0], rel=1e-15)


def _shell_product(comm, nx, ny, dx, dy, full_x):
    """The shell matrix of 2.5 A on ``comm`` (a window nx x ny of dx x dy rectangles), its rows of
    2.5 A full_x, and the objects to destroy."""
    op = InfluenceOperator(Rectangles(dx, dy), comm)
    conv = op.window(nx, ny)
    mat = shell_matrix(conv, 2.5)
    x, y = mat.createVecs()
    x.setArray(full_x[conv.r0 : conv.r1].ravel())
    mat.mult(x, y)
    return conv, mat, x, y


@pytest.mark.ranks4
def test_shell_matrix_mult_symmetry(comm):
    nx, ny, dx, dy = 20, 11, 1e-4, 2e-4
    rng = np.random.default_rng(7)
    full_x, full_z = rng.random((nx, ny)), rng.random((nx, ny))
    conv, mat, x, y = _shell_product(comm, nx, ny, dx, dy, full_x)
    ref = 2.5 * dense_reference(nx, ny, dx, dy, full_x)
    assert np.abs(y.array.reshape(-1, ny) - ref[conv.r0 : conv.r1]).max() <= 1e-12 * np.abs(ref).max()
    # symmetric: z.(A x) == x.(A z)
    z, az = mat.createVecs()
    z.setArray(full_z[conv.r0 : conv.r1].ravel())
    mat.mult(z, az)
    assert z.dot(y) == pytest.approx(x.dot(az), rel=1e-13)
    diagonal = x.duplicate()
    mat.getDiagonal(diagonal)
    assert np.all(diagonal.array == pytest.approx(2.5 * love_coefficients(1, 1, dx, dy)[0, 0], rel=1e-14))
    assert mat.getPythonContext().applications == 2
    for obj in (mat, x, y, z, az, diagonal):
        obj.destroy()


@pytest.mark.ranks4
@pytest.mark.parallel
def test_shell_matrix_mult_is_independent_of_the_rank_count(comm):
    """The distributed product against the same product on one rank (COMM_SELF), to round-off."""
    nx, ny, dx, dy = 20, 11, 1e-4, 2e-4
    full_x = np.random.default_rng(7).random((nx, ny))
    conv, mat, x, y = _shell_product(comm, nx, ny, dx, dy, full_x)
    serial = InfluenceOperator(Rectangles(dx, dy), MPI.COMM_SELF).window(nx, ny)(full_x) * 2.5
    assert np.abs(y.array.reshape(-1, ny) - serial[conv.r0 : conv.r1]).max() <= 1e-13 * np.abs(serial).max()
    for obj in (mat, x, y):
        obj.destroy()


@pytest.mark.parametrize("n,size", [(10, 3), (2, 4), (7, 1)])
def test_row_partition_covers_every_row_once(n, size):
    part = RowPartition(n, size)
    rows = np.concatenate([np.arange(*part.range(r)) for r in range(size)])
    assert np.array_equal(rows, np.arange(n))
    assert part.counts.max() - part.counts.min() <= 1


@pytest.mark.ranks4
def test_move_rows_between_partitions(comm):
    """Rows 3..14 of a 17-row field, split evenly, re-split as a window: every rank gets exactly its rows."""
    field = np.arange(17 * 4, dtype=float).reshape(17, 4)
    grid = [RowPartition(17, comm.size).range(r) for r in range(comm.size)]
    window_part = RowPartition(12, comm.size)
    window = [(3 + a, 3 + b) for a, b in (window_part.range(r) for r in range(comm.size))]
    a, b = grid[comm.rank]
    moved = move_rows(field[a:b], grid, window, comm)
    c, d = window[comm.rank]
    assert np.array_equal(moved, field[c:d])


@pytest.mark.ranks4
@pytest.mark.parametrize("dtype", [float, complex])
@pytest.mark.parametrize("nx,ny", [(17, 10), (3, 9), (13, 1), (2, 50)])
def test_transposes_give_every_rank_its_block_of_the_whole_field(comm, dtype, nx, ny):
    """rows_to_columns and columns_to_rows against slices of the whole field (splits uneven or with empty
    parts on 4 ranks; a strided view of the rows as input too)."""
    rng = np.random.default_rng(5)
    field = (rng.random((nx, ny + 1)) + (1j * rng.random((nx, ny + 1)) if dtype is complex else 0))[:, 1:]
    rows, cols = RowPartition(nx, comm.size), RowPartition(ny, comm.size)
    (r0, r1), (c0, c1) = rows.range(comm.rank), cols.range(comm.rank)
    assert np.array_equal(rows_to_columns(field[r0:r1], rows, cols, comm), field[:, c0:c1])
    columns = np.ascontiguousarray(field[:, c0:c1])
    assert np.array_equal(columns_to_rows(columns, rows, cols, comm), field[r0:r1])
    for view in (np.s_[:, : c1 - c0], np.s_[:, : 2 * (c1 - c0) : 2]):  # of wider rows; every other value
        wider = np.full((nx, 2 * (c1 - c0) + 3), np.nan, dtype=dtype)
        wider[view] = columns
        assert np.array_equal(columns_to_rows(wider[view], rows, cols, comm), field[r0:r1])


@pytest.mark.parallel
def test_an_application_under_mpi_holds_one_ranks_arrays_shared(comm, monkeypatch):
    """The arrays an application of A on a 256^2 window allocates at once (tracemalloc's peak, the kept work
    array included: made afresh), summed over the ranks, against the same application on one rank: the
    transposes pass each transform on alone (no rank keeps its rows' transform beside its columns'), so the
    sum is within 5 % (measured 1.00 on 2 ranks; 1.25 when each rank kept both)."""
    import tracemalloc

    n = 256
    table = love_coefficients(n, n, 1e-3, 1e-3)

    def peak(c: MPI.Comm) -> float:
        monkeypatch.setattr(Convolution, "_scratch", np.empty(0, dtype=complex))
        conv = Convolution(table, n, n, c)
        x = np.random.default_rng(2).random((conv.r1 - conv.r0, n))
        tracemalloc.start()
        conv(x)
        most = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        return most

    shared = comm.allreduce(peak(comm))
    assert shared <= 1.05 * peak(MPI.COMM_SELF)


@pytest.mark.ranks4
@pytest.mark.parametrize("di,dj", [(0, 0), (1, 0), (3, -2), (-4, 1), (12, 0), (0, -7), (-2, -3)])
def test_shift_field_moves_a_distributed_field_by_whole_cells(comm, di, dj):
    from petroll.solver.partition import shift_field

    nx, ny = 11, 7
    field = np.arange(nx * ny, dtype=float).reshape(nx, ny) + 1
    expected = np.zeros_like(field)
    for i in range(nx):
        for j in range(ny):
            if 0 <= i - di < nx and 0 <= j - dj < ny:
                expected[i, j] = field[i - di, j - dj]
    rows = RowPartition(nx, comm.size)
    r0, r1 = rows.range(comm.rank)
    assert np.array_equal(shift_field(field[r0:r1], di, dj, rows, comm), expected[r0:r1])


def test_kernels_of_the_most_recent_window_shapes_are_kept(comm):
    op = InfluenceOperator(Rectangles(1e-3, 1e-3), comm)
    first = op.window(4, 5)
    for n in range(6, 6 + op.kept - 1):  # fill the cache
        op.window(n, n)
    assert op.window(4, 5) is first  # still kept, now the newest
    for n in range(20, 20 + op.kept - 1):
        op.window(n, n)
    assert op.window(4, 5) is first and len(op._windows) == op.kept
    op.window(40, 40)  # one shape more: the least recently used goes
    assert (20, 20, False) not in op._windows and (4, 5, False) in op._windows
    x = np.random.default_rng(1).random((op.window(9, 9).r1 - op.window(9, 9).r0, 9))
    assert_close(op.window(9, 9)(x), Convolution(op.coefficients(9, 9), 9, 9, comm)(x), 1e-14)
