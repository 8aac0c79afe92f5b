"""PETSc at the edge: every PETSc object petroll makes (but pk, itself a TAO type: petroll/solver/pk.py) is
made here, around numerics that are plain numpy (and mpi4py), testable without PETSc.

- The contact QP (petroll.solver.contact): its options (:func:`contact_options`), its TAO, shell Hessian
  and vectors per window shape (:class:`WindowQP`, kept and reused; destroyed in order at exit).
- The influence operator as a PETSc Python shell matrix (:class:`ShellInfluence`, :func:`shell_matrix`;
  the operator itself, petroll.solver.influence.Convolution, is numpy FFTs over mpi4py), its principal
  submatrices (:class:`RestrictedShell`, what TAO's active-set types take) and the inverse-circulant PC
  (:class:`CirculantInverse`).
- GMRES (PETSc KSP) on a linear map and a preconditioner given as numpy functions (:func:`gmres`: the
  steady sliding solve's contact equations, petroll.solver.sliding.ContactSystem).

The inverse-circulant preconditioner: the contact QP's Hessian is the shell matrix (scale A on a window of
cells). Its preconditioner is (scale C)^-1, C the circulant approximation of A on the window
(petroll.solver.influence.Convolution with ``inverse=True``; for a layer, on a torus 1.5 times the window,
cut back to it: petroll.solver.kernels.layer.TORUS): it undoes A's 1/|k| smoothing, so Krylov iterations
hardly grow with the grid. TAO's active-set types (tron, gpcg, bnls, bntr, bntl) run their KSP on the free
variables only: the Hessian's principal submatrix that ``MatCreateSubMatrix`` gives them. The shell
answers that call with a :class:`RestrictedShell` that knows its index set, so the PC applies R C^-1 R^T
(R the restriction to the free variables: symmetric positive definite like C^-1) to the reduced vectors.
``pk`` applies the same PC to its gradient on the free variables.
"""

from __future__ import annotations

import atexit
import gc
import itertools
import weakref
from typing import Callable

import numpy as np

from petroll.errors import SolverError
from petroll.model.tao import TAO_TYPES
from petroll.solver.influence import Convolution
from petroll.solver.pk import PK_PYTHON_TYPE, PolonskyKeer, tao_reasons


def contact_options(prefix: str, tao_type: str, precondition: bool, workers: int) -> tuple[str, bool, int]:
    """The contact solver's settings from PETSc's options database (prefix ``prefix``), each defaulting to
    the given one: the TAO type (the scene's unless -<prefix>tao_type overrides it), whether the circulant
    PC is used (-<prefix>pc_circulant) and the FFT threads per rank (-<prefix>fft_workers). ``pk`` is spelt
    for TAO as its Python type, -<prefix>tao_type python -<prefix>tao_python_type
    petroll.solver.pk.PolonskyKeer (the ``petroll`` command translates -<prefix>tao_type pk on its command
    line: petroll.solver.pk.command_line)."""
    from petsc4py import PETSc

    options = PETSc.Options(prefix)
    chosen = options.getString("tao_type", tao_type)
    if chosen == "python" and options.getString("tao_python_type", "") == PK_PYTHON_TYPE:
        chosen = "pk"
    elif chosen == "pk" and options.hasName("tao_type"):
        raise SolverError(f"-{prefix}tao_type pk: TAO reads this option itself and knows pk only as "
                          f"-{prefix}tao_type python -{prefix}tao_python_type {PK_PYTHON_TYPE}")
    if chosen not in TAO_TYPES:
        raise SolverError(f"-{prefix}tao_type {chosen}: unknown; allowed: {', '.join(TAO_TYPES)}")
    return chosen, options.getBool("pc_circulant", precondition), options.getInt("fft_workers", workers)


KRYLOV_TYPES = ("pk", "tron", "gpcg", "bnls", "bntr", "bntl")
"""The TAO types whose KSP works on the Hessian (pk only applies its PC): these get the preconditioner.
bqnls's KSP works on its quasi-Newton matrix instead; bncg and blmvm run none."""


