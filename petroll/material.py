"""Viscoelastic materials (surface creep compliance J(t)) and their time integrators (formulation §1, §4).

J(t) is the surface compliance (1 - nu^2) D(t) in 1/Pa, D the uniaxial creep compliance, nu constant.
Every integrator turns step n+1 into an elastic-like problem w = J_eff A p + A v: ``J_eff`` (1/Pa) and the
*preceding displacement* u = A v, with v a field in pressure space (Pa * 1/Pa = dimensionless times A's
length): one convolution per step, whatever the number of Prony terms.

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

import math
from dataclasses import dataclass

import numpy as np

from petroll.errors import SolverError

GUARD_VIOLATION = 0.01
"""The largest excursion of a held cell's pressure outside [1/Jinf, 1/J0], as a fraction of that range,
that a guarded history accepts (:func:`holding_violation`)."""


@dataclass(frozen=True)
class Prony:
    """J(t) = Jinf - sum_r dJ[r] exp(-t / tau[r]) (1/Pa, s); no terms is an elastic material."""

    Jinf: float
    dJ: tuple[float, ...] = ()
    tau: tuple[float, ...] = ()

    @property
    def J0(self) -> float:
        return self.Jinf - sum(self.dJ)

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        return self.Jinf - sum(d * np.exp(-t / tau) for d, tau in zip(self.dJ, self.tau))

    @property
    def longest_time(self) -> float:
        return max(self.tau, default=0.0)


def elastic(E: float, nu: float) -> Prony:
    return Prony((1 - nu**2) / E)


def sls(E0: float, Einf: float, nu: float, tau_creep: float | None = None,
        tau_relax: float | None = None) -> Prony:
    """Standard linear solid from its instantaneous and relaxed moduli and one of its two times.

    Creep: J(t) = Jinf - (Jinf - J0) exp(-t / tau_creep); the modulus relaxes with tau_relax =
    tau_creep J0 / Jinf = tau_creep Einf / E0.
    """
    if tau_creep is None:
        tau_creep = tau_relax * E0 / Einf
    J0, Jinf = (1 - nu**2) / E0, (1 - nu**2) / Einf
    return Prony(Jinf, (Jinf - J0,), (tau_creep,)) if E0 != Einf else Prony(Jinf)


def kelvin(Einf: float, nu: float, compliances, times) -> Prony:
    """Generalized Kelvin creep series D(t) = 1/Einf - sum_r compliances[r] exp(-t / times[r])."""
    c = 1 - nu**2
    return Prony(c / Einf, tuple(c * d for d in compliances), tuple(times))


def maxwell(Einf: float, nu: float, moduli, times) -> Prony:
    """Generalized Maxwell relaxation series E(t) = Einf + sum_r moduli[r] exp(-t / times[r]), converted
    exactly to its creep (Kelvin) series.

    With g(s) = s E~(s) = Einf + sum_r E_r s / (s + 1/T_r), the creep compliance is the inverse Laplace
    transform of 1 / (s g(s)): D(t) = 1/Einf + sum_k exp(z_k t) / (z_k g'(z_k)) over the zeros z_k of g,
    one between each pair of consecutive poles -1/T_r (found by bisection to round-off).
    """
    E = np.asarray(moduli, dtype=float)
    rates = 1.0 / np.asarray(times, dtype=float)
    order = np.argsort(rates)
    E, rates = E[order], rates[order]

    def g(s):
        return Einf + np.sum(E * s / (s + rates))

    def dg(s):
        return np.sum(E * rates / (s + rates) ** 2)

    # g increases on each interval between poles: from -inf (just right of -rates[k]) ... to +inf (left of
    # -rates[k-1]); the last interval (-rates[0], 0) ends at g(0) = Einf > 0.
    zeros = []
    for k in range(len(rates)):
        lo = -rates[k]
        hi = -rates[k - 1] if k > 0 else 0.0
        zeros.append(_bisect(g, lo + 1e-15 * abs(lo), hi - 1e-15 * abs(hi) if hi else 0.0, rising=True))
    dD = [-1.0 / (z * dg(z)) for z in zeros]
    return kelvin(Einf, nu, dD, [-1.0 / z for z in zeros])


def _bisect(f, a: float, b: float, rising: bool) -> float:
    """The zero of a monotone f in (a, b) (rising: f < 0 near a and > 0 near b), by bisection to round-off."""
    for _ in range(400):
        mid = 0.5 * (a + b)
        if (f(mid) > 0) == rising:
            b = mid
        else:
            a = mid
        if abs(b - a) <= 4e-16 * abs(mid):
            break
    return 0.5 * (a + b)


def relaxation_series(material: Prony) -> tuple[float, tuple[float, ...], tuple[float, ...]]:
    """The surface relaxation modulus G(t) = Ginf + sum_k dG[k] exp(-t / theta[k]) (Pa, s) of a Prony
    creep compliance J: the convolution inverse, int_0^t G(t - s) dJ(s) = 1.

    With h(s) = s J~(s) = J0 + sum_r dJ_r a_r / (s + a_r) (a_r = 1 / tau_r), s G~(s) = 1 / h(s): G has the
    poles 0 (residue 1 / Jinf) and the zeros z_k of h, one in each gap between consecutive -a_r and one
    below the fastest, -a_max - sum_r dJ_r a_r / J0 < z < -a_max (found by bisection to round-off);
    dG_k = 1 / (z_k h'(z_k)) > 0, theta_k = -1 / z_k.
    """
    if not material.dJ:
        return 1.0 / material.Jinf, (), ()
    dJ = np.asarray(material.dJ, dtype=float)
    rates = 1.0 / np.asarray(material.tau, dtype=float)
    order = np.argsort(rates)
    dJ, rates = dJ[order], rates[order]
    J0 = material.J0

    def h(s):
        return J0 + np.sum(dJ * rates / (s + rates))

    def dh(s):
        return -np.sum(dJ * rates / (s + rates) ** 2)

    # h decreases on each bracket from > 0 at its left end (+inf just right of a pole) to -inf (left of -a)
    brackets = [(-rates[k + 1] * (1 - 1e-15), -rates[k] * (1 + 1e-15)) for k in range(len(rates) - 1)]
    brackets.append((-rates[-1] - float(np.sum(dJ * rates)) / J0, -rates[-1] * (1 + 1e-15)))
    zeros = []
    for a, b in brackets:
        zeros.append(_bisect(h, a, b, rising=False))
    dG = tuple(float(1.0 / (z * dh(z))) for z in zeros)
    theta = tuple(float(-1.0 / z) for z in zeros)
    return 1.0 / material.Jinf, dG, theta


@dataclass(frozen=True)
class Tabulated:
    """J(t) (1/Pa) interpolated linearly in a table, constant past its last time; t[0] must be 0."""

    t: tuple[float, ...]
    J: tuple[float, ...]

    @property
    def J0(self) -> float:
        return self.J[0]

    @property
    def Jinf(self) -> float:
        return self.J[-1]

    def __call__(self, t):
        return np.interp(t, self.t, self.J)

    @property
    def longest_time(self) -> float:
        return self.t[-1]


# -- integrators ------------------------------------------------------------------------------------------
class PronyHistory:
    """Pressure-space state of a Prony material: p^n and q_r^n = sum_m exp(-(t_n - t_m)/tau_r) dp_m-ish.

    ``beta_one=True`` gives the paper's scheme (J frozen at J0 over the newest step), otherwise the
    exponential integrator. ``dt = 0`` is a jump (the sudden first step).
    """

    guard = False  # True (make_history): refuse step lengths at which the scheme cannot hold a penetration
    _safe: set | None = None

    def __init__(self, material: Prony, local_shape: tuple[int, int], beta_one: bool = False):
        self.material, self.beta_one = material, beta_one
        self.pressure = np.zeros(local_shape)
        self.q = [np.zeros(local_shape) for _ in material.dJ]

    @property
    def name(self) -> str:
        return "paper" if self.beta_one else "exponential"

    def guard_step(self, dt: float) -> None:
        """Raise SolverError if this integrator cannot hold a penetration at steps of dt (guarded only)."""
        _guard(self, dt)

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


class RelaxationHistory(PronyHistory):
    """The relaxation form for a Prony material: p = G * dW with G(t) = Ginf + sum_k dG_k exp(-t/theta_k)
    (:func:`relaxation_series`) and W the displacement in pressure space (w = A W), W linear in time within
    a step (exact exponential integration: second order, and exact for a held displacement).

    With e_k = exp(-dt/theta_k), gamma_k = theta_k (1 - e_k)/dt (1 at dt = 0) and s_k the Maxwell
    internal fields (s_k' = W' - s_k/theta_k):

        p^{n+1} = G_eff W^{n+1} + sum_k dG_k (e_k s_k^n - gamma_k W^n),   G_eff = Ginf + sum_k dG_k gamma_k

    so W^{n+1} = J_eff p^{n+1} + v with J_eff = 1/G_eff and v = -sum_k dG_k (e_k s_k^n - gamma_k W^n)/G_eff:
    the same step problem as the creep form. ``pressure`` is p^n; ``q`` holds the fields s_k (what a
    checkpoint stores); W^n is kept and rebuilt from them (W = (p - sum dG_k s_k)/Ginf) when they are set.
    """

    def __init__(self, material: Prony, local_shape: tuple[int, int]):
        self.material, self.beta_one = material, False
        self.Ginf, self.dG, self.theta = relaxation_series(material)
        self._pressure = np.zeros(local_shape)
        self._q = [np.zeros(local_shape) for _ in self.dG]
        self._W = np.zeros(local_shape)

    @property
    def name(self) -> str:
        return "relaxation"

    # setting the state from outside (a restart) rebuilds W from it
    @property
    def pressure(self) -> np.ndarray:
        return self._pressure

    @pressure.setter
    def pressure(self, value: np.ndarray) -> None:
        self._pressure, self._W = value, None

    @property
    def q(self) -> list[np.ndarray]:
        return self._q

    @q.setter
    def q(self, value: list[np.ndarray]) -> None:
        self._q, self._W = value, None

    @property
    def displacement(self) -> np.ndarray:
        """W^n, the displacement in pressure space (w = A W, dimensionless)."""
        if self._W is None:
            self._W = (self._pressure - sum((d * s for d, s in zip(self.dG, self._q)), 0.0)) / self.Ginf
        return self._W

    def _coefficients(self, dt: float):
        for d, theta in zip(self.dG, self.theta):
            decay = math.exp(-dt / theta)
            gamma = 1.0 if dt == 0 else -math.expm1(-dt / theta) * theta / dt
            yield d, decay, gamma

    def compliance(self, dt: float) -> float:
        self.guard_step(dt)
        return 1.0 / (self.Ginf + sum(d * gamma for d, _, gamma in self._coefficients(dt)))

    def preceding(self, dt: float) -> np.ndarray | None:
        if not self._q:
            return None
        W = self.displacement
        c = np.zeros_like(self._pressure)
        for (d, decay, gamma), s in zip(self._coefficients(dt), self._q):
            c += d * (decay * s - gamma * W)
        return -c * self.compliance(dt)

    def advance(self, pressure: np.ndarray, dt: float) -> None:
        v = self.preceding(dt)
        W0 = self.displacement
        W1 = self.compliance(dt) * pressure + (v if v is not None else 0.0)
        for (_, decay, gamma), s in zip(self._coefficients(dt), self._q):
            s *= decay
            s += gamma * (W1 - W0)
        self._pressure, self._W = pressure.copy(), W1


class HereditaryHistory:
    """The paper's scheme for any J(t): the full hereditary sum over all past pressure increments.

    w_n = sum_m J(t_n - t_m) A (p_m - p_{m-1}); cost and memory grow with the step count.
    """

    guard = False
    _safe: set | None = None
    name = "paper"

    def __init__(self, material, local_shape: tuple[int, int]):
        self.material = material
        self.pressure = np.zeros(local_shape)
        self.times: list[float] = []
        self.increments: list[np.ndarray] = []

    def guard_step(self, dt: float) -> None:
        _guard(self, dt)

    def compliance(self, dt: float) -> float:
        self.guard_step(dt)
        return float(self.material(0.0))

    def preceding(self, dt: float) -> np.ndarray | None:
        if not self.times:
            return None
        now = self.times[-1] + dt
        v = -float(self.material(0.0)) * self.pressure
        for t, dp in zip(self.times, self.increments):
            v += float(self.material(now - t)) * dp
        return v

    def advance(self, pressure: np.ndarray, dt: float) -> None:
        self.times.append(self.times[-1] + dt if self.times else 0.0)
        self.increments.append(pressure - self.pressure)
        self.pressure = pressure.copy()


def make_history(material, integrator: str, local_shape: tuple[int, int], guard: bool = True):
    """The integrator ``integrator`` ("relaxation", "exponential" or "paper") for ``material`` on this
    rank's rows; ``guard``: refuse step lengths at which it cannot hold a penetration (:func:`_guard`)."""
    if isinstance(material, Prony) and integrator == "relaxation":
        history = RelaxationHistory(material, local_shape)
    elif isinstance(material, Prony):
        history = PronyHistory(material, local_shape, beta_one=integrator == "paper")
    else:
        history = HereditaryHistory(material, local_shape)
    history.guard = guard
    return history


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


def holding_violation(material, integrator: str, dt: float) -> float:
    """How far the held cell's pressure (:func:`holding_response`) leaves [1/Jinf, 1/J0], as a fraction of
    that range (0: it stays inside)."""
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


def _guard(history, dt: float) -> None:
    if not history.guard or dt <= 0:
        return
    if history._safe is None:
        history._safe = set()
    if dt in history._safe:
        return
    material, name = history.material, history.name
    violation = holding_violation(material, name, dt)
    if violation <= GUARD_VIOLATION:
        history._safe.add(dt)
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
