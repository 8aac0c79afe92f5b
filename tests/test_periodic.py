"""Periodic grids ([grid] periodic): the periodic kernels against dense matrices summed from their
definitions, Westergaard's sinusoid in full and partial contact (Johnson 1985, section 13.2), the
doubly sinusoidal surface in full contact, a grid periodic along one axis against line contact, a
viscoelastic full contact relaxing, a body that slides around the cell, and the scene contract."""

import math

import numpy as np
import pytest
from mpi4py import MPI
from scipy.integrate import quad
from scipy.special import k0

from petroll.errors import SceneError, SolverError
from petroll.model.materials import Layer
from petroll.model.scene import parse_scene
from petroll.model.bodies.rough import PeriodicSurface
from petroll.solver.influence import Convolution
from petroll.solver.kernels.periodic import HalfSpace, HalfSpaceAlong, LayerSpectral
from petroll.solver.partition import RowPartition, roll_field
from petroll.solver.simulation import Simulation

E, NU = 2.0e6, 0.0
ESTAR = E / (1 - NU**2)


def gathered(comm, local):
    return np.concatenate(comm.allgather(local))


def dense_periodic(kernel) -> np.ndarray:
    """The operator's matrix summed from the kernel's coefficients by explicit Fourier sums (no FFT): along
    a Fourier axis sum_m S(m) exp(2 pi i m d / n) / n over all frequencies, along a real-space axis the
    coefficient at the offset."""
    nx, ny = kernel.nx, kernel.ny
    mx = np.arange(nx) - nx // 2 if kernel.fourier[0] else None
    my = np.arange(ny) - ny // 2 if kernel.fourier[1] else None
    ix, iy = np.divmod(np.arange(nx * ny), ny)
    dx, dy = ix[:, None] - ix[None, :], iy[:, None] - iy[None, :]
    if all(kernel.fourier):
        s = kernel.values(mx[:, None], my[None, :])
        phase = np.exp(2j * np.pi * (mx[None, None, :, None] * dx[:, :, None, None] / nx
                                     + my[None, None, None, :] * dy[:, :, None, None] / ny))
        return ((phase * s).sum(axis=(2, 3)) / (nx * ny)).real
    if kernel.fourier[0]:
        table = kernel.values(mx[:, None], np.arange(ny)[None, :])  # (frequencies, offsets >= 0)
        phase = np.exp(2j * np.pi * mx[None, None, :] * dx[:, :, None] / nx)
        return ((phase * table[:, np.abs(dy)].transpose(1, 2, 0)).sum(axis=2) / nx).real
    table = kernel.values(np.arange(nx)[:, None], my[None, :])  # (offsets >= 0, frequencies)
    phase = np.exp(2j * np.pi * my[None, None, :] * dy[:, :, None] / ny)
    return ((phase * table[np.abs(dx), :]).sum(axis=2) / ny).real


KERNELS = {
    "half-space": lambda: HalfSpace(0.3, 0.2, 9, 8),
    "line": lambda: HalfSpace(0.3, 1.0, 12, 1),
    "layer": lambda: LayerSpectral(0.3, 0.2, 8, 7, Layer(0.25, "bonded", 0.3)),
    "along x": lambda: HalfSpaceAlong(0.3, 0.2, 8, 7, 0, 1.4),
    "along y": lambda: HalfSpaceAlong(0.3, 0.2, 7, 10, 1, 2.1),
}


@pytest.mark.ranks4
@pytest.mark.parametrize("name", KERNELS)
def test_periodic_convolution_and_its_inverse_equal_the_dense_matrices(comm, name):
    kernel = KERNELS[name]()
    nx, ny = kernel.nx, kernel.ny
    matrix = dense_periodic(kernel)
    x = np.random.default_rng(nx * ny).standard_normal((nx, ny))
    conv = Convolution(kernel, nx, ny, comm)
    y = gathered(comm, conv(x[conv.r0 : conv.r1]))
    expected = (matrix @ x.ravel()).reshape(nx, ny)
    assert np.abs(y - expected).max() <= 1e-12 * np.abs(expected).max()
    assert conv.diagonal == pytest.approx(matrix[0, 0], rel=1e-12)
    inverse = Convolution(kernel, nx, ny, comm, inverse=True)
    z = gathered(comm, inverse(y[conv.r0 : conv.r1]))
    if all(kernel.fourier) and kernel.values(0, 0) == 0:  # the half-space: the inverse on the mean-free part
        x = x - x.mean()
        z = z - z.mean()
    if not all(kernel.fourier):  # one periodic axis: the inverse of the circulant along the other
        eigen = np.linalg.eigvalsh(np.linalg.inv(np.asarray(_dense_inverse(kernel))))
        assert eigen.min() > 0
        return
    assert np.abs(z - x).max() <= 1e-10 * np.abs(x).max()


