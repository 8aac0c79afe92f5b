"""Materials from DMA data (petroll.model.dma, ``petroll material fit``) and temperature through
time-temperature superposition ([material] temperature, shift).

Oracles: E*(w) of a known Maxwell series written in complex form here (not the module's real and
imaginary parts), its creep compliance from materials.maxwell, hand-computed WLF and Arrhenius factors,
and, for the rolling run, the same scene at the reference temperature with the speed scaled by a_T.
"""

import math
import re
import pathlib
import tomllib
import warnings

import numpy as np
import pytest
from mpi4py import MPI

import petroll
from kills import SCENE as KILL_SCENE
from petroll.cli import main
from petroll.errors import SceneError
from petroll.model import dma, materials
from petroll.model.scene import parse_scene
from petroll.studies.sweep import point_scene
from compare import close_tree

ROOT = pathlib.Path(__file__).resolve().parents[1]

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

# A known rubber-like generalized Maxwell series: one term per decade from 2.2e-7 s to 2.2 s, moduli
# falling as a power of the time, Einf = 2 MPa. The times sit half-way between the fit's default
# candidate times for the data below (20 per decade from 10^-9.798 s), the worst placement for a grid.
TRUE_EINF = 2e6
TRUE_TIMES = 10 ** (np.arange(-6.623, 0.5, 1.0))
TRUE_MODULI = 1e6 * (TRUE_TIMES / TRUE_TIMES.max()) ** -0.5


def complex_modulus(frequency, Einf=TRUE_EINF, moduli=TRUE_MODULI, times=TRUE_TIMES):
    """E*(i w) = Einf + sum_k E_k i w T_k / (1 + i w T_k) (Pa) at ``frequency`` (Hz)."""
    iwt = 2j * np.pi * np.asarray(frequency)[:, None] * np.asarray(times)[None, :]
    return Einf + (np.asarray(moduli) * iwt / (1 + iwt)).sum(axis=1)


# -- shift laws ---------------------------------------------------------------------------------------------
def test_wlf_and_arrhenius_factors_against_hand_computed_values():
    wlf = materials.WLF(C1=17.44, C2=51.6, T_ref=300.0)
    # 310 K: log10 a_T = -17.44 x 10 / 61.6 = -2.8311688, a_T = 10^0.1688312 x 1e-3 = 1.475133e-3
    assert materials.shift_factor(wlf, 310.0) == pytest.approx(1.475133e-3, rel=1e-6)
    # 290 K: log10 a_T = 174.4 / 41.6 = 4.1923077, a_T = 1.557068 x 1e4
    assert materials.shift_factor(wlf, 290.0) == pytest.approx(1.557068e4, rel=1e-6)
    assert materials.shift_factor(wlf, 300.0) == 1.0
    with pytest.raises(ValueError, match="above T_ref - C2 = 248.4 K"):
        materials.shift_factor(wlf, 248.4)  # the pole: C2 + T - T_ref = 0
    arrhenius = materials.Arrhenius(Ea=100e3, T_ref=300.0)
    # Ea/R = 1e5 / 8.314462618 = 12027.24 K; 320 K: ln a_T = 12027.24 (1/320 - 1/300) = -12027.24 / 4800
    # = -2.505674, a_T = 0.0816206; 280 K: ln a_T = 12027.24 x 20 / 84000 = 2.863628, a_T = 17.52498
    assert materials.shift_factor(arrhenius, 320.0) == pytest.approx(0.0816206, rel=1e-6)
    assert materials.shift_factor(arrhenius, 280.0) == pytest.approx(17.52498, rel=1e-6)
    assert materials.make_shift({"law": "arrhenius", "Ea": 1e5, "T_ref": 300}) == arrhenius
    assert dma.parse_shift("wlf:17.44,51.6,300") == wlf
    for bad in ({"law": "wlf", "C1": 1.0, "T_ref": 300.0}, {"law": "vft"}, {"law": "arrhenius", "Ea": -1.0,
                                                                          "T_ref": 300.0}, 3.0):
        with pytest.raises(ValueError, match="law"):
            materials.make_shift(bad)


