"""Stresses below the surface (``petroll stress``) against closed forms: the influence coefficients of a
loaded cell against quadrature of Boussinesq's point load, a Hertz step's stresses on the axis and its
maximum shear (Johnson 1985, §3.4), the far field of a small patch against a point load, ranks; line
contact: the strip's coefficients against Flamant's line load, a cylinder against McEwen's closed form."""

import pathlib

import h5py
import numpy as np
import pytest
from mpi4py import MPI
from scipy import integrate, optimize

import petroll
from petroll.cli import main
from petroll.driver import run
from petroll.errors import PetrollError
from petroll.model.scene import parse_scene
from petroll.solver.partition import RowPartition
from petroll.solver.stress import SubsurfaceStress, cell_stress, max_shear, von_mises


def point_load(x, y, z, nu):
    """Boussinesq: the stresses (6, ...) xx, yy, zz, xy, xz, yz at (x, y, z) below a unit compressive point
    load at the origin, tension positive (Johnson 1985, §3.2; the xy term in the form 1/(rho (rho + z)))."""
    r2 = x * x + y * y
    rho = np.sqrt(r2 + z * z)
    c = 1 / (rho * (rho + z))  # = (1 - z/rho) / r^2
    sxx = ((1 - 2 * nu) * (c * (x * x - y * y) / r2 + z * y * y / (r2 * rho**3)) - 3 * z * x * x / rho**5)
    syy = ((1 - 2 * nu) * (c * (y * y - x * x) / r2 + z * x * x / (r2 * rho**3)) - 3 * z * y * y / rho**5)
    szz = -3 * z**3 / rho**5
    sxy = (1 - 2 * nu) * x * y * (2 * rho + z) / (rho**3 * (rho + z) ** 2) - 3 * x * y * z / rho**5
    sxz, syz = -3 * x * z * z / rho**5, -3 * y * z * z / rho**5
    return np.array([sxx, syy, szz, sxy, sxz, syz]) / (2 * np.pi)


def hertz_axis(z, nu):
    """Hertz pressure p0 sqrt(1 - r^2/a^2) on a half-space: sigma_r (= sigma_theta) and sigma_z on the axis,
    in units of p0, at depth z in units of a (Johnson 1985, §3.4)."""
    z = np.asarray(z, dtype=float)
    return -(1 + nu) * (1 - z * np.arctan(1 / z)) + 0.5 / (1 + z * z), -1 / (1 + z * z)


@pytest.mark.slow
@pytest.mark.parametrize("offset", [(0, 0, 0.3), (1, 2, 0.5), (-2, 1, 1.3), (3, -1, 0.05), (0, 0, 2.0)])
def test_cell_coefficients_are_the_integral_of_the_point_load(offset):
    """The closed-form stresses below a loaded dx x dy cell equal the quadrature of Boussinesq's point load
    over the cell (split at the point's vertical so the integrand's axis is never sampled)."""
    dx, dy, nu = 1.0, 0.7, 0.3
    ix, iy, z = offset
    x, y = ix * dx, iy * dy
    closed = cell_stress(np.array(x), np.array(y), z, dx, dy, nu)
    assert np.max(np.abs(closed - cell_quadrature(point_load, x, y, z, dx, dy, nu))) < 1e-11


def cell_quadrature(point, x, y, z, dx, dy, nu) -> np.ndarray:
    """The six stresses ``point(x, y, z, nu)`` of a point load integrated over a dx x dy cell centred at the
    origin, at (x, y, z): adaptive quadrature split at the point's vertical (the integrand's axis is never
    sampled)."""
    return np.array([sum(integrate.dblquad(lambda v, u: point(x - u, y - v, z, nu)[c], u0, u1, v0, v1,
                                           epsabs=1e-13, epsrel=1e-11)[0]
                         for u0, u1 in ((-dx / 2, 0), (0, dx / 2)) for v0, v1 in ((-dy / 2, 0), (0, dy / 2)))
                     for c in range(6)])


