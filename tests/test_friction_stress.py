"""Stresses below tangential surface tractions (``petroll stress`` of a run with friction): the closed-form
coefficients of a cell carrying a tangential traction against dense quadrature of Cerruti's point force
(Johnson 1985, Eq. 3.87, an independent form), the surface's boundary conditions, the strip's against the
cell's limit, and a run's stresses with its tractions."""

import numpy as np
import pytest
from scipy import integrate
from test_stress import cell_quadrature

from petroll.solver.stress import (SubsurfaceStress, cell_shear_stress, shear_stress_table,
                                   strip_shear_stress_table)


def cerruti(x, y, z, nu):
    """Johnson's Eq. 3.87: the stresses (6, ...) xx, yy, zz, xy, xz, yz at (x, y, z) of a unit force along
    +X on the half-space's surface at the origin, tension positive."""
    r = np.sqrt(x * x + y * y + z * z)
    c = 1 - 2 * nu
    sxx = -3 * x**3 / r**5 + c * (x / r**3 - 3 * x / (r * (r + z) ** 2) + x**3 / (r**3 * (r + z) ** 2)
                                  + 2 * x**3 / (r**2 * (r + z) ** 3))
    syy = -3 * x * y * y / r**5 + c * (x / r**3 - x / (r * (r + z) ** 2) + x * y * y / (r**3 * (r + z) ** 2)
                                       + 2 * x * y * y / (r**2 * (r + z) ** 3))
    sxy = -3 * x * x * y / r**5 + c * (-y / (r * (r + z) ** 2) + x * x * y / (r**3 * (r + z) ** 2)
                                       + 2 * x * x * y / (r**2 * (r + z) ** 3))
    return np.array([sxx, syy, -3 * x * z * z / r**5, sxy, -3 * x * x * z / r**5, -3 * x * y * z / r**5]) / (2 * np.pi)


@pytest.mark.slow
@pytest.mark.parametrize("offset", [(0, 0, 0.3), (1, 2, 0.5), (-2, 1, 1.3), (3, -1, 0.05), (0, 0, 2.0),
                                    (1, 0, 0.2)])
@pytest.mark.parametrize("nu", [0.0, 0.3, 0.5])
def test_cell_shear_coefficients_are_the_integral_of_cerruti_point_force(offset, nu):
    """Quadrature split at the point's vertical (the integrand's axis never sampled), to 1e-11."""
    dx, dy = 1.0, 0.7
    ix, iy, z = offset
    x, y = ix * dx, iy * dy
    closed = cell_shear_stress(np.array(x), np.array(y), z, dx, dy, nu)
    assert np.max(np.abs(closed - cell_quadrature(cerruti, x, y, z, dx, dy, nu))) < 1e-10


def test_the_table_along_y_is_the_table_along_x_turned():
    """A traction along Y on a dx x dy cell is one along X on a dy x dx cell, turned: against the direct
    quadrature of the point force along Y (Cerruti's with x and y exchanged) at a few offsets."""
    dx, dy, nu, z = 1.0, 0.7, 0.25, 0.4
    ox, oy = np.arange(-2, 3), np.arange(-1, 3)
    table = shear_stress_table(ox, oy, z, dx, dy, nu, axis=1)
    for i, j in ((0, 0), (3, 1), (1, 3)):
        x, y = ox[i] * dx, oy[j] * dy
        turned = cell_shear_stress(np.array(y), np.array(x), z, dy, dx, nu)[[1, 0, 2, 3, 5, 4]]
        assert np.max(np.abs(table[:, i, j] - turned)) < 1e-14
        direct = [integrate.dblquad(lambda v, u: cerruti(y - v, x - u, z, nu)[[1, 0, 2, 3, 5, 4]][c],
                                    -dx / 2, dx / 2, -dy / 2, dy / 2, epsabs=1e-12, epsrel=1e-10)[0]
                  for c in range(6)]
        assert np.max(np.abs(table[:, i, j] - direct)) < 1e-9


def test_the_surface_carries_the_traction():
    """At z = 0 a cell carrying t_x has sigma_xz = -t_x at its centre, 0 at other centres; sigma_zz =
    sigma_yz = 0 everywhere (the boundary conditions)."""
    ox, oy = np.arange(-3, 4), np.arange(-2, 3)
    s = shear_stress_table(ox, oy, 0.0, 1.0, 0.8, 0.3)
    expected = np.zeros((len(ox), len(oy)))
    expected[3, 2] = -1.0
    assert np.max(np.abs(s[4] - expected)) < 1e-14
    assert np.max(np.abs(s[2])) < 1e-14 and np.max(np.abs(s[5])) < 1e-14