SCENE = {**{key: KILL_SCENE[key] for key in ("material", "body", "motion")},
         "grid": {"nx": 40, "ny": 20, "x": [-0.8e-3, 2.4e-3], "y": [-0.8e-3, 0.8e-3]},
         "time": {"steps_per_cell": 1, "distance": 1.2e-3}}
"""The kill storm's SLS sphere (tests/kills.py) rolling 12 cells of a 40 x 20 grid, nothing saved."""
WLF = {"law": "wlf", "C1": 17.44, "C2": 51.6, "T_ref": 300.0}


def with_material(material: dict) -> dict:
    return {**SCENE, "material": material}


@pytest.mark.parametrize("material", [
    {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 0.01},
    {"model": "prony", "series": "maxwell", "Einf": 2e6, "nu": 0.4, "moduli": [3e6, 5e6], "times": [1e-3, 0.1]},
    {"model": "prony", "series": "kelvin", "Einf": 2e6, "nu": 0.5, "compliances": [2e-7, 1e-7],
     "times": [1e-3, 0.1]},
], ids=["sls", "maxwell", "kelvin"])
def test_temperature_multiplies_every_time_by_a_T(material):
    ref = parse_scene(with_material(material)).material
    for T, law in ((310.0, WLF), (285.0, {"law": "arrhenius", "Ea": 80e3, "T_ref": 300.0})):
        scene = parse_scene(with_material({**material, "temperature": T, "shift": law}))
        a_T = materials.shift_factor(materials.make_shift(law), T)
        assert scene.shift_factor == pytest.approx(a_T, rel=1e-15)
        t = np.concatenate([[0.0], np.geomspace(1e-6, 10.0, 60)])
        assert scene.material(t * a_T) == pytest.approx(ref(t), rel=1e-12)  # J_T(t) = J_ref(t / a_T)
    if material["model"] == "sls":  # the same SLS written with its relaxation time already multiplied
        a_T = materials.shift_factor(materials.WLF(17.44, 51.6, 300.0), 310.0)
        direct = materials.sls(10e6, 2e6, 0.5, tau_relax=0.01 * a_T)
        shifted = parse_scene(with_material({**material, "temperature": 310.0, "shift": WLF})).material
        assert shifted.tau == pytest.approx(direct.tau, rel=1e-14)
        assert shifted.dJ == pytest.approx(direct.dJ, rel=1e-14)


def test_a_tabulated_material_has_its_time_axis_scaled(tmp_path):
    (tmp_path / "J.csv").write_text("0,1e-7\n0.01,2e-7\n0.1,4e-7\n")
    material = {"model": "tabulated", "file": "J.csv", "quantity": "J"}
    ref = parse_scene(with_material(material), base_dir=tmp_path).material
    scene = parse_scene(with_material({**material, "temperature": 290.0, "shift": WLF}), base_dir=tmp_path)
    assert scene.material.t == pytest.approx(tuple(t * 1.557068e4 for t in ref.t), rel=1e-6)
    assert scene.material.J == ref.J


@pytest.mark.parametrize("changes, key, allowed", [
    ({"temperature": 310.0}, "[material] temperature", "needs [material] shift too"),
    ({"shift": WLF}, "[material] shift", "needs [material] temperature too"),
    ({"temperature": 240.0, "shift": WLF}, "[material] temperature", "above T_ref - C2 = 248.4 K"),
    ({"temperature": 310.0, "shift": {"law": "wlf", "C1": 17.44}}, "[material] shift", "takes exactly"),
    ({"temperature": 310.0, "shift": {"law": "arrhenius", "Ea": 1e5, "T_ref": -3.0}}, "[material] shift",
     "T_ref = -3.0 must be a finite number > 0"),
    ({"temperature": -1.0, "shift": WLF}, "[material] temperature", "must be a finite number > 0 (K)"),
    ({"temperature": 1.0, "shift": {"law": "arrhenius", "Ea": 1e6, "T_ref": 300.0}}, "[material] temperature",
     "beyond what a float holds"),
    ({"temperature": 99.0, "shift": {"law": "arrhenius", "Ea": 1e5, "T_ref": 300.0}}, "[material] temperature",
     "which takes the material's times outside 1e-30 ... 1e+30 s"),
], ids=["no-shift", "no-temperature", "wlf-pole", "wlf-keys", "arrhenius-T_ref", "negative", "overflow",
        "times-out-of-scale"])
