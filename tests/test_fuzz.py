"""Randomised trials of damaged input and faults (issue 35): scenes, height maps, DMA tables, sweep
specifications, checkpoints, full and read-only disks, each damaged the way users damage them (cut short,
wrong types, huge, tiny, NaN and infinite numbers, odd encodings, missing keys, deep nesting).

Each test draws a few dozen inputs from one seed, runs the ``petroll`` command on them in this process
(``petroll.cli.main``) under a time limit, and counts what must never happen: a traceback (an exception
out of ``main``), a hang (the time limit), an error of more than one line, a warning printed before it
(any warning but petroll's own). Zero of each. The seed is ``PETROLL_FUZZ_SEED`` if set, else a new one per
session; every test prints it (``pytest -s``) and every failure names it with the inputs that failed:
``PETROLL_FUZZ_SEED=N pytest tests/test_fuzz.py`` draws them again. Serial tests (in-process, but their
time limit must not leave another rank waiting)."""

from __future__ import annotations

import collections
import contextlib
import errno
import math
import os
import pathlib
import random
import secrets
import shutil
import signal
import subprocess
import traceback
import warnings

import numpy as np
import pytest

from petroll.model.limits import PetrollWarning

ROOT = pathlib.Path(__file__).resolve().parents[1]
SEED = int(os.environ.get("PETROLL_FUZZ_SEED") or secrets.randbits(32))
VERBOSE = bool(os.environ.get("PETROLL_FUZZ_VERBOSE"))
"""Print every input and what became of it (pytest -s)."""
pytestmark = pytest.mark.serial


class Hang(BaseException):
    """Raised in the command by the time limit (a BaseException: no ``except Exception`` swallows it)."""


