"""Persson's theory of rubber friction and contact mechanics, for comparison with petroll's rough runs.

A rigid, isotropically rough surface of power spectrum C(q) (Persson's convention, petroll.model.roughness)
slides at speed V over a viscoelastic half-space of complex plane-strain modulus M(omega) = E(omega) /
(1 - nu^2) = 1 / J*(omega) (petroll.model.materials.Prony.complex_compliance) under the nominal pressure
sigma0. With q0 the smallest and q1 the largest wavenumber of the roughness (rad/m):

* Persson, J. Chem. Phys. 115, 3840 (2001), Eqs. (4)-(6) (also Persson, Albohr, Tartaglino, Volokitin
  and Tosatti, J. Phys.: Condens. Matter 17, R1 (2005), Eqs. (12), (21), (23)):

      mu   = 1/2 integral_q0^q1 dq q^3 C(q) S(q) P(q) integral_0^2pi dphi cos(phi) Im M(q V cos phi) / sigma0
      P(q) = erf(1 / (2 sqrt(G(q))))
      G(q) = 1/8 integral_q0^q dq' q'^3 C(q') integral_0^2pi dphi |M(q' V cos phi) / sigma0|^2

  with S(q) = 1 (the 2001 theory). A/A0 = P(q1) is the fraction of the nominal area in real contact.
* Persson, J. Phys.: Condens. Matter 18, 7789 (2006), Eq. (3) and Lorenz et al., J. Phys.: Condens.
  Matter 25, 225004 (2013): S(q) = gamma + (1 - gamma) P(q)^2, gamma ~ 0.5, corrects the friction for the
  asperities' partial contact (``gamma``; None: S = 1).

Known limits (tested): an elastic solid of modulus M has A/A0 = erf(sqrt(2) sigma0 / (M h'_rms)) at every
load (so A/A0 ~ sqrt(8/pi) sigma0 / (M h'_rms) at small loads), and no friction; a viscoelastic solid
slides with its relaxed modulus as V -> 0 and its instantaneous one as V -> inf; in full contact (P = 1)
a standard linear solid's angular integral is 2 pi dM / b (1 - 1/sqrt(1 + b^2)), b = q V theta (theta its
relaxation time, dM = M(inf) - M(0)). The flash temperature (the heating of the rubber by the friction it
makes) is left out: petroll's runs are isothermal.

Quadrature: q on a uniform grid in ln q (``per_efold`` points per e-fold; a tabulated spectrum's nodes
added, each with a point just below it, so that a jump of C is integrated exactly), G cumulated by the
trapezoidal rule; M(omega) from a cubic spline in ln(omega) through 16 exact values per e-fold; the angle in two
pieces, cos(phi) in [1/2, 1] by Gauss-Legendre in phi and cos(phi) in (0, 1/2] by Gauss-Legendre in
ln cos(phi) down to 1e-16 (the integrands are smooth in ln(omega), where a relaxation time shows as a step
of width ~1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.special import erf

from petroll.model.materials import Prony
from petroll.model.roughness import SelfAffinePSD, TabulatedPSD

__all__ = ["PerssonResult", "angular_rule", "persson", "plane_strain_modulus"]


def angular_rule(nodes: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """(c, w): nodes c = cos(phi) in (0, 1] and weights such that sum w f(c) = integral_0^pi/2 f(cos phi)
    dphi for f smooth in ln(c); 2 ``nodes`` on [0, pi/3], and ``nodes`` per unit of ln(c) below c = 1/2."""
    x, w = np.polynomial.legendre.leggauss(2 * nodes)
    phi = (x + 1.0) * (math.pi / 6.0)  # [0, pi/3]: c in [1/2, 1]
    c_top, w_top = np.cos(phi), w * (math.pi / 6.0)
    depth = math.log(0.5 / 1e-16)
    pieces = math.ceil(depth)
    x, w = np.polynomial.legendre.leggauss(nodes)
    s = ((x[None, :] + 1.0) / 2.0 + np.arange(pieces)[:, None]) * (depth / pieces)  # s = ln(1/2 / c)
    c_low = 0.5 * np.exp(-s.ravel())
    # dphi = dc / sqrt(1 - c^2), dc = c ds
    w_low = np.tile(w / 2.0 * depth / pieces, pieces) * c_low / np.sqrt(1.0 - c_low**2)
    return np.concatenate([c_top, c_low]), np.concatenate([w_top, w_low])


def plane_strain_modulus(material: Prony, omega: np.ndarray, per_efold: int = 16) -> np.ndarray:
    """M(omega) = 1 / J*(omega) (Pa) at angular frequencies ``omega`` >= 0: a cubic spline in ln(omega)
    through ``per_efold`` exact values per e-fold (relative error ~1e-7 for a Prony series, whose terms
    change over an e-fold or more), so that a long series costs its table, not every point."""
    positive = omega[omega > 0.0]
    if positive.size == 0 or not material.dJ:
        return np.broadcast_to(1.0 / material.complex_compliance(0.0), omega.shape)
    low, high = math.log(positive.min()), math.log(positive.max())
    s = np.linspace(low, high, max(int(math.ceil((high - low) * per_efold)), 4) + 1)
    table = CubicSpline(s, 1.0 / material.complex_compliance(np.exp(s)))
    with np.errstate(divide="ignore"):
        return np.where(omega > 0.0, table(np.log(np.maximum(omega, positive.min()))),
                        1.0 / material.complex_compliance(0.0))


@dataclass(frozen=True)
class PerssonResult:
    """Persson's theory at one pressure and speed: ``q`` (rad/m), G(q), P(q) (the fraction of the nominal
    area in contact at magnification q1/q... , A/A0 = ``area``), and ``mu`` the friction coefficient."""

    q: np.ndarray
    G: np.ndarray
    P: np.ndarray
    mu: float

    @property
    def area(self) -> float:
        """A/A0 = P(q1): the real contact area's fraction of the nominal area."""
        return float(self.P[-1])