def _dense_inverse(kernel) -> np.ndarray:
    """The inverse preconditioner's matrix of a one-axis periodic kernel, applied column by column."""
    n = kernel.nx * kernel.ny
    conv = Convolution(kernel, kernel.nx, kernel.ny, MPI.COMM_SELF, inverse=True)
    return np.stack([conv(np.eye(n)[k].reshape(kernel.nx, kernel.ny)).ravel() for k in range(n)], axis=1)


@pytest.mark.parametrize("offset", [0, 1, 4])
def test_one_axis_kernel_is_the_integral_of_the_line_kernels_transform(offset):
    """Along the real-space axis: (2/pi) int over the cell of K0(|kx| |y|) for kx != 0."""
    dx, dy, nx = 0.3, 0.2, 8
    kernel = HalfSpaceAlong(dx, dy, nx, 7, 0, 1.4)
    for m in (1, 3, -4):
        k = abs(2 * np.pi * m / (nx * dx))
        lo, hi = offset * dy - dy / 2, offset * dy + dy / 2
        points = [0.0] if lo < 0 < hi else None
        value = quad(lambda y: 2 / np.pi * k0(k * abs(y)), lo, hi, points=points, limit=200)[0]
        assert kernel.values(np.array([m]), np.array([offset]))[0] == pytest.approx(value, rel=1e-10)


def wave_scene(dirpath, comm, n=128, wavelength=1.0, amplitude=0.01, line=False, **motion):
    """Westergaard's surface Z = D (1 - cos(2 pi x / lambda)) as a height map of the grid's samples."""
    x = (np.arange(n) + 0.5) * wavelength / n - wavelength / 2
    z = amplitude * (1 - np.cos(2 * np.pi * x / wavelength))
    path = dirpath / f"wave-{n}-{line}.npy"
    if comm.rank == 0:
        np.save(path, z if line else np.repeat(z[:, None], 4, axis=1))
    comm.Barrier()
    grid = {"nx": n, "x": [-wavelength / 2, wavelength / 2], "periodic": True}
    if not line:
        grid.update(ny=4, y=[-2 * wavelength / n, 2 * wavelength / n])
    raw = {"grid": grid, "material": {"model": "elastic", "E": E, "nu": NU},
           "body": {"shape": "heightmap", "file": str(path), "cell": wavelength / n},
           "motion": motion or {"load": 1.0}, "solver": {"tol": 1e-10}}
    return parse_scene(raw), x


def westergaard(x, mean, wavelength=1.0, amplitude=0.01):
    """Johnson (1985), section 13.2: the pressure under a wavy surface pressed to the mean pressure."""
    full = math.pi * ESTAR * amplitude / wavelength
    if mean >= full:
        return mean + full * np.cos(2 * np.pi * x / wavelength)
    s2 = mean / full
    inside = np.sin(np.pi * x / wavelength) ** 2 < s2
    root = np.sqrt(np.where(inside, s2 - np.sin(np.pi * x / wavelength) ** 2, 0.0))
    return np.where(inside, 2 * mean * np.cos(np.pi * x / wavelength) / s2 * root, 0.0)


