"""Prony series fitted to dynamic mechanical analysis (DMA) data (``petroll material fit``).

DMA gives the uniaxial storage and loss moduli E'(f), E''(f) (Pa) against the frequency f (Hz), often at
several temperatures. A generalized Maxwell series E(t) = Einf + sum_k E_k exp(-t / T_k) has, with
w = 2 pi f,

    E'(w) = Einf + sum_k E_k (w T_k)^2 / (1 + (w T_k)^2),    E''(w) = sum_k E_k w T_k / (1 + (w T_k)^2),

linear in (Einf, E_k) once the relaxation times T_k are fixed. :func:`fit_prony` spreads candidate times
evenly in log over the data's range of 1/w extended by one decade at each end (so that relaxations just
outside the measured window, whose tails the data see, are represented), and solves the non-negative
least-squares problem (``scipy.optimize.nnls``) on the relative residuals E'_fit/E' - 1 and
E''_fit/E'' - 1: both moduli count in relative terms whatever their size. NNLS leaves most candidates at
zero modulus (about two active terms per relaxation the data resolve); those are dropped.

Data at several temperatures are shifted onto the reference temperature first (time-temperature
superposition): a point measured at f and T lies at the reduced frequency f a_T(T), a_T from the shift
law (:mod:`petroll.model.materials`). Temperatures are in kelvin.

The CSV (:func:`read_dma`): a header line ``frequency,storage,loss`` (any order; an optional fourth column
``temperature``), then one row of numbers per measurement; lines starting with ``#`` and blank lines are
skipped. Frequencies must increase down the rows (at each temperature).
"""

from __future__ import annotations

import csv
import math
import pathlib
import tomllib
from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from petroll.errors import PetrollError
from petroll.model import materials
from petroll.model.scene import dumps

COLUMNS = {"frequency": "Hz", "storage": "Pa", "loss": "Pa", "temperature": "K"}
"""The CSV's columns and their units; temperature is optional."""

ALLOWED = ("a CSV with the header frequency,storage,loss and optionally temperature (Hz, Pa, Pa, K), then "
           "rows of finite numbers > 0, frequency increasing down the rows (at each temperature); lines "
           "starting with # are comments")

DEFAULT_PER_DECADE = 20.0
"""Candidate relaxation times per decade when neither ``terms`` nor ``per_decade`` is given. Dense on
purpose: NNLS keeps only a few of them (docs/materials.md measures the error against the density)."""

EXTEND_DECADES = 1.0
"""How far the candidate times reach beyond the data's range of 1/(2 pi f), in decades, at each end."""

SIGNIFICANT = 7
"""Significant digits kept of each fitted number (the TOML block is written from them; the reported
errors are those of the rounded series)."""

SHIFT_TEXT = "wlf:C1,C2,T_ref or arrhenius:Ea,T_ref (C2, T_ref in K; Ea in J/mol), or a TOML file whose " \
             "[material] shift gives the law"


class DMAError(PetrollError):
    """A DMA file or fit request that cannot be used (one line: file, line, what is allowed)."""


@dataclass(frozen=True)
class DMAData:
    """DMA measurements in file order. ``reduced`` is the frequency shifted to the shift law's T_ref,
    f a_T(T) (Hz; the frequency itself without a temperature column)."""

    source: str
    frequency: np.ndarray  # Hz, as measured
    storage: np.ndarray  # E', Pa
    loss: np.ndarray  # E'', Pa
    temperature: np.ndarray | None  # K, or None without that column
    shift: materials.WLF | materials.Arrhenius | None
    reduced: np.ndarray  # Hz at T_ref


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

    def table(self, shift: materials.WLF | materials.Arrhenius | None = None) -> dict:
        """The scene's [material] table; with a shift law, at its T_ref (temperature = T_ref, shift)."""
        table = {"model": "prony", "series": "maxwell", "Einf": self.Einf, "nu": self.nu,
                 "moduli": list(self.moduli), "times": list(self.times)}
        if shift is not None:
            table.update(temperature=shift.T_ref, shift=shift.table())
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


