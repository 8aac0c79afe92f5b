"""The half-space's kernels: Love's uniformly loaded rectangles (3-D) and the plane-strain strips (line
contact), real-space coefficients for unit surface compliance (formulation §2)."""

from __future__ import annotations

import numpy as np

from petroll.solver.kernels.base import Kernel


def love_coefficients(nx: int, ny: int, dx: float, dy: float, rows: np.ndarray | None = None) -> np.ndarray:
    """Love's coefficients A(ix, iy) for cell offsets 0 <= ix < nx, 0 <= iy < ny (units of dx); with
    ``rows``, only the offsets ix in ``rows`` (shape (len(rows), ny)).

    The displacement at a cell centre offset by (ix dx, iy dy) from a dx x dy cell carrying unit pressure,
    for unit surface compliance. A is even in both offsets, so these values give every pair of cells.
    Computed as :func:`rectangle_displacement` is, from its four corner terms, each evaluated once: a
    cell's edge is its neighbour's (the table's edges along Y, and along X without ``rows``).
    """
    v = (np.arange(ny + 1) - 0.5) * dy  # the edges along Y: y - b of offset iy is y + b of offset iy - 1
    if rows is None:
        corners = _f((np.arange(nx + 1) - 0.5)[:, None] * dx, v[None, :])
        lo, hi = corners[:-1], corners[1:]  # at x - a and x + a
    else:
        ix = np.asarray(rows)[:, None]
        lo, hi = (_f((ix + side) * dx, v[None, :]) for side in (-0.5, 0.5))
    return (hi[:, 1:] - hi[:, :-1] - lo[:, 1:] + lo[:, :-1]) / np.pi


def rectangle_displacement(x, y, a: float, b: float):
    """Displacement at (x, y) (m) from unit pressure on the rectangle |X| < a, |Y| < b, for unit surface
    compliance (Love 1929): units of length."""
    return (_f(x + a, y + b) - _f(x + a, y - b) - _f(x - a, y + b) + _f(x - a, y - b)) / np.pi


def _f(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """u asinh(v/|u|) + v asinh(u/|v|), with the limit 0 of each term where its divisor is 0."""
    u, v = np.broadcast_arrays(u, v)
    au, av = np.abs(u), np.abs(v)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(au > 0, u * np.arcsinh(v / np.where(au > 0, au, 1.0)), 0.0)
        t2 = np.where(av > 0, v * np.arcsinh(u / np.where(av > 0, av, 1.0)), 0.0)
    return t1 + t2


def strip_coefficients(nx: int, dx: float, datum: float) -> np.ndarray:
    """The plane-strain strip kernel A(k) for offsets 0 <= k < nx (shape (nx,), m per unit compliance).

    The surface displacement (positive into the half-space) at a strip centre offset by k dx from a strip
    of width dx carrying unit pressure, for unit surface compliance (w = J A p, J = (1 - nu^2)/E):
    the exact integral of the line-load kernel -(2/pi) ln(|x - s|/L) over the strip (Johnson, Contact
    Mechanics, 1985, Eq. 2.19b), with G(u) = u ln(|u|/L) - u:

        A(k) = -(2/pi) [G(k dx + dx/2) - G(k dx - dx/2)]

    The constant of the logarithmic kernel is fixed by the ``datum`` L (m): displacements are measured
    relative to the surface points at distance L from each load. With L at least the grid's length
    (petroll uses L = x1 - x0, :attr:`petroll.model.grid.Grid.datum`) every coefficient is positive and the
    matrix is positive definite (its smallest eigenvalue, measured, >= 0.13 A(0) up to nx = 1000; the
    continuous operator is positive definite while L exceeds a quarter of the loaded length, the
    logarithmic capacity of a segment). Under load control the pressure does not depend on L: changing it
    adds (2 J/pi) ln(L'/L) times the total load to every cell's displacement, which the penetration
    absorbs. Even in k: these values give every pair of strips.
    """
    a = dx / 2
    x = np.arange(nx) * dx

    def g(u: np.ndarray) -> np.ndarray:
        au = np.abs(u)
        return np.where(au > 0, u * np.log(np.where(au > 0, au, 1.0) / datum), 0.0) - u

    return -(2 / np.pi) * (g(x + a) - g(x - a))


class Rectangles(Kernel):
    """Love's rectangles on dx x dy cells (:func:`love_coefficients`); any rows from the closed form, and
    the row-sum bound in closed form (:meth:`row_sum_bound`)."""

    direct = True

    def table(self, nx: int, ny: int, rows: np.ndarray | None = None) -> np.ndarray:
        return love_coefficients(nx, ny, self.dx, self.dy, rows)

    def row_sum_bound(self, nx: int, ny: int) -> float:
        """The sum over all offsets |ix| < nx, |iy| < ny: the displacement at the centre of a (2 nx - 1) dx
        x (2 ny - 1) dy rectangle under unit pressure (Love's formula, no table)."""
        return float(rectangle_displacement(0.0, 0.0, (2 * nx - 1) * self.dx / 2, (2 * ny - 1) * self.dy / 2))


class Strips(Kernel):
    """The plane-strain strips of width dx with the datum L (m) (:func:`strip_coefficients`): a table of
    shape (nx, 1)."""

    def __init__(self, dx: float, dy: float, datum: float):
        super().__init__(dx, dy)
        self.datum = datum

    def table(self, nx: int, ny: int, rows: np.ndarray | None = None) -> np.ndarray:
        out = strip_coefficients(nx, self.dx, self.datum)[:, None]
        return out if rows is None else out[rows]
