"""Tests of petroll.model.bodies: analytic bodies, height maps, rasterised meshes and the scene-table factory."""

import math
import pathlib

import meshio
import numpy as np
import pytest

from petroll.model import bodies
from petroll.model.bodies import (
    BODY_KEYS,
    Body,
    Cylinder,
    Ellipsoid,
    HeightMap,
    Sphere,
    make_body,
    mesh_height_map,
)
from petroll.errors import SceneError

RNG = np.random.default_rng(20240611)


def fd_slope(body, x, y, h=1e-6):
    """Central finite differences of body.height."""
    return (
        (body.height(x + h, y) - body.height(x - h, y)) / (2 * h),
        (body.height(x, y + h) - body.height(x, y - h)) / (2 * h),
    )


def raises_key(key, fn, *args, **kwargs):
    with pytest.raises(SceneError) as info:
        fn(*args, **kwargs)
    assert info.value.key == key
    assert key in str(info.value)
    return info.value


# ------------------------------------------------------------------------------------------------ sphere


def test_sphere_height_matches_exact_formula():
    radius = 0.7
    body = Sphere(radius)
    r = RNG.uniform(0, radius * 0.999, 500)
    phi = RNG.uniform(0, 2 * np.pi, 500)
    x, y = r * np.cos(phi), r * np.sin(phi)
    expected = np.array([radius - math.sqrt(radius**2 - ri**2) for ri in r])
    np.testing.assert_allclose(body.height(x, y), expected, rtol=1e-12, atol=1e-15)
    assert body.height(0.0, 0.0) == 0.0
    assert body.radius_hint == radius
    assert isinstance(body, Body)


def test_sphere_near_apex_is_paraboloid():
    radius = 2.0
    body = Sphere(radius)
    r = np.linspace(0, 0.02, 41)
    z = body.height(r / math.sqrt(2), r / math.sqrt(2))
    # Z = r^2/(2R) + r^4/(8R^3) + ..., all terms positive
    excess = z - r**2 / (2 * radius)
    assert np.all(excess >= -1e-18)
    assert np.all(excess <= r**4 / (8 * radius**3) * 1.01 + 1e-18)


def test_sphere_continuation_beyond_radius():
    body = Sphere(1.0)
    np.testing.assert_allclose(body.height(np.array([1.0, 1.5, 3.0]), 0.0), [1.0, 1.5, 3.0])
    sx, sy = body.slope(np.array([0.0, 3.0]), np.array([2.0, 4.0]))
    np.testing.assert_allclose(sx, [0.0, 0.6])
    np.testing.assert_allclose(sy, [1.0, 0.8])


