"""Viscoelastic materials (surface creep compliance J(t)) and their time integrators (formulation §1, §4).

J(t) is the surface compliance (1 - nu^2) D(t) in 1/Pa, D the uniaxial creep compliance, nu constant.
Every integrator turns step n+1 into an elastic-like problem w = J_eff A p + A v: ``J_eff`` (1/Pa) and the
*preceding displacement* u = A v, with v a field in pressure space (Pa * 1/Pa = dimensionless times A's
length): one convolution per step, whatever the number of Prony terms.

Integrators (``[solver] integrator``):

- ``exponential`` (Prony materials, the default): exact for a displacement linear in time within a step,
  second order, unconditionally stable; state p^n and one field q_r per term.
- ``paper`` (Yin et al. 2015): J frozen at J(0) over the newest step, exact J for older increments;
  first order. For a Prony series the hereditary sum collapses to the same recursion as ``exponential``
  with beta_r = 1; for a tabulated J it is the full hereditary sum over all past increments.

A sudden start (the first step, t = 0) is the instantaneous response: J_eff = J(0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


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
        a, b = lo + 1e-15 * abs(lo), hi - 1e-15 * abs(hi) if hi else 0.0
        for _ in range(200):
            mid = 0.5 * (a + b)
            if g(mid) > 0:
                b = mid
            else:
                a = mid
            if b - a <= 4e-16 * abs(mid):
                break
        zeros.append(0.5 * (a + b))
    dD = [-1.0 / (z * dg(z)) for z in zeros]
    return kelvin(Einf, nu, dD, [-1.0 / z for z in zeros])


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

    def __init__(self, material: Prony, local_shape: tuple[int, int], beta_one: bool = False):
        self.material, self.beta_one = material, beta_one
        self.pressure = np.zeros(local_shape)
        self.q = [np.zeros(local_shape) for _ in material.dJ]

    def _coefficients(self, dt: float):
        for d, tau in zip(self.material.dJ, self.material.tau):
            decay = math.exp(-dt / tau)
            beta = 1.0 if self.beta_one or dt == 0 else -math.expm1(-dt / tau) * tau / dt
            yield d, decay, beta

    def compliance(self, dt: float) -> float:
        """J_eff of the next step, of length dt (s)."""
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


class HereditaryHistory:
    """The paper's scheme for any J(t): the full hereditary sum over all past pressure increments.

    w_n = sum_m J(t_n - t_m) A (p_m - p_{m-1}); cost and memory grow with the step count.
    """

    def __init__(self, material, local_shape: tuple[int, int]):
        self.material = material
        self.pressure = np.zeros(local_shape)
        self.times: list[float] = []
        self.increments: list[np.ndarray] = []

    def compliance(self, dt: float) -> float:
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


def make_history(material, integrator: str, local_shape: tuple[int, int]):
    """The integrator ``integrator`` ("exponential" or "paper") for ``material`` on this rank's rows."""
    if isinstance(material, Prony):
        return PronyHistory(material, local_shape, beta_one=integrator == "paper")
    return HereditaryHistory(material, local_shape)
