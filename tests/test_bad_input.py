"""Bad input (issue 6): generated malformed and extreme scenes (dicts and TOML text) and command lines.

petroll never crashes with a traceback or hangs: it runs, or exits non-zero with one line that names the
file, the key, the value and what is allowed, and leaves what was already in the output directory alone.
The command line runs in-process (petroll.cli.main) for speed; a few subprocess cases (marked serial)
check the real command, and `mpirun -n 2` cases check that an error on one rank ends all ranks promptly.
"""

import datetime
import math
import os
import pathlib
import shutil
import re
import signal
import subprocess
import time
import tomllib
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from petroll.model.bodies import BODY_KEYS
from petroll.errors import SceneError
from petroll.model.limits import PetrollWarning
from petroll.model.schema import SCHEMA
from petroll.model.scene import dumps, parse_scene

ROOT = pathlib.Path(__file__).resolve().parents[1]
FUZZ = settings(max_examples=300, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                       HealthCheck.data_too_large])

BASE = {  # a small valid scene: 32 x 32 cells (9 per contact radius), an SLS sphere, a few steps
    "grid": {"nx": 32, "ny": 32, "x": [-0.8e-3, 0.8e-3], "y": [-0.8e-3, 0.8e-3]},
    "material": {"model": "sls", "E0": 1e7, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
    "body": {"shape": "sphere", "radius": 0.01},
    "motion": {"penetration": 2e-5},
    "time": {"dt": 0.01, "end": 0.03, "max_steps": 20},
    "solver": {"tol": 1e-8},
}

KEYS = sorted({(s, k) for s, keys in SCHEMA.items() for k in keys}
              | {("body", k) for keys in BODY_KEYS.values() for k in keys} | {("material", "bogus")})
SECTIONS = [*SCHEMA, "bogus"]

numbers = st.one_of(
    st.integers(-3, 40),
    st.sampled_from([0, -1, 2**24, 2**24 + 1, 2**31, 2**63, 10**30, True, False]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 5e-324, 1e-300, 1e-30, 1e-12, 1e-6, 0.5, 1.0, 1e6, 1e12, 1e300, -1e-6,
                     math.nan, math.inf, -math.inf]),
)
words = st.one_of(st.text(max_size=12), st.sampled_from(
    ["sphere", "cylinder", "ellipsoid", "heightmap", "mesh", "sls", "elastic", "prony", "tabulated",
     "kelvin", "maxwell", "D", "J", "x", "y", "ramp", "sinusoidal", "tabulated", "tron", "pk", "bogus",
     "relaxation", "exponential", "paper", "", "missing.csv", "../etc/passwd"]))
scalars = st.one_of(numbers, words, st.just(datetime.date(2026, 1, 1)))
programs = st.fixed_dictionaries(
    {"kind": st.sampled_from(["ramp", "sinusoidal", "tabulated", "bogus"])},
    optional={"start": numbers, "end": numbers, "duration": numbers, "mean": numbers, "amplitude": numbers,
              "period": numbers, "phase": numbers, "t": st.lists(numbers, max_size=4),
              "value": st.lists(st.one_of(numbers, st.lists(numbers, max_size=3)), max_size=4), "x": scalars})
values = st.one_of(scalars, st.lists(st.one_of(scalars, st.lists(numbers, max_size=3)), max_size=4), programs,
                   st.dictionaries(words, scalars, max_size=3))
mutation = st.one_of(
    st.tuples(st.just("set"), st.sampled_from(KEYS), values),
    st.tuples(st.just("drop"), st.sampled_from(KEYS), st.none()),
    st.tuples(st.just("section"), st.sampled_from(SECTIONS), st.one_of(scalars, st.just({}))),
)


def mutate(raw: dict, changes) -> dict:
    import copy

    raw = copy.deepcopy(raw)
    for kind, where, value in changes:
        if kind == "set":
            section, key = where
            table = raw.setdefault(section, {})
            if isinstance(table, dict):
                table[key] = value
        elif kind == "drop":
            section, key = where
            if isinstance(raw.get(section), dict):
                raw[section].pop(key, None)
        elif value == {}:
            raw.pop(where, None)
        else:
            raw[where] = value
    return raw


