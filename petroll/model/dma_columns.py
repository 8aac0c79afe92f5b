"""Reading a DMA table's columns (:func:`petroll.model.dma.read_dma`): the names petroll, pyvisco and
instruments write, units (a units row, a header's ``(unit)``, ``--units``), conversion to Hz, Pa and K,
and the plausibility of the values for their unit. DMAError (one line) for anything else."""

from __future__ import annotations

import csv
import math
import pathlib

import numpy as np

from petroll.errors import DMAError
from petroll.errors import shown as shown_value
from petroll.model.limits import MAGNITUDES, scale_message

COLUMNS = {"frequency": "Hz", "storage": "Pa", "loss": "Pa", "temperature": "K", "set": "a label"}
"""The CSV's columns and their units (without a unit stated); temperature and set are optional."""

ALLOWED = ("a CSV with the header frequency,storage,loss and optionally temperature and set (Hz, Pa, Pa, K, "
           "a label naming the measurement set; other units in a units row under the header), then rows of "
           "finite numbers > 0 (the set: any text); lines starting with # are comments")

NAMES = {
    "frequency": ("frequency", "f", "freq", "freq."),
    "angular frequency": ("angular frequency", "omega", "\u03c9"),
    "storage": ("storage", "storage modulus", "e_stor", "e'", "e\u2032"),
    "loss": ("loss", "loss modulus", "e_loss", "e''", 'e"', "e\u2033"),
    "temperature": ("temperature", "T", "temp", "temp."),
    "set": ("set", "sweep"),
}
"""Header names recognised (case and surrounding blanks aside) for each column: petroll's own; pyvisco's
user format f, E_stor, E_loss, T, Set (NREL/pyvisco, pyvisco/load.py user_raw and
examples/freq/user/raw/freq_user_raw.csv; omega for angular frequency); Netzsch Eplexor's f, E', E'', T
(as pyvisco's Eplexor_raw reads its export); TA Instruments TRIOS and Anton Paar RheoCompass's Storage
modulus, Loss modulus, Frequency, Angular frequency, Temperature (as imewei/rheojax's readers,
rheojax/io/readers/trios/common.py, map them). An angular frequency is in rad/s unless its unit says
otherwise. Shear moduli (G', G_stor, ...) are refused: petroll fits uniaxial E' and E''."""

SHEAR = ("g_stor", "g_loss", "g'", "g''", 'g"', "g\u2032", "g\u2033")
"""Names of shear moduli (pyvisco's G_stor, G_loss; instruments' G', G'')."""

EXTRA = ("tan delta", "tan_del", "tan d", "tan(delta)", "tan \u03b4", "tand", "loss factor", "|e*|", "e*",
         "e_comp", "complex modulus", "phase angle", "delta", "\u03b4", "strain", "stress", "force",
         "displacement", "time", "t", "t_set", "f_set", "point no.", "point", "amplitude", "static force",
         "dynamic force", "log_at")
"""Other quantities instruments export beside E' and E'', ignored (and listed in the report). A name of
one letter is compared as written (pyvisco's T is a temperature, its t a time), longer ones whatever
their case."""

UNITS = {"frequency": {"Hz": 1.0, "rad/s": 1.0 / (2.0 * math.pi)},
         "storage": {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9},
         "temperature": {"K": 0.0, "C": 273.15, "\u00b0C": 273.15, "degC": 273.15}}
"""Units read (case-sensitive: mPa is not MPa), and each one's factor to Hz or Pa; a temperature's offset
to K. loss takes storage's units."""

PLAUSIBLE = {"storage": (1e3, 1e12), "temperature": 100.0}
"""A solid's relaxed modulus is at least 1 kPa (a soft gel) and its storage modulus at most 1 TPa
(diamond's Young's modulus is 1.1 TPa), in Pa; DMA runs above 100 K (liquid nitrogen cools it to about
123 K): values beyond are taken for a wrong unit and refused."""


