"""Time resolution checked like space (issue 35; petroll.model.preflight, docs/accuracy.md): a step that
moves the body across too much of its contact is warned or refused, in transient, steady and sliding runs;
steps too fine for a steady sliding solve or a steady memory are refused naming the bound; negative
friction from a dissipative material is warned and kept in results.h5; a body placed outside its grid is
refused.

The oracle for each threshold is the same scene with a fine step (the answer the refused or warned step
gives against it): the refusals stand where the answer is off by more than 10 %, the warnings where it is
off by more than the ~1 % of the space check, and the value each message names gives an answer within it.
Refusals: one line on stderr, exit 2, nothing else printed before it, nothing written.
"""

import math
import warnings

import h5py
import numpy as np
import pytest

import petroll
from petroll.errors import SceneError
from petroll.model.limits import PetrollWarning
from petroll.model.preflight import check, check_run
from petroll.model.timestep import GOOD_STEPS, LEAST_STEPS
from petroll.model.scene import dumps, load_scene, parse_scene, shipped_scene
from petroll.solver.simulation import Simulation


def steady_sphere(**changes):
    """runs/sphere.toml solved directly (steady rolling; 11.9 cells per contact half-width)."""
    scene = load_scene(shipped_scene("sphere.toml"))
    return scene.replace({"time.mode": "steady", "time.distance": None, "time.steady": None,
                          "time.steps_per_cell": None, **changes})


def rough(n=32, **changes):
    """runs/rough-rubber.toml on n^2 cells with its short cut-off at 4 cells (the shipped ratio): steady
    sliding on a periodic grid, single contacts about a cell wide."""
    scene = load_scene(shipped_scene("rough-rubber.toml"))
    return scene.replace({"grid.nx": n, "grid.ny": n, "body.cutoff": 4 * 4e-3 / n, **changes})


def mu_r(scene, comm) -> float:
    """The steady state's mu_r (a direct solve: no preflight, the solver alone)."""
    return list(Simulation(scene, comm).steps())[-1].mu_r


def refused(cli_main, directory, scene, comm, verb="run") -> str:
    """``petroll VERB`` on the scene's TOML in ``directory`` (the same on every rank): exit 2 with one line
    on rank 0's stderr and nothing on stdout, nothing written; that line (on every rank)."""
    path = directory / "scene.toml"
    if comm.rank == 0:
        path.write_text(dumps(scene.raw), encoding="utf-8")
    comm.Barrier()
    code, out, err = cli_main([verb, str(path), "--out", str(directory / "out")] if verb == "run" else
                              [verb, str(path)])
    assert code == 2 and out == "", (code, out, err)
    if comm.rank == 0:
        assert err.count("\n") == 1 and err.startswith("petroll: error: "), err
    assert not (directory / "out" / "results.h5").exists()
    return comm.bcast(err, root=0)


def one_warning(caught, text: str) -> str:
    lines = [str(w.message) for w in caught if issubclass(w.category, PetrollWarning) and text in str(w.message)]
    assert len(lines) == 1, [str(w.message) for w in caught]
    return lines[0]


# -- steps per contact half-width ---------------------------------------------------------------------------
def test_steps_per_half_width_are_the_contacts_cells_at_one_step_per_cell():
    """runs/sphere.toml at 1 step per cell along X: the steps per half-width are Hertz's a = sqrt(R delta)
    over the cell (11.9); runs/sphere-sinusoidal.toml (dt = 2 ms, peak speed 18 mm/s): a / (18 mm/s x dt);
    a scene of one step has none."""
    a = math.sqrt(0.01 * 20e-6)
    found = check(load_scene(shipped_scene("sphere.toml"))).time
    assert found.cells == pytest.approx(1.0, rel=1e-12) and found.key == "[time] steps_per_cell"
    assert found.steps == pytest.approx(a / 37.5e-6, rel=2e-3)
    sinusoidal = check(load_scene(shipped_scene("sphere-sinusoidal.toml"))).time
    assert sinusoidal.steps == pytest.approx(a / (0.018 * 2e-3), rel=2e-3) and sinusoidal.key == "[time] dt"
    assert check(load_scene(shipped_scene("hertz.toml"))).time is None


@pytest.mark.serial
def test_petroll_check_prints_cells_per_step_and_the_verdict(cli_main, tmp_path):
    code, out, err = cli_main(["check", str(shipped_scene("sphere.toml"))])
    assert code == 0 and err == ""
    assert ("time step: 1 cells per step at most ([time] steps_per_cell = 1), 11.9 steps per contact "
            "half-width along the motion (estimated half-width 0.000447 m): at least 8, fine") in out
    path = tmp_path / "fast.toml"
    path.write_text(shipped_scene("sphere.toml").read_text().replace("steps_per_cell = 1", "steps_per_cell = 1e-9"))
    code, out, err = cli_main(["check", str(path)])
    assert code == 0 and "107 cells per step at most" in out and "a run is refused: gives 0.11 steps" in out


