"""Time-temperature shift factors found from the data (``petroll material fit --shift auto:T_REF``).

Each measurement set (an isotherm, :mod:`petroll.model.dma`) covers a few decades of frequency; at its
temperature T it measures the master curve at T_ref at the reduced frequencies f a_T(T). Sets adjacent
in temperature overlap on the master curve, and the horizontal shift between them is found by least
squares on their overlap (:func:`pair_shift`):

- each set's log10 E' and log10 E'' are represented against log10 f by a cubic (least squares over its
  rows), and the scatter of its rows about that cubic measured (rms, its 4 coefficients taken out);
- for a trial shift d (decades: the colder set's log10 a_T minus the warmer's), every row of either set
  that falls within the other's frequency range is compared with the other's cubic; the objective is the
  mean of the squared differences, each modulus weighted by 1 / (the two sets' scatters squared): a
  modulus measured with more scatter (E'' where tan delta is near an instrument's phase resolution)
  counts less, one that is flat (E' on a plateau) constrains d little by itself;
- d is searched over every shift that leaves an overlap of at least MIN_OVERLAP of the narrower set's
  span of log10 f (a grid of GRID_STEP decades, refined by a bounded scalar minimisation around its best
  point). A best shift at either end of that range means the sets do not overlap: refused.

The shifts are chained from the coldest set, and log10 a_T is interpolated between the sets' mean
temperatures by PCHIP (:class:`petroll.model.materials.TableShift`), set to 0 at T_ref. Along a sweep the
temperature wanders by tenths of a kelvin and each row is at its recorded temperature: a second pass
moves every row by the first pass's law from its set's mean temperature to its own, and finds the shifts
again.

**Standard errors.** A pair's shift is a function of its two sets' rows. Its derivative with respect to
each row's log10 E' and log10 E'' (the implicit function's: the slopes and curvatures of the other set's
cubic at the compared rows, each cubic's own dependence on its set's rows, and the weights' dependence on
the scatters), with each row scattering by its set's scatter about its cubic (for that modulus), gives
each shift's variance and the covariance of neighbouring shifts (they share a set); from them follows
the variance of every set's log10 a_T along the chain to T_ref (its dependence on the shifts taken
through the PCHIP law that sets it to 0 at T_ref), to which RESOLUTION is added in quadrature. A standard
error above SIGMA_WARN is warned of. The scatter includes what a cubic misses of the curve's shape, so
exact data still get a small error.

WLF (C1, C2 about T_ref) and Arrhenius (Ea) are fitted to the factors by least squares
(``scipy.optimize.least_squares``; Arrhenius is linear in Ea); their residuals say how well each law
describes the material. Temperatures in K, shifts in decades.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.optimize import least_squares, minimize_scalar

from petroll.errors import DMAError
from petroll.model import materials

MIN_OVERLAP = 0.25
"""The least overlap of two adjacent sets on the master curve, as a fraction of the narrower set's span of
log10 f (0.75 decade for sweeps over 3 decades)."""

GRID_STEP = 0.01
"""The step (decades) of the search over trial shifts before its local refinement."""

PASSES = 2
"""Passes over the sets: the second moves each row to its own temperature by the first pass's law."""

MIN_ROWS = 5
"""The fewest rows (at 4 different frequencies or more) of a set whose shift is to be found."""

SIGMA_WARN = 0.1
"""A set's log10 a_T whose standard error exceeds this (decades) is warned of: the master curve is blurred
there by more than a tenth of a decade of time."""

FLOOR = 1e-6
"""A scatter (decades of modulus) no measurement reaches (exact synthetic data): the least one taken."""

RESOLUTION = 2e-3
"""The method's own error (decades), added in quadrature to each set's standard error: on noise-free
synthetic sweeps the factors err by 0.8e-3 (polymer) to 3e-3 (rubber, 6 sets from T_ref), and near T_ref
the table law's interpolation to T_ref errs by a few 1e-4 where the noise adds nothing."""


@dataclass(frozen=True)
class Isotherm:
    """One set's data for shifting: ``label``, mean ``temperature`` (K), and per row the frequency (Hz),
    E', E'' (Pa) and the recorded temperature (K)."""

    label: str
    temperature: float
    frequency: np.ndarray
    storage: np.ndarray
    loss: np.ndarray
    row_temperature: np.ndarray