def parse_mapping(option: str, text: str, values: str) -> dict[str, str]:
    """``--columns frequency=f,storage=E_stor,...`` or ``--units storage=MPa,...`` as a dict; DMAError
    naming the option for anything else (``values``: what the right-hand sides are)."""
    mapping = {}
    for part in (p for p in text.split(",") if p.strip()):
        key, sign, value = (s.strip() for s in part.partition("="))
        if not sign or key not in COLUMNS or not value or key in mapping:
            why = (f"{key!r} is not one of {', '.join(COLUMNS)}" if sign and key not in COLUMNS else
                   f"{key} given twice" if key in mapping else f"{part.strip()!r} is not COLUMN=VALUE")
            raise DMAError(f"{option} {text!r}: {why}; must be COLUMN={values},... with COLUMN one of "
                           f"{', '.join(COLUMNS)}")
        mapping[key] = value
    return mapping


def _name_and_unit(header: str) -> tuple[str, str | None]:
    """A header field as (name, unit in it or None): ``E' (MPa)`` or ``Frequency [Hz]`` -> (E', MPa); a
    name recognised whole (``tan(delta)``) is kept whole."""
    text = header.strip()
    if _recognised(text) is not None:
        return text, None
    for open_, close in (("(", ")"), ("[", "]")):
        if text.endswith(close) and open_ in text:
            name, _, unit = text[:-1].rpartition(open_)
            if name.strip() and unit.strip():
                return name.strip(), unit.strip()
    return text, None


def _same(a: str, b: str) -> bool:
    """Header names compared: exactly when either has one letter, else whatever their case."""
    return a == b if min(len(a), len(b)) == 1 else a.lower() == b.lower()


def _recognised(name: str) -> str | None:
    """The column a header name is (NAMES), "shear", "extra" (EXTRA), or None."""
    for column, names in NAMES.items():
        if any(_same(name, n) for n in names):
            return column
    if any(_same(name, n) for n in SHEAR):
        return "shear"
    return "extra" if any(_same(name, n) for n in EXTRA) else None


def _unit(path, line: int, column: str, unit: str, where: str) -> str:
    """``unit`` checked for ``column`` (the name UNITS gives it), or DMAError."""
    kind = "storage" if column == "loss" else "frequency" if column == "angular frequency" else column
    known = UNITS.get(kind)
    if known is None:  # the set: any text
        return unit
    found = next((u for u in known if u == unit or (kind != "storage" and u.lower() == unit.lower())), None)
    if found is None:
        raise DMAError(f"{path}, line {line}: {column} unit {unit!r} ({where}): must be one of "
                       f"{', '.join(known)}; the file must be {ALLOWED}")
    return found


