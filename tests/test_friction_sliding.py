"""Steady sliding with friction (docs/friction.md#steady-sliding): `[time] mode = "steady"` on a periodic
grid with `[friction] coefficient`: full slip, the traction mu p opposing the sliding velocity, the friction
force mu P plus the pressure's hysteresis force mu_r P of the same (frictionless) sliding run. The bodies
are quasi-identical (a rigid body on a nu = 1/2 half-space), so the traction moves no surface normally and
the pressure is the frictionless one; other pairs are refused in one line.

Unmarked tests are collective (every rank under mpirun) and write into shared_dir.
"""

import copy
import math

import numpy as np
import pytest
from mpi4py import MPI

from petroll.driver import run
from petroll.errors import SceneError
from petroll.model.scene import parse_scene

MU = 0.4
SLS = {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 2e-3}
ELASTIC = {"model": "elastic", "E": 2e6, "nu": 0.5}
WAVELENGTH, LOAD = 1e-3, 0.01


def bumps(comm, directory, material, n=32, velocity=(0.5, 0.0), line=False) -> dict:
    """A rigid surface D (1 - cos kx cos ky) (D = 5 um, wavelength 1 mm: one bump per periodic cell, n x n
    cells; line contact: D (1 - cos kx) on n strips) pressed by 10 mN (10 N/m) onto ``material``, sliding
    at ``velocity`` (m/s; V tau_relax = the wavelength at 0.5 m/s: near the SLS's loss peak), partial
    contact; the steady solve's integrator at 64/n steps per cell."""
    x = (np.arange(n) + 0.5) * WAVELENGTH / n
    wave = np.cos(2 * np.pi * x / WAVELENGTH)
    z = 5e-6 * (1 - (wave if line else np.outer(wave, wave)))
    path = directory / f"bumps{n}{line}.npy"
    if comm.rank == 0:
        np.save(path, z)
    comm.Barrier()
    grid = {"nx": n, "x": [0, WAVELENGTH], "periodic": True}
    if not line:
        grid.update(ny=n, y=[0, WAVELENGTH])
    return {"grid": grid, "material": material,
            "motion": {"load": 1e3 * LOAD if line else LOAD, "velocity": velocity[0] if line else list(velocity)},
            "body": {"shape": "heightmap", "file": str(path), "cell": WAVELENGTH / n},
            "time": {"mode": "steady", "steps_per_cell": max(1, 64 // n)}, "solver": {"tol": 1e-10}}


def with_friction(raw: dict) -> dict:
    return {**copy.deepcopy(raw), "friction": {"coefficient": MU}}


@pytest.mark.parametrize("material", ["elastic", "sls"])
def test_sliding_friction_is_mu_p_plus_the_hysteresis_of_the_frictionless_run(comm, shared_dir, material):
    """Full slip: the traction field is -mu p along the motion cellwise (p the frictionless run's pressure
    to round-off: the traction moves no surface normally), its force -mu P, no stick, the slip velocity V
    in the contact and its power mu P V; the friction force is mu P plus the frictionless run's mu_r P. An
    elastic half-space has no hysteresis (mu_r 0: it dissipates nothing); the SLS near
    its loss peak a real one."""
    raw = bumps(comm, shared_dir, ELASTIC if material == "elastic" else SLS)
    plain = run(parse_scene(raw), comm, shared_dir / "plain")
    sliding = run(parse_scene(with_friction(raw)), comm, shared_dir / "friction")
    s, f = plain.series, sliding.series
    force, speed = f["force"][0], 0.5
    assert force == pytest.approx(LOAD, rel=1e-9)
    for key in ("force", "mu_r", "force_x", "force_y", "area", "p_max", "delta"):
        assert f[key][0] == pytest.approx(s[key][0], rel=1e-12, abs=1e-14 * abs(s["force"][0])), key
    p, q = plain.pressure[0], sliding.field("traction_x")[0]
    assert np.abs(sliding.pressure[0] - p).max() <= 1e-12 * p.max()
    assert np.abs(q + MU * p).max() <= 1e-13 * MU * p.max()
    assert np.abs(sliding.field("traction_y")[0]).max() == 0.0
    slip = sliding.field("slip")[0]
    assert np.array_equal(slip > 0, p > 0) and np.abs(slip[p > 0] - speed).max() <= 1e-15 * speed
    assert f["traction_x"][0] == pytest.approx(-MU * force, rel=1e-12)
    assert abs(f["traction_y"][0]) <= 1e-15 * force and f["stick_area"][0] == 0.0
    assert f["friction_power"][0] == pytest.approx(MU * force * speed, rel=1e-12)
    assert math.isnan(f["creepage_x"][0]) and math.isnan(f["creepage_y"][0])
    total = -f["traction_x"][0] + f["dissipation"][0] / speed  # the force resisting the sliding along +X
    assert total == pytest.approx((MU + s["mu_r"][0]) * force, rel=1e-12)  # mu_r: the dissipation's
    if material == "elastic":
        assert abs(s["mu_r"][0]) <= 1e-12 and 0.1 < s["area"][0] / WAVELENGTH**2 < 0.9
    else:
        assert s["mu_r"][0] > 1e-4 and s["area"][0] / WAVELENGTH**2 < 0.5  # a partial, lagging contact
    print(f"{material}: mu_r {s['mu_r'][0]:.4g}, friction coefficient mu + mu_r = {total / force:.5g}")


def test_sliding_friction_opposes_any_direction_and_in_line_contact(comm, shared_dir):
    """Sliding along (0.6, 0.8): the traction -mu p (0.6, 0.8) (forces and fields); line contact (plane strain,
    strips along Y): traction_x = -mu p, per unit length, no traction_y."""
    raw = with_friction(bumps(comm, shared_dir, SLS, n=16, velocity=(0.3, 0.4)))
    results = run(parse_scene(raw), comm, shared_dir / "diagonal")
    s, p = results.series, results.pressure[0]
    for key, d in (("traction_x", 0.6), ("traction_y", 0.8)):
        assert s[key][0] == pytest.approx(-MU * d * s["force"][0], rel=1e-12)
        assert np.abs(results.field(key)[0] + MU * d * p).max() <= 1e-13 * MU * p.max()
    line = run(parse_scene(with_friction(bumps(comm, shared_dir, SLS, n=64, line=True))), comm, shared_dir / "line")
    s = line.series
    assert "traction_y" not in s and "traction_y" not in line.fields
    assert s["traction_x"][0] == pytest.approx(-MU * s["force"][0], rel=1e-12) and s["mu_r"][0] > 0
    assert s["friction_power"][0] == pytest.approx(MU * s["force"][0] * 0.5, rel=1e-12)


def test_sliding_friction_scenes_are_checked(comm, shared_dir):
    """Refused in one line: friction on a periodic grid outside steady sliding, a creepage or tangential
    force (full slip), a rigid body on a half-space of nu != 1/2 (the coupling), a body of the same
    viscoelastic material (its own material does not stream through the contact). An elastic body of the
    same material is taken (the coupling cancels)."""
    raw = with_friction(bumps(comm, shared_dir, SLS, n=8))
    cases = [
        ({"time": {"steps_per_cell": 8, "distance": 1e-3}}, "[friction]", "only in steady sliding"),
        ({"motion": {**raw["motion"], "creepage": [1e-3, 0.0]}}, "[motion] creepage", "full slip"),
        ({"motion": {**raw["motion"], "tangential_force": [1e-3, 0.0]}}, "[motion] tangential_force", "full slip"),
        ({"material": {**SLS, "nu": 0.3}}, "[body] material", "normal-tangential coupling"),
        ({"body": {**raw["body"], "material": "same"}}, "[body] material", "does not stream"),
    ]
    for change, key, allowed in cases:
        with pytest.raises(SceneError) as info:
            parse_scene({**copy.deepcopy(raw), **change})
        text = str(info.value)
        assert info.value.key == key and allowed in text and "\n" not in text, text
    same = parse_scene({**copy.deepcopy(raw), "material": {**ELASTIC, "nu": 0.3},
                        "body": {**raw["body"], "material": "same"}})
    assert same.friction.coefficient == MU


@pytest.mark.parallel
def test_sliding_friction_on_two_ranks_is_the_one_rank_run(comm, tmp_path, shared_dir):
    """Rows split over ``comm`` against every rank's own COMM_SELF run, to 1e-10: the series and fields."""
    scene = parse_scene(with_friction(bumps(comm, shared_dir, SLS, n=16, velocity=(0.3, 0.4))))
    both = run(scene, comm, shared_dir / "both")
    alone = run(scene, MPI.COMM_SELF, tmp_path / f"alone-{comm.rank}")
    for key in ("traction_x", "traction_y", "stick_area", "friction_power", "force", "mu_r"):
        a, b = alone.series[key], both.series[key]
        assert np.abs(b - a).max() <= 1e-10 * np.abs(a).max(), key
    for key in ("traction_x", "traction_y", "slip"):
        a, b = alone.field(key), both.field(key)
        assert np.abs(a - b).max() <= 1e-10 * np.abs(a).max(), key
    assert alone.series["mu_r"][0] > 0
