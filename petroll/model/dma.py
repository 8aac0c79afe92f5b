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
``temperature`` and ``set``), then one row per measurement; lines starting with ``#`` and blank lines are
skipped.
"""

from __future__ import annotations

import csv
import math
import pathlib
from dataclasses import dataclass

import numpy as np

from petroll.errors import DMAError, SceneError, shown
from petroll.model.limits import MAGNITUDES, scale_message
from petroll.model import materials, tts
from petroll.model.prony_fit import TOLERANCE, PronyFit, candidate_times, fit_prony, storage_loss  # noqa: F401
from petroll.model.scene import dumps
from petroll.model.toml_file import load_scene_table

COLUMNS = {"frequency": "Hz", "storage": "Pa", "loss": "Pa", "temperature": "K", "set": "a label"}
"""The CSV's columns and their units; temperature and set are optional."""

ALLOWED = ("a CSV with the header frequency,storage,loss and optionally temperature and set (Hz, Pa, Pa, K, "
           "a label naming the measurement set), then rows of finite numbers > 0 (the set: any text); lines "
           "starting with # are comments")

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

    @property
    def T_ref(self) -> float | None:
        """The reference temperature of the reduced frequencies (K), None without a shift law."""
        if self.found is not None:
            return self.found.T_ref
        return None if self.shift is None else self.shift.T_ref


def read_dma(path: str | pathlib.Path, shift=None, tolerance: float = DEFAULT_TOLERANCE) -> DMAData:
    """Read a DMA table (module docstring) and group its rows into sets (:func:`group_sets`); with a
    temperature column, ``shift`` (required: a law of materials.make_shift, or :class:`AutoShift` to find
    the factors from the data) gives each row's reduced frequency. DMAError naming the file, the line and
    what is allowed for anything else."""
    path = pathlib.Path(path)
    if not 0 < tolerance < math.inf:
        raise DMAError(f"--tolerance {tolerance!r}: must be a finite number > 0 (K)")
    lines, column = _read_columns(path)
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
                   shift, reduced, tolerance if by_temperature else None, found)


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


def _read_columns(path: pathlib.Path) -> tuple[list[int], dict]:
    """(the data rows' line numbers, {name: values}): numbers, and the set labels as text."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
        raise DMAError(f"{path}: cannot read it ({why}); must be {ALLOWED}") from None
    text = text.removeprefix("\ufeff")  # a byte-order mark (spreadsheets write one): not the header's
    try:
        rows = [(number, fields) for number, fields in
                enumerate(csv.reader(text.splitlines()), start=1)
                if fields and "".join(fields).strip() and not fields[0].lstrip().startswith("#")]
    except csv.Error as exc:  # a field longer than csv's limit (131072 characters)
        raise DMAError(f"{path}: not a CSV table ({exc}); must be {ALLOWED}") from None
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
    if len(rows) < 3:
        raise DMAError(f"{path}: {len(rows) - 1} data row(s); a fit needs at least 2; must be {ALLOWED}")
    values = {name: [] for name in names}
    for number, fields in rows[1:]:
        if len(fields) != len(names):
            raise DMAError(f"{path}, line {number}: {len(fields)} values for the {len(names)} columns "
                           f"{','.join(names)}; must be {ALLOWED}")
        for name, field in zip(names, fields):
            values[name].append(_value(path, number, name, field))
    column = {name: (v if name == "set" else np.array(v)) for name, v in values.items()}
    return [number for number, _ in rows[1:]], column


def _value(path, line: int, name: str, field: str):
    if name == "set":
        if not field.strip():
            raise DMAError(f"{path}, line {line}: set is empty: must name the row's measurement set; the "
                           f"file must be {ALLOWED}")
        return field.strip()
    try:
        value = float(field)
    except ValueError:
        value = math.nan
    if not 0 < value < math.inf:
        raise DMAError(f"{path}, line {line}: {name} = {shown(field.strip())}: must be a finite number > 0 "
                       f"({COLUMNS[name]}); the file must be {ALLOWED}")
    if name != "temperature" and not MAGNITUDES[0] <= value <= MAGNITUDES[1]:
        raise DMAError(f"{path}, line {line}: {name} = {shown(field.strip())}: "
                       f"{scale_message(value, COLUMNS[name])}")
    return value


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


def material_toml(fit: PronyFit, shift=None, source: str | None = None, T_ref: float | None = None) -> str:
    """The [material] block of ``fit`` as TOML, with comment lines saying where it comes from; with a
    shift law, at ``T_ref`` (K, default the law's)."""
    lo, hi = fit.frequency_range
    where = f" from {source}" if source else ""
    if shift is not None and T_ref is None:
        T_ref = shift.T_ref
    at = f" at T_ref = {T_ref:g} K" if shift is not None else ""
    head = (f"# Generalized Maxwell series fitted by petroll material fit{where}: {len(fit.moduli)} terms\n"
            f"# (of {fit.candidates} candidate times), to E', E'' over {lo:.4g} ... {hi:.4g} Hz{at}; "
            f"relative error rms {100 * fit.rms_error:.3g} %, max {100 * fit.max_error:.3g} %.\n")
    return head + dumps({"material": fit.table(shift, T_ref)})


def describe_sets(data: DMAData) -> str:
    """The sets of ``data`` as a table of text lines: label, rows, mean temperature, spread, frequencies;
    with factors found from the data, each set's log10 a_T, and the shift to the next set, the overlap it
    leaves and the misfit there (tts.pair_shift)."""
    how = ("the set column" if data.tolerance is None else
           f"temperatures within {data.tolerance:g} K of their neighbours")
    found = data.found
    head = f"  {'set':>8} {'rows':>5} {'T (K)':>9} {'spread (K)':>10}   {'frequency (Hz)':<17}"
    if found is not None:
        head += f" {'log10 a_T':>10} {'to next':>8} {'overlap':>8} {'misfit':>7}"
    lines = [f"{len(data.sets)} sets ({how}):", head.rstrip()]
    for k, s in enumerate(data.sets):
        f = data.frequency[s.rows]
        line = (f"  {s.label:>8} {len(s.rows):5d} {s.temperature:9.2f} {s.spread:10.3f}   "
                f"{f'{f.min():.4g} ... {f.max():.4g}':<17}")
        if found is not None:
            line += f" {found.log10_aT[k]:10.3f}"
            if k < len(found.shifts):
                line += f" {found.shifts[k]:8.3f} {found.overlaps[k]:8.2f} {found.misfits[k]:7.2f}"
        lines.append(line.rstrip())
    return "\n".join(lines)


def report(data: DMAData, fit: PronyFit) -> str:
    """What ``petroll material fit`` says (lines starting ``petroll:``): the sets, the shift factors found
    and the laws fitted to them, and the fit's size and error."""
    lines = []
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