def read_columns(path: pathlib.Path, mapping: dict[str, str], units: dict[str, str]):
    """(the data rows' line numbers, {column: values in Hz, Pa, K; the set labels as text},
    {column: (header name, unit)}, the ignored header names)."""
    try:
        text = path.read_text(encoding="utf-8-sig")  # a byte-order mark (Excel's UTF-8 CSV) dropped
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
        raise DMAError(f"{path}: cannot read it ({why}); must be {ALLOWED}") from None
    lines_ = text.splitlines()
    first = next((line for line in lines_ if line.strip() and not line.lstrip().startswith("#")), "")
    delimiter = "\t" if "\t" in first else ";" if ";" in first and "," not in first else ","
    try:
        rows = [(number, fields) for number, fields in
                enumerate(csv.reader(lines_, delimiter=delimiter), start=1)
                if fields and "".join(fields).strip() and not fields[0].lstrip().startswith("#")]
    except csv.Error as exc:  # a field longer than csv's limit (131072 characters)
        raise DMAError(f"{path}: not a CSV table ({exc}); must be {ALLOWED}") from None
    if not rows:
        raise DMAError(f"{path}: no header line; must be {ALLOWED}")
    header_line, header = rows[0]
    names, in_header = zip(*(_name_and_unit(h) for h in header))
    where = f"{path}, line {header_line}: header {delimiter.join(header)!r}"
    chosen = _choose_columns(where, names, mapping)
    rows = rows[1:]
    stated = {}
    if rows and not any(_is_number(field) for field in rows[0][1]):  # a units row
        unit_line, unit_fields = rows.pop(0)
        if len(unit_fields) > len(names):
            raise DMAError(f"{path}, line {unit_line}: a units row of {len(unit_fields)} fields for the "
                           f"{len(names)} columns; must be {ALLOWED}")
        stated = {k: (field.strip().strip("[]").strip(), unit_line) for k, field in enumerate(unit_fields)}
    if len(rows) < 2:
        raise DMAError(f"{path}: {len(rows)} data row(s); a fit needs at least 2; must be {ALLOWED}")
    absent = [column for column in units if column not in chosen]
    if absent:
        raise DMAError(f"{path}: --units {absent[0]}={units[absent[0]]}: the table has no {absent[0]} column "
                       f"(its columns: {', '.join(chosen)})")
    used = {}
    for column, (k, kind) in chosen.items():
        given = [(u, line, what) for u, line, what in (
            (units.get(column), header_line, f"--units {column}="),
            (stated.get(k, ("", 0))[0], stated.get(k, ("", 0))[1], "the units row"),
            (in_header[k], header_line, "in the header")) if u and u not in ("-", "")]
        if column != "set" and len({_unit(path, line, kind, u, what) for u, line, what in given}) > 1:
            raise DMAError(f"{path}: column {names[k]!r}: units {', '.join(repr(u) for u, _, _ in given)} "
                           f"disagree ({', '.join(w for _, _, w in given)}); give one")
        unit = (_unit(path, given[0][1], kind, *given[0][::2]) if given and column != "set" else
                "rad/s" if kind == "angular frequency" else COLUMNS[column])
        used[column] = (names[k], unit)
    values = {column: [] for column in chosen}
    for number, fields in rows:
        if len(fields) != len(names):
            raise DMAError(f"{path}, line {number}: {len(fields)} values for the {len(names)} columns "
                           f"{','.join(names)}; must be {ALLOWED}")
        for column, (k, _) in chosen.items():
            values[column].append(_value(path, number, column, fields[k], used[column][1]))
    column_values = {name: (v if name == "set" else np.array(v)) for name, v in values.items()}
    lines = [number for number, _ in rows]
    _plausible(path, lines, column_values, used)
    ignored = tuple(names[k] for k in range(len(names)) if k not in {k for k, _ in chosen.values()})
    return lines, column_values, used, ignored


def _is_number(field: str) -> bool:
    try:
        float(field)
    except ValueError:
        return False
    return True


def _choose_columns(where: str, names, mapping: dict[str, str]) -> dict[str, tuple[int, str]]:
    """{column: (its index in the header, what it was recognised as)}: ``mapping``'s header names, then the
    names recognised (NAMES); DMAError for a missing, doubled, unknown or shear column."""
    chosen = {}
    for column, name in mapping.items():
        matches = [k for k, n in enumerate(names) if _same(n, name) or n.lower() == name.lower()]
        if not matches:
            raise DMAError(f"{where}: --columns {column}={name}: no such column; the columns are "
                           f"{', '.join(names)}")
        chosen[column] = (matches[0], column)
    taken = {k for k, _ in chosen.values()}
    for k, name in enumerate(names):
        kind = _recognised(name)
        column = "frequency" if kind == "angular frequency" else kind
        if k in taken or kind == "extra" or (mapping and column not in COLUMNS):
            continue
        if kind == "shear":
            raise DMAError(f"{where}: column {name!r} is a shear modulus; petroll fits uniaxial E', E'' "
                           "(E = 2 (1 + nu) G for an isotropic solid: convert the column, or map it with "
                           "--columns if it holds E); must be " + ALLOWED)
        if kind is None:
            raise DMAError(f"{where}: unknown column {name!r}; must be {ALLOWED}, or the names pyvisco or an "
                           "instrument exports, or give --columns frequency=NAME,storage=NAME,... (other "
                           "columns are then ignored)")
        if column in mapping:
            continue
        if column in chosen:
            raise DMAError(f"{where}: columns {names[chosen[column][0]]!r} and {name!r} both give {column}; "
                           f"choose one with --columns {column}=NAME")
        chosen[column] = (k, kind)
    missing = [c for c in ("frequency", "storage", "loss") if c not in chosen]
    if missing:
        raise DMAError(f"{where}: missing column {missing[0]!r}; must be {ALLOWED}")
    return chosen