def test_bad_temperature_keys_are_refused_with_one_line(changes, key, allowed):
    with pytest.raises(SceneError) as info:
        parse_scene(with_material({**SCENE["material"], **changes}), source="t.toml")
    assert info.value.key == key and allowed in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(SceneError, match="not a key of model 'elastic'"):
        parse_scene(with_material({"model": "elastic", "E": 1e7, "nu": 0.5, "temperature": 300.0,
                                   "shift": WLF}))


def test_a_sweep_point_varies_the_temperature_and_reports_a_T():
    scene = parse_scene(with_material({**SCENE["material"], "temperature": 300.0, "shift": WLF}))
    point = point_scene(scene, "material.temperature", 310.0)
    assert point.shift_factor == pytest.approx(1.475133e-3, rel=1e-6)
    assert point.material.tau[0] == pytest.approx(scene.material.tau[0] * 1.475133e-3, rel=1e-6)


# -- time-temperature superposition in a rolling run --------------------------------------------------------
def test_rolling_at_T_is_rolling_at_T_ref_with_the_speed_times_a_T(comm, shared_dir):
    """mu_r(V, T) = mu_r(V a_T, T_ref): every time of the material is a_T times longer at T, and with
    steps_per_cell the time step dx / (V steps_per_cell) at speed V is a_T times the one at V a_T, so
    every dimensionless number of the discrete problem (dt / tau, V dt / dx, the body's positions)
    is the same: the two runs solve the same QPs up to round-off in a_T's products."""
    law = materials.make_shift(WLF)
    T = 302.0  # a_T = 10^(-17.44 x 2 / 53.6) = 0.2235
    a_T = materials.shift_factor(law, T)
    V = 0.05
    hot = parse_scene({**with_material({**SCENE["material"], "temperature": T, "shift": WLF}),
                       "motion": {"velocity": [V, 0.0], "penetration": 2e-5}})
    ref = parse_scene({**SCENE, "motion": {"velocity": [V * a_T, 0.0], "penetration": 2e-5}})
    one = petroll.run(hot, comm, out=shared_dir / "hot").series
    two = petroll.run(ref, comm, out=shared_dir / "ref").series
    assert len(one["t"]) == len(two["t"]) == 16  # 15 steps of one cell (80 um) after the start
    assert one["t"] == pytest.approx(two["t"] * a_T, rel=1e-12)
    assert np.ptp(one["mu_r"]) > 0.2 * np.max(one["mu_r"])  # a transient, not a trivial constant
    for name in ("mu_r", "force", "delta", "area", "p_max", "lead", "trail", "distance"):
        scale = np.max(np.abs(two[name]))  # (mu_r at the start is round-off about 0)
        assert np.max(np.abs(one[name] - two[name])) <= 1e-12 * scale, name  # measured: <= 5e-15
    assert np.array_equal(one["applications"], two["applications"])  # the very same solver path


# -- fitting a Prony series ------------------------------------------------------------------------------
@pytest.mark.parametrize("noise", [0.0, 0.0025])  # relative noise sigma; the recovered curves err by up
# to 0.8-1.3 sigma (10 seeds measured, docs/materials.md), so 0.5 % holds for sigma up to about 0.3 %
def test_fit_recovers_a_known_series_and_its_creep_compliance(noise):
    frequency = np.geomspace(1e-3, 1e8, 133)  # 12 per decade
    E = complex_modulus(frequency)
    rng = np.random.default_rng(18)
    storage = E.real * (1 + noise * rng.standard_normal(len(E)))
    loss = E.imag * (1 + noise * rng.standard_normal(len(E)))
    fit = dma.fit_prony(frequency, storage, loss, nu=0.5)
    assert all(m > 0 for m in fit.moduli) and list(fit.times) == sorted(fit.times)
    dense = np.geomspace(1e-3, 1e8, 2000)  # between the data points too
    exact = complex_modulus(dense)
    fitted_storage, fitted_loss = fit.dynamic(dense)
    assert np.max(np.abs(fitted_storage / exact.real - 1)) < 5e-3
    assert np.max(np.abs(fitted_loss / exact.imag - 1)) < 5e-3
    assert fit.rms_error < 3 * noise + 2e-3  # the reported error: that of the data
    t = np.concatenate([[0.0], np.geomspace(1e-10, 1e3, 400), [1e9]])
    J = materials.maxwell(TRUE_EINF, 0.5, TRUE_MODULI, TRUE_TIMES)(t)
    assert np.max(np.abs(fit.material()(t) / J - 1)) < 1e-2


