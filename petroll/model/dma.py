"""DMA tables (``petroll material fit``): measurement sets, time-temperature shift, the fitted block.

DMA gives the uniaxial storage and loss moduli E'(f), E''(f) (Pa) against the frequency f (Hz), usually
as frequency sweeps at several temperatures. The rows of one sweep form a **set** (an isotherm): the rows
sharing a value of the optional ``set`` column, or else the rows whose temperatures lie within
``tolerance`` (default 0.5 K) of their neighbours in temperature (the thermocouple wanders by tenths of a
kelvin along a sweep). Each set stands at its mean temperature; :func:`group_sets` says how they are
found. Rows may come in any order, frequencies repeated or nearly so: each set's rows are taken by
increasing frequency.

Data at several temperatures are shifted onto a reference temperature T_ref (time-temperature
superposition): a row measured at f and T lies at the reduced frequency f a_T(T), a_T from the shift
law (:mod:`petroll.model.materials`) at the row's own temperature. Temperatures are in kelvin.

The Prony fit itself is :func:`petroll.model.prony_fit.fit_prony` (also reachable here as
``dma.fit_prony``).

The CSV (:func:`read_dma`): a header line naming the columns ``frequency,storage,loss`` (any order; optional
``temperature`` and ``set``), optionally a units row, then one row per measurement; lines starting with
``#`` and blank lines are skipped, a UTF-8 byte-order mark is ignored, and tabs or semicolons separate the
fields where the header holds them. Besides petroll's names, the names pyvisco and common instruments
export are recognised (:data:`NAMES`; ``columns`` maps others), other quantities they export are ignored
(:data:`EXTRA`), and a unit is read from a units row, from the header name (``E' (MPa)``) or from
``units`` (:data:`UNITS`); values are converted to Hz, Pa and K, then checked for plausibility
(:mod:`petroll.model.dma_columns`).
"""

from __future__ import annotations

import math
import pathlib
from dataclasses import dataclass

import numpy as np

from petroll.errors import DMAError, SceneError
from petroll.model import materials, tts
from petroll.model.dma_columns import (  # noqa: F401
    ALLOWED,
    COLUMNS,
    EXTRA,
    NAMES,
    PLAUSIBLE,
    SHEAR,
    UNITS,
    likely_units,
    parse_mapping,
    read_columns,
    unit_hint,
)
from petroll.model.prony_fit import TOLERANCE, PronyFit, candidate_times, fit_prony, storage_loss  # noqa: F401
from petroll.model.scene import dumps
from petroll.model.toml_file import load_scene_table

DEFAULT_TOLERANCE = 0.5
"""Temperatures (K) within which rows, taken in order of temperature, belong to one set (no set column)."""

SPREAD_FACTOR = 2.0
"""A set found by temperature whose rows spread over more than SPREAD_FACTOR x tolerance is refused: its
temperatures chain (a ramp, not an isotherm)."""

SHIFT_TEXT = ("auto:T_ref (the factors found from the data), wlf:C1,C2,T_ref or arrhenius:Ea,T_ref (C2, "
              "T_ref in K; Ea in J/mol), or a TOML file whose [material] shift gives the law")


@dataclass(frozen=True)
class AutoShift:
    """``--shift auto:T_ref``: the shift factors are found from the data (:mod:`petroll.model.tts`) and
    chained to T_ref (K)."""

    T_ref: float


@dataclass(frozen=True)
class DMASet:
    """One measurement set (an isotherm): ``rows`` index the table's arrays, by increasing frequency;
    ``label`` is the set column's value, or the set's rank in temperature (1: the coldest) without it;
    ``temperature`` the rows' mean (K; None without a temperature column), ``spread`` their range (K)."""

    label: str
    rows: np.ndarray
    temperature: float | None
    spread: float


