"""Friction in scenes and runs (docs/friction.md): the keys and their one-line refusals, runs with friction
(shift, transient and steady rolling) against closed forms, their series, fields and checkpoints, 1 and 2
ranks. The tangential numerics themselves are tested in tests/test_tangential.py.

Unmarked tests are collective (every rank under mpirun) and write into shared_dir.
"""

import copy
import math
import signal

import numpy as np
import pytest
from mpi4py import MPI

from petroll.driver import run
from petroll.errors import SceneError
from petroll.io.checkpoint import RunInterrupted, StopRequest, read_checkpoint
from petroll.model.scene import dumps, parse_scene

E, NU, MU = 2.1e11, 0.3, 0.3
RADIUS, LOAD = 0.05, 100.0
A = (3 * LOAD * RADIUS * 2 * (1 - NU**2) / (4 * E)) ** (1 / 3)  # two steel bodies' Hertz radius (m)


def rolling(cells_per_radius=8, **motion) -> dict:
    """Two bodies of one material, a sphere on a grid of ``cells_per_radius`` cells per Hertz radius,
    rolling 3.75 radii along X (one cell per step)."""
    h = A / cells_per_radius
    n = 3 * cells_per_radius
    return {
        "grid": {"nx": 4 * n, "ny": n, "x": [-2.5 * n * h, 1.5 * n * h], "y": [-n * h / 2, n * h / 2]},
        "material": {"model": "elastic", "E": E, "nu": NU},
        "body": {"shape": "sphere", "radius": RADIUS, "material": "same", "position": [-1.25 * n * h, 0.0]},
        "motion": {"load": LOAD, "velocity": [1.0, 0.0], **motion},
        "friction": {"coefficient": MU},
        "time": {"steps_per_cell": 1, "distance": 1.25 * n * h},
        "solver": {"tol": 1e-10},
    }


def scene_of(raw):
    return parse_scene(raw, source="test_friction_scene")


# -- keys --------------------------------------------------------------------------------------------------

def changed(raw, **changes):
    out = copy.deepcopy(raw)
    for key, value in changes.items():
        section, name = key.split("__")
        if value is None:
            out.setdefault(section, {}).pop(name, None)
        else:
            out.setdefault(section, {})[name] = value
    return out


REFUSED = [
    ({"friction__coefficient": 0.0}, "[friction] coefficient", "> 0"),
    ({"friction__coefficient": 1e300}, "[friction] coefficient", "at most 100"),
    ({"body__material": {"E": 1e-300, "nu": 0.3}}, "[body] material", "outside what petroll computes with"),
    ({"friction__coefficient": None}, "[friction] coefficient", "required"),
    ({"friction__mu": 0.3}, "[friction] mu", "unknown key"),
    ({"motion__creepage": [2.0, 0.0]}, "[motion] creepage", "between -1 and 1"),
    ({"motion__creepage": "small"}, "[motion] creepage", "pair [xi, eta]"),
    ({"motion__tangential_force": [1.0, 2.0, 3.0]}, "[motion] tangential_force", "pair [Fx, Fy]"),
    ({"motion__tangential_force": [1.0, 0.0], "motion__creepage": [0.001, 0.0]},
     "[motion] creepage / tangential_force", "at most one"),
    ({"motion__spin": "fast"}, "[motion] spin", "finite number"),
    ({"motion__tangential_force": [25.0, 20.0]}, "[motion] tangential_force", "friction bound mu x load = 30"),
    ({"motion__velocity": [0.0, 0.0], "motion__creepage": [0.001, 0.0]}, "[motion] creepage", "rolling body"),
    ({"body__material": "steel"}, "[body] material", '"same"'),
    ({"body__material": {"E": 1e9}}, "[body] material", "inline table"),
    ({"body__material": {"E": 1e11, "nu": 0.3}}, "[body] material", "not quasi-identical"),
    ({"body__material": None}, "[body] material", "rigid body on a half-space of nu = 0.3"),
    ({"material__layer": {"thickness": 1e-3, "base": "bonded"}}, "[friction]", "layers are not modelled"),
    ({"friction__coefficient": None, "motion__creepage": [0.001, 0.0]}, "[friction] coefficient", "required"),
]