def test_fit_options_and_refusals():
    frequency = np.geomspace(1e-2, 1e2, 20)
    E = complex_modulus(frequency)
    coarse = dma.fit_prony(frequency, E.real, E.imag, terms=3)
    assert coarse.candidates == 3 and len(coarse.moduli) <= 3
    # terms spread over the data's 1/(2 pi f), one decade beyond at each end
    assert dma.candidate_times(1e-2, 1e2, terms=3) == pytest.approx(
        [1e-1 / (2 * math.pi * 1e2), 1 / (2 * math.pi), 10 / (2 * math.pi * 1e-2)], rel=1e-12)
    assert dma.fit_prony(frequency, E.real, E.imag, per_decade=2).candidates == 13  # 6 decades x 2 + 1
    for kwargs, text in (({"terms": 2, "per_decade": 3}, "not both"), ({"nu": 0.6}, "nu = 0.6"),
                         ({"terms": 0}, "terms = 0")):
        with pytest.raises(dma.DMAError, match=text):
            dma.fit_prony(frequency, E.real, E.imag, **kwargs)
    with pytest.raises(dma.DMAError, match="no relaxed modulus"):
        wt = 2 * np.pi * frequency * 1e-3  # a Maxwell fluid (one term, no Einf): E' -> 0 at low frequency
        dma.fit_prony(frequency, 1e6 * wt**2 / (1 + wt**2), 1e6 * wt / (1 + wt**2))


def write_shifted_table(path: pathlib.Path, law) -> None:
    """The known series measured at 0.1 ... 100 Hz and 270 ... 330 K, each temperature shifted by ``law``."""
    lines = ["# a DMA table at several temperatures", "frequency,storage,loss,temperature"]
    for T in np.arange(270.0, 331.0, 10.0):
        f = np.geomspace(0.1, 100, 13)
        E = complex_modulus(f * materials.shift_factor(law, T))
        lines += [f"{a!r},{b.real!r},{b.imag!r},{T!r}" for a, b in zip(f, E)]
    path.write_text("\n".join(lines) + "\n")


def test_data_at_several_temperatures_are_shifted_onto_the_reference(tmp_path):
    law = materials.WLF(8.86, 101.6, 300.0)  # a_T from 10^3.71 (270 K) to 10^-2.02 (330 K)
    write_shifted_table(tmp_path / "dma.csv", law)
    data = dma.read_dma(tmp_path / "dma.csv", law)
    assert len(data.frequency) == 91 and data.reduced.min() == pytest.approx(0.1 * 10 ** (-8.86 * 30 / 131.6))
    fit = dma.fit_prony(data.reduced, data.storage, data.loss)
    dense = np.geomspace(data.reduced.min(), data.reduced.max(), 1000)
    exact, (storage, loss) = complex_modulus(dense), fit.dynamic(dense)
    assert np.max(np.abs(storage / exact.real - 1)) < 5e-3 and np.max(np.abs(loss / exact.imag - 1)) < 5e-3
    with pytest.raises(dma.DMAError, match="temperature column needs a shift law"):
        dma.read_dma(tmp_path / "dma.csv")