@contextlib.contextmanager
def time_limit(seconds: float):
    """Raise :class:`Hang` in the main thread after ``seconds`` (SIGALRM)."""
    def expire(signum, frame):
        raise Hang(f"still running after {seconds:g} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


class Trial:
    """A category's inputs run through ``petroll.cli.main``, their outcomes counted (:meth:`call`), and
    the verdict (:meth:`verdict`): no traceback, hang, multi-line error or foreign warning."""

    def __init__(self, name: str, capsys):
        self.name, self.capsys = name, capsys
        self.random = random.Random(f"{SEED}-{name}")
        self.counts = collections.Counter()
        self.faults: list[str] = []
        self.say(f"{name}: seed {SEED} (PETROLL_FUZZ_SEED={SEED} draws these inputs again)")

    def say(self, line: str) -> None:
        """Print past the command's captured output (seen with pytest -s)."""
        with self.capsys.disabled():
            print(line, flush=True)

    def call(self, argv: list, what: str, limit: float = 30.0) -> tuple[int | None, str]:
        """``petroll ARGV`` (``what`` describes the input): (exit status or None, its stderr)."""
        argv = [str(a) for a in argv]
        self.capsys.readouterr()
        code, failure = None, None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                with time_limit(limit):
                    from petroll.cli import main

                    code = main(argv)
            except SystemExit as exc:  # argparse
                code = exc.code
            except Hang as exc:
                failure = ("hang", str(exc))
            except BaseException as exc:  # noqa: BLE001 - a traceback is what is counted here
                lines = traceback.format_exception(exc)
                failure = ("traceback", " | ".join(line.strip() for line in lines[-3:]))
        err = self.capsys.readouterr().err
        said = [line for line in err.splitlines() if line.strip()]
        foreign = [f"{w.category.__name__}: {w.message} ({pathlib.Path(w.filename).name}:{w.lineno})"
                   for w in caught if not issubclass(w.category, PetrollWarning)]
        if failure is None and foreign:
            failure = ("warning", foreign[0])
        if failure is None and code not in (0, 2):
            failure = ("exit status", f"{code}: {said[-1] if said else ''}")
        if failure is None and code == 2:
            errors = [line for line in said if not line.startswith("petroll: warning: ")]
            if len(errors) != 1 or not errors[0].startswith("petroll: error: ") or said[-1] != errors[0]:
                failure = ("multi-line", " / ".join(said)[:400])
        if failure is None and code == 0 and any(line.startswith("petroll: error") for line in said):
            failure = ("error with status 0", said[0])
        self.counts["exit 0" if failure is None and code == 0 else
                    "refused" if failure is None else failure[0]] += 1
        if failure is not None:
            self.faults.append(f"{failure[0]}: {what}: petroll {' '.join(argv)[:200]}: {failure[1][:400]}")
        if VERBOSE:
            self.say(f"  {what[:70]}: exit {code}: {failure or (said[-1][:160] if said else '')}")
        return (None if failure is not None and failure[0] in ("hang", "traceback") else code), err

    def verdict(self, least: int = 1) -> None:
        """Print the counts; fail naming the seed and the inputs that went wrong."""
        total = sum(self.counts.values())
        self.say(f"{self.name}: seed {SEED}: {total} inputs: " + ", ".join(f"{k} {v}" for k, v in
                                                                          sorted(self.counts.items())))
        assert not self.faults, f"seed {SEED} (PETROLL_FUZZ_SEED={SEED}): {len(self.faults)} of {total}:\n" + \
            "\n".join(self.faults)
        assert total >= least


# -- damage ------------------------------------------------------------------------------------------------
ODD_NUMBERS = ["nan", "inf", "-inf", "+inf", "0", "-0.0", "-1", "1e308", "1.7976931348623157e308", "5e-324",
               "1e-320", "1e-300", "1e300", "9" * 40, "-" + "9" * 30, "1" * 5000, "2147483648",
               "9223372036854775808", "true", '"7"', "[]", "{}", "[1, 2]", "1979-05-27", '""', "0x10"]


def damaged_text(text: str, rng: random.Random) -> tuple[str | bytes, str]:
    """``text`` damaged one way drawn by ``rng``: (the new text or bytes, what was done)."""
    lines = text.splitlines(keepends=True)
    kind = rng.choice(["cut", "insert", "number", "drop", "twice", "nest", "encoding", "swap", "bytes"])
    if kind == "cut":
        at = rng.randrange(len(text) + 1)
        return text[:at], f"cut at character {at}"
    if kind == "insert":
        at = rng.randrange(len(text) + 1)
        junk = rng.choice(["=", "[", "]", "\"", "'", "\n[grid]\n", "\\", "\x00", "#", ",", "{", "\u00e9", "\t",
                           "\r", "[[a]]\n", "a.b.c = 1\n", "\ufeff"])
        return text[:at] + junk + text[at:], f"{junk!r} inserted at {at}"
    if kind in ("number", "nest"):
        spots = [(k, line) for k, line in enumerate(lines) if " = " in line and not line.lstrip().startswith("#")]
        if spots:
            k, line = rng.choice(spots)
            key, _, _ = line.partition(" = ")
            if kind == "number":
                value = rng.choice(ODD_NUMBERS)
            else:
                depth = rng.choice([3, 17, 100, 999, 3000])
                value = rng.choice(["[" * depth + "1" + "]" * depth,
                                    "{a = " * depth + "1" + "}" * depth])
            lines[k] = f"{key} = {value}\n"
            return "".join(lines), f"line {k + 1}: {key.strip()} = {value[:30]}"
        return text, "unchanged"
    if kind == "drop" and lines:
        k = rng.randrange(len(lines))
        return "".join(lines[:k] + lines[k + 1:]), f"line {k + 1} dropped ({lines[k].strip()[:40]!r})"
    if kind == "twice" and lines:
        k = rng.randrange(len(lines))
        return "".join(lines[:k + 1] + lines[k:]), f"line {k + 1} twice"
    if kind == "swap" and len(lines) > 1:
        a, b = rng.randrange(len(lines)), rng.randrange(len(lines))
        lines[a], lines[b] = lines[b], lines[a]
        return "".join(lines), f"lines {a + 1} and {b + 1} swapped"
    if kind == "encoding":
        how = rng.choice(["bom", "utf-16", "latin-1", "crlf", "cp1252-bom"])
        data = {"bom": lambda: "\ufeff" + text, "utf-16": lambda: text.encode("utf-16"),
                "latin-1": lambda: ("# d\u00e9j\u00e0\n" + text).encode("latin-1"),
                "crlf": lambda: text.replace("\n", "\r\n"),
                "cp1252-bom": lambda: b"\xef\xbb\xbf" + ("# \u20ac\n" + text).encode("cp1252")}[how]()
        return data, f"encoding {how}"
    data = bytearray(text.encode())
    for _ in range(rng.randint(1, 8)):
        if data:
            data[rng.randrange(len(data))] = rng.randrange(256)
    return bytes(data), "random bytes changed"


ODD_VALUES = [math.nan, math.inf, -math.inf, 0, 0.0, -1, -1e-6, 5e-324, 1e-320, 1e-300, 1e-31, 1e-30, 1e30,
              1e31, 1e300, 2**31, 2**63 - 1, 10**30, True, False, "", "x", "sphere", [], [0.0], [1e-3, 1e-3],
              [math.nan, 0.0], [[1.0, 2.0]], {}, {"kind": "ramp"}, {"kind": "tabulated", "t": [0, 1],
                                                                   "value": [0, 1e300]}]


def damaged_table(text: str, rng: random.Random) -> tuple[str, str]:
    """``text`` (a scene) parsed, one key set to an odd value, dropped, or a key added, written again."""
    import tomllib

    from petroll.model.scene import dumps

    raw = tomllib.loads(text)
    section = rng.choice(sorted(raw))
    table = raw[section]
    kind = rng.choice(["set", "set", "drop", "add", "scale"])
    key = rng.choice(sorted(table)) if table and kind != "add" else rng.choice(["bogus", "nx", "radius", "dt"])
    if kind == "drop":
        table.pop(key, None)
        return dumps(raw), f"[{section}] {key} dropped"
    value = rng.choice(ODD_VALUES)
    if kind == "scale" and isinstance(table.get(key), (int, float)) and not isinstance(table[key], bool):
        value = type(table[key])(table[key] * rng.choice([1e-12, 1e-3, 0.5, 2, 10, 1e3, 1e12]))
    table[key] = value
    return dumps(raw), f"[{section}] {key} = {str(value)[:40]}"


def write(path: pathlib.Path, data: str | bytes) -> pathlib.Path:
    if isinstance(data, str):
        path.write_text(data, encoding="utf-8", errors="surrogatepass")
    else:
        path.write_bytes(data)
    return path


def shrunk(text: str) -> str:
    """A shipped scene made cheap to run: at most 24 x 24 cells, rolled 4 of them or 4 steps, at most 20
    steps (a longer run is refused in one line, which counts as well)."""
    import tomllib

    from petroll.model.scene import dumps

    raw = tomllib.loads(text)
    grid = raw["grid"]
    grid["nx"] = min(grid["nx"], 24)
    if "ny" in grid:
        grid["ny"] = min(grid["ny"], 24)
    time = raw.get("time", {})
    if "distance" in time:
        time["distance"] = min(time["distance"], 4 * (grid["x"][1] - grid["x"][0]) / grid["nx"])
    if "end" in time and "dt" in time:
        time["end"] = min(time["end"], 4 * time["dt"])
    if time:
        time["max_steps"] = 20
    return dumps(raw)


SCENES = sorted(p.name for p in (ROOT / "runs").glob("*.toml"))


@pytest.mark.slow
def test_damaged_shipped_scenes(tmp_path, capsys, monkeypatch):
    """Each shipped scene (runs/), damaged: ``petroll check`` on every one, ``petroll run`` on those made
    cheap first (at most 24 x 24 cells, 5 steps)."""
    trial = Trial("scenes", capsys)
    for name in ROOT.joinpath("runs").glob("*.csv"):
        shutil.copy(name, tmp_path)
    monkeypatch.chdir(tmp_path)
    for k in range(40):
        name = trial.random.choice(SCENES)
        text = (ROOT / "runs" / name).read_text(encoding="utf-8")
        cheap = trial.random.random() < 0.4
        if cheap:
            text = shrunk(text)
        data, how = (damaged_table if trial.random.random() < 0.5 else damaged_text)(text, trial.random)
        scene = write(tmp_path / f"s{k}.toml", data)
        verb = ["run", scene, "--out", f"out{k}", "--quiet"] if cheap else ["check", scene]
        trial.call(verb, f"{name} {how}", limit=60)
    trial.verdict()


# -- height maps -------------------------------------------------------------------------------------------
CELL = 50e-6
MAP_SCENE = """[grid]
nx = 32
ny = 32
x = [-0.8e-3, 0.8e-3]
y = [-0.8e-3, 0.8e-3]
{periodic}
[material]
model = "elastic"
E = 10.0e6
nu = 0.5

[body]
shape = "heightmap"
file = "{file}"
{cell}
{extra}
[motion]
{motion}
"""


def sphere_map(n: int = 32) -> np.ndarray:
    """A sphere of radius 10 mm sampled on n x n cell centres of CELL (m): a valid height map."""
    c = (np.arange(n) - (n - 1) / 2) * CELL
    return (c[:, None] ** 2 + c[None, :] ** 2) / (2 * 0.01)


def damaged_map(rng: random.Random, where: pathlib.Path) -> tuple[pathlib.Path, str, str]:
    """A height map file damaged one way: (its path, the [body] cell line, what was done)."""
    heights = sphere_map()
    kind = rng.choice(["npy"] * 3 + ["txt", "xyz"])
    cell = f"cell = {CELL!r}"
    if kind == "npy":
        how = rng.choice(["nan", "+inf", "-inf", "all inf", "1-D", "3-D", "empty", "object", "complex", "bool",
                          "int8", "huge", "tiny relief", "flat", "cut", "bytes", "npz", "text", "fine",
                          "inf row", "one cell"])
        path = where / "map.npy"
        a = heights.copy()
        if how in ("nan", "+inf", "-inf"):
            a.flat[rng.randrange(a.size)] = {"nan": np.nan, "+inf": np.inf, "-inf": -np.inf}[how]
        elif how == "inf row":
            a[rng.randrange(32)] = np.inf
        arrays = {"all inf": lambda: np.full((32, 32), np.inf), "1-D": lambda: a[0], "3-D": lambda: a[None],
                  "empty": lambda: np.zeros((0, 3)), "complex": lambda: a + 1j, "bool": lambda: a > 1e-5,
                  "int8": lambda: (a * 1e6).astype(np.int8), "huge": lambda: a * 1e300,
                  "tiny relief": lambda: 1.0 + a * 1e-40, "flat": lambda: np.zeros((32, 32)),
                  "one cell": lambda: a[:1, :1]}
        if how == "object":
            np.save(path, np.array([{"a": 1}], dtype=object), allow_pickle=True)
        elif how in ("cut", "bytes"):
            np.save(path, a)
            data = bytearray(path.read_bytes())
            if how == "cut":
                data = data[: rng.randrange(len(data))]
            else:
                for _ in range(8):
                    data[rng.randrange(len(data))] = rng.randrange(256)
            path.write_bytes(bytes(data))
        elif how == "npz":
            np.savez(where / "map.npz", a)
            (where / "map.npz").rename(path)
        elif how == "text":
            path.write_text("1 2\n3 4\n")
        else:
            np.save(path, arrays.get(how, lambda: a)())
        return path, cell, f"npy {how}"
    if kind == "txt":
        path = where / "map.txt"
        how = rng.choice(["empty", "comments", "ragged", "words", "commas", "bom", "nan", "one row", "fine",
                          "semicolons", "crlf"])
        lines = [" ".join(f"{v:.6e}" for v in row) for row in heights]
        text = {"empty": "", "comments": "# heights\n# none\n", "ragged": "\n".join(lines[:5]) + "\n1 2\n",
                "words": "a b c\nd e f\n", "commas": "\n".join(line.replace(" ", ", ") for line in lines),
                "bom": "\ufeff" + "\n".join(lines), "nan": "\n".join(lines).replace(lines[3].split()[4], "nan", 1),
                "one row": lines[0], "fine": "\n".join(lines), "semicolons": "\n".join(lines).replace(" ", ";"),
                "crlf": "\r\n".join(lines)}[how]
        path.write_text(text, encoding="utf-8")
        return path, cell, f"txt {how}"
    path = where / "map.xyz"
    how = rng.choice(["empty", "two columns", "twice", "irregular", "nan x", "fine", "one point", "words"])
    c = (np.arange(32) - 15.5) * CELL
    points = [(x, y, heights[i, j]) for i, x in enumerate(c) for j, y in enumerate(c)]
    if how == "twice":
        points.append(points[5])
    elif how == "irregular":
        points[7] = (points[7][0] + CELL / 3, *points[7][1:])
    elif how == "nan x":
        points[9] = (math.nan, *points[9][1:])
    elif how == "one point":
        points = points[:1]
    text = {"empty": "", "two columns": "\n".join(f"{x} {y}" for x, y, _ in points),
            "words": "x y z\n"}.get(how, "\n".join(f"{x!r} {y!r} {z!r}" for x, y, z in points))
    path.write_text(text, encoding="utf-8")
    return path, "", f"xyz {how}"


@pytest.mark.slow
def test_damaged_height_maps(tmp_path, capsys):
    """A 32 x 32 map of a sphere, damaged (NaN, infinite, huge, tiny, empty, wrong shape or type, cut,
    random bytes; text matrices and xyz lists with empty, ragged, non-numeric, duplicated or irregular
    content), on a periodic grid or not, under penetration or load control: ``petroll check`` and
    ``petroll run`` (one step on 32 x 32 cells)."""
    trial = Trial("height maps", capsys)
    for k in range(30):
        where = tmp_path / f"m{k}"
        where.mkdir()
        path, cell, how = damaged_map(trial.random, where)
        periodic = trial.random.choice(["", "periodic = true", 'periodic = ["y"]'])
        motion = trial.random.choice(["penetration = 20e-6", "load = 0.1"])
        extra = trial.random.choice(["", "", 'unit = "um"', 'unit = "nm"', "position = [0.0, 0.0]"])
        scene = where / "s.toml"
        scene.write_text(MAP_SCENE.format(periodic=periodic, file=path.name, cell=cell, extra=extra,
                                          motion=motion), encoding="utf-8")
        what = f"{how}, {periodic or 'not periodic'}, {motion}, {extra or '-'}"
        trial.call(["check", scene], what)
        trial.call(["run", scene, "--out", where / "out", "--quiet"], what, limit=60)
    trial.verdict()


# -- DMA tables --------------------------------------------------------------------------------------------
def damaged_table_csv(text: str, rng: random.Random) -> tuple[str | bytes, str]:
    """A DMA table damaged one way: a value odd, a row or column dropped or repeated, the header changed,
    text damage (damaged_text)."""
    lines = text.splitlines()
    data = [k for k, line in enumerate(lines) if line and line[0].isdigit()]
    kind = rng.choice(["value", "value", "value", "row", "column", "header", "text", "rows"])
    if kind == "value" and data:
        k = rng.choice(data)
        fields = lines[k].split(",")
        c = rng.randrange(len(fields))
        fields[c] = rng.choice(["nan", "inf", "-1", "0", "1e-320", "5e-324", "1e-31", "1e300", "1e31", "", "x",
                                "1e30", "9" * 400, "1,2", "\"3\""])
        lines[k] = ",".join(fields)
        return "\n".join(lines) + "\n", f"line {k + 1} column {c + 1} = {fields[c][:20]}"
    if kind == "row" and data:
        k = rng.choice(data)
        return "\n".join(lines[:k] + lines[k + 1:]) + "\n", f"line {k + 1} dropped"
    if kind == "rows" and data:
        keep = data[: rng.choice([0, 1, 2, 3])]
        head = [line for line in lines if not (line and line[0].isdigit())]
        return "\n".join(head + [lines[k] for k in keep]) + "\n", f"{len(keep)} data rows"
    if kind == "column":
        c = rng.randrange(4)
        return "\n".join(",".join(f for i, f in enumerate(line.split(",")) if i != c) if not line.startswith("#")
                         else line for line in lines) + "\n", f"column {c + 1} dropped"
    if kind == "header":
        k = next(k for k, line in enumerate(lines) if line.startswith("frequency"))
        lines[k] = rng.choice(["Frequency,Storage,Loss,Temperature", "frequency;storage;loss;temperature",
                               "frequency,storage,loss,temperature,set", "f,E1,E2,T", "",
                               "frequency,storage,storage,temperature"])
        return "\n".join(lines) + "\n", f"header {lines[k]!r}"
    return damaged_text(text, rng)


@pytest.mark.slow
def test_damaged_dma_tables(tmp_path, capsys):
    """The shipped DMA tables (runs/*.csv), damaged, fitted with ``petroll material fit`` under options drawn
    from the valid and the odd (shift laws, --terms, --per-decade, --einf, --nu, --tolerance)."""
    trial = Trial("DMA tables", capsys)
    tables = {"rubber-dma.csv": "wlf:8.86,101.6,293.15", "polymer-dma.csv": "auto:293.15"}
    for k in range(30):
        name = trial.random.choice(sorted(tables))
        data, how = damaged_table_csv((ROOT / "runs" / name).read_text(encoding="utf-8"), trial.random)
        csv = write(tmp_path / f"t{k}.csv", data)
        options = ["--shift", trial.random.choice([tables[name]] * 27 + [
            "wlf:8.86,101.6,nan", "wlf:1e300,1,293", "arrhenius:1e300,293.15", "auto:1e-300", "auto:0",
            "wlf:8.86,-293.15,293.15", "bogus", str(tmp_path / "missing.toml"), "auto:1e300"])]
        for option, values in (("--terms", ["3", "0", "2001", "100000", "1" * 30]),
                               ("--per-decade", ["0.5", "1e-300", "1e300", "nan"]),
                               ("--einf", ["3e6", "1e-300", "1e300"]), ("--nu", ["0.5", "-1", "0.6", "nan"]),
                               ("--tolerance", ["0.5", "0", "1e300", "nan"])):
            if trial.random.random() < 0.1 and not (option == "--per-decade" and "--terms" in options):
                options += [option, trial.random.choice(values)]
        out = ["--out", tmp_path / f"fit{k}.toml"] if trial.random.random() < 0.5 else []
        trial.call(["material", "fit", csv, *options, *out], f"{name} {how}", limit=60)
    trial.verdict()


# -- sweep specifications ----------------------------------------------------------------------------------
SWEEP_SCENE = """[grid]
nx = 16
ny = 16
x = [-0.8e-3, 0.8e-3]
y = [-0.8e-3, 0.8e-3]
allow_coarse = true

[material]
model = "sls"
E0 = 10.0e6
Einf = 2.0e6
nu = 0.5
tau_relax = 0.01

[body]
shape = "sphere"
radius = 0.01

[motion]
penetration = 20.0e-6
"""


VALID_SPECS = ["motion.penetration=1e-5,2e-5", "motion.penetration=1e-5..3e-5:lin:3", "grid.nx=12,16",
               "material.tau_relax=0.001..0.1:log:3", "motion.load=0.05,0.1", "body.radius=0.005,0.01,0.02",
               "material.E0=5e6,2e7", "material.Einf=1e6,2e6", "material.nu=0.3,0.5"]


def sweep_spec(rng: random.Random) -> str:
    """A --vary text: a valid one (VALID_SPECS), or a key (valid, of another type, unknown) with values
    (lists, ranges, odd numbers)."""
    if rng.random() < 0.4:
        return rng.choice(VALID_SPECS)
    key = rng.choice(["motion.penetration", "motion.load", "material.tau_relax", "material.E0", "grid.nx",
                      "body.radius", "motion.velocity", "time.dt", "material.model", "grid.x", "bogus.key",
                      "motion", "", "grid.periodic", "material.nu", "time.steps_per_cell"])
    number = lambda: rng.choice(["1e-5", "2e-5", "3e-5", "0", "-1", "nan", "inf", "1e-320", "1e300", "8",
                                 "16", "100000", "1" * 400, "x", "", "1e-3", "0.4"])  # noqa: E731
    form = rng.choice(["list", "list", "lin", "log", "odd"])
    if form == "list":
        values = ",".join(number() for _ in range(rng.choice([1, 2, 2, 3])))
    elif form in ("lin", "log"):
        count = rng.choice(["2", "3", "1", "0", "1000000000", "99999999999999999999", "9" * 5000, "-2", "x"])
        values = f"{number()}..{number()}:{form}:{count}"
    else:
        values = rng.choice(["1..2", "1..2:lin", "1..2:cubic:3", ",,", "1,,2", "1;2", "[1,2]", "1..2:lin:3:4"])
    return f"{key}={values}" if rng.random() < 0.95 else values


@pytest.mark.slow
def test_odd_sweep_specifications(tmp_path, capsys):
    """``petroll sweep`` of a 16 x 16 static scene over --vary texts drawn from the valid and the odd
    (unknown keys, keys of other types, empty, NaN, infinite, huge and tiny values, counts up to 10^5000,
    malformed ranges); once or twice --vary."""
    trial = Trial("sweep specifications", capsys)
    scene = write(tmp_path / "s.toml", SWEEP_SCENE)
    for k in range(24):
        specs = [sweep_spec(trial.random) for _ in range(2 if trial.random.random() < 0.1 else 1)]
        argv = ["sweep", scene, "--out", tmp_path / f"sweep{k}", "--quiet"]
        for spec in specs:
            argv += ["--vary", spec]
        trial.call(argv, " ".join(spec[:60] for spec in specs), limit=60)
    trial.verdict()


# -- checkpoints -------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def checkpointed(tmp_path_factory):
    """A run of test_checkpoint's rolling sphere stopped after step 5 by a stop request: (its scene file,
    its output directory with results.h5 and checkpoints/step-00000004.h5, -00000005.h5)."""
    from mpi4py import MPI

    from petroll.driver import run
    from petroll.io.checkpoint import RunInterrupted
    from test_checkpoint import interrupter, make_scene, raw_scene, write_toml

    where = tmp_path_factory.mktemp("checkpointed")
    raw = raw_scene()
    write_toml(where / "s.toml", raw)
    stop, on_step = interrupter(5, MPI.COMM_SELF)
    with pytest.raises(RunInterrupted), warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)  # a coarse grid, on purpose
        run(make_scene(raw, where), MPI.COMM_SELF, where / "run", stop=stop, on_step=on_step)
    return where / "s.toml", where / "run"