@dataclass(frozen=True)
class DMAData:
    """DMA measurements in file order, their sets ordered by temperature, and the reduced frequency f a_T
    at each row's temperature (Hz at T_ref; the frequency itself without a temperature column)."""

    source: str
    frequency: np.ndarray  # Hz, as measured
    storage: np.ndarray  # E', Pa
    loss: np.ndarray  # E'', Pa
    temperature: np.ndarray | None  # K, or None without that column
    sets: tuple[DMASet, ...]
    shift: materials.WLF | materials.Arrhenius | materials.TableShift | None
    reduced: np.ndarray  # Hz at T_ref
    tolerance: float | None = None  # K, when the sets were found by temperature
    found: tts.ShiftFit | None = None  # the factors found from the data (--shift auto)
    columns: dict | None = None  # {column: (its header name, the unit read)}
    ignored: tuple[str, ...] = ()  # header names of the columns not used

    @property
    def T_ref(self) -> float | None:
        """The reference temperature of the reduced frequencies (K), None without a shift law."""
        if self.found is not None:
            return self.found.T_ref
        return None if self.shift is None else self.shift.T_ref


def read_dma(path: str | pathlib.Path, shift=None, tolerance: float = DEFAULT_TOLERANCE,
             columns: dict[str, str] | None = None, units: dict[str, str] | None = None) -> DMAData:
    """Read a DMA table (module docstring) and group its rows into sets (:func:`group_sets`); with a
    temperature column, ``shift`` (required: a law of materials.make_shift, or :class:`AutoShift` to find
    the factors from the data) gives each row's reduced frequency. ``columns`` maps petroll's columns
    (frequency, storage, loss, temperature, set) to header names (the others are then ignored), ``units``
    gives their units (:data:`UNITS`; over a units row's). DMAError naming the file, the line and what is
    allowed for anything else."""
    path = pathlib.Path(path)
    if not 0 < tolerance < math.inf:
        raise DMAError(f"--tolerance {tolerance!r}: must be a finite number > 0 (K)")
    lines, column, used, ignored = read_columns(path, columns or {}, units or {})
    temperature, labels = column.get("temperature"), column.get("set")
    if labels is not None and temperature is None:
        raise DMAError(f"{path}: a set column needs a temperature column (the sets are isotherms); must be "
                       f"{ALLOWED}")
    sets = group_sets(path, lines, column["frequency"], temperature, labels, tolerance)
    reduced = column["frequency"]
    if temperature is not None and shift is None:
        raise DMAError(f"{path}: a temperature column needs a shift law (petroll material fit --shift) to "
                       f"bring the data to one reference temperature: {SHIFT_TEXT}")
    found = None
    if isinstance(shift, AutoShift):
        found, reduced = _found(path, column, sets, shift.T_ref)
        shift = found.law
    elif temperature is not None:
        reduced = reduced * _factors(path, lines, shift, temperature)
    by_temperature = temperature is not None and labels is None
    return DMAData(str(path), column["frequency"], column["storage"], column["loss"], temperature, sets,
                   shift, reduced, tolerance if by_temperature else None, found, used, ignored)


def _found(path, column: dict, sets: tuple[DMASet, ...], T_ref: float) -> tuple[tts.ShiftFit, np.ndarray]:
    """The shift factors found from the sets (tts.find_shifts) and every row's reduced frequency (Hz)."""
    if column.get("temperature") is None:
        raise DMAError(f"{path}: --shift auto needs a temperature column (the factors are found between "
                       "measurement sets at different temperatures)")
    isotherms = [tts.Isotherm(s.label, s.temperature, *(column[name][s.rows] for name in
                                                         ("frequency", "storage", "loss", "temperature")))
                 for s in sets]
    try:
        found = tts.find_shifts(isotherms, T_ref)
    except DMAError as exc:
        raise DMAError(f"{path}: {exc}") from None
    reduced = np.empty(len(column["frequency"]))
    for s, log10_aT in zip(sets, found.row_log10_aT):
        reduced[s.rows] = column["frequency"][s.rows] * 10**log10_aT
    return found, reduced


