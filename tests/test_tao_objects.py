"""The contact solver's PETSc objects: the inverse-circulant PC against dense matrices, TAO objects built
once per window shape and reused, and options that stay with their solver's prefix."""

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from petroll.model.bodies import Sphere
from petroll.model.grid import Grid
from petroll.solver.contact import ContactSolver
from petroll.errors import SolverError
from petroll.solver.influence import Convolution, dense_influence, spare_cores
from petroll.solver.petsc import CirculantInverse, shell_matrix
from petroll.solver.kernels.love import love_coefficients

R, J = 0.01, 7.5e-8


def dense_circulant(nx, ny, dx, dy):
    """C: the Love kernel wrapped periodically on the nx x ny torus (offsets taken the short way round)."""
    table = love_coefficients(nx, ny, dx, dy)
    ix, iy = np.divmod(np.arange(nx * ny), ny)
    wx = np.abs((ix[:, None] - ix[None, :] + nx // 2) % nx - nx // 2)
    wy = np.abs((iy[:, None] - iy[None, :] + ny // 2) % ny - ny // 2)
    return table[wx, wy]


@pytest.mark.parametrize("nx,ny", [(7, 5), (8, 6)])
def test_circulant_pc_on_free_variables_against_dense_matrices(comm, nx, ny):
    """The shell's principal submatrix is A[F, F] and the PC applies (s C)^-1 restricted to F."""
    dx, dy, scale = 0.3, 0.2, 2.5
    table = love_coefficients(nx, ny, dx, dy)
    mat = shell_matrix(Convolution(table, nx, ny, comm), scale)
    mat.getPythonContext().inverse = Convolution(table, nx, ny, comm, inverse=True)
    r0, r1 = mat.getOwnershipRange()
    free = np.random.default_rng(nx).random(nx * ny) < 0.6
    index = np.flatnonzero(free[r0:r1]) + r0
    iset = PETSc.IS().createGeneral(index.astype(PETSc.IntType), comm=comm)
    sub = mat.createSubMatrix(iset, iset)
    pc = PETSc.PC().create(comm)
    pc.setType("python")
    pc.setPythonContext(CirculantInverse())
    pc.setOperators(sub, sub)
    pc.setUp()
    x, y = sub.createVecs()
    values = np.random.default_rng(1).standard_normal(nx * ny)[free]
    lo = np.count_nonzero(free[:r0])
    x.setArray(values[lo : lo + len(index)])
    whole = np.flatnonzero(free)
    sub.mult(x, y)
    expected = scale * dense_influence(table)[np.ix_(whole, whole)] @ values
    got = np.concatenate(comm.allgather(y.array_r.copy()))
    assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max()
    pc.apply(x, y)
    expected = np.linalg.inv(scale * dense_circulant(nx, ny, dx, dy))[np.ix_(whole, whole)] @ values
    got = np.concatenate(comm.allgather(y.array_r.copy()))
    assert np.abs(got - expected).max() <= 1e-10 * np.abs(expected).max()
    for obj in (pc, sub, mat, iset, x, y):
        obj.destroy()


@pytest.mark.ranks4
@pytest.mark.parametrize("nx,ny,torus", [(7, 5, (11, 8)), (8, 1, (12, 1)), (6, 6, (9, 10))])
def test_inverse_circulant_on_a_torus_is_the_dense_torus_inverse_cut_to_the_block(comm, nx, ny, torus):
    """Convolution(inverse=True, torus=(lx, ly)): the block's field zero-padded onto the lx x ly torus, the
    inverse of the kernel's circulant there, cut back to the block: R C^-1 R^T, symmetric positive
    definite."""
    dx, dy = 0.3, 0.2
    lx, ly = torus
    conv = Convolution(love_coefficients(lx, ly, dx, dy), nx, ny, comm, inverse=True, torus=torus)
    block = (np.arange(nx)[:, None] * ly + np.arange(ny)[None, :]).ravel()
    expected_matrix = np.linalg.inv(dense_circulant(lx, ly, dx, dy))[np.ix_(block, block)]
    x = np.random.default_rng(nx).standard_normal((nx, ny))
    got = np.concatenate(comm.allgather(conv(x[conv.r0 : conv.r1])))
    expected = (expected_matrix @ x.ravel()).reshape(nx, ny)
    assert np.abs(got - expected).max() <= 1e-12 * np.abs(expected).max()
    assert np.linalg.eigvalsh(0.5 * (expected_matrix + expected_matrix.T)).min() > 0


def hertz_solver(comm, **kwargs):
    a = (R * 1e-5) ** 0.5
    grid = Grid(40, 40, -1.6 * a, 1.6 * a, -1.6 * a, 1.6 * a)
    solver = ContactSolver(grid, comm, tol=1e-9, **kwargs)
    return solver, Sphere(R).height(grid.x[solver.r0 : solver.r1, None], grid.y[None, :])


@pytest.mark.parametrize("tao_type", ["pk", "tron", "bnls", "bntr"])
def test_preconditioner_changes_the_cost_not_the_answer(comm, tao_type):
    answers = []
    for precondition in (True, False):
        solver, height = hertz_solver(comm, tao_type=tao_type, precondition=precondition)
        step = solver.solve_penetration(height, J, 1e-5)
        qp = solver.window_qp(*(step.window[1] - step.window[0], step.window[3] - step.window[2]))
        pc = qp.tao.getKSP().getPC().getType()
        assert pc == ("python" if precondition else "none")
        answers.append(step.pressure)
    scale = comm.allreduce(answers[0].max(initial=0), op=MPI.MAX)
    assert comm.allreduce(np.abs(answers[0] - answers[1]).max(initial=0), op=MPI.MAX) <= 1e-6 * scale


def test_tao_objects_are_built_once_per_window_shape(comm):
    solver, height = hertz_solver(comm)
    first = solver.solve_penetration(height, J, 1e-5)
    shape = (first.window[1] - first.window[0], first.window[3] - first.window[2])
    qp = solver.window_qp(*shape)
    tao = qp.tao.handle
    again = solver.solve_penetration(height, J, 1e-5, warm=first.pressure)  # same window: same objects
    assert solver.window_qp(*shape) is qp and qp.tao.handle == tao
    assert again.applications <= 2  # started at the answer: confirmed, not re-solved
    fresh, _ = hertz_solver(comm)
    reference = fresh.solve_penetration(height, J, 1e-5).pressure
    assert comm.allreduce(np.abs(again.pressure - reference).max(initial=0), op=MPI.MAX) <= 1e-7 * reference.max(
        initial=1.0)
    others = {solver.solve_penetration(height, J, 1e-5 * (0.2 + 0.05 * k)).window for k in range(12)}
    assert len(others) > solver.kept  # other shapes, more than are kept: the oldest were pushed out
    assert solver.window_qp(*shape) is not qp


def test_two_solvers_with_their_own_prefixes_do_not_leak(comm):
    """Options for one prefix reach that solver only, and solving writes nothing into the options database."""
    options = PETSc.Options()
    given = {"tao_a_tao_type": "tron", "tao_b_pc_circulant": "0", "tao_b_tao_max_it": "500",
             "tao_a_fft_workers": "2"}
    for key, value in given.items():
        options.setValue(key, value)
    try:
        before = options.getAll()
        a, height = hertz_solver(comm, prefix="tao_a_")
        b, _ = hertz_solver(comm, prefix="tao_b_")
        pa, pb = (s.solve_penetration(height, J, 1e-5) for s in (a, b))
        assert options.getAll() == before
        qa, qb = (s.window_qp(p.window[1] - p.window[0], p.window[3] - p.window[2]) for s, p in ((a, pa), (b, pb)))
        assert (a.tao_type, qa.tao.getType(), qa.tao.getKSP().getPC().getType()) == ("tron", "tron", "python")
        assert (b.tao_type, qb.tao.getType(), qb.tao.getKSP().getPC().getType()) == ("pk", "python", "none")
        assert (qa.tao.getMaximumIterations(), qb.tao.getMaximumIterations()) == (10000, 500)
        assert (a.influence.workers, b.influence.workers) == (2, spare_cores(comm))
        scale = comm.allreduce(pa.pressure.max(initial=0), op=MPI.MAX)
        assert comm.allreduce(np.abs(pa.pressure - pb.pressure).max(initial=0), op=MPI.MAX) <= 1e-6 * scale
    finally:
        for key in given:
            options.delValue(key)


def test_fft_workers_below_one_is_refused(comm):
    options = PETSc.Options()
    options.setValue("tao_c_fft_workers", "0")
    try:
        with pytest.raises(SolverError, match="-tao_c_fft_workers 0: the FFT threads per rank must be >= 1"):
            hertz_solver(comm, prefix="tao_c_")
    finally:
        options.delValue("tao_c_fft_workers")