def damage_checkpoint(path: pathlib.Path, rng: random.Random) -> str:
    """Damage one checkpoint file in place, one way: cut, bytes, an attribute or dataset changed or gone,
    its scene text damaged, another kind of file in its place; an edit made through h5py sealed again
    half the time (as a faulty writer would: the checks behind the seal are tried too)."""
    from petroll.io.hdf5 import seal

    how = _damage(path, rng)
    if how.startswith(("attribute", "dataset", "scene")) and rng.random() < 0.5:
        seal(path)
        how += ", sealed again"
    return how


def _damage(path: pathlib.Path, rng: random.Random) -> str:
    import h5py

    kind = rng.choice(["cut", "bytes", "attribute", "attribute", "dataset", "dataset", "scene", "other"])
    if kind == "cut":
        data = path.read_bytes()
        path.write_bytes(data[: rng.randrange(len(data))])
        return "cut"
    if kind == "bytes":
        data = bytearray(path.read_bytes())
        for _ in range(rng.choice([1, 4, 64])):
            data[rng.randrange(len(data))] = rng.randrange(256)
        path.write_bytes(bytes(data))
        return "bytes changed"
    if kind == "other":
        what = rng.choice(["empty", "text", "directory"])
        path.unlink()
        if what == "directory":
            path.mkdir()
        else:
            path.write_text("" if what == "empty" else "not a checkpoint\n")
        return f"replaced by {what}"
    with h5py.File(path, "r+") as f:
        if kind == "attribute":
            name = rng.choice(sorted(f.attrs))
            value = rng.choice([None, math.nan, -1, "x", 2**62, np.zeros(3), b"\xff"])
            if value is None:
                del f.attrs[name]
            else:
                f.attrs[name] = value
            return f"attribute {name} = {value!r}"[:80]
        names = []
        f.visit(lambda n: names.append(n) if isinstance(f[n], h5py.Dataset) else None)
        if kind == "dataset":
            name = rng.choice(sorted(names))
            data = f[name][()]
            del f[name]
            how = rng.choice(["gone", "shape", "type", "nan"])
            if how == "shape":
                f[name] = np.zeros(np.asarray(data).size + 1)
            elif how == "type":
                f[name] = np.array(["x"] * max(1, np.asarray(data).size), dtype=h5py.string_dtype())
            elif how == "nan":
                f[name] = np.full(np.shape(data), np.nan)
            return f"dataset {name} {how}"
        text = str(f.attrs.get("scene", ""))
        f.attrs["scene"] = rng.choice(["\ufeff" + text, text[: len(text) // 2], "[" * 3000, "x = " + "[" * 900
                                       + "]" * 900, text.replace("nx", "n x", 1), "x = 1" + "9" * 5000])
        return "scene text damaged"


@pytest.mark.slow
def test_damaged_checkpoints(tmp_path, capsys, checkpointed):
    """A run's newest (or another) checkpoint damaged: ``petroll restart`` of its directory or the file,
    ``petroll info`` of the directory, and the run again over it (which removes the checkpoints it knows to
    be another run's, and must keep those it cannot read)."""
    trial = Trial("checkpoints", capsys)
    scene, original = checkpointed
    for k in range(16):
        run = tmp_path / f"run{k}"
        shutil.copytree(original, run)
        target = run / "checkpoints" / trial.random.choice(["step-00000005.h5", "step-00000005.h5",
                                                            "step-00000004.h5"])
        how = f"{target.name} {damage_checkpoint(target, trial.random)}"
        verb = trial.random.choice([["restart", run], ["restart", target], ["info", run],
                                    ["restart", run, "--out", tmp_path / f"elsewhere{k}"]])
        trial.call([*verb, "--quiet"] if verb[0] == "restart" else verb, how, limit=60)
        if trial.random.random() < 0.3:
            trial.call(["run", scene, "--out", run, "--quiet"], f"{how}, run again", limit=60)
    trial.verdict()


# -- full and read-only disks ------------------------------------------------------------------------------
DISK_BYTES = 16 * 2**20


class Disk:
    """A small file system for the trial at ``where``: a real tmpfs where this process may mount one (root
    with CAP_SYS_ADMIN), filled up (``fill``) or remounted read-only (``read_only``). Elsewhere simulated
    in this process: a full disk by a file-size limit (RLIMIT_FSIZE: every write() past ``free`` bytes of a
    file fails, EFBIG), a read-only one by OSError(EROFS) from Python's file layer (os.open, open, io.open,
    os.mkdir, os.replace) for paths below ``where`` (every petroll write goes through them: HDF5 files
    through petroll.io.journal's os.open, figures through open). ``kind`` says which;
    PETROLL_FUZZ_DISK=simulated simulates where a tmpfs could be mounted."""

    def __init__(self, where: pathlib.Path, monkeypatch):
        self.where, self.monkeypatch = where, monkeypatch
        where.mkdir()
        simulate = os.environ.get("PETROLL_FUZZ_DISK") == "simulated"  # the fallback, also where mount works
        done = None if simulate else subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={DISK_BYTES}", "tmpfs",
                                                     str(where)], capture_output=True, text=True)
        self.kind = "tmpfs" if done is not None and done.returncode == 0 else "simulated"
        self.mode, self.free = "writable", None

    def reset(self) -> None:
        for path in self.where.iterdir():
            shutil.rmtree(path) if path.is_dir() and not path.is_symlink() else path.unlink()

    @contextlib.contextmanager
    def state(self, mode: str, free: int):
        """Within the block the disk is ``mode``: "writable", "full" (``free`` bytes left) or "read-only"."""
        self.mode, self.free = mode, free
        undo = contextlib.ExitStack()
        if self.kind == "tmpfs" and mode == "full":
            left = os.statvfs(self.where).f_bavail * os.statvfs(self.where).f_frsize
            with open(self.where / "filler", "wb") as fh:  # tmpfs: fill to within ``free`` bytes
                with contextlib.suppress(OSError):
                    fh.write(bytes(max(0, left - free)))
        elif self.kind == "tmpfs" and mode == "read-only":
            subprocess.run(["mount", "-o", "remount,ro", str(self.where)], check=True)
            undo.callback(subprocess.run, ["mount", "-o", "remount,rw", str(self.where)], check=True)
        elif mode == "full":
            import resource

            previous = resource.getrlimit(resource.RLIMIT_FSIZE)
            handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            undo.callback(signal.signal, signal.SIGXFSZ, handler)
            undo.callback(resource.setrlimit, resource.RLIMIT_FSIZE, previous)
            resource.setrlimit(resource.RLIMIT_FSIZE, (max(free, 1), previous[1]))
        elif mode == "read-only":
            self._refuse_writes(undo)
        with undo:
            yield

    def _refuse_writes(self, undo: contextlib.ExitStack) -> None:
        import builtins
        import io

        root = str(self.where)

        def below(path) -> bool:
            try:
                return os.path.abspath(os.fspath(path)).startswith(root)
            except TypeError:
                return False

        def refuse(path):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), os.fspath(path))

        real = {"os.open": os.open, "open": builtins.open, "io.open": io.open, "mkdir": os.mkdir,
                "replace": os.replace}

        def os_open(path, flags, *args, **kwargs):
            if below(path) and flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
                refuse(path)
            return real["os.open"](path, flags, *args, **kwargs)

        def opener(which):
            def open_(file, mode="r", *args, **kwargs):
                if not isinstance(file, int) and below(file) and any(c in mode for c in "wax+"):
                    refuse(file)
                return real[which](file, mode, *args, **kwargs)
            return open_

        def mkdir(path, *args, **kwargs):
            if below(path):
                refuse(path)
            return real["mkdir"](path, *args, **kwargs)

        def replace(a, b, *args, **kwargs):
            if below(a) or below(b):
                refuse(b)
            return real["replace"](a, b, *args, **kwargs)

        patch = pytest.MonkeyPatch()
        undo.callback(patch.undo)
        patch.setattr(os, "open", os_open)
        patch.setattr(builtins, "open", opener("open"))
        patch.setattr(io, "open", opener("io.open"))
        patch.setattr(os, "mkdir", mkdir)
        patch.setattr(os, "replace", replace)

    def held(self) -> list[str]:
        """The files below ``where`` that this process holds open."""
        found = []
        for fd in os.listdir("/proc/self/fd"):
            with contextlib.suppress(OSError):
                target = os.readlink(f"/proc/self/fd/{fd}")
                if target.startswith(str(self.where)):
                    found.append(target[len(str(self.where)) + 1:])
        return found

    def close(self) -> None:
        if self.kind == "tmpfs":
            subprocess.run(["umount", "-l", str(self.where)], capture_output=True)