def test_surface_carries_the_pressure_and_no_shear(comm):
    """At z = 0 every cell centre has sigma_zz = -p and sigma_xz = sigma_yz = 0 (the boundary conditions)."""
    nx, ny = 12, 9
    rows = RowPartition(nx, comm.size)
    r0, r1 = rows.range(comm.rank)
    p = np.random.default_rng(3).uniform(0, 2e6, (nx, ny))
    s = SubsurfaceStress(nx, ny, 1e-4, 2e-4, 0.3, comm).at(p[r0:r1], 0.0)
    assert np.max(np.abs(s[2] + p[r0:r1])) < 1e-9 * 2e6
    assert np.max(np.abs(s[4:])) < 1e-9 * 2e6


def hertz_scene(nu: float = 0.3):
    """A sphere (R = 10 mm) pressed 25 um into an elastic half-space: a = 0.5 mm = 16 cells (odd grid: a cell
    centre on the axis)."""
    dx = 0.5e-3 / 16
    half = 49 * dx / 2
    return parse_scene({
        "grid": {"nx": 49, "ny": 49, "x": [-half, half], "y": [-half, half]},
        "material": {"model": "elastic", "E": 10e6, "nu": nu},
        "body": {"shape": "sphere", "radius": 0.01},
        "motion": {"penetration": 25e-6},
    }, source="test_stress")


@pytest.mark.slow
def test_hertz_stresses_on_the_axis_and_the_maximum_shear(comm, shared_dir):
    """a/dx = 16, nu = 0.3: on the axis sigma_r = sigma_theta and sigma_z within 0.2 % of p0 of the closed
    form from z = 0.1 a to 2 a; the maximum shear (Tresca) 0.3100 p0 at z = 0.481 a (the closed form's
    maximum, the known 0.31 p0 at 0.48 a) and the von Mises maximum (twice it, on the axis) within 0.2 %,
    located on the axis within half a depth step. (The issue asks 1 %; measured: 1.2e-4 p0 on the axis,
    1.1e-4 relative on the maximum.)"""
    nu, a, R, delta = 0.3, 0.5e-3, 0.01, 25e-6
    run(hertz_scene(nu), comm, shared_dir)
    p0 = 2 * np.sqrt(delta / R) * 10e6 / (np.pi * (1 - nu**2))
    z = a * np.linspace(0.1, 2.0, 77)  # 0.025 a apart
    found = petroll.stress(shared_dir, depths=z, comm=comm)
    assert found.path == shared_dir / "stress.h5" and found.step == 0 and found.nu == nu
    with h5py.File(found.path, "r") as f:
        assert f["sigma_xx"].shape == (77, 49, 49) and f.attrs["motion_axis"] == "x"
        axis = {name: f[name][:, 24, 24] for name in ("sigma_xx", "sigma_yy", "sigma_zz", "max_shear")}
        assert np.allclose(f["z"][()], z, rtol=0, atol=1e-15)
    sigma_r, sigma_z = hertz_axis(z / a, nu)
    for name, exact in (("sigma_xx", sigma_r), ("sigma_yy", sigma_r), ("sigma_zz", sigma_z)):
        assert np.max(np.abs(axis[name] / p0 - exact)) < 0.002, name
    deepest = optimize.minimize_scalar(lambda s: 0.5 * np.diff(hertz_axis(s, nu))[0], bounds=(0.2, 1.0),
                                       method="bounded")
    tau, z_tau = -deepest.fun, deepest.x
    assert abs(tau - 0.31) < 0.0005 and abs(z_tau - 0.48) < 0.005  # the known values
    assert abs(found.max_shear_max / (tau * p0) - 1) < 0.002
    assert abs(found.von_mises_max / (2 * tau * p0) - 1) < 0.002  # on the axis |sigma_r - sigma_z| = 2 tau
    x, y, zm = found.max_shear_at
    assert abs(x) < 1e-12 and abs(y) < 1e-12 and abs(zm / a - z_tau) <= 0.0125 + 1e-9
    assert found.max_shear_max == pytest.approx(np.max(axis["max_shear"]), rel=1e-12)


