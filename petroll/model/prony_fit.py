"""A generalized Maxwell (Prony) series fitted to storage and loss moduli (``petroll material fit``).

A generalized Maxwell series E(t) = Einf + sum_k E_k exp(-t / T_k) has, with w = 2 pi f,

    E'(w) = Einf + sum_k E_k (w T_k)^2 / (1 + (w T_k)^2),    E''(w) = sum_k E_k w T_k / (1 + (w T_k)^2),

linear in (Einf, E_k) once the relaxation times T_k are fixed. :func:`fit_prony` places candidate times
evenly in log over the data's range of 1/w, extended by one decade at each end (relaxations just outside
the measured window show their tails in the data), and solves the non-negative least-squares problem
(``scipy.optimize.nnls``) on the relative residuals E'_fit/E' - 1 and E''_fit/E'' - 1: both moduli count
in relative terms whatever their size. Candidates left at zero modulus are dropped.

**How many terms.** By default the density of candidate times is chosen for the data: the coarsest of
DENSITIES (per decade) whose rms error is within TOLERANCE of the densest's, or below FLOOR. Noisy data
(measurements) then take about 2 terms per decade: the series follows the data's trend, not its noise, and
a positive sum of Maxwell terms half a decade apart cannot oscillate between them by more than a
fraction of a per cent. Exact data (a known series) take as many as they need. ``terms`` or
``per_decade`` fix the candidates instead.

**The relaxed modulus.** When the data's lowest-frequency E' is flat within its scatter over a decade or
more (:func:`plateau`), the data have reached the relaxed state: Einf is the mean E' of the plateau's
lowest decade, and no candidate time reaches beyond the lowest frequency (1/(2 pi f_min)): slow terms
would otherwise take the plateau over, the more so where the measured loss does not vanish on it (an
instrument's phase offset). Otherwise Einf is a free unknown of the fit (refused if it comes out 0).
``einf`` fixes it instead: a value (Pa), or "data" (the mean E' of the lowest quarter decade).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from petroll.errors import DMAError
from petroll.model import materials
from petroll.model.limits import MAGNITUDES, scale_message

DENSITIES = (1.0, 1.5, 2.0, 3.0, 5.0, 10.0, 20.0)
"""Candidate times per decade tried by default, coarsest first; the last is the reference (the best)."""

TOLERANCE = 1.05
"""A density is taken when its rms relative error is within this factor of the densest's..."""

FLOOR = 1e-3
"""... or below this (0.1 %: finer than DMA data are measured)."""

EXTEND_DECADES = 1.0
"""How far the candidate times reach beyond the data's range of 1/(2 pi f), in decades, at each end."""

PLATEAU_DECADES = 1.0
"""The least span (decades of frequency, from the lowest) over which E' must be flat to be a plateau."""

FROM_DATA_DECADES = 0.25
"""``einf = "data"``: Einf is the mean E' of the rows within this many decades of the lowest frequency."""

MAX_TERMS = 2000
"""The most candidate times a fit takes (``terms``, or ``per_decade`` times the decades): NNLS's work grows
with their square (2000: about a second for 150 rows). The default densities, at most 20 per decade over
the at most 60 decades of data within MAGNITUDES (and 2 more), give at most 1241."""

SIGNIFICANT = 7
"""Significant digits kept of each fitted number (the TOML block is written from them; the reported
errors are those of the rounded series)."""


