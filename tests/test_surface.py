"""The deformed surface (``Simulation.surface``): a Hertz step's displacement against the closed form
inside and outside the contact, the gap's contact conditions on a Hertz step and on a rolling viscoelastic
run (where the preceding displacement of the history is part of w)."""

import h5py
import numpy as np
import pytest

from petroll.model.scene import parse_scene
from petroll.solver.simulation import Simulation

E, NU, R, DELTA = 10e6, 0.3, 0.01, 25e-6


def gathered(comm, local: np.ndarray) -> np.ndarray:
    return np.concatenate(comm.allgather(local))


def hertz_sim(comm) -> Simulation:
    """A sphere pressed 25 um into an elastic half-space: a = 0.5 mm = 16 cells."""
    dx = 0.5e-3 / 16
    half = 49 * dx / 2
    scene = parse_scene({"grid": {"nx": 49, "ny": 49, "x": [-half, half], "y": [-half, half]},
                         "material": {"model": "elastic", "E": E, "nu": NU},
                         "body": {"shape": "sphere", "radius": R}, "motion": {"penetration": DELTA}},
                        source="test_surface")
    return Simulation(scene, comm)


def hertz_displacement(r: np.ndarray, a: float, p0: float, J: float) -> np.ndarray:
    """Hertz's surface displacement (m) under p0 sqrt(1 - r^2/a^2) (Johnson 1985, §3.4 and §4.2)."""
    outside = np.maximum(r, a)
    return np.where(r <= a, J * np.pi * p0 / (4 * a) * (2 * a * a - r * r),
                    J * p0 / (2 * a) * ((2 * a * a - r * r) * np.arcsin(a / outside)
                                         + a * np.sqrt(np.maximum(r * r - a * a, 0.0))))


def test_hertz_step_displacement_and_gap(comm):
    """a/dx = 16: w within 0.2 % of the penetration of Hertz's closed form inside and outside the contact
    (measured 3.1e-4 inside, 1.1e-3 outside); the gap vanishes where p > 0 (to 1e-6 of the penetration;
    measured 1e-9, the solver's tolerance) and is positive wherever p = 0, within 0.1 % of delta of
    Hertz's gap Z + w - delta there (measured 2.3e-4)."""
    sim = hertz_sim(comm)
    sim.step(0.0, 0.0)
    w, g = (gathered(comm, f) for f in sim.surface())
    assert_hertz_surface(w, g, gathered(comm, sim.pressure), sim.scene.grid.x, sim.scene.grid.y)


def assert_hertz_surface(w, g, p, x, y) -> None:
    """w and the gap g of hertz_sim's step (whole grid) against Hertz's closed form (tolerances above)."""
    x, y = np.meshgrid(x, y, indexing="ij")
    r = np.hypot(x, y)
    J = (1 - NU**2) / E
    a = np.sqrt(R * DELTA)
    exact = hertz_displacement(r, a, 2 * a / (np.pi * J * R), J)
    inside = r <= a
    assert np.max(np.abs(w - exact)[inside]) < 1e-3 * DELTA
    assert np.max(np.abs(w - exact)[~inside]) < 2e-3 * DELTA
    assert np.max(np.abs(g[p > 0])) < 1e-6 * DELTA
    assert np.all(g[p == 0] > 0)
    body = R - np.sqrt(R * R - r * r)  # the sphere's height above its lowest point
    assert np.max(np.abs(g - (body + exact - DELTA))[p == 0]) < 1e-3 * DELTA


def test_rolling_gap_holds_the_contact_conditions_with_the_history(comm):
    """A sphere rolling on a standard linear solid: after 13 steps the saved w = J_eff A p + u (u from the
    whole history) closes the gap where p > 0 and leaves it >= 0 elsewhere; without u the gap under the
    contact would be off by the relaxed part of the displacement (checked: more than 10 % of delta)."""
    scene = parse_scene({
        "grid": {"nx": 40, "ny": 20, "x": [-0.8e-3, 2.4e-3], "y": [-0.8e-3, 0.8e-3]},
        "material": {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
        "body": {"shape": "sphere", "radius": 0.01},
        "motion": {"velocity": [0.05, 0.0], "penetration": 2e-5},
        "time": {"steps_per_cell": 1, "distance": 0.9e-3}}, source="test_surface")
    sim = Simulation(scene, comm)
    for record in sim.steps():
        pass
    assert record.step == 12
    w, g = (gathered(comm, f) for f in sim.surface())
    p = gathered(comm, sim.pressure)
    scale = 2e-5
    assert np.max(np.abs(g[p > 0])) < 1e-6 * scale
    assert g.min() > -1e-6 * scale
    compliance = sim.history.compliance(record.t - sim.records[-2].t)  # the step's J_eff
    own = gathered(comm, sim.solver.influence.window(40, 20)(compliance * sim.pressure))
    assert np.max(np.abs(own - w)[p > 0]) > 0.1 * scale


@pytest.mark.slow
def test_saved_displacement_and_gap_fields_in_results_xdmf_and_plot(comm, shared_dir):
    """[output] fields = ["displacement", "gap"]: results.h5 holds fields/displacement and fields/gap (m,
    the layout of fields/pressure, pressure saved too) equal to Hertz's closed form as in the test above
    (the same tolerances), results.xdmf lists the three fields, and petroll plot draws surface.png."""
    import xml.etree.ElementTree as ET

    from petroll.driver import run
    from petroll.plot import plot_results

    raw = hertz_sim(comm).scene.raw
    raw["output"] = {"fields": ["gap", "displacement"]}
    results = run(parse_scene(raw, source="test_surface"), comm, shared_dir)
    assert results.fields == ("pressure", "displacement", "gap")
    w, g, p = (results.field(name)[-1] for name in ("displacement", "gap", "pressure"))
    assert w.shape == g.shape == p.shape == (49, 49)
    assert_hertz_surface(w, g, p, results.x, results.y)
    if comm.rank != 0:
        return
    with h5py.File(shared_dir / "results.h5", "r") as f:
        assert f["fields/displacement"].attrs["units"] == f["fields/gap"].attrs["units"] == "m"
    root = ET.parse(shared_dir / "results.xdmf").getroot()
    names = [a.get("Name") for a in root.findall("./Domain/Grid/Grid")[-1].findall("Attribute")]
    assert names == ["pressure", "displacement", "gap"]
    written = plot_results(shared_dir)
    surface = shared_dir / "plots" / "surface.png"
    assert surface in written and surface.stat().st_size > 0


def test_unknown_output_field_is_refused_naming_the_key():
    import pytest

    from petroll.errors import SceneError

    raw = {"grid": {"nx": 8, "ny": 8, "x": [-1e-3, 1e-3], "y": [-1e-3, 1e-3]},
           "material": {"model": "elastic", "E": E, "nu": NU}, "body": {"shape": "sphere", "radius": R},
           "motion": {"penetration": DELTA}, "output": {"fields": ["pressure", "strain"]}}
    with pytest.raises(SceneError, match=r"\[output\] fields.*'displacement', 'gap'"):
        parse_scene(raw, source="test_surface")
