"""Studies of viscoelastic friction (docs/friction.md#traction-against-speed-and-temperature): the creep
coefficient against the speed (a sweep's column creep_coefficient, runs/creep-coefficient.toml) between
its elastic limits, and a family of traction curves over the temperature (`petroll sweep` with two
`--vary`) on the material `petroll material fit` wrote, against time-temperature superposition.

Unmarked tests are collective (every rank under mpirun) and write into shared_dir.
"""

import math
import pathlib

import numpy as np
import pytest

from petroll.model.scene import load_scene, parse_scene
from petroll.studies.sweep import SweepTable, sweep

ROOT = pathlib.Path(__file__).resolve().parents[1]
KALKER_C11 = 5.20
"""Kalker's C11 at nu = 1/2, a circular contact (Three-Dimensional Elastic Bodies in Rolling Contact, 1990,
Table E.3): a rigid body on a half-space of nu = 1/2 has Kalker's combined modulus 2 G and nu = 1/2."""


def elastic(scene, modulus: float):
    """``scene`` with an elastic half-space of Young's modulus ``modulus`` (nu = 1/2) for its SLS."""
    return scene.replace({"material.model": "elastic", "material.E": modulus, "material.E0": None,
                          "material.Einf": None, "material.tau_creep": None})


@pytest.mark.slow
def test_the_creep_coefficient_runs_from_the_relaxed_to_the_glassy_kalker_coefficient(comm, shared_dir):
    """runs/creep-coefficient.toml (a rigid sphere on the SLS of E0/Einf = 5 pressed 25 um: the Hertz radius
    a at any modulus, a creepage 1e-4 where the force saturates near 4e-2) swept over V tau/a = 1e-3 ... 1e3
    by decades: the creep coefficient -F.xi/(G c^2 |xi|^2) (G, c relaxed) at 1e-3 is the elastic run's with
    Einf, at 1e3 E0/Einf = 5 times the elastic run's with E0 (the glassy modulus's own coefficient), each
    within 1 % (measured: +0.06 %, -0.63 %; the fast departure falls as a/(V tau)), rising monotonically
    between them; the elastic coefficient is Kalker's C11 within 3 % (measured -1.4 % at 10 cells per
    radius)."""
    scene = load_scene(ROOT / "runs" / "creep-coefficient.toml")
    table = sweep(scene, "motion.velocity=1e-5..10:log:7", out=shared_dir / "speeds", comm=comm)
    c = table.columns
    assert np.allclose(c["v_tau_a"], np.logspace(-3, 3, 7), rtol=1e-9)
    coefficient = c["creep_coefficient"]
    limits = {}
    for name, modulus in (("relaxed", 2e6), ("glassy", 10e6)):
        point = sweep(elastic(scene, modulus), "motion.velocity=0.01", out=shared_dir / name, comm=comm, plot=False)
        limits[name] = float(point.columns["creep_coefficient"][0]) * modulus / 2e6  # in G_inf's units
    slow, fast = coefficient[0] / limits["relaxed"] - 1, coefficient[-1] / limits["glassy"] - 1
    print(f"creep coefficient {np.round(coefficient, 3)}; slow {slow:+.2e}, fast {fast:+.2e}; elastic "
          f"{limits['relaxed']:.4f} (Kalker {KALKER_C11})")
    assert abs(slow) <= 1e-2 and abs(fast) <= 1e-2
    assert np.all(np.diff(coefficient) > 0)
    assert limits["relaxed"] == pytest.approx(KALKER_C11, rel=3e-2)
    assert limits["glassy"] == pytest.approx(5 * limits["relaxed"], rel=1e-9)  # displacement control: c alike
    assert (shared_dir / "speeds" / "sweep.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_a_family_of_traction_curves_over_the_temperature_of_a_fitted_material(comm, cli_main, shared_dir):
    """`petroll material fit runs/rubber-dma.csv --shift wlf:...` writes a [material] block that goes into a
    scene as it is (the geometry of runs/creep-coefficient.toml, the tread rubber's 39-term Prony series
    and its WLF law); `petroll sweep --vary motion.creepage=... --vary material.temperature=...` gives one
    traction curve per temperature (family.csv, family.png, each curve a sweep directory). Time-temperature
    superposition is the oracle: the curve at T is the curve at T_ref at the speed a_T V (log10 a_T =
    -C1 (T - T_ref)/(C2 + T - T_ref)), to 1e-10 (measured 1.5e-15); the colder curve's forces are larger (the rubber stiffer)."""
    block = shared_dir / "rubber.toml"
    code, _, err = cli_main(["material", "fit", str(ROOT / "runs" / "rubber-dma.csv"), "--shift",
                             "wlf:8.86,101.6,293.15", "--out", str(block)])
    assert code == 0, err
    geometry = (ROOT / "runs" / "creep-coefficient.toml").read_text(encoding="utf-8")
    head, _, rest = geometry.partition("[material]")
    tail = rest[rest.index("[body]"):].replace("creepage = [-1.0e-4, 0.0]", "creepage = [-1.0e-2, 0.0]")
    scene_path = shared_dir / "rubber-scene.toml"
    if comm.rank == 0:
        scene_path.write_text(head + block.read_text(encoding="utf-8") + "\n" + tail
                              + "\n[solver]\ntol = 1e-10\n", encoding="utf-8")
    comm.Barrier()
    temperatures = (303.15, 318.15)
    code, out, err = cli_main(["sweep", str(scene_path), "--vary", "motion.creepage=2e-3,1.5e-2", "--vary",
                               "material.temperature=" + ",".join(map(str, temperatures)), "--out",
                               str(shared_dir / "family"), "--quiet"])
    assert code == 0, err
    if comm.rank == 0:
        assert "2 curves of motion.creepage at material.temperature = 303.15, 318.15 (4 points, 4 run" in out
        rows = (shared_dir / "family" / "family.csv").read_text().splitlines()
        assert rows[0].startswith("material.temperature (K),motion.creepage (-),force (N)") and len(rows) == 5
        assert (shared_dir / "family" / "family.png").read_bytes()[:4] == b"\x89PNG"
    comm.Barrier()
    scene = load_scene(scene_path)
    curves, worst = {}, 0.0
    for temperature in temperatures:
        found = SweepTable.open(shared_dir / "family" / f"material.temperature={temperature:.10g}")
        a_t = 10 ** (-8.86 * (temperature - 293.15) / (101.6 + temperature - 293.15))
        assert math.isclose(float(found.columns["a_T"][0]), a_t, rel_tol=1e-12)
        shifted = scene.replace({"motion.velocity": [0.01 * a_t, 0.0]})
        reference = sweep(shifted, "motion.creepage=2e-3,1.5e-2", out=shared_dir / f"tref-{temperature}",
                          comm=comm, plot=False)
        for key in ("traction_x", "force", "mu_r"):
            a, b = found.columns[key], reference.columns[key]
            worst = max(worst, np.abs(a - b).max() / np.abs(b).max())
            assert np.abs(a - b).max() <= 1e-10 * np.abs(b).max(), (temperature, key)
        curves[temperature] = found.columns["traction_x"]
    print(f"traction at 303.15 K {curves[303.15]} N, at 318.15 K {curves[318.15]} N; vs T_ref at a_T V: {worst:.1e}")
    assert np.all(curves[318.15] > 0) and np.all(curves[303.15] / curves[318.15] > 1.03)  # stiffer when colder
