"""What a rough surface's contact will be, from its spectrum and the load, before a run (``petroll check``,
the run's checks: petroll.model.preflight; the slope check: petroll.model.limits).

A periodic grid's surface (petroll.model.bodies.rough.PeriodicSurface) has no curvature radius that sizes
its contact: its contact is many small spots. Its estimates are

- **the short cut-off wavelength** lambda_s = 2 pi / q_s, q_s the wavenumber below which
  ``SLOPE_SHARE`` of the surface's mean square slope lies (a generated surface: just below its [body]
  cutoff; a measured one: where its spectrum ends), and the cells per lambda_s along the grid's coarser
  axis: below ``GOOD_CUTOFF_CELLS`` the run warns (measured: docs/rough.md);
- **the area fraction** A/A0 = erf(sqrt(2) p0 / (M h'_rms)) of Persson's theory for an elastic solid of
  plane-strain modulus M = 1/J (p0 the nominal pressure load / cell area, h'_rms the rms slope), with the
  glassy J0 and the rubbery Jinf: the contact a viscoelastic solid makes lies between them;
- **the penetration**: the rigid interference Z < delta covering ``INTERFERENCE_SHARE`` times A/A0 of the
  cell (each single contact's interference region is about twice its contact, as a Hertz contact's
  sqrt(2) a radius), Z the body's heights at the cells (the largest over the compliance range: the
  rubbery one), below mean(Z), where full contact is.

Under penetration control the estimates go the other way: the area fraction is 1 / INTERFERENCE_SHARE of
the interference's.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
from scipy.special import erf

from petroll.model.bodies.rough import PeriodicSurface

SLOPE_SHARE = 0.99
"""The share of the mean square slope below the short cut-off wavenumber q_s."""

GOOD_CUTOFF_CELLS = 4
"""Cells per short cut-off wavelength below which a run warns (docs/rough.md: the measurement)."""

INTERFERENCE_SHARE = 2.0
"""Interference area over contact area of a rough surface's single contacts (Hertz: (sqrt(2) a)^2 / a^2)."""


@dataclass(frozen=True)
class RoughContact:
    """The estimates of a periodic rough surface's contact (lengths in m).

    ``cutoff``: the short cut-off wavelength lambda_s; ``cells``: cells per lambda_s along the coarser
    axis; ``rms_slope``: h'_rms; ``spot``: the half-width of a single contact (PeriodicSurface.
    contact_scale); ``area``: A/A0 (glassy, rubbery); ``penetration``: delta (glassy, rubbery);
    ``relief``: highest - lowest point of the surface; ``exact``: the penetration is the scene's."""

    cutoff: float
    cells: float
    rms_slope: float
    spot: float
    area: tuple[float, float]
    penetration: tuple[float, float]
    relief: float
    exact: bool

    def lines(self, axis_cell: float) -> list[str]:
        """``petroll check``'s lines on the surface, its contact and the cut-off's resolution (``axis_cell``:
        the grid's longer cell side, m)."""
        control = ("penetration" if self.exact else "Persson's theory at the load, from the spectrum: "
                   "A/A0 = erf(sqrt(2) p0 J / h'_rms)")
        verdict = (f"at least {GOOD_CUTOFF_CELLS}, fine" if self.cells >= GOOD_CUTOFF_CELLS else
                   f"fewer than {GOOD_CUTOFF_CELLS}: a run warns")
        return [f"rough surface: rms slope {self.rms_slope:.4g}, relief {self.relief:.4g} m, single contacts "
                f"about {self.spot:.3g} m in half-width",
                f"contact ({control}): area fraction A/A0 {self.area[0]:.3g} glassy (J0), {self.area[1]:.3g} "
                f"rubbery (Jinf); penetration {self.penetration[0]:.4g} m glassy, {self.penetration[1]:.4g} m "
                "rubbery" + (" (the scene's)" if self.exact else " (estimated: interference over twice the "
                             "area)"),
                f"resolution: short cut-off wavelength {self.cutoff:.4g} m ({SLOPE_SHARE:.0%} of the mean "
                f"square slope at longer wavelengths): {self.cells:.1f} cells of {axis_cell:.4g} m per "
                f"cut-off, {verdict} (docs/rough.md)"]

    def warning(self, source: str, axis_cell: float) -> str | None:
        """The one-line warning on too few cells per cut-off, None if there are enough."""
        if self.cells >= GOOD_CUTOFF_CELLS:
            return None
        return (f"{source}: [grid]: {self.cells:.1f} cells of {axis_cell:.4g} m per short cut-off wavelength "
                f"{self.cutoff:.4g} m of the rough surface, fewer than {GOOD_CUTOFF_CELLS}: its area and "
                f"friction are not resolved (docs/rough.md); cells of {self.cutoff / GOOD_CUTOFF_CELLS:.4g} m "
                f"give {GOOD_CUTOFF_CELLS}")