@pytest.mark.parametrize("changes, key, allowed", REFUSED)
def test_bad_friction_keys_are_refused_in_one_line_naming_the_key(changes, key, allowed):
    raw = changed(rolling(), **changes)
    if changes.get("friction__coefficient", 1) is None and "motion__creepage" in changes:
        del raw["friction"]  # friction's keys without [friction]
        key, allowed = "[motion] creepage", "needs [friction] coefficient"
    with pytest.raises(SceneError) as info:
        scene_of(raw)
    text = str(info.value)
    assert info.value.key == key and allowed in text and "\n" not in text, text


def test_line_contact_takes_numbers_along_x_and_refuses_spin_and_y():
    raw = carter(0.3)
    scene = scene_of(raw)
    assert scene.friction.creepage == (raw["motion"]["creepage"], 0.0)
    assert scene.fields == ("pressure", "traction_x", "slip")
    for changes, key in (({"motion__spin": 0.1}, "[motion] spin"),
                         ({"motion__creepage": [0.0, 1e-4]}, "[motion] creepage")):
        with pytest.raises(SceneError) as info:
            scene_of(changed(raw, **changes))
        assert info.value.key == key


def test_a_body_material_adds_its_compliances():
    """'same' doubles both compliances; an elastic body of another E with the same (1 - 2 nu)/G is
    quasi-identical: c = 1/(2 G1) + 1/(2 G2), nu = (nu1/G1 + nu2/G2)/(1/G1 + 1/G2), J = sum (1 - nu^2)/E."""
    g = E / (2 * (1 + NU))
    same = scene_of(rolling())
    assert same.friction.compliance == pytest.approx(1 / g, rel=1e-15)
    assert same.material.Jinf == pytest.approx(2 * (1 - NU**2) / E, rel=1e-15)
    # nu2 = 0.5 cannot match nu = 0.3's (1 - 2 nu)/G > 0; take a half-space of nu 0.5 and a rigid body
    rigid = scene_of(changed(rolling(), material__nu=0.5, body__material=None))
    assert rigid.friction.body == "rigid" and rigid.friction.compliance == pytest.approx(1.5 / E, rel=1e-15)
    g2 = 2 * g  # (1 - 2 nu2)/G2 = (1 - 2 nu)/G: nu2 = 1/2 - (1 - 2 nu) g2/(2 g) = -0.1
    nu2 = 0.5 - (1 - 2 * NU) * g2 / (2 * g)
    other = scene_of(changed(rolling(), body__material={"E": 2 * g2 * (1 + nu2), "nu": nu2}))
    assert other.friction.compliance == pytest.approx(0.5 / g + 0.5 / g2, rel=1e-14)
    assert other.friction.nu == pytest.approx((NU / g + nu2 / g2) / (1 / g + 1 / g2), rel=1e-14)
    assert other.material.Jinf == pytest.approx((1 - NU**2) / E + (1 - nu2**2) / (2 * g2 * (1 + nu2)), rel=1e-14)


def test_without_friction_the_normal_series_are_those_of_a_run_with_it(comm, shared_dir):
    """Quasi-identical bodies: friction leaves the normal problem alone, so a run with [friction] has, bit
    for bit, the normal series and pressure of the same run without it (today's frictionless path), which
    writes no friction series or fields."""
    raw = rolling(creepage=[-1e-3, 0.0])
    raw["time"]["distance"] /= 4
    plain = copy.deepcopy(raw)
    del plain["friction"], plain["motion"]["creepage"]
    with_friction = run(scene_of(raw), comm, shared_dir / "friction")
    without = run(scene_of(plain), comm, shared_dir / "plain")
    assert set(with_friction.series) - set(without.series) == {
        "traction_x", "traction_y", "creepage_x", "creepage_y", "shift_x", "shift_y", "stick_area",
        "friction_power", "friction_iterations", "friction_applications"}
    assert without.fields == ("pressure",) and with_friction.fields == ("pressure", "traction_x", "traction_y", "slip")
    for name in without.series:
        if name != "solve_time":
            assert np.array_equal(with_friction.series[name], without.series[name]), name
    assert np.array_equal(with_friction.pressure, without.pressure)


# -- runs against closed forms -----------------------------------------------------------------------------

