"""Rough bodies (petroll.model.bodies.rough): a periodic surface returns its samples at the sample points,
repeats with its period, and between samples follows a smooth surface (a sum of Fourier modes) to the
spline's O(h^4) in height and the slope to O(h^3); roughness on a sphere adds to it. Scene keys: a height
map read from every format is the .npy map's body; a body's roughness, generated or measured, is the
smooth body plus the periodic surface of those samples."""

import numpy as np
import pytest
from test_topography import write_x3p

from petroll.errors import SceneError
from petroll.model.bodies import Cylinder, Sphere
from petroll.model.bodies.rough import PeriodicSurface, RoughBody, grid_surface
from petroll.model.grid import Grid
from petroll.model.roughness import self_affine_heights
from petroll.model.scene import parse_scene

CELL = (1e-6, 2e-6)


def modes(x, y, period):
    """A smooth periodic test surface (m) and its slopes: two Fourier modes of the period (Lx, Ly)."""
    ax, ay = 2 * np.pi * x / period[0], 2 * np.pi * y / period[1]
    h = 1e-7 * (np.cos(ax + 0.3) + 0.5 * np.sin(2 * ax - ay))
    hx = 1e-7 * (-np.sin(ax + 0.3) + np.cos(2 * ax - ay)) * 2 * np.pi / period[0]
    hy = 1e-7 * (-0.5 * np.cos(2 * ax - ay)) * 2 * np.pi / period[1]
    return h, hx, hy


def surface_of_modes(n, origin=(0.0, 0.0)):
    period = (n * CELL[0], n * CELL[1])
    i = np.arange(n)
    h, _, _ = modes(i[:, None] * CELL[0], i[None, :] * CELL[1], period)
    return PeriodicSurface(h, CELL, origin), h, period


def test_samples_are_returned_and_the_surface_repeats():
    surface, h, period = surface_of_modes(16, origin=(-3e-6, 5e-6))
    i = np.arange(16)
    x, y = -3e-6 + i[:, None] * CELL[0], 5e-6 + i[None, :] * CELL[1]
    np.testing.assert_allclose(surface.height(x, y), h - surface.lowest, rtol=0, atol=1e-12 * np.ptp(h))
    assert h.min() - 0.01 * np.ptp(h) < surface.lowest <= h.min()
    np.testing.assert_allclose(surface.height(x + 2 * period[0], y - period[1]), surface.height(x, y),
                               rtol=0, atol=1e-12 * np.ptp(h))


@pytest.mark.parametrize("n", [16, 32])
def test_between_samples_it_follows_a_smooth_surface(n):
    surface, h, period = surface_of_modes(n)
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-period[0], period[0], 500), rng.uniform(0, 2 * period[1], 500)
    exact, ex, ey = modes(x, y, period)
    dense = np.linspace(0, 1, 400, endpoint=False)
    lowest = modes(dense[:, None] * period[0], dense[None, :] * period[1], period)[0].min()
    assert abs(surface.lowest - lowest) < {16: 5e-4, 32: 3e-5}[n] * np.ptp(h)  # the spline's minimum
    height_error = np.abs(surface.height(x, y) - (exact - lowest)).max() / np.ptp(h)
    sx, sy = surface.slope(x, y)
    slope_error = max(np.abs(sx - ex).max() / np.abs(ex).max(), np.abs(sy - ey).max() / np.abs(ey).max())
    # the cubic spline: errors fall 16x per doubling (measured 2.2e-4, 1.2e-5 in height; bilinear: 8e-2)
    assert height_error < {16: 5e-4, 32: 3e-5}[n], height_error
    assert slope_error < {16: 3e-3, 32: 2e-4}[n], slope_error
    # at the samples the slopes are the modes' exact derivatives
    i = np.arange(n)
    _, ex, ey = modes(i[:, None] * CELL[0], i[None, :] * CELL[1], period)
    sx, sy = surface.slope(i[:, None] * CELL[0], i[None, :] * CELL[1])
    np.testing.assert_allclose(sx, ex, rtol=0, atol=1e-10 * np.abs(ex).max())
    np.testing.assert_allclose(sy, ey, rtol=0, atol=1e-10 * np.abs(ey).max())
    # on scattered samples, one period away too (a run's contact cells): those samples' exact derivatives
    pick = np.random.default_rng(1).integers(0, n, (2, 50))
    sx, sy = surface.slope((pick[0] - n * (pick[0] % 2)) * CELL[0], pick[1] * CELL[1])
    np.testing.assert_allclose(sx, ex[pick[0], pick[1]], rtol=0, atol=1e-10 * np.abs(ex).max())
    np.testing.assert_allclose(sy, ey[pick[0], pick[1]], rtol=0, atol=1e-10 * np.abs(ey).max())