@pytest.mark.slow
def test_steady_rolling_steps_are_warned_and_refused_where_mu_r_is_off(comm, shared_dir, cli_main):
    """Steady runs/sphere.toml: 0.1 step per cell (1.2 steps per half-width) is refused, naming
    steps_per_cell and the value giving 8 steps (0.671); there mu_r is 37 % off the fine step's (16 per
    cell, the oracle: 2e-5 from its limit), 0.5 per cell (6 steps) is warned and 1.8 % off, the named
    value runs without a time warning and within 1.5 %, and the shipped 1 per cell within 0.5 %."""
    fine = mu_r(steady_sphere(**{"time.steps_per_cell": 16}), comm)
    err = refused(cli_main, shared_dir, steady_sphere(**{"time.steps_per_cell": 0.1}), comm)
    assert ("[time] steps_per_cell = 0.1: gives 1.2 steps per contact half-width along the motion (the body "
            "moves 10 cells per step; estimated half-width 0.000447 m); at least 2 are needed: steps_per_cell "
            ">= 0.671 gives 8, or set [time] allow_coarse = true to run anyway") in err
    with pytest.warns(PetrollWarning, match=r"0.1 gives 1.2 steps per contact half-width"):
        coarse = petroll.run(steady_sphere(**{"time.steps_per_cell": 0.1, "time.allow_coarse": True}), comm,
                             out=shared_dir / "coarse")
    assert abs(coarse.series["mu_r"][0] / fine - 1) > 0.1
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        warned = petroll.run(steady_sphere(**{"time.steps_per_cell": 0.5}), comm, out=shared_dir / "warned")
    assert "steps_per_cell = 0.5 gives 6 steps per contact half-width" in one_warning(caught, "steps_per_cell")
    assert 0.01 < abs(warned.series["mu_r"][0] / fine - 1) < 0.03
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        named = petroll.run(steady_sphere(**{"time.steps_per_cell": 0.671}), comm, out=shared_dir / "named")
    assert not [w for w in caught if "steps per contact" in str(w.message)]
    assert abs(named.series["mu_r"][0] / fine - 1) < 0.015
    assert abs(mu_r(steady_sphere(), comm) / fine - 1) < 0.005


@pytest.mark.slow
def test_a_transient_step_across_the_whole_track_is_refused_and_would_be_wrong(comm, shared_dir, cli_main):
    """runs/sphere.toml at steps_per_cell = 1e-9: one step rolls the whole 4 mm (107 cells, 0.11 steps per
    half-width): refused in one line; run anyway (allow_coarse) its mu_r is 1000 times too small against the
    shipped 1 step per cell's (itself within 0.4 % of 16 steps per cell, docs/accuracy.md)."""
    scene = load_scene(shipped_scene("sphere.toml"))
    err = refused(cli_main, shared_dir, scene.replace("time.steps_per_cell", 1e-9), comm)
    assert "[time] steps_per_cell = 1e-09: gives 0.11 steps per contact half-width" in err
    assert "steps_per_cell >= 0.671 gives 8" in err
    with pytest.warns(PetrollWarning, match="0.11 steps per contact half-width"):
        jump = petroll.run(scene.replace({"time.steps_per_cell": 1e-9, "time.allow_coarse": True}), comm,
                           out=shared_dir / "jump")
    assert len(jump.series["t"]) == 2
    shipped = Simulation(scene.replace("time.steady", None), comm).last_step().mu_r
    assert jump.series["mu_r"][-1] < 0.01 * shipped


@pytest.mark.slow
def test_steady_sliding_steps_are_refused_or_warned_against_the_single_contacts(comm, shared_dir, cli_main):
    """A rough surface sliding on 32^2 cells: its single contacts are about a cell wide (rms slope / rms
    curvature), so 1 step per cell (0.98 steps per contact) is refused, mu_r 15 % off the fine step's (64 per
    cell); the value named for 8 steps runs within 0.6 % of it."""
    fine = mu_r(rough(**{"time.steps_per_cell": 64}), comm)
    err = refused(cli_main, shared_dir, rough(**{"time.steps_per_cell": 1}), comm)
    assert "[time] steps_per_cell = 1.0: gives 0.98 steps per contact half-width" in err
    named = float(err.split("steps_per_cell >= ")[1].split()[0])
    assert 7 < named < 9
    assert abs(mu_r(rough(**{"time.steps_per_cell": 1}), comm) / fine - 1) > 0.1
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        results = petroll.run(rough(**{"time.steps_per_cell": named}), comm, out=shared_dir / "named")
    assert not [w for w in caught if "steps per contact" in str(w.message)]
    assert abs(results.series["mu_r"][0] / fine - 1) < 0.006