def _factors(path, lines: list[int], shift, temperature: np.ndarray) -> np.ndarray:
    factors = np.empty(len(temperature))
    for i, T in enumerate(temperature):
        try:
            factors[i] = materials.shift_factor(shift, float(T))
        except ValueError as exc:
            raise DMAError(f"{path}, line {lines[i]}: temperature = {T:g} K: the shift law {exc}") from None
    return factors


def group_sets(path, lines: list[int], frequency: np.ndarray, temperature: np.ndarray | None,
               labels: list[str] | None, tolerance: float) -> tuple[DMASet, ...]:
    """The measurement sets of a table, by increasing mean temperature.

    With ``labels`` (the set column): the rows sharing a label. Otherwise the rows sorted by temperature,
    a new set starting wherever two neighbours differ by more than ``tolerance`` (K); a set whose rows
    then spread over more than SPREAD_FACTOR x tolerance is refused (the temperatures chain: a ramp).
    Without a temperature column: one set of every row."""
    if temperature is None:
        return (DMASet("1", np.argsort(frequency, kind="stable"), None, 0.0),)
    if labels is not None:
        names = list(dict.fromkeys(labels))
        label_of = np.array([names.index(label) for label in labels])
        groups = [(name, np.flatnonzero(label_of == k)) for k, name in enumerate(names)]
    else:
        order = np.argsort(temperature, kind="stable")
        breaks = np.flatnonzero(np.diff(temperature[order]) > tolerance) + 1
        groups = [(None, rows) for rows in np.split(order, breaks)]
    groups.sort(key=lambda group: float(np.mean(temperature[group[1]])))
    sets = []
    for rank, (name, rows) in enumerate(groups, start=1):
        T = temperature[rows]
        spread = float(T.max() - T.min())
        if name is None and spread > SPREAD_FACTOR * tolerance:
            raise DMAError(f"{path}: the rows from line {lines[rows.min()]} at {T.min():g} ... {T.max():g} "
                           f"K chain into one set: neighbours in temperature within --tolerance "
                           f"{tolerance:g} K, but spread over {spread:.3g} K (over {SPREAD_FACTOR:g} x the "
                           "tolerance: a ramp, not an isotherm); give a set column or a smaller --tolerance")
        rows = rows[np.argsort(frequency[rows], kind="stable")]
        sets.append(DMASet(name or str(rank), rows, float(np.mean(T)), spread))
    return tuple(sets)


RMS_BOUND, MAX_BOUND = 0.03, 0.15
"""The fit's relative error warned of: rms above 3 % (three times a DMA's usual 1 % scatter) or the largest
above 15 % (five times that)."""

WLF_RANGE = {"C1": (1.0, 60.0), "C2": (10.0, 400.0)}
"""WLF constants within which a law is physical. WLF's 'universal' constants at Tg are C1 = 17.44 and
C2 = 51.6 K (Williams, Landel and Ferry, J. Am. Chem. Soc. 77, 3701, 1955), the law holding from Tg to
about Tg + 100 K (IUPAC Gold Book, 'WLF equation'); referred to another T_ref, C2 = C2g + T_ref - Tg and
C1 = C1g C2g / C2. Constants 3 times smaller or larger than the universal ones at Tg, referred to any
T_ref from Tg - 5 K to Tg + 350 K, stay within these ranges; constants beyond them describe no polymer:
a degenerate fit (C1 and C2 growing together make the law a straight line, Arrhenius-like) or a law
fitted to too few or noisy factors."""

RIPPLE = 1e-3
"""A fitted E'' that goes up and down between two neighbouring data frequencies by more than this
(decades: 0.23 %) while the data there are monotone is warned of as a ripple of the Maxwell terms."""

RIPPLE_WINDOW = 2
"""Points on each side of a gap whose log10 E'' must be monotone (with the gap's two) for the data to be
smooth there."""