def test_roughness_adds_to_a_smooth_body():
    roughness, _, _ = surface_of_modes(16)
    x, y = np.linspace(-4e-5, 4e-5, 9)[:, None], np.linspace(-6e-5, 6e-5, 7)[None, :]
    for body in (Sphere(1e-3), Cylinder(1e-3, width=1e-4, edge_radius=1e-5)):
        rough = RoughBody(body, roughness)
        np.testing.assert_allclose(rough.height(x, y), body.height(x, y) + roughness.height(x, y), rtol=1e-15, atol=0)
        slope = np.add(body.slope(x, y), roughness.slope(x, y))
        outside = np.isinf(body.height(x, y))
        np.testing.assert_allclose(rough.slope(x, y), np.where(outside, 0.0, slope), rtol=1e-15, atol=0)
        assert rough.radius_hint == body.radius_hint
    assert np.isinf(RoughBody(Cylinder(1e-3, width=1e-4), roughness).height(0.0, 1e-4)).all()


def test_bad_samples_are_refused():
    with pytest.raises(SceneError, match="at least 4 x 4 finite heights"):
        PeriodicSurface(np.full((8, 8), np.nan), CELL)


def test_a_periodic_grid_surface_puts_its_samples_on_the_cell_centres():
    grid = Grid(16, 8, -4e-6, 12e-6, 0.0, 16e-6)  # cells 1 um x 2 um
    heights = np.random.default_rng(4).normal(size=(16, 8)) * 1e-7
    surface = grid_surface(heights, (1e-6, 2e-6), grid)
    np.testing.assert_allclose(surface.height(grid.x[:, None], grid.y[None, :]), heights - surface.lowest,
                               rtol=0, atol=1e-12 * np.ptp(heights))
    # a body moved by 3 cells along x and wrapped: the samples rolled by 3
    moved = surface.height(grid.x[:, None] - 3e-6, grid.y[None, :])
    np.testing.assert_allclose(moved, np.roll(heights, 3, axis=0) - surface.lowest, rtol=0,
                               atol=1e-12 * np.ptp(heights))
    with pytest.raises(SceneError, match=r"\[body\] file.*16 x 8, not 16 x 9"):
        grid_surface(np.zeros((16, 9)), (1e-6, 2e-6), grid)
    with pytest.raises(SceneError, match=r"\[body\] cell.*spacing is the grid's"):
        grid_surface(heights, (1e-6, 1e-6), grid)


