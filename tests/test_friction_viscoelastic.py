"""Viscoelastic friction (docs/friction.md#viscoelastic-bodies): the tangential creep function through the
normal problem's integrators, against exact creep, against the elastic limits of slow and fast rolling,
its scene keys, checkpoints and ranks.

Unmarked tests are collective (every rank under mpirun) and write into shared_dir.
"""

import copy
import math

import numpy as np
import pytest
from mpi4py import MPI

from petroll.driver import run
from petroll.errors import SceneError
from petroll.model import materials
from petroll.model.scene import parse_scene
from test_friction_scene import assert_restarts_bitwise

MU = 0.3
SLS = {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_creep": 0.05}
"""The rubber-like SLS of docs/master-curve.md: E0/Einf = 5, nu = 1/2, creep time tau = 50 ms."""


def scene_of(raw):
    return parse_scene(raw, source="test_friction_viscoelastic")


# -- the creep of a held shift: exact ------------------------------------------------------------------------

PRONY = materials.kelvin(2e6, 0.5, (2e-7, 1e-7), (0.01, 0.05))
"""A two-term Kelvin (Prony) series, E0/Einf = 2.5, retardation times tau/5 and tau."""


def held_shift(comm, integrator: str, steps_per_tau: int, material=None):
    """(the worst relative difference of the shift from J(t)/J0 times the first one's over 3 tau, the largest
    change of the tractions from the first step's, Pa, over mu p0): :func:`test_a_held_tangential_force_
    creeps_as_the_creep_function`'s run at steps of tau/``steps_per_tau``."""
    from petroll.solver.friction import ShearMemory, Stepping
    from petroll.solver.history import make_history
    from petroll.solver.tangential import TangentialSolver
    from test_tangential import hertz_grid, hertz_pressure, total

    material = material or materials.sls(SLS["E0"], SLS["Einf"], 0.5, SLS["tau_creep"])
    factor = 1 / (1 - 0.5)
    grid = hertz_grid(8)
    solver = TangentialSolver(grid, comm, 0.5, factor * material.Jinf, tol=1e-11)
    memory = ShearMemory(make_history(material, integrator, (solver.m, *solver.local_shape)), factor)
    stepping = Stepping(solver, memory=memory)
    p0 = 1e5
    p = hertz_pressure(grid, solver.r0, solver.r1, p0=p0)
    force = [-0.5 * MU * total(comm, p, grid), 0.0]
    first = stepping.shift(MU * p, force=force, dt=0.0)
    shift0, dt = stepping.shift_total[0], SLS["tau_creep"] / steps_per_tau
    assert shift0 > 0
    worst, moved = 0.0, 0.0
    for n in range(1, 3 * steps_per_tau + 1):
        solution = stepping.shift(MU * p, force=force, dt=dt)
        exact = float(material(n * dt)) / material.J0
        worst = max(worst, abs(stepping.shift_total[0] / shift0 / exact - 1))
        moved = max(moved, np.abs(solution.traction - first.traction).max(initial=0.0) / (MU * p0))
    return worst, moved


def test_a_held_tangential_force_creeps_as_the_creep_function(comm):
    """A rigid sphere on an SLS half-space (Hertz's pressure held), shifted at t = 0 by Q = mu P/2 (the
    instantaneous, Cattaneo problem with c = J0/(1 - nu)), then Q held: the tractions stay the first step's
    exactly (stick cells: K q uniform, so a larger compliance needs only a larger uniform shift; slip
    cells: the slip grows along the first step's) and the shift grows as J(t)/J0 (exact creep; J(3 tau)/J0
    = 4.8; and a two-term Prony series). The exponential integrator is exact for tractions constant within
    a step (to the solver's tolerance; measured 7e-16); the relaxation form (exact for a displacement
    linear within a step) to second order in dt (measured 6.1e-3 at tau/5, 1.6e-3 at tau/10)."""
    worst, moved = held_shift(comm, "exponential", 5)
    print(f"exponential: shift / creep function's, worst {worst:.2e}; tractions moved {moved:.1e} mu p0")
    assert worst <= 1e-7 and moved <= 1e-7
    worst, moved = held_shift(comm, "exponential", 5, PRONY)
    print(f"exponential, Prony: worst {worst:.2e}")
    assert worst <= 1e-7 and moved <= 1e-7
    coarse, _ = held_shift(comm, "relaxation", 5)
    fine, moved = held_shift(comm, "relaxation", 10)
    print(f"relaxation: worst {coarse:.2e} at tau/5, {fine:.2e} at tau/10")
    assert fine <= 2e-3 and coarse / fine > 3.5 and moved <= 1e-7


# -- slow and fast rolling: the elastic limits ------------------------------------------------------------

LIMITS = {1e-3: 5.8e-5, 1e3: 5.5e-3}
"""V tau/a: the measured largest relative difference of the traction curve from the elastic one (relaxed,
glassy modulus) at three creepages, 12 cells per glassy half-width (the fast limit's departure falls as
a/(V tau), docs/friction.md)."""


def line_rolling(material: dict, vtau: float, frac: float, cells: int = 12, lengths: float = 4.0) -> dict:
    """A rigid cylinder (R = 0.1 m) on a nu = 1/2 half-space of ``material`` under the load of a relaxed
    half-width a = 1 mm (docs/master-curve.md's V tau/a), rolling ``lengths`` a (to whole cells) from rest
    to x = 0 at V = vtau a/tau, one cell of a0/cells per step (a0 the glassy half-width), at the creepage
    -frac mu a0/R."""
    radius, a = 0.1, 1e-3
    jinf = 0.75 / SLS["Einf"]
    load = math.pi * a * a / (4 * radius * jinf)
    a0 = a * math.sqrt(SLS["Einf"] / SLS["E0"])
    h = a0 / cells
    distance = round(lengths * a / h) * h  # whole cells: every step one cell
    lo = -distance - 1.5 * a
    nx = int(round((1.5 * a - lo) / h))
    return {"grid": {"nx": nx, "x": [lo, lo + nx * h]}, "material": material,
            "body": {"shape": "cylinder", "radius": radius, "position": [-distance, 0.0]},
            "motion": {"load": load, "velocity": vtau * a / SLS["tau_creep"],
                       "creepage": -frac * MU * a0 / radius},
            "friction": {"coefficient": MU}, "time": {"steps_per_cell": 1, "distance": distance},
            "solver": {"tol": 1e-10}}


@pytest.mark.parametrize("vtau", sorted(LIMITS))
def test_slow_and_fast_rolling_tend_to_the_elastic_traction_curves(comm, shared_dir, vtau):
    """An SLS's traction curve (the creep force over mu P at three creepages, after rolling 4 a from rest)
    at V tau/a = 1e-3 is the elastic one with the relaxed modulus Einf, at 1e3 with the glassy E0, within
    1 % (measured: LIMITS): slow rolling relaxes within each step, fast rolling leaves no time to creep. The
    same runs' normal force and peak pressure agree too (the limits of formulation §7). Under the load of
    the relaxed contact the glassy one is sqrt(5) times narrower: the creepages are relative to it."""
    modulus = SLS["Einf"] if vtau < 1 else SLS["E0"]
    worst = 0.0
    for frac in (0.1, 0.3, 0.6):
        out = {}
        for name, material in (("sls", SLS), ("elastic", {"model": "elastic", "E": modulus, "nu": 0.5})):
            results = run(scene_of(line_rolling(material, vtau, frac)), comm, shared_dir / f"{name}-{frac}")
            s = results.series
            out[name] = (s["traction_x"][-1] / (MU * s["force"][-1]), s["p_max"][-1])
        worst = max(worst, abs(out["sls"][0] / out["elastic"][0] - 1))
        assert out["sls"][1] == pytest.approx(out["elastic"][1], rel=1e-2)
        assert out["elastic"][0] > 0.1 * frac  # a real creep force, not a vanishing one
    print(f"V tau/a = {vtau:g}: traction curve within {worst:.2e} of the elastic one")
    assert worst <= min(1e-2, 1.5 * LIMITS[vtau])


# -- scenes, checkpoints, ranks ---------------------------------------------------------------------------

E_HALF = 0.5 * (SLS["E0"] + SLS["Einf"])


def sphere(**motion) -> dict:
    """Two SLS bodies of one material (nu = 0.3): a sphere rolling 2 radii along X at V tau/a = 1, one cell
    per step, 6 cells per relaxed Hertz radius."""
    nu, radius, load = 0.3, 0.01, 1.0
    jinf = 2 * (1 - nu**2) / SLS["Einf"]
    a = (3 * load * radius * jinf / 4) ** (1 / 3)
    h = a / 6
    n = 18
    return {
        "grid": {"nx": 4 * n, "ny": n, "x": [-2.5 * n * h, 1.5 * n * h], "y": [-n * h / 2, n * h / 2]},
        "material": {**SLS, "nu": nu},
        "body": {"shape": "sphere", "radius": radius, "material": "same", "position": [-1.25 * n * h, 0.0]},
        "motion": {"load": load, "velocity": [a / SLS["tau_creep"], 0.0], **motion},
        "friction": {"coefficient": MU},
        "time": {"steps_per_cell": 1, "distance": 0.75 * n * h},
        "solver": {"tol": 1e-10},
    }


def test_viscoelastic_friction_keys():
    """An SLS half-space under a rigid body (nu = 1/2): c(t) = J(t)/(1 - nu) = 2 J(t); a body of the same
    material doubles J(t) (instantaneous and relaxed) for both problems. Refused in one line: a layer with
    friction, an elastic body on a viscoelastic half-space, a rigid body at nu != 1/2."""
    rigid = scene_of(line_rolling(SLS, 1.0, 0.3))
    jinf, j0 = 0.75 / SLS["Einf"], 0.75 / SLS["E0"]
    assert rigid.friction.memory == 2.0 and rigid.friction.compliance == pytest.approx(2 * jinf, rel=1e-15)
    assert rigid.material.Jinf == pytest.approx(jinf, rel=1e-15) and rigid.friction.body == "rigid"
    same = scene_of(sphere())
    assert same.friction.body == "same" and same.friction.memory == pytest.approx(1 / 0.7, rel=1e-15)
    single = materials.sls(SLS["E0"], SLS["Einf"], 0.3, SLS["tau_creep"])
    assert same.material.Jinf == pytest.approx(2 * single.Jinf, rel=1e-15)
    assert same.material.J0 == pytest.approx(2 * single.J0, rel=1e-15) and same.material.tau == single.tau
    assert j0 < jinf
    raw = sphere()
    cases = [
        ({"material": {**raw["material"], "layer": {"thickness": 1e-3, "base": "bonded"}}}, "[friction]",
         "layers are not modelled"),
        ({"body": {**raw["body"], "material": {"E": 1e9, "nu": 0.3}}}, "[body] material", "elastic body on it"),
        ({"body": {k: v for k, v in raw["body"].items() if k != "material"}}, "[body] material",
         "rigid body on a half-space of nu = 0.3"),
    ]
    for change, key, allowed in cases:
        bad = {**copy.deepcopy(raw), **change}
        with pytest.raises(SceneError) as info:
            scene_of(bad)
        text = str(info.value)
        assert info.value.key == key and allowed in text and "\n" not in text, text


def test_an_interrupted_viscoelastic_friction_run_restarts_bitwise(comm, shared_dir):
    """Force control on two SLS bodies (the tangential history, sources and tractions are the state),
    stopped after step 5 and restarted from its checkpoint: every series and field of the uninterrupted
    run, bit for bit."""
    raw = sphere(tangential_force=[-0.1, 0.03])
    raw["output"] = {"every": 3, "checkpoint_every": 2}
    reference = assert_restarts_bitwise(scene_of(raw), 5, comm, shared_dir)
    assert reference.series["traction_x"][-1] == pytest.approx(-0.1, rel=1e-9)


def test_a_viscoelastic_friction_run_on_two_ranks_is_the_one_rank_run(comm, tmp_path, shared_dir):
    """Rows split over ``comm`` against every rank's own COMM_SELF run, to 1e-10: transient rolling of two
    SLS bodies at a creepage with spin, and their steady state at a force with spin."""
    steady = sphere(tangential_force=[-0.1, 0.03], spin=20.0)
    steady["time"] = {"mode": "steady"}
    for name, raw in (("transient", sphere(creepage=[-1e-2, 5e-3], spin=20.0)), ("steady", steady)):
        scene = scene_of(raw)
        both = run(scene, comm, shared_dir / name)
        alone = run(scene, MPI.COMM_SELF, tmp_path / f"{name}-{comm.rank}")
        for key in ("traction_x", "traction_y", "creepage_x", "creepage_y", "stick_area", "friction_power",
                    "force", "mu_r"):
            a, b = alone.series[key], both.series[key]
            assert np.array_equal(np.isnan(a), np.isnan(b)), (name, key)
            assert np.nanmax(np.abs(b - a), initial=0.0) <= 1e-10 * np.nanmax(np.abs(a)), (name, key)
        for key in ("traction_x", "traction_y"):
            a, b = alone.field(key), both.field(key)
            assert np.abs(a - b).max() <= 1e-10 * np.abs(a).max(), (name, key)
        assert np.abs(alone.series["traction_x"][-1]) > 0.05 * MU * alone.series["force"][-1]


def long_sphere(vtau: float, material=None) -> dict:
    """:func:`sphere` under the tangential force -mu P/2 at V tau/a = ``vtau``, rolling 15 relaxed radii on
    a longer grid (the wake of the steady solve is the grid behind the contact)."""
    raw = sphere(tangential_force=[-0.5 * MU * 1.0, 0.0])
    n, nu = 18, 0.3
    a = (3 * 1.0 * 0.01 * 2 * (1 - nu**2) / SLS["Einf"] / 4) ** (1 / 3)
    h = a / 6
    raw["grid"] = {"nx": 8 * n, "ny": n, "x": [-6.5 * n * h, 1.5 * n * h], "y": [-n * h / 2, n * h / 2]}
    raw["body"]["position"] = [-5 * n * h, 0.0]
    raw["time"]["distance"] = 5 * n * h
    raw["motion"]["velocity"] = [vtau * a / SLS["tau_creep"], 0.0]
    if material is not None:
        raw["material"] = material
    return raw


def test_the_direct_steady_solve_is_the_transient_s_steady_state(comm, shared_dir):
    """Two SLS spheres at V tau/a = 1 (the loss peak) under the tangential force mu P/2, rolled 15 radii
    from rest one cell per step, against the `[time] mode = "steady"` scene with the body where the run
    ended (the normal steady solve, then the tangential one with the integrator's response along the
    motion, the grid behind the contact its wake): creepage, mu_r within 0.2 % (measured 2e-8, 2e-9),
    the traction field within 0.2 % of mu p0 (measured 7e-9). The creepage is neither elastic limit's
    (the steady elastic runs with Einf and E0: 5.4 % and 47 % apart)."""
    raw = long_sphere(1.0)
    transient = run(scene_of(raw), comm, shared_dir / "transient")
    steady = copy.deepcopy(raw)
    steady["body"]["position"] = [float(transient.series["sx"][-1]), 0.0]
    steady["time"] = {"mode": "steady"}
    direct = run(scene_of(steady), comm, shared_dir / "steady")
    t, d = transient.series, direct.series
    errors = {k: d[k][0] / t[k][-1] - 1 for k in ("creepage_x", "mu_r", "p_max")}
    bound = MU * d["p_max"][0]
    field = np.abs(transient.field("traction_x")[-1] - direct.field("traction_x")[0]).max() / bound
    print(f"steady vs transient: {errors}, traction field {field:.2e} of mu p0")
    assert max(abs(e) for e in errors.values()) <= 2e-3 and field <= 2e-3
    for name, modulus in (("relaxed", SLS["Einf"]), ("glassy", SLS["E0"])):
        elastic = copy.deepcopy(steady)
        elastic["material"] = {"model": "elastic", "E": modulus, "nu": 0.3}
        limit = run(scene_of(elastic), comm, shared_dir / name).series["creepage_x"][0]
        print(f"{name}: creepage {limit / d['creepage_x'][0]:.3f} of the viscoelastic one")
        assert abs(limit / d["creepage_x"][0] - 1) > 0.03


def test_temperature_enters_the_tangential_creep_function_through_the_shift_law(comm, shared_dir):
    """An SLS at 30 K above its WLF reference temperature rolls (at V tau/a = 10 for tau at T_ref, where the
    traction curve leaves the relaxed one) as the SLS of retardation time a_T tau, log10 a_T = -C1 dT/(C2 +
    dT), at its reference: the same traction series to 1e-9, and not the unshifted material's (measured:
    41 % apart)."""
    wlf = {"law": "wlf", "C1": 8.86, "C2": 101.6, "T_ref": 300.0}
    a_t = 10 ** (-wlf["C1"] * 30.0 / (wlf["C2"] + 30.0))
    cases = {"warm": {**SLS, "temperature": 330.0, "shift": wlf},
             "shifted": {**SLS, "tau_creep": SLS["tau_creep"] * a_t}, "reference": SLS}
    series = {name: run(scene_of(line_rolling(material, 10.0, 0.3, cells=6)), comm, shared_dir / name)
              .series["traction_x"] for name, material in cases.items()}
    assert np.abs(series["warm"] - series["shifted"]).max() <= 1e-9 * np.abs(series["shifted"]).max()
    print(f"a_T = {a_t:.3g}: warm vs reference {series['warm'][-1] / series['reference'][-1] - 1:+.2%}")
    assert abs(series["warm"][-1] / series["reference"][-1] - 1) > 0.1