def fit_dma(data: DMAData, terms: int | None = None, per_decade: float | None = None, nu: float = 0.5,
            einf: float | str | None = None) -> tuple[PronyFit, list[str]]:
    """The Prony fit of ``data`` (:func:`fit_prony` on the reduced frequencies) and its warnings
    (:func:`fit_warnings`). DMAError when the relaxed modulus is below 1 kPa (PLAUSIBLE), naming the
    unit the data are likely in."""
    fit = fit_prony(data.reduced, data.storage, data.loss, terms, per_decade, nu, einf)
    low = PLAUSIBLE["storage"][0]
    if fit.Einf < low:
        name, unit = (data.columns or {}).get("storage", ("storage", "Pa"))
        factor = UNITS["storage"][unit]
        raise DMAError(f"{data.source}: the relaxed modulus Einf = {fit.Einf:.4g} Pa ({fit.einf_how}) is below "
                       f"{low:g} Pa, softer than any solid petroll can roll on, with storage ({name!r}) in "
                       f"{unit}" + unit_hint(likely_units(data.storage / factor, fit.Einf / factor)))
    return fit, fit_warnings(data, fit)


def fit_warnings(data: DMAData, fit: PronyFit) -> list[str]:
    """One line for each thing the user should look at: the fit's error beyond RMS_BOUND or MAX_BOUND, a
    WLF law (given, or fitted to the factors found) beyond WLF_RANGE, ripples of E'' (:func:`ripples`),
    shift factors with a standard error above tts.SIGMA_WARN."""
    lines = []
    if fit.rms_error > RMS_BOUND or fit.max_error > MAX_BOUND:
        lines.append(f"the fit's relative error (rms {100 * fit.rms_error:.3g} %, max {100 * fit.max_error:.3g} "
                     f"%) exceeds {100 * RMS_BOUND:g} % rms or {100 * MAX_BOUND:g} % max: check the units, the "
                     "shift (sets that do not superpose) and the data's scatter, or fix the density "
                     "(--per-decade)")
    laws = [("the shift law given", data.shift)] if isinstance(data.shift, materials.WLF) else []
    if data.found is not None and data.found.wlf.law is not None:
        laws.append(("WLF fitted to the factors found", data.found.wlf.law))
    for what, law in laws:
        bad = [f"{name} = {getattr(law, name):.4g}" for name, (lo, hi) in WLF_RANGE.items()
               if not lo <= getattr(law, name) <= hi]
        if bad:
            ranges = ", ".join(f"{name} {lo:g} ... {hi:g}" for name, (lo, hi) in WLF_RANGE.items())
            lines.append(f"{what} is degenerate: {', '.join(bad)}, beyond the physical ranges ({ranges} K; "
                         "docs/materials.md): the factors do not determine it (a straight line in T, or too "
                         "few or noisy factors)")
    found = ripples(data, fit)
    if found:
        bump, lo, hi = found[0]
        denser = (f"--per-decade {2 * fit.per_decade:g}" if math.isfinite(fit.per_decade) else
                  f"--terms {2 * fit.candidates}")
        lines.append(f"the fitted E'' ripples between neighbouring data frequencies where the data are "
                     f"monotone: {len(found)} gap(s), the largest {100 * (10**bump - 1):.2g} % at {lo:.4g} ... "
                     f"{hi:.4g} Hz (too few terms: {denser}, or more data there)")
    if data.found is not None:
        lines += data.found.warnings()
    return lines


