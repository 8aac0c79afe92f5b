"""A periodic rough scene's checks (petroll.model.rough_contact, docs/rough.md): the estimates from its
spectrum and load against the surface's keys, Persson's formula and an elastic run; the warning on too
few cells per short cut-off wavelength; a sweep's warnings shown once and its table and figure in the
terms of sliding friction (A/A0, mu, speed)."""

import math
import warnings

import numpy as np
import pytest
from scipy.special import erf

import petroll
from petroll.model.limits import PetrollWarning, largest_penetration
from petroll.model.preflight import check, check_run
from petroll.model.rough_contact import GOOD_CUTOFF_CELLS, rough_contact
from petroll.model.scene import parse_scene

L, N = 1.0e-3, 32
RAW = {
    "grid": {"nx": N, "ny": N, "x": [0.0, L], "y": [0.0, L], "periodic": True},
    "material": {"model": "elastic", "E": 3.0e6, "nu": 0.5},
    "body": {"shape": "rough", "hurst": 0.8, "cutoff": 4 * L / N, "rms_slope": 0.1, "seed": 3},
    "motion": {"velocity": [0.01, 0.0], "load": 0.05},
    "time": {"mode": "steady", "steps_per_cell": 8},
}


SLS = {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01}


def scene_with(material=None, **changes):
    raw = {section: dict(table) for section, table in RAW.items()}
    raw["material"] = dict(material or raw["material"])
    for key, value in changes.items():
        section, name = key.split("__")
        raw[section][name] = value
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PetrollWarning)
        return parse_scene(raw)


def test_the_estimates_come_from_the_spectrum_and_the_load():
    scene = scene_with()
    found = rough_contact(scene)
    assert found.rms_slope == pytest.approx(0.1, rel=1e-9)  # the generator's rms slope, the interpolant's
    # the cut-off: just above the generator's (99 % of the slope below it), in cells of the grid
    assert 4 * L / N <= found.cutoff <= 1.1 * 4 * L / N and found.cells == pytest.approx(found.cutoff * N / L)
    J = (1 - 0.5**2) / 3.0e6
    p0 = 0.05 / L**2
    persson = float(erf(math.sqrt(2) * p0 * J / 0.1))
    assert found.area == pytest.approx((persson, persson), rel=1e-12)
    delta, exact = largest_penetration(scene)  # what the slope check takes: the rough estimate, not a summit's
    assert not exact and delta == pytest.approx(found.penetration[1], rel=1e-12)
    assert 0 < delta < found.relief


def test_the_penetration_and_area_estimates_meet_an_elastic_run(shared_dir, comm):
    scene = scene_with()
    found = rough_contact(scene)
    results = petroll.run(scene, comm, out=shared_dir / "elastic")
    area = float(results.series["area"][-1]) / L**2
    delta = float(results.series["delta"][-1])
    assert found.area[1] == pytest.approx(area, rel=0.25), (found.area, area)  # Persson: about 10-20 %
    assert found.penetration[1] == pytest.approx(delta, rel=0.25), (found.penetration, delta)
    from petroll.cli import summary

    text = summary(scene, results, wall=1.0)  # the run's paragraph: sliding friction's terms
    assert f"friction mu {results.series['mu_r'][-1]:.4e}" in text and f"A/A0 {area:.4g}" in text
    assert "patch from" not in text and "mu_r" not in text


def test_check_reports_the_rough_contact_not_a_curvature():
    lines = check(scene_with()).lines()
    text = "\n".join(lines)
    assert "curvature radii" not in text and "cells per contact half-width" not in text
    assert "area fraction A/A0" in text and "short cut-off wavelength" in text
    (resolution,) = [line for line in lines if line.startswith("resolution:")]
    assert f"{rough_contact(scene_with()).cells:.1f} cells of" in resolution and "fine" in resolution


@pytest.mark.parametrize("cutoff_cells, warned", [(2, True), (3, True), (GOOD_CUTOFF_CELLS, False), (8, False)])
def test_a_run_warns_below_the_least_cells_per_cut_off(cutoff_cells, warned):
    scene = scene_with(body__cutoff=cutoff_cells * L / N)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_run(scene)
    texts = [str(w.message) for w in caught if "cut-off" in str(w.message)]
    assert len(texts) == int(warned), texts
    if warned:
        assert f"fewer than {GOOD_CUTOFF_CELLS}" in texts[0] and "\n" not in texts[0]


def test_a_rough_sweep_warns_once_and_speaks_of_friction(shared_dir, comm, cli_main):
    """``petroll sweep`` over three speeds on a coarse surface (2 cells per cut-off): its warning once, not
    at every point; the table's A/A0 is the area over the cell's; the figure's terms are sliding
    friction's."""
    from petroll.model.scene import dumps
    from petroll.plot.sweep import SweepData
    from petroll.studies.sweep import SweepTable

    raw = {**RAW, "material": SLS, "body": {**RAW["body"], "cutoff": 2 * L / N}}
    if comm.rank == 0:
        (shared_dir / "rough.toml").write_text(dumps(raw), encoding="utf-8")
    comm.Barrier()
    code, out, err = cli_main(["sweep", str(shared_dir / "rough.toml"), "--vary",
                               "motion.velocity=1e-3,1e-2,1e-1", "--out", str(shared_dir / "sweep"), "--quiet"])
    assert code == 0
    if comm.rank == 0:
        lines = err.splitlines()
        assert len([line for line in lines if "cut-off" in line]) == 1, err
        assert len(lines) == len(set(lines)), err
        assert out.count("friction mu ") == 3 and "mu_r" not in out, out
    table = SweepTable.open(shared_dir / "sweep")
    assert np.allclose(table.columns["area_fraction"], table.columns["area"] / L**2, rtol=1e-12, atol=0)
    assert np.all(np.isnan(table.columns["v_tau_a"])) and np.all(np.isnan(table.columns["a"]))
    d = SweepData.of(table)
    assert d.cell and d.secondary is None and not d.limits
    assert d.xlabel == "sliding speed V (m/s)" and d.mu == r"$\mu$"
