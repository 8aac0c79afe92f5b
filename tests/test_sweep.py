"""petroll sweep: the --vary forms, a small sweep's table and plot, resuming without recomputation
(finished points, and a point interrupted mid-run), and bad specifications as one line with exit 2."""

import csv
import pathlib

import h5py
import numpy as np
import pytest

import petroll
from petroll.errors import SceneError
from petroll.model.clock import TimeMode
from petroll.model.scene import dumps
from petroll.studies.sweep import (COLUMNS, DEFAULT_STEADY, SweepError, SweepInterrupted, SweepTable, Vary,
                           parse_vary, point_scene, sweep)

RAW = {  # a/dx = 4.5: tiny, each point a few tenths of a second
    "grid": {"nx": 40, "ny": 16, "x": [-0.8e-3, 3.2e-3], "y": [-0.8e-3, 0.8e-3]},
    "material": {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
    "body": {"shape": "sphere", "radius": 0.01},
    "motion": {"velocity": [0.003, 0.004], "penetration": 2e-5},  # |V| = 5 mm/s, direction (0.6, 0.8)
    "time": {"steps_per_cell": 1, "distance": 1.6e-3},  # no steady: the sweep adds it
    "solver": {"tol": 1e-9},
}
RAW_X = {**RAW, "motion": {"velocity": [0.005, 0.0], "penetration": 2e-5},
         "time": {"steps_per_cell": 1, "distance": 2.4e-3}}
SPEEDS = (0.002, 0.005, 0.01)


def test_vary_forms():
    assert parse_vary("material.tau_relax=0.001,0.01,0.1") == Vary("material.tau_relax", (0.001, 0.01, 0.1),
                                                                   "material.tau_relax=0.001,0.01,0.1")
    log = parse_vary("motion.velocity=1e-4..1e-1:log:4")
    assert log.key == "motion.velocity" and log.values == pytest.approx((1e-4, 1e-3, 1e-2, 1e-1), rel=1e-12)
    assert log.values[0] == 1e-4 and log.values[-1] == 1e-1  # the ends exactly as written
    assert parse_vary("motion.penetration = 1e-5..3e-5:lin:3").values == pytest.approx((1e-5, 2e-5, 3e-5))
    assert parse_vary("grid.nx=16,32").values == (16.0, 32.0)


@pytest.mark.parametrize("spec, reason", [
    ("motion.velocity", "must be KEY=VALUES"),
    ("velocity=1,2", "section.key"),
    ("nothing.velocity=1,2", "unknown section [nothing]"),
    ("motion.velocity=abc", "numbers separated by commas"),
    ("motion.velocity=1,,2", "numbers separated by commas"),
    ("motion.velocity=1,1", "values must differ"),
    ("motion.velocity=1e-4..1e-1:log:1", "N >= 2"),
    ("motion.velocity=0..1e-1:log:5", "START > 0"),
    ("motion.velocity=1e-4..1e-1:geo:5", "START..STOP:log:N"),
    ("motion.velocity=1e-4..1e-1", "START..STOP:log:N"),
    ("motion.velocity=logspace(-3,1,9)*[1,0]", "numbers separated by commas"),
])
def test_bad_vary_specs_are_one_line(spec, reason):
    with pytest.raises(SweepError) as info:
        parse_vary(spec)
    message = str(info.value)
    assert "\n" not in message and reason in message and message.startswith(f"--vary {spec!r}: ")
    assert "KEY=START..STOP:log:N" in message  # says what is allowed


def test_point_scenes_vary_vectors_along_their_direction_and_drop_exclusive_keys():
    scene = petroll.parse_scene(RAW)
    point = point_scene(scene, "motion.velocity", 0.01)
    assert np.allclose(point.velocity(0.0), [0.006, 0.008], rtol=1e-14)
    assert point.time.steady == DEFAULT_STEADY and scene.time.steady is None
    load = point_scene(scene, "motion.load", 0.05)
    assert load.penetration is None and float(load.load(0.0)) == 0.05
    with pytest.raises(SweepError, match="not an integer"):
        point_scene(scene, "grid.nx", 40.5)
    assert point_scene(scene, "grid.nx", 44.0).grid.nx == 44
    ramp = scene.replace("motion.velocity", {"kind": "ramp", "start": [0.0, 0.0], "end": [0.01, 0.0],
                                             "duration": 0.1})
    with pytest.raises(SweepError, match="as a program"):
        point_scene(ramp, "motion.velocity", 0.01)
    still = scene.replace({"motion.velocity": [0.0, 0.0], "time.distance": None, "time.end": 0.1})
    with pytest.raises(SweepError, match="no direction"):
        point_scene(still, "motion.velocity", 0.01)


def _mtimes(directory: pathlib.Path) -> dict[str, int]:
    return {p.parent.name: p.stat().st_mtime_ns for p in sorted(directory.glob("points/*/results.h5"))}


@pytest.mark.slow
def test_a_small_sweep_writes_its_table_and_plot_and_resumes_without_recomputing(comm, shared_dir):
    scene = petroll.parse_scene(RAW_X)
    out = shared_dir / "sweep"
    lines = []
    table = sweep(scene, "motion.velocity=0.002,0.005,0.01", out, comm, log=lines.append)
    assert table.computed == [0, 1, 2]
    assert table.csv.is_file() and table.h5.is_file() and table.png.stat().st_size > 10_000
    c = table.columns
    assert set(c) == {n for n in COLUMNS if not n.endswith("_error")} and all(len(v) == 3 for v in c.values())
    assert np.array_equal(c["value"], SPEEDS)
    a = np.sqrt(0.01 * 2e-5)
    # tau = 50 ms, the creep time (the loss peak of an SLS), found by a bounded search to 1e-10 in ln omega
    assert c["v_tau_a"] == pytest.approx(np.array(SPEEDS) * 0.05 / a, rel=1e-9)
    assert c["mu_r_slow"] == pytest.approx(np.array(SPEEDS) * 0.05 * 0.8 / 0.01, rel=1e-12)
    assert np.all(c["steady"] == 1) and np.all(c["distance"] < 2.4e-3 * 0.9)
    assert np.all(c["mu_r"] > 0.005) and np.all(c["mu_r"] < c["mu_r_slow"])
    assert np.all((c["force"] > c["force_Jinf"]) & (c["force"] < c["force_J0"]))
    for k, path in enumerate(table.points):  # each row is its point's Results.steady
        results = petroll.Results.open(out / path / "results.h5")
        assert results.steady.mu_r == c["mu_r"][k] and results.steady.force == c["force"][k]
        assert results.scene_text == point_scene(scene, "motion.velocity", SPEEDS[k]).text
    if comm.rank == 0:
        assert len(lines) == 3 and all("ran;" in line for line in lines)
        with open(table.csv, newline="") as fh:
            rows = list(csv.reader(fh))
        assert rows[0][0] == "motion.velocity (m/s)" and rows[0][2] == "mu_r (-)" and len(rows) == 4
        assert [float(r[2]) for r in rows[1:]] == pytest.approx(c["mu_r"], rel=1e-9)
        with h5py.File(table.h5, "r") as f:
            assert f["table/force"].attrs["units"] == "N" and f.attrs["key"] == "motion.velocity"
    reopened = SweepTable.open(out)
    assert all(np.array_equal(reopened.columns[n], c[n], equal_nan=True) for n in c) and set(reopened.columns) == set(c)

    before = comm.bcast(_mtimes(out) if comm.rank == 0 else None, root=0)
    assert len(before) == 3
    again = sweep(scene, "motion.velocity=0.002,0.005,0.01", out, comm, plot=False)
    assert again.computed == []  # nothing run again
    assert all(np.array_equal(again.columns[n], c[n], equal_nan=True) for n in c) and set(again.columns) == set(c)
    # a longer list runs only the new value; a changed scene runs every point again
    longer = sweep(scene, "motion.velocity=0.002,0.0035,0.005,0.01", out, comm, plot=False)
    assert longer.computed == [1]
    after = comm.bcast(_mtimes(out) if comm.rank == 0 else None, root=0)
    assert {k: after[k] for k in before} == before
    changed = sweep(scene.replace("solver.tol", 1e-10), "motion.velocity=0.002,0.005", out, comm, plot=False)
    assert changed.computed == [0, 1]


class StopAfter:
    """A stop request that comes after ``calls`` agreements (the run agrees once per step)."""

    def __init__(self, calls: int):
        self.calls = calls

    def agreed(self, comm) -> int:
        self.calls -= 1
        return 15 if self.calls < 0 else 0


@pytest.mark.slow
def test_an_interrupted_sweep_resumes_its_point_from_the_checkpoint(comm, shared_dir):
    scene = petroll.parse_scene(RAW_X)
    spec = "motion.velocity=0.002,0.01"
    with pytest.raises(SweepInterrupted) as info:  # point 1 runs 13 steps; stop in point 2's 6th step
        sweep(scene, spec, shared_dir / "cut", comm, stop=StopAfter(1 + 13 + 1 + 6), plot=False, transient=True)
    assert info.value.index == 1 and info.value.exit_code == 143 and "resumes" in str(info.value)
    point = shared_dir / "cut" / "points" / "motion.velocity=0.01"
    assert len(list((point / "checkpoints").glob("step-*.h5"))) == 1
    assert not petroll.Results.open(point / "results.h5").complete
    resumed = sweep(scene, spec, shared_dir / "cut", comm, plot=False, transient=True)
    assert resumed.computed == [1]
    whole = sweep(scene, spec, shared_dir / "whole", comm, plot=False, transient=True)
    cut = petroll.Results.open(point / "results.h5")
    full = petroll.Results.open(shared_dir / "whole" / "points" / "motion.velocity=0.01" / "results.h5")
    assert cut.complete and len(cut.series["t"]) == len(full.series["t"]) > 6
    for name in cut.series:
        if name != "solve_time":
            assert np.array_equal(cut.series[name], full.series[name]), name
    assert np.array_equal(resumed.columns["mu_r"], whole.columns["mu_r"])


@pytest.mark.slow
def test_a_constant_speed_sweep_solves_each_point_directly_from_its_neighbour(comm, shared_dir):
    """Each point of a sweep along X is the steady state solved directly ([time] mode = "steady", one
    step), started from the previous point's pressure: the same values as each point solved from scratch
    (to the fixed point's tolerance), in fewer operator applications; --transient runs them from rest."""
    from petroll.solver.simulation import Simulation

    shared = shared_dir
    scene = petroll.parse_scene({**RAW_X, "solver": {"tol": 1e-10}})
    spec = "motion.velocity=0.001,0.002,0.004"
    table = sweep(scene, spec, shared / "direct", comm, plot=False)
    assert list(table.columns["steps"]) == [1, 1, 1] and list(table.columns["steady"]) == [1, 1, 1]
    continued = alone = 0
    for k, speed in enumerate((0.001, 0.002, 0.004)):
        point = point_scene(scene, "motion.velocity", speed)
        assert point.time.mode is TimeMode.STEADY and point.time.steps_per_cell == 1 and point.time.distance is None
        record = Simulation(point, comm).solve_steady(tol=1e-10)
        assert table.columns["force"][k] == pytest.approx(record.force, rel=1e-8)
        assert table.columns["mu_r"][k] == pytest.approx(record.mu_r, rel=1e-7)
        results = petroll.Results.open(shared / "direct" / table.points[k] / "results.h5")
        continued += int(results.series["applications"][0])
        alone += record.applications
    assert continued < alone
    rolled = sweep(scene, spec, shared / "rolled", comm, plot=False, transient=True)
    assert all(rolled.columns["steps"] > 5)
    assert rolled.columns["mu_r"] == pytest.approx(table.columns["mu_r"], rel=0.05)  # [time] steady = 1e-3




@pytest.mark.slow
def test_a_sweep_varies_a_key_inside_an_inline_table(comm, shared_dir):
    """``material.layer.thickness``: each point is the scene with that thickness written in its TOML
    (parsed independently here), its unit is the thickness's (m), the layer's other keys are kept; keys
    that are no inline table's, or unknown inside one, are refused in one line naming them."""
    from petroll.solver.simulation import Simulation

    layered = {**RAW_X, "material": {**RAW_X["material"], "layer": {"thickness": 1e-3, "base": "bonded"}},
               "solver": {"tol": 1e-10}}
    scene = petroll.parse_scene(layered)
    table = sweep(scene, "material.layer.thickness=2e-4,5e-4", shared_dir / "layer", comm, plot=False)
    assert table.unit == "m" and list(table.columns["steps"]) == [1, 1]
    for k, h in enumerate((2e-4, 5e-4)):
        written = {**layered, "material": {**layered["material"], "layer": {"thickness": h, "base": "bonded"}},
                   "time": {"mode": "steady"}}
        record = Simulation(petroll.parse_scene(written), comm).solve_steady(tol=1e-10)
        assert table.columns["mu_r"][k] == pytest.approx(record.mu_r, rel=1e-7)
        assert table.columns["force"][k] == pytest.approx(record.force, rel=1e-8)
    assert table.columns["force"][0] > 1.2 * table.columns["force"][1]  # a thinner layer is stiffer
    with pytest.raises(SceneError) as info:  # a scene without the table: not made up from the one key
        scene.replace("material.layer", None).replace("material.layer.thickness", 1e-3)
    assert "the scene has no material.layer" in str(info.value)
    for key, reason in (("material.layer.depth", "[material] layer"), ("material.E0.x", "E0 is not a table"),
                        ("material..x", "section.key")):
        with pytest.raises(SceneError) as info:
            scene.replace(key, 1.0)
        assert reason in str(info.value) and "\n" not in str(info.value)


@pytest.mark.slow
def test_the_sweep_command_runs_and_refuses_bad_specs_in_one_line(comm, capsys, cli_main, shared_dir):
    if comm.rank == 0:
        (shared_dir / "scene.toml").write_text(dumps(RAW_X), encoding="utf-8")
    comm.Barrier()
    scene = str(shared_dir / "scene.toml")
    capsys.readouterr()
    code, out, err = cli_main(["sweep", scene, "--vary", "motion.velocity=0.005,0.01", "--out",
                           str(shared_dir / "cli"), "--quiet"])
    assert code == 0, err
    if comm.rank == 0:
        assert out.count("petroll: point ") == 2 and "sweep of motion.velocity over 2 values (2 run" in out
    assert (shared_dir / "cli" / "sweep.png").is_file()
    for argv, expected in [
        (["--vary", "motion.velocity=fast"], "petroll: error: --vary 'motion.velocity=fast': a list must "
                                             "hold"),
        (["--vary", "motion.velocity=1..2:log:0"], "petroll: error: --vary 'motion.velocity=1..2:log:0': a "
                                                   "range needs N >= 2"),
        (["--vary", "material.E0=1e6,-1"], "petroll: error: "),  # the scene refuses the value
        (["--vary", "motion.velocity=1,2", "--vary", "material.E0=1,2", "--vary", "motion.load=1,2"],
         "petroll: error: --vary given 3 times"),
        (["--vary", "motion.velocity=1,2", "--vary", "motion.velocity=3,4"], "petroll: error: --vary "
                                                                            "motion.velocity given twice"),
        (["--vary", "motion.velocity=1,2", "--vary", "material.E0=1e6,-1"], "petroll: error: "),
        (["--vary", "motion.velocity=1,2", "--vary", "material.E0=1e6,2e6", "--estimate-error"],
         "petroll: error: --estimate-error: with one --vary only"),
        ([], "petroll: error: the following arguments are required: --vary"),
    ]:
        code, out, err = cli_main(["sweep", scene, "--out", str(shared_dir / "bad"), *argv])
        assert code == 2
        if comm.rank == 0:
            lines = [line for line in err.splitlines() if line.strip()]
            assert len(lines) == 1 and lines[0].startswith(expected), (argv, lines)
        assert not (shared_dir / "bad" / "points").exists()


def test_a_family_is_one_sweep_per_value_of_its_second_key(comm, shared_dir):
    """petroll.studies.family.family: a curve over the speed at two penetrations, the second the sweep of
    the scene with that penetration (to round-off), family.csv their rows with the penetration first; the
    same key twice is refused in one line."""
    from petroll.studies.family import family

    scene = petroll.parse_scene(RAW_X)
    found = family(scene, "motion.velocity=0.002,0.01", "motion.penetration=1.5e-5,2e-5", shared_dir / "family",
                   comm, plot=False)
    assert found.values == (1.5e-5, 2e-5) and found.computed == 4
    alone = sweep(scene.replace("motion.penetration", 2e-5), "motion.velocity=0.002,0.01", shared_dir / "alone",
                  comm, plot=False)
    for name in ("force", "mu_r", "value"):
        a, b = found.tables[1].columns[name], alone.columns[name]
        assert np.abs(a - b).max() <= 1e-12 * np.abs(b).max(), name
    assert found.tables[1].columns["force"][0] > 1.3 * found.tables[0].columns["force"][0]
    if comm.rank == 0:
        rows = found.csv.read_text().splitlines()
        assert rows[0].startswith("motion.penetration (m),motion.velocity (m/s),force (N)") and len(rows) == 5
        assert [float(r.split(",")[0]) for r in rows[1:]] == [1.5e-5, 1.5e-5, 2e-5, 2e-5]
        assert float(rows[3].split(",")[2]) == pytest.approx(found.tables[1].columns["force"][0], rel=1e-9)
    with pytest.raises(SweepError, match=r"^--vary motion.velocity given twice; a family varies two different"):
        family(scene, "motion.velocity=1,2", "motion.velocity=3,4", shared_dir / "bad", comm)


def test_the_docs_name_every_table_column_and_steady_field():
    import dataclasses

    root = pathlib.Path(__file__).resolve().parents[1]
    sweep_doc = (root / "docs" / "sweep.md").read_text(encoding="utf-8")
    assert all(f"`{name}`" in sweep_doc for name in COLUMNS), [n for n in COLUMNS if f"`{n}`" not in sweep_doc]
    api_doc = (root / "docs" / "api.md").read_text(encoding="utf-8")
    fields = [f.name for f in dataclasses.fields(petroll.SteadyState)]
    assert all(f"`{name}`" in api_doc for name in fields), [n for n in fields if f"`{n}`" not in api_doc]
