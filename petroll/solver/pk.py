"""A Polonsky-Keer constrained conjugate gradient as a TAO Python type (scene/CLI name: ``pk``).

Solves min f(x) = 1/2 x^T H x + b^T x + c subject to the variable bounds set on the TAO (lower <= x <=
upper, any mix of finite and infinite values; a side TAO holds no vector for: the context's uniform
``bounds``, by default unconstrained) for a symmetric positive definite H
(Polonsky & Keer, Wear 1999, displacement-controlled form, here for two-sided bounds): conjugate gradients
on the free variables (strictly between their bounds), projection onto the bounds after each step, and
variables at a bound whose gradient points into the box put back with a steepest-descent step (which,
like any change of the free set, restarts the conjugacy). With a preconditioner C^-1 the conjugate step tau
is in its units: the steepest-descent step is tau <g, C^-1 g> / <g, g> over the free variables (the same
first-order decrease; tau itself let the active set of a periodic rough contact thrash without end, its
objective never falling: 10000 iterations against 100). f and its gradient come from TAO's
objective-gradient routine, H t from TAO's Hessian matrix: the type works for any such QP set up on a TAO.
It ends with TAO's gradient vector holding the gradient at the solution (see Cost for its round-off).

Preconditioned by the PC of the TAO's KSP (KSP type ``preonly``: one PC application per iteration,
restricted to the free variables; PC type ``none`` by default, options prefix the TAO's). petroll's
contact solver sets it to the inverse circulant of the window's kernel
(:class:`petroll.solver.petsc.CirculantInverse`), so the iteration count hardly grows with the grid
(Hertz at 154^2 cells, cold: 30 against 72 applications without it; docs/benchmarks.md).

Cost: one Hessian application per iteration plus one objective-gradient evaluation; once the free set
stops changing (no variable clipped or put back) the gradient and f are updated exactly for a quadratic
(g - tau H d, f - tau g.d + tau^2 d.Hd / 2) instead, so late iterations cost one application; the
gradient is recomputed at least every ``-tao_pk_refresh`` (25) iterations, so that an updated gradient
differs from a fresh one by round-off only (about 1e-15 of its scale, far below any useful gatol): the
stop is judged on it, with no confirming evaluation (which would cost one application per solve).
Beside its applications an iteration streams its vectors through memory in five passes (the free set,
the free gradient, <g, g> and the residual, the gradient's update folded in; <g, C^-1 g>; the direction;
d.g and d.H d; the step, projection and re-entries); under load control six (the first sums g over the free
set, a second shifts it by the multiplier and takes <g, g> and the residual), each doing all its work
on a block of :data:`BLOCK` values before the next block: about 20 reads and writes of a vector's length
per iteration, and no work array of that length but the free set's mask (g - lambda is made a block at a
time). Dots and sums are summed per block by numpy (one thread; the last digits depend on BLOCK).

Load control (Polonsky & Keer's force-controlled form): with ``total`` set on the context, the solve also
holds sum x = total (bounds must then be x >= 0, no upper bound). Its multiplier lambda (the mean gradient
over the free variables; for the contact QP, the change of penetration) shifts the gradient, g - lambda,
in everything above: directions are projected onto sum d = 0 over the free variables, variables clipped or
put back are followed by a rescaling x <- x total / sum x. It is left in ``multiplier``; TAO's gradient
vector holds g, and g - lambda is the gradient of the Lagrangian.

Reports to TAO's monitors each iteration the true objective f and, as the residual, the projected
gradient r = x - P(x - (g - lambda)) (P the projection onto the bounds) in the max norm, and stops on TAO's
three tolerances applied to it: |r| <= gatol (CONVERGED_GATOL), |r| <= grtol |f| (CONVERGED_GRTOL; f != 0),
|r| <= gttol |r_0| (CONVERGED_GTTOL; r_0 the first iterate's), each only where it is > 0; TAO's defaults
are gatol = grtol = 1e-8, gttol = 0 (-tao_gatol, -tao_grtol, -tao_gttol). Every objective-gradient
evaluation goes through TAO (``computeObjectiveGradient``), so TAO's counter of function/gradient
evaluations (``-tao_view``) holds them, and -tao_max_funcs limits them. Other reasons: DIVERGED_MAXITS
(the iteration limit), DIVERGED_MAXFCN (the objective-gradient evaluation limit), DIVERGED_NAN (a
non-finite f or gradient), DIVERGED_USER (a search direction of zero or negative curvature, d^T H d <= 0:
H is not positive definite; the context's ``breakdown`` says so in words).
"""