@dataclass(frozen=True)
class LawFit:
    """A shift law fitted to the factors (None with the ``note`` saying why not), its residuals against
    them (rms and largest, decades)."""

    law: materials.WLF | materials.Arrhenius | None
    rms: float
    max: float
    note: str = ""

    def text(self) -> str:
        """The law as ``--shift`` takes it, e.g. wlf:17.4,51.6,293.15."""
        if isinstance(self.law, materials.WLF):
            return f"wlf:{self.law.C1:.6g},{self.law.C2:.6g},{self.law.T_ref:g}"
        if isinstance(self.law, materials.Arrhenius):
            return f"arrhenius:{self.law.Ea:.6g},{self.law.T_ref:g}"
        return "none"


@dataclass(frozen=True)
class PairShift:
    """The shift of one pair of neighbouring sets (:func:`pair_shift`): ``d`` (decades), the overlap it
    leaves (decades), the misfit there, and, for its standard error, the change of d with each row's
    log10 E' and log10 E'' (``colder_gradient``, ``warmer_gradient``: shape (2, rows), E' then E'') and
    the two sets' scatters about their cubics (``colder_scatter``, ``warmer_scatter``: E', E'';
    decades)."""

    d: float
    overlap: float
    misfit: float
    colder_gradient: np.ndarray
    warmer_gradient: np.ndarray
    colder_scatter: np.ndarray
    warmer_scatter: np.ndarray

    @property
    def variance(self) -> float:
        """Var(d), decades^2, from the rows' scatters (module docstring)."""
        return float(np.sum((self.colder_gradient * self.colder_scatter[:, None]) ** 2)
                     + np.sum((self.warmer_gradient * self.warmer_scatter[:, None]) ** 2))


@dataclass(frozen=True)
class ShiftFit:
    """Shift factors found from the data: per set (by increasing temperature) its mean temperature (K),
    log10 a_T (0 at T_ref) and its standard error (decades, chained to T_ref); per pair of neighbours the
    shift between them, its standard error, the overlap it leaves (decades) and the misfit there
    (:func:`pair_shift`); the tabulated law through the factors, WLF and Arrhenius fitted to them, and
    log10 a_T of every row at its own temperature."""

    T_ref: float
    labels: tuple[str, ...]
    temperatures: np.ndarray
    log10_aT: np.ndarray
    shifts: np.ndarray
    overlaps: np.ndarray
    misfits: np.ndarray
    law: materials.TableShift
    wlf: LawFit
    arrhenius: LawFit
    row_log10_aT: tuple[np.ndarray, ...]  # each set's rows at their own temperatures (the last pass's law)
    sigma: np.ndarray  # standard error of each set's log10_aT, decades
    shift_sigma: np.ndarray  # standard error of each pair's shift, decades

    def warnings(self) -> list[str]:
        """One line if any set's log10 a_T has a standard error above SIGMA_WARN, else none."""
        over = np.flatnonzero(self.sigma > SIGMA_WARN)
        if over.size == 0:
            return []
        sets = ", ".join(f"set {self.labels[k]} ({self.temperatures[k]:.2f} K: {self.sigma[k]:.2g})"
                         for k in over)
        return [f"the shift factors of {over.size} of {len(self.labels)} sets have a standard error above "
                f"{SIGMA_WARN:g} decade (chained to T_ref = {self.T_ref:g} K from each pair's overlap): {sets}; "
                "the master curve is blurred there (noisy or flat data, little overlap, or sets far from "
                "T_ref)"]


