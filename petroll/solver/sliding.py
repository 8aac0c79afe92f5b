"""Steady sliding on a periodic grid solved directly: the pressure of a body sliding at a constant velocity
over a viscoelastic half-space (or layer), without the transient.

In the body's frame the pressure is stationary. A material point sees each of its Fourier modes
p_k e^{i k.xi} (xi = x - s(t), the body at s = V t) as a pressure oscillating from step to step by
z = e^{-i k.V dt}; the run's time integrator ([solver] integrator, steps of dt) answers it with
W = H(z) p (petroll.solver.history.transfer), so the surface displacement is

    w_k = S_k p_k,      S_k = A_k H(e^{-i k.V dt}),

A_k the grid's periodic kernel (petroll.solver.kernels.periodic, unit compliance). As dt -> 0 H tends to
the complex compliance J*(-k.V); with the body crossing one cell per step along X or Y it is exactly the
steady state the transient run converges to (the DFT shifts samples by whole cells exactly).

S is not even (Im H is odd in k: the displacement lags the pressure), so the contact conditions p >= 0,
g = K p + Z - delta >= 0, p g = 0 (K = F^-1 diag(S) F) are a linear complementarity problem that no QP
states. Its solution is the fixed point of

    p <- QP_M(Z + (K - M) p),      M = F^-1 diag(|S|^2 / Re S) F,

each step a contact QP with the symmetric positive definite Hessian M (petroll's contact solver: pk, the
exact inverse of M as its preconditioner, load control inside it). Since S / m = cos(phi) e^{i phi}
(phi_k the loss angle of mode k), |S - m| / m = |sin phi| < 1 for every mode: the map is a contraction in
the M norm (a projection onto the constraints and a linear map of norm max |sin phi_k|). It is not
iterated to convergence: a first QP (to 0.1) gives a contact set, from which a primal-dual active set
method finds the complementarity solution directly (:meth:`SteadySliding._active_set`: each contact set's
equations K_CC p_C = delta - Z_C, with the force's row under load control, solved by GMRES (PETSc's KSP, petroll.solver.petsc) preconditioned
by R K^-1 R^T; the set then loses its cells of negative pressure and gains those of negative gap, until it
holds). A step of the fixed point, its QP solved to 1 % of the tolerance, confirms the answer: the solve
ends when that step changes the pressure by less than the tolerance (else the active set method starts
again from the QP's contact).
"""

from __future__ import annotations

import copy
import math

import numpy as np
from mpi4py import MPI

from petroll.errors import SolverError
from petroll.solver.contact import ContactSolver
from petroll.solver.history import Transfer
from petroll.solver.influence import Convolution
from petroll.solver.kernels.periodic import Spectral
from petroll.solver.petsc import gmres
from petroll.solver.steady import steady_step

FORMS = ("operator", "modulus", "lag", "newton", "dissipation")
"""The kernels of the steady sliding solve, each A_k times a factor of H (class SlidingKernel)."""


class SlidingKernel(Spectral):
    """One of the steady sliding solve's kernels on a periodic ``base`` kernel, for the velocity
    ``velocity`` (m/s, along the base's Fourier axes only) and the material's integrator at steps of dt,
    H its ``transfer`` (a :class:`~petroll.solver.history.Transfer`, which the kernels of one solve share:
    they ask H at the same modes): with S = A H, ``form`` "operator": S; "modulus": |S|^2 / Re S = A |H|^2 / Re H (symmetric positive
    definite, real); "lag": S - modulus; "newton": conj(H) / Re H alone (no A: a multiplier of the modes,
    identity in real space along a non-Fourier axis; after M^-1 it gives K^-1); "dissipation": (k.e) Im S,
    e the direction of motion, k.e at the frequency the integrator sees: its phase per step k.V dt brought
    into (-pi, pi] (k.e itself where |k.V dt| <= pi: along an axis, at most one cell per step), so that
    (k.e) Im H >= 0 for every mode (the integrator's loss); real and even, (k.e) and Im H being odd in k;
    the material's power under a pressure p is V sum p (D p) dA (:meth:`SteadySliding.dissipated`). Where
    a mode is its own conjugate (2 m = 0 mod n along every Fourier axis) the real part is taken (a real
    field's transform is real there)."""

    def __init__(self, base: Spectral, transfer: Transfer, velocity, form: str):
        super().__init__(base.dx, base.dy, base.nx, base.ny, base.fourier)
        self.base, self.form = base, form
        self.even = form in ("modulus", "dissipation")
        self.transfer, self.velocity, self.dt = transfer, tuple(velocity), transfer.dt

    def factor(self, ax, ay) -> np.ndarray:
        """The form's factor of H at (ax, ay) (frequency indices along the Fourier axes)."""
        mx = np.asarray(ax) if self.fourier[0] else np.zeros(1, int)
        my = np.asarray(ay) if self.fourier[1] else np.zeros(1, int)
        kx, ky = self.wavenumbers(mx, my)
        phase = -(kx * self.velocity[0] + ky * self.velocity[1]) * self.dt
        h = self.transfer(np.exp(1j * phase))
        own = np.ones(h.shape, dtype=bool)  # self-conjugate modes
        for m, n, fourier in ((mx, self.nx, self.fourier[0]), (my, self.ny, self.fourier[1])):
            if fourier:
                own = own & ((2 * m) % n == 0)
        h = np.where(own, h.real, h)
        if self.form == "operator":
            return h
        if self.form == "dissipation":  # k.e, at the frequency the integrator sees (its phase per step)
            return -np.angle(np.exp(1j * phase)) / (math.hypot(*self.velocity) * self.dt) * h.imag
        modulus = np.abs(h) ** 2 / h.real
        if self.form == "modulus":
            return modulus
        return h - modulus if self.form == "lag" else np.conj(h) / h.real

    def values(self, ax, ay) -> np.ndarray:
        factor = self.factor(ax, ay)
        if self.form == "newton":
            if all(self.fourier):
                return factor
            offset = np.asarray(ay if self.fourier[0] else ax)
            return np.where(offset == 0, factor, 0.0)
        return self.base.values(ax, ay) * factor