def test_the_strip_is_the_long_cell():
    """Plane strain: a strip's coefficients are those of a cell 1e5 times longer than wide (to its
    length's correction, 1e-5), and sigma_yy = nu (sigma_xx + sigma_zz)."""
    nu, z = 0.3, 0.7
    ox = np.arange(-4, 5)
    strip = strip_shear_stress_table(ox, z, 1.0, nu)[:, :, 0]
    long = shear_stress_table(ox, np.array([0]), z, 1.0, 1e5, nu)[:, :, 0]
    scale = np.abs(strip).max()
    assert np.max(np.abs(strip[[0, 2, 4]] - long[[0, 2, 4]])) < 1e-5 * scale
    assert np.max(np.abs(strip[1] - nu * (strip[0] + strip[2]))) < 1e-14 * scale


def test_traction_adds_to_the_pressure_and_ranks_split_rows(comm):
    """SubsurfaceStress with tractions: the sum of the pressure's and each traction's stresses, each from
    its own coefficients summed directly (the dense convolution), on the ranks' rows."""
    from mpi4py import MPI

    nx, ny, dx, dy, nu, z = 7, 5, 1.0, 0.8, 0.3, 0.6
    rng = np.random.default_rng(3)
    p, tx, ty = rng.random((3, nx, ny))
    solver = SubsurfaceStress(nx, ny, dx, dy, nu, comm)
    r0, r1 = solver.r0, solver.r1
    got = solver.at(p[r0:r1], z, np.stack([tx[r0:r1], ty[r0:r1]]))
    alone = SubsurfaceStress(nx, ny, dx, dy, nu, MPI.COMM_SELF)
    ox, oy = np.arange(-(nx - 1), nx), np.arange(-(ny - 1), ny)
    tables = [shear_stress_table(ox, oy, z, dx, dy, nu, a) for a in (0, 1)]
    dense = alone.at(p, z)
    for i in range(nx):
        for j in range(ny):
            for t, load in zip(tables, (tx, ty)):
                dense[:, i, j] += np.einsum("cab,ab->c", t[:, i - np.arange(nx)[:, None] + nx - 1,
                                                           j - np.arange(ny)[None, :] + ny - 1], load)
    assert np.max(np.abs(got - dense[:, r0:r1])) < 1e-12 * np.abs(dense).max()


@pytest.mark.parametrize("line", [True, False])
def test_petroll_stress_of_a_friction_run_includes_its_tractions(line, comm, shared_dir):
    """At the surface sigma_xz = q_x, sigma_yz = q_y (the tractions on the body: the half-space carries
    -q) and sigma_zz = -p; below, the run's stresses are the frictionless stresses of its pressure plus
    those of its tractions alone (each from SubsurfaceStress)."""
    import h5py
    from mpi4py import MPI

    import petroll
    from petroll.driver import run
    from petroll.model.scene import parse_scene

    a = 1e-4
    if line:
        raw = {"grid": {"nx": 48, "x": [-1.5 * a, 1.5 * a]},
               "motion": {"load": 2e4, "velocity": 1.0, "creepage": -2e-4},
               "body": {"shape": "cylinder", "radius": 0.1}}
    else:
        raw = {"grid": {"nx": 32, "ny": 32, "x": [-1.6 * a, 1.6 * a], "y": [-1.6 * a, 1.6 * a]},
               "motion": {"load": 5.0, "velocity": [1.0, 0.0], "creepage": [-3e-4, 1e-4], "spin": 1.0},
               "body": {"shape": "sphere", "radius": 0.05}}
    raw.update(material={"model": "elastic", "E": 2e11, "nu": 0.5}, friction={"coefficient": 0.3},
               time={"mode": "steady"})
    results = run(parse_scene(raw), comm, shared_dir / "run")
    depth = 3e-5
    petroll.stress(shared_dir / "run", depths=[0.0, depth], comm=comm)
    p, qx = results.pressure[0], results.field("traction_x")[0]
    q = np.stack([qx] if line else [qx, results.field("traction_y")[0]])
    with h5py.File(shared_dir / "run" / "stress.h5", "r") as f:
        s = np.stack([f[name][()] for name in ("sigma_xx", "sigma_yy", "sigma_zz", "sigma_xy", "sigma_xz",
                                                "sigma_yz")]).reshape(6, 2, *p.shape)
    scale = p.max()
    assert np.abs(q).max() > 0.1 * 0.3 * scale
    assert np.max(np.abs(s[4, 0] - q[0])) < 1e-12 * scale and np.max(np.abs(s[2, 0] + p)) < 1e-12 * scale
    if not line:
        assert np.max(np.abs(s[5, 0] - q[1])) < 1e-12 * scale
    nx, ny = p.shape
    alone = SubsurfaceStress(nx, ny, results.x[1] - results.x[0], 1.0 if line else results.y[1] - results.y[0],
                             0.5, MPI.COMM_SELF, line)
    parts = alone.at(p, depth) + alone.at(np.zeros_like(p), depth, -q)
    assert np.max(np.abs(s[:, 1] - parts)) < 1e-12 * scale