def _value(path, line: int, name: str, field: str, unit: str):
    """One field in Hz, Pa or K (its ``unit`` converted), or the set's label."""
    if name == "set":
        if not field.strip():
            raise DMAError(f"{path}, line {line}: set is empty: must name the row's measurement set; the "
                           f"file must be {ALLOWED}")
        return field.strip()
    try:
        value = float(field)
    except ValueError:
        value = math.nan
    if name == "temperature":
        value += UNITS["temperature"][unit]
    else:
        value *= UNITS["storage" if name == "loss" else name][unit]
    if not 0 < value < math.inf:
        shown = f" {unit}" if unit != COLUMNS[name] else ""
        hint = ("; if the column is in degrees Celsius, say so in a units row under the header (C) or with "
                "--units temperature=C" if name == "temperature" and unit == "K" and math.isfinite(value)
                else f"; the file must be {ALLOWED}")
        raise DMAError(f"{path}, line {line}: {name} = {shown_value(field.strip())}{shown}: must be a finite "
                       f"number > 0 ({COLUMNS[name]}){hint}")
    if name != "temperature" and not MAGNITUDES[0] <= value <= MAGNITUDES[1]:
        raise DMAError(f"{path}, line {line}: {name} = {shown_value(field.strip())}: "
                       f"{scale_message(value, COLUMNS[name])}")
    return value


def likely_units(raw: np.ndarray, einf_raw: float | None = None) -> list[str]:
    """The units in which the numbers ``raw`` (as written) would be plausible storage moduli (PLAUSIBLE):
    at most 1 TPa, and their relaxed modulus (``einf_raw``, or their least) at least 1 kPa; the likeliest
    first: the one that puts the relaxed modulus nearest 0.1 ... 100 MPa and the largest nearest 1 MPa
    ... 10 GPa (rubbers and polymers, from their rubbery to their glassy state), in decades."""
    low, high = PLAUSIBLE["storage"]
    least = raw.min() if einf_raw is None else einf_raw

    def off(value: float, lo: float, hi: float) -> float:
        return max(math.log10(lo / value), math.log10(value / hi), 0.0)

    fits = [(off(least * f, 1e5, 1e8) + off(raw.max() * f, 1e6, 1e10), u) for u, f in UNITS["storage"].items()
            if low <= least * f and raw.max() * f <= high]
    return [u for _, u in sorted(fits)]


def unit_hint(units: list[str]) -> str:
    if not units:
        return ""
    other = f" (or {' or '.join(units[1:])})" if len(units) > 1 else ""
    return (f"; likely in {units[0]}{other}: state the unit in a units row under the header or with "
            f"--units storage={units[0]},loss={units[0]}")


def _plausible(path, lines: list[int], column: dict, used: dict) -> None:
    """DMAError where the values are implausible for their unit (PLAUSIBLE), naming the likely unit: a
    storage modulus above 1 TPa, a temperature below 100 K.
    (A relaxed modulus below 1 kPa is refused after the fit: :func:`fit_dma`.)"""
    storage = column["storage"]
    name, unit = used["storage"]
    high = PLAUSIBLE["storage"][1]
    if storage.max() > high:
        k = int(np.argmax(storage))
        raise DMAError(f"{path}, line {lines[k]}: storage ({name!r}, {unit}) = {storage[k]:.4g} Pa: above "
                       f"{high:g} Pa, stiffer than any solid (diamond: 1.1e12 Pa)"
                       + unit_hint(likely_units(storage / UNITS["storage"][unit])))
    temperature = column.get("temperature")
    if temperature is not None and temperature.min() < PLAUSIBLE["temperature"]:
        k = int(np.argmin(temperature))
        name, unit = used["temperature"]
        raise DMAError(f"{path}, line {lines[k]}: temperature ({name!r}, {unit}) = {temperature[k]:g} K: below "
                       f"{PLAUSIBLE['temperature']:g} K, colder than DMA is run; if the column is in degrees "
                       "Celsius, say so in a units row under the header (C) or with --units temperature=C")