@pytest.mark.slow
@pytest.mark.parametrize("line", [False, True])
@pytest.mark.parametrize("fraction", [0.2, 0.5, 1.5])
def test_westergaard_at_128_cells_per_wavelength(comm, shared_dir, line, fraction):
    """Load control (the default pk): full contact exact to round-off; partial contact: the peak pressure
    within 1e-3, the contact the cells inside the closed form's, the pressure within 1e-3 of the peak at
    cells more than 3 cells inside the contact's edges (next to a square-root edge a cell-centred value
    errs by O(sqrt(dx/a)): 1.2e-3 of the peak 1 to 3 cells inside at 0.2, as at 256 cells). Penetration control at the penetration found gives the same pressure."""
    mean = fraction * math.pi * ESTAR * 0.01
    cell_width = 1.0 if line else 4 / 128
    scene, x = wave_scene(shared_dir, comm, line=line, load=mean * cell_width)
    assert isinstance(scene.body, PeriodicSurface)
    sim = Simulation(scene, comm)
    record = next(sim.steps())
    p = gathered(comm, sim.pressure)
    exact = westergaard(x, mean)
    assert record.force == pytest.approx(mean * cell_width, rel=1e-10)
    assert np.abs(p - exact[:, None]).max(axis=1).max() <= (1e-9 if fraction > 1 else 1.0) * exact.max()
    if fraction < 1:
        assert p.max() == pytest.approx(exact.max(), rel=1e-3)
        assert np.array_equal((p > 0).all(axis=1), exact > 0)
        half_width = math.asin(math.sqrt(fraction)) / math.pi  # a / lambda
        inside = half_width - np.abs(x) > 3 / 128
        assert np.abs(p[inside] - exact[inside, None]).max() <= 1e-3 * exact.max()
    if fraction < 1:  # (full contact under penetration control: tests/test_periodic.py, the mean gap)
        again = Simulation(scene.replace({"motion.load": None, "motion.penetration": record.delta}), comm)
        next(again.steps())
        assert np.abs(gathered(comm, again.pressure) - p).max() <= 1e-6 * p.max()


def test_doubly_sinusoidal_surface_in_full_contact(comm, shared_dir):
    """h = D cos(kx x) cos(ky y): full contact above p* = E* D |k| / 2 with p = mean + p* cos cos."""
    nx, ny, lx, ly, D = 64, 32, 1.0, 0.5, 1e-3
    x, y = ((np.arange(n) + 0.5) * length / n for n, length in ((nx, lx), (ny, ly)))
    z = D * (1 - np.cos(2 * np.pi * x / lx)[:, None] * np.cos(2 * np.pi * y / ly)[None, :])
    path = shared_dir / "egg.npy"
    if comm.rank == 0:
        np.save(path, z)
    comm.Barrier()
    k = 2 * np.pi * math.hypot(1 / lx, 1 / ly)
    full = ESTAR * D * k / 2
    raw = {"grid": {"nx": nx, "ny": ny, "x": [0, lx], "y": [0, ly], "periodic": ["x", "y"]},
           "material": {"model": "elastic", "E": E, "nu": NU},
           "body": {"shape": "heightmap", "file": str(path), "cell": [lx / nx, ly / ny]},
           "motion": {"load": 1.2 * full * lx * ly}, "solver": {"tol": 1e-11}}
    sim = Simulation(parse_scene(raw), comm)
    next(sim.steps())
    exact = 1.2 * full + full * np.cos(2 * np.pi * x / lx)[:, None] * np.cos(2 * np.pi * y / ly)[None, :]
    assert np.abs(gathered(comm, sim.pressure) - exact).max() <= 1e-9 * exact.max()


@pytest.mark.parametrize("axis", ["x", "y"])
def test_a_cylinder_on_a_grid_periodic_along_its_axis_is_line_contact(comm, axis):
    """A cylinder lying along the periodic axis: only the strip mode is loaded, whose kernel is line
    contact's strips with the datum of the other axis's length: the line-contact solver's pressure on the
    same cells, to the solvers' tolerance."""
    n, half, load, radius = 64, 0.2, 1e4, 1.0  # half-width 0.08
    across = {"nx": n, "x": [-half, half]}
    line = Simulation(parse_scene({"grid": across, "material": {"model": "elastic", "E": E, "nu": NU},
                                   "body": {"shape": "cylinder", "radius": radius},
                                   "motion": {"load": load}, "solver": {"tol": 1e-11}}), comm)
    next(line.steps())
    reference = gathered(comm, line.pressure)[:, 0]
    grid = ({"nx": 8, "ny": n, "x": [0, 1.0], "y": [-half, half]} if axis == "x" else
            {"nx": n, "ny": 8, "x": [-half, half], "y": [0, 1.0]})
    raw = {"grid": {**grid, "periodic": [axis]}, "material": {"model": "elastic", "E": E, "nu": NU},
           "body": {"shape": "cylinder", "radius": radius, "width": 100.0, "axis": axis},
           "motion": {"load": load}, "solver": {"tol": 1e-11}}
    sim = Simulation(parse_scene(raw), comm)
    next(sim.steps())
    p = gathered(comm, sim.pressure)
    profile = p if axis == "x" else p.T
    assert np.abs(profile - reference[None, :]).max() <= 1e-8 * reference.max()
    with pytest.raises(SolverError, match="does not repeat"):
        next(Simulation(parse_scene({**raw, "motion": {"load": 10 * load}}), comm).steps())