@pytest.mark.slow
def test_steps_too_fine_or_longer_than_the_grid_are_refused_naming_the_bound(comm, cli_main, shared_dir):
    """steps_per_cell = 2^63 - 1 sliding (a step of 1e-21 of the grid; issue 35: mu_r 5.9e-5 for 0.025) is
    refused naming the finest it takes, which runs within 1e-6 of 1e5 steps per cell (converged to 1e-9);
    1e-25 (a step 1e20 m long; a ValueError before) is refused even with allow_coarse, in steady rolling
    and sliding; a steady memory beyond 2^24 steps is refused naming that bound."""
    err = refused(cli_main, shared_dir, rough(**{"time.steps_per_cell": 2**63 - 1}), comm)
    assert "the steady sliding step moves the body" in err and "below 1e-10 of it the solve loses its digits" in err
    finest = float(err.split("steps_per_cell <= ")[1].split()[0])
    assert finest == pytest.approx(1e10 / 32, rel=1e-2)
    assert mu_r(rough(**{"time.steps_per_cell": finest}), comm) == pytest.approx(
        mu_r(rough(**{"time.steps_per_cell": 1e5}), comm), rel=1e-6)
    for scene in (steady_sphere(**{"time.steps_per_cell": 1e-25, "time.allow_coarse": True}),
                  rough(**{"time.steps_per_cell": 1e-25, "time.allow_coarse": True})):
        err = refused(cli_main, shared_dir, scene, comm)
        assert "[time] steps_per_cell = 1e-25: the body moves 1e+25 cells per step" in err
        assert "farther than the grid is long" in err
    err = refused(cli_main, shared_dir, steady_sphere(**{"time.steps_per_cell": 65536}), comm)
    assert "the steady memory would span 2.01e+07 steps" in err and "at most 16777216 are kept" in err


def test_the_time_thresholds_are_the_space_ones():
    assert (GOOD_STEPS, LEAST_STEPS) == (8, 2)


# -- negative friction --------------------------------------------------------------------------------------
@pytest.mark.slow
def test_coarse_steps_turn_the_lateral_force_negative_not_the_sliding_friction(comm, shared_dir):
    """The rough surface at 0.1 step per cell (allowed coarse): the lateral force's coefficient comes out
    -1.1e-3 where the fine step gives +1.8e-2, but the friction, from the material's dissipated power, is
    positive and draws no negative-friction warning; results.h5's attribute warnings holds the time step's
    alone (Results.warnings); an elastic material at that step dissipates nothing: mu_r 0."""
    scene = rough(**{"time.steps_per_cell": 0.1, "time.allow_coarse": True})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        results = petroll.run(scene, comm, out=shared_dir / "coarse")
    resolved = mu_r(rough(**{"time.steps_per_cell": 8}), comm)
    assert results.rough["mu_lateral"][0] == pytest.approx(-1.14e-3, rel=0.01)
    assert 0 < results.series["mu_r"][0] and 0.01 < resolved
    assert not [w for w in caught if "dissipative" in str(w.message)]
    assert len(results.warnings) == 1 and "steps per contact" in results.warnings[0]
    if comm.rank == 0:
        with h5py.File(shared_dir / "coarse" / "results.h5") as f:
            assert [w.decode() if isinstance(w, bytes) else w for w in f.attrs["warnings"]] == list(results.warnings)
    elastic = scene.replace({"material.model": "elastic", "material.E": 10e6, "material.moduli": None,
                             "material.times": None, "material.Einf": None, "material.series": None,
                             "material.temperature": None, "material.shift": None})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        plain = petroll.run(elastic, comm, out=shared_dir / "elastic")
    assert abs(plain.series["mu_r"][0]) < 1e-10 and abs(plain.rough["mu_lateral"][0]) > 1e-5
    assert not [w for w in caught if "dissipative" in str(w.message)]


