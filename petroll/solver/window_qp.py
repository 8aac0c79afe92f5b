"""The contact QP's PETSc objects on one window shape (:class:`WindowQP`), built once by
:class:`petroll.solver.contact.ContactSolver` and reused for every QP posed on that shape, and their
orderly destruction at exit."""

from __future__ import annotations

import atexit
import gc
import itertools
import weakref

import numpy as np

from petroll.errors import SolverError
from petroll.solver.influence import shell_matrix
from petroll.solver.pk import PolonskyKeer, tao_reasons
from petroll.solver.precondition import CirculantInverse

KRYLOV_TYPES = ("pk", "tron", "gpcg", "bnls", "bntr", "bntl")
"""The TAO types whose KSP works on the Hessian (pk only applies its PC): these get the preconditioner.
bqnls's KSP works on its quasi-Newton matrix instead; bncg and blmvm run none."""


class WindowQP:
    """The contact QP's PETSc objects on one window shape, built once and reused for every QP posed on it:
    the shell Hessian A / A_00, the right-hand side, solution, gradient and bound (p_hat >= 0) vectors,
    and the TAO, configured from the options database (prefix ``solver.prefix``) once, when built (``solver``:
    the :class:`petroll.solver.contact.ContactSolver` whose settings it takes).

    Types that run a KSP (pk, tron, gpcg, bnls, bntr, bntl) get the inverse-circulant PC
    (petroll.solver.precondition) unless ``solver.precondition`` is false (-<prefix>pc_circulant 0: PC
    ``none``) or the options name the KSP's PC (-<KSP prefix>pc_type ...).
    """

    def __init__(self, solver, nx: int, ny: int):
        from petsc4py import PETSc

        influence = solver.influence
        self.hessian = shell_matrix(influence.window(nx, ny), 1.0 / influence.diagonal)
        self.x, self.rhs = self.hessian.createVecs()
        self.grad, self.gap, lower, upper = (self.x.duplicate() for _ in range(4))
        self.pk = solver.tao_type == "pk"
        lower.set(0.0)
        upper.set(PETSc.INFINITY)
        tao = self.tao = PETSc.TAO().create(solver.comm)
        tao.setOptionsPrefix(solver.prefix)
        if self.pk:
            tao.setType("python")
            tao.setPythonContext(PolonskyKeer())
        else:
            tao.setType(solver.tao_type)
        tao.setObjectiveGradient(self._objective_gradient, self.grad)
        tao.setHessian(lambda tao, p, H, P: None, self.hessian, self.hessian)
        tao.setVariableBounds((lower, upper))
        tao.setTolerances(gatol=solver.tol, grtol=0.0, gttol=0.0)
        tao.setMaximumIterations(solver.max_iterations)
        tao.setMaximumFunctionEvaluations(10 * solver.max_iterations)
        tao.setFromOptions()
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
        self._vecs = (lower, upper)
        if not _LIVE:  # registered after PETSc started: runs before its finalisation
            atexit.register(_destroy_live)
        self.created = next(_CREATED)
        _LIVE.add(self)

    def _objective_gradient(self, tao, p, grad) -> float:
        """1/2 p^T H p + rhs^T p and its gradient H p + rhs (the scaled gap)."""
        self.hessian.mult(p, grad)
        grad.axpy(1.0, self.rhs)
        return 0.5 * (p.dot(grad) + p.dot(self.rhs))

    def solve(self, rhs: np.ndarray, start: np.ndarray | None, total: float | None = None):
        """Solve from ``start`` (p_hat, this rank's window entries; None: 0). ``total`` (pk only): hold
        sum p_hat = total (load control). Returns p_hat, the gap H p_hat + rhs - lambda (local arrays; lambda
        the load constraint's multiplier, 0 without it), lambda, TAO's iterations and the operator
        applications."""
        context = self.hessian.getPythonContext()
        before = context.applications
        self.rhs.setArray(rhs)
        if start is None:
            self.x.set(0.0)
        else:
            self.x.setArray(np.maximum(start, 0.0))
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
            self.tao.getGradient()[0].copy(self.gap)
            multiplier = self.tao.getPythonContext().multiplier
            self.gap.shift(-multiplier)
        else:  # other types may keep a projected gradient there
            self.hessian.mult(self.x, self.gap)
            self.gap.axpy(1.0, self.rhs)
        return self.x.array_r.copy(), self.gap.array_r.copy(), multiplier, its, context.applications - before

    def destroy(self) -> None:
        for obj in (self.tao, self.hessian, self.x, self.rhs, self.grad, self.gap, *self._vecs):
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
