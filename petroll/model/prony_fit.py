"""A generalized Maxwell (Prony) series fitted to storage and loss moduli (``petroll material fit``).

A generalized Maxwell series E(t) = Einf + sum_k E_k exp(-t / T_k) has, with w = 2 pi f,

    E'(w) = Einf + sum_k E_k (w T_k)^2 / (1 + (w T_k)^2),    E''(w) = sum_k E_k w T_k / (1 + (w T_k)^2),

linear in (Einf, E_k) once the relaxation times T_k are fixed. :func:`fit_prony` spreads candidate times
evenly in log over the data's range of 1/w extended by one decade at each end (so that relaxations just
outside the measured window, whose tails the data see, are represented), and solves the non-negative
least-squares problem (``scipy.optimize.nnls``) on the relative residuals E'_fit/E' - 1 and
E''_fit/E'' - 1: both moduli count in relative terms whatever their size. NNLS leaves most candidates at
zero modulus (about two active terms per relaxation the data resolve); those are dropped.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from petroll.errors import DMAError
from petroll.model import materials

DEFAULT_PER_DECADE = 20.0
"""Candidate relaxation times per decade when neither ``terms`` nor ``per_decade`` is given. Dense on
purpose: NNLS keeps only a few of them (docs/materials.md measures the error against the density)."""

EXTEND_DECADES = 1.0
"""How far the candidate times reach beyond the data's range of 1/(2 pi f), in decades, at each end."""

SIGNIFICANT = 7
"""Significant digits kept of each fitted number (the TOML block is written from them; the reported
errors are those of the rounded series)."""


@dataclass(frozen=True)
class PronyFit:
    """A fitted generalized Maxwell series E(t) = Einf + sum moduli[k] exp(-t / times[k]) (Pa, s), times
    increasing, with its relative errors on the data it was fitted to (rms and largest over the E' and
    E'' points together, and the largest of each)."""

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


def candidate_times(f_min: float, f_max: float, terms: int | None = None,
                    per_decade: float | None = None) -> np.ndarray:
    """Relaxation times (s) evenly spaced in log from 1/(2 pi f_max) to 1/(2 pi f_min), extended by
    EXTEND_DECADES at each end: ``terms`` of them, or ``per_decade`` per decade (DEFAULT_PER_DECADE)."""
    lo = math.log10(1 / (2 * math.pi * f_max)) - EXTEND_DECADES
    hi = math.log10(1 / (2 * math.pi * f_min)) + EXTEND_DECADES
    if terms is None:
        terms = math.ceil((per_decade or DEFAULT_PER_DECADE) * (hi - lo)) + 1
    return np.logspace(lo, hi, terms) if terms > 1 else np.array([10 ** (0.5 * (lo + hi))])


def fit_prony(frequency, storage, loss, terms: int | None = None, per_decade: float | None = None,
              nu: float = 0.5) -> PronyFit:
    """Fit a Maxwell series with non-negative moduli to E'(f), E''(f) (Hz, Pa, Pa; module docstring).

    ``terms`` (candidate times in all) or ``per_decade`` (per decade of the extended range) sets the
    candidate times (default: DEFAULT_PER_DECADE per decade); ``nu`` (-1 < nu <= 0.5) is carried into
    the material. DMAError if the request is invalid or the data give no relaxed modulus (Einf = 0).
    """
    f = np.asarray(frequency, dtype=float)
    e1, e2 = np.asarray(storage, dtype=float), np.asarray(loss, dtype=float)
    if not (f.shape == e1.shape == e2.shape and f.ndim == 1):
        raise DMAError("frequency, storage and loss must be 1-D arrays of one length")
    if len(f) < 2 or not np.all(np.isfinite(np.concatenate([f, e1, e2])) & (np.concatenate([f, e1, e2]) > 0)):
        raise DMAError("frequency, storage and loss must hold at least 2 finite numbers > 0 each")
    if f.max() == f.min():
        raise DMAError(f"all frequencies are {f[0]:g} Hz: a fit needs at least 2 different frequencies")
    if terms is not None and per_decade is not None:
        raise DMAError("give terms or per_decade, not both")
    if terms is not None and (isinstance(terms, bool) or not isinstance(terms, (int, np.integer)) or terms < 1):
        raise DMAError(f"terms = {terms!r}: must be an integer >= 1")
    if per_decade is not None and not 0 < per_decade < math.inf:
        raise DMAError(f"per_decade = {per_decade!r}: must be a finite number > 0")
    if not -1 < nu <= 0.5:
        raise DMAError(f"nu = {nu!r}: must be a number with -1 < nu <= 0.5")
    times = candidate_times(float(f.min()), float(f.max()), terms, per_decade)
    c1, c2 = _columns(f, times)
    scale = float(np.median(e1))  # unknowns in units of a typical modulus: O(1) numbers for NNLS
    matrix = np.vstack([np.hstack([np.ones((len(f), 1)), c1]) / e1[:, None],
                        np.hstack([np.zeros((len(f), 1)), c2]) / e2[:, None]]) * scale
    x, _ = nnls(matrix, np.ones(2 * len(f)), maxiter=50 * matrix.shape[1])
    x = x * scale
    Einf, active = _rounded(x[0]), np.flatnonzero(x[1:] > 0)
    if Einf <= 0:
        raise DMAError("the fit gives no relaxed modulus (Einf = 0): the data do not reach a rubbery plateau "
                       "at their lowest frequencies; add lower frequencies (or higher temperatures)")
    moduli = tuple(_rounded(m) for m in x[1:][active])
    times = tuple(_rounded(t) for t in times[active])
    fit_e1, fit_e2 = storage_loss(Einf, moduli, times, f)
    r1, r2 = np.abs(fit_e1 / e1 - 1), np.abs(fit_e2 / e2 - 1)
    both = np.concatenate([r1, r2])
    return PronyFit(Einf, moduli, times, float(nu), len(x) - 1, (float(f.min()), float(f.max())),
                    float(np.sqrt(np.mean(both**2))), float(both.max()), float(r1.max()), float(r2.max()))


def _rounded(value: float) -> float:
    return float(f"{value:.{SIGNIFICANT}g}")
