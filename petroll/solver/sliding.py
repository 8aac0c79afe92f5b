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
states. They are solved by the fixed point

    p <- QP_M(Z + (K - M) p),      M = F^-1 diag(|S|^2 / Re S) F,

each step a contact QP with the symmetric positive definite Hessian M (petroll's contact solver: pk, the
exact inverse of M as its preconditioner, load control inside it). Since S / m = cos(phi) e^{i phi}
(phi_k the loss angle of mode k), |S - m| / m = |sin phi| < 1 for every mode: the map is a contraction in
the M norm (a projection onto the constraints and a linear map of norm max |sin phi_k|). Its residual r
is mapped by the Newton-like step N r = R F^-1 diag(conj(S) / Re S) F R^T r on the contact cells (R the
restriction to them: the exact inverse of I - the map's Jacobian, M^-1 K, were every cell in contact) and
kept elsewhere, then Anderson-mixed. The QPs are solved inexactly (to 30 % of the last change of the
pressure: cheaper than tighter QPs over the whole solve, measured) until the change is below the
tolerance, then once more to 1 % of it.
"""

from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI

from petroll.errors import SolverError
from petroll.solver.contact import ContactSolver
from petroll.solver.history import transfer
from petroll.solver.influence import Convolution
from petroll.solver.kernels.periodic import Spectral
from petroll.solver.steady import Anderson

FORMS = ("operator", "modulus", "lag", "newton")
"""The kernels of the steady sliding solve, each A_k times a factor of H (class SlidingKernel)."""


class SlidingKernel(Spectral):
    """One of the steady sliding solve's kernels on a periodic ``base`` kernel, for the velocity
    ``velocity`` (m/s, along the base's Fourier axes only) and the material's integrator at steps of dt:
    with S = A H, ``form`` "operator": S; "modulus": |S|^2 / Re S = A |H|^2 / Re H (symmetric positive
    definite, real); "lag": S - modulus; "newton": conj(H) / Re H alone (no A: a multiplier of the modes,
    identity in real space along a non-Fourier axis). Where a mode is its own conjugate (2 m = 0 mod n
    along every Fourier axis) the real part is taken (a real field's transform is real there)."""

    def __init__(self, base: Spectral, material, integrator: str, velocity, dt: float, form: str):
        super().__init__(base.dx, base.dy, base.nx, base.ny, base.fourier)
        self.base, self.form = base, form
        self.even = form == "modulus"
        self.material, self.integrator, self.velocity, self.dt = material, integrator, tuple(velocity), dt

    def factor(self, ax, ay) -> np.ndarray:
        """The form's factor of H at (ax, ay) (frequency indices along the Fourier axes)."""
        mx = np.asarray(ax) if self.fourier[0] else np.zeros(1, int)
        my = np.asarray(ay) if self.fourier[1] else np.zeros(1, int)
        kx, ky = self.wavenumbers(mx, my)
        phase = -(kx * self.velocity[0] + ky * self.velocity[1]) * self.dt
        h = transfer(self.material, self.integrator, self.dt, np.exp(1j * phase))
        own = np.ones(h.shape, dtype=bool)  # self-conjugate modes
        for m, n, fourier in ((mx, self.nx, self.fourier[0]), (my, self.ny, self.fourier[1])):
            if fourier:
                own = own & ((2 * m) % n == 0)
        h = np.where(own, h.real, h)
        if self.form == "operator":
            return h
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


class SteadySliding:
    """The steady sliding state of one scene on ``comm``: ``solve(profile, ...)`` (collective).

    ``kernel``: the grid's periodic kernel (A_k); ``velocity`` (m/s) constant; ``dt`` the integrator's
    step (s); ``tol`` the solver's contact tolerance for the QPs. The QPs are solved by a ContactSolver on
    the modulus kernel M (compliance 1: the kernel holds the material's)."""

    def __init__(self, scene, comm, kernel: Spectral, velocity, dt: float):
        self.scene, self.comm = scene, comm
        g, material, integrator = scene.grid, scene.material, scene.solver.integrator

        def make(form):
            return SlidingKernel(kernel, material, integrator, velocity, dt, form)

        self.qp = ContactSolver(g, comm, tao_type=scene.solver.tao_type, tol=scene.solver.tol,
                                kernel=make("modulus"))
        self.operator = Convolution(make("operator"), g.nx, g.ny, comm, workers=self.qp.workers)
        self.lag = Convolution(make("lag"), g.nx, g.ny, comm, workers=self.qp.workers)
        self.newton = Convolution(make("newton"), g.nx, g.ny, comm, workers=self.qp.workers)
        self.iterations = 0  # fixed-point iterations of the last solve

    def solve(self, profile: np.ndarray, tol: float, max_iterations: int = 500,
              start: tuple[np.ndarray, float | None] | None = None):
        """The steady pressure (Pa, this rank's rows) for the body's heights ``profile`` (m, this rank's
        rows), under the scene's constant load or penetration: a StepSolution of the last QP, whose
        pressure is the fixed point's to ``tol`` (the largest change of the pressure between iterations,
        relative to its peak), and the surface displacement w = K p (m). ``start``: a first guess
        (this rank's rows of a pressure, Pa, and its penetration, m, or None), e.g. a neighbouring speed's
        steady state."""
        scene, solver, comm = self.scene, self.qp, self.comm
        x = np.zeros(solver.local_shape) if start is None else np.array(start[0], dtype=float)
        delta = None if start is None else start[1]
        mixer, work = Anderson(comm, depth=8), list(solver.work)
        change, solution, scale, last = math.inf, None, 1.0, False
        try:
            for self.iterations in range(1, max_iterations + 1):
                # the QPs' tolerance is in units of the scaled pressure p_hat = p A_00 / w_ref (w_ref: the
                # heights' range), whose peak is ``scale``: 30 % of the last change of the pressure, relative
                # to its peak, then 1 % of tol (at least as tight as [solver] tol) for the last one
                final = min(scene.solver.tol, max(0.01 * tol * scale, 1e-13))
                solver.tol = final if last else max(final, min(1e-1, 0.3 * change * scale))
                height = profile + self.lag(x)
                warm = solution.pressure if solution is not None else None if start is None else x
                if scene.penetration is not None:
                    solution = solver.solve_penetration(height, 1.0, float(scene.penetration(0.0)), warm)
                else:
                    solution = solver.solve_load(height, 1.0, float(scene.load(0.0)), scene.body.radius_hint,
                                                 delta, warm)
                delta, p = solution.delta, solution.pressure
                extremes = np.array([np.abs(p - x).max(initial=0.0), p.max(initial=0.0),
                                     height.max(initial=-np.inf), -height.min(initial=np.inf)])
                comm.Allreduce(MPI.IN_PLACE, extremes, op=MPI.MAX)
                change = extremes[0] / extremes[1] if extremes[1] > 0 else 0.0
                spread = extremes[2] + extremes[3]
                scale = extremes[1] * solver.influence.diagonal / spread if spread > 0 else 1.0
                if change <= tol and last:
                    break
                last = change <= tol  # confirmed by a QP solved to the final tolerance
                contact = p > 0
                step = np.where(contact, self.newton(np.where(contact, p - x, 0.0)), p - x)
                x = mixer.next(x, x + step)
            else:
                raise SolverError(f"the steady sliding solve did not converge within {max_iterations} "
                                  f"iterations (last change {change:.3g} of the peak pressure)")
        finally:
            solver.tol = scene.solver.tol
        solution.iterations = solver.work[0] - work[0]
        solution.applications = solver.work[1] - work[1]
        return solution, self.operator(solution.pressure)