def test_far_field_decays_like_a_point_load(comm):
    """Below a small loaded patch (4 x 4 cells of unequal pressures), at depths of 10 and 20 times its size,
    every component equals the point load's of the same force to O((patch/z)^2), here within 1 % of the
    point load's largest stress at that depth (the patch's centre of pressure is the load point)."""
    nx = ny = 161
    dx = 1.0
    rows = RowPartition(nx, comm.size)
    r0, r1 = rows.range(comm.rank)
    p = np.zeros((nx, ny))
    p[79:83, 79:83] = np.random.default_rng(5).uniform(0.5, 1.5, (4, 4))
    force = p.sum() * dx * dx
    c = (np.arange(nx) - 80) * dx
    cx, cy = (p.sum(1) @ c) / p.sum(), (p.sum(0) @ c) / p.sum()
    solver = SubsurfaceStress(nx, ny, dx, dx, 0.25, comm)
    for z in (40.0, 80.0):
        s = solver.at(p[r0:r1], z)
        X, Y = np.meshgrid(c[r0:r1] - cx, c - cy, indexing="ij")
        exact = force * point_load(X + 1e-9, Y + 1e-9, z, 0.25)
        scale = force * 3 / (2 * np.pi * z * z)  # |sigma_zz| on the axis
        error = comm.allreduce(float(np.max(np.abs(s - exact), initial=0.0)), op=MPI.MAX)
        assert error < 0.01 * scale, (z, error / scale)


@pytest.mark.parallel
def test_two_ranks_agree_with_one_to_round_off(comm):
    """The stresses, von Mises and Tresca fields and their maxima of an asymmetric pressure field (a random
    patch) are the same on 2 ranks as on 1 (each rank recomputes the whole on COMM_SELF)."""
    nx, ny, dx, dy, nu = 21, 14, 1e-4, 1.5e-4, 0.35
    p = np.zeros((nx, ny))
    p[5:15, 3:11] = np.random.default_rng(9).uniform(0, 1e6, (10, 8))
    r0, r1 = RowPartition(nx, comm.size).range(comm.rank)
    many = SubsurfaceStress(nx, ny, dx, dy, nu, comm)
    one = SubsurfaceStress(nx, ny, dx, dy, nu, MPI.COMM_SELF)
    for z in (0.0, 1e-4, 7e-4):
        s_many, s_one = many.at(p[r0:r1], z), one.at(p, z)[:, r0:r1]
        assert np.max(np.abs(s_many - s_one)) < 1e-9 * 1e6 * 1e-3
        assert np.max(np.abs(von_mises(s_many) - von_mises(s_one))) < 1e-12 * 1e6
        assert np.max(np.abs(max_shear(s_many) - max_shear(s_one))) < 1e-12 * 1e6


def write_patch_results(directory: pathlib.Path, scene_material: str) -> np.ndarray:
    """A results.h5 holding one saved field, a random patch on a 21 x 14 grid (rank 0 writes)."""
    from petroll.io.results import ResultsFile
    from petroll.records import SERIES, StepRecord

    nx, ny = 21, 14
    p = np.zeros((nx, ny))
    p[5:15, 3:11] = np.random.default_rng(9).uniform(0, 1e6, (10, 8))
    text = ("[grid]\nnx = 21\nny = 14\nx = [0.0, 2.1e-3]\ny = [-1.05e-3, 1.05e-3]\n\n[material]\n"
            f"{scene_material}\n")
    if MPI.COMM_WORLD.rank == 0:
        x, y = (np.arange(nx) + 0.5) * 1e-4, -1.05e-3 + (np.arange(ny) + 0.5) * 1.5e-4
        records = [StepRecord(**{name: 0 for name in SERIES} | {"step": k, "t": 0.1 * k})
                   for k in range(5)]
        out = ResultsFile(directory / "results.h5", text, x, y, MPI.COMM_SELF)
        out.append(records[:4])
        out.append(records, {"pressure": p}, complete=True)
    MPI.COMM_WORLD.Barrier()
    return p


@pytest.mark.parallel
def test_the_stress_file_is_the_same_on_two_ranks_and_one(comm, shared_dir):
    for name in ("two", "one"):
        (shared_dir / name).mkdir(exist_ok=True)
        write_patch_results(shared_dir / name, 'model = "elastic"\nE = 1e7\nnu = 0.35')
    two = petroll.stress(shared_dir / "two", depths=[0.0, 1e-4, 3e-4], comm=comm)
    if comm.rank == 0:
        one = petroll.stress(shared_dir / "one", depths=[0.0, 1e-4, 3e-4], comm=MPI.COMM_SELF)
        assert two.max_shear_max == pytest.approx(one.max_shear_max, rel=1e-12)
        with h5py.File(two.path) as f, h5py.File(one.path) as g:
            for name in ("von_mises", "max_shear"):  # where 2 ranks found the maximum, 1 rank's field has it
                at, field = getattr(two, f"{name}_at"), g[name][()]  # (a tie within round-off may pick either)
                k, i, j = (int(np.argmin(np.abs(g[axis][()] - v))) for axis, v in zip("zxy", (at[2], at[0], at[1])))
                assert field[k, i, j] == pytest.approx(field.max(), rel=1e-12), name
            for name in ("sigma_xx", "sigma_yz", "von_mises", "max_shear"):
                assert np.max(np.abs(f[name][()] - g[name][()])) < 1e-12 * 1e6, name


