"""Scenes: the default scene, every kind of invalid scene (in memory, on disk and through the command line),
the happy path through the command line and the Python API against Hertz, Scene.replace, and the
generated scene reference.

Unmarked tests run on every rank under mpirun: they either stay in memory or write only into a directory
that rank 0 chose and broadcast. Tests that start processes are marked ``serial``.
"""

import copy
import math
import pathlib
import re
import tomllib
import warnings

import h5py
import numpy as np
import pytest

from petroll.model.bodies import Sphere
from petroll.errors import MISSING, PetrollError, SceneError
from petroll.model.schema import SCHEMA
from petroll.model.tao import DEFAULT_TAO_TYPE
from petroll.model.scene import Scene, load_scene, parse_scene

ROOT = pathlib.Path(__file__).resolve().parent.parent
SPHERE = ROOT / "runs" / "hertz.toml"


def default_raw() -> dict:
    """The default scene as a fresh dict (the parsed TOML of runs/hertz.toml)."""
    with open(SPHERE, "rb") as fh:
        return tomllib.load(fh)


HERTZ_REL = 5e-4
"""How close runs/hertz.toml's force comes to Hertz's: its grid (a/dx = 17.9) gives 7.0e-5 (measured)."""


def hertz_force(raw: dict, delta: float) -> float:
    """Hertz: F = 4 sqrt(R) delta^1.5 / (3 J), J = (1 - nu^2) / E, from the scene's own numbers."""
    m = raw["material"]
    J = (1.0 - m["nu"] ** 2) / m["E"]
    return 4.0 * math.sqrt(raw["body"]["radius"]) * delta**1.5 / (3.0 * J)


def assert_scene_error(exc: SceneError, source: str, key: str, value_repr: str, allowed) -> None:
    """The error names the file, the key, the bad value (repr) and what is allowed (a text or several), in
    the format "source: key = value: allowed"."""
    message = str(exc)
    assert isinstance(exc, PetrollError)
    assert exc.source == source
    assert exc.key == key, message
    assert message.startswith(f"{source}: {key} = {value_repr}: "), message
    for fragment in (allowed,) if isinstance(allowed, str) else allowed:
        assert fragment in exc.allowed, message
    assert "\n" not in message


def write_toml(path: pathlib.Path, raw: dict) -> None:
    """A scene dict as a TOML file, written with plain str/repr (no dependency on petroll's writer)."""

    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return '"' + v + '"'
        if isinstance(v, list):
            return "[" + ", ".join(value(item) for item in v) + "]"
        return repr(v)

    text = "".join(f"[{section}]\n" + "".join(f"{k} = {value(v)}\n" for k, v in table.items()) + "\n"
                   for section, table in raw.items())
    path.write_text(text, encoding="utf-8")


# -- 1. the default scene ------------------------------------------------------------------------------------
def test_default_scene_loads_with_the_files_values():
    raw = default_raw()
    scene = load_scene(SPHERE)
    assert isinstance(scene, Scene)
    assert scene.source == str(SPHERE)
    assert scene.text == SPHERE.read_text(encoding="utf-8")
    g = raw["grid"]
    assert (scene.grid.nx, scene.grid.ny) == (g["nx"], g["ny"]) == (64, 64)
    assert (scene.grid.x0, scene.grid.x1) == tuple(g["x"])
    assert (scene.grid.y0, scene.grid.y1) == tuple(g["y"])
    assert scene.material.J0 == scene.material.Jinf  # elastic: J = (1 - nu^2)/E
    assert scene.material.J0 == pytest.approx((1 - 0.5**2) / 10.0e6, rel=1e-15)
    assert raw["material"] == {"model": "elastic", "E": 10.0e6, "nu": 0.5}
    assert isinstance(scene.body, Sphere)
    assert scene.body.radius == raw["body"]["radius"] == 0.01
    assert scene.position == tuple(raw["body"]["position"])
    assert scene.penetration(0.0) == scene.penetration(1.0) == raw["motion"]["penetration"] == 20.0e-6
    assert scene.load is None
    assert scene.solver.tao_type == DEFAULT_TAO_TYPE
    assert scene.solver.tol == raw["solver"]["tol"]
    assert scene.output_dir == pathlib.Path(raw["output"]["dir"])
    assert scene.raw == raw
    # the same dict through parse_scene is accepted too (the base of every invalid variant below)
    assert parse_scene(raw, source="bad.toml").grid == scene.grid