# -- the command ---------------------------------------------------------------------------------------------
def test_material_fit_writes_a_block_ready_to_paste_and_the_figure(comm, capsys, shared_dir):
    if comm.rank == 0:
        write_shifted_table(shared_dir / "dma.csv", materials.WLF(8.86, 101.6, 300.0))
    comm.barrier()
    code = main(["material", "fit", str(shared_dir / "dma.csv"), "--shift", "wlf:8.86,101.6,300", "--nu",
                 "0.49",
                 "--out", str(shared_dir / "material.toml")])
    assert code == 0
    out = capsys.readouterr().out
    # Without --out the block alone goes to stdout (ready to redirect), the report to stderr; the shift
    # law may come from a TOML file's [material] shift (here: the block just written)
    assert main(["material", "fit", str(shared_dir / "dma.csv"), "--shift", str(shared_dir / "material.toml"),
                 "--nu", "0.49", "--plot", str(shared_dir / "other.png")]) == 0
    printed = capsys.readouterr()
    here = sorted(pathlib.Path.cwd().iterdir())
    shift = str(shared_dir / "material.toml")
    assert main(["material", "fit", str(shared_dir / "dma.csv"), "--shift", shift]) == 0
    assert sorted(pathlib.Path.cwd().iterdir()) == here  # no figure dropped into the current directory
    assert "plot: none" in capsys.readouterr().err or comm.rank != 0
    if comm.rank != 0:
        assert out == printed.out == printed.err == ""  # only rank 0 works and speaks
        return
    assert "7 sets (temperatures within 0.5 K of their neighbours)" in out and "relative error rms" in out
    assert "7 sets shifted to T_ref = 300 K" in out
    text = (shared_dir / "material.toml").read_text()
    block = tomllib.loads(text)["material"]
    assert block["temperature"] == 300.0 and block["shift"] == {"law": "wlf", "C1": 8.86, "C2": 101.6,
                                                                 "T_ref": 300.0}
    assert block["model"] == "prony" and block["series"] == "maxwell" and block["nu"] == 0.49
    scene = parse_scene(with_material(block))  # pasted into a scene as it is
    data = dma.read_dma(shared_dir / "dma.csv", materials.WLF(8.86, 101.6, 300.0))
    fit = dma.fit_prony(data.reduced, data.storage, data.loss, nu=0.49)  # the Python API: the same fit
    t = np.geomspace(1e-8, 1e3, 50)
    assert scene.material(t) == pytest.approx(fit.material()(t), rel=1e-12)
    assert (shared_dir / "material.png").read_bytes()[:8] == PNG_MAGIC  # beside --out
    assert not [p for p in shared_dir.iterdir() if ".tmp" in p.name]  # atomic writes leave no temporary files
    assert printed.out == text and "relative error rms" in printed.err
    assert (shared_dir / "other.png").read_bytes()[:8] == PNG_MAGIC


@pytest.mark.parametrize("content, line, allowed", [
    ("frequency,storage\n1,2e6\n", 1, "missing column 'loss'"),
    ("# DMA\nfrequency,storage,loss,tempreature\n1,2e6,1e5,300\n", 2, "unknown column 'tempreature'"),
    ("frequency,storage,loss\n1,2e6,1e5\n-2,2e6,1e5\n", 3, "frequency = '-2': must be a finite number > 0 (Hz)"),
    ("frequency,storage,loss\n1,2e6,1e5\n2,nan,1e5\n", 3, "storage = 'nan': must be a finite number > 0 (Pa)"),
    ("frequency,storage,loss\n1,2e6,1e5\n2,2e6\n", 3, "2 values for the 3 columns"),
    ("frequency,storage,loss,temperature\n1,2e6,1e5,300\n2,2e6,1e5,310\n0.5,2e6,1e5,0\n", 4,
     "temperature = '0': must be a finite number > 0 (K)"),
], ids=["missing", "unknown", "negative", "nan", "short-row", "temperature"])
def test_bad_dma_files_are_refused_with_one_line_naming_file_and_line(comm, capsys, content, line, allowed,
                                                                      shared_dir):
    if comm.rank == 0:
        (shared_dir / "bad.csv").write_text(content)
    comm.barrier()
    argv = ["material", "fit", str(shared_dir / "bad.csv"), "--out", str(shared_dir / "m.toml")]
    if "temperature" in content:
        argv += ["--shift", "wlf:8.86,101.6,300"]
    assert main(argv) == 2
    if comm.rank == 0:
        err = capsys.readouterr().err
        lines = [text for text in err.splitlines() if text.strip()]
        bad = shared_dir / "bad.csv"
        assert len(lines) == 1 and lines[0].startswith(f"petroll: error: {bad}, line {line}: "), err
        assert allowed in lines[0] and "Traceback" not in err
        assert sorted(p.name for p in shared_dir.iterdir()) == ["bad.csv"]  # nothing written