class WindowQP:
    """The contact QP's PETSc objects on one window shape, built once and reused for every QP posed on it:
    the shell Hessian A / A_00, the right-hand side, solution, gradient and bound (p_hat >= 0) vectors,
    and the TAO, configured from the options database (prefix ``solver.prefix``) once, when built (``solver``:
    the :class:`petroll.solver.contact.ContactSolver` whose settings it takes).

    Types that run a KSP (pk, tron, gpcg, bnls, bntr, bntl) get the inverse-circulant PC
    (:class:`CirculantInverse`) unless ``solver.precondition`` is false (-<prefix>pc_circulant 0: PC
    ``none``) or the options name the KSP's PC (-<KSP prefix>pc_type ...).
    """

    def __init__(self, solver, nx: int, ny: int):
        from petsc4py import PETSc

        influence = solver.influence
        self.hessian = shell_matrix(influence.window(nx, ny), 1.0 / influence.diagonal)
        self.x, self.rhs = self.hessian.createVecs()
        self.grad = self.x.duplicate()
        self.pk = solver.tao_type == "pk"
        tao = self.tao = PETSc.TAO().create(solver.comm)
        tao.setOptionsPrefix(solver.prefix)
        self._vecs = ()
        if self.pk:  # p_hat >= 0 given to pk as a number: no bound vectors (16 bytes per cell)
            tao.setType("python")
            tao.setPythonContext(PolonskyKeer(bounds=(0.0, np.inf)))
        else:
            tao.setType(solver.tao_type)
            self._vecs = lower, upper = self.x.duplicate(), self.x.duplicate()
            lower.set(0.0)
            upper.set(PETSc.INFINITY)
            tao.setVariableBounds((lower, upper))
        tao.setObjectiveGradient(self._objective_gradient, self.grad)
        tao.setHessian(lambda tao, p, H, P: None, self.hessian, self.hessian)
        tao.setTolerances(gatol=solver.tol, grtol=0.0, gttol=0.0)
        tao.setMaximumIterations(solver.max_iterations)
        tao.setMaximumFunctionEvaluations(10 * solver.max_iterations)
        tao.setFromOptions()
        if self.pk:  # -<prefix>tao_python_type (how the command line names pk) makes a new, unbounded context
            tao.getPythonContext().bounds = (0.0, np.inf)
        tao.setSolution(self.x)
        tao.setUp()
        self.kind, self.prefix = tao.getType(), solver.prefix
        ksp = tao.getKSP()
        if solver.tao_type in KRYLOV_TYPES and not PETSc.Options(ksp.getOptionsPrefix()).hasName("pc_type"):
            if solver.precondition:
                self.hessian.getPythonContext().inverse = influence.window(nx, ny, inverse=True)
                ksp.getPC().setType("python")
                ksp.getPC().setPythonContext(CirculantInverse())
            else:
                ksp.getPC().setType("none")
        if not _LIVE:  # registered after PETSc started: runs before its finalisation
            atexit.register(_destroy_live)
        self.created = next(_CREATED)
        _LIVE.add(self)

    def _objective_gradient(self, tao, p, grad) -> float:
        """1/2 p^T H p + rhs^T p and its gradient H p + rhs (the scaled gap)."""
        self.hessian.mult(p, grad)
        grad.axpy(1.0, self.rhs)
        return 0.5 * (p.dot(grad) + p.dot(self.rhs))

    def solve(self, total: float | None, tol: float):
        """Solve to the tolerance ``tol`` (TAO's gatol) from the start the caller wrote in ``x`` (p_hat >= 0)
        on the right-hand side it wrote in ``rhs`` (this rank's window entries, written in place: no copies;
        after a solve ``x`` holds its answer, a start for a tighter solve).
        ``total`` (pk only): hold sum p_hat = total (load control). Returns p_hat (a read-only view of ``x``,
        valid until the next solve), the gap H p_hat + rhs - lambda (a new array; lambda the load
        constraint's multiplier, 0 without it), lambda, TAO's iterations and the operator applications
        (arrays of this rank's window entries)."""
        self.tao.setTolerances(gatol=tol, grtol=0.0, gttol=0.0)  # the solver's tol may change between solves
        context = self.hessian.getPythonContext()
        before = context.applications
        if self.pk:
            self.tao.getPythonContext().total = total
        self.tao.solve(self.x)
        reason, its = self.tao.getConvergedReason(), self.tao.getIterationNumber()
        if reason < 0:
            why = getattr(self.tao.getPythonContext(), "breakdown", "") if self.pk else ""
            raise SolverError(f"TAO ({self.kind}) did not converge (reason {_reason_name(reason)} after {its} "
                              f"iterations{'; ' + why if why else ''}); try another -{self.prefix}tao_type, "
                              f"a larger [solver] tol or -{self.prefix}tao_max_it")
        multiplier = 0.0
        if self.pk:  # pk ends on the gradient at the solution, left in TAO's gradient vector
            multiplier = self.tao.getPythonContext().multiplier
        else:  # other types may keep a projected gradient there: recomputed in it (the next solve's anew)
            self.hessian.mult(self.x, self.grad)
            self.grad.axpy(1.0, self.rhs)
        gap = self.grad.array_r - multiplier
        return self.x.array_r, gap, multiplier, its, context.applications - before

    def error_estimate(self, x: np.ndarray, gap: np.ndarray, inverse: Convolution) -> float:
        """The relative L2 error of a solution ``x`` (p_hat, this rank's window entries) whose scaled gap is
        ``gap``, estimated from its natural residual min(x, gap): on the cells where that is the gap (those
        that carry pressure and should), the error x - x* solves H_FF e = gap, estimated with the
        preconditioner, e ~ R (scale C)^-1 R^T gap (``inverse``: the window's inverse circulant C^-1; R the
        restriction to those cells); elsewhere the error is the residual itself (pressure on a cell that
        should leave the contact, or a cell that should enter it). Returns |e|_2 / |x|_2 (0 where x = 0).
        Measured against references solved to 1e-12 (rough periodic and wavy sphere, 64^2 and 128^2, tol
        1e-4 ... 1e-8): 1.2-1.7 times the true error (tests/test_pressure_tol.py)."""
        from mpi4py import MPI

        context = self.hessian.getPythonContext()
        ny = context.conv.ny
        free = (x > 0) & (gap < x)
        inverted = inverse(np.where(free, gap, 0.0).reshape(-1, ny)).ravel() / context.scale
        error = np.where(free, inverted, np.minimum(x, gap))
        sums = np.array([np.dot(error, error), np.dot(x, x)])
        self.hessian.getComm().tompi4py().Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        return float(np.sqrt(sums[0] / sums[1])) if sums[1] > 0 else 0.0

    def destroy(self) -> None:
        for obj in (self.tao, self.hessian, self.x, self.rhs, self.grad, *self._vecs):
            obj.destroy()
        _LIVE.discard(self)