def find_shifts(sets: list[Isotherm], T_ref: float) -> ShiftFit:
    """The shift factors of ``sets`` (ordered by temperature) chained to ``T_ref`` (module docstring).
    DMAError when there are too few sets or rows, T_ref lies outside the sets' temperatures or two
    neighbours do not overlap."""
    temperatures = np.array([s.temperature for s in sets])
    if len(sets) < 2:
        raise DMAError("--shift auto: finding shifts needs at least 2 measurement sets at different "
                       f"temperatures; the table has {len(sets)}")
    if not temperatures[0] <= T_ref <= temperatures[-1]:
        raise DMAError(f"--shift auto:{T_ref:g}: T_ref must lie within the sets' temperatures "
                       f"{temperatures[0]:g} ... {temperatures[-1]:g} K (factors are found, not "
                       "extrapolated)")
    for s in sets:
        if len(s.frequency) < MIN_ROWS or len(np.unique(s.frequency)) < 4:
            raise DMAError(f"--shift auto: set {s.label} ({s.temperature:g} K) has {len(s.frequency)} rows "
                           f"at {len(np.unique(s.frequency))} frequencies; finding its shift needs at least "
                           f"{MIN_ROWS} rows at 4 frequencies")
    offsets = [np.zeros(len(s.frequency)) for s in sets]
    for _ in range(PASSES):
        pairs = [pair_shift(a, b, da, db) for a, b, da, db in zip(sets, sets[1:], offsets, offsets[1:])]
        chained = np.concatenate([[0.0], -np.cumsum([p.d for p in pairs])])
        nodes, values = _nodes(temperatures, chained)
        law = PchipInterpolator(nodes, values, extrapolate=True)
        offsets = [law(s.row_temperature) - law(s.temperature) for s in sets]
    log10_aT = chained - float(law(T_ref))
    nodes, values = _nodes(temperatures, log10_aT)
    table = materials.TableShift(tuple(float(t) for t in nodes), tuple(float(v) for v in values))
    shifts, overlaps, misfits = (np.array([getattr(p, name) for p in pairs]) for name in ("d", "overlap",
                                                                                          "misfit"))
    chain = _chain_jacobian(temperatures, shifts, T_ref)
    with np.errstate(over="ignore", invalid="ignore"):  # a wild value (1e30 Pa) overflows: unknown, inf
        covariance = _shift_covariance(pairs)
        sigma = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", chain, covariance, chain), 0.0) + RESOLUTION**2)
    sigma = np.where(np.isfinite(sigma), sigma, np.inf)  # above SIGMA_WARN: warned of, set by set
    covariance[~np.isfinite(covariance)] = np.inf
    laws = fit_wlf(temperatures, log10_aT, T_ref), fit_arrhenius(temperatures, log10_aT, T_ref)
    return ShiftFit(float(T_ref), tuple(s.label for s in sets), temperatures, log10_aT, shifts, overlaps,
                    misfits, table, *laws, tuple(value + offset for value, offset in zip(log10_aT, offsets)),
                    sigma, np.sqrt(np.diag(covariance)))


def _shift_covariance(pairs: list[PairShift]) -> np.ndarray:
    """The covariance of the pairs' shifts (decades^2): each its own variance, and neighbours through the
    set they share (the warmer set of one is the colder of the next)."""
    covariance = np.diag([p.variance for p in pairs])
    for k, (a, b) in enumerate(zip(pairs, pairs[1:])):
        shared = float(np.sum(a.warmer_gradient * b.colder_gradient * (a.warmer_scatter ** 2)[:, None]))
        covariance[k, k + 1] = covariance[k + 1, k] = shared
    return covariance


def _chain_jacobian(temperatures: np.ndarray, shifts: np.ndarray, T_ref: float) -> np.ndarray:
    """d log10_aT (each set) / d shift (each pair): the chain from the coldest set, less the PCHIP law's
    value at T_ref (by central differences of 1e-6 decade; the law is smooth in its values)."""

    def factors(d: np.ndarray) -> np.ndarray:
        chained = np.concatenate([[0.0], -np.cumsum(d)])
        nodes, values = _nodes(temperatures, chained)
        return chained - float(PchipInterpolator(nodes, values, extrapolate=True)(T_ref))

    step = 1e-6
    columns = [(factors(shifts + step * e) - factors(shifts - step * e)) / (2 * step)
               for e in np.eye(len(shifts))]
    return np.array(columns).T