class ContactSystem:
    """The steady contact's linear equations on a contact set C, K_CC p_C - delta 1 = -Z_C (the gap closed
    on C), the unknowns the pressures on C (this rank's cells of C in order), bordered under load control
    by the force's row sum p_C = the held pressures' sum (Pa). The last unknown (rank 0's) is then
    delta / c (Pa), c the operator's diagonal (m/Pa), and the force's row is scaled by c / |C|.
    :meth:`mult` applies the equations' matrix, :meth:`apply` its preconditioner: R P R^T on C, P =
    ``inverse`` an approximate inverse of K (m -> Pa), and 1 / c to the force's row. Both map this rank's
    unknowns (numpy arrays) collectively over ``comm``; GMRES runs on them in petroll.solver.petsc."""

    def __init__(self, operator, inverse, shape: tuple[int, int], comm, border: bool):
        self.operator, self.inverse, self.shape, self.comm = operator, inverse, shape, comm
        self.border, self.c = border, float(operator.diagonal)
        self.cells, self.weight = np.zeros(0, dtype=np.intp), 1.0
        self.applications = 0  # of the operator

    def set_contact(self, contact: np.ndarray) -> tuple[int, int]:
        """Pose the equations on ``contact`` (this rank's cells): (this rank's, the global) number of
        unknowns."""
        self.cells = np.flatnonzero(contact)
        local = len(self.cells) + int(self.border and self.comm.rank == 0)
        total = self.comm.allreduce(local)
        self.weight = self.c / max(1, total - int(self.border))
        return local, total

    def field(self, values: np.ndarray) -> np.ndarray:
        """The grid field (this rank's rows) that is ``values`` on C and 0 elsewhere."""
        out = np.zeros(self.shape)
        out.ravel()[self.cells] = values[: len(self.cells)]
        return out

    def mult(self, a: np.ndarray) -> np.ndarray:
        n = len(self.cells)
        self.applications += 1
        out = np.empty(len(a))
        out[:n] = self.operator(self.field(a)).ravel()[self.cells]
        if self.border:
            delta, total = self.comm.allreduce(np.array([a[n] if len(a) > n else 0.0, a[:n].sum()]))
            out[:n] -= self.c * delta
            if len(out) > n:
                out[n] = self.weight * total
        return out

    def apply(self, a: np.ndarray) -> np.ndarray:
        n = len(self.cells)
        out = np.empty(len(a))
        out[:n] = self.inverse(self.field(a)).ravel()[self.cells]
        if len(out) > n:
            out[n] = a[n] / self.c
        return out