def carter(frac: float, cells=16) -> dict:
    """Carter's steady rolling: a rigid cylinder on a nu = 1/2 half-space (line contact), ``cells`` per
    half-width a = 1e-4 m, at the creepage of the stick zone's fraction 1 - frac."""
    a, radius, e = 1e-4, 0.1, 2e11
    load = math.pi * a * a / (4 * radius * 0.75 / e)  # a = sqrt(4 P R J/pi), J = (1 - nu^2)/E
    return {
        "grid": {"nx": 3 * cells, "x": [-1.5 * a, 1.5 * a]},
        "material": {"model": "elastic", "E": e, "nu": 0.5},
        "body": {"shape": "cylinder", "radius": radius},
        "motion": {"load": load, "velocity": 1.0, "creepage": -frac * MU * a / radius},
        "friction": {"coefficient": MU},
        "time": {"mode": "steady"},
    }


@pytest.mark.parametrize("frac", [0.1, 0.3, 0.6, 0.9])
def test_carter_creep_force_from_a_steady_scene_within_1_percent(frac, comm, shared_dir):
    results = run(scene_of(carter(frac)), comm, shared_dir / "carter")
    s = results.series
    exact = 1 - (1 - frac) ** 2
    error = s["traction_x"][0] / (MU * s["force"][0]) / exact - 1
    print(f"Carter frac {frac}: {100 * error:+.2f} %")
    assert abs(error) < 0.01
    power = s["friction_power"][0]  # the slip's power: below the rigid creepage's, F |xi| V
    assert 0 < power < s["traction_x"][0] * abs(s["creepage_x"][0])


def test_cattaneo_shift_from_a_scene_within_2_percent(comm, shared_dir):
    """A sphere on a half-space of its own material shifted by Q = mu P/2 over four steps: the shift is
    twice Mindlin's 3 mu P (2 - nu)/(16 G a) (1 - (1 - Q/(mu P))^(2/3)) and the stick radius
    a (1 - Q/(mu P))^(1/3); the tangential force on the body opposes the shift."""
    raw = rolling(cells_per_radius=16, tangential_force=[-0.5 * MU * LOAD, 0.0])
    raw["motion"]["velocity"] = [0.0, 0.0]
    raw["body"]["position"] = [-A / 2, 0.0]  # the grid's x from -2.5 n h: the contact well inside it
    raw["time"] = {"dt": 0.25, "end": 1.0}
    results = run(scene_of(raw), comm, shared_dir / "cattaneo")
    s = results.series
    assert len(s["t"]) == 5 and np.isnan(s["creepage_x"]).all()
    assert s["traction_x"] == pytest.approx(-0.5 * MU * LOAD * s["t"], rel=1e-9, abs=1e-9 * LOAD)
    g = E / (2 * (1 + NU))
    shift = 2 * 3 * MU * LOAD * (2 - NU) / (16 * g * A) * (1 - 0.5 ** (2 / 3))
    stick = A * 0.5 ** (1 / 3)
    print(f"shift {s['shift_x'][-1] / shift - 1:+.2%}, stick radius {math.sqrt(s['stick_area'][-1] / math.pi) / stick - 1:+.2%}")
    assert s["shift_x"][-1] == pytest.approx(shift, rel=0.02)
    assert math.sqrt(s["stick_area"][-1] / math.pi) == pytest.approx(stick, rel=0.02)
    assert abs(s["shift_y"][-1]) < 1e-9 * shift
    slip = results.field("slip")[-1]
    assert (slip >= 0).all() and (slip > 0).any()


# -- checkpoints and ranks ---------------------------------------------------------------------------------

@pytest.mark.slow
def test_an_interrupted_friction_run_restarts_bitwise(comm, shared_dir):
    """Transient rolling under force control (order 2: the last two tractions are the state) stopped after
    step 6 and restarted from its checkpoint: every series and field of the uninterrupted run, bit for
    bit."""
    raw = rolling(tangential_force=[-20.0, 5.0])
    raw["output"] = {"every": 4, "checkpoint_every": 3}
    reference = assert_restarts_bitwise(scene_of(raw), 6, comm, shared_dir)
    assert reference.series["traction_x"][-1] == pytest.approx(-20.0, rel=1e-9)