def ripples(data: DMAData, fit: PronyFit) -> list[tuple[float, float, float]]:
    """(bump in decades, lower and upper frequency in Hz) of every gap between neighbouring reduced
    frequencies (rows within 1e-6 decade merged, their log10 E'' averaged) where the fit's log10 E''
    rises above or falls below both ends by more than RIPPLE, though the data's log10 E'' is monotone over
    the gap and RIPPLE_WINDOW points on each side; largest first."""
    x, y = np.log10(data.reduced), np.log10(data.loss)
    order = np.argsort(x, kind="stable")
    x, y = x[order], y[order]
    group = np.cumsum(np.concatenate([[True], np.diff(x) > 1e-6])) - 1
    count = np.bincount(group)
    x, y = np.bincount(group, x) / count, np.bincount(group, y) / count
    inside = np.linspace(0.0, 1.0, 17)
    found = []
    for i in range(len(x) - 1):
        step = np.diff(y[max(i - RIPPLE_WINDOW, 0):i + 2 + RIPPLE_WINDOW])
        if not (np.all(step > 0) or np.all(step < 0)):
            continue
        z = np.log10(fit.dynamic(10 ** (x[i] + inside * (x[i + 1] - x[i])))[1])
        bump = max(z.max() - max(z[0], z[-1]), min(z[0], z[-1]) - z.min())
        if bump > RIPPLE:
            found.append((float(bump), float(10 ** x[i]), float(10 ** x[i + 1])))
    return sorted(found, reverse=True)


def parse_shift(text: str):
    """A shift law from ``wlf:C1,C2,T_ref``, ``arrhenius:Ea,T_ref`` or a TOML file's [material] shift, or
    :class:`AutoShift` from ``auto:T_ref``."""
    if text.strip().lower().startswith("auto:"):
        try:
            T_ref = float(text.partition(":")[2])
        except ValueError:
            T_ref = math.nan
        if not 0 < T_ref < math.inf:
            raise DMAError(f"--shift {text!r}: auto:T_ref needs T_ref a finite number > 0 (K); must be "
                           f"{SHIFT_TEXT}")
        return AutoShift(T_ref)
    if text.endswith(".toml"):
        try:
            table = load_scene_table(text)["material"]["shift"]
        except (SceneError, KeyError, TypeError) as exc:
            why = exc.allowed if isinstance(exc, SceneError) else f"{type(exc).__name__}: {exc}"
            raise DMAError(f"--shift {text}: cannot read [material] shift from it ({why}); allowed: "
                           f"{SHIFT_TEXT}") from None
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


def material_toml(fit: PronyFit, shift=None, source: str | None = None, T_ref: float | None = None,
                  warnings=(), found: tts.ShiftFit | None = None) -> str:
    """The [material] block of ``fit`` as TOML, with comment lines saying where it comes from; with a
    shift law, at ``T_ref`` (K, default the law's); each of ``warnings`` as a comment line "# warning:
    ..."; with shift factors ``found`` from the data, their standard errors as comment lines."""
    lo, hi = fit.frequency_range
    where = f" from {source}" if source else ""
    if shift is not None and T_ref is None:
        T_ref = shift.T_ref
    at = f" at T_ref = {T_ref:g} K" if shift is not None else ""
    head = (f"# Generalized Maxwell series fitted by petroll material fit{where}: {len(fit.moduli)} terms\n"
            f"# (of {fit.candidates} candidate times), to E', E'' over {lo:.4g} ... {hi:.4g} Hz{at}; "
            f"relative error rms {100 * fit.rms_error:.3g} %, max {100 * fit.max_error:.3g} %.\n")
    if found is not None:
        head += ("# The shift factors' standard errors (decades of log10 a_T; each pair's overlap, chained to "
                 "T_ref), per set:\n"
                 f"#   T = {[round(float(t), 4) for t in found.temperatures]}\n"
                 f"#   log10_aT_error = {[float(f'{s:.3g}') for s in found.sigma]}\n")
    head += "".join(f"# warning: {line}\n" for line in warnings)
    return head + dumps({"material": fit.table(shift, T_ref)})


def describe_columns(data: DMAData) -> str:
    """How the table's columns were read, where that is not petroll's own format (other names, units or
    columns ignored); "" otherwise."""
    used = data.columns or {}
    own = all(name == column and unit == COLUMNS[column] for column, (name, unit) in used.items())
    if own and not data.ignored:
        return ""
    read = ", ".join(f"{name!r} as {column}" + ("" if column == "set" else f" ({unit})")
                     for column, (name, unit) in used.items())
    ignored = f"; ignored: {', '.join(repr(n) for n in data.ignored)}" if data.ignored else ""
    return f"columns read: {read} (converted to Hz, Pa, K){ignored}."