def intact(path: pathlib.Path) -> str | None:
    """Why a file petroll wrote earlier is no longer whole (None if it is)."""
    import tomllib

    import h5py

    try:
        if path.suffix == ".h5":
            with h5py.File(path, "r") as f:
                f.visit(lambda name: None)
            if path.name == "results.h5":
                from petroll.io.results import Results

                Results.open(path)
        elif path.suffix == ".png":
            data = path.read_bytes()
            if not (data.startswith(b"\x89PNG") and data.endswith(b"IEND\xaeB`\x82")):
                return "not a whole PNG"
        elif path.suffix == ".toml":
            tomllib.loads(path.read_text(encoding="utf-8"))
        elif path.suffix == ".csv" and not path.read_text(encoding="utf-8").strip():
            return "empty"
    except Exception as exc:  # noqa: BLE001 - any failure to read it is the answer
        return f"{type(exc).__name__}: {exc}"
    return None


@pytest.fixture(scope="module")
def earlier(tmp_path_factory, checkpointed):
    """What a user had on the disk before: a run with checkpoints and its figures and stresses, a sweep,
    a fitted material (templates copied onto the disk for every input)."""
    from petroll.cli import main

    scene, run = checkpointed
    where = tmp_path_factory.mktemp("earlier")
    shutil.copytree(run, where / "run")
    write(where / "static.toml", SWEEP_SCENE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)
        for argv in (["plot", where / "run"], ["stress", where / "run"],
                     ["sweep", where / "static.toml", "--vary", "motion.penetration=1e-5,2e-5", "--out",
                      where / "sweep", "--quiet"],
                     ["material", "fit", ROOT / "runs" / "rubber-dma.csv", "--shift", "wlf:8.86,101.6,293.15",
                      "--out", where / "fit" / "rubber.toml"]):
            assert main([str(a) for a in argv]) == 0, argv
    return scene, where