def assert_restarts_bitwise(scene, step: int, comm, shared_dir):
    """Run ``scene``, then again stopped after ``step`` and restarted from its checkpoint: every series
    and field of the uninterrupted run, bit for bit (its results returned)."""
    reference = run(scene, comm, shared_dir / "reference")
    stop = StopRequest()

    def on_step(record):
        if record.step == step and comm.rank == comm.size - 1:
            stop.request(signal.SIGTERM)

    with pytest.raises(RunInterrupted) as info:
        run(scene, comm, shared_dir / "stopped", stop=stop, on_step=on_step)
    assert info.value.step == step
    restarted = run(scene, comm, shared_dir / "stopped", restart=read_checkpoint(info.value.checkpoint, comm))
    assert set(restarted.series) == set(reference.series)
    for name in reference.series:
        if name != "solve_time":
            assert np.array_equal(restarted.series[name], reference.series[name], equal_nan=True), name
    assert np.array_equal(restarted.field_steps, reference.field_steps)
    for name in reference.fields:
        assert np.array_equal(restarted.field(name), reference.field(name), equal_nan=True), name
    return reference


@pytest.mark.parallel
def test_a_friction_run_on_two_ranks_is_the_one_rank_run(comm, tmp_path, shared_dir):
    """The rows split over ``comm`` against every rank's own COMM_SELF run: transient rolling at a creepage
    with spin, and the steady state at a force."""
    raw = rolling(creepage=[-5e-4, 2e-4], spin=0.5)
    raw["time"]["distance"] /= 2
    steady = rolling(tangential_force=[-10.0, 3.0], spin=0.5)
    steady["time"] = {"mode": "steady"}
    for name, case in (("transient", raw), ("steady", steady)):
        scene = scene_of(case)
        both = run(scene, comm, shared_dir / name)
        alone = run(scene, MPI.COMM_SELF, tmp_path / f"{name}-{comm.rank}")
        for key in ("traction_x", "traction_y", "creepage_x", "creepage_y", "stick_area", "friction_power"):
            a, b = alone.series[key], both.series[key]
            assert np.array_equal(np.isnan(a), np.isnan(b)), (name, key)  # a shift's creepage, power at t = 0
            assert np.nanmax(np.abs(b - a), initial=0.0) <= 1e-10 * np.nanmax(np.abs(a)), (name, key)
        for key in ("traction_x", "traction_y"):
            a, b = alone.field(key), both.field(key)
            assert np.abs(a - b).max() <= 1e-10 * np.abs(a).max(), (name, key)


def test_a_scene_file_with_friction_runs_from_the_command_line(shared_dir, comm, cli_main):
    raw = carter(0.5)
    if comm.rank == 0:
        (shared_dir / "carter.toml").write_text(dumps(raw), encoding="utf-8")
    comm.Barrier()
    code, out, err = cli_main(["run", str(shared_dir / "carter.toml"), "--out", str(shared_dir / "cli"), "--quiet"])
    assert code == 0, err


def test_the_stick_slip_map_is_zero_outside_stick_where_no_slip_and_slip_elsewhere():
    """traction.png's stick/slip map: 0 outside the contact, stick where the slip velocity is 0 and slip
    elsewhere (NaN: a step of no duration's slipping cells)."""
    from petroll.plot.friction import SLIP, STICK, stick_slip

    p = np.array([0.0, 1.0, 2.0, 3.0])
    assert list(stick_slip(p, np.array([0.0, 0.0, 1e-3, np.nan]))) == [0, STICK, SLIP, SLIP]


@pytest.mark.slow
@pytest.mark.serial  # figures: one process
def test_petroll_plot_draws_the_tractions_and_the_stick_slip_map(tmp_path):
    """traction.png beside the other figures, in line contact and in 3-D."""
    from petroll.plot.runs import plot_results

    sphere = rolling(creepage=[-1e-3, 2e-4])
    sphere["time"]["distance"] /= 4
    for name, raw in (("line", carter(0.4)), ("sphere", sphere)):
        run(scene_of(raw), MPI.COMM_SELF, tmp_path / name)
        written = plot_results(tmp_path / name)
        assert tmp_path / name / "plots" / "traction.png" in written
        assert (tmp_path / name / "plots" / "traction.png").stat().st_size > 10000