# -- 2. invalid scenes, in memory ----------------------------------------------------------------------------
def _set(section, key, value):
    """Set [section] key = value, or (key None) the whole section to value."""
    def mutate(raw):
        if key is None:
            raw[section] = value
        else:
            raw.setdefault(section, {})[key] = value

    return mutate


def _drop(section, key):
    def mutate(raw):
        del raw[section][key]

    return mutate


def _add_section(raw):
    raw["extra"] = {"a": 1}


_GRID_BOX = repr([[-0.8e-3, 0.8e-3], [-0.8e-3, 0.8e-3]])

# (id, mutation of the default scene, key, repr of the value in the message, part of the allowed text)
INVALID = [
    ("unknown-section", _add_section, "[extra]", "{'a': 1}", "unknown section"),
    ("unknown-grid-key", _set("grid", "nz", 3), "[grid] nz", "3", "unknown key"),
    ("missing-nx", _drop("grid", "nx"), "[grid] nx", "(missing)", "required"),
    ("missing-E", _drop("material", "E"), "[material] E", "(missing)", "required"),
    ("nx-float", _set("grid", "nx", 1.5), "[grid] nx", "1.5", "must be an integer >= 1"),
    ("nx-bool", _set("grid", "nx", True), "[grid] nx", "True", "must be an integer >= 1"),
    ("nx-zero", _set("grid", "nx", 0), "[grid] nx", "0", "must be an integer >= 1"),
    ("E-string", _set("material", "E", "soft"), "[material] E", "'soft'", "must be a finite number > 0"),
    ("x-reversed", _set("grid", "x", [1, 0]), "[grid] x", "[1, 0]", "min < max"),
    ("x-short", _set("grid", "x", [0]), "[grid] x", "[0]", "must be a pair [min, max]"),
    ("radius-negative", _set("body", "radius", -1), "[body] radius", "-1", "> 0"),
    ("nu-too-large", _set("material", "nu", 0.7), "[material] nu", "0.7", "-1 < nu <= 0.5"),
    # E0/Einf beyond 1e7: J0 = Jinf - dJ would keep fewer digits than the solver's tolerance (1e30 left none)
    ("sls-ratio", _set("material", None, {"model": "sls", "E0": 1e30, "Einf": 2e6, "nu": 0.5,
                                          "tau_relax": 0.01}),
     "[material] E0", "1e+30", ("gives E0/Einf = 5e+23", "E0/Einf <= 1e+07")),
    ("maxwell-ratio", _set("material", None, {"model": "prony", "series": "maxwell", "Einf": 1.0, "nu": 0.5,
                                               "moduli": [8e6, 1.2e7], "times": [1.0, 2.0]}),
     "[material] moduli", "[8000000.0, 12000000.0]", "gives E0/Einf = 2e+07"),
    ("kelvin-no-J0", _set("material", None, {"model": "prony", "series": "kelvin", "Einf": 2e6, "nu": 0.5,
                                              "compliances": [3e-7, 3e-7], "times": [1.0, 2.0]}),
     "[material] compliances", "[3e-07, 3e-07]", "the compliances must sum to less than 1/Einf"),
    ("penetration-and-load", _set("motion", "load", 0.1), "[motion] penetration / load",
     "{'penetration': 2e-05, 'load': 0.1}", "exactly one of penetration"),
    ("neither-penetration-nor-load", _drop("motion", "penetration"), "[motion] penetration / load",
     "(missing)", "exactly one of penetration"),
    ("unknown-shape", _set("body", "shape", "cube"), "[body] shape", "'cube'",
     ("must be one of", "sphere", "ellipsoid", "cylinder", "heightmap", "mesh")),
    ("unknown-body-key", _set("body", "colour", "red"), "[body] colour", "'red'", "unknown key"),
    ("tao-type", _set("solver", "tao_type", "newton"), "[solver] tao_type", "'newton'",
     ("must be one of", "'tron'", "'gpcg'", "'blmvm'")),
    ("tol-too-large", _set("solver", "tol", 0.5), "[solver] tol", "0.5", "between 1e-15 and 0.1"),
    ("tol-zero", _set("solver", "tol", 0.0), "[solver] tol", "0.0", "> 0"),
    # rigid interference radius sqrt(2 R delta) = 1.4 mm > the grid's half-width 0.8 mm
    ("contact-reaches-edge", _set("motion", "penetration", 1e-4), "[grid] x / y", _GRID_BOX,
     "must contain the contact region"),
]