@pytest.mark.slow
def test_full_and_read_only_disks(tmp_path, capsys, monkeypatch, earlier):
    """Every verb that writes, on a disk left with a few bytes to a few MB free, or read-only, over what an
    earlier session wrote there (a run with checkpoints, figures, stresses, a sweep, a fitted material):
    one line and exit 2 (or success), nothing that was there lost or left half written, no temporary file
    left behind, no file left open."""
    scene, template = earlier
    disk = Disk(tmp_path / "disk", monkeypatch)
    trial = Trial(f"disks ({disk.kind})", capsys)
    try:
        for k in range(16):
            disk.reset()
            for name in ("run", "sweep", "fit"):
                shutil.copytree(template / name, disk.where / name)
            before = {p: p.stat().st_mtime_ns for p in disk.where.rglob("*") if p.is_file()}
            mode = trial.random.choice(["full", "full", "read-only"])
            free = trial.random.choice([0, 512, 4096, 32768, 200_000, 1_000_000, 4_000_000])
            d = disk.where
            verb = trial.random.choice([
                ["run", scene, "--out", d / "new", "--quiet"], ["run", scene, "--out", d / "run", "--quiet"],
                ["restart", d / "run", "--quiet"], ["stress", d / "run"], ["plot", d / "run"],
                ["plot", d / "run", "--out", d / "figures", "--format", trial.random.choice(["png", "pdf", "svg"])],
                ["plot", d / "sweep"], ["plot", d / "run" / "stress.h5"],
                ["sweep", template / "static.toml", "--vary", "motion.penetration=1e-5,1.5e-5,2e-5", "--out",
                 d / "sweep", "--quiet"],
                ["material", "fit", ROOT / "runs" / "rubber-dma.csv", "--shift", "wlf:8.86,101.6,293.15", "--out",
                 d / "fit" / "rubber.toml"],
                ["export", d / "run", "--csv", "--out", d / "series.csv"]])
            what = f"{mode}{f' ({free} bytes free)' if mode == 'full' else ''}: {verb[0]}"
            with disk.state(mode, free):
                code, _ = trial.call(verb, what, limit=60)
            (d / "filler").unlink(missing_ok=True)
            left = [str(p.relative_to(d)) for p in d.rglob(".*.tmp*")]
            damaged = [f"{p.relative_to(d)} ({why})" for p in before if p.exists() and (why := intact(p))]
            gone = [str(p.relative_to(d)) for p in before if not p.exists() and p.suffix != ".h5"
                    and "checkpoints" not in p.parts]
            held = disk.held()
            if left or damaged or (gone and code != 0) or held:
                trial.faults.append(f"files: {what}: petroll {verb[0]}: temporaries left {left}, damaged "
                                    f"{damaged}, gone {gone}, held open {held}")
    finally:
        disk.close()
    trial.verdict()