def test_sphere_slope_matches_finite_differences_and_broadcasts():
    body = Sphere(0.5)
    x = RNG.uniform(-0.3, 0.3, (40, 1))
    y = RNG.uniform(-0.3, 0.3, (1, 30))
    sx, sy = body.slope(x, y)
    fx, fy = fd_slope(body, x, y)
    assert sx.shape == sy.shape == (40, 30) == body.height(x, y).shape
    np.testing.assert_allclose(sx, fx, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(sy, fy, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf"), "1.0", True, None])
def test_sphere_rejects_bad_radius(bad):
    err = raises_key("[body] radius", Sphere, bad, source="scene.toml")
    assert str(err).startswith("scene.toml: [body] radius = ")


# --------------------------------------------------------------------------------------------- ellipsoid


def test_ellipsoid_with_equal_radii_is_sphere_paraboloid():
    body = Ellipsoid(0.4, 0.4)
    x, y = RNG.uniform(-1, 1, 100), RNG.uniform(-1, 1, 100)
    np.testing.assert_allclose(body.height(x, y), (x**2 + y**2) / 0.8, rtol=1e-14)
    assert body.radius_hint == pytest.approx(0.4)


def test_ellipsoid_values_and_slopes():
    body = Ellipsoid(radius_x=2.0, radius_y=0.5)
    # by hand: Z(1, 1) = 1/4 + 1 = 1.25; slope (x/Rx, y/Ry) = (0.5, 2)
    assert float(body.height(1.0, 1.0)) == pytest.approx(1.25, rel=1e-15)
    sx, sy = body.slope(np.array([1.0]), np.array([1.0]))
    assert (sx[0], sy[0]) == pytest.approx((0.5, 2.0), rel=1e-15)
    x, y = RNG.uniform(-1, 1, (20, 1)), RNG.uniform(-1, 1, (1, 15))
    sx, sy = body.slope(x, y)
    fx, fy = fd_slope(body, x, y)
    assert sx.shape == sy.shape == (20, 15)
    np.testing.assert_allclose(sx, fx, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(sy, fy, rtol=1e-7, atol=1e-9)
    assert body.radius_hint == pytest.approx(1.0)


def test_ellipsoid_rejects_bad_radii():
    raises_key("[body] radius_x", Ellipsoid, -1.0, 1.0)
    raises_key("[body] radius_y", Ellipsoid, 1.0, 0)


# ---------------------------------------------------------------------------------------------- cylinder


def test_cylinder_mid_plane_is_circle():
    body = Cylinder(radius=0.3, width=0.2)
    s = np.linspace(-0.29, 0.29, 59)
    np.testing.assert_allclose(body.height(s, 0.0), 0.3 - np.sqrt(0.09 - s**2), rtol=1e-12, atol=1e-16)
    # flat along the axis up to the edge
    t = np.linspace(-0.1, 0.1, 21)
    np.testing.assert_allclose(body.height(0.05, t), 0.3 - math.sqrt(0.09 - 0.05**2), rtol=1e-14)
    assert body.radius_hint == 0.3


def test_cylinder_sharp_edge_jumps_to_inf():
    body = Cylinder(radius=1.0, width=2.0)
    z = body.height(0.1, np.array([-1.0 - 1e-12, -1.0, 0.999999, 1.0, 1.0 + 1e-12, 5.0]))
    base = 1.0 - math.sqrt(1.0 - 0.01)
    np.testing.assert_allclose(z[1:4], base, rtol=1e-14)
    assert np.isinf(z[0]) and np.isinf(z[4]) and np.isinf(z[5])
    sx, sy = body.slope(np.array([0.1, 0.1]), np.array([0.5, 1.5]))
    assert sy[0] == 0.0 and sx[1] == 0.0 and sy[1] == 0.0


def test_cylinder_rounded_edge_is_quarter_circle():
    # R = 1, W = 2, e = 0.5: flat for |t| <= 0.5, rounded for 0.5 < |t| <= 1
    body = Cylinder(1.0, 2.0, edge_radius=0.5)
    t = np.array([0.0, 0.5, 0.8, 0.5 + 0.5 * math.sin(math.pi / 6), 1.0, -0.8, 1.0 + 1e-9])
    # by hand: u = |t| - 0.5; edge = 0.5 - sqrt(0.25 - u^2)
    expected = [0.0, 0.0, 0.1, 0.5 - 0.5 * math.cos(math.pi / 6), 0.5, 0.1, math.inf]
    np.testing.assert_allclose(body.height(0.0, t), expected, rtol=1e-12, atol=1e-15)
    # continuity into the rounded edge, slope there by finite differences
    y = np.linspace(-0.95, 0.95, 77)
    x = np.linspace(-0.6, 0.6, 13)[:, None]
    sx, sy = body.slope(x, y)
    fx, fy = fd_slope(body, x, y, h=1e-7)
    np.testing.assert_allclose(sx, fx, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(sy, fy, rtol=1e-5, atol=1e-7)
    # the slope stays finite at the rim (unit-slope convention)
    _, rim = body.slope(np.array([0.0, 0.0]), np.array([1.0, -1.0]))
    np.testing.assert_array_equal(rim, [1.0, -1.0])


def test_cylinder_axis_x_is_transposed():
    by = Cylinder(0.4, 0.3, edge_radius=0.05, axis="y")
    bx = Cylinder(0.4, 0.3, edge_radius=0.05, axis="x")
    a = np.linspace(-0.2, 0.2, 33)[:, None]
    b = np.linspace(-0.39, 0.39, 41)[None, :]
    np.testing.assert_allclose(bx.height(b.T, a.T), by.height(a, b).T, rtol=1e-15, atol=0)
    syx, syy = by.slope(a, b)
    sxx, sxy = bx.slope(b.T, a.T)
    np.testing.assert_allclose(sxx, syy.T, rtol=1e-15, atol=0)
    np.testing.assert_allclose(sxy, syx.T, rtol=1e-15, atol=0)
    # axis x: rolls along y, so the circle is in y and the width is along x
    assert np.isinf(bx.height(0.16, 0.0)) and np.isfinite(bx.height(0.0, 0.3))


@pytest.mark.parametrize(
    "kwargs, key",
    [
        (dict(radius=0.0, width=1.0), "[body] radius"),
        (dict(radius=1.0, width=-1.0), "[body] width"),
        (dict(radius=1.0, width=1.0, edge_radius=0.6), "[body] edge_radius"),
        (dict(radius=1.0, width=1.0, edge_radius=-0.1), "[body] edge_radius"),
        (dict(radius=1.0, width=1.0, edge_radius="0.1"), "[body] edge_radius"),
        (dict(radius=1.0, width=1.0, axis="z"), "[body] axis"),
        (dict(radius=1.0, width=1.0, axis=1), "[body] axis"),
    ],
)
def test_cylinder_rejects_bad_arguments(kwargs, key):
    raises_key(key, Cylinder, **kwargs)


def test_cylinder_edge_radius_half_width_allowed():
    body = Cylinder(1.0, 1.0, edge_radius=0.5)
    assert float(body.height(0.0, 0.0)) == 0.0
    assert float(body.height(0.0, 0.25)) == pytest.approx(0.5 - math.sqrt(0.25 - 0.0625))


# --------------------------------------------------------------------------------------------- heightmap


RX, RY = 0.8, 0.3
HX, HY = 0.01, 0.02


def paraboloid_map(center=(0.03, -0.04)):
    """Map of x^2/(2Rx) + y^2/(2Ry) + 5 on a grid that has a node at the origin."""
    nx, ny = 21, 15
    xs = center[0] - (nx - 1) * HX / 2 + HX * np.arange(nx)
    ys = center[1] - (ny - 1) * HY / 2 + HY * np.arange(ny)
    assert np.min(np.abs(xs)) < 1e-12 and np.min(np.abs(ys)) < 1e-12
    heights = xs[:, None] ** 2 / (2 * RX) + ys[None, :] ** 2 / (2 * RY) + 5.0
    return HeightMap(heights, (HX, HY), center), xs, ys


def exact(x, y):
    return x**2 / (2 * RX) + y**2 / (2 * RY)


def test_heightmap_reproduces_samples_exactly():
    body, xs, ys = paraboloid_map()
    x, y = xs[:, None], ys[None, :]
    np.testing.assert_allclose(body.height(x, y), exact(x, y), atol=1e-13)
    assert float(body.height(0.0, 0.0)) == pytest.approx(0.0, abs=1e-13)


def test_heightmap_reproduces_a_cubic_between_samples():
    """The bicubic spline holds every cubic polynomial exactly: heights (up to the common minimum) and slopes
    of x^2/(2Rx) + y^2/(2Ry) + cubic terms at arbitrary points, also next to the map's edges."""
    body, xs, ys = paraboloid_map()
    a, b, c = 0.7, -0.4, 0.9

    def cubic(x, y):
        return exact(x, y) + a * x**3 + b * x * y**2 + c * x**2 * y

    heights = cubic(xs[:, None], ys[None, :])
    body = HeightMap(heights, (HX, HY), (0.03, -0.04))
    x = RNG.uniform(xs[0], xs[-1], 400)
    y = RNG.uniform(ys[0], ys[-1], 400)
    z = body.height(x, y)
    np.testing.assert_allclose(z - z[0], cubic(x, y) - cubic(x[0], y[0]), atol=1e-13)
    sx, sy = body.slope(x, y)
    np.testing.assert_allclose(sx, x / RX + 3 * a * x**2 + b * y**2 + 2 * c * x * y, atol=1e-11)
    np.testing.assert_allclose(sy, y / RY + 2 * b * x * y + c * x**2, atol=1e-11)


@pytest.mark.parametrize("offset", [0.0, 0.001, 0.25, 0.5])
def test_heightmap_sphere_heights_and_slopes_do_not_see_the_samples(offset):
    """A sphere sampled on a lattice offset by a fraction of its spacing from the points it is evaluated at
    (the grid's cell centres): slopes within 1e-4 of the bilinear bias h / (2R) of the exact sphere's,
    heights within O(h^4), at every offset; Z >= 0 with its zero at the apex even where no sample is."""
    radius, h = 1.0, 0.02
    sphere = Sphere(radius)
    k = np.arange(-15, 16)
    samples = (k + offset) * h
    center = (offset * h, offset * h)  # the map's middle sample sits at (offset h, offset h)
    body = HeightMap(sphere.height(samples[:, None], samples[None, :]), h, center)
    x = (np.arange(-10, 11) * h)[:, None]  # points on the unshifted lattice
    y = (np.arange(-10, 11) * h + 0.3 * h)[None, :]
    sx, sy = body.slope(x, y)
    ex, ey = sphere.slope(x, y)
    bias = h / (2 * radius)
    assert np.abs(sx - ex).max() <= 1e-4 * bias
    assert np.abs(sy - ey).max() <= 1e-4 * bias
    np.testing.assert_allclose(body.height(x, y), sphere.height(x, y), atol=1e-4 * h**2 / radius)
    fine = np.linspace(-3 * h, 3 * h, 121)
    z = body.height(fine[:, None], fine[None, :])
    assert z.min() >= -1e-15 and z.min() <= 1e-9 * h**2 / radius
    assert float(body.height(0.0, 0.0)) <= 1e-6 * h**2 / radius


def test_heightmap_outside_is_inf_with_zero_slope():
    body, xs, ys = paraboloid_map()
    x = np.array([xs[0] - 1e-8, xs[-1] + 1e-8, 0.0, 0.0, xs[0], xs[-1]])
    y = np.array([0.0, 0.0, ys[0] - 1e-8, ys[-1] + 1e-8, ys[0], ys[-1]])
    z = body.height(x, y)
    assert np.all(np.isinf(z[:4])) and np.all(np.isfinite(z[4:]))
    sx, sy = body.slope(x, y)
    assert np.all(sx[:4] == 0) and np.all(sy[:4] == 0)


def test_heightmap_radius_hint():
    body, _, _ = paraboloid_map()
    assert body.radius_hint == pytest.approx(math.sqrt(RX * RY), rel=1e-6)
    flat = HeightMap(np.zeros((5, 3)), 0.5)
    assert flat.radius_hint == pytest.approx(1.0)  # half the larger extent (4 * 0.5 / 2)


def test_heightmap_scalar_cell_and_broadcast():
    heights = RNG.uniform(0, 1, (6, 7))
    body = HeightMap(heights, 0.1)
    assert body.cell == (0.1, 0.1)
    z = body.height(np.zeros((3, 1)), np.zeros((1, 4)))
    assert z.shape == (3, 4)
    # centre (0, 0) lies in the middle of the grid: x nodes at -0.25 ... 0.25
    corners = body.height(np.array([-0.25, 0.25]), np.array([-0.3, 0.3]))
    assert corners[1] - corners[0] == pytest.approx(heights[-1, -1] - heights[0, 0], abs=1e-14)


def test_heightmap_inf_entries_mean_no_surface():
    heights = np.zeros((4, 4))
    heights[0, 0] = np.inf
    heights[2, 2] = -1.0
    body = HeightMap(heights, 1.0)  # nodes at -1.5, -0.5, 0.5, 1.5
    assert np.isinf(body.height(-1.2, -1.2))  # cell with the +inf corner
    assert float(body.height(1.5, 1.5)) - float(body.height(0.5, 0.5)) == pytest.approx(1.0, abs=1e-14)
    fine = np.linspace(-1.5, 1.5, 1201)  # Z >= 0, and 0 at its lowest point (the spline's, not a sample's)
    z = body.height(fine[:, None], fine[None, :])
    assert 0.0 <= z[np.isfinite(z)].min() <= 1e-4


def test_heightmap_npy_round_trip(tmp_path):
    heights = RNG.uniform(-1, 1, (8, 5))
    path = tmp_path / "map.npy"
    np.save(path, heights)
    body = HeightMap.from_npy(path, [0.1, 0.2], source="s.toml")
    np.testing.assert_array_equal(body.heights, heights)
    direct = HeightMap(heights, (0.1, 0.2))
    x, y = RNG.uniform(-0.4, 0.4, 50), RNG.uniform(-0.5, 0.5, 50)
    np.testing.assert_allclose(body.height(x, y), direct.height(x, y), rtol=1e-15, atol=0)


@pytest.mark.parametrize(
    "heights",
    [np.zeros(5), np.zeros((2, 2, 2)), np.zeros((1, 5)), np.zeros((5, 1)), [[0, 1], [np.nan, 0]],
     [[0, 1], [-np.inf, 0]], np.full((3, 3), np.inf), [["a", "b"], ["c", "d"]]],
)
def test_heightmap_rejects_bad_heights(heights, tmp_path):
    raises_key("[body] file", HeightMap, heights, 0.1)
    if np.asarray(heights).dtype.kind == "f":
        path = tmp_path / "bad.npy"
        np.save(path, np.asarray(heights))
        err = raises_key("[body] file", HeightMap.from_npy, path, 0.1, source="x.toml")
        assert str(path) in str(err) and str(err).startswith("x.toml: ")


@pytest.mark.parametrize("cell", [0.0, -0.1, float("nan"), "0.1", True, [0.1], [0.1, 0.0], [0.1, 0.2, 0.3]])
def test_heightmap_rejects_bad_cell(cell):
    raises_key("[body] cell", HeightMap, np.zeros((3, 3)), cell)


def test_from_npy_rejects_unreadable_files(tmp_path):
    raises_key("[body] file", HeightMap.from_npy, tmp_path / "missing.npy", 0.1)
    garbage = tmp_path / "garbage.npy"
    garbage.write_text("not a numpy file")
    err = raises_key("[body] file", HeightMap.from_npy, garbage, 0.1)
    assert "is not a .npy file" in str(err)
    npz = tmp_path / "z.npz"
    np.savez(npz, a=np.zeros((3, 3)))
    raises_key("[body] file", HeightMap.from_npy, npz, 0.1)


# -------------------------------------------------------------------------------------------------- mesh


def spherical_cap(radius=1.0, cap=0.5, rings=40, sectors=128, shift=(0.0, 0.0, 0.0)):
    """Triangulated lower cap of a sphere (apex vertex at shift), and its longest edge."""
    points = [[0.0, 0.0]]
    for k in range(1, rings + 1):
        r = cap * k / rings
        phi = 2 * np.pi * np.arange(sectors) / sectors + (0.5 * np.pi / sectors) * (k % 2)
        points.extend(np.column_stack([r * np.cos(phi), r * np.sin(phi)]))
    points = np.array(points)
    z = radius - np.sqrt(radius**2 - (points**2).sum(axis=1))
    xyz = np.column_stack([points, z]) + np.array(shift)
    tris = []
    for s in range(sectors):
        tris.append([0, 1 + s, 1 + (s + 1) % sectors])
    for k in range(1, rings):
        a, b = 1 + (k - 1) * sectors, 1 + k * sectors
        for s in range(sectors):
            s1 = (s + 1) % sectors
            tris.append([a + s, b + s, b + s1])
            tris.append([a + s, b + s1, a + s1])
    tris = np.array(tris)
    e = xyz[tris[:, [1, 2, 0]]] - xyz[tris]
    longest = np.sqrt((e[..., :2] ** 2).sum(axis=-1)).max()
    return xyz, tris, longest


def check_cap(body, radius=1.0, cap=0.5, sectors=128, longest=0.05, bare=True, margin=0.0):
    """The mesh's height map on the sphere's within the interpolation bound of the mesh's longest edge (the
    facets lie above the sphere by at most that; the spline through their samples stays within it), more
    than ``margin`` inside the cap's rim (where the surface ends or jumps, the spline rings)."""
    assert isinstance(body, HeightMap)
    sphere = Sphere(radius)
    g = np.arange(-0.6, 0.6 + 1e-12, 0.0125)
    x, y = g[:, None], g[None, :]
    z = body.height(x, y)
    r = np.hypot(x, y)
    inner = r < cap * math.cos(np.pi / sectors) * 0.97 - margin
    # piecewise-linear interpolation of a convex surface lies above it, by at most ~ h^2 max|Z''| / 2
    curvature = radius**2 / (radius**2 - cap**2) ** 1.5
    bound = 0.5 * longest**2 * curvature
    diff = z[inner] - sphere.height(x, y)[inner]
    assert np.abs(diff).max() <= bound
    if bare:
        assert np.all(np.isinf(z[r > cap * 1.02]))
    assert float(body.height(0.0, 0.0)) == pytest.approx(0.0, abs=1e-12)
    assert body.radius_hint == pytest.approx(radius, rel=0.05)


@pytest.mark.slow
@pytest.mark.parametrize("ext", ["stl", "obj"])
def test_mesh_sphere_cap_matches_sphere(tmp_path, ext):
    xyz, tris, longest = spherical_cap()
    assert longest < 0.035
    path = tmp_path / f"cap.{ext}"
    meshio.write_points_cells(path, xyz, [("triangle", tris)])
    body = mesh_height_map(path, 0.01)
    check_cap(body, longest=longest)


@pytest.mark.slow
@pytest.mark.parametrize("chunk", [2_000_000, 5_000])
def test_mesh_reference_point_is_lowest_vertex_and_lowest_surface_wins(tmp_path, monkeypatch, chunk):
    monkeypatch.setattr(bodies.mesh, "_RASTER_CHUNK", chunk)  # small chunks: the minimum spans several
    xyz, tris, longest = spherical_cap(shift=(0.3, -0.2, 0.7))
    # a second copy of the cap lying above it and sticking out to +x (so that the x-y bounding box is not
    # centred on the lowest vertex) must not matter where it overlaps the lower cap
    upper = xyz + np.array([0.25, 0.0, 0.3])
    points = np.vstack([xyz, upper])  # lower surface first, so the upper one is rasterised last
    cells = np.vstack([tris, tris + len(xyz)])
    path = tmp_path / "cap2.obj"
    meshio.write_points_cells(path, points, [("triangle", cells)])
    body = mesh_height_map(path, [0.01, 0.0125])
    check_cap(body, longest=longest, bare=False, margin=0.05)  # the upper cap begins at the lower's rim
    assert np.isfinite(body.height(0.7, 0.0)) and np.isinf(body.height(-0.55, 0.0))


def test_mesh_errors(tmp_path):
    empty = tmp_path / "empty.stl"
    empty.write_bytes(b"")
    raises_key("[body] file", mesh_height_map, empty, 0.01)
    raises_key("[body] file", mesh_height_map, tmp_path / "nope.stl", 0.01)
    lines = tmp_path / "lines.vtk"
    meshio.write_points_cells(lines, np.eye(3), [("line", np.array([[0, 1], [1, 2]]))])
    err = raises_key("[body] file", mesh_height_map, lines, 0.01, source="m.toml")
    assert "triangle" in str(err) and str(err).startswith("m.toml: ")
    xyz, tris, _ = spherical_cap(rings=4, sectors=16)
    ok = tmp_path / "small.stl"
    meshio.write_points_cells(ok, xyz, [("triangle", tris)])
    raises_key("[body] cell", mesh_height_map, ok, -1.0)
    raises_key("[body] cell", mesh_height_map, ok, 10.0)


def test_mesh_of_many_triangles_rasterises_to_its_sphere(tmp_path):
    """~51k triangles (a binary STL, float32 coordinates) on a 251 x 251 raster: the sphere within the
    interpolation bound (how fast is a benchmark's business, not a unit test's)."""
    xyz, tris, longest = spherical_cap(rings=100, sectors=256)
    path = tmp_path / "big.stl"
    meshio.write_points_cells(path, xyz, [("triangle", tris)], binary=True)
    body = mesh_height_map(path, 0.004)
    assert body.heights.shape == (251, 251)
    check_cap(body, sectors=256, longest=longest)


# ------------------------------------------------------------------------------------------- make_body


def test_make_body_builds_each_shape(tmp_path):
    src = "scene.toml"
    sphere = make_body({"shape": "sphere", "radius": 0.01, "position": [0, 0]}, tmp_path, src)
    assert sphere == Sphere(0.01)
    ell = make_body({"shape": "ellipsoid", "radius_x": 1, "radius_y": 2.0}, tmp_path, src)
    assert ell == Ellipsoid(1.0, 2.0)
    cyl = make_body({"shape": "cylinder", "radius": 1.0, "width": 0.5}, tmp_path, src)
    assert cyl == Cylinder(1.0, 0.5, 0.0, "y")
    table = {"shape": "cylinder", "radius": 1.0, "width": 0.5, "edge_radius": 0.1, "axis": "x"}
    cyl2 = make_body(table, tmp_path, src)
    assert cyl2 == Cylinder(1.0, 0.5, 0.1, "x")

    sub = tmp_path / "data"
    sub.mkdir()
    np.save(sub / "m.npy", np.arange(12.0).reshape(3, 4))
    hm = make_body({"shape": "heightmap", "file": "data/m.npy", "cell": [0.1, 0.2]}, tmp_path, src)
    assert isinstance(hm, HeightMap) and hm.cell == (0.1, 0.2)
    np.testing.assert_array_equal(hm.heights, np.arange(12.0).reshape(3, 4))
    table = {"shape": "heightmap", "file": str(sub / "m.npy"), "cell": 0.1}
    hm2 = make_body(table, pathlib.Path("/nonexistent"), src)  # absolute paths ignore base_dir
    assert hm2.cell == (0.1, 0.1)

    xyz, tris, _ = spherical_cap(rings=10, sectors=32)
    meshio.write_points_cells(sub / "cap.stl", xyz, [("triangle", tris)])
    mesh = make_body({"shape": "mesh", "file": "data/cap.stl", "cell": 0.05}, tmp_path, src)
    assert isinstance(mesh, HeightMap) and float(mesh.height(0.0, 0.0)) == pytest.approx(0.0, abs=1e-15)


def test_body_keys_cover_every_shape():
    assert set(BODY_KEYS) == {"sphere", "ellipsoid", "cylinder", "heightmap", "rough", "mesh"}
    for keys in BODY_KEYS.values():
        assert all(isinstance(desc, str) and desc for desc in keys.values())
    assert set(BODY_KEYS["cylinder"]) == {"radius", "width", "edge_radius", "axis", "roughness"}
    assert set(BODY_KEYS["heightmap"]) == {"file", "cell", "format", "unit"}


@pytest.mark.parametrize(
    "table, key, fragment",
    [
        ({"shape": "sphere", "radius": 1.0, "width": 2.0}, "[body] width", "radius"),
        ({"shape": "ellipsoid", "radius": 1, "radius_x": 1, "radius_y": 1}, "[body] radius", "radius_x"),
        ({"shape": "sphere"}, "[body] radius", "required"),
        ({"shape": "cylinder", "radius": 1.0}, "[body] width", "required"),
        ({"shape": "heightmap", "file": "m.npy"}, "[body] cell", "required"),
        ({"shape": "sphere", "radius": "1.0"}, "[body] radius", "number"),
        ({"shape": "sphere", "radius": True}, "[body] radius", "number"),
        ({"shape": "sphere", "radius": -1.0}, "[body] radius", "> 0"),
        ({"shape": "cylinder", "radius": 1.0, "width": 0.0}, "[body] width", "> 0"),
        ({"shape": "ellipsoid", "radius_x": 1.0, "radius_y": [1.0]}, "[body] radius_y", "number"),
        ({"shape": "heightmap", "file": 3, "cell": 0.1}, "[body] file", "path"),
        ({"shape": "heightmap", "file": "m.npy", "cell": "0.1"}, "[body] cell", "number"),
        ({"shape": "mesh", "file": "m.stl", "cell": -0.1}, "[body] cell", "> 0"),
        ({"shape": "heightmap", "file": "absent.npy", "cell": 0.1}, "[body] file", "cannot read"),
        ({"shape": "cone", "radius": 1.0}, "[body] shape", "sphere"),
        ({"radius": 1.0}, "[body] shape", "sphere"),
    ],
)
def test_make_body_errors(tmp_path, table, key, fragment):
    err = raises_key(key, make_body, table, tmp_path, "my.toml")
    message = str(err)
    assert message.startswith(f"my.toml: {key} = ")
    assert fragment in message


def test_make_body_missing_value_is_marked():
    err = raises_key("[body] radius", make_body, {"shape": "sphere"}, pathlib.Path("."), "a.toml")
    assert "(missing)" in str(err)
