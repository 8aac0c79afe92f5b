"""Rough bodies (petroll.model.surfaces): a periodic surface returns its samples at the sample points,
repeats with its period, and between samples follows a smooth surface (a sum of Fourier modes) to the
spline's O(h^4) in height and the slope to O(h^3); roughness on a sphere adds to it."""

import numpy as np
import pytest

from petroll.errors import SceneError
from petroll.model.bodies import Cylinder, Sphere
from petroll.model.surfaces import PeriodicSurface, RoughBody

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
    np.testing.assert_allclose(surface.height(x, y), h - h.min(), rtol=0, atol=1e-12 * np.ptp(h))
    np.testing.assert_allclose(surface.height(x + 2 * period[0], y - period[1]), surface.height(x, y),
                               rtol=0, atol=1e-12 * np.ptp(h))


@pytest.mark.parametrize("n", [16, 32])
def test_between_samples_it_follows_a_smooth_surface(n):
    surface, h, period = surface_of_modes(n)
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-period[0], period[0], 500), rng.uniform(0, 2 * period[1], 500)
    exact, ex, ey = modes(x, y, period)
    height_error = np.abs(surface.height(x, y) - (exact - h.min())).max() / np.ptp(h)
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


def test_roughness_adds_to_a_smooth_body():
    roughness, _, _ = surface_of_modes(16)
    x, y = np.linspace(-4e-5, 4e-5, 9)[:, None], np.linspace(-6e-5, 6e-5, 7)[None, :]
    for body in (Sphere(1e-3), Cylinder(1e-3, width=1e-4, edge_radius=1e-5)):
        rough = RoughBody(body, roughness)
        np.testing.assert_array_equal(rough.height(x, y), body.height(x, y) + roughness.height(x, y))
        slope = np.add(body.slope(x, y), roughness.slope(x, y))
        outside = np.isinf(body.height(x, y))
        np.testing.assert_array_equal(rough.slope(x, y), np.where(outside, 0.0, slope))
        assert rough.radius_hint == body.radius_hint
    assert np.isinf(RoughBody(Cylinder(1e-3, width=1e-4), roughness).height(0.0, 1e-4)).all()


def test_bad_samples_are_refused():
    with pytest.raises(SceneError, match="at least 4 x 4 finite heights"):
        PeriodicSurface(np.full((8, 8), np.nan), CELL)