def assert_one_line(message: str, source: str) -> None:
    assert "\n" not in message and "Traceback" not in message, message
    assert message.startswith(f"{source}: "), message
    assert " = " in message and ": " in message[len(source) + 2:], message  # key = value: allowed


# -- scenes as dicts (the Python API) --------------------------------------------------------------------
@pytest.mark.slow
@FUZZ
@given(st.lists(mutation, min_size=1, max_size=3))
def test_malformed_scene_dicts_are_refused_with_one_line(changes):
    raw = mutate(BASE, changes)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning but PetrollWarning is a bug
        warnings.simplefilter("ignore", PetrollWarning)
        try:
            scene = parse_scene(raw, source="fuzz.toml")
        except SceneError as exc:
            assert_one_line(str(exc), "fuzz.toml")
            assert exc.key in str(exc)
            event(f"refused: {exc.key}")
            return
    event("accepted")
    assert scene.grid.nx * scene.grid.ny >= 1  # accepted: a valid scene
    tomllib.loads(dumps(scene.raw))  # and what results.h5 stores of it is valid TOML


@pytest.mark.slow
@FUZZ
@given(st.lists(st.tuples(st.sampled_from([("grid", "nx"), ("grid", "ny"), ("grid", "x"), ("grid", "y"),
                                           ("material", "E0"), ("material", "Einf"), ("body", "radius"),
                                           ("motion", "penetration"), ("time", "dt"), ("time", "end")]),
                          st.one_of(st.floats(1e-300, 1e300), st.integers(1, 2**24),
                                    st.lists(st.floats(-1e300, 1e300), min_size=2, max_size=2))),
                min_size=1, max_size=4))
def test_extreme_but_valid_numbers_parse_or_are_refused_quickly(changes):
    """Huge grids (up to 2^24 cells a side), tiny and huge lengths and moduli: parsing stays cheap."""
    raw = mutate(BASE, [("set", where, value) for where, value in changes])
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", PetrollWarning)
            parse_scene(raw, source="fuzz.toml")
    except SceneError as exc:
        assert_one_line(str(exc), "fuzz.toml")


# -- scenes as TOML text through the command line (in-process) ------------------------------------------

def _prepare(tmp_path: pathlib.Path):
    out = tmp_path / "out"
    out.mkdir(exist_ok=True)
    for name in out.iterdir():  # an earlier example's run (checkpoints/ if it asked for them)
        if name.name not in ("results.h5", "notes.txt"):
            shutil.rmtree(name) if name.is_dir() else name.unlink()
    (out / "results.h5").write_bytes(b"an earlier result")
    (out / "notes.txt").write_text("keep me")
    return out


def _check_failure(code, err, out: pathlib.Path, source: str) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("petroll: error: "), err
    assert source in lines[0], lines[0]
    assert "Traceback" not in err
    assert (out / "results.h5").read_bytes() == b"an earlier result"
    assert (out / "notes.txt").read_text() == "keep me"
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "results.h5"]


small_numbers = st.one_of(st.integers(-3, 40), st.sampled_from([2**24 + 1, 2**31, 10**30, True]), st.floats(),
                         st.sampled_from([5e-324, 1e-300, 1e-12, 1e12, 1e300, -1e-6]))
small_mutation = st.one_of(  # values that keep a valid scene small (a run of at most a few 8 x 8 steps)
    st.tuples(st.just("set"), st.sampled_from(KEYS), st.one_of(small_numbers, words, st.lists(small_numbers,
                                                                                           max_size=3))),
    st.tuples(st.just("drop"), st.sampled_from([k for k in KEYS if k != ("time", "max_steps")]), st.none()),
    st.tuples(st.just("section"), st.sampled_from([s for s in SECTIONS if s != "grid"]),
              st.one_of(scalars, st.just({}))),
)


