"""Periodic kernels: Fourier coefficients along the periodic axes of a grid.

A pressure harmonic p e^{i k.x} on a half-space displaces its surface by w = J (2/|k|) p e^{i k.x} (unit
surface compliance: the symbol 2/|k|), on a layer of thickness h by J (2/|k|) L(|k| h) p e^{i k.x}
(petroll.solver.kernels.layer.response). On a grid periodic along both axes (nx dx by ny dy) the operator
multiplies the grid's DFT by the symbol at the DFT's wavenumbers k = 2 pi (mx / (nx dx), my / (ny dy)),
|mx| <= nx/2, |my| <= ny/2, without padding: the kernel of Tamaas's periodic solver (Frerot, Anciaux &
Molinari, 2020), exact for a pressure that is a trigonometric polynomial on the lattice (pressure at
points, band-limited), not Love's cell-uniform one. The same symbol with ky = 0 is the plane-strain
kernel of a periodic line-contact grid.

The half-space symbol has no k = 0 value: a uniform pressure displaces an infinite half-space without
bound. It is set to 0: displacements are measured from the mean plane of the deformed surface (their
mean over the cell is 0), so under load control the mean pressure (load / cell area) is what it is, and
a penetration is that of the body's lowest point below that plane (the mean gap is then mean(Z) - delta;
docs/design.md). A layer's symbol tends to 2 h L'(0) (finite) as k -> 0: it keeps its k = 0 value.

A grid periodic along X only (``fourier`` = (True, False)) is Fourier along X and real space along Y:
pressure harmonic e^{i kx x} along X, uniform over each cell's width dy; its displacement at the centre
of a cell offset by oy dy is the integral over the cell of the line kernel's transform,
(2/pi) K0(|kx| |y|), in closed form (scipy.special.iti0k0, the integral of K0 from 0), and for kx = 0 the
plane-strain strips with the datum L = the grid's length along Y (petroll.solver.kernels.love). Y periodic
only is the same with the axes swapped. Layers: fully periodic grids only.
"""

from __future__ import annotations

import numpy as np
from scipy.special import iti0k0

from petroll.model.materials import Layer
from petroll.solver.kernels.base import Kernel
from petroll.solver.kernels.layer import response, thin_compliance
from petroll.solver.kernels.love import strip_coefficients


class Spectral(Kernel):
    """A kernel on an nx x ny grid whose coefficients are Fourier along the axes where ``fourier`` is
    True (at signed DFT frequency indices m, wavenumber 2 pi m / (n d)) and real space (at signed cell
    offsets) along the others; :meth:`values` gives them. No real-space table. ``even``: the kernel is
    even along both axes (its spectrum is real)."""

    positive = False
    even = True

    def __init__(self, dx: float, dy: float, nx: int, ny: int, fourier: tuple[bool, bool]):
        super().__init__(dx, dy)
        self.nx, self.ny, self.fourier = nx, ny, fourier

    def wavenumbers(self, mx, my) -> tuple[np.ndarray, np.ndarray]:
        """(kx, ky) (rad/m) of the DFT frequency indices (mx, my) of the grid."""
        return (2 * np.pi * np.asarray(mx) / (self.nx * self.dx),
                2 * np.pi * np.asarray(my) / (self.ny * self.dy))

    def values(self, ax, ay) -> np.ndarray:
        """The coefficients at (ax, ay): frequency indices along Fourier axes, cell offsets along the
        others (broadcast arrays); m per Pa per unit compliance."""
        raise NotImplementedError


class HalfSpace(Spectral):
    """The half-space on a grid periodic along both axes (a line-contact grid: along X): 2/|k|, 0 at
    k = 0 (displacements from the deformed surface's mean plane)."""

    def __init__(self, dx: float, dy: float, nx: int, ny: int):
        super().__init__(dx, dy, nx, ny, (True, True))

    def values(self, ax, ay) -> np.ndarray:
        k = np.hypot(*self.wavenumbers(ax, ay))
        return np.divide(2.0, k, out=np.zeros(k.shape), where=k > 0)


class LayerSpectral(Spectral):
    """A layer on a rigid base on a grid periodic along both axes: (2/|k|) L(|k| h), and its finite limit
    2 h L'(0) at k = 0 (petroll.solver.kernels.layer.thin_compliance)."""

    def __init__(self, dx: float, dy: float, nx: int, ny: int, layer: Layer):
        super().__init__(dx, dy, nx, ny, (True, True))
        self.layer = layer

    def values(self, ax, ay) -> np.ndarray:
        k = np.hypot(*self.wavenumbers(ax, ay))
        inside = k > 0
        out = np.full(k.shape, thin_compliance(self.layer))
        out[inside] = 2.0 / k[inside] * response(k[inside] * self.layer.thickness, self.layer.nu,
                                                 self.layer.base)
        return out


class HalfSpaceAlong(Spectral):
    """The half-space on a 3-D grid periodic along one axis (``axis`` 0: X, 1: Y) and not the other,
    whose length ``datum`` (m) fixes the constant of the kx = 0 (strip) mode (module docstring)."""

    def __init__(self, dx: float, dy: float, nx: int, ny: int, axis: int, datum: float):
        super().__init__(dx, dy, nx, ny, (axis == 0, axis == 1))
        self.axis, self.datum = axis, datum

    def values(self, ax, ay) -> np.ndarray:
        m, offset = (ax, ay) if self.axis == 0 else (ay, ax)
        m, offset = np.broadcast_arrays(np.asarray(m), np.abs(np.asarray(offset)))
        k = np.abs(self.wavenumbers(m, 0)[0] if self.axis == 0 else self.wavenumbers(0, m)[1])
        width = self.dy if self.axis == 0 else self.dx  # the cell's side along the real-space axis
        n_across = self.ny if self.axis == 0 else self.nx
        out = np.empty(m.shape)
        strips = k == 0
        out[strips] = strip_coefficients(n_across, width, self.datum)[offset[strips]]
        far, near = k[~strips] * (offset[~strips] * width + width / 2), k[~strips] * (offset[~strips] * width
                                                                                       - width / 2)
        # (2/pi) int K0(|k| |y|) dy over the cell = (2/(pi k)) [I(k y1) - I(k y0)], I(z) = int_0^z K0, odd
        ends = iti0k0(far)[1] - np.sign(near) * iti0k0(np.abs(near))[1]
        out[~strips] = 2 / (np.pi * k[~strips]) * ends
        return out