class SteadySliding:
    """The steady sliding state of ``scene`` at its constant velocity (m/s, taken at t = 0) with the
    integrator's step dt (petroll.solver.steady.steady_step): :meth:`solve` (collective over the comm of
    ``solver``, the scene's contact solver, whose operator's kernel is the grid's periodic kernel A_k).
    ``tol``: the fixed point's largest change of the pressure between iterations, relative to its peak,
    at which it stops (``steady``: unused; the fixed point ends at ``tol``). A steady solve of
    petroll.solver.steady_state (``velocity``, ``direction``, ``speed``, ``profile``, ``iterations``).

    The QPs are solved by a ContactSolver of its own on the modulus kernel M (compliance 1: the kernel holds
    the material's; the scene's [solver] tol); the active set method's equations by GMRES (PETSc KSP,
    petroll.solver.petsc.gmres) on a :class:`ContactSystem`."""

    SWEEPS = 30
    """Contact sets one active set solve (:meth:`_active_set`) tries before the fixed point's QP resumes."""

    def __init__(self, scene, solver: ContactSolver, tol: float, steady: float | None = None):
        self.scene, self.comm, self.tol = scene, solver.comm, tol
        comm, kernel = solver.comm, solver.influence.kernel
        g, material, integrator = scene.grid, scene.material, scene.solver.integrator
        velocity, dt = steady_step(scene)
        self.speed = float(np.hypot(*velocity))
        self.velocity, self.direction = velocity, velocity / self.speed
        sx, sy = scene.position
        self.profile = scene.body.height(*g.offsets(g.x[solver.r0 : solver.r1, None], g.y[None, :], sx, sy))

        transfer = Transfer(material, integrator, dt)  # H at the grid's modes, once for every form

        def make(form):
            return SlidingKernel(kernel, transfer, velocity, form)

        self.qp = ContactSolver(g, comm, tao_type=scene.solver.tao_type, tol=scene.solver.tol,
                                kernel=make("modulus"))
        self.operator = Convolution(make("operator"), g.nx, g.ny, comm, workers=self.qp.workers)
        self.lag = Convolution(make("lag"), g.nx, g.ny, comm, workers=self.qp.workers)
        self.loss = Convolution(make("dissipation"), g.nx, g.ny, comm, workers=self.qp.workers)
        newton = Convolution(make("newton"), g.nx, g.ny, comm, workers=self.qp.workers)
        self.system = ContactSystem(self.operator, self._inverse(newton), self.qp.local_shape, comm,
                                    scene.penetration is None)
        self.iterations = 0  # fixed-point steps (QPs) of the last solve

    def _inverse(self, newton: Convolution):
        """K^-1 (Pa per m): the ``newton`` multiplier M / S after the QP's inverse of M, one multiplier
        where both transform alike (a grid periodic along both axes)."""
        g = self.scene.grid
        m_inverse = self.qp.influence.window(g.nx, g.ny, inverse=True)
        if (m_inverse.lx, m_inverse.ly) == (newton.lx, newton.ly):
            fused = copy.copy(newton)
            fused.spectrum = newton.spectrum * m_inverse.spectrum
            return fused
        return lambda x: newton(m_inverse(x))

    def _closed(self, profile, pressure, delta, total, contact, target):
        """The pressure (Pa) and penetration (m) that close the gap on ``contact`` (under load control the
        pressures summing to ``total``, Pa), by GMRES (restarted every 30 iterations, right-preconditioned:
        its residual is the equations') from ``pressure`` and ``delta``, stopped once the residual (m) is at
        most max(r times the first, a), (r, a) = ``target`` of the right-hand side's norm (m)."""
        system, penetration = self.system, self.scene.penetration
        sizes = system.set_contact(contact)
        n = len(system.cells)
        fixed = float(penetration(0.0)) if penetration is not None else 0.0
        x, b = np.empty(sizes[0]), np.empty(sizes[0])
        x[:n] = pressure.ravel()[system.cells]
        b[:n] = fixed - profile.ravel()[system.cells]
        if len(x) > n:
            x[n], b[n] = delta / system.c, system.weight * total
        x, reason, its = gmres(system.mult, system.apply, sizes, self.comm, x, b, target)
        if reason < 0:
            raise SolverError(f"GMRES on the steady sliding contact's equations did not converge (reason "
                              f"{reason} after {its} iterations)")
        if penetration is None:
            fixed = self.comm.bcast(x[n] * system.c if len(x) > n else None, root=0)
        return system.field(x), fixed

    def _active_set(self, profile, pressure, delta, total, gap_tol, tol):
        """The contact pressure (Pa) and penetration (m) by a primal-dual active set method from the
        contact of ``pressure``: on a contact set C the gap is closed (:meth:`_closed`, to 1e-2 of its first
        residual); then C loses its cells of negative pressure and gains those of gap below -``gap_tol``
        (m), until it holds; the last set's equations are then solved to ``tol`` times the right-hand
        side's norm. After :attr:`SWEEPS` sets, the last one's answer (the caller's QP goes on)."""
        contact, x, tight = pressure > 0, pressure, False
        for _ in range(self.SWEEPS):
            x, delta = self._closed(profile, x, delta, total, contact,
                                    (lambda norm: (0.0, tol * norm)) if tight else (lambda norm: (1e-2, 0.0)))
            gap = self.operator(x) + profile - delta
            self.system.applications += 1
            new = (contact & (x > 0)) | (~contact & (gap < -gap_tol))
            changed = self.comm.allreduce(int(np.count_nonzero(new != contact)))
            if changed == 0 and tight:
                break
            tight, contact = changed == 0, new
        return np.where(contact, np.maximum(x, 0.0), 0.0), delta

    def solve(self, start: tuple[np.ndarray, float | None] | None = None, max_iterations: int = 500):
        """The steady pressure (Pa, this rank's rows) for the body's heights :attr:`profile`, under the
        scene's constant load or penetration: a StepSolution of the last QP, whose pressure is the fixed
        point's to ``tol`` (its largest change over a fixed-point step, relative to its peak), and the
        surface displacement w = K p (m). ``start``: a first guess (a pressure, Pa, on the whole grid or
        this rank's rows, and its penetration, m, or None), e.g. a neighbouring speed's steady state. Its
        ``applications`` count the QPs' and the active set solves' operator applications."""
        scene, solver, comm, profile, tol = self.scene, self.qp, self.comm, self.profile, self.tol
        x = np.zeros(solver.local_shape) if start is None else solver.own_rows(start[0]).copy()
        delta = None if start is None else start[1]
        work, applications = list(solver.work), self.system.applications
        solution, scale, change = None, 1.0, math.inf
        try:
            for self.iterations in range(1, max_iterations + 1):
                # the QPs' tolerance is in units of the scaled pressure p_hat = p A_00 / w_ref (w_ref: the
                # heights' range), whose peak is ``scale``: 1 % of tol (at least as tight as [solver] tol);
                # the first QP, which only finds a contact to start from, to 0.1
                final = min(scene.solver.tol, max(0.01 * tol * scale, 1e-13))
                solver.tol = final if solution is not None else max(final, 0.1)
                solution = self._qp(profile + self.lag(x), delta,
                                    x if solution is not None or start is not None else None)
                delta, p = solution.delta, solution.pressure
                extremes = np.array([np.abs(p - x).max(initial=0.0), p.max(initial=0.0),
                                     profile.max(initial=-np.inf), -profile.min(initial=np.inf)])
                comm.Allreduce(MPI.IN_PLACE, extremes, op=MPI.MAX)
                change = extremes[0] / extremes[1] if extremes[1] > 0 else 0.0
                spread = extremes[2] + extremes[3]
                scale = extremes[1] * solver.influence.diagonal / spread if spread > 0 else 1.0
                if change <= tol and self.iterations > 1:
                    break
                x, delta = self._active_set(profile, p, delta, comm.allreduce(float(p.sum())),
                                            0.01 * tol * scale * spread, 1e-3 * tol)
            else:
                raise SolverError(f"the steady sliding solve did not converge within {max_iterations} "
                                  f"iterations (last change {change:.3g} of the peak pressure)")
        finally:
            solver.tol = scene.solver.tol
        solution.iterations = solver.work[0] - work[0]
        solution.applications = solver.work[1] - work[1] + self.system.applications - applications
        return solution, self.operator(solution.pressure)

    def dissipated(self, pressure: np.ndarray) -> float:
        """The power (W; line contact W/m) the material dissipates under the steady ``pressure`` (Pa, this
        rank's rows): the work of the pressure on the surface's displacement as each material point sees it
        change, mean(p dw/dt) over the cell times its area, w's modes oscillating at k.V (module
        docstring), V sum_k |p_k|^2 (k.e) Im S_k = V sum p (D p) dA with D the "dissipation" kernel
        (SlidingKernel): >= 0 for a dissipative material, each mode's (k.e) Im H being >= 0, and 0 for an
        elastic one (H real).
        On the contact w = delta - Z, so in the continuum it is the lateral force's power V sum p dZ/dx dA;
        on the grid they differ where the spectral derivative of w across the contact's edges does (the
        discretisation's difference; equal in full contact). Collective."""
        power = float((pressure * self.loss(pressure)).sum()) * self.scene.grid.cell_area * self.speed
        return self.comm.allreduce(power)

    def _qp(self, height, delta, warm):
        """A fixed-point step's contact QP on the modulus kernel for ``height`` (m), warm from ``warm`` (Pa,
        or None), its penetration from ``delta`` (m) under load control."""
        scene, solver = self.scene, self.qp
        if scene.penetration is not None:
            return solver.solve_penetration(height, 1.0, float(scene.penetration(0.0)), warm)
        return solver.solve_load(height, 1.0, float(scene.load(0.0)), scene.body.radius_hint, delta, warm)