def _small(changes) -> dict:
    raw = mutate(BASE, changes)
    if isinstance(raw.get("time"), dict):
        raw["time"]["max_steps"] = 20  # a run stays short whatever the mutations
    return raw


texts = st.one_of(
    st.lists(small_mutation, min_size=1, max_size=2).map(lambda changes: _toml(_small(changes))),
    st.text(max_size=200),
    st.tuples(st.integers(0, 400), st.text(max_size=8)).map(
        lambda cut: (lambda t: t[: cut[0]] + cut[1] + t[cut[0]:])(_toml(BASE))),
    st.binary(max_size=60).map(lambda b: b"[grid]\nnx = " + b),
)


def _toml(raw: dict) -> str:
    try:
        return dumps(raw)
    except Exception:  # values TOML cannot hold (nan keys...): written as text anyway
        return repr(raw)


@pytest.mark.slow
@pytest.mark.serial
@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(texts)
def test_malformed_scene_files_fail_with_one_line_and_keep_the_output(tmp_path, cli_main, text):
    scene = tmp_path / "FUZZ.toml"
    if isinstance(text, bytes):
        scene.write_bytes(text)
    else:
        scene.write_text(text, encoding="utf-8", errors="surrogatepass")
    out = _prepare(tmp_path)
    code, stdout, err = cli_main(["run", str(scene), "--out", str(out), "--quiet"])
    event(f"exit status {code}")
    if code == 0:
        assert (out / "results.h5").read_bytes()[:4] == b"\x89HDF" and "Traceback" not in err
        assert (out / "notes.txt").read_text() == "keep me"
        assert all(line.startswith("petroll: warning: ") for line in err.splitlines() if line.strip()), err
    else:
        _check_failure(code, err, out, str(scene))


tokens = st.one_of(
    st.sampled_from(["run", "keys", "plot", "restart", "stress", "--depth", "--step", "--out", "--quiet",
                     "--scene", "--times", "--fast",
                     "--bogus", "-petroll_tao_type", "-h", "-x", "", "1,2", "nan", "--out=",
                     "runs/hertz.toml", "missing.toml", "DIR", "-1", "inf"]),
    st.text(max_size=6),
)