from __future__ import annotations

import numpy as np

BLOCK = 1 << 16
"""Values per block of an iteration's fused passes: each pass over the vectors does all its elementwise work
on one block (a 512 KiB slice of each vector, several of them in the cache) before the next, so that a
vector is streamed from memory about once per pass rather than once per numpy call."""

PK_PYTHON_TYPE = "petroll.solver.pk.PolonskyKeer"
"""pk's name for TAO: -<prefix>tao_type python -<prefix>tao_python_type petroll.solver.pk.PolonskyKeer."""


def command_line(args: list[str]) -> list[str]:
    """PETSc command-line arguments with every ``-<prefix>tao_type pk`` spelt as TAO knows pk (above)."""
    out = []
    for arg in args:
        if arg == "pk" and out and out[-1].endswith("tao_type") and out[-1].startswith("-"):
            out += ["python", f"{out[-1][:-len('type')]}python_type", PK_PYTHON_TYPE]
        else:
            out.append(arg)
    return out


class PolonskyKeer:
    """Context of a TAO of type ``python``: ``tao.setType("python"); tao.setPythonContext(PolonskyKeer())``
    (or ``-tao_type python -tao_python_type petroll.solver.pk.PolonskyKeer``)."""

    def __init__(self, bounds: tuple[float, float] = (-np.inf, np.inf)):
        self.refresh = 25  # recompute the gradient from scratch at least this often (-tao_pk_refresh)
        self.breakdown = ""  # why the last solve stopped with DIVERGED_USER, in words
        self.total = None  # load control: sum x held at this value (None: no such constraint)
        self.multiplier = 0.0  # its multiplier lambda at the last solve's end (0 without it)
        # (lower, upper): uniform bounds for a side on which TAO holds no bound vector (a vector costs 8 bytes
        # per variable; petroll's contact QP gives (0, inf) here and no vectors)
        self.bounds = bounds

    def setFromOptions(self, tao) -> None:
        """-<prefix>tao_pk_refresh N; the KSP (prefix the TAO's) is ``preonly`` and its PC ``none`` unless
        -<prefix>ksp_type / -<prefix>pc_type say otherwise."""
        from petsc4py import PETSc

        prefix = tao.getOptionsPrefix() or ""
        self.refresh = PETSc.Options(prefix).getInt("tao_pk_refresh", self.refresh)
        ksp = tao.getKSP()
        ksp.setOptionsPrefix(prefix)
        if ksp.getType() != "preonly" and not PETSc.Options(prefix).hasName("ksp_type"):
            ksp.setType("preonly")
        if not PETSc.Options(prefix).hasName("pc_type") and ksp.getPC().getType() is None:
            ksp.getPC().setType("none")
        ksp.setFromOptions()

    def view(self, tao, viewer) -> None:
        pc = tao.getKSP().getPC()
        lines = ["Polonsky-Keer conjugate gradients projected onto the variable bounds",
                 f"preconditioner: {pc.getType() or 'none'} (the KSP's PC below, applied once per iteration "
                 "to the free variables' gradient)",
                 "load control: sum x = total when the context's total is set (now: "
                 f"{'none' if self.total is None else format(self.total, '.6g')})",
                 "restart: conjugacy restarted whenever a variable reaches or leaves a bound; gradient "
                 f"recomputed at least every {self.refresh} iterations (-tao_pk_refresh)",
                 "step: exact minimiser along each direction, then projection (no line search: the "
                 "TaoLineSearch below is petsc4py's default for Python types and unused)",
                 "residual: max norm of the projected gradient r = x - P(x - g); stops at |r| <= gatol, "
                 "grtol |f| or gttol |r_0| (those > 0)"]
        for line in lines:
            viewer.printfASCII(f"  {line}\n")

    def solve(self, tao) -> None:
        from mpi4py import MPI
        from petsc4py import PETSc

        Reason = tao_reasons()
        x = tao.getSolution()
        hessian = tao.getHessian()[0]
        comm = x.getComm().tompi4py()
        gatol, grtol, gttol = tao.getTolerances()
        max_it, max_fev = tao.getMaximumIterations(), tao.getMaximumFunctionEvaluations()
        box = _Box(*self._bounds(tao, x, self.bounds))
        pc = tao.getKSP().getPC()
        preconditioned = pc.getType() not in (None, "none")
        if preconditioned:
            pc.setOperators(hessian, hessian)
            pc.setUp()
        g = tao.getGradient()[0]  # left holding the gradient at the solution
        own = [] if g.handle else [x.duplicate()]  # none given to TAO: a vector of its own
        g = own[0] if own else g
        # three work vectors: d the direction; hd the free gradient, then H d; z C^-1 of the free gradient
        d, hd, z = (x.duplicate() for _ in range(3))
        n = x.getLocalSize()
        # the free set, and a block's work arrays (g - lambda, the residual, products, a mask)
        free = np.empty(n, dtype=bool)
        blocks = [slice(i, min(i + BLOCK, n)) for i in range(0, n, BLOCK)]
        ga_b, r_b, p_b, free_b = (np.empty(min(n, BLOCK)) for _ in range(4))
        mask_b = np.empty(min(n, BLOCK), dtype=bool)
        with x as xw:
            box.project(xw, slice(None))
        self.breakdown = ""

        def total(value) -> float:
            return comm.allreduce(float(value))

        def dot(a: np.ndarray, b: np.ndarray) -> float:
            """a . b of two blocks, by numpy's pairwise sum on one thread (a threaded BLAS dot costs 10 times
            more on a block in the cache when the cores are busy, and its sum depends on the thread count)."""
            return float(np.multiply(a, b, out=p_b[:a.size]).sum())

        def ones(s: slice) -> np.ndarray:
            """The free set on the block s as 1.0 and 0.0 (in free_b): numpy multiplies by a float mask 3
            times faster than by a boolean one, and a ufunc's where= or a masked sum is 30 times slower."""
            out = free_b[:s.stop - s.start]
            np.copyto(out, free[s])
            return out

        def shifted(ga: np.ndarray, s: slice, lam: float) -> np.ndarray:
            """g - lambda on the block s (in ga_b; g itself without load control)."""
            if not lam:
                return ga[s]
            return np.subtract(ga[s], lam, out=ga_b[:s.stop - s.start])

        load = self.total
        if load is not None:
            if not box.nonnegative or not load >= 0:
                raise ValueError("pk: load control (total) needs bounds x >= 0 and total >= 0")
            held = total(x.array_r.sum())
            if held > 0:
                x.scale(load / held)
            else:  # uniform
                x.set(load / x.getSize())

        evaluations = 0

        def evaluate() -> float:
            nonlocal evaluations
            evaluations += 1
            return tao.computeObjectiveGradient(x, g)

        f = evaluate()
        conjugate, previous_gz, its, step, first = False, 1.0, 0, 0.0, None
        lam, pending = 0.0, 0.0  # pending: a step whose g - step H d is still to be made (H d in hd)
        while True:
            xa = x.array_r
            # g - pending H d; the free set, the gradient there into hd (0 elsewhere); without load control
            # (no multiplier) also <gf, gf> and the residual's max norm
            count, gsum, gg, res = 0, 0.0, 0.0, 0.0
            with hd as gf, g as gw:
                for s in blocks:
                    if pending:
                        gw[s] -= pending * gf[s]
                    box.free(xa[s], free[s], s)
                    count += np.count_nonzero(free[s])
                    np.multiply(gw[s], ones(s), out=gf[s])
                    if load is None:
                        gg += dot(gf[s], gf[s])
                        res = max(res, box.residual(xa[s], gw[s], r_b[:s.stop - s.start], s))
                    else:
                        gsum += gf[s].sum()
            count = total(count)
            lam = self._multiplier(comm, total(gsum), g.array_r, count)
            if load is not None:  # gf -= lambda on the free variables; <gf, gf>; the residual's max norm
                with hd as gf:
                    ga = g.array_r
                    for s in blocks:
                        gfs = gf[s]
                        if lam:
                            gfs -= np.multiply(ones(s), lam, out=r_b[:s.stop - s.start])
                        gg += dot(gfs, gfs)
                        res = max(res, box.residual(xa[s], shifted(ga, s, lam), r_b[:s.stop - s.start], s))
            res = comm.allreduce(res, op=MPI.MAX)
            first = res if first is None else first
            tao.setIterationNumber(its)
            tao.monitor(its, f, res, 0.0, step)
            if not (np.isfinite(f) and np.isfinite(res)):
                reason = Reason.DIVERGED_NAN
            elif res <= gatol:
                reason = Reason.CONVERGED_GATOL
            elif grtol > 0 and f != 0 and res <= grtol * abs(f):
                reason = Reason.CONVERGED_GRTOL
            elif gttol > 0 and res <= gttol * first:
                reason = Reason.CONVERGED_GTTOL
            elif its >= max_it:
                reason = Reason.DIVERGED_MAXITS
            elif 0 <= max_fev <= evaluations:  # a negative limit: none
                reason = Reason.DIVERGED_MAXFCN
            else:
                reason = Reason.CONTINUE_ITERATING
            if reason != Reason.CONTINUE_ITERATING:
                break
            its += 1
            gf = hd.array_r
            gg = total(gg)
            steepest = not gg > 0
            if not steepest:  # conjugate gradients on the free variables
                if preconditioned:
                    pc.apply(hd, z)
                else:
                    hd.copy(z)
                # d <- the free part of C^-1 gf (z), less its mean there under load control, + beta d;
                # <gf, z - mean> = <gf, z>: gf sums to 0 over the free variables (lambda is its mean there)
                za, gz, zsum = z.array_r, 0.0, 0.0
                for s in blocks:
                    gz += dot(gf[s], za[s])
                    if load is not None:
                        zsum += dot(za[s], ones(s))
                mean = total(zsum) / count if load is not None else 0.0
                gz = total(gz)
                beta = gz / previous_gz if conjugate else 0.0  # conjugate: none clipped, none put back
                with d as da:
                    for s in blocks:
                        zs = np.subtract(za[s], mean, out=r_b[:s.stop - s.start]) if mean else za[s]
                        if conjugate:
                            da[s] *= beta
                            da[s] += zs
                        else:
                            da[s] = zs
                        da[s] *= ones(s)
                previous_gz = gz
            else:  # nothing free, or a stationary free part: projected steepest descent
                with d as da:
                    for s in blocks:
                        box.residual(xa[s], shifted(g.array_r, s, lam), da[s], s)
            hessian.mult(d, hd)
            da, hda, ga = d.array_r, hd.array_r, g.array_r
            gd, dhd = 0.0, 0.0
            for s in blocks:
                gd += dot(shifted(ga, s, lam), da[s])
                dhd += dot(da[s], hda[s])
            gd, dhd = total(gd), total(dhd)
            if not dhd > 0:
                reason = Reason.DIVERGED_NAN if not np.isfinite(dhd) else Reason.DIVERGED_USER
                self.breakdown = (f"breakdown at iteration {its}: d^T H d = {dhd:.3g} along a search direction "
                                  "(the Hessian is not positive definite)")
                break
            step = gd / dhd
            # the step along the gradient of a direction preconditioned by C^-1: scaled by <g, C^-1 g> / <g, g>
            # (the same first-order decrease as the conjugate step's)
            along = step if steepest else step * gz / gg
            # x - step d, projected, re-entries put back
            clipped, back, held = False, 0, 0.0
            with x as new:
                ga = g.array_r
                for s in blocks:
                    xs, gs, m = new[s], shifted(ga, s, lam), mask_b[:s.stop - s.start]
                    xs -= step * da[s]
                    clipped = clipped or box.outside(xs, s)
                    box.project(xs, s)
                    box.reentering(xs, gs, m, s)
                    at = np.flatnonzero(m)
                    if at.size:
                        back += at.size
                        xs[at] = box.clip(xs[at] - along * gs[at], s, at)
                    held += xs.sum() if load is not None else 0.0
            changed = comm.allreduce(bool(back) or clipped, op=MPI.LOR)
            if changed and load is not None:
                x.scale(load / total(held))
            conjugate = not (changed or steepest)
            pending = 0.0
            if changed or its % self.refresh == 0:
                f = evaluate()
            else:  # exact for a quadratic and an unchanged free set, up to round-off (g: in the next pass)
                f += -step * gd + 0.5 * step * step * dhd
                pending = step
        self.multiplier = lam
        tao.setIterationNumber(its)
        tao.setConvergedReason(reason)
        for v in (d, hd, z, *own):
            v.destroy()

    def _multiplier(self, comm, gsum: float, g: np.ndarray, count: int) -> float:
        """lambda, the load constraint's multiplier: the mean gradient over the free variables (``gsum``: its
        sum there over all ranks; ``count`` of them), or without free variables the least gradient ``g``; 0
        without load control."""
        from mpi4py import MPI

        if self.total is None:
            return 0.0
        if count == 0:
            return comm.allreduce(float(g.min(initial=np.inf)), op=MPI.MIN)
        return gsum / count

    @staticmethod
    def _bounds(tao, x, uniform: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
        """This rank's lower and upper bounds (``uniform``'s where TAO has no bound vector); a bound that is
        the same for every variable (the contact QP's 0 and infinity) as a read-only broadcast of that
        value, which holds no array (16 bytes per variable less at the solve's peak)."""
        n = x.getLocalSize()
        return tuple(_bound(vector, n, side, value) for vector, side, value in zip(tao.getVariableBounds(),
                                                                                  (-np.inf, np.inf), uniform))


def _bound(vector, n: int, side: float, missing: float) -> np.ndarray:
    """One bound's values (``missing`` where TAO has no vector; ``side`` -inf for the lower bound, inf for
    the upper); PETSc's infinity (PETSC_INFINITY, PETSC_NINFINITY) is finite in floating point: made
    ``side`` (a value beyond 1e300 on its side)."""
    if vector is None or not vector.handle:
        return np.broadcast_to(float(missing), (n,))
    values, sign = vector.array_r, np.sign(side)
    if n and np.all(values == values[0]):
        value = float(values[0])
        return np.broadcast_to(side if value * sign >= 1e300 else value, (n,))
    values = values.copy()
    values[values * sign >= 1e300] = side
    return values


class _Box:
    """The bounds lo <= x <= hi (this rank's), the operations of an iteration on them for a block ``s`` (a
    slice of this rank's variables) of the arrays, written into given arrays; where the bounds are x >= 0
    alone (the contact QP's: ``nonnegative``) by comparisons with 0 and np.maximum (0.23 ms against clip's
    3.0 ms with array bounds, on 2 10^5 values)."""

    def __init__(self, lo: np.ndarray, hi: np.ndarray):
        self.lo, self.hi = lo, hi
        self.nonnegative = bool(np.all(lo == 0) and np.all(hi == np.inf))

    def project(self, v: np.ndarray, s: slice) -> None:
        """v <- P(v), the projection onto the bounds."""
        if self.nonnegative:
            np.maximum(v, 0.0, out=v)
        else:
            np.clip(v, self.lo[s], self.hi[s], out=v)

    def clip(self, values: np.ndarray, s: slice, at: np.ndarray) -> np.ndarray:
        """``values`` of the variables at the indices ``at`` of the block projected onto their bounds."""
        return np.clip(values, self.lo[s][at], self.hi[s][at])

    def free(self, x: np.ndarray, out: np.ndarray, s: slice) -> None:
        """out <- the variables strictly between their bounds."""
        np.greater(x, self.lo[s], out=out)
        if not self.nonnegative:
            out &= x < self.hi[s]

    def outside(self, v: np.ndarray, s: slice) -> bool:
        """Whether P changes any of the values ``v`` (one below lo or above hi)."""
        if self.nonnegative:
            return bool(v.min(initial=0.0) < 0)
        return bool(np.any(v < self.lo[s]) or np.any(v > self.hi[s]))

    def reentering(self, x: np.ndarray, g: np.ndarray, out: np.ndarray, s: slice) -> None:
        """out <- the variables at a bound whose gradient ``g`` points into the box."""
        np.less_equal(x, self.lo[s], out=out)
        out &= g < 0.0
        if not self.nonnegative:
            out |= (x >= self.hi[s]) & (g > 0)

    def residual(self, x: np.ndarray, g: np.ndarray, out: np.ndarray, s: slice) -> float:
        """out <- the projected gradient x - P(x - g); returns its max norm."""
        if self.nonnegative:  # x - max(x - g, 0) = min(x, g)
            np.minimum(x, g, out=out)
        else:
            np.subtract(x, g, out=out)
            self.project(out, s)
            np.subtract(x, out, out=out)
        return max(float(out.max(initial=0.0)), -float(out.min(initial=0.0)))


def tao_reasons():
    """TAO's converged/diverged reason constants: ``PETSc.TAO.ConvergedReason`` (petsc4py >= 3.20; what a
    PyPI build gives) or ``PETSc.TAO.Reason`` (petsc4py 3.18, Debian 12)."""
    from petsc4py import PETSc

    return getattr(PETSc.TAO, "ConvergedReason", None) or PETSc.TAO.Reason