@pytest.mark.slow
def test_command_writes_the_file_and_figure_and_refuses_bad_requests(comm, capsys, shared_dir):
    p = write_patch_results(shared_dir, 'model = "elastic"\nE = 1e7\nnu = 0.35')
    assert main(["stress", str(shared_dir), "--depth", "2e-4,0,1e-4"]) == 0
    if comm.rank == 0:
        out = capsys.readouterr().out
        assert "at 3 depths from 0 to 0.0002 m" in out and str(shared_dir / "stress.png") in out
        assert (shared_dir / "stress.png").read_bytes()[:4] == b"\x89PNG"
        with h5py.File(shared_dir / "stress.h5") as f:
            assert list(f["z"][()]) == [0.0, 1e-4, 2e-4]  # sorted
            assert np.allclose(f["sigma_zz"][0], -p, rtol=0, atol=1e-9)  # the surface carries -p
            vm = f["von_mises"][()]
            k, i, j = np.unravel_index(np.argmax(vm), vm.shape)
            assert f.attrs["von_mises_max"] == vm[k, i, j]
            assert tuple(f.attrs["von_mises_at"]) == (f["x"][i], f["y"][j], f["z"][k])
            assert f.attrs["step"] == 4 and f.attrs["t"] == pytest.approx(0.4) and f.attrs["nu"] == 0.35
    for argv, words in ((["--step", "3"], "--step 3: no pressure field saved at that step"),
                        (["--depth=-1e-4"], "argument --depth: expected comma-separated depths >= 0 in m"),
                        (["--depths", "deep"], "argument --depths: invalid choice: 'deep'"),
                        (["--nu", "0.7"], "--nu 0.7: Poisson's ratio must be a number with -1 < nu <= 0.5")):
        capsys.readouterr()
        try:
            code = main(["stress", str(shared_dir), *argv])
        except SystemExit as exc:  # argparse's own errors
            code = exc.code
        assert code == 2
        err = capsys.readouterr().err
        if comm.rank == 0:
            lines = err.strip().splitlines()
            assert len(lines) == 1 and lines[0].startswith("petroll: error: ") and words in lines[0], err
    with pytest.raises(PetrollError, match="depths must be finite numbers >= 0"):
        petroll.stress(shared_dir, depths=[1e-4, -1e-4], comm=comm)
    if comm.rank == 0:
        (shared_dir / "J").mkdir()
    comm.Barrier()
    write_patch_results(shared_dir / "J", 'model = "tabulated"\nfile = "J.csv"\nquantity = "J"')
    assert main(["stress", str(shared_dir / "J")]) == 2
    if comm.rank == 0:
        assert "[material] nu: the run's scene gives no Poisson's ratio" in capsys.readouterr().err
    assert main(["stress", str(shared_dir / "J"), "--nu", "0.5"]) == 0
    if comm.rank == 0:
        (shared_dir / "layer").mkdir()
    comm.Barrier()
    write_patch_results(shared_dir / "layer",
                        'model = "elastic"\nE = 1e7\nnu = 0.3\nlayer = {thickness = 1e-3}')
    capsys.readouterr()
    assert main(["stress", str(shared_dir / "layer")]) == 2
    if comm.rank == 0:
        assert "stresses of a half-space only" in capsys.readouterr().err


# -- line contact (plane strain) -------------------------------------------------------------------------
def line_load(x, z, nu):
    """Flamant: the plane-strain stresses (6, ...) at (x, z) below a unit compressive line load (N/m) at
    x = 0 (Johnson 1985, §2.2), tension positive; sigma_yy = nu (sigma_xx + sigma_zz)."""
    r4 = (x * x + z * z) ** 2
    sxx, szz, sxz = -2 * x * x * z / (np.pi * r4), -2 * z**3 / (np.pi * r4), -2 * x * z * z / (np.pi * r4)
    return np.array([sxx, nu * (sxx + szz), szz, 0 * x, sxz, 0 * x])