@dataclass(frozen=True)
class PronyFit:
    """A fitted generalized Maxwell series E(t) = Einf + sum moduli[k] exp(-t / times[k]) (Pa, s), times
    increasing, with its relative errors on the data it was fitted to (rms and largest over the E' and
    E'' points together, and the largest of each), how many candidate times it had (``per_decade`` of
    them per decade; ``best_rms``: the densest default density's rms error, when the density was chosen)
    and how Einf was found (``einf_how``, a phrase)."""

    Einf: float
    moduli: tuple[float, ...]
    times: tuple[float, ...]
    nu: float
    candidates: int  # number of candidate times offered to NNLS
    frequency_range: tuple[float, float]  # Hz, of the fitted (reduced) data
    rms_error: float
    max_error: float
    max_storage_error: float
    max_loss_error: float
    per_decade: float = math.nan
    best_rms: float = math.nan
    einf_how: str = "fitted"

    def dynamic(self, frequency) -> tuple[np.ndarray, np.ndarray]:
        """(E', E'') of the series at ``frequency`` (Hz), Pa."""
        return storage_loss(self.Einf, self.moduli, self.times, frequency)

    def material(self) -> materials.Prony:
        """The surface creep compliance J(t) of the series (its exact Kelvin form, materials.maxwell)."""
        return materials.maxwell(self.Einf, self.nu, self.moduli, self.times)

    def table(self, shift=None, T_ref: float | None = None) -> dict:
        """The scene's [material] table; with a shift law (materials.make_shift's), at ``T_ref`` (K;
        default the law's): temperature = T_ref, shift = the law's table."""
        table = {"model": "prony", "series": "maxwell", "Einf": self.Einf, "nu": self.nu,
                 "moduli": list(self.moduli), "times": list(self.times)}
        if shift is not None:
            table.update(temperature=shift.T_ref if T_ref is None else T_ref, shift=shift.table())
        return table


def storage_loss(Einf: float, moduli, times, frequency) -> tuple[np.ndarray, np.ndarray]:
    """(E', E'') (Pa) of E(t) = Einf + sum moduli[k] exp(-t / times[k]) at ``frequency`` (Hz)."""
    columns = _columns(np.asarray(frequency, dtype=float), np.asarray(times, dtype=float))
    moduli = np.asarray(moduli, dtype=float)
    return Einf + columns[0] @ moduli, columns[1] @ moduli