@pytest.mark.parametrize("mutate, key, value_repr, allowed", [case[1:] for case in INVALID],
                         ids=[case[0] for case in INVALID])
def test_invalid_scene_is_refused_naming_file_key_value_and_allowed(mutate, key, value_repr, allowed):
    raw = default_raw()
    mutate(raw)
    before = copy.deepcopy(raw)
    with pytest.raises(SceneError) as info:
        parse_scene(raw, source="bad.toml")
    assert_scene_error(info.value, "bad.toml", key, value_repr, allowed)
    assert raw == before  # the caller's dict is not modified


def test_every_required_key_is_refused_when_missing():
    """Each schema key without a default, removed alone, is named as the missing key (not some other)."""
    required = [(section, name) for section, keys in SCHEMA.items() for name, spec in keys.items()
                if spec.default is MISSING]
    assert ("grid", "nx") in required and ("body", "shape") in required
    for section, name in required:
        raw = default_raw()
        del raw[section][name]
        with pytest.raises(SceneError) as info:
            parse_scene(raw, source="bad.toml")
        assert_scene_error(info.value, "bad.toml", f"[{section}] {name}", "(missing)", "required")


# -- 2. invalid scene files ----------------------------------------------------------------------------------
FILE_CASES = [
    ("syntax", b"[grid\nnx = 64\n", "(syntax)", "must be valid TOML"),
    ("not-utf8", b"[grid]\nnx = 64\n# \xff\xfe caf\xe9\n", "(file)", "must be a UTF-8 text file"),
]


@pytest.mark.parametrize("content, key, allowed", [c[1:] for c in FILE_CASES], ids=[c[0] for c in FILE_CASES])
def test_invalid_scene_file_is_refused(shared_dir, comm, content, key, allowed):
    path = shared_dir / "bad.toml"
    if comm.rank == 0:
        path.write_bytes(content)
    comm.Barrier()
    with pytest.raises(SceneError) as info:
        load_scene(path)
    exc = info.value
    assert exc.source == str(path) and exc.key == key
    assert str(exc).startswith(f"{path}: {key} = "), str(exc)
    assert allowed in str(exc)
    assert "\n" not in str(exc)
    comm.Barrier()


def test_missing_scene_file_is_refused(shared_dir):
    path = shared_dir / "no-such-scene.toml"
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert_scene_error(info.value, str(path), "(file)", repr(str(path)), "must be a readable scene file")


def test_invalid_value_in_a_scene_file_names_the_file(shared_dir, comm):
    raw = default_raw()
    raw["body"]["radius"] = -1
    path = shared_dir / "negative.toml"
    if comm.rank == 0:
        write_toml(path, raw)
    comm.Barrier()
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert_scene_error(info.value, str(path), "[body] radius", "-1", "> 0")
    comm.Barrier()


# -- 3. invalid scenes through the command line --------------------------------------------------------------
CLI_CASES = [
    ("nu", lambda raw: raw["material"].update(nu=0.7), "[material] nu"),
    ("unknown-key", lambda raw: raw["grid"].update(nz=3), "[grid] nz"),
    ("both-motions", lambda raw: raw["motion"].update(load=0.1), "[motion] penetration / load"),
]


