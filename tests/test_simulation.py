"""The public time loop ``Simulation.steps``: its clock, its stops and its step limit, against the
arithmetic of the scene's [time] section and against steps taken one by one with ``Simulation.step``;
``Simulation.last_step`` against the last record of ``steps``."""

from dataclasses import replace

import pytest

from petroll.errors import SceneError
from petroll.model.scene import parse_scene
from petroll.solver.simulation import Simulation

RAW = {  # 16 x 16 cells, an SLS sphere
    "grid": {"nx": 16, "ny": 16, "x": [-1e-3, 1e-3], "y": [-1e-3, 1e-3]},
    "material": {"model": "sls", "E0": 1e7, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
    "body": {"shape": "sphere", "radius": 0.01},
    "motion": {"penetration": 2e-5},
    "solver": {"tol": 1e-9},
}


def scene(**time):
    return parse_scene({**RAW, "time": time} if time else RAW, source="test")


def test_steps_follow_the_clock_and_announce_the_last_step(comm):
    """dt = 0.01 s to end = 0.035 s: the sudden start, three whole steps and a last one of 0.005 s; while a
    record is out, sim.t is its time and sim.dt_next the next step's length (None after the last)."""
    sim = Simulation(scene(dt=0.01, end=0.035), comm)
    seen = [(record.t, sim.t, sim.dt_next) for record in sim.steps()]
    times = [0.0, 0.01, 0.02, 0.03, 0.035]
    assert [t for t, _, _ in seen] == pytest.approx(times, abs=1e-15)
    assert [t for _, t, _ in seen] == [t for t, _, _ in seen]
    assert [dt for _, _, dt in seen[:-1]] == pytest.approx([0.01, 0.01, 0.01, 0.005], abs=1e-15)
    assert seen[-1][2] is None
    assert [r.step for r in sim.records] == list(range(5))


def test_steps_are_the_steps_taken_one_by_one(comm):
    """The same pressures as Simulation.step called by hand with the same lengths (a second driver of the
    same integrator), and ``dts`` replaces the clock: a scene without [time] runs the given lengths."""
    dts = [0.004, 0.011, 0.02]
    looped = Simulation(scene(), comm)
    forces = [r.force for r in looped.steps(dts=dts)]
    by_hand, t = Simulation(scene(), comm), 0.0
    hand = [by_hand.step(0.0, 0.0).force]
    for dt in dts:
        t += dt
        hand.append(by_hand.step(t, dt).force)
    assert forces == hand  # bitwise: the same operations in the same order
    assert len(list(Simulation(scene(), comm).steps())) == 1  # no [time]: the single elastic step


def test_steps_stop_at_steady_state_and_refuse_more_than_max_steps(comm):
    """Rolling with [time] steady: the run is the same run without it cut at the first step whose force and
    resisting force changed by less than steady x force over one patch length (criterion of
    docs/design.md, "Rolling", evaluated here on the uncut run); a run needing more than [time] max_steps
    steps raises SceneError naming the key."""
    rolling = dict(RAW, grid={"nx": 48, "ny": 16, "x": [-1e-3, 5e-3], "y": [-1e-3, 1e-3]},
                   motion={"penetration": 2e-5, "velocity": [0.01, 0.0]})
    tol = 1e-3
    full = list(Simulation(parse_scene({**rolling, "time": {"steps_per_cell": 1, "distance": 3.5e-3}},
                                       source="test"), comm).steps())
    cut = list(Simulation(parse_scene({**rolling, "time": {"steps_per_cell": 1, "distance": 3.5e-3,
                                                           "steady": tol}}, source="test"), comm).steps())

    def settled(n):
        now = full[n]
        then = [r for r in full[1:n] if r.distance <= now.distance - (now.lead - now.trail)]
        return bool(then) and all(abs(a - b) <= tol * now.force for a, b in (
            (now.force, then[-1].force), (now.mu_r * now.force, then[-1].mu_r * then[-1].force)))

    first = next(n for n in range(2, len(full)) if settled(n))
    assert first < len(full) - 5  # the stop saves steps on this track
    assert [r.force for r in cut] == [r.force for r in full[: first + 1]]
    with pytest.raises(SceneError, match=r"\[time\] max_steps"):
        for _ in Simulation(parse_scene({**rolling, "time": {"steps_per_cell": 1, "distance": 3.5e-3,
                                                             "max_steps": 3}}, source="test"), comm).steps():
            pass


@pytest.mark.slow
@pytest.mark.parametrize("motion", [{"penetration": 2e-5, "velocity": [0.01, 0.0]},
                                    {"load": 0.04, "velocity": [0.008, 0.006]}])
def test_the_last_step_alone_is_the_last_record_of_the_steps(comm, motion):
    """Simulation.last_step (diagnostics at the last step only, what the error estimate reads) against the
    whole run's last record from Simulation.steps: the same record, field by field and bitwise (the same
    operations in the same order), but for its wall time, under penetration and load control (the
    penetration guessed from the step before's) and along a slanting path (the distance summed step by
    step); it keeps no records, and refuses a run needing more than [time] max_steps steps."""
    rolling = dict(RAW, grid={"nx": 40, "ny": 24, "x": [-1e-3, 4e-3], "y": [-1e-3, 2e-3]}, motion=motion)
    scene = parse_scene({**rolling, "time": {"steps_per_cell": 1, "distance": 2.2e-3}}, source="test")
    whole = list(Simulation(scene, comm).steps())
    alone = Simulation(scene, comm)
    last = alone.last_step()
    assert len(whole) > 10 and alone.records == [] and (alone.t, alone.dt_next) == (whole[-1].t, None)
    assert replace(last, solve_time=0.0) == replace(whole[-1], solve_time=0.0)
    limited = replace(scene, time=replace(scene.time, max_steps=3))  # past the scene's own check of it
    with pytest.raises(SceneError, match=r"\[time\] max_steps = 3: the run needs more steps"):
        Simulation(limited, comm).last_step()
