"""The Python API: a scene built in Python runs exactly as the same scene written as TOML and run by the
command line; the steady-state convenience values of Results agree with the series."""

import math

import numpy as np
import pytest

import petroll
from petroll.errors import SceneError
from compare import assert_close

RAW = {
    "grid": {"nx": 40, "ny": 16, "x": [-0.8e-3, 3.2e-3], "y": [-0.8e-3, 0.8e-3]},
    "material": {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
    "body": {"shape": "sphere", "radius": 0.01},
    "motion": {"velocity": [0.01, 0.0], "penetration": 2e-5},
    "time": {"steps_per_cell": 1, "distance": 2.4e-3, "steady": 1e-3},
    "solver": {"tol": 1e-9},
    "output": {"every": 5},
}


@pytest.mark.slow
def test_a_scene_built_in_python_runs_exactly_as_its_toml_through_the_command_line(comm, api_and_cli):
    api, cli, out = api_and_cli(RAW)
    if comm.rank == 0:
        assert "steady state reached" in out
    assert set(api.series) == set(cli.series)
    assert len(api.series["t"]) > 5
    for name in api.series:  # two runs of one scene: equal to round-off (floats are never compared by ==)
        if name != "solve_time":  # wall time
            assert_close(api.series[name], cli.series[name], 1e-12, name)
    assert_close(api.pressure, cli.pressure, 1e-12, "pressure")
    assert np.array_equal(api.field_steps, cli.field_steps)
    assert_close(api.x, cli.x, 1e-15, "x")
    assert_close(api.y, cli.y, 1e-15, "y")
    assert api.scene_text == cli.scene_text == petroll.parse_scene(RAW).text
    assert api.steady == cli.steady


@pytest.mark.slow
def test_steady_values_agree_with_the_series_and_survive_reopening(comm, shared_dir):
    results = petroll.run(petroll.parse_scene(RAW), comm, out=shared_dir / "run")
    s, st = results.series, results.steady
    assert isinstance(st, petroll.SteadyState)
    assert (st.force, st.mu_r, st.delta, st.area, st.lead, st.trail, st.p_max) == tuple(
        float(s[name][-1]) for name in ("force", "mu_r", "delta", "area", "lead", "trail", "p_max"))
    assert (st.step, st.t, st.distance) == (len(s["t"]) - 1, s["t"][-1], s["distance"][-1])
    # stopped on [time] steady before the 2.4 mm it could roll
    assert st.reached and st.distance < 2.4e-3 * 0.9
    # the change over the last contact length, computed here directly from the series
    window = s["lead"][-1] - s["trail"][-1]
    assert st.window == pytest.approx(window, rel=1e-12) and window > 0
    back = int(np.flatnonzero(s["distance"] <= s["distance"][-1] - window * (1 - 1e-9))[-1])
    assert 0 < back < len(s["t"]) - 1
    force, mu_r = s["force"], s["mu_r"]
    assert st.force_change == pytest.approx(abs(force[-1] - force[back]) / force[-1], rel=1e-12)
    assert st.mu_r_change == pytest.approx(abs(mu_r[-1] - mu_r[back]) / abs(mu_r[-1]), rel=1e-12)
    resisting = abs(s["mu_r"][-1] * s["force"][-1] - s["mu_r"][back] * s["force"][back]) / s["force"][-1]
    assert st.resisting_change == pytest.approx(resisting, rel=1e-12)
    assert st.converged(1e-3) and not st.converged(st.force_change / 2)
    assert st.mu_r > 0.005  # near the peak (V tau/a = 1.1): a real rolling resistance
    assert petroll.Results.open(results.path).steady == st  # the same values from the file
    # a run that does not roll: the final values, no convergence measure, not "reached"
    still = petroll.run(petroll.parse_scene({**RAW, "motion": {"penetration": 2e-5}, "time": {
        "dt": 0.01, "end": 0.03, "steady": 1e-3}}), comm, out=shared_dir / "still").steady
    assert math.isnan(still.force_change) and math.isnan(still.mu_r_change) and not still.reached
    assert not still.converged(1.0)


def test_scene_replace_gives_a_validated_copy():
    scene = petroll.parse_scene(RAW)
    faster = scene.replace("motion.velocity", [0.02, 0.0])
    assert float(faster.velocity(0.0)[0]) == 0.02 and float(scene.velocity(0.0)[0]) == 0.01
    load = scene.replace({"motion.penetration": None, "motion.load": 0.05})
    assert load.penetration is None and float(load.load(0.0)) == 0.05
    with pytest.raises(SceneError, match=r"\[motion\] penetration / load"):
        scene.replace("motion.load", 0.05)