def test_viscoelastic_full_contact_relaxes_with_the_relaxation_modulus(comm, shared_dir):
    """A wavy surface held in full contact on an SLS under a constant load: the displacement is held, so
    the pressure's harmonic relaxes as the surface modulus E(t) = 1/Jinf + (1/J0 - 1/Jinf) exp(-t/T)
    times k D / 2, exactly at every step of the default (relaxation) integrator."""
    E0, Einf, tau = 10e6, 2e6, 0.01
    material = {"model": "sls", "E0": E0, "Einf": Einf, "nu": NU, "tau_creep": tau}
    scene, x = wave_scene(shared_dir, comm, n=64, load=2 * math.pi * E0 * 0.01 * 4 / 64)
    sim = Simulation(parse_scene({**scene.raw, "material": material, "time": {"dt": 0.004, "end": 0.04}}), comm)
    J0, Jinf = (1 - NU**2) / E0, (1 - NU**2) / Einf
    T = tau * J0 / Jinf
    k = 2 * np.pi
    for record in sim.steps():
        modulus = 1 / Jinf + (1 / J0 - 1 / Jinf) * math.exp(-record.t / T)
        p = gathered(comm, sim.pressure)[:, 0]
        harmonic = 2 * np.mean(p * np.cos(k * x))
        assert harmonic == pytest.approx(k * 0.01 / 2 * modulus, rel=1e-8)
        assert p.min() > 0


def test_a_sliding_body_wraps_around_the_cell(comm, shared_dir):
    """An elastic wavy surface sliding one cell per step along X: each step's pressure is the first one
    moved by the distance slid, around the cell (and back where it started after one period)."""
    n = 32
    scene, _ = wave_scene(shared_dir, comm, n=n, load=0.3 * math.pi * ESTAR * 0.01 * 4 / n)
    scene = parse_scene({**scene.raw, "motion": {**scene.raw["motion"], "velocity": [1.0, 0.0]},
                         "time": {"steps_per_cell": 1, "distance": 1.25}})
    sim = Simulation(scene, comm)
    first = None
    for record in sim.steps():
        p = gathered(comm, sim.pressure)
        first = p if first is None else first
        assert np.abs(p - np.roll(first, record.step, axis=0)).max() <= 1e-8 * first.max()
    assert record.step == 40


@pytest.mark.parallel
def test_a_rough_surface_sliding_by_fractions_of_a_cell_is_the_same_on_every_rank_count(comm, shared_dir):
    """A generated rough surface on an SLS sliding 0.4 cell per step along X across the cell's end, so
    that every rank's rows need the surface's samples from around the period: each step's pressure on
    ``comm`` is the one of the same run on a single rank (the oracle), and each rank holds the spline
    coefficients of its rows (and the stencils' and the margin's), not the whole surface's."""
    from petroll.model.bodies.rough import ROWS_MARGIN

    n, length = 128, 1e-3
    raw = {"grid": {"nx": n, "ny": 16, "x": [0, length], "y": [0, length / 8], "periodic": True},
           "material": {"model": "sls", "E0": 10e6, "Einf": 2e6, "nu": 0.5, "tau_relax": 1e-3},
           "body": {"shape": "rough", "hurst": 0.8, "rolloff": length / 4, "cutoff": 4 * length / n,
                    "rms_slope": 0.1, "seed": 5, "position": [0.99 * length, 0.0]},
           "motion": {"load": 0.3e6 * length * length / 8, "velocity": [0.4 * length / n / 1e-4, 0.0]},
           "time": {"dt": 1e-4, "end": 6e-4}, "solver": {"tol": 1e-12}}
    ours, alone = Simulation(parse_scene(raw), comm), Simulation(parse_scene(raw), MPI.COMM_SELF)
    for mine, oracle in zip(ours.steps(), alone.steps()):
        p = gathered(comm, ours.pressure)
        assert np.abs(p - alone.pressure).max() <= 1e-8 * alone.pressure.max()
        assert mine.force_x == pytest.approx(oracle.force_x, rel=1e-8)
    assert mine.step == 6 and mine.sx > length  # the body has crossed the cell's end
    rows = ours.solver.r1 - ours.solver.r0
    assert ours.scene.body.rows_held <= rows + 3 + 2 * ROWS_MARGIN
    assert alone.scene.body.rows_held == n


