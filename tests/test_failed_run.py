"""A run that fails mid-way (issue 24, item 3): one line naming the scene file, the step, its time and the
distance rolled, where results.h5 (every step solved before the failure, complete = false) and the last
checkpoint are; the summary printed before it says the run is partial. Oracle: the same scene run to a
distance it can reach, whose steps are the failed run's first ones."""

import numpy as np
import pytest

import petroll
from petroll.driver import RunFailed
from petroll.errors import SceneError
from petroll.model.scene import dumps, load_scene, shipped_scene


def sphere(**changes):
    return load_scene(shipped_scene("sphere.toml")).replace({"time.steady": None, "output.every": None,
                                                            **changes})


@pytest.mark.slow
def test_a_contact_reaching_the_edge_mid_run_keeps_every_step_solved(comm, shared_dir, cli_main, monkeypatch):
    """runs/sphere.toml rolled 10 mm on its 6 mm grid, the check before step 1 bypassed (as where its
    estimate misses): the solver stops at the edge; results.h5 holds all 119 steps (a run without [output]
    every), the same as a run to 4 mm holds (its 108 steps but the last, shortened to land on 4 mm), and the checkpoint of step 100 is named."""
    far = sphere(**{"time.distance": 10e-3, "output.checkpoint_every": 50})
    if comm.rank == 0:
        (shared_dir / "far.toml").write_text(dumps(far.raw))
    comm.Barrier()
    monkeypatch.setattr("petroll.driver.check_run", lambda scene: None)
    out = shared_dir / "far"
    code, stdout, err = cli_main(["run", str(shared_dir / "far.toml"), "--out", str(out), "--quiet"])
    assert code == 2
    if comm.rank == 0:
        lines = err.strip().splitlines()
        assert len(lines) == 1, err
        assert lines[0].startswith(f"petroll: error: {shared_dir / 'far.toml'}: step 119 (t = 0.44625 s, "
                                   "0.004425 m rolled) failed: [grid]: the contact region")
        assert (f"{out / 'results.h5'} holds the 119 steps solved before it (complete = false); last "
                f"checkpoint: {out / 'checkpoints' / 'step-00000100.h5'}") in lines[0]
        assert "partial" in stdout and "nan" not in stdout
    kept = petroll.Results.open(out / "results.h5")
    assert not kept.complete and len(kept.series["t"]) == 119
    assert (out / "checkpoints" / "step-00000100.h5").is_file()
    reference = petroll.run(sphere(), comm, out=shared_dir / "reference")
    for name in ("t", "sx", "force", "mu_r", "area", "p_max"):
        np.testing.assert_allclose(kept.series[name][:107], reference.series[name][:107], rtol=1e-12, atol=0)


def test_a_run_beyond_max_steps_is_refused_or_keeps_its_steps(comm, shared_dir):
    """runs/sphere-sinusoidal.toml (speed varying in time) rolled 0.5 mm needs 18 steps; with [time]
    max_steps = 15 it passes the scene's own check (distance / (peak speed x dt) = 13.9 steps at least), and
    the clock walked before step 1 refuses it, naming the key: it would stop unfinished. runs/sphere.toml
    to [time] end = 0.4 s (107 steps) with max_steps = 30 (1.1 mm of rolling, more than the 0.89 mm contact length its [time] steady stop
    needs, which comes at step 53) may stop early, so it runs, and stops mid-way: RunFailed naming the key
    after the 31 steps solved (steps 0-30), all in results.h5, complete = false."""
    scene = load_scene(shipped_scene("sphere-sinusoidal.toml")).replace(
        {"time.end": None, "time.distance": 0.5e-3, "time.max_steps": 15, "output.every": None})
    with pytest.raises(SceneError, match=r"\[time\] max_steps = 15: the run to \[time\] distance = 0.0005 m with "
                       r"\[time\] dt = 0.002 takes more steps .* unfinished"):
        petroll.run(scene, comm, out=shared_dir / "refused")
    assert not (shared_dir / "refused" / "results.h5").exists()
    scene = load_scene(shipped_scene("sphere.toml")).replace(
        {"time.distance": None, "time.end": 0.4, "time.max_steps": 30, "output.every": None})
    with pytest.raises(RunFailed, match=r"step 31 .* \[time\] max_steps .* holds the 31 steps") as info:
        petroll.run(scene, comm, out=shared_dir / "capped")
    assert info.value.steps == 31 and info.value.checkpoint is None
    kept = petroll.Results.open(shared_dir / "capped" / "results.h5")
    assert not kept.complete and len(kept.series["t"]) == 31


def creeping_scene(**changes):
    """A sphere (R = 10 mm) held at rest under 0.1 N on an SLS (E0 = 10 MPa, Einf = 2 MPa, creep time
    50 ms), 10 ms steps: its contact grows from Hertz's glassy radius 0.38 mm to the rubbery 0.66 mm, and
    the 1.3 mm grid holds the glassy interference (0.54 mm) but not the rubbery contact."""
    raw = {"grid": {"nx": 42, "ny": 42, "x": [-0.65625e-3, 0.65625e-3], "y": [-0.65625e-3, 0.65625e-3]},
           "material": {"model": "sls", "E0": 1e7, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
           "body": {"shape": "sphere", "radius": 0.01}, "motion": {"load": 0.1},
           "time": {"dt": 0.01, "end": 0.3}}
    return petroll.parse_scene(raw, source="creep.toml").replace(changes) if changes else \
        petroll.parse_scene(raw, source="creep.toml")


def test_a_load_controlled_contact_that_creeps_to_the_edge_warns_then_stops_keeping_its_steps(comm, shared_dir):
    """The check before step 1 warns that the creeping contact may reach the edge (the glassy one fits: not
    refused); the run stops where it does, with every step solved before in results.h5 (complete = false),
    the same as the same scene on a grid wide enough (2 mm across, the same cells) holds for them (the
    domain does not enter a half-space's answer: to the solver's tolerance)."""
    from petroll.model.limits import PetrollWarning

    with pytest.warns(PetrollWarning, match=r"as the contact creeps under the load .*rubbery estimate"):
        with pytest.raises(RunFailed, match=r"creep.toml: step (\d+) .* reaches the grid edge") as info:
            petroll.run(creeping_scene(), comm, out=shared_dir / "creep")
    steps = info.value.steps
    assert 2 <= steps < 30
    kept = petroll.Results.open(shared_dir / "creep" / "results.h5")
    assert not kept.complete and len(kept.series["t"]) == steps
    wide = creeping_scene(**{"grid.nx": 64, "grid.ny": 64, "grid.x": [-1e-3, 1e-3], "grid.y": [-1e-3, 1e-3]})
    # (cells of 31.25 um in both, their centres at the same places around the body)
    reference = petroll.run(wide, comm, out=shared_dir / "wide")
    assert reference.complete and len(reference.series["t"]) == 31
    np.testing.assert_allclose(kept.series["delta"], reference.series["delta"][:steps], rtol=1e-6)
