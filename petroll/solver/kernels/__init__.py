"""The influence kernels: the surface displacement per unit pressure, for unit surface compliance, as the
coefficients the influence operator (petroll/solver/influence.py) applies.

- love.py: the half-space. `Rectangles`, Love's uniformly loaded rectangles (3-D; any rows from the
  closed form); `Strips`, the plane-strain strips of line contact (relative to the grid's datum).
- layer.py: a layer on a rigid base. `LayerRectangles`, `LayerStrips`: Love's or the strips'
  coefficients plus the layer's correction (its surface response L(|k| h) transformed to real space).
- cerruti.py: the half-space's tangential kernels (friction): Cerruti's uniformly loaded rectangles (u_x,
  u_y from q_x, q_y; the normal-tangential coupling, proportional to 1 - 2 nu) and line contact's strips,
  per unit shear compliance 1/(2 G); `tangential_kernel` picks a grid's.
- periodic.py: periodic grids. `HalfSpace`, `LayerSpectral`: the symbols 2/|k| and (2/|k|) L(|k| h) at the
  DFT wavenumbers of a grid periodic along both axes (a line-contact grid: along X); `HalfSpaceAlong`:
  Fourier along the one periodic axis, real space (cell-uniform) along the other.

Real-space kernels are applied as linear convolutions (zero-padded FFTs), Fourier coefficients as
periodic ones (unpadded FFTs). The kernels import nothing of the operator that applies them;
:func:`grid_kernel` picks a grid's.
"""

from __future__ import annotations

from petroll.model.grid import Grid
from petroll.model.materials import Layer
from petroll.solver.kernels.base import Kernel
from petroll.solver.kernels.layer import LayerRectangles, LayerStrips
from petroll.solver.kernels.love import Rectangles, Strips
from petroll.solver.kernels.periodic import HalfSpace, HalfSpaceAlong, LayerSpectral


def grid_kernel(grid: Grid, layer: Layer | None = None) -> Kernel:
    """The kernel of ``grid`` on a half-space (``layer`` None) or on ``layer``: rectangles, or strips with
    the grid's datum on a line-contact grid; on a periodic grid, the periodic kernels (a layer: periodic
    along every axis only, ValueError otherwise)."""
    if grid.line and grid.periodic[0] or all(grid.periodic):
        if layer is None:
            return HalfSpace(grid.dx, grid.dy, grid.nx, grid.ny)
        return LayerSpectral(grid.dx, grid.dy, grid.nx, grid.ny, layer)
    if any(grid.periodic):
        if layer is not None:
            raise ValueError("a layer on a grid periodic along one axis only")
        axis = 0 if grid.periodic[0] else 1
        datum = grid.y1 - grid.y0 if axis == 0 else grid.x1 - grid.x0
        return HalfSpaceAlong(grid.dx, grid.dy, grid.nx, grid.ny, axis, datum)
    if grid.line:
        return Strips(grid.dx, grid.dy, grid.datum) if layer is None else LayerStrips(grid.dx, grid.dy,
                                                                                      grid.datum, layer)
    return Rectangles(grid.dx, grid.dy) if layer is None else LayerRectangles(grid.dx, grid.dy, layer)
