"""The influence kernels: the surface displacement per unit pressure, for unit surface compliance, as the
coefficients the influence operator (petroll/solver/influence.py) applies.

- love.py: the half-space. `Rectangles`, Love's uniformly loaded rectangles (3-D; any rows from the
  closed form); `Strips`, the plane-strain strips of line contact (relative to the grid's datum).
- layer.py: a layer on a rigid base. `LayerRectangles`, `LayerStrips`: Love's or the strips'
  coefficients plus the layer's correction (its surface response L(|k| h) transformed to real space).

Real-space kernels are applied as linear convolutions (zero-padded FFTs). The kernels import nothing of
the operator that applies them; :func:`grid_kernel` picks a grid's.
"""

from __future__ import annotations

from petroll.model.grid import Grid
from petroll.model.materials import Layer
from petroll.solver.kernels.base import Kernel
from petroll.solver.kernels.layer import LayerRectangles, LayerStrips
from petroll.solver.kernels.love import Rectangles, Strips


def grid_kernel(grid: Grid, layer: Layer | None = None) -> Kernel:
    """The kernel of ``grid`` on a half-space (``layer`` None) or on ``layer``: rectangles, or strips with
    the grid's datum on a line-contact grid."""
    if grid.line:
        return Strips(grid.dx, grid.dy, grid.datum) if layer is None else LayerStrips(grid.dx, grid.dy,
                                                                                      grid.datum, layer)
    return Rectangles(grid.dx, grid.dy) if layer is None else LayerRectangles(grid.dx, grid.dy, layer)
