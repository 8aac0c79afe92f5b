"""Time integrators of the hereditary law (formulation §4): each turns step n+1 into an elastic-like problem.

Every integrator turns step n+1 into w = J_eff A p + A v: ``J_eff`` (1/Pa) and the *preceding
displacement* u = A v, with v a field in pressure space (Pa * 1/Pa = dimensionless times A's length): one
convolution per step, whatever the number of Prony terms.

Integrators (``[solver] integrator``):

- ``relaxation`` (Prony materials, the default): the relaxation form p = G * dW (G the convolution inverse
  of J, a Maxwell series) integrated exactly for a displacement W linear in time within a step; second
  order, and monotone: a held displacement relaxes exactly (no overshoot below the relaxed modulus, no
  ringing), whatever the step (docs/stability.md). State p^n and one field s_k per relaxation term.
- ``exponential`` (Prony materials): the creep form, exact for a *pressure* linear in time within a step;
  second order and stable, but after a sudden change of displacement with a step longer than about the
  relaxation time the pressure undershoots the relaxed value and rings (with E0/Einf = 1e4 the contact is
  lost at a fixed penetration); petroll refuses such steps (``guard``). State p^n and one field q_r per
  term.
- ``paper`` (Yin et al. 2015): J frozen at J(0) over the newest step, exact J for older increments;
  first order. For a Prony series the hereditary sum collapses to the same recursion as ``exponential``
  with beta_r = 1; for a tabulated J it is the full hereditary sum over all past increments.

A sudden start (the first step, t = 0) is the instantaneous response: J_eff = J(0).

Histories made by :func:`make_history` are *guarded*: at every new step length they run the integrator on
one cell held at a fixed displacement after a sudden start (:func:`holding_violation`) and refuse, with a
SolverError naming the largest safe step, a step at which the pressure leaves the bounds set by the
relaxed and instantaneous moduli by more than 1 % of their difference (unstable or ringing).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from petroll.errors import SolverError
from petroll.model.materials import Prony, relaxation_series

GUARD_VIOLATION = 0.01
"""The largest excursion of a held cell's pressure outside [1/Jinf, 1/J0], as a fraction of that range,
that a guarded history accepts (:func:`holding_violation`)."""



class History:
    """What every integrator shares: the guard against step lengths at which it cannot hold a penetration.

    Subclasses keep ``pressure`` (p^n, Pa, this rank's rows) and provide ``compliance(dt)`` (J_eff, 1/Pa),
    ``preceding(dt)`` (v with u = A v, or None) and ``advance(pressure, dt)``; ``dt = 0`` is a jump (the
    sudden first step). ``name`` is the integrator's (``[solver] integrator``), ``kind`` the state a
    checkpoint holds (petroll.io.checkpoint): "prony" (p^n and one field per term, plus W^n for the
    relaxation form) or "hereditary" (all past times and pressure increments).
    """

    name = ""
    kind = "prony"

    def __init__(self, material) -> None:
        self.material = material
        self.guard = False  # True (make_history): refuse step lengths at which the scheme cannot hold
        self._safe: set[float] = set()

    def guard_step(self, dt: float) -> None:
        """Raise SolverError if this integrator cannot hold a penetration at steps of dt (guarded only)."""
        if not self.guard or dt <= 0 or dt in self._safe:
            return
        _refuse_unsafe(self.material, self.name, dt)
        self._safe.add(dt)


class PronyHistory(History):
    """Creep-form state of a Prony material: p^n and one field q_r per term (formulation §4b).

    ``beta_one=True`` gives the paper's scheme (J frozen at J0 over the newest step), otherwise the
    exponential integrator.
    """

    def __init__(self, material: Prony, local_shape: tuple[int, int], beta_one: bool = False):
        super().__init__(material)
        self.beta_one = beta_one
        self.name = "paper" if beta_one else "exponential"
        self.pressure = np.zeros(local_shape)
        self.q = [np.zeros(local_shape) for _ in material.dJ]

    def _coefficients(self, dt: float):
        for d, tau in zip(self.material.dJ, self.material.tau):
            decay = math.exp(-dt / tau)
            beta = 1.0 if self.beta_one or dt == 0 else -math.expm1(-dt / tau) * tau / dt
            yield d, decay, beta

    def compliance(self, dt: float) -> float:
        """J_eff of the next step, of length dt (s)."""
        self.guard_step(dt)
        return self.material.Jinf - sum(d * beta for d, _, beta in self._coefficients(dt))

    def preceding(self, dt: float) -> np.ndarray | None:
        """v with u = A v for the next step (None: no history, u = 0)."""
        if not self.q:
            return None
        v = np.zeros_like(self.pressure)
        for (d, decay, beta), q in zip(self._coefficients(dt), self.q):
            v += d * (beta * self.pressure - decay * q)
        return v

    def advance(self, pressure: np.ndarray, dt: float) -> None:
        """Take the solved pressure of the step of length dt into the state."""
        for (_, decay, beta), q in zip(self._coefficients(dt), self.q):
            q *= decay
            q += beta * (pressure - self.pressure)
        self.pressure = pressure.copy()

    def restore(self, pressure: np.ndarray, q: list[np.ndarray]) -> None:
        """Set the state (a restart): p^n and the fields q_r."""
        self.pressure, self.q = pressure, q

    def state(self) -> list[np.ndarray]:
        """The whole state as a list of fields, [p^n, q_1, ...]: what :meth:`load_state` takes back."""
        return [self.pressure, *self.q]

    def load_state(self, fields: list[np.ndarray]) -> None:
        self.restore(fields[0], list(fields[1:]))


class RelaxationHistory(History):
    """The relaxation form for a Prony material: p = G * dW with G(t) = Ginf + sum_k dG_k exp(-t/theta_k)
    (:func:`relaxation_series`) and W the displacement in pressure space (w = A W), W linear in time within
    a step (exact exponential integration: second order, and exact for a held displacement).

    With e_k = exp(-dt/theta_k), gamma_k = theta_k (1 - e_k)/dt (1 at dt = 0) and s_k the Maxwell
    internal fields (s_k' = W' - s_k/theta_k):

        p^{n+1} = G_eff W^{n+1} + sum_k dG_k (e_k s_k^n - gamma_k W^n),   G_eff = Ginf + sum_k dG_k gamma_k

    so W^{n+1} = J_eff p^{n+1} + v with J_eff = 1/G_eff and v = -sum_k dG_k (e_k s_k^n - gamma_k W^n)/G_eff:
    the same step problem as the creep form. State: ``pressure`` (p^n), ``q`` (the fields s_k) and
    ``displacement`` (W^n).
    """

    name = "relaxation"

    def __init__(self, material: Prony, local_shape: tuple[int, int]):
        super().__init__(material)
        self.Ginf, self.dG, self.theta = relaxation_series(material)
        self.pressure = np.zeros(local_shape)
        self.q = [np.zeros(local_shape) for _ in self.dG]
        self.displacement = np.zeros(local_shape)

    def _coefficients(self, dt: float):
        for d, theta in zip(self.dG, self.theta):
            decay = math.exp(-dt / theta)
            gamma = 1.0 if dt == 0 else -math.expm1(-dt / theta) * theta / dt
            yield d, decay, gamma

    def compliance(self, dt: float) -> float:
        """J_eff = 1/G_eff of the next step, of length dt (s)."""
        self.guard_step(dt)
        return 1.0 / (self.Ginf + sum(d * gamma for d, _, gamma in self._coefficients(dt)))

    def preceding(self, dt: float) -> np.ndarray | None:
        """v with W^{n+1} = J_eff p^{n+1} + v (None: an elastic material)."""
        if not self.q:
            return None
        c = np.zeros_like(self.pressure)
        for (d, decay, gamma), s in zip(self._coefficients(dt), self.q):
            c += d * (decay * s - gamma * self.displacement)
        return -c * self.compliance(dt)

    def advance(self, pressure: np.ndarray, dt: float) -> None:
        """Take the solved pressure of the step of length dt into the state."""
        v = self.preceding(dt)
        W1 = self.compliance(dt) * pressure + (v if v is not None else 0.0)
        for (_, decay, gamma), s in zip(self._coefficients(dt), self.q):
            s *= decay
            s += gamma * (W1 - self.displacement)
        self.pressure, self.displacement = pressure.copy(), W1

    def restore(self, pressure: np.ndarray, q: list[np.ndarray], displacement: np.ndarray | None = None) -> None:
        """Set the state (a restart). Without ``displacement``, W is rebuilt from p and s_k
        (W = (p - sum dG_k s_k)/Ginf, equal to the computed W only to round-off)."""
        self.pressure, self.q = pressure, q
        if displacement is None:
            displacement = (pressure - sum((d * s for d, s in zip(self.dG, q)), 0.0)) / self.Ginf
        self.displacement = displacement

    def state(self) -> list[np.ndarray]:
        """The whole state as a list of fields, [p^n, s_1, ..., W^n]: what :meth:`load_state` takes back."""
        return [self.pressure, *self.q, self.displacement]

    def load_state(self, fields: list[np.ndarray]) -> None:
        self.restore(fields[0], list(fields[1:-1]), fields[-1])


class HereditaryHistory(History):
    """The paper's scheme for any J(t): the full hereditary sum over all past pressure increments.

    w_n = sum_m J(t_n - t_m) A (p_m - p_{m-1}); cost and memory grow with the step count.
    """

    name = "paper"
    kind = "hereditary"

    def __init__(self, material, local_shape: tuple[int, int]):
        super().__init__(material)
        self.pressure = np.zeros(local_shape)
        self.times: list[float] = []
        self.increments: list[np.ndarray] = []

    def compliance(self, dt: float) -> float:
        """J_eff = J(0) (the paper's freeze over the newest step)."""
        self.guard_step(dt)
        return float(self.material(0.0))

    def preceding(self, dt: float) -> np.ndarray | None:
        """v with u = A v for the next step (None before the first step)."""
        if not self.times:
            return None
        now = self.times[-1] + dt
        v = -float(self.material(0.0)) * self.pressure
        for t, dp in zip(self.times, self.increments):
            v += float(self.material(now - t)) * dp
        return v

    def advance(self, pressure: np.ndarray, dt: float) -> None:
        """Take the solved pressure of the step of length dt into the state."""
        self.times.append(self.times[-1] + dt if self.times else 0.0)
        self.increments.append(pressure - self.pressure)
        self.pressure = pressure.copy()


def make_history(material, integrator: str, local_shape: tuple[int, int], guard: bool = True):
    """The integrator ``integrator`` ("relaxation", "exponential" or "paper") for ``material`` on this
    rank's rows; ``guard``: refuse step lengths at which it cannot hold a penetration."""
    if isinstance(material, Prony) and integrator == "relaxation":
        history = RelaxationHistory(material, local_shape)
    elif isinstance(material, Prony):
        history = PronyHistory(material, local_shape, beta_one=integrator == "paper")
    else:
        history = HereditaryHistory(material, local_shape)
    history.guard = guard
    return history


# -- the integrator as a linear state machine ---------------------------------------------------------------
def state_space(material, integrator: str, dt: float):
    """(h0, s1, M, c): the integrator ``integrator`` for a Prony ``material`` at steps of dt (s) as a
    linear, time-invariant state machine on one material point. A pressure p over a step gives W = h0 p
    (1/Pa, h0 = J_eff) and, from rest, the state s1 p; a step at p = 0 maps a state s to M s and gives
    W = c s. s1, M and c are measured by steps of the integrator itself from every basis state at once
    (one cell each); (h0, None, None, None) for a material without memory (elastic). Guarded like a run's
    history (SolverError at a step the integrator cannot hold)."""
    history = make_history(material, integrator, (1, 1))
    h0 = history.compliance(dt)
    history.advance(np.ones((1, 1)), dt)
    if history.preceding(dt) is None:
        return h0, None, None, None
    after = np.array([f[0, 0] for f in history.state()])  # s1, just after a unit pulse
    d = len(after)
    history.load_state([row.reshape(1, d).copy() for row in np.eye(d)])  # cell j holds the state e_j
    c = history.preceding(dt)[0].copy()
    history.advance(np.zeros((1, d)), dt)
    return h0, after, np.array([f[0] for f in history.state()]), c  # M: column j = M e_j


def transfer(material, integrator: str, dt: float, z: np.ndarray) -> np.ndarray:
    """H(z) = sum_s h[s] z^-s (1/Pa): the steady response W_n = H(z) p_n of the integrator (steps of dt)
    to a pressure p_n = z^n (|z| = 1: oscillating at the angular frequency arg(z) / dt), h the pulse
    response of :func:`state_space`: h0 + c (z I - M)^-1 s1. As dt -> 0 at a fixed frequency it tends to
    the complex compliance J*(omega) (Prony.complex_compliance)."""
    h0, after, M, c = state_space(material, integrator, dt)
    z = np.asarray(z, dtype=complex)
    if after is None:
        return np.full(z.shape, h0, dtype=complex)
    # (z I - M) y = s1 solved for each distinct z (M's eigenvectors are too ill-conditioned to diagonalise
    # it once many decay rates lie near 1: long times over short steps), in blocks of 512 systems
    values, where = np.unique(z.ravel(), return_inverse=True)
    out = np.empty(len(values), dtype=complex)
    d = len(after)
    for start in range(0, len(values), 512):
        block = values[start : start + 512]
        systems = block[:, None, None] * np.eye(d) - M
        y = np.linalg.solve(systems, np.broadcast_to(after.astype(complex), (len(block), d))[..., None])
        out[start : start + 512] = h0 + y[..., 0] @ c
    return out[where].reshape(z.shape)


class Transfer:
    """:func:`transfer` of one material's integrator at steps of dt, remembering H at the distinct z of its
    last call (a d x d solve per z, d the integrator's state size: 40 for a 39-term Prony series): the
    kernels of one steady sliding solve, one per form (petroll.solver.sliding), ask at the same z, the
    modes of one grid. H is computed as :func:`transfer` computes it: the same values."""

    def __init__(self, material, integrator: str, dt: float):
        self.material, self.integrator, self.dt = material, integrator, dt
        self._z, self._h = None, None  # the last call's distinct z and H there

    def __call__(self, z) -> np.ndarray:
        z = np.asarray(z, dtype=complex)
        values, where = np.unique(z.ravel(), return_inverse=True)
        if self._z is None or not np.array_equal(values, self._z):
            self._z, self._h = values, transfer(self.material, self.integrator, self.dt, values)
        return self._h[where].reshape(z.shape)


# -- the holding test ---------------------------------------------------------------------------------------
def holding_response(material, integrator: str, dt: float, steps: int = 40) -> np.ndarray:
    """Pressures (Pa) of one cell (unit influence) held at a unit displacement in pressure space from a
    sudden start at t = 0, with steps of dt, as the integrator computes them: the exact answer is the
    relaxation modulus G(t), between 1/Jinf and 1/J0 and non-increasing."""
    history = make_history(material, integrator, (1, 1), guard=False)
    pressures = []
    for n in range(steps):
        step = 0.0 if n == 0 else dt
        v = history.preceding(step)
        p = (1.0 - (0.0 if v is None else v)) / history.compliance(step)
        history.advance(np.asarray(p, dtype=float).reshape(1, 1), step)
        pressures.append(float(np.asarray(p).ravel()[0]))
    return np.array(pressures)


@functools.lru_cache(maxsize=256)
def holding_violation(material, integrator: str, dt: float) -> float:
    """How far the held cell's pressure (:func:`holding_response`) leaves [1/Jinf, 1/J0], as a fraction of
    that range (0: it stays inside). Remembered per material, integrator and step: every guarded history
    (a run's, a steady solve's state space) asks it at its first step of each length."""
    lo, hi = 1.0 / material.Jinf, 1.0 / material.J0
    if not hi > lo * (1 + 1e-12):
        return 0.0
    p = holding_response(material, integrator, dt)
    if not np.all(np.isfinite(p)):
        return math.inf
    return max(lo - p.min(), p.max() - hi, 0.0) / (hi - lo)


def largest_safe_step(material, integrator: str, dt: float) -> float:
    """The largest step below dt (to 1 %) at which the holding violation stays within GUARD_VIOLATION."""
    lo, hi = math.log(dt) - math.log(1e9), math.log(dt)  # lo: a step far below every material time
    if holding_violation(material, integrator, math.exp(lo)) > GUARD_VIOLATION:
        return 0.0
    while hi - lo > 0.01:
        mid = 0.5 * (lo + hi)
        if holding_violation(material, integrator, math.exp(mid)) > GUARD_VIOLATION:
            hi = mid
        else:
            lo = mid
    return math.exp(lo)


def _refuse_unsafe(material, name: str, dt: float) -> None:
    """SolverError (naming the largest safe step) if integrator ``name`` cannot hold a penetration at dt."""
    violation = holding_violation(material, name, dt)
    if violation <= GUARD_VIOLATION:
        return
    safe = largest_safe_step(material, name, dt)
    p = holding_response(material, name, dt)
    what = "oscillates outside" if np.any(np.diff(p[1:]) * np.diff(p[:-1]) < 0) else "leaves"
    remedy = f"a time step <= {safe:.3g} s (fixed [time] dt, or more steps_per_cell)"
    if isinstance(material, Prony):
        remedy += ' or integrator = "relaxation" (the default for Prony materials)'
    raise SolverError(
        f"[solver] integrator = {name!r} cannot hold a penetration with this material at a time step of "
        f"{dt:.3g} s: on a cell held at a fixed displacement after a sudden start, the pressure it computes "
        f"{what} the bounds set by the relaxed and instantaneous moduli by {violation:.3g} of their "
        f"difference (E0/Einf = {material.Jinf / material.J0:.3g}); use {remedy}")