# -- a body outside its grid -------------------------------------------------------------------------------
def test_a_body_placed_outside_its_grid_is_refused_by_check_and_run(cli_main, shared_dir, comm):
    """runs/hertz.toml's sphere at [1, 1] m, its grid +-0.8 mm (issue 35: "no contact, force 0", and check
    said the contact stays inside): one line naming [body] position, from check and run alike."""
    scene = load_scene(shipped_scene("hertz.toml")).replace("body.position", [1.0, 1.0])
    for verb in ("check", "run"):
        err = refused(cli_main, shared_dir, scene, comm, verb=verb)
        assert "[body] position = [1.0, 1.0]: the body lies outside the grid [-0.0008, 0.0008] x [-0.0008, " \
               "0.0008] m" in err and "more than the largest penetration 2e-05 m" in err
    with pytest.raises(SceneError, match=r"\[body\] position"):
        check(scene.replace({"motion.penetration": None, "motion.load": 0.02}))  # load control: the same


@pytest.mark.slow
def test_a_body_far_along_a_periodic_axis_is_its_image_on_the_grid(comm):
    """On a periodic grid a position 250 periods away is the body at the origin: not refused, the same
    steady sliding state (the oracle: the body at [0, 0])."""
    here = rough(**{"time.steps_per_cell": 8})
    far = here.replace("body.position", [1.0, 1.0])  # 250 periods of 4 mm
    check_run(far)
    a, b = (list(Simulation(s, comm).steps())[-1] for s in (here, far))
    assert b.force == pytest.approx(a.force, rel=1e-9) and b.mu_r == pytest.approx(a.mu_r, rel=1e-6)


def test_a_transient_whose_steps_would_not_finish_is_refused_naming_max_steps(cli_main, shared_dir, comm):
    """runs/sphere.toml to [time] end = 0.4 s at a million steps per cell (4e8 steps) with max_steps =
    1000: its [time] steady stop needs one contact length of rolling (0.89 mm) and the 1000 steps roll
    3.75e-8 m, so the run would stop at max_steps unfinished: refused before step 1, naming the bound."""
    scene = load_scene(shipped_scene("sphere.toml")).replace(
        {"time.distance": None, "time.end": 0.4, "time.steps_per_cell": 1e6, "time.max_steps": 1000})
    err = refused(cli_main, shared_dir, scene, comm)
    assert ("[time] max_steps = 1000: the run to [time] end = 0.4 s with [time] steps_per_cell = 1e+06 takes "
            "more steps (its clock walked: more than 1000); it would stop there unfinished") in err


def test_a_sweep_to_a_step_longer_than_the_grid_is_refused_naming_the_value_given(cli_main, shared_dir, comm):
    """``petroll sweep --vary time.steps_per_cell=1e-300,1`` on the steady sphere whose scene writes
    steps_per_cell = 1 (a TOML integer; issue 35: a ValueError, and a number key was rounded to 0 as if it
    were an integer one): one line naming 1e-300, exit 2."""
    path = shared_dir / "steady.toml"
    if comm.rank == 0:
        path.write_text(dumps({**steady_sphere().raw, "time": {"mode": "steady", "steps_per_cell": 1}}),
                        encoding="utf-8")
    comm.Barrier()
    code, out, err = cli_main(["sweep", str(path), "--vary", "time.steps_per_cell=1e-300,1", "--out",
                               str(shared_dir / "sweep"), "--quiet"])
    assert code == 2
    if comm.rank == 0:
        assert err.count("\n") == 1 and "[time] steps_per_cell = 1e-300: the body moves 1e+300 cells" in err, err


def test_negative_friction_is_warned_only_where_the_material_must_resist():
    """The warning's conditions (petroll.model.limits.negative_friction): a dissipative material moving at
    a steady state (a steady solve, or a transient at constant velocity and penetration) with mu_r below
    -1e-12; not an elastic material, a body at rest (its mu_r is the grid's alignment), a speed that
    varies (stored energy may push the body on), or round-off."""
    from petroll.model.limits import negative_friction

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)
        sphere = load_scene(shipped_scene("sphere.toml"))
        elastic = sphere.replace({"material.model": "elastic", "material.E": 10e6, "material.E0": None,
                                  "material.Einf": None, "material.tau_relax": None})
        rest = sphere.replace({"motion.velocity": [0.0, 0.0], "time.distance": None, "time.end": 0.1,
                               "time.steps_per_cell": None, "time.dt": 0.01, "time.steady": None})
        varying = load_scene(shipped_scene("sphere-sinusoidal.toml"))
    assert negative_friction(sphere, -1e-3).startswith(f"{sphere.source}: mu_r = -0.001 < 0 from a dissipative")
    assert negative_friction(steady_sphere(), -1e-3) is not None
    for scene, value in ((sphere, -1e-13), (sphere, 1e-3), (elastic, -1e-3), (rest, -1e-3), (varying, -1e-3)):
        assert negative_friction(scene, value) is None
