"""Viscoelastic material laws: the surface creep compliance J(t) (formulation §1).

J(t) is the surface compliance (1 - nu^2) D(t) in 1/Pa, D the uniaxial creep compliance, nu constant.
Laws: elastic, standard linear solid, Prony series (Kelvin creep or Maxwell relaxation form, converted
exactly to the creep series), tabulated J(t). Their time integrators live in :mod:`petroll.solver.history`.

Temperature enters through time-temperature superposition: a shift law (:class:`WLF`, :class:`Arrhenius`)
gives the factor a_T(T) by which every relaxation and retardation time at temperature T exceeds its value
at the reference temperature T_ref (:func:`shifted`). Temperatures are absolute, in kelvin.
"""

from __future__ import annotations

import functools
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

    def complex_compliance(self, omega) -> np.ndarray:
        """J*(omega) = J(0) + integral_0^inf J'(t) exp(-i omega t) dt (1/Pa) at angular frequencies omega
        (rad/s): the steady surface displacement per unit pressure oscillating as exp(i omega t),
        Jinf - sum_r dJ_r i omega tau_r / (1 + i omega tau_r). Jinf at omega = 0, J0 as |omega| -> inf,
        Im J* < 0 for omega > 0 (the displacement lags); 1 / J* is the complex plane-strain modulus
        E*(omega) = E(omega) / (1 - nu^2)."""
        w = 1j * np.asarray(omega, dtype=float)
        compliance = np.full(w.shape, self.Jinf, dtype=complex)
        for d, tau in zip(self.dJ, self.tau):
            compliance -= d * w * tau / (1.0 + w * tau)
        return compliance


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


@functools.lru_cache(maxsize=64)
def relaxation_series(material: Prony) -> tuple[float, tuple[float, ...], tuple[float, ...]]:
    """The surface relaxation modulus G(t) = Ginf + sum_k dG[k] exp(-t / theta[k]) (Pa, s) of a Prony
    creep compliance J: the convolution inverse, int_0^t G(t - s) dJ(s) = 1. Remembered per material: a
    run's history, its step guard's holding test and a steady solve's state space each ask it (a 39-term
    series takes about 10 ms of bisection).

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

    def complex_compliance(self, omega) -> np.ndarray:
        """J*(omega) = J(0) + integral_0^inf J'(t) exp(-i omega t) dt (1/Pa) at angular frequencies omega > 0
        (rad/s), exact for the piecewise linear J of the table (constant after its last time)."""
        w = np.asarray(omega, dtype=float)[..., None]
        t, J = np.asarray(self.t), np.asarray(self.J)
        slope = np.diff(J) / np.diff(t)
        pieces = slope * (np.exp(-1j * w * t[:-1]) - np.exp(-1j * w * t[1:])) / (1j * w)
        return J[0] + pieces.sum(axis=-1)


def loss_peak_time(material: Prony | Tabulated) -> float:
    """The characteristic time of a viscoelastic material: 1/omega (s) at the largest loss compliance
    J''(omega) = -Im J*(omega), the frequency at which it dissipates most under a given pressure. For an
    SLS this is its creep (retardation) time tau exactly; NaN for an elastic material."""
    from scipy.optimize import minimize_scalar

    times = [t for t in (material.tau if isinstance(material, Prony) else material.t) if t > 0]
    if not times or material.J0 == material.Jinf:
        return math.nan
    lo, hi = math.log(1e-3 / max(times)), math.log(1e3 / min(times))
    grid = np.linspace(lo, hi, int(20 * (hi - lo)) + 2)
    loss = -material.complex_compliance(np.exp(grid)).imag
    k = int(np.argmax(loss))
    best = minimize_scalar(lambda x: float(material.complex_compliance(np.exp(x)).imag),
                           bounds=(grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]), method="bounded",
                           options={"xatol": 1e-10})
    return float(math.exp(-best.x))


# -- a layer on a rigid base ------------------------------------------------------------------------------
LAYER_BASES = ("bonded", "frictionless")
"""How a layer's bottom is held by its rigid base ([material] layer base)."""


@dataclass(frozen=True)
class Layer:
    """A layer of ``thickness`` (m) on a rigid base, its bottom ``base`` = "bonded" or "frictionless"; the
    top (the contact surface) is frictionless. ``nu``: the material's Poisson's ratio, constant in time,
    which the layer's kernel depends on (petroll/solver/kernels/layer.py)."""

    thickness: float
    base: str
    nu: float


# -- temperature: time-temperature superposition ---------------------------------------------------------
GAS_CONSTANT = 8.314462618
"""Molar gas constant R, J/(mol K) (CODATA 2018, exact)."""

SHIFT_FORMS = ('{law = "wlf", C1 = ..., C2 = ... (K), T_ref = ... (K)} or {law = "arrhenius", Ea = ... '
               '(J/mol), T_ref = ... (K)}, all numbers > 0, or {law = "table", T = [...] (K, > 0, '
               'increasing), log10_aT = [...] (as many finite numbers)}')
"""What a shift law may be written as (scene key [material] shift)."""


@dataclass(frozen=True)
class WLF:
    """Williams-Landel-Ferry: log10 a_T = -C1 (T - T_ref) / (C2 + T - T_ref); C2 and T_ref in K.

    Defined above its pole, T > T_ref - C2 (:meth:`lowest`)."""

    C1: float
    C2: float
    T_ref: float

    def log10(self, T: float) -> float:
        """log10 a_T at the temperature T (K); ValueError at or below the pole T_ref - C2."""
        if not T > self.lowest:
            raise ValueError(f"must be above T_ref - C2 = {self.lowest:g} K, the pole of the WLF law")
        return -self.C1 * (T - self.T_ref) / (self.C2 + T - self.T_ref)

    @property
    def lowest(self) -> float:
        return self.T_ref - self.C2

    def table(self) -> dict:
        return {"law": "wlf", "C1": self.C1, "C2": self.C2, "T_ref": self.T_ref}