def describe_sets(data: DMAData) -> str:
    """The sets of ``data`` as a table of text lines: label, rows, mean temperature, spread, frequencies;
    with factors found from the data, each set's log10 a_T and its standard error (+-, decades, chained
    to T_ref), and the shift to the next set, its standard error, the overlap it leaves and the misfit
    there (tts.pair_shift)."""
    how = ("the set column" if data.tolerance is None else
           f"temperatures within {data.tolerance:g} K of their neighbours")
    found = data.found
    head = f"  {'set':>8} {'rows':>5} {'T (K)':>9} {'spread (K)':>10}   {'frequency (Hz)':<17}"
    if found is not None:
        head += f" {'log10 a_T':>10} {'+-':>6} {'to next':>8} {'+-':>6} {'overlap':>8} {'misfit':>7}"
    lines = [f"{len(data.sets)} sets ({how}):", head.rstrip()]
    for k, s in enumerate(data.sets):
        f = data.frequency[s.rows]
        line = (f"  {s.label:>8} {len(s.rows):5d} {s.temperature:9.2f} {s.spread:10.3f}   "
                f"{f'{f.min():.4g} ... {f.max():.4g}':<17}")
        if found is not None:
            line += f" {found.log10_aT[k]:10.3f} {found.sigma[k]:6.3f}"
            if k < len(found.shifts):
                line += (f" {found.shifts[k]:8.3f} {found.shift_sigma[k]:6.3f} {found.overlaps[k]:8.2f} "
                         f"{found.misfits[k]:7.2f}")
        lines.append(line.rstrip())
    return "\n".join(lines)


def report(data: DMAData, fit: PronyFit) -> str:
    """What ``petroll material fit`` says (lines starting ``petroll:``): the sets, the shift factors found
    and the laws fitted to them, and the fit's size and error."""
    lines = []
    read = describe_columns(data)
    if read:
        lines.append(f"petroll: {data.source}: {read}")
    if data.temperature is not None:
        lines.append("petroll: " + describe_sets(data))
    if data.found is not None:
        found = data.found
        laws = "; ".join(
            f"{name}: {law.note}" if law.law is None else
            f"{name}: --shift {law.text()} (residual rms {law.rms:.3g}, max {law.max:.3g} decade)"
            for name, law in (("WLF", found.wlf), ("Arrhenius", found.arrhenius)))
        lines.append(f"petroll: shift factors found from the data (each set overlapped with the next), "
                     f"log10 a_T = 0 at T_ref = {found.T_ref:g} K, written as a table law (interpolated "
                     f"between the sets' temperatures). Fitted to them: {laws}.")
    lo, hi = fit.frequency_range
    shifted = ("" if data.temperature is None else
               f", {len(data.sets)} sets shifted to T_ref = {data.T_ref:g} K")
    how = (f"{fit.per_decade:g} per decade, the coarsest within {100 * (TOLERANCE - 1):g} % of the densest's "
           f"error {100 * fit.best_rms:.3g} %" if math.isfinite(fit.best_rms) else "as asked")
    lines.append(f"petroll: {data.source}: {len(data.frequency)} points{shifted} over {lo:.4g} ... {hi:.4g} "
                 f"Hz: {len(fit.moduli)} Maxwell terms (of {fit.candidates} candidate times: {how}), Einf = "
                 f"{fit.Einf:.6g} Pa ({fit.einf_how}); relative error rms {100 * fit.rms_error:.3g} %, max "
                 f"{100 * fit.max_error:.3g} % (E' {100 * fit.max_storage_error:.3g} %, E'' "
                 f"{100 * fit.max_loss_error:.3g} %).")
    return "\n".join(lines)
