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
from petroll.model.topology import Line, Periodic, PeriodicAlong
from petroll.solver.kernels.base import Kernel
from petroll.solver.kernels.layer import LayerRectangles, LayerStrips
from petroll.solver.kernels.love import Rectangles, Strips
from petroll.solver.kernels.periodic import HalfSpace, HalfSpaceAlong, LayerSpectral


def grid_kernel(grid: Grid, layer: Layer | None = None) -> Kernel:
    """The kernel of ``grid`` on a half-space (``layer`` None) or on ``layer``, by its topology
    (petroll.model.topology): rectangles, or strips with the grid's datum in line contact; on a grid that
    repeats, the periodic kernels (a layer: repeating along every axis only, ValueError otherwise)."""
    g, top = grid, grid.topology
    if isinstance(top, PeriodicAlong):
        if layer is not None:
            raise ValueError("a layer on a grid periodic along one axis only")
        datum = g.y1 - g.y0 if top.axis == 0 else g.x1 - g.x0
        return HalfSpaceAlong(g.dx, g.dy, g.nx, g.ny, top.axis, datum)
    if isinstance(top, Periodic):
        if layer is None:
            return HalfSpace(g.dx, g.dy, g.nx, g.ny)
        return LayerSpectral(g.dx, g.dy, g.nx, g.ny, layer)
    if isinstance(top, Line):
        return Strips(g.dx, g.dy, g.datum) if layer is None else LayerStrips(g.dx, g.dy, g.datum, layer)
    return Rectangles(g.dx, g.dy) if layer is None else LayerRectangles(g.dx, g.dy, layer)
