"""A Polonsky-Keer constrained conjugate gradient as a TAO Python type (scene/CLI name: ``pk``).

Solves min 1/2 p^T H p + b^T p subject to p >= 0 for a symmetric positive definite H (Polonsky & Keer,
Wear 1999, displacement-controlled form): conjugate gradients on the cells in contact (p > 0), projection
onto p >= 0 after each step, and cells with p = 0 and negative gap put back into contact with a
steepest-descent step (which restarts the conjugacy). The gap g = H p + b comes from TAO's gradient,
H t from TAO's Hessian matrix, so the type works for any such QP set up on a TAO object.

Preconditioned when the Hessian is petroll's shell matrix with an inverse circulant
(:class:`petroll.solver.influence.ShellInfluence`): the search direction is built from z = M g on the contact
cells, M the inverse of H's circulant approximation on the window (an unpadded FFT pair, about a quarter
of an application's FFT work), so the iteration count hardly grows with the grid (Hertz, load control:
29 against 123 iterations at 512^2 cells; docs/benchmarks.md).

Cost: one Hessian application per iteration plus one gradient evaluation; once the contact set stops
changing (no cell clipped or put back) the gap is updated as g - tau H t instead, so late iterations cost
one application. Stops when the natural residual max |min(p, g)| <= gatol (checked on a freshly computed
gap), the same measure petroll checks after every solve.
"""

from __future__ import annotations

import numpy as np


class PolonskyKeer:
    """Context of a TAO of type ``python``: ``tao.setType("python"); tao.setPythonContext(PolonskyKeer())``."""

    refresh = 25  # recompute the gap from scratch at least this often (round-off of the cheap update)

    def solve(self, tao) -> None:
        from mpi4py import MPI
        from petsc4py import PETSc

        p = tao.getSolution()
        hessian = tao.getHessian()[0]
        comm = p.getComm().tompi4py()
        gatol = tao.getTolerances()[0]
        max_it = tao.getMaximumIterations()
        g, t, r = p.duplicate(), p.duplicate(), p.duplicate()
        p.setArray(np.maximum(p.array_r, 0.0))
        precondition = getattr(hessian.getPythonContext() if hessian.getType() == "python" else None,
                               "precondition", lambda x: x)

        def gap():
            tao.computeGradient(p, g)

        def residual() -> float:
            local = np.abs(np.minimum(p.array_r, g.array_r)).max(initial=0.0)
            return comm.allreduce(float(local), op=MPI.MAX)

        gap()
        fresh = True
        previous_gz, conjugate, its = 1.0, False, 0
        reason = PETSc.TAO.Reason.DIVERGED_MAXITS
        while True:
            res = residual()
            if res <= gatol and not fresh:
                gap()  # confirm on an exact gap
                fresh, res = True, residual()
            tao.setIterationNumber(its)
            tao.monitor(its, 0.0, res, 0.0, 0.0)
            if res <= gatol:
                reason = PETSc.TAO.Reason.CONVERGED_GATOL
                break
            if its >= max_it:
                break
            its += 1
            pa, ga = p.array_r, g.array_r
            contact = pa > 0
            if not comm.allreduce(bool(contact.any()), op=MPI.LOR):
                self._first_step(p, g, t, r, hessian)  # nothing in contact yet: steepest descent
                gap()
                fresh, conjugate = True, False
                continue
            gc = np.where(contact, ga, 0.0)
            z = np.where(contact, precondition(gc), 0.0)  # the preconditioned gap on the contact cells
            gz = comm.allreduce(float(np.dot(gc, z)))
            beta = gz / previous_gz if conjugate else 0.0
            t.setArray(np.where(contact, z + beta * t.array_r, 0.0))
            previous_gz = gz
            hessian.mult(t, r)
            ta, ra = t.array_r, r.array_r
            num = comm.allreduce(float(np.dot(ga[contact], ta[contact])))
            den = comm.allreduce(float(np.dot(ra[contact], ta[contact])))
            if den <= 0:
                break
            tau = num / den
            new = pa - tau * ta
            clipped = new < 0
            new[clipped] = 0.0
            reenter = (new == 0) & (ga < 0)
            new[reenter] -= tau * ga[reenter]
            changed = comm.allreduce(bool(clipped.any() or reenter.any()), op=MPI.LOR)
            p.setArray(new)
            conjugate = not changed
            if changed or its % self.refresh == 0:
                gap()
                fresh = True
            else:
                g.axpy(-tau, r)  # exact for an unchanged contact set, up to round-off
                fresh = False
        tao.setIterationNumber(its)
        tao.setConvergedReason(reason)
        for v in (g, t, r):
            v.destroy()

    @staticmethod
    def _first_step(p, g, d, hd, hessian) -> None:
        """p = alpha max(-g, 0), alpha the exact minimiser along that direction."""
        d.setArray(np.maximum(-g.array_r, 0.0))
        hessian.mult(d, hd)
        dd, dhd = d.dot(d), d.dot(hd)
        p.setArray(d.array_r * (dd / dhd if dhd > 0 else 0.0))
