"""What every kernel of the family gives the influence operator (petroll/solver/influence.py)."""

from __future__ import annotations

import numpy as np


class Kernel:
    """A non-periodic kernel: real-space coefficients A(ix, iy) on dx x dy cells, even in both offsets,
    m per Pa of pressure per 1/Pa of surface compliance (w = J A p), applied as a linear convolution
    (zero-padded FFTs).

    ``positive``: every coefficient > 0 (a field p >= 0 pushes every cell down: the contact QP's exact
    window, the wake's lower bound). ``torus``: the preconditioner's circulant is built on a torus this
    many times the QP's window along each axis longer than one cell (1: the window itself). ``direct``:
    :meth:`table` computes any rows from a closed form, cheaply enough that large blocks need no kept
    table (each rank computes the rows its part of the kernel needs).
    """

    periodic = (False, False)
    positive = True
    torus = 1.0
    direct = False

    def __init__(self, dx: float, dy: float):
        self.dx, self.dy = dx, dy

    def table(self, nx: int, ny: int, rows: np.ndarray | None = None) -> np.ndarray:
        """A(ix, iy) for offsets 0 <= ix < nx, 0 <= iy < ny (or the row offsets ``rows``): shape
        (len(rows), ny)."""
        raise NotImplementedError

    def row_sum_bound(self, nx: int, ny: int) -> float | None:
        """A closed form of the sum of |A| over all offsets |ix| < nx, |iy| < ny, or None (the operator
        sums its table)."""
        return None