def _nodes(temperatures: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct temperatures (sets at one temperature merged, their values averaged)."""
    nodes, index = np.unique(temperatures, return_inverse=True)
    return nodes, np.bincount(index, weights=values) / np.bincount(index)


def _cubic(x: np.ndarray, y: np.ndarray) -> tuple[np.poly1d, float]:
    """The least-squares cubic of y(x) and the rows' scatter about it (rms, 4 degrees of freedom out)."""
    cubic = np.poly1d(np.polyfit(x, y, 3))
    return cubic, math.sqrt(np.sum((y - cubic(x)) ** 2) / max(len(x) - 4, 1))


def pair_shift(colder: Isotherm, warmer: Isotherm, colder_offset=0.0, warmer_offset=0.0) -> PairShift:
    """The shift of ``colder`` onto ``warmer``, d = log10 a_T(colder) - log10 a_T(warmer), by least squares
    on their overlap (module docstring), the overlap it leaves (decades), the rms of the weighted
    differences there (about 1 where the sets superpose within their scatter) and what its standard error
    needs (:class:`PairShift`). The offsets (decades) move each row's log10 f first. DMAError when the
    best shift leaves too little overlap."""
    xa = np.log10(colder.frequency) + colder_offset
    xb = np.log10(warmer.frequency) + warmer_offset
    ya = np.log10([colder.storage, colder.loss])
    yb = np.log10([warmer.storage, warmer.loss])
    ca, cb = [_cubic(xa, y) for y in ya], [_cubic(xb, y) for y in yb]
    scatter_a = np.array([max(c[1], FLOOR) for c in ca])
    scatter_b = np.array([max(c[1], FLOOR) for c in cb])
    weights = 1 / (scatter_a**2 + scatter_b**2)
    least = MIN_OVERLAP * min(np.ptp(xa), np.ptp(xb))
    lo, hi = xb.min() - xa.max() + least, xb.max() - xa.min() - least

    def objective(d) -> np.ndarray:
        """The mean squared weighted difference at each trial shift of the array ``d``."""
        d = np.atleast_1d(d)[:, None]
        at_b, at_a = xa[None, :] + d, xb[None, :] - d  # colder rows in warmer's frequencies, and back
        ina = (at_b >= xb.min()) & (at_b <= xb.max())
        inb = (at_a >= xa.min()) & (at_a <= xa.max())
        total = sum(w * (np.sum(ina * (y_a - pb(at_b)) ** 2, axis=1)
                         + np.sum(inb * (y_b - pa(at_a)) ** 2, axis=1))
                    for w, y_a, y_b, (pa, _), (pb, _) in zip(weights, ya, yb, ca, cb))
        count = len(weights) * (ina.sum(axis=1) + inb.sum(axis=1))
        return np.where(count > 0, total / np.maximum(count, 1), np.inf)

    grid = np.linspace(lo, hi, max(3, math.ceil((hi - lo) / GRID_STEP) + 1))
    best = int(np.argmin(objective(grid)))
    if best in (0, len(grid) - 1):
        raise DMAError(f"--shift auto: sets {colder.label} ({colder.temperature:g} K) and {warmer.label} "
                       f"({warmer.temperature:g} K) do not overlap on the master curve (their best shift "
                       f"leaves less than {least:.2g} decade of overlap); measure at closer temperatures, or "
                       "give the shift law (--shift wlf:... or arrhenius:...)")
    found = minimize_scalar(lambda d: float(objective(d)[0]), bounds=(grid[best - 1], grid[best + 1]),
                            method="bounded", options={"xatol": 1e-6})
    d = float(found.x)
    overlap = min(xa.max() + d, xb.max()) - max(xa.min() + d, xb.min())
    gradient_a, gradient_b = _shift_gradient(xa, xb, ya, yb, d, ca, cb, weights)
    return PairShift(d, float(overlap), math.sqrt(float(objective(d)[0])), gradient_a, gradient_b, scatter_a,
                     scatter_b)


def _shift_gradient(xa, xb, ya, yb, d: float, ca, cb, weights) -> tuple[np.ndarray, np.ndarray]:
    """(dd/dya, dd/dyb), shape (2, rows) each: the change of the shift found with each row's log10 modulus
    (the implicit function's derivative). The colder rows compared with the warmer's cubic have residuals
    r1 = ya - pb(xa + d), the warmer's with the colder's r2 = yb - pa(xb - d), pa and pb the least-squares
    cubics of the rows (linear in them: the coefficients P y, P the projection); d makes
    g = sum_m w_m (J1.r1 + J2.r2) vanish, J = dr/dd (J1 = -pb'(xa + d), J2 = pa'(xb - d)), so
    dd/dy = -(dg/dy) / (dg/dd), both taken exactly (with the cubics' slopes and curvatures)."""
    ina = (xa + d >= xb.min()) & (xa + d <= xb.max())
    inb = (xb - d >= xa.min()) & (xb - d <= xa.max())
    u, v = xa[ina] + d, xb[inb] - d  # where each set's rows are read off the other's cubic
    project_a, project_b = np.linalg.pinv(np.vander(xa, 4)), np.linalg.pinv(np.vander(xb, 4))
    value_b, value_a = np.vander(u, 4) @ project_b, np.vander(v, 4) @ project_a  # p(x) = value @ y
    slope_b = np.hstack([np.vander(u, 3) * [3.0, 2.0, 1.0], np.zeros((len(u), 1))]) @ project_b  # p'(x)
    slope_a = np.hstack([np.vander(v, 3) * [3.0, 2.0, 1.0], np.zeros((len(v), 1))]) @ project_a
    dg_dd, dg_da, dg_db = 0.0, [], []
    for w, y_a, y_b, (pa, sa), (pb, sb) in zip(weights, ya, yb, ca, cb):
        r1, r2 = y_a[ina] - pb(u), y_b[inb] - pa(v)
        j1, j2 = -np.polyder(pb)(u), np.polyder(pa)(v)
        dg_dd += w * (j1 @ j1 - np.polyder(pb, 2)(u) @ r1 + j2 @ j2 - np.polyder(pa, 2)(v) @ r2)
        grad_a = np.zeros(len(xa))
        grad_a[ina] += j1
        grad_a += slope_a.T @ r2 - value_a.T @ j2
        grad_b = np.zeros(len(xb))
        grad_b[inb] += j2
        grad_b += -slope_b.T @ r1 - value_b.T @ j1
        # the weight w = 1 / (sa^2 + sb^2) moves with the rows too: d(s^2)/dy = 2 (y - p(x)) / (rows - 4)
        g = j1 @ r1 + j2 @ r2
        for grad, s, y, p, x in ((grad_a, sa, y_a, pa, xa), (grad_b, sb, y_b, pb, xb)):
            if s > FLOOR:
                grad -= w * g * 2 * (y - p(x)) / max(len(x) - 4, 1)
        dg_da.append(w * grad_a)
        dg_db.append(w * grad_b)
    if not dg_dd > 0:  # not a minimum the data determine
        return np.full((2, len(xa)), np.inf), np.full((2, len(xb)), np.inf)
    return -np.array(dg_da) / dg_dd, -np.array(dg_db) / dg_dd


def fit_wlf(T: np.ndarray, log10_aT: np.ndarray, T_ref: float) -> LawFit:
    """WLF about T_ref fitted to the factors by least squares, its pole T_ref - C2 below the coldest."""
    dT = T - T_ref
    pole = T_ref - T.min() + 1e-3  # C2 above this keeps the pole below the coldest set

    def residuals(c):
        return -c[0] * dT / (c[1] + dT) - log10_aT

    use = np.abs(log10_aT) > 1e-3  # (T - T_ref)/log10 a_T = -C2/C1 - (T - T_ref)/C1: a line's start
    start = [17.44, max(51.6, 2 * pole)]
    if use.sum() >= 2:
        slope, intercept = np.polyfit(dT[use], dT[use] / log10_aT[use], 1)
        if slope < 0 and -intercept / slope > pole:
            start = [-1 / slope, intercept / slope]
    try:
        found = least_squares(residuals, start, bounds=([1e-9, pole], [np.inf, np.inf]))
    except ValueError as exc:  # (no finite start)
        return LawFit(None, math.nan, math.nan, f"no WLF fit ({exc})")
    C1, C2 = (float(v) for v in found.x)
    r = residuals(found.x)
    return LawFit(materials.WLF(C1, C2, float(T_ref)), float(np.sqrt(np.mean(r**2))), float(np.abs(r).max()))


def fit_arrhenius(T: np.ndarray, log10_aT: np.ndarray, T_ref: float) -> LawFit:
    """Arrhenius about T_ref fitted to the factors by linear least squares in Ea."""
    u = (1 / T - 1 / T_ref) / (materials.GAS_CONSTANT * math.log(10))  # log10 a_T = Ea u
    Ea = float(np.dot(u, log10_aT) / np.dot(u, u))
    r = Ea * u - log10_aT
    if not Ea > 0:
        return LawFit(None, float(np.sqrt(np.mean(log10_aT**2))), float(np.abs(log10_aT).max()),
                      "the factors do not fall with temperature")
    return LawFit(materials.Arrhenius(Ea, float(T_ref)), float(np.sqrt(np.mean(r**2))),
                  float(np.abs(r).max()))