@pytest.mark.slow
@pytest.mark.serial
@pytest.mark.parametrize("mutate, key", [c[1:] for c in CLI_CASES], ids=[c[0] for c in CLI_CASES])
def test_cli_bad_scene_one_line_exit_2_output_untouched(tmp_path, mutate, key, cli):
    raw = default_raw()
    mutate(raw)
    scene = tmp_path / "BAD.toml"
    write_toml(scene, raw)
    out = tmp_path / "out"
    out.mkdir()
    keep = out / "results.h5"
    keep.write_bytes(b"an earlier result")
    stamp = keep.stat().st_mtime_ns
    proc = cli("run", str(scene), "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, proc.stderr
    assert proc.stderr.strip() == lines[0]
    assert lines[0].startswith("petroll: error: "), lines[0]
    assert str(scene) in lines[0] and key in lines[0], lines[0]
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout
    assert sorted(p.name for p in out.iterdir()) == ["results.h5"]
    assert keep.read_bytes() == b"an earlier result" and keep.stat().st_mtime_ns == stamp
    assert not (tmp_path / "results").exists()  # nor any default output directory


@pytest.mark.slow
@pytest.mark.serial
@pytest.mark.parametrize("name, content, key", [
    ("missing.toml", None, "(file)"),
    ("syntax.toml", b"[grid\n", "(syntax)"),
    ("latin1.toml", b"# caf\xe9\n", "(file)"),
])
def test_cli_unreadable_scene_one_line_exit_2(tmp_path, name, content, key, cli):
    scene = tmp_path / name
    if content is not None:
        scene.write_bytes(content)
    proc = cli("run", str(scene), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith(f"petroll: error: {scene}: {key} = "), lines[0]
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not (tmp_path / "out").exists()


@pytest.mark.serial
def test_cli_unknown_option_fails_without_traceback(tmp_path, cli):
    proc = cli("run", str(SPHERE), "--out", str(tmp_path / "out"), "--bogus", cwd=tmp_path)
    assert proc.returncode != 0
    assert "--bogus" in proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    assert not (tmp_path / "out").exists()


# -- 4. the happy path through the command line --------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.serial
def test_cli_run_default_scene_writes_results_matching_hertz(tmp_path, cli):
    out = tmp_path / "out"
    proc = cli("run", str(SPHERE), "--out", str(out), cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr + proc.stdout
    raw = default_raw()
    with h5py.File(out / "results.h5", "r") as f:
        series = f["series"]
        for name in ("force", "delta", "area", "p_max", "iterations"):
            assert series[name].shape == (1,), name
        assert f["fields/pressure"].shape == (1, 64, 64)
        assert f["fields/x"].shape == (64,) and f["fields/y"].shape == (64,)
        scene_text = f.attrs["scene"]
        scene_text = scene_text.decode() if isinstance(scene_text, bytes) else str(scene_text)
        assert scene_text == SPHERE.read_text(encoding="utf-8")
        delta = float(series["delta"][0])
        force = float(series["force"][0])
        pressure = f["fields/pressure"][0]
        x, y = f["fields/x"][()], f["fields/y"][()]
        p_max = float(series["p_max"][0])
    assert delta == raw["motion"]["penetration"]
    assert force == pytest.approx(hertz_force(raw, delta), rel=HERTZ_REL)
    assert np.all(pressure >= 0) and pressure.max() == pytest.approx(p_max)
    # cell centres of the scene's grid
    h = 1.6e-3 / 64
    assert np.allclose(x, -0.8e-3 + (np.arange(64) + 0.5) * h, rtol=0, atol=1e-15)
    assert np.allclose(y, x, rtol=0, atol=1e-15)
    # the pressure integrates to the force
    assert pressure.sum() * h * h == pytest.approx(force, rel=1e-6)
    assert not (tmp_path / "results").exists()  # --out wins over the scene's [output] dir


# -- 5. in process, on every rank ----------------------------------------------------------------------------
def test_run_in_process_matches_hertz(comm, shared_dir):
    from petroll.driver import run

    raw = default_raw()
    scene = load_scene(SPHERE)
    results = run(scene, comm, shared_dir / "disp")
    delta = float(results.series["delta"][0])
    assert delta == scene.penetration(0.0)
    assert float(results.series["force"][0]) == pytest.approx(hertz_force(raw, delta), rel=HERTZ_REL)
    assert results.pressure.shape == (1, 64, 64)
    assert results.scene_text == scene.text
    comm.Barrier()


def test_load_control_gives_the_displacement_controlled_penetration(comm, shared_dir):
    """Load control finds the force to 10 tol = 1e-7 (so the penetration to 2/3 of that), the same grid's
    displacement-controlled answer (measured: 1.0e-10 apart)."""
    from petroll.driver import run

    scene = load_scene(SPHERE)
    displaced = run(scene, comm, shared_dir / "disp")
    force = float(displaced.series["force"][0])
    loaded_scene = scene.replace({"motion.penetration": None, "motion.load": force})
    assert loaded_scene.penetration is None and loaded_scene.load(0.0) == force
    loaded = run(loaded_scene, comm, shared_dir / "load")
    assert float(loaded.series["delta"][0]) == pytest.approx(scene.penetration(0.0), rel=1e-7)
    assert float(loaded.series["force"][0]) == pytest.approx(force, rel=1e-7)
    comm.Barrier()


# -- 6. the generated scene reference ----------------------------------------------------------------------
def test_docs_scene_md_is_the_generated_reference():
    from petroll.model.reference import scene_reference

    assert (ROOT / "docs" / "scene.md").read_text(encoding="utf-8") == scene_reference()


@pytest.mark.parametrize("kind", ["constant", "ramp", "sinusoidal", "tabulated"])
def test_each_program_example_of_the_reference_gives_its_kind(kind):
    """The example of every kind of program in docs/scene.md, in runs/sphere.toml's [motion], is that kind
    with the values its formula gives (written out here independently of petroll.model.motion)."""
    from petroll.model.motion import PROGRAMS

    line = PROGRAMS[kind].example
    key = line.split(" = ")[0]
    raw = tomllib.loads((ROOT / "runs" / "sphere.toml").read_text(encoding="utf-8"))
    raw["motion"] = {k: v for k, v in raw["motion"].items() if k != ("penetration" if key == "load" else key)}
    raw["motion"].update(tomllib.loads(line))
    program = getattr(parse_scene(raw), key)
    expected = {
        "constant": lambda t: np.array([0.01, 0.0]),
        "ramp": lambda t: np.array(0.05 * min(t / 0.02, 1.0)),
        "sinusoidal": lambda t: np.array([0.01 + 0.008 * math.sin(2 * math.pi * t / 0.2), 0.0]),
        "tabulated": lambda t: np.array(np.interp(t, [0.0, 0.05, 0.1], [1e-5, 2e-5, 2e-5])),
    }[kind]
    assert type(program).__name__.lower() == kind
    for t in (0.0, 0.013, 0.02, 0.07, 0.3):
        assert program(t) == pytest.approx(expected(t), rel=1e-14, abs=1e-300), t


def test_the_reference_shows_each_default_as_the_toml_that_gives_it():
    """Every default in the reference's tables, parsed as TOML and given in a scene, is the key's value when
    the key is left out (checked through the key's own conversion)."""
    from petroll.model.reference import scene_reference

    shown = {}
    for section in re.split(r"^## ", scene_reference(), flags=re.M)[1:]:
        name = section.split("]")[0].strip("[")
        for key, default in re.findall(r"^\| `(\w+)` \| [^|]+ \| [^|]+ \| `([^`]+)` \|", section, flags=re.M):
            shown[name, key] = tomllib.loads(f"v = {default}")["v"]
    declared = {(s, k): spec for s, keys in SCHEMA.items() for k, spec in keys.items()
                if spec.default not in (None, MISSING)}
    assert set(shown) == set(declared)
    for (section, key), value in shown.items():
        spec = declared[section, key]
        assert value == spec.default and repr(spec.check(value)) == repr(spec.check(spec.default)), key
    assert shown["motion", "velocity"] == [0.0, 0.0] and shown["solver", "tao_type"] == DEFAULT_TAO_TYPE


# -- 7. Scene.replace ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("key, value, named, value_repr, allowed", [
    ("material.nu", 0.7, "[material] nu", "0.7", "-1 < nu <= 0.5"),
    ("grid.nx", 0, "[grid] nx", "0", "must be an integer >= 1"),
    ("body.radius", "big", "[body] radius", "'big'", "> 0"),
    ("solver.tao_type", "newton", "[solver] tao_type", "'newton'", "must be one of"),
    ("grid.nz", 3, "[grid] nz", "3", "unknown key"),
    ("nosection", 1, "nosection", "1", "must be written section.key"),
])
def test_replace_with_a_bad_value_names_the_key(key, value, named, value_repr, allowed):
    scene = load_scene(SPHERE)
    with pytest.raises(SceneError) as info:
        scene.replace(key, value)
    assert_scene_error(info.value, scene.source, named, value_repr, allowed)
    assert scene.raw["material"]["nu"] == 0.5 and scene.grid.nx == 64 and "nz" not in scene.raw["grid"]


def test_replace_with_a_good_value_returns_a_new_validated_scene():
    scene = load_scene(SPHERE)
    smaller = scene.replace("body.radius", 0.005)
    assert smaller.body.radius == 0.005 and scene.body.radius == 0.01
    assert smaller.raw["body"]["radius"] == 0.005 and scene.raw["body"]["radius"] == 0.01
    assert smaller.source == scene.source and smaller.grid == scene.grid


@pytest.mark.parametrize("path", sorted((ROOT / "runs").glob("*.toml")), ids=lambda p: p.name)
def test_every_shipped_scene_is_valid(path):
    scene = load_scene(path)
    assert scene.output_dir == pathlib.Path("results") / path.stem


@pytest.mark.parametrize("series, terms, times, shown", [
    ("maxwell", "moduli", [1e-2, 1e-2], "0.01 appears twice"),
    ("kelvin", "compliances", [1e-3, 1e-2, 1e-2], "0.01 appears twice"),
    ("maxwell", "moduli", [1e-2, 1e-2 * (1 + 1e-10)], "0.01 and 0.010000000001 are within 1e-09 of each other"),
])
def test_repeated_prony_times_are_named(tmp_path, cli_main, comm, series, terms, times, shown):
    """Prony times = [1e-2, 1e-2] in steady mode: was refused as 'use a time step <= 0 s', after a numpy
    divide warning (issue 35). The refusal names [material] times and the time repeated."""
    values = [1e6] * len(times) if terms == "moduli" else [1e-8] * len(times)
    raw = {"grid": {"nx": 32, "ny": 32, "x": [-0.8e-3, 0.8e-3], "y": [-0.8e-3, 0.8e-3]},
           "material": {"model": "prony", "series": series, "Einf": 2e6, "nu": 0.5, terms: values, "times": times},
           "body": {"shape": "sphere", "radius": 0.01}, "motion": {"velocity": [0.01, 0.0], "penetration": 2e-5},
           "time": {"mode": "steady"}}
    write_toml(tmp_path / "s.toml", raw)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code, _, err = cli_main(["run", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")])
    assert code == 2
    assert comm.rank or err.strip() == (f"petroll: error: {tmp_path / 's.toml'}: [material] times = {times!r}: must "
                                         f"differ: {shown}; merge terms of one time into one (add their {terms})")


def test_prony_times_a_billionth_apart_are_distinct_terms_equal_to_the_merged_one():
    """Times 1e-8 apart (above the 1e-9 refused): the creep compliance of the two terms is that of the one
    merged term (moduli added) within 1e-7: the conversion to creep form resolves them."""
    from petroll.model import materials

    two = materials.maxwell(2e6, 0.5, [1e6, 2e6], [1e-2, 1e-2 * (1 + 1e-8)])
    one = materials.maxwell(2e6, 0.5, [3e6], [1e-2])
    t = np.geomspace(1e-6, 1.0, 50)
    assert two(t) == pytest.approx(one(t), rel=1e-7)