@pytest.mark.ranks4
@pytest.mark.parametrize("di,dj", [(0, 0), (1, 0), (3, -2), (-4, 1), (12, 0), (0, -7), (-23, -3)])
def test_roll_field_moves_a_distributed_field_around(comm, di, dj):
    nx, ny = 11, 7
    field = np.arange(nx * ny, dtype=float).reshape(nx, ny)
    rows = RowPartition(nx, comm.size)
    r0, r1 = rows.range(comm.rank)
    assert np.array_equal(roll_field(field[r0:r1], di, dj, rows, comm), np.roll(field, (di, dj), (0, 1))[r0:r1])


@pytest.mark.parametrize("value,allowed", [(1, "must be true"), (["z"], "must be true"), (["x", "x"], "must be true"),
                                           ([], "must be true")])
def test_bad_periodic_values_are_refused(value, allowed):
    raw = {"grid": {"nx": 8, "ny": 8, "x": [0, 1], "y": [0, 1], "periodic": value},
           "material": {"model": "elastic", "E": E, "nu": NU}, "body": {"shape": "sphere", "radius": 1.0},
           "motion": {"load": 1.0}}
    with pytest.raises(SceneError, match=r"\[grid\] periodic .*" + allowed):
        parse_scene(raw)


def test_a_line_grid_repeats_along_x_only():
    raw = {"grid": {"nx": 8, "x": [0, 1], "periodic": ["y"]}, "material": {"model": "elastic", "E": E, "nu": NU},
           "body": {"shape": "cylinder", "radius": 1.0}, "motion": {"load": 1.0}}
    with pytest.raises(SceneError, match="along X only"):
        parse_scene(raw)


def test_a_height_map_is_the_periodic_surface_only_at_the_grids_size_and_spacing(comm, shared_dir):
    scene, _ = wave_scene(shared_dir, comm, n=32)
    assert isinstance(scene.body, PeriodicSurface)
    surface = scene.body
    g = scene.grid
    heights = surface.height(g.x[:, None], g.y[None, :])  # the samples, from the surface's lowest point
    samples = np.load(scene.raw["body"]["file"])
    assert np.abs((heights - heights[0, 0]) - (samples - samples[0, 0])).max() <= 1e-13 * np.ptp(samples)
    assert not isinstance(scene.replace("body.cell", 1 / 31).body, PeriodicSurface)
    assert not isinstance(scene.replace("grid.periodic", False).body, PeriodicSurface)


def test_a_penetration_that_leaves_no_mean_gap_is_refused(comm, shared_dir):
    scene, _ = wave_scene(shared_dir, comm, n=32, penetration=0.0101)
    with pytest.raises(SolverError, match=r"\[motion\] penetration: .* leaves no mean gap"):
        next(Simulation(scene, comm).steps())


@pytest.mark.parametrize("periodic", [(True, True), (True, False), (False, False)])
def test_contact_islands_are_the_connected_components_around_the_cell(periodic):
    """petroll.solver.rough.contact_islands against scipy's connected components of the graph of cells
    sharing a side (across the periodic edges too): the same partition of the contact."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from petroll.solver.rough import contact_islands

    nx, ny = 23, 17
    contact = np.random.default_rng(4).random((nx, ny)) < 0.45
    index = np.arange(nx * ny).reshape(nx, ny)
    pairs = []
    for axis, wrap in ((0, periodic[0]), (1, periodic[1])):
        neighbour = np.roll(index, -1, axis=axis)
        ok = contact & np.roll(contact, -1, axis=axis)
        if not wrap:
            edge = [slice(None), slice(None)]
            edge[axis] = -1
            ok[tuple(edge)] = False
        pairs.append(np.stack([index[ok], neighbour[ok]]))
    i, j = np.concatenate(pairs, axis=1)
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(nx * ny, nx * ny))
    _, components = connected_components(graph, directed=False)
    labels, count = contact_islands(contact, periodic)
    assert count == len(np.unique(components[contact.ravel()])) and count > 10
    ours, theirs = labels.ravel()[contact.ravel()], components[contact.ravel()]
    pairs = set(zip(ours, theirs))
    assert len(pairs) == count and np.all(labels[~contact] == 0)  # a one-to-one map of the islands
