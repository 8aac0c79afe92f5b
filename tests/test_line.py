"""Line contact (plane strain; docs/line-contact.md): the strip kernel against quadrature, plane-strain
Hertz, the datum's irrelevance under load control, the scene contract, results per unit length, restart
and rank-count independence. Viscoelastic checks: tests/test_line_rolling.py.
"""

import math

import h5py
import numpy as np
import pytest
from mpi4py import MPI
from scipy.integrate import quad

from petroll.driver import run
from petroll.errors import SceneError
from petroll.io.checkpoint import read_checkpoint
from petroll.model.grid import line_grid
from petroll.model.scene import parse_scene
from petroll.solver.influence import Convolution, dense_influence, influence_operator
from petroll.solver.kernels.love import strip_coefficients
from petroll.solver.simulation import Simulation

E, NU, R = 1e7, 0.3, 0.01
J = (1 - NU**2) / E
ELASTIC = {"model": "elastic", "E": E, "nu": NU}
SLS = {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_creep": 0.01}


def hertz(load: float, compliance: float = J, radius: float = R) -> tuple[float, float]:
    """Plane-strain Hertz (Johnson 1985, Eq. 4.43): half-width a and peak pressure p0 for a load per
    length (N/m) on a cylinder."""
    a = math.sqrt(4 * load * radius * compliance / math.pi)
    return a, 2 * load / (math.pi * a)


def line_raw(nx=128, extent=(-2e-3, 2e-3), load=1000.0, material=None, **sections) -> dict:
    raw = {"grid": {"nx": nx, "x": list(extent)}, "material": dict(material or ELASTIC),
           "body": {"shape": "cylinder", "radius": R}, "motion": {"load": load}}
    raw.update(sections)
    return raw


def first_step(raw: dict, comm) -> tuple[Simulation, object]:
    sim = Simulation(parse_scene(raw, source="test_line"), comm)
    return sim, next(sim.steps())


def whole(sim) -> np.ndarray:
    """The pressure on every rank, shape (nx,)."""
    return np.concatenate(sim.comm.allgather(sim.pressure[:, 0]))


# -- the operator -----------------------------------------------------------------------------------------
def test_strip_kernel_is_the_quadrature_of_the_logarithmic_kernel_and_positive_definite():
    dx, n = 1e-4, 40
    datum = n * dx
    table = strip_coefficients(n, dx, datum)
    for k in (0, 1, 2, 7, n - 1):
        x = k * dx
        exact = quad(lambda s: -(2 / math.pi) * math.log(abs(x - s) / datum), -dx / 2, dx / 2,
                     points=[x] if k == 0 else None, limit=200)[0]
        assert table[k] == pytest.approx(exact, rel=1e-10, abs=1e-18)
    dense = dense_influence(table[:, None])
    assert table.min() > 0  # the datum at the grid's length: every coefficient positive
    assert np.linalg.eigvalsh(dense).min() > 0.1 * table[0]  # and positive definite
    # a datum below a quarter of the loaded length (the segment's logarithmic capacity) is not
    small = dense_influence(strip_coefficients(n, dx, 0.2 * datum)[:, None])
    assert np.linalg.eigvalsh(small).min() < 0


def test_line_fft_operator_is_the_dense_strip_matrix_on_any_rank_count(comm):
    grid = line_grid(37, -1e-3, 2.7e-3)
    op = influence_operator(grid, comm)
    dense = dense_influence(strip_coefficients(37, grid.dx, grid.datum)[:, None])
    field = np.random.default_rng(3).random((37, 1))
    conv = op.window(37, 1)
    local = conv(field[conv.r0 : conv.r1])
    got = np.concatenate(comm.allgather(local[:, 0]))
    assert np.allclose(got, dense @ field[:, 0], rtol=1e-12, atol=1e-12 * np.abs(dense @ field[:, 0]).max())
    # the preconditioner's inverse circulant is positive on every window of the grid
    for m in (1, 2, 5, 37):
        inverse = Convolution(strip_coefficients(m, grid.dx, grid.datum)[:, None], m, 1, comm, inverse=True)
        assert comm.allreduce(float(inverse.spectrum.min(initial=np.inf)), op=MPI.MIN) > 0


# -- plane-strain Hertz ------------------------------------------------------------------------------------
@pytest.mark.parametrize("nx", [64, 256])
def test_plane_strain_hertz_width_peak_and_elliptic_profile(nx, comm):
    """Half-width within one strip, peak and profile within the grid's accuracy (the profile's error is at
    the edges, where the ellipse's slope is infinite), penetration relative to the datum L = grid length:
    delta = (2 J P/pi) (ln(2 L/a) + 1/2) (the Hertz pressure's displacement at the centre)."""
    load = 1000.0
    a, p0 = hertz(load)
    sim, rec = first_step(line_raw(nx=nx, extent=(-2 * a, 2 * a), load=load, solver={"tol": 1e-10}), comm)
    dx = sim.scene.grid.dx
    assert rec.force == pytest.approx(load, rel=1e-8)
    assert abs(rec.area / 2 - a) <= dx and abs(rec.lead - a) <= dx and abs(rec.trail + a) <= dx
    assert rec.p_max == pytest.approx(p0, rel=2e-3)
    x = sim.scene.grid.x
    p = whole(sim)
    ellipse = p0 * np.sqrt(np.maximum(1 - x**2 / a**2, 0.0))
    inner = np.abs(x) < 0.8 * a
    assert np.abs(p - ellipse)[inner].max() <= 5e-3 * p0
    assert np.sqrt(np.mean((p - ellipse) ** 2)) <= 0.06 * p0 * (dx / a) ** 0.5
    L = sim.scene.grid.datum
    assert rec.delta == pytest.approx(2 * J * load / math.pi * (math.log(2 * L / a) + 0.5), rel=2e-3)
    assert rec.mu_r == pytest.approx(0.0, abs=1e-12) and rec.cop_x == pytest.approx(0.0, abs=1e-3 * dx)


def test_pressure_does_not_depend_on_the_datum_under_load_control(comm):
    """Two grids with the same strips, one three times as long (datum L x 3): the same pressure on the
    common strips (to the solver's tolerance), the penetration shifted by exactly (2 J P/pi) ln 3."""
    load, dx = 500.0, 2e-5
    short = line_raw(nx=200, extent=(-100 * dx, 100 * dx), load=load, solver={"tol": 1e-11})
    long = line_raw(nx=600, extent=(-300 * dx, 300 * dx), load=load, solver={"tol": 1e-11})
    s1, r1 = first_step(short, comm)
    s3, r3 = first_step(long, comm)
    p1, p3 = whole(s1), whole(s3)
    assert np.abs(p3[200:400] - p1).max() <= 1e-8 * p1.max()
    assert not p3[:200].any() and not p3[400:].any()
    assert r3.delta - r1.delta == pytest.approx(2 * J * load / math.pi * math.log(3), rel=1e-6)


# -- the scene contract -----------------------------------------------------------------------------------
@pytest.mark.parametrize("change, key, words", [
    ({"motion": {"penetration": 1e-5}}, "[motion] penetration", "datum"),
    ({"motion": {"load": 100.0, "velocity": [0.01, 0.001]}}, "[motion] velocity", "along X only"),
    ({"body": {"shape": "cylinder", "radius": R, "width": 0.01}}, "[body] width", "line contact"),
    ({"body": {"shape": "sphere", "radius": R}}, "[body] shape", "line contact"),
    ({"grid": {"nx": 10, "ny": 10, "x": [-1e-3, 1e-3]}}, "[grid] y", "neither"),
])
def test_line_scene_refusals_name_the_key_and_why(change, key, words):
    raw = line_raw()
    raw.update(change)
    with pytest.raises(SceneError) as info:
        parse_scene(raw, source="s.toml")
    assert info.value.key == key and words in str(info.value)


def test_velocity_as_a_number_or_a_program_of_numbers_moves_along_x():
    for velocity, at in ((0.02, 0.02), ({"kind": "ramp", "start": 0.0, "end": 0.04, "duration": 1.0}, 0.02),
                         ([0.02, 0.0], 0.02)):
        scene = parse_scene(line_raw(motion={"load": 100.0, "velocity": velocity}))
        assert np.allclose(scene.velocity(0.5), [at, 0.0])
    assert scene.grid.line and scene.grid.ny == 1 and scene.grid.cell_area == scene.grid.dx


def test_heightmap_profile_is_a_cylinder_sampled(comm, shared_dir):
    """A 1-D .npy profile sampling the cylinder's arc finely gives the cylinder's answer."""
    dx = 4e-3 / 128
    s = np.arange(-400, 401) * (dx / 4)
    if comm.rank == 0:
        np.save(shared_dir / "profile.npy", R - np.sqrt(R**2 - s**2) + 1e-3)
    comm.Barrier()
    raw = line_raw(body={"shape": "heightmap", "file": "profile.npy", "cell": dx / 4})
    scene = parse_scene(raw, base_dir=shared_dir)
    sim_map = Simulation(scene, comm)
    next(sim_map.steps())
    sim_cyl, rec_cyl = first_step(line_raw(), comm)
    assert np.abs(whole(sim_map) - whole(sim_cyl)).max() <= 1e-3 * rec_cyl.p_max
    bad = shared_dir / "map2d.npy"
    if comm.rank == 0:
        np.save(bad, np.zeros((4, 4)))
    comm.Barrier()
    with pytest.raises(SceneError, match="1-D array"):
        parse_scene(line_raw(body={"shape": "heightmap", "file": "map2d.npy", "cell": dx}),
                    base_dir=shared_dir)


# -- results, restart, ranks ------------------------------------------------------------------------------
def rolling_raw(out=None) -> dict:
    return line_raw(nx=160, extent=(-1.5e-3, 2.5e-3), load=200.0, material=SLS,
                    motion={"load": 200.0, "velocity": 0.05},
                    time={"steps_per_cell": 1, "distance": 0.5e-3},
                    solver={"tol": 1e-11}, output={"every": 4, "checkpoint_every": 5, "keep": 10})


@pytest.mark.slow
def test_results_are_per_unit_length_and_a_restart_is_bitwise(comm, shared_dir):
    scene = parse_scene(rolling_raw(), source="roll")
    reference = run(scene, comm, shared_dir / "reference")
    assert reference.line and reference.pressure.shape[1:] == (160, 1)
    assert "force_y" not in reference.series and "cop_y" not in reference.series
    with h5py.File(shared_dir / "reference" / "results.h5", "r") as f:
        assert f["series/force"].attrs["units"] == "N/m" and f["series/area"].attrs["units"] == "m"
        assert f.attrs["line_contact"]
    assert np.allclose(reference.series["force"], 200.0, rtol=1e-9)
    # the contact width is the number of loaded strips times dx
    dx = scene.grid.dx
    last = reference.pressure[-1, :, 0]
    assert reference.series["area"][-1] == pytest.approx((last > 0).sum() * dx)
    check = read_checkpoint(shared_dir / "reference" / "checkpoints" / "step-00000005.h5", comm)
    again = run(scene, comm, shared_dir / "again", restart=check)
    for name in reference.series:
        if name != "solve_time":
            assert np.array_equal(again.series[name], reference.series[name], equal_nan=True), name
    assert np.array_equal(again.pressure, reference.pressure)
    if comm.rank == 0:  # the figures of a line-contact run: profiles instead of maps
        from petroll.plot import plot_results

        written = plot_results(shared_dir / "reference")
        assert [p.name for p in written] == ["pressure.png", "patches.png", "series.png"]
        assert all(p.stat().st_size > 10000 for p in written)


@pytest.mark.slow
@pytest.mark.parallel
def test_two_ranks_agree_with_one(comm, shared_dir):
    scene = parse_scene(rolling_raw(), source="roll")
    two = run(scene, comm, shared_dir / "two")
    one = None
    if comm.rank == 0:
        one = run(scene, MPI.COMM_SELF, shared_dir / "one")
    one = comm.bcast(None if one is None else (one.series, one.pressure), root=0)
    series, pressure = one
    for name in ("force", "force_x", "mu_r", "delta", "p_max", "lead", "trail", "cop_x"):
        scale = np.abs(series[name]).max() if name != "force_x" else np.abs(series["force"]).max()
        assert np.abs(two.series[name] - series[name]).max() <= 1e-9 * scale, name
    assert np.abs(two.pressure - pressure).max() <= 1e-9 * np.abs(pressure).max()


def test_command_line_speaks_per_unit_length_and_refuses_a_penetration(comm, shared_dir, capsys):
    """`petroll run` of a line scene: the summary gives N/m and the contact width; a penetration is one
    line `petroll: error:` naming the key and why, exit 2."""
    from petroll.cli import main

    if comm.rank == 0:
        (shared_dir / "line.toml").write_text('[grid]\nnx = 64\nx = [-2e-3, 2e-3]\n\n[material]\n'
                                              'model = "elastic"\nE = 1e7\nnu = 0.3\n\n[body]\n'
                                              'shape = "cylinder"\nradius = 0.01\n\n'
                                              '[motion]\nload = 1000.0\n')
        text = (shared_dir / "line.toml").read_text()
        (shared_dir / "bad.toml").write_text(text.replace("load = 1000.0", "penetration = 1e-5"))
    comm.Barrier()
    assert main(["run", str(shared_dir / "line.toml"), "--out", str(shared_dir / "out")]) == 0
    out = capsys.readouterr().out
    if comm.rank == 0:
        assert "force 1000 N/m" in out and "contact width" in out and "m^2" not in out
    assert main(["run", str(shared_dir / "bad.toml"), "--out", str(shared_dir / "bad")]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    if comm.rank == 0:
        assert len(err) == 1 and err[0].startswith("petroll: error:") and "[motion] penetration" in err[0]
        assert "datum" in err[0] and "N/m" in err[0]


def test_steep_contact_warns_with_the_estimated_half_width():
    """a/R = 0.4 (relaxed Hertz for the load per length): the small-slope warning names the half-width."""
    from petroll.model.limits import PetrollWarning

    load = math.pi * (0.4 * R) ** 2 / (4 * R * J)
    with pytest.warns(PetrollWarning, match=r"half-width 0\.004 m \(line contact\)"):
        parse_scene(line_raw(extent=(-0.01, 0.01), load=load))