def test_the_shipped_example_is_the_fit_of_the_shipped_table():
    """runs/sphere-dma.toml's [material] is what ``petroll material fit`` gives for runs/rubber-dma.csv."""
    root = pathlib.Path(__file__).resolve().parents[1] / "runs"
    law = dma.parse_shift("wlf:8.86,101.6,293.15")
    data = dma.read_dma(root / "rubber-dma.csv", law)
    fit = dma.fit_prony(data.reduced, data.storage, data.loss)
    shipped = tomllib.loads((root / "sphere-dma.toml").read_text())["material"]
    assert close_tree({k: v for k, v in shipped.items() if k not in ("Einf", "moduli", "times")},
                      {k: v for k, v in fit.table(law).items() if k not in ("Einf", "moduli", "times")}, rel=1e-12)
    f = np.geomspace(data.reduced.min(), data.reduced.max(), 500)  # the same curves (NNLS may differ in
    ours, theirs = fit.dynamic(f), dma.storage_loss(shipped["Einf"], shipped["moduli"], shipped["times"], f)
    assert np.allclose(ours, theirs, rtol=1e-4, atol=0)  # round-off between scipy versions)
    assert len(data.frequency) == 143 and fit.rms_error < 0.012  # 1 % noise in the synthetic table


@pytest.mark.parametrize("column, value, allowed", [
    ("storage", "1e-320", "storage = '1e-320': 9.99989e-321 Pa is outside what petroll computes with"),
    ("loss", "1e-320", "loss = '1e-320': 9.99989e-321 Pa is outside"),
    ("frequency", "1e300", "frequency = '1e300': 1e+300 Hz is outside what petroll computes with"),
    ("frequency", "5e-324", "frequency = '5e-324': 4.94066e-324 Hz is outside"),
], ids=["storage-1e-320", "loss-1e-320", "frequency-1e300", "frequency-5e-324"])
def test_dma_values_beyond_double_precision_are_refused_in_one_line_without_warnings(tmp_path, cli_main, column,
                                                                                   value, allowed):
    """Were an OverflowError (prony_fit), a ValueError from NNLS, or a refusal after a numpy overflow
    warning naming no file (issue 35): one line naming the file, the line and the bound."""
    lines = (ROOT / "runs" / "rubber-dma.csv").read_text().splitlines()
    header = next(k for k, text in enumerate(lines) if text.startswith("frequency"))
    fields = lines[header + 3].split(",")
    fields[["frequency", "storage", "loss"].index(column)] = value
    lines[header + 3] = ",".join(fields)
    (tmp_path / "t.csv").write_text("\n".join(lines) + "\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code, _, err = cli_main(["material", "fit", str(tmp_path / "t.csv"), "--shift", "wlf:8.86,101.6,293.15"])
    said = [text for text in err.splitlines() if text.strip()]
    assert code == 2
    if MPI.COMM_WORLD.rank:  # rank 0 fits and says why not
        return
    assert len(said) == 1, err
    assert said[0].startswith(f"petroll: error: {tmp_path / 't.csv'}, line {header + 4}: ") and allowed in said[0]


def test_the_fit_refuses_values_it_cannot_compute_with():
    """The Python API: moduli of 1e-320 Pa (an OverflowError, then a ValueError from NNLS), frequencies of
    1e31 Hz, --einf 1e300, more than 2000 candidate times (issue 35)."""
    frequency = np.geomspace(1e-2, 1e2, 20)
    E = complex_modulus(frequency)
    for args, kwargs, text in (((frequency, np.full(20, 1e-320), E.imag), {}, "outside what petroll computes"),
                               ((np.geomspace(1e29, 1e31, 20), E.real, E.imag), {}, "e+30 Hz or Pa is outside what"),
                               ((frequency, E.real, E.imag), {"einf": 1e300}, "--einf 1e+300"),
                               ((frequency, E.real, E.imag), {"terms": 2001}, "at most 2000"),
                               ((frequency, E.real, E.imag), {"per_decade": 400.0}, "gives 2401 candidate")):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(dma.DMAError, match=re.escape(text)):
                dma.fit_prony(*args, **kwargs)