@pytest.mark.slow
@pytest.mark.serial
@settings(max_examples=150, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(st.lists(tokens, max_size=5))
def test_malformed_command_lines_fail_with_one_line(tmp_path, cli_main, monkeypatch, argv):
    import tempfile

    work = pathlib.Path(tempfile.mkdtemp(dir=tmp_path))  # one directory per example
    monkeypatch.chdir(work)
    (work / "runs").mkdir()
    (work / "runs" / "hertz.toml").write_text(_toml(BASE))
    (work / "DIR").mkdir()
    (work / "DIR" / "results.h5").write_bytes(b"an earlier result")
    code, stdout, err = cli_main(argv)
    event(f"exit status {code}")
    assert "Traceback" not in err + stdout
    assert (work / "DIR" / "results.h5").read_bytes() == b"an earlier result" or "run" in argv
    if code != 0:
        lines = [line for line in err.splitlines() if line.strip()]
        assert code == 2 and len(lines) == 1 and lines[0].startswith("petroll: error: "), (argv, err)
        assert not (work / "results").exists(), argv  # a failed command makes no default output


# -- the real command, and MPI (subprocesses) -----------------------------------------------------------
@pytest.mark.slow
@pytest.mark.serial
def test_extreme_scene_through_the_real_command(tmp_path, cli):
    """Moduli 1e12 Pa, a 1 um sphere, 1e-3 s steps: runs; a scene past the limits: one line, exit 2."""
    raw = mutate(BASE, [("set", ("material", "E0"), 1e12), ("set", ("material", "Einf"), 1e9),
                        ("set", ("body", "radius"), 1e-6), ("set", ("motion", "penetration"), 2e-9),
                        ("set", ("grid", "x"), [-1e-7, 1e-7]), ("set", ("grid", "y"), [-1e-7, 1e-7])])
    (tmp_path / "tiny.toml").write_text(dumps(raw))
    done = cli("run", "tiny.toml", "--out", "o", cwd=tmp_path, timeout=120)
    assert done.returncode == 0, done.stderr
    raw["motion"]["penetration"] = 1e-6  # delta = R: the contact would reach the sphere's equator
    raw["grid"] = {"nx": 8, "ny": 8, "x": [-5e-6, 5e-6], "y": [-5e-6, 5e-6]}
    (tmp_path / "deep.toml").write_text(dumps(raw))
    out = _prepare(tmp_path)
    refused = cli("run", "deep.toml", "--out", out, cwd=tmp_path, timeout=120)
    _check_failure(refused.returncode, refused.stderr, out,
                   "deep.toml: [motion] penetration = 1e-06: too large")


@pytest.mark.slow
@pytest.mark.serial
def test_an_error_raised_on_every_rank_is_printed_once_and_exits_cleanly(tmp_path, cli):
    raw = mutate(BASE, [("set", ("grid", "nx"), 0)])
    (tmp_path / "bad.toml").write_text(dumps(raw))
    out = _prepare(tmp_path)
    proc = cli("run", "bad.toml", "--out", out, cwd=tmp_path, ranks=2, timeout=60)
    assert proc.returncode == 2
    ours = [line for line in proc.stderr.splitlines() if line.startswith("petroll")]
    assert ours == ["petroll: error: bad.toml: [grid] nx = 0: must be an integer >= 1, at most 16777216 "
                    "(2^24)"]
    assert "MPI_ABORT" not in proc.stderr and "Traceback" not in proc.stderr
    assert (out / "results.h5").read_bytes() == b"an earlier result"


@pytest.mark.slow
@pytest.mark.serial
@pytest.mark.parametrize("hook, code, text", [
    ("1", 2, "petroll: error: test failure on rank 1 (PETROLL_TEST_FAIL_RANK) (on rank 1 of 2 only; "
             "ending all ranks)"),
    ("0:crash", 1, "RuntimeError: test failure on rank 0 (PETROLL_TEST_FAIL_RANK) (on rank 0 of 2 only; "
                   "ending all ranks)"),
])
def test_an_error_on_one_rank_ends_all_ranks_promptly(tmp_path, hook, code, text, cli):
    """The other rank waits in a collective of the run; the failing rank prints its message and aborts the
    job after ERROR_AGREEMENT_S (3 s) instead of leaving it hanging."""
    (tmp_path / "ok.toml").write_text(dumps(BASE))
    started = time.monotonic()
    proc = cli("run", "ok.toml", "--out", "o", "--quiet", cwd=tmp_path, ranks=2, timeout=90,
               PETROLL_TEST_FAIL_RANK=hook)
    wall = time.monotonic() - started
    assert proc.returncode != 0
    assert text in proc.stderr, proc.stderr
    assert wall < 60
    assert not (tmp_path / "o" / "results.h5").exists()


# -- issue 35: crashes, tracebacks, hangs and misleading refusals at the edges -----------------------------
def refused(cli_main, argv: list, *needles: str, seconds: float = 30.0) -> str:
    """``petroll ARGV`` in this process with every warning an error (none may be printed before the
    refusal): exit status 2 on every rank, one line naming ``needles`` (rank 0 prints it), within
    ``seconds``. Returns the line ("" on other ranks)."""
    from mpi4py import MPI

    started = time.monotonic()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code, _, err = cli_main([str(a) for a in argv])
    assert code == 2, (code, err)
    assert time.monotonic() - started < seconds, f"took {time.monotonic() - started:.1f} s"
    if MPI.COMM_WORLD.rank != 0:
        return ""
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("petroll: error: "), (code, err)
    assert all(needle in lines[0] for needle in needles), (needles, lines[0])
    return lines[0]


HERTZ = ROOT / "runs" / "hertz.toml"


@pytest.mark.parametrize("text, key, allowed", [
    ("[" + ".".join(["a"] * 2000) + "]\n", "[a] a", "may nest at most 16 deep"),
    ("x = " + "[" * 5000 + "]" * 5000 + "\n", "(syntax)", "may nest at most 16 deep"),
    ("x = " + "{a = " * 3000 + "1" + "}" * 3000 + "\n", "(syntax)", "may nest at most 16 deep"),
    (HERTZ.read_text().replace("[solver]", "[solver]\nbogus = " + "[" * 300 + "]" * 300), "[solver] bogus",
     "may nest at most 16 deep"),
    (HERTZ.read_text().replace("nx = 64", "nx = " + "9" * 5000), "(syntax)", "(4300 digits)"),
    (HERTZ.read_text().replace("nx = 64", "nx = " + "9" * 4000), "[grid] nx", "at most 16777216"),
], ids=["table-2000-deep", "5000-arrays", "3000-inline-tables", "300-arrays", "5000-digits", "4000-digits"])
def test_deep_nesting_and_huge_integers_are_refused_in_one_line(tmp_path, cli_main, text, key, allowed):
    """Each was a RecursionError or ValueError traceback (issue 35); a value too long to show is cut."""
    scene = tmp_path / "s.toml"
    scene.write_text(text)
    for verb in ("check", "run"):
        line = refused(cli_main, [verb, scene, "--out", tmp_path / "out"][: 2 if verb == "check" else 4],
                       f"{scene}: {key} = ", allowed)
        assert len(line) < 700, line
    assert not (tmp_path / "out").exists()


def test_a_scene_with_a_byte_order_mark_is_read_as_without(tmp_path, cli_main, comm):
    """Windows editors save UTF-8 with a byte-order mark: was 'Invalid statement (line 1, column 1)'. The
    scene and the text results.h5 stores are the file's without it."""
    from petroll.model.scene import load_scene

    plain, marked = tmp_path / "plain.toml", tmp_path / "marked.toml"
    plain.write_text(HERTZ.read_text(), encoding="utf-8")
    marked.write_bytes(b"\xef\xbb\xbf" + HERTZ.read_bytes())
    assert load_scene(marked).text == load_scene(plain).text and load_scene(marked).raw == load_scene(plain).raw
    code, out, err = cli_main(["check", str(marked)])
    assert code == 0 and ("checked, nothing run" in out or comm.rank), err


def test_a_scene_file_larger_than_16_mib_is_refused_unread(cli_main):
    refused(cli_main, ["check", "/dev/zero"], "/dev/zero: (file) = ", "larger than 16 MiB", seconds=10)


@pytest.mark.parametrize("argv, needles", [
    (["sweep", HERTZ, "--vary", "motion.penetration=1e-6..2e-5:lin:99999999999999999999"],
     ["N = 99999999999999999999", "at most 1000 values"]),
    (["sweep", HERTZ, "--vary", "motion.penetration=1e-6..2e-5:lin:1000000000"], ["N = 1000000000", "at most 1000"]),
    (["sweep", HERTZ, "--vary", "motion.penetration=1e-6..2e-5:log:" + "9" * 5000], ["(5000 digits)", "at most 1000"]),
    (["sweep", HERTZ, "--vary", "grid.nx=" + ",".join(str(n) for n in range(8, 1209))], ["1201 values", "at most 1000"]),
    (["sweep", HERTZ, "--vary", "grid.nx=100000,36"], ["[grid] nx = 100000", "27944 cells per contact half-width",
                                                       "more than 1024", "nx <= 3664 gives 1024"]),
    (["material", "fit", ROOT / "runs" / "rubber-dma.csv", "--shift", "wlf:8.86,101.6,293.15", "--terms", "100000"],
     ["terms = 100000 (--terms)", "at most 2000"]),
    (["material", "fit", ROOT / "runs" / "rubber-dma.csv", "--shift", "wlf:8.86,101.6,293.15", "--per-decade",
      "1000"], ["per_decade = 1000.0 (--per-decade)", "at most 2000"]),
], ids=["lin-1e20", "lin-1e9", "log-5000-digits", "1201-values", "nx-100000", "terms-100000", "per-decade-1000"])
def test_every_count_a_user_types_is_bounded_before_work_starts(tmp_path, cli_main, argv, needles):
    """Were a ValueError (lin:10^20), hangs (lin:10^9 still running after 60 s; nx = 100000 still running 5
    s after SIGTERM: a steady solve on 6.4 million cells; --terms 100000): refused at once, stating the
    bound (issue 35)."""
    argv = [*argv, "--out", tmp_path / "out"] if argv[0] == "sweep" else argv
    refused(cli_main, argv, *needles, seconds=20)
    assert not any((tmp_path / "out").rglob("results.h5"))


@pytest.mark.slow
def test_max_steps_depths_and_times_are_bounded(shared_dir, comm, cli_main, monkeypatch):
    raw = mutate(BASE, [("set", ("time", "max_steps"), 10**6 + 1)])
    if comm.rank == 0:
        (shared_dir / "s.toml").write_text(dumps(raw))
    comm.Barrier()
    refused(cli_main, ["check", shared_dir / "s.toml"], "[time] max_steps = 1000001", "at most 1000000")
    monkeypatch.chdir(shared_dir)
    raw["time"] = {"dt": 0.001, "end": 0.02, "max_steps": 30}
    raw["output"] = {"every": 1}  # 21 saved fields
    comm.Barrier()
    if comm.rank == 0:
        (shared_dir / "s.toml").write_text(dumps(raw))
    comm.Barrier()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)
        assert cli_main(["run", "s.toml", "--out", "run", "--quiet"])[0] == 0
    refused(cli_main, ["stress", "run", "--depth", ",".join(["1e-5"] * 1001)], "1001 depths", "at most 1000")
    times = ",".join(str(t) for t in np.linspace(0.0, 0.02, 17))
    refused(cli_main, ["plot", "run", "--times", times], "--times: picks", "at most 16")


