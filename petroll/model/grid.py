"""The material-frame grid of uniformly loaded rectangles (geometry only; its split over ranks is
:mod:`petroll.solver.partition`).

Fields on the grid are numpy arrays of shape (nx, ny), axis 0 along X; a flattened field has index
ix * ny + iy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Grid:
    """nx x ny cells covering [x0, x1] x [y0, y1] in the material frame (lengths in scene units, e.g. m)."""

    nx: int
    ny: int
    x0: float
    x1: float
    y0: float
    y1: float

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
    def x(self) -> np.ndarray:
        """Cell-centre X coordinates, shape (nx,)."""
        return self.x0 + (np.arange(self.nx) + 0.5) * self.dx

    @property
    def y(self) -> np.ndarray:
        """Cell-centre Y coordinates, shape (ny,)."""
        return self.y0 + (np.arange(self.ny) + 0.5) * self.dy