def mcewen(x, z, a):
    """Hertz line contact (peak pressure 1, half-width a): McEwen's (1949) closed form (Johnson 1985,
    §4.2, with m, n the signs of z, x): sigma_xx, sigma_zz, sigma_xz, tension positive."""
    A = a * a - x * x + z * z
    root = np.sqrt(A * A + 4 * x * x * z * z)
    m, n = np.sqrt(0.5 * (root + A)), np.sign(x) * np.sqrt(np.maximum(0.5 * (root - A), 0.0))
    q = (z * z + n * n) / (m * m + n * n)
    return (-(m * (1 + q) - 2 * z) / a, -m * (1 - q) / a, -n * (m * m - z * z) / ((m * m + n * n) * a))


@pytest.mark.parametrize("offset", [(0, 0.3), (1, 0.5), (-2, 1.3), (3, 0.05)])
def test_strip_coefficients_are_the_integral_of_the_line_load(offset):
    from petroll.solver.stress import strip_stress_table

    dx, nu = 0.8, 0.3
    k, z = offset
    table = strip_stress_table(np.array([k]), z, dx, nu)[:, 0, 0]
    quadrature = [sum(integrate.quad(lambda s: line_load(k * dx - s, z, nu)[c], s0, s1, epsabs=1e-13,
                                     epsrel=1e-12)[0] for s0, s1 in ((-dx / 2, 0), (0, dx / 2)))
                  for c in range(6)]
    assert np.max(np.abs(table - quadrature)) < 1e-12


def test_line_contact_hertz_stresses_are_mcewens(comm, shared_dir):
    """A cylinder on an elastic half-space in plane strain, a/dx = 16 (load control, 1000 N/m): every
    stress at every strip from z = 0.1 a to 2 a within 1 % of p0 of McEwen's closed form, and the maximum
    shear 0.300 p0 at z = 0.786 a within 1 %. stress.h5 holds (nz, nx) fields."""
    nu, E, R, load = 0.3, 1e7, 0.01, 1000.0
    a = np.sqrt(4 * load * R * (1 - nu**2) / (E * np.pi))
    p0 = 2 * load / (np.pi * a)
    dx = a / 16
    run(parse_scene({"grid": {"nx": 96, "x": [-48 * dx, 48 * dx]},
                     "material": {"model": "elastic", "E": E, "nu": nu},
                     "body": {"shape": "cylinder", "radius": R}, "motion": {"load": load}},
                    source="test_stress"), comm, shared_dir)
    z = a * np.linspace(0.1, 2.0, 77)
    found = petroll.stress(shared_dir, depths=z, comm=comm)
    with h5py.File(found.path, "r") as f:
        assert f["sigma_xx"].shape == (77, 96) and bool(f.attrs["line_contact"])
        got = {name: f[name][()] for name in ("sigma_xx", "sigma_yy", "sigma_zz", "sigma_xy", "sigma_xz",
                                             "sigma_yz", "max_shear")}
        x = f["x"][()]
    X, Z = np.meshgrid(x, z)
    sxx, szz, sxz = mcewen(X, Z, a)
    for name, exact in (("sigma_xx", sxx), ("sigma_zz", szz), ("sigma_xz", sxz),
                        ("sigma_yy", nu * (sxx + szz))):
        assert np.max(np.abs(got[name] / p0 - exact)) < 0.01, name
    assert not np.any(got["sigma_xy"]) and not np.any(got["sigma_yz"])
    tau = 0.5 * np.sqrt((sxx - szz) ** 2 + 4 * sxz**2)  # in-plane (sigma_yy is the intermediate one)
    k = np.unravel_index(np.argmax(tau), tau.shape)
    assert abs(tau[k] - 0.300) < 0.001 and abs(z[k[0]] / a - 0.786) < 0.02  # the known values
    assert abs(found.max_shear_max / (tau[k] * p0) - 1) < 0.01
    assert abs(found.max_shear_at[0]) < dx and found.max_shear_at[1] == 0.0
    assert abs(found.max_shear_at[2] - z[k[0]]) < 0.05 * a