@pytest.mark.slow
@pytest.mark.serial
@pytest.mark.parametrize("argv", [["keys"], ["check", "runs/sphere.toml"]], ids=["keys", "check"])
def test_a_reader_that_stops_reading_ends_the_command_quietly(argv, cli):
    """``petroll check S | head -1``: stdout's reader gone (here closed before the command starts, so its
    first write fails), the command ends as a shell reports one ended by SIGPIPE, 141, with nothing on
    stderr: no PETSc signal report, no MPI_ABORT (exit 59), no Python traceback."""
    read, write = os.pipe()
    os.close(read)
    try:
        child = cli.start(*argv, cwd=pathlib.Path(__file__).parents[1], stdout=write, stderr=subprocess.PIPE,
                          text=True)
    finally:
        os.close(write)
    _, err = child.communicate(timeout=120)
    assert (child.returncode, err) == (128 + signal.SIGPIPE, "")


@pytest.mark.serial  # one process: the line is checked where it is printed
def test_a_step_count_per_cell_that_underflows_is_refused_in_one_line(tmp_path, cli_main):
    """``steps_per_cell = 5e-324`` (the smallest double, drawn by test_fuzz's seed 2289785311; in a steady
    scene by seed 3490272453), and 1e-315 at 0.01 m/s, whose time per cell overflows: the steps per second
    underflow to 0 (was ZeroDivisionError in model/clock.py, transient and steady); one line naming the key."""
    for name, value in (("sphere-dma.toml", "5e-324"), ("rough-rubber.toml", "5e-324"),
                        ("rough-rubber.toml", "1e-315")):
        text = (pathlib.Path(__file__).parents[1] / "runs" / name).read_text(encoding="utf-8")
        assert re.search(r"(?m)^steps_per_cell = ", text), name  # the scene sets it, to be replaced
        scene = tmp_path / f"tiny-{value}-{name}"
        scene.write_text(re.sub(r"(?m)^steps_per_cell = .*$", f"steps_per_cell = {value}", text), encoding="utf-8")
        code, _, err = cli_main(["check", str(scene)])
        assert code == 2 and err.count("\n") == 1 and f"[time] steps_per_cell = {value}: gives no finite step" \
            in err, (name, value, err)