def _columns(frequency: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """E' and E'' of a unit Maxwell term per time (columns), at each frequency (rows)."""
    wt = 2 * np.pi * frequency[:, None] * times[None, :]
    return wt**2 / (1 + wt**2), wt / (1 + wt**2)


def candidate_times(f_min: float, f_max: float, terms: int | None = None, per_decade: float | None = None,
                    slow_extension: float = EXTEND_DECADES) -> np.ndarray:
    """Relaxation times (s) evenly spaced in log from 1/(2 pi f_max) / 10^EXTEND_DECADES to 1/(2 pi f_min)
    x 10^slow_extension: ``terms`` of them, or ``per_decade`` per decade (default 20)."""
    lo = math.log10(1 / (2 * math.pi * f_max)) - EXTEND_DECADES
    hi = math.log10(1 / (2 * math.pi * f_min)) + slow_extension
    if terms is None:
        terms = math.ceil((per_decade or DENSITIES[-1]) * (hi - lo)) + 1
    return np.logspace(lo, hi, terms) if terms > 1 else np.array([10 ** (0.5 * (lo + hi))])


def plateau(frequency, storage) -> tuple[float, float, float, int] | None:
    """(span, change, mean, rows) when E' at the lowest frequencies is flat within its scatter: the largest
    span from the lowest frequency (quarter-decade steps, at least PLATEAU_DECADES, each holding 5 rows
    or more over most of it) on which a straight line of log E' against log f changes by at most twice
    the rows' scatter about it (or FLOOR); ``change``: the line's relative change over the span; ``mean``:
    the mean E' (Pa) of the ``rows`` rows within PLATEAU_DECADES of the lowest frequency. None otherwise."""
    x, y = np.log10(np.asarray(frequency, dtype=float)), np.log(np.asarray(storage, dtype=float))
    found = None
    for span in np.arange(PLATEAU_DECADES, np.ptp(x) + 1e-9, 0.25):
        rows = x <= x.min() + span
        if rows.sum() < 5 or np.ptp(x[rows]) < 0.8 * span:
            continue
        slope, intercept = np.polyfit(x[rows], y[rows], 1)
        scatter = math.sqrt(np.sum((y[rows] - slope * x[rows] - intercept) ** 2) / (rows.sum() - 2))
        if abs(slope) * span <= max(2 * scatter, FLOOR):
            found = (float(span), float(math.expm1(abs(slope) * span)))
    if found is None:
        return None
    lowest = x <= x.min() + PLATEAU_DECADES
    return (*found, float(np.mean(np.exp(y[lowest]))), int(lowest.sum()))


def fit_prony(frequency, storage, loss, terms: int | None = None, per_decade: float | None = None,
              nu: float = 0.5, einf: float | str | None = None) -> PronyFit:
    """Fit a Maxwell series with non-negative moduli to E'(f), E''(f) (Hz, Pa, Pa; module docstring).

    ``terms`` (candidate times in all) or ``per_decade`` (per decade of the candidates' range) fixes the
    candidates (default: the density chosen for the data); ``einf``: None (fitted), a value (Pa) or
    "data"; ``nu`` (-1 < nu <= 0.5) is carried into the material. Rows in any order. DMAError if the
    request is invalid or the data give no relaxed modulus (Einf = 0), saying why.
    """
    f, e1, e2 = _checked(frequency, storage, loss, terms, per_decade, nu)
    fixed, einf_how, slow = _relaxed(f, e1, einf)
    lo, hi = float(f.min()), float(f.max())
    decades = math.log10(hi / lo) + EXTEND_DECADES + slow  # the candidates' span (candidate_times)
    if per_decade is not None and math.ceil(per_decade * decades) + 1 > MAX_TERMS:
        raise DMAError(f"per_decade = {per_decade!r} (--per-decade): gives {math.ceil(per_decade * decades) + 1} "
                       f"candidate times over their {decades:.3g} decades; at most {MAX_TERMS}")
    best = math.nan
    if terms is not None or per_decade is not None:
        times = candidate_times(lo, hi, terms, per_decade, slow)
        x, rms = _solve(f, e1, e2, times, fixed)
    else:
        tried = {}
        for density in reversed(DENSITIES):  # the densest first: the reference
            tried[density] = _solve(f, e1, e2, candidate_times(lo, hi, None, density, slow), fixed)
            if density == DENSITIES[-1]:
                best = tried[density][1]
        per_decade = next(d for d in DENSITIES if tried[d][1] <= max(TOLERANCE * best, FLOOR))
        times = candidate_times(lo, hi, None, per_decade, slow)
        x, rms = tried[per_decade]
    Einf = _rounded(x[0])
    if Einf <= 0:
        raise DMAError("the fit gives no relaxed modulus (Einf = 0): the data do not reach a rubbery plateau "
                       "at their lowest frequencies (E' not flat within its scatter over a decade there); "
                       "add lower frequencies (or higher temperatures), or set it: --einf VALUE or "
                       "--einf-from-data")
    active = np.flatnonzero(x[1:] > 0)
    moduli = tuple(_rounded(m) for m in x[1:][active])
    times = tuple(_rounded(t) for t in times[active])
    fit_e1, fit_e2 = storage_loss(Einf, moduli, times, f)
    r1, r2 = np.abs(fit_e1 / e1 - 1), np.abs(fit_e2 / e2 - 1)
    both = np.concatenate([r1, r2])
    return PronyFit(Einf, moduli, times, float(nu), len(x) - 1, (lo, hi), float(np.sqrt(np.mean(both**2))),
                    float(both.max()), float(r1.max()), float(r2.max()), float(per_decade or math.nan), best,
                    einf_how)


def _checked(frequency, storage, loss, terms, per_decade, nu) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The data as float arrays, or DMAError naming what is wrong with the request."""
    f = np.asarray(frequency, dtype=float)
    e1, e2 = np.asarray(storage, dtype=float), np.asarray(loss, dtype=float)
    if not (f.shape == e1.shape == e2.shape and f.ndim == 1):
        raise DMAError("frequency, storage and loss must be 1-D arrays of one length")
    values = np.concatenate([f, e1, e2])
    if len(f) < 2 or not np.all(np.isfinite(values) & (values > 0)):
        raise DMAError("frequency, storage and loss must hold at least 2 finite numbers > 0 each")
    if not np.all((MAGNITUDES[0] <= values) & (values <= MAGNITUDES[1])):
        bad = float(values[(values < MAGNITUDES[0]) | (values > MAGNITUDES[1])][0])
        raise DMAError(f"frequency, storage and loss: {scale_message(bad, 'Hz or Pa')}")
    if f.max() == f.min():
        raise DMAError(f"all frequencies are {f[0]:g} Hz: a fit needs at least 2 different frequencies")
    if terms is not None and per_decade is not None:
        raise DMAError("give terms or per_decade, not both")
    if terms is not None and (isinstance(terms, bool) or not isinstance(terms, (int, np.integer))
                              or not 1 <= terms <= MAX_TERMS):
        raise DMAError(f"terms = {terms!r} (--terms): must be an integer >= 1, at most {MAX_TERMS}")
    if per_decade is not None and not 0 < per_decade < math.inf:
        raise DMAError(f"per_decade = {per_decade!r}: must be a finite number > 0")
    if not -1 < nu <= 0.5:
        raise DMAError(f"nu = {nu!r}: must be a number with -1 < nu <= 0.5")
    return f, e1, e2


def _relaxed(f: np.ndarray, e1: np.ndarray, einf) -> tuple[float | None, str, float]:
    """(Einf fixed or None, how it is found, the candidates' extension beyond the lowest frequency)."""
    if isinstance(einf, str) and einf == "data":
        rows = np.log10(f) <= np.log10(f.min()) + FROM_DATA_DECADES
        value = float(np.mean(e1[rows]))
        return value, (f"from the data: the mean E' of the {rows.sum()} rows within {FROM_DATA_DECADES:g} "
                       f"decade of the lowest frequency"), EXTEND_DECADES
    if einf is not None:
        if (isinstance(einf, bool) or not isinstance(einf, (int, float))
                or not MAGNITUDES[0] <= einf <= MAGNITUDES[1]):
            raise DMAError(f"--einf {einf!r}: must be a finite number > 0 (Pa), from {MAGNITUDES[0]:g} to "
                           f"{MAGNITUDES[1]:g}, or \"data\"")
        return float(einf), "given (--einf)", EXTEND_DECADES
    flat = plateau(f, e1)
    if flat is None:
        return None, "fitted", EXTEND_DECADES
    span, change, mean, rows = flat
    return mean, (f"the low-frequency plateau: flat within {100 * change:.2g} % over {span:g} decades, Einf "
                  f"the mean E' of its {rows} rows within {PLATEAU_DECADES:g} decade of the lowest "
                  "frequency; no candidate time beyond it"), 0.0


def _solve(f, e1, e2, times: np.ndarray, fixed: float | None) -> tuple[np.ndarray, float]:
    """(Einf and the moduli at ``times``, the rms relative error) by NNLS on the relative residuals; Einf a
    free unknown, or ``fixed``."""
    c1, c2 = _columns(f, times)
    scale = float(np.median(e1))  # unknowns in units of a typical modulus: O(1) numbers for NNLS
    matrix = np.vstack([np.hstack([np.ones((len(f), 1)), c1]) / e1[:, None],
                        np.hstack([np.zeros((len(f), 1)), c2]) / e2[:, None]]) * scale
    if fixed is not None:  # E'_fit/E' - 1 = (terms)/E' - (1 - Einf/E'): Einf's column moves to the target
        matrix[:, 0] *= fixed / scale
    target = np.ones(2 * len(f))
    if fixed is None:
        x, _ = nnls(matrix, target, maxiter=50 * matrix.shape[1])
    else:
        moduli, _ = nnls(matrix[:, 1:], target - matrix[:, 0], maxiter=50 * matrix.shape[1])
        x = np.concatenate([[1.0], moduli])
    rms = math.sqrt(np.mean((matrix @ x - target) ** 2))
    return x * np.concatenate([[scale if fixed is None else fixed], np.full(len(times), scale)]), rms


def _rounded(value: float) -> float:
    return float(f"{value:.{SIGNIFICANT}g}")