@pytest.mark.slow
def test_the_onset_of_rolling_from_a_cattaneo_shift_reaches_the_steady_scene(comm, shared_dir):
    """Force control, Q = mu P/2: step 0 shifts the body (Cattaneo), then it rolls one cell per step;
    after two contact lengths its creepage and tractions are the steady scene's (solved directly, the
    body where the transient ends) within 0.2 % (of mu p0 for the tractions)."""
    raw = rolling(tangential_force=[-0.5 * MU * LOAD, 0.0])
    h = A / 8
    raw["body"]["position"] = [-4 * A, 0.0]
    raw["time"]["distance"] = 4 * A
    transient = run(scene_of(raw), comm, shared_dir / "transient")
    end = transient.series["sx"][-1]
    assert end == pytest.approx(0.0, abs=h / 100) and np.isnan(transient.series["creepage_x"][0])
    assert transient.series["shift_x"][0] > 0  # the shift opposes the force on the body
    steady = changed(raw, body__position=[float(end), 0.0])
    steady["time"] = {"mode": "steady"}
    direct = run(scene_of(steady), comm, shared_dir / "steady")
    xi, reference = transient.series["creepage_x"][-1], direct.series["creepage_x"][0]
    print(f"onset: creepage {xi / reference - 1:+.3%}")
    assert xi == pytest.approx(reference, rel=2e-3)
    q, q_ref = transient.field("traction_x")[-1], direct.field("traction_x")[0]
    bound = MU * direct.pressure[0].max()
    print(f"onset: tractions within {np.abs(q - q_ref).max() / bound:.2e} of mu p0")
    assert np.abs(q - q_ref).max() < 2e-3 * bound


@pytest.mark.serial  # one process: the benchmark's own (COMM_WORLD) solves
def test_petroll_bench_friction_quick_writes_its_table(tmp_path, cli_main):
    """`petroll bench friction --quick`: every case's row in friction.csv, the tangential solves counting
    their operator applications (two FFT pairs each in 3-D)."""
    import csv

    code, out, err = cli_main(["bench", "friction", "--quick", "--out", str(tmp_path)])
    assert code == 0, err
    rows = list(csv.DictReader(open(tmp_path / "friction.csv", encoding="utf-8")))
    assert [r["case"].split(",")[0] for r in rows][:4] == ["normal QP"] * 3 + ["shift Q = mu P/2"]
    assert len(rows) == 14 and rows[-1]["case"].startswith("creep curve, 3 points")
    plain, both = rows[-3], rows[-2]  # the steady scenes: frictionless, then under mu P/2
    assert plain["case"].startswith("steady scene, frictionless") and both["case"].startswith("steady scene, force")
    ratio = float(both["note"].split()[1])
    assert ratio == pytest.approx(float(both["seconds"]) / float(plain["seconds"]), rel=1e-2)
    # the friction run: the frictionless one's normal QPs (1 FFT pair each) and its tangential ones (2 each)
    tangential = float(both["applications"]) - float(plain["applications"])
    assert tangential > 0 and float(both["fft_pairs"]) == pytest.approx(
        float(plain["fft_pairs"]) + 2 * tangential, rel=1e-12)
    for row in rows[3:-3] + rows[-1:]:
        assert float(row["fft_pairs"]) == pytest.approx(2 * float(row["applications"]), rel=1e-12)
        assert float(row["applications"]) > 0


def test_the_steady_scenes_of_bench_friction_solve_one_normal_problem(comm):
    """The frictionless steady scene of `petroll bench friction` and the same under the tangential force
    mu P/2 (two SLS bodies of one material: no normal-tangential coupling) at 4 cells per relaxed radius:
    the same steady pressure to 1e-10, the tangential force the one held (-mu P/2, to the QP's tolerance),
    both times positive and finite."""
    from petroll.bench.friction import steady_scenes

    (plain, plain_record, plain_s), (both, both_record, both_s) = steady_scenes(4, comm)
    largest = comm.allreduce(float(plain.pressure.max(initial=0.0)), op=MPI.MAX)
    difference = comm.allreduce(float(np.abs(both.pressure - plain.pressure).max(initial=0.0)), op=MPI.MAX)
    assert largest > 0 and difference <= 1e-10 * largest
    assert both_record.force == pytest.approx(plain_record.force, rel=1e-10)
    held = both.friction.records[-1]
    assert held.traction_x == pytest.approx(-0.5 * MU * both_record.force, rel=1e-6)
    assert plain.friction is None
    assert 0 < plain_s < math.inf and 0 < both_s < math.inf