@dataclass(frozen=True)
class Arrhenius:
    """Arrhenius: ln a_T = (Ea / R) (1/T - 1/T_ref); Ea in J/mol, T and T_ref in K, R = GAS_CONSTANT."""

    Ea: float
    T_ref: float

    def log10(self, T: float) -> float:
        """log10 a_T at the temperature T (K)."""
        return self.Ea / GAS_CONSTANT * (1.0 / T - 1.0 / self.T_ref) / math.log(10.0)

    def table(self) -> dict:
        return {"law": "arrhenius", "Ea": self.Ea, "T_ref": self.T_ref}


@dataclass(frozen=True)
class TableShift:
    """Tabulated: log10 a_T given at the temperatures T (K, increasing), interpolated between them by a
    monotone piecewise cubic (PCHIP: through every point, no overshoot, a continuous slope); refused
    outside T[0] ... T[-1]. The material's other keys hold at T_ref, where log10 a_T = 0."""

    T: tuple[float, ...]
    log10_aT: tuple[float, ...]

    @functools.cached_property
    def _interpolant(self):
        from scipy.interpolate import PchipInterpolator

        return PchipInterpolator(self.T, self.log10_aT, extrapolate=False)

    def log10(self, T: float) -> float:
        """log10 a_T at the temperature T (K); ValueError outside the table's temperatures."""
        if not self.T[0] <= T <= self.T[-1]:
            raise ValueError(f"must be within the table's temperatures {self.T[0]:g} ... {self.T[-1]:g} K")
        return float(self._interpolant(T))

    @property
    def T_ref(self) -> float:
        """The temperature (K) where log10 a_T = 0; ValueError unless there is exactly one."""
        roots = np.unique(self._interpolant.solve(0.0, extrapolate=False))
        if len(roots) != 1:
            raise ValueError(f"the table's log10_aT crosses 0 at {len(roots)} temperatures: a reference "
                             "temperature needs exactly one")
        return float(roots[0])

    def table(self) -> dict:
        return {"law": "table", "T": list(self.T), "log10_aT": list(self.log10_aT)}


def shift_factor(law: WLF | Arrhenius | TableShift, T: float) -> float:
    """a_T(T) = 10^law.log10(T): the factor on every material time at T (K) relative to T_ref (> 1 colder).

    ValueError (with what is allowed) where the law is undefined or a_T over- or underflows."""
    exponent = law.log10(T)
    if not -300 < exponent < 300:
        raise ValueError(f"gives a_T = 10^{exponent:.4g}, beyond what a float holds; a temperature nearer "
                         "T_ref is needed")
    return 10.0**exponent


def make_shift(table: dict) -> WLF | Arrhenius:
    """A shift law from its table (``[material] shift``, :data:`SHIFT_FORMS`); ValueError naming what is
    allowed otherwise."""
    laws = {"wlf": (WLF, ("C1", "C2", "T_ref")), "arrhenius": (Arrhenius, ("Ea", "T_ref")),
            "table": (TableShift, ("T", "log10_aT"))}
    if not isinstance(table, dict) or table.get("law") not in laws:
        raise ValueError(f"must be {SHIFT_FORMS}")
    if table["law"] == "table" and set(table) == {"law", "T", "log10_aT"}:
        return _table_shift(table["T"], table["log10_aT"])
    build, names = laws[table["law"]]
    if set(table) != {"law", *names}:
        raise ValueError(f"the {table['law']} law takes exactly the keys law, {', '.join(names)}; allowed: "
                         f"{SHIFT_FORMS}")
    values = [table[name] for name in names]
    for name, value in zip(names, values):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
            raise ValueError(f"{name} = {value!r} must be a finite number > 0; allowed: {SHIFT_FORMS}")
    return build(*(float(v) for v in values))


def _table_shift(T, log10_aT) -> TableShift:
    def numbers(values) -> list[float] | None:
        ok = isinstance(values, (list, tuple)) and all(
            not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) for v in values)
        return [float(v) for v in values] if ok else None

    T, values = numbers(T), numbers(log10_aT)
    if T is None or len(T) < 2 or T[0] <= 0 or any(b <= a for a, b in zip(T, T[1:])):
        raise ValueError(f"T must be a list of at least 2 increasing temperatures > 0 (K); allowed: "
                         f"{SHIFT_FORMS}")
    if values is None or len(values) != len(T):
        raise ValueError(f"log10_aT must be a list of {len(T)} finite numbers (one per T); allowed: "
                         f"{SHIFT_FORMS}")
    return TableShift(tuple(T), tuple(values))


def shifted(material: Prony | Tabulated, factor: float) -> Prony | Tabulated:
    """The material at another temperature: every time multiplied by ``factor`` = a_T, i.e. J_T(t) =
    J_ref(t / a_T). For a Prony series that scales each retardation time (and with them the relaxation
    times, exactly: s E~(s) maps to itself under s -> s / a_T); for a table, its time axis."""
    if isinstance(material, Tabulated):
        return Tabulated(tuple(t * factor for t in material.t), material.J)
    return Prony(material.Jinf, material.dJ, tuple(tau * factor for tau in material.tau))