def periodic_surface(scene) -> PeriodicSurface | None:
    """The rough surface that is the body of a 3-D grid periodic along X and Y, else None (line contact's
    profiles keep the smooth-body estimates: Persson's area is that of an isotropic surface)."""
    g = scene.grid
    return scene.body if g.topology.statistics and isinstance(scene.body, PeriodicSurface) else None


@functools.lru_cache(maxsize=2)
def surface_statistics(surface: PeriodicSurface) -> tuple[float, float, np.ndarray]:
    """(lambda_s, h'_rms, the heights Z at the samples sorted): :func:`cutoff_wavelength` and the heights
    of a surface, kept for the last two surfaces asked about (a scene's checks ask several times) until
    :func:`release_statistics`."""
    z = np.sort((surface.heights - surface.lowest).ravel())
    z.setflags(write=False)
    return (*cutoff_wavelength(surface), z)


def release_statistics() -> None:
    """Let :func:`surface_statistics`'s kept heights go (8 bytes per sample): a run calls it once its
    checks are made, before its own arrays come."""
    surface_statistics.cache_clear()


def cutoff_wavelength(surface: PeriodicSurface) -> tuple[float, float]:
    """(lambda_s in m, h'_rms): the wavelength 2 pi / q_s with SLOPE_SHARE of the mean square slope at
    |q| <= q_s, and the rms slope of the samples' trigonometric interpolant; (inf, 0) for a flat surface."""
    q, power = surface.spectrum()
    slope = q**2 * power
    total = float(slope.sum())
    if not total > 0.0:
        return math.inf, 0.0
    order = np.argsort(q)
    share = np.cumsum(slope[order]) / total
    q_s = float(q[order][np.searchsorted(share, SLOPE_SHARE)])
    return 2.0 * math.pi / q_s, math.sqrt(total)


def area_fraction(pressure: float, compliance: float, rms_slope: float) -> float:
    """Persson's A/A0 = erf(sqrt(2) p0 J / h'_rms) of an elastic solid of compliance J = 1/M (1/Pa) at
    nominal pressure p0 (Pa); 1 for a flat surface."""
    return float(erf(math.sqrt(2.0) * pressure * compliance / rms_slope)) if rms_slope > 0 else 1.0


def rough_contact(scene) -> RoughContact | None:
    """The :class:`RoughContact` of a periodic grid's rough surface (None for any other scene) at the
    scene's largest load or penetration."""
    surface = periodic_surface(scene)
    if surface is None:
        return None
    g = scene.grid
    cutoff, rms_slope, z = surface_statistics(surface)
    side = max(g.dx, g.dy)
    mean = float(z.mean())
    if scene.penetration is not None:
        delta = float(scene.penetration.largest())
        share = float(np.searchsorted(z, delta)) / z.size / INTERFERENCE_SHARE
        areas, deltas, exact = (share, share), (delta, delta), True
    else:
        pressure = float(scene.load.largest()) / ((g.x1 - g.x0) * (g.y1 - g.y0))
        areas = tuple(area_fraction(pressure, J, rms_slope) for J in (scene.material.J0, scene.material.Jinf))
        deltas = tuple(min(float(np.quantile(z, min(1.0, INTERFERENCE_SHARE * a))), mean) for a in areas)
        exact = False
    return RoughContact(cutoff, cutoff / side, rms_slope, surface.contact_scale, areas, deltas,
                        float(z[-1] - z[0]), exact)