def read_dma(path: str | pathlib.Path, shift: materials.WLF | materials.Arrhenius | None = None) -> DMAData:
    """Read a DMA table (module docstring); with a temperature column, ``shift`` (required) gives each
    row's reduced frequency. DMAError naming the file, the line and what is allowed for anything else."""
    path = pathlib.Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
        raise DMAError(f"{path}: cannot read it ({why}); must be {ALLOWED}") from None
    rows = [(number, fields) for number, fields in
            enumerate(csv.reader(text.splitlines()), start=1)
            if fields and "".join(fields).strip() and not fields[0].lstrip().startswith("#")]
    if not rows:
        raise DMAError(f"{path}: no header line; must be {ALLOWED}")
    header_line, header = rows[0]
    names = [name.strip().lower() for name in header]
    unknown = [n for n in names if n not in COLUMNS]
    missing = [n for n in ("frequency", "storage", "loss") if n not in names]
    if unknown or missing or len(set(names)) != len(names):
        what = (f"unknown column {unknown[0]!r}" if unknown else f"missing column {missing[0]!r}" if missing
                else "a column named twice")
        raise DMAError(f"{path}, line {header_line}: header {','.join(header)!r}: {what}; must be {ALLOWED}")
    values = np.empty((len(rows) - 1, len(names)))
    for i, (number, fields) in enumerate(rows[1:]):
        if len(fields) != len(names):
            raise DMAError(f"{path}, line {number}: {len(fields)} values for the {len(names)} columns "
                           f"{','.join(names)}; must be {ALLOWED}")
        for j, (name, field) in enumerate(zip(names, fields)):
            try:
                value = float(field)
            except ValueError:
                value = math.nan
            if not 0 < value < math.inf:
                raise DMAError(f"{path}, line {number}: {name} = {field.strip()!r}: must be a finite number > 0 "
                               f"({COLUMNS[name]}); the file must be {ALLOWED}")
            values[i, j] = value
    if len(values) < 2:
        raise DMAError(f"{path}: {len(values)} data row(s); a fit needs at least 2; must be {ALLOWED}")
    column = {name: values[:, j] for j, name in enumerate(names)}
    temperature = column.get("temperature")
    lines = [number for number, _ in rows[1:]]
    _check_increasing(path, lines, column["frequency"], temperature)
    reduced = column["frequency"]
    if temperature is not None:
        if shift is None:
            raise DMAError(f"{path}: a temperature column needs a shift law (petroll material fit --shift) to "
                           f"bring the data to one reference temperature: {SHIFT_TEXT}")
        factors = np.empty(len(temperature))
        for i, T in enumerate(temperature):
            try:
                factors[i] = materials.shift_factor(shift, float(T))
            except ValueError as exc:
                raise DMAError(f"{path}, line {lines[i]}: temperature = {T:g} K: the shift law {exc}") from None
        reduced = reduced * factors
    return DMAData(str(path), column["frequency"], column["storage"], column["loss"], temperature, shift,
                   reduced)


def _check_increasing(path, lines: list[int], frequency: np.ndarray, temperature: np.ndarray | None) -> None:
    last: dict[float, int] = {}
    for i, f in enumerate(frequency):
        key = float(temperature[i]) if temperature is not None else 0.0
        j = last.get(key)
        if j is not None and not f > frequency[j]:
            where = f" at temperature {key:g} K" if temperature is not None else ""
            raise DMAError(f"{path}, line {lines[i]}: frequency = {f:g} Hz does not exceed {frequency[j]:g} Hz "
                           f"on line {lines[j]}{where}; must be {ALLOWED}")
        last[key] = i


def parse_shift(text: str) -> materials.WLF | materials.Arrhenius:
    """A shift law from ``wlf:C1,C2,T_ref``, ``arrhenius:Ea,T_ref`` or a TOML file's [material] shift."""
    if text.endswith(".toml"):
        try:
            table = tomllib.loads(pathlib.Path(text).read_text(encoding="utf-8"))["material"]["shift"]
        except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, KeyError, TypeError) as exc:
            raise DMAError(f"--shift {text}: cannot read [material] shift from it ({type(exc).__name__}: "
                           f"{exc}); allowed: {SHIFT_TEXT}") from None
    else:
        law, _, numbers = text.partition(":")
        names = {"wlf": ("C1", "C2", "T_ref"), "arrhenius": ("Ea", "T_ref")}.get(law.strip().lower())
        try:
            parts = [float(v) for v in numbers.split(",")]
        except ValueError:
            parts = []
        if names is None or len(parts) != len(names):
            raise DMAError(f"--shift {text!r}: must be {SHIFT_TEXT}")
        table = {"law": law.strip().lower(), **dict(zip(names, parts))}
    try:
        return materials.make_shift(table)
    except ValueError as exc:
        raise DMAError(f"--shift {text}: {exc}") from None


def material_toml(fit: PronyFit, shift: materials.WLF | materials.Arrhenius | None = None,
                  source: str | None = None) -> str:
    """The [material] block of ``fit`` as TOML, with comment lines saying where it comes from."""
    lo, hi = fit.frequency_range
    where = f" from {source}" if source else ""
    at = f" at T_ref = {shift.T_ref:g} K" if shift is not None else ""
    head = (f"# Generalized Maxwell series fitted by petroll material fit{where}: {len(fit.moduli)} terms\n"
            f"# (of {fit.candidates} candidate times), to E', E'' over {lo:.4g} ... {hi:.4g} Hz{at}; relative "
            f"error rms {100 * fit.rms_error:.3g} %, max {100 * fit.max_error:.3g} %.\n")
    return head + dumps({"material": fit.table(shift)})
