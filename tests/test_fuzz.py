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