def whole_spline(heights, cell, origin):
    """The oracle: the spline through all samples, its coefficients by scipy's recursive periodic
    prefilter (ndimage.spline_filter) of the heights and of their spectral slopes (numpy's FFT)."""
    from scipy import ndimage

    nx, ny = heights.shape
    kx = 2 * np.pi * np.fft.fftfreq(nx, cell[0]) * (np.arange(nx) != nx // 2)
    ky = 2 * np.pi * np.fft.fftfreq(ny, cell[1]) * (np.arange(ny) != ny // 2)
    spectrum = np.fft.fft2(heights)
    fields = (heights, np.fft.ifft2(1j * kx[:, None] * spectrum).real,
              np.fft.ifft2(1j * ky[None, :] * spectrum).real)
    coefficients = [ndimage.spline_filter(f, order=3, mode="grid-wrap") for f in fields]

    def at(which, x, y):
        x, y = np.broadcast_arrays(x, y)
        points = np.stack([(x - origin[0]) / cell[0], (y - origin[1]) / cell[1]]).reshape(2, -1)
        return ndimage.map_coordinates(coefficients[which], points, order=3, mode="grid-wrap",
                                       prefilter=False).reshape(x.shape)

    return at


@pytest.mark.parametrize("n", [256, 255])
def test_a_surface_on_some_rows_holds_those_rows_and_is_the_whole_spline_wherever_it_moved(n):
    """A surface evaluated on half a grid's rows, the body moved by fractions of a cell, by whole cells and
    around the period: the heights and slopes of the spline through all samples to round-off, from the
    coefficients of only the rows the points' stencils need (their FFTs against scipy's recursive filter)."""
    from petroll.model.bodies.rough import ROWS_MARGIN

    heights = self_affine_heights(ROUGH, (n, 24), CELL)
    origin = (0.5 * CELL[0], -3 * CELL[1])
    surface = PeriodicSurface(heights, CELL, origin)
    oracle = whole_spline(heights, CELL, origin)
    i, j = np.arange(n)[:, None], np.arange(24)[None, :]
    scale = (np.ptp(heights), *(np.abs(oracle(k, origin[0] + i * CELL[0], origin[1] + j * CELL[1])).max()
                                for k in (1, 2)))
    for rows in (slice(0, n // 2), slice(n // 2, n)):
        for moved in (0.0, 0.37, 5.5, -17.25, 3 * n + 0.1, n // 2 + 0.8):
            x, y = origin[0] + (i[rows] - moved) * CELL[0], origin[1] + (j + 0.3) * CELL[1]
            got = (surface.height(x, y), *surface.slope(x, y))
            want = (oracle(0, x, y) - surface.lowest, oracle(1, x, y), oracle(2, x, y))
            for a, b, s in zip(got, want, scale):
                np.testing.assert_allclose(a, b, rtol=0, atol=1e-12 * s)
            # the rows of the points' stencils (half the grid and 3) and the margin each side
            assert surface.rows_held <= n // 2 + 1 + 3 + 2 * ROWS_MARGIN < n


# ---------------------------------------------------------------------------------------------------------
# scene keys: a height map in every format, roughness on smooth bodies

GRID = {"nx": 32, "ny": 24, "x": [-0.8e-3, 0.8e-3], "y": [-0.6e-3, 0.6e-3]}  # 50 um cells
MOTION = {"load": 0.1}
MATERIAL = {"model": "elastic", "E": 10e6, "nu": 0.5}


def scene_body(body: dict, tmp_path):
    raw = {"grid": GRID, "material": MATERIAL, "body": body, "motion": MOTION}
    return parse_scene(raw, source="test.toml", base_dir=tmp_path).body


def test_a_height_map_is_the_same_body_in_every_format(tmp_path):
    """A sphere's cap sampled 41 x 41 at 40 um, written as .npy (the oracle: petroll's .npy height map),
    a text matrix in um, an xyz list in mm and an .x3p file: the same heights and slopes everywhere."""
    k = (np.arange(41) - 20) * 40e-6
    heights = Sphere(0.01).height(k[:, None], k[None, :])
    np.save(tmp_path / "cap.npy", heights)
    np.savetxt(tmp_path / "cap.txt", heights * 1e6, fmt="%.17e")
    x, y = np.meshgrid(k * 1e3, k * 1e3, indexing="ij")
    np.savetxt(tmp_path / "cap.xyz", np.column_stack([x.ravel(), y.ravel(), heights.ravel() * 1e3]),
               fmt="%.17e")
    write_x3p(tmp_path / "cap.x3p", heights, (40e-6, 40e-6))
    oracle = scene_body({"shape": "heightmap", "file": "cap.npy", "cell": 40e-6}, tmp_path)
    px, py = np.linspace(-0.7e-3, 0.7e-3, 29)[:, None], np.linspace(-0.7e-3, 0.7e-3, 23)[None, :]
    for table in ({"file": "cap.txt", "cell": [40e-6, 40e-6], "unit": "um"},
                  {"file": "cap.xyz", "unit": "mm"}, {"file": "cap.x3p"}):
        body = scene_body({"shape": "heightmap", **table}, tmp_path)
        np.testing.assert_allclose(body.height(px, py), oracle.height(px, py), rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(body.slope(px, py), oracle.slope(px, py), rtol=1e-9, atol=1e-12)


ROUGH = {"hurst": 0.8, "rolloff": 0.4e-3, "cutoff": 0.2e-3, "rms_height": 0.2e-6, "seed": 4}


CYLINDER = {"shape": "cylinder", "radius": 0.01, "width": 1e-3, "edge_radius": 3e-4}


@pytest.mark.parametrize("smooth", [{"shape": "sphere", "radius": 0.01}, CYLINDER])
def test_generated_roughness_adds_to_the_smooth_body(tmp_path, smooth):
    rough = scene_body({**smooth, "roughness": ROUGH}, tmp_path)
    plain = scene_body(smooth, tmp_path)
    tile = PeriodicSurface(self_affine_heights(ROUGH, (32, 24), (50e-6, 50e-6)), (50e-6, 50e-6))
    px, py = np.linspace(-1e-3, 1e-3, 31)[:, None], np.linspace(-0.7e-3, 0.7e-3, 21)[None, :]
    np.testing.assert_allclose(rough.height(px, py), plain.height(px, py) + tile.height(px, py), rtol=1e-14)
    # the samples at the reference point's lattice, the tile repeating with the grid's size
    x, y = 1.6e-3 + 150e-6, -1.2e-3 * (smooth["shape"] == "sphere")
    np.testing.assert_allclose(rough.height(x, y) - plain.height(x, y), tile.heights[3, 0] - tile.lowest,
                               rtol=1e-9)


def test_measured_roughness_and_its_mistakes(tmp_path):
    heights = np.random.default_rng(2).normal(size=(16, 12)) * 1e-7
    write_x3p(tmp_path / "road.x3p", heights, (20e-6, 30e-6))
    body = scene_body({"shape": "sphere", "radius": 0.01, "roughness": {"file": "road.x3p"}}, tmp_path)
    lowest = body.roughness.lowest
    assert body.height(0.0, 0.0) == pytest.approx(heights[0, 0] - lowest, rel=1e-12)
    assert body.height(16 * 20e-6, 2 * 30e-6) - Sphere(0.01).height(16 * 20e-6, 2 * 30e-6) == pytest.approx(
        heights[0, 2] - lowest, rel=1e-9)
    cases = [({"file": "road.x3p", "seed": 1}, "[body] roughness.seed", "unknown key"),
             ({"file": "road.x3p", "unit": "um"}, "[body] roughness.unit", "metres"),
             ({"hurst": 0.8}, "[body] roughness.rms_height", "exactly one"),
             ({"hurst": 0.8, "rms_slope": 0.1, "cutoff": 10e-6}, "[body] roughness.cutoff", "2 cells"),
             (0.5, "[body] roughness", "inline table")]
    for roughness, key, words in cases:
        with pytest.raises(SceneError) as err:
            scene_body({"shape": "sphere", "radius": 0.01, "roughness": roughness}, tmp_path)
        assert key in str(err.value) and words in str(err.value), str(err.value)


def test_a_generated_rough_surface_has_one_sample_per_cell(tmp_path):
    """shape = "rough": the keys' surface drawn on the grid's nx x ny cells (self_affine_heights, itself
    checked against its spectrum in test_roughness.py), sample (i, j) on the centre of cell (i, j) and
    repeating; on a grid that does not repeat, the surface reaches its edges and is refused there."""
    keys = {"hurst": 0.7, "rolloff": 0.4e-3, "cutoff": 0.2e-3, "rms_slope": 0.05, "seed": 9}
    body = scene_body({"shape": "rough", **keys}, tmp_path)
    samples = self_affine_heights(keys, (32, 24), (50e-6, 50e-6))
    x, y = (np.arange(32) + 0.5)[:, None] * 50e-6 - 0.8e-3, (np.arange(24) + 0.5)[None, :] * 50e-6 - 0.6e-3
    np.testing.assert_allclose(body.height(x, y), samples - body.lowest, rtol=0, atol=1e-12 * np.ptp(samples))
    np.testing.assert_allclose(body.height(x + 1.6e-3, y - 1.2e-3), body.height(x, y), rtol=0, atol=1e-18)
    raw = {"grid": GRID, "material": MATERIAL, "body": {"shape": "rough", **keys},
           "motion": {"penetration": 0.5 * np.ptp(samples)}}
    with pytest.raises(SceneError, match=r"\[grid\] x / y.*up to the grid's edge"):
        parse_scene(raw, source="test.toml")
    with pytest.raises(SceneError, match=r"\[body\] seed"):
        scene_body({"shape": "rough", **keys, "seed": "one"}, tmp_path)


def test_a_generated_surface_makes_its_coefficients_once_before_its_run(monkeypatch):
    """runs/rough-rubber.toml's surface (a periodic grid's generated rough body) read and checked before a
    run (load_scene, the pre-flight, the path's checks, the first whole-grid heights and slopes): its
    spline coefficients are made once, for every row (its lowest point needs some, the pre-flight's
    queries between the samples others), and let go by the run's whole-grid queries, which lie on the
    samples and need none; its samples' spectrum is made where asked for, not kept (8 bytes per sample):
    for the contact scale and the cut-off (the slopes on the samples, for the radius hint and the run, come
    from 1-D transforms a block at a time, rough._spectral_slope)."""
    import sys

    import scipy.fft

    from petroll.model import preflight
    from petroll.model.bodies import rough
    from petroll.model.scene import load_scene, shipped_scene

    made = {"coefficients": 0, "spectra": 0}
    coefficients, rfft2 = rough._row_coefficients, scipy.fft.rfft2

    def counted(*args):
        made["coefficients"] += 1
        return coefficients(*args)

    def transformed(*args, **kwargs):  # the surface's transforms (not the generator's, of its own)
        made["spectra"] += sys._getframe(1).f_globals["__name__"] == rough.__name__
        return rfft2(*args, **kwargs)

    monkeypatch.setattr(rough, "_row_coefficients", counted)
    monkeypatch.setattr(scipy.fft, "rfft2", transformed)
    scene = load_scene(shipped_scene("rough-rubber.toml"))
    preflight.check_run(scene)
    g = scene.grid
    scene.body.height(g.x[:, None], g.y[None, :])
    scene.body.slope(g.x[:, None], g.y[None, :])
    assert made == {"coefficients": 1, "spectra": 2} and scene.body.rows_held == 0
