"""The inverse-circulant preconditioner as a PETSc Python PC, for every TAO type that runs a KSP.

The contact QP's Hessian is petroll's shell matrix (:class:`petroll.solver.influence.ShellInfluence`,
scale A on a window of cells). Its preconditioner is (scale C)^-1, C the circulant approximation of A on
the window (:class:`petroll.solver.influence.Convolution` with ``inverse=True``; for a layer, on a torus
1.5 times the window, cut back to it: petroll.solver.kernels.layer.TORUS): it undoes A's 1/|k| smoothing, so
Krylov iterations hardly grow with the grid.

TAO's active-set types (tron, gpcg, bnls, bntr, bntl) run their KSP on the free variables only: the
Hessian's principal submatrix that ``MatCreateSubMatrix`` gives them. The shell answers that call with a
:class:`RestrictedShell` that knows its index set, so the PC applies R C^-1 R^T (R the restriction to the
free variables: symmetric positive definite like C^-1) to the reduced vectors. ``pk`` applies the same PC
to its gradient on the free variables.
"""

from __future__ import annotations

import numpy as np


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
            y.setArray(self.shell.precondition(x.array_r))
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