_LIVE: weakref.WeakSet[WindowQP] = weakref.WeakSet()
"""WindowQPs not yet destroyed: destroyed at exit, while PETSc still runs (later, their callbacks crash it)."""


_CREATED = itertools.count()
"""Creation numbers of WindowQPs: every rank creates the collective ones in the same order."""


def _destroy_live() -> None:
    """Destroy the live WindowQPs in the order they were created: the same on every rank (destroying is
    collective; a set's order, by address, may differ between ranks and deadlock the exit). Unreachable
    objects are collected first, at this same point on every rank: PETSc objects freed by Python's cyclic
    collector (at moments that differ between ranks) are queued for PETSc's collective clean-up at
    finalisation, which hung `mpirun -n 4` at exit when the queues differed."""
    gc.collect()
    for qp in sorted(_LIVE, key=lambda qp: qp.created):
        qp.destroy()


def _reason_name(reason: int) -> str:
    names = {v: k for k, v in vars(tao_reasons()).items() if isinstance(v, int)}
    return f"{names.get(reason, 'UNKNOWN')} ({reason})"


class ShellInfluence:
    """Context of a PETSc Python (shell) matrix y = scale A x over a distributed window of cells.

    Vectors hold the window's local rows flattened (index ix * ny + iy). The matrix is symmetric positive
    definite; ``applications`` counts the mults (the operator applications of a solve). With ``inverse``
    (the window's inverse circulant, a Convolution with inverse=True), ``precondition`` applies an
    approximate inverse of the matrix (:class:`CirculantInverse`). Principal submatrices
    (``MatCreateSubMatrix``, as TAO's active-set types take) are
    :class:`RestrictedShell` views of it.
    """

    def __init__(self, conv: Convolution, scale: float = 1.0, inverse: Convolution | None = None):
        self.conv, self.scale, self.inverse, self.applications = conv, scale, inverse, 0

    def precondition(self, x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """(scale C)^-1 x for a vector's local array ``x`` (flattened rows), written into ``out`` if given
        (with ``inverse`` only: :class:`CirculantInverse` checks it is set)."""
        return np.divide(self.inverse(x.reshape(-1, self.conv.ny)).ravel(), self.scale, out=out)

    def mult(self, mat, x, y) -> None:
        local = x.getArray(readonly=True).reshape(-1, self.conv.ny)
        with y as out:  # written in place: no temporary copies of the window
            np.multiply(self.conv(local), self.scale, out=out.reshape(-1, self.conv.ny))
        self.applications += 1

    def multTranspose(self, mat, x, y) -> None:
        self.mult(mat, x, y)

    def getDiagonal(self, mat, d) -> None:
        d.set(self.conv.diagonal * self.scale)

    def createSubMatrix(self, mat, isrow, iscol, submat):
        return restricted_shell(mat, isrow, iscol, submat)


def shell_matrix(conv: Convolution, scale: float = 1.0, inverse: Convolution | None = None):
    """A PETSc shell matrix applying ``scale * A`` with the FFT convolution ``conv`` (on conv's comm);
    ``inverse``: the preconditioner's inverse circulant (see :class:`ShellInfluence`)."""
    from petsc4py import PETSc

    n_local = (conv.r1 - conv.r0) * conv.ny
    n = conv.nx * conv.ny
    context = ShellInfluence(conv, scale, inverse)
    mat = PETSc.Mat().createPython([(n_local, n), (n_local, n)], context, comm=conv.comm)
    mat.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    mat.setUp()
    return mat


class RestrictedShell:
    """Context of a Python Mat: the principal submatrix M[I, I] of a Python shell matrix M, I the index set
    (this rank's part of it lies in this rank's rows, as TAO's index sets of free variables do)."""

    def __init__(self, parent, index):
        self.parent = parent
        self.full_in, self.full_out = parent.createVecs()
        self.set_index(index)

    def set_index(self, index) -> None:
        self.index = np.asarray(index.getIndices()) - self.parent.getOwnershipRange()[0]

    @property
    def shell(self):
        """The parent matrix's Python context."""
        return self.parent.getPythonContext()

    def mult(self, mat, x, y) -> None:
        self.full_in.set(0.0)
        self.full_in.array[self.index] = x.array_r
        self.parent.mult(self.full_in, self.full_out)
        y.setArray(self.full_out.array_r[self.index])

    def multTranspose(self, mat, x, y) -> None:
        self.mult(mat, x, y)

    def getDiagonal(self, mat, d) -> None:
        self.parent.getDiagonal(self.full_out)
        d.setArray(self.full_out.array_r[self.index])

    def destroy(self, mat) -> None:
        for v in (self.full_in, self.full_out):
            v.destroy()


def restricted_shell(parent, isrow, iscol, submat=None):
    """M[I, I] as a Python Mat (``createSubMatrix`` of a Python shell M); ``submat`` reused when given."""
    from petsc4py import PETSc

    if not isrow.equal(iscol):
        raise NotImplementedError("only principal submatrices (isrow == iscol) of the influence matrix")
    if submat is not None and submat.handle:
        submat.getPythonContext().set_index(isrow)
        return submat
    n_local, n = isrow.getLocalSize(), isrow.getSize()
    sub = PETSc.Mat().createPython([(n_local, n), (n_local, n)], RestrictedShell(parent, isrow),
                                   comm=parent.getComm())
    sub.setOption(PETSc.Mat.Option.SYMMETRIC, True)
    sub.setUp()
    return sub


class CirculantInverse:
    """Context of a PETSc Python PC: y = (scale C)^-1 x for the shell Hessian of a window, restricted to the
    free variables when the PC's matrix is a :class:`RestrictedShell` of it."""

    def setUp(self, pc) -> None:
        matrix = pc.getOperators()[1]
        context = matrix.getPythonContext() if matrix.getType() == "python" else None
        if isinstance(context, RestrictedShell):
            self.shell, self.index = context.shell, context.index
            self.full = np.zeros(context.full_in.getLocalSize())
        else:
            self.shell, self.index = context, None
        if getattr(self.shell, "inverse", None) is None:
            raise TypeError("the circulant-inverse PC needs petroll's influence shell matrix with its inverse "
                            "circulant as the preconditioning matrix")

    def apply(self, pc, x, y) -> None:
        if self.index is None:
            with y as out:  # written in place: no temporary copy of the window
                self.shell.precondition(x.array_r, out)
            return
        self.full[:] = 0.0
        self.full[self.index] = x.array_r
        y.setArray(self.shell.precondition(self.full)[self.index])

    def applyTranspose(self, pc, x, y) -> None:
        self.apply(pc, x, y)

    def view(self, pc, viewer) -> None:
        viewer.printfASCII("  petroll inverse circulant: (scale C)^-1, C the periodic wrap of the window's "
                           "influence kernel (a layer's: on a torus around the window), restricted to the "
                           "free variables\n")


class _Linear:
    """Context of a PETSc Python Mat, or of a Python PC, applying a numpy function to a vector's local
    array (this rank's entries)."""

    def __init__(self, function: Callable[[np.ndarray], np.ndarray]):
        self.function = function

    def mult(self, mat, x, y) -> None:
        y.array[:] = self.function(x.array_r)

    def apply(self, pc, x, y) -> None:
        y.array[:] = self.function(x.array_r)


def gmres(apply: Callable[[np.ndarray], np.ndarray], precondition: Callable[[np.ndarray], np.ndarray],
          sizes: tuple[int, int], comm, x: np.ndarray, b: np.ndarray,
          target: Callable[[float], tuple[float, float]], restart: int = 30, max_it: int = 1000):
    """Solve apply(x) = b by GMRES (PETSc KSP; restarted every ``restart`` iterations, right-preconditioned
    by ``precondition``, so that its residual is the equations') from ``x`` (this rank's entries of
    ``sizes`` = (this rank's, all) unknowns; ``apply`` and ``precondition`` map this rank's entries,
    collectively). It stops once the residual is at most max(r times the first residual, a), (r, a) =
    ``target(|b|)``, or after ``max_it`` iterations. Returns the solution (this rank's entries), KSP's
    converged reason (< 0: it did not converge) and its iterations."""
    from petsc4py import PETSc

    mat = PETSc.Mat().createPython([sizes, sizes], _Linear(apply), comm=comm)
    mat.setUp()
    ksp = PETSc.KSP().create(comm=comm)
    vx, vb = mat.createVecs()
    try:
        ksp.setOperators(mat)
        ksp.setType("gmres")
        ksp.setGMRESRestart(restart)
        ksp.setPCSide(PETSc.PC.Side.RIGHT)
        ksp.getPC().setType("python")
        ksp.getPC().setPythonContext(_Linear(precondition))
        ksp.setInitialGuessNonzero(True)
        ksp.setTolerances(max_it=max_it)
        vx.array[:], vb.array[:] = x, b
        rtol, atol = target(vb.norm())
        first = []

        def converged(ksp, its, rnorm):
            if its == 0:
                first[:] = [rnorm]
            if rnorm <= max(rtol * first[0], atol):
                return PETSc.KSP.ConvergedReason.CONVERGED_ATOL
            if its >= max_it:
                return PETSc.KSP.ConvergedReason.DIVERGED_ITS
            return PETSc.KSP.ConvergedReason.ITERATING

        ksp.setConvergenceTest(converged)
        ksp.solve(vb, vx)
        return vx.array_r.copy(), ksp.getConvergedReason(), ksp.getIterationNumber()
    finally:
        for obj in (ksp, mat, vx, vb):
            obj.destroy()
