"""The material-frame grid of uniformly loaded rectangles (geometry only; its split over ranks is
:mod:`petroll.solver.partition`).

Fields on the grid are numpy arrays of shape (nx, ny), axis 0 along X; a flattened field has index
ix * ny + iy.

A *periodic* grid repeats along X, Y or both (``periodic``): the cells tile a cell of the periodic
surface, and a body's offsets from its reference point wrap around (:meth:`Grid.offsets`). What differs
between a grid that repeats and one that does not (and line contact) is the grid's ``topology``
(petroll.model.topology); nothing else reads ``periodic``.

A *line-contact* grid (plane strain; a scene whose [grid] has nx and x only) is the same object with
``line = True``, ny = 1 and Y from -1/2 to 1/2: its cells are strips of unit length along Y, so that
``cell_area`` = dx and every force summed over the cells is a force per unit length (N/m), every area a
contact width (m). Its influence operator is the plane-strain strip kernel (petroll.solver.kernels.love).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from petroll.model.topology import Topology, topology


@dataclass(frozen=True)
class Grid:
    """nx x ny cells covering [x0, x1] x [y0, y1] in the material frame (lengths in scene units, e.g. m)."""

    nx: int
    ny: int
    x0: float
    x1: float
    y0: float
    y1: float
    line: bool = False  # plane strain: ny = 1 strip of unit length (use :func:`line_grid`)
    periodic: tuple[bool, bool] = (False, False)  # the grid repeats along X, Y (a line grid: along X only)

    @property
    def dx(self) -> float:
        return (self.x1 - self.x0) / self.nx

    @property
    def dy(self) -> float:
        return (self.y1 - self.y0) / self.ny

    @property
    def cell_area(self) -> float:
        return self.dx * self.dy

    @property
    def cell(self) -> float:
        """The smallest cell side that motion can cross (dx for a line-contact grid), m."""
        return self.dx if self.line else min(self.dx, self.dy)

    @property
    def datum(self) -> float | None:
        """Line contact: the datum distance L = x1 - x0 (m) of the plane-strain displacements, which are
        measured relative to surface points at distance L from each load (petroll.solver.kernels.love);
        None for a 3-D grid."""
        return self.x1 - self.x0 if self.line else None

    @cached_property
    def topology(self) -> Topology:
        """Windowed half-space, periodic along both axes or one, or line contact (petroll.model.topology)."""
        return topology(self)

    def offsets(self, x, y, sx: float, sy: float) -> tuple[np.ndarray, np.ndarray]:
        """Offsets (x - sx, y - sy) (m) of points from a body's reference point at (sx, sy), taken along a
        repeating axis to the nearest image of the reference point (:meth:`Topology.offsets`)."""
        return self.topology.offsets(x, y, sx, sy)

    @property
    def x(self) -> np.ndarray:
        """Cell-centre X coordinates, shape (nx,)."""
        return self.x0 + (np.arange(self.nx) + 0.5) * self.dx

    @property
    def y(self) -> np.ndarray:
        """Cell-centre Y coordinates, shape (ny,)."""
        return self.y0 + (np.arange(self.ny) + 0.5) * self.dy


def line_grid(nx: int, x0: float, x1: float, periodic: bool = False) -> Grid:
    """A line-contact (plane-strain) grid of nx strips covering [x0, x1] (m), unit length along Y;
    ``periodic``: repeating along X."""
    return Grid(nx, 1, x0, x1, -0.5, 0.5, line=True, periodic=(periodic, False))
