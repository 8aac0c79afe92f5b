"""[grid] target_error (petroll.studies.target, docs/accuracy.md): the grid a pilot chooses against Hertz's
closed form on an elastic sphere (its error at most the target, finer for a tighter one), the choice
printed and stored in results.h5, and the refusals."""

import math
import pathlib
import tomllib

import pytest

import petroll
from petroll.errors import SceneError
from petroll.model.scene import dumps, load_scene, parse_scene
from petroll.solver.simulation import Simulation
from petroll.studies.sweep import sweep
from petroll.studies.target import PILOT_CELLS, asks_target, targeted

E, NU, R, F = 1e7, 0.5, 0.01, 0.2
E_STAR = E / (1 - NU**2)
A = (3 * F * R / (4 * E_STAR)) ** (1 / 3)  # Hertz: contact radius, penetration, peak pressure
DELTA, P0 = A * A / R, 3 * F / (2 * math.pi * A * A)
RAW = {"material": {"model": "elastic", "E": E, "nu": NU}, "body": {"shape": "sphere", "radius": R},
       "motion": {"velocity": [0.0, 0.0], "load": F}, "solver": {"tol": 1e-10}}


def with_target(target, **motion):
    return parse_scene({**RAW, "motion": {"velocity": [0.0, 0.0], **(motion or {"load": F})},
                        "grid": {"target_error": target}})


@pytest.mark.parametrize("motion", [{"load": F}, {"penetration": DELTA}], ids=["load", "penetration"])
def test_the_chosen_grid_meets_the_target_against_hertz(comm, motion):
    """Hertz's penetration (load control) or force (penetration control) and peak pressure: the run on the
    grid chosen is within each target (the sphere's own surface departs from Hertz's paraboloid by about
    (a/R)^2 / 10 = 2e-4 of the penetration, below the tightest target), and a tighter target gets more cells
    (measured: 8, 10-11, 20-22 per half-width; errors 1e-4 to 1.7e-3)."""
    cells = []
    for target in (1e-2, 2e-3, 5e-4):
        scene = with_target(target, **motion)
        assert asks_target(scene) and scene.grid.dx == pytest.approx(A / PILOT_CELLS, rel=0.05)  # the pilot's
        chosen = targeted(scene, comm)
        assert not asks_target(chosen)
        cells.append(A / chosen.grid.dx)
        record = Simulation(chosen, comm).last_step()
        headline = (record.delta / DELTA if "load" in motion else
                    record.force / (4 / 3 * E_STAR * math.sqrt(R) * DELTA**1.5))
        assert abs(headline - 1) <= target and abs(record.p_max / P0 - 1) <= target, (target, cells[-1])
    assert cells[0] < cells[1] < cells[2] and cells[0] == pytest.approx(8, rel=0.05)  # 8: the least


def test_the_run_prints_and_stores_the_choice(shared_dir, comm, cli_main):
    if comm.rank == 0:
        (shared_dir / "target.toml").write_text(dumps({**RAW, "grid": {"target_error": 2e-3}}), encoding="utf-8")
    comm.Barrier()
    code, out, err = cli_main(["run", str(shared_dir / "target.toml"), "--out", str(shared_dir / "cli"),
                               "--quiet"])
    assert code == 0 and err == ""
    text = petroll.Results.open(shared_dir / "cli" / "results.h5").scene_text
    head = text.splitlines()[0]
    assert head.startswith("# [grid] target_error = 0.002: ") and "predicted relative errors delta " in head
    cells = int(head.split(": ")[1].split(" cells")[0])
    grid = tomllib.loads(text)["grid"]
    assert "target_error" not in grid and (grid["x"][1] - grid["x"][0]) / grid["nx"] == pytest.approx(
        A / cells, rel=0.05)
    if comm.rank == 0:
        assert out.startswith(f"petroll: {shared_dir / 'target.toml'}: [grid] sized by petroll: ")
        assert f"target_error = 0.002: {cells} cells per contact half-width" in out
    api = petroll.run(with_target(2e-3), comm, out=shared_dir / "api")  # the API runs the pilot too
    assert api.scene_text == text
    scene = load_scene(shared_dir / "target.toml")
    assert targeted(scene, comm).output_dir == scene.output_dir == pathlib.Path("results/target")


def test_a_sweep_chooses_each_point_s_grid_and_keeps_finished_points(shared_dir, comm):
    """Each point's results.h5 holds its own choice; a sweep run again finds its points finished (their
    text as run is the targeted scene's), and solves none."""
    scene = with_target(2e-3)
    first = sweep(scene, "motion.load=0.05,0.2", shared_dir / "sweep", comm, plot=False)
    assert first.computed == [0, 1]
    for point in first.points:
        text = petroll.Results.open(shared_dir / "sweep" / point / "results.h5").scene_text
        assert text.startswith("# [grid] target_error = 0.002: ")
    again = sweep(scene, "motion.load=0.05,0.2", shared_dir / "sweep", comm, plot=False)
    assert again.computed == []
    assert again.columns["force"] == pytest.approx(first.columns["force"], rel=1e-12)


@pytest.mark.parametrize("grid, key, says", [
    ({"target_error": 0.01, "cells_per_half_width": 16}, "[grid] target_error / cells_per_half_width", "give one"),
    ({"target_error": 0.01, "nx": 10, "ny": 10, "x": [-1e-3, 1e-3], "y": [-1e-3, 1e-3]}, "[grid] target_error",
     "without [grid] nx"),
    ({"target_error": 0}, "[grid] target_error", "> 0"),
    ({"target_error": True}, "[grid] target_error", "> 0"),
])
def test_conflicting_or_bad_targets_are_refused_in_one_line(grid, key, says):
    with pytest.raises(SceneError) as info:
        parse_scene({**RAW, "grid": grid})
    message = str(info.value)
    assert key in message and says in message and "\n" not in message


def test_a_target_beyond_256_cells_is_refused_naming_the_cells_needed(shared_dir, comm, cli_main):
    """1e-6: the peak pressure's error at 16 cells (about 1e-3) needs about 16 sqrt(1000) = 500."""
    with pytest.raises(SceneError) as info:
        targeted(with_target(1e-6), comm)
    message = str(info.value)
    needed = int(message.split("needs ")[1].split(" cells")[0])
    assert 300 < needed < 1000 and "more than 256" in message and "\n" not in message
    if comm.rank == 0:
        (shared_dir / "fine.toml").write_text(dumps({**RAW, "grid": {"target_error": 1e-6}}), encoding="utf-8")
    comm.Barrier()
    code, out, err = cli_main(["run", str(shared_dir / "fine.toml"), "--out", str(shared_dir / "fine"), "--quiet"])
    assert code == 2 and out == ""
    if comm.rank == 0:
        assert "[grid] target_error" in err and f"needs {needed} cells" in err and len(err.splitlines()) == 1