def persson(psd: SelfAffinePSD | TabulatedPSD, material: Prony, pressure: float, velocity: float, *,
            gamma: float | None = None, per_efold: int = 256, nodes: int = 8) -> PerssonResult:
    """Persson's friction coefficient and contact area (module docstring) of the roughness ``psd`` (its
    q_long the smallest wavenumber q0 > 0, q_cutoff q1; a measured surface's: ``TabulatedPSD.of``)
    sliding at ``velocity`` (m/s) on ``material`` (a Prony series; J includes 1 - nu^2) under the nominal
    ``pressure`` sigma0 (Pa)."""
    q0, q1 = psd.q_long, psd.q_cutoff
    if not 0.0 < q0 < q1:
        raise ValueError(f"the roughness needs 0 < q_long < q_cutoff, got {q0!r}, {q1!r}")
    count = max(int(math.ceil(per_efold * math.log(q1 / q0))), 8) + 1
    s = np.linspace(math.log(q0), math.log(q1), count)
    knots = getattr(psd, "q", None)  # a table's: C is smooth between its nodes and may jump at them
    if knots is not None:
        inner = np.log(knots[(knots > q0) & (knots < q1)])
        s = np.unique(np.concatenate([s, inner, inner - 1e-12]))  # each side of a node
    q = np.exp(s)
    q[0], q[-1] = q0, q1  # exactly: exp(log(q1)) may round past the cut-off, where C = 0
    c, weights = angular_rule(nodes)
    modulus = plane_strain_modulus(material, np.abs(velocity) * q[:, None] * c[None, :])
    # integral_0^2pi dphi: 4 x integral_0^pi/2, both integrands being even in cos(phi)
    loss = 4.0 * (modulus.imag * c[None, :]) @ weights / pressure
    square = 4.0 * (np.abs(modulus) ** 2) @ weights / pressure**2
    spectrum = q**4 * psd(q)  # q^3 C(q) dq = q^4 C(q) d(ln q)
    dG = spectrum * square / 8.0
    G = np.concatenate([[0.0], np.cumsum((dG[1:] + dG[:-1]) / 2.0 * np.diff(s))])
    with np.errstate(divide="ignore"):
        P = np.where(G > 0.0, erf(0.5 / np.sqrt(np.where(G > 0.0, G, 1.0))), 1.0)
    S = 1.0 if gamma is None else gamma + (1.0 - gamma) * P**2
    integrand = 0.5 * spectrum * S * P * loss
    mu = float(np.sum((integrand[1:] + integrand[:-1]) / 2.0 * np.diff(s)))
    return PerssonResult(q, G, P, mu)
