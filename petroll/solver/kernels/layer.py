"""Influence coefficients of an elastic layer of thickness h on a rigid base (bonded or frictionless).

Surface response. A normal pressure p(k) e^{i k.x} on the free surface of a layer (Young's modulus E,
Poisson's ratio nu, thickness h) whose bottom is held by a rigid base displaces the surface by

    w(k) = J (2/|k|) L(|k| h) p(k),      J = (1 - nu^2)/E (the surface compliance), w into the layer,

with the dimensionless layer function L(u) (u = |k| h; L -> 1 as u -> inf: the half-space):

    bonded base:        L(u) = (2 kappa sinh 2u - 4u) / (2 kappa cosh 2u + 1 + kappa^2 + 4u^2),
                        kappa = 3 - 4 nu
    frictionless base:  L(u) = (cosh 2u - 1) / (sinh 2u + 2u)

(Vorovich, Aleksandrov and Babeshko, *Non-classical mixed problems of the theory of elasticity*, 1974;
the kernels of the layer indentation problems in Argatov and Mishuris, *Indentation Testing of Biological
Materials*, 2018, ch. 1). Both hold for nu = 0.5. They were derived again for petroll (plane-strain
Fourier mode of the Navier equations, frictionless top) and are checked to round-off against an
independent transfer-matrix solution of those equations in tests/test_layer.py. Thin layers (u -> 0):
bonded, L ~ u (1 - 2 nu)/(2 (1 - nu)^2) (the uniaxial-strain foundation w = h (1 + nu)(1 - 2 nu) p /
(E (1 - nu))), or for nu = 0.5, L ~ (2/3) u^3 (w = -(h^3/E) lap p); frictionless, L ~ u/2 (w = J h p).
With a constant nu the response is J(t) times the same kernel, so a viscoelastic layer only changes the
influence coefficients.

Coefficients. The coefficient of a uniformly loaded cell is Love's exact half-space coefficient plus the
layer's correction, whose spectrum (2/|k|)(L - 1) decays like e^{-2|k|h} but is singular (-2/|k|) at k = 0
(the correction's far field -1/(pi r) cancels the half-space's). That singularity is taken out in closed
form: with c = h,

    (2/|k|)(L - 1) = -(2/|k|) g(k) + (2/|k|)(L - 1 + g),    g(k) = (4/3) e^{-c|k|} - (1/3) e^{-2c|k|},

the first term is the field of point loads at depths c and 2c, -(1/pi) [(4/3)/sqrt(r^2 + c^2) -
(1/3)/sqrt(r^2 + 4c^2)], integrated over the cell exactly (:func:`rectangle_potential`); the second, the
*remainder*, is smooth at k = 0 (g was chosen so that its expansion has no |k| term: its far field falls
as -3 c^4/(2 pi r^5)) and decays exponentially, so its radial profile is computed once per (nu, base) by a
Hankel transform (Gauss-Legendre panels) on a table in r/h, and integrated over each cell by a q x q
Gauss rule (q grows as h/dx falls). Line contact (plane strain) takes the same split with the strip
kernel: the point loads' field is (2/pi)[(2/3) ln(x^2 + c^2) - (1/6) ln(x^2 + 4c^2)] - the strip's datum
constant, integrated over the strip exactly, and the remainder is a cosine transform (far field
-2 c^4/(pi x^4)).

Accuracy (measured, tests/test_layer.py and docs/layer.md): the sum of a cell's coefficients over a
100 h grid equals the layer's uniform-load compliance 2 h L'(0) to 3e-8 relative; the coefficients agree
with a twice finer table to 2e-12 of the diagonal, with a q + 8 rule to 5e-10 for h >= dx and 2e-8 for
h = dx/4, and with a 128-point rule to 2e-8 for h = dx/10 (6e-7 for nu = 0.5 bonded); a scene with h
below dx/16 is warned about (petroll.model.limits).
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy.special import j0

from petroll.model.materials import Layer
from petroll.solver.kernels.base import Kernel
from petroll.solver.kernels.love import love_coefficients, strip_coefficients

TABLE_END, TABLE_STEP = 40.0, 0.005
"""The remainder's table covers r/h in [0, TABLE_END] (beyond: its far field) in steps of TABLE_STEP."""


def response(u, nu: float, base: str):
    """L(u), u = |k| h >= 0: the layer's surface compliance over the half-space's (module docstring);
    written with e = exp(-2u) so that it neither overflows nor loses its small-u behaviour."""
    u = np.asarray(u, dtype=float)
    e = np.exp(-2 * u)
    one_minus_e2 = -np.expm1(-4 * u)
    if base == "bonded":
        kappa = 3 - 4 * nu
        return (kappa * one_minus_e2 - 4 * u * e) / (kappa * (1 + e * e) + (1 + kappa**2 + 4 * u * u) * e)
    if base == "frictionless":
        return np.expm1(-2 * u) ** 2 / (one_minus_e2 + 4 * u * e)
    raise ValueError(f"base {base!r}: must be 'bonded' or 'frictionless'")


def thin_compliance(layer: Layer) -> float:
    """lim (2/k) L(k h) as k -> 0 (m): the displacement per unit uniform pressure per unit compliance J,
    i.e. w = J thin_compliance p for a load much wider than h (0 for a bonded incompressible layer)."""
    nu = layer.nu
    slope = 0.5 if layer.base == "frictionless" else (1 - 2 * nu) / (2 * (1 - nu) ** 2)
    return 2 * layer.thickness * slope


def _subtracted(u: np.ndarray) -> np.ndarray:
    """g(u) with c = h: (4/3) e^{-u} - (1/3) e^{-2u}."""
    return (4 * np.exp(-u) - np.exp(-2 * u)) / 3


def _nodes() -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights on u in [0, 36] (panels of 0.25, 16 points each): the remainder's
    spectrum is below 1e-15 beyond, and 16 points per panel resolve cos(u x) and J0(u x) up to x = 40."""
    x, w = np.polynomial.legendre.leggauss(16)
    starts = np.arange(0.0, 36.0, 0.25)
    nodes = (starts[:, None] + 0.125 * (x[None, :] + 1)).ravel()
    return nodes, np.tile(0.125 * w, len(starts))


@functools.lru_cache(maxsize=8)
def _remainder(nu: float, base: str, line: bool) -> "CubicSpline":
    """The remainder's profile against s = r/h (3-D) or x/h (line) on [0, TABLE_END], in units of 1/h
    (3-D: (1/pi) int (L - 1 + g) J0(u s) du) or dimensionless (line: (2/pi) int (L - 1 + g)/u cos(u s) du)."""
    u, w = _nodes()
    spectrum = response(u, nu, base) - 1 + _subtracted(u)
    if line:
        weights, transform = w * spectrum / u * (2 / np.pi), np.cos
    else:
        weights, transform = w * spectrum / np.pi, j0
    s = np.arange(0.0, TABLE_END + TABLE_STEP / 2, TABLE_STEP)
    values = np.concatenate([transform(np.outer(part, u)) @ weights for part in np.array_split(s, 16)])
    from scipy.interpolate import CubicSpline  # here: scipy.interpolate takes 40 ms to import

    return CubicSpline(s, values, bc_type=((1, 0.0), "not-a-knot"))


def _remainder_at(s: np.ndarray, nu: float, base: str, line: bool) -> np.ndarray:
    """The remainder's profile at s = r/h >= 0 (see :func:`_remainder`); beyond the table its far field,
    -3/(2 pi s^5) (3-D, in units of 1/h) or -2/(pi s^4) (line)."""
    inside = s <= TABLE_END
    out = np.empty_like(s)
    out[inside] = _remainder(nu, base, line)(s[inside])
    far = s[~inside]
    out[~inside] = -2 / (np.pi * far**4) if line else -3 / (2 * np.pi * far**5)
    return out


def quadrature_points(cell: float, thickness: float) -> int:
    """Points per axis of the Gauss rule over a cell of side ``cell`` for the remainder (scale h)."""
    return int(min(64, max(4, math.ceil(4 * cell / thickness) + 3)))


def rectangle_potential(x, y, a: float, b: float, z: float):
    """int over |X| < a, |Y| < b of 1/sqrt((x - X)^2 + (y - Y)^2 + z^2) dX dY (m): the field at depth z > 0
    of a uniformly loaded rectangle, in closed form (its z -> 0 limit is pi times Love's coefficient)."""

    def f(u, v):
        u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
        r = np.sqrt(u * u + v * v + z * z)
        return (u * np.arcsinh(v / np.hypot(u, z)) + v * np.arcsinh(u / np.hypot(v, z))
                - z * np.arctan(u * v / (z * r)))

    return f(x + a, y + b) - f(x + a, y - b) - f(x - a, y + b) + f(x - a, y - b)


def layer_coefficients(nx: int, ny: int, dx: float, dy: float, layer: Layer,
                       rows: np.ndarray | None = None) -> np.ndarray:
    """The layer's coefficients A(ix, iy) for offsets 0 <= ix < nx, 0 <= iy < ny (or the row offsets
    ``rows``): the displacement at a cell centre offset by (ix dx, iy dy) from a dx x dy cell under unit
    pressure, for unit surface compliance (w = J A p, m per Pa of pressure per 1/Pa of J). Love's
    coefficients plus the layer's correction (module docstring)."""
    ix = np.arange(nx) if rows is None else np.asarray(rows)
    x, y = ix[:, None] * dx, np.arange(ny)[None, :] * dy
    h, c = layer.thickness, layer.thickness
    out = love_coefficients(nx, ny, dx, dy, rows=ix)
    out -= (4 * rectangle_potential(x, y, dx / 2, dy / 2, c)
            - rectangle_potential(x, y, dx / 2, dy / 2, 2 * c)) / (3 * np.pi)
    q = quadrature_points(max(dx, dy), h)
    t, wt = np.polynomial.legendre.leggauss(q)
    for tx, wx in zip(t * dx / 2, wt * dx / 2):
        for ty, wy in zip(t * dy / 2, wt * dy / 2):
            s = np.hypot(x - tx, y - ty) / h
            out += wx * wy * _remainder_at(s, layer.nu, layer.base, False) / h
    return out


def layer_strip_coefficients(nx: int, dx: float, datum: float, layer: Layer) -> np.ndarray:
    """The plane-strain coefficients of strips of width dx on the layer, offsets 0 <= k < nx (shape (nx,),
    per unit compliance): the strip kernel of :func:`petroll.solver.kernels.love.strip_coefficients` with
    ``datum`` plus the layer's correction; the sum does not depend on the datum (a layer on a rigid base
    has a displacement that vanishes far from the load)."""
    h, c, a = layer.thickness, layer.thickness, dx / 2
    x = np.arange(nx) * dx

    def log_strip(z: float) -> np.ndarray:  # int over the strip of (1/2) ln(s^2 + z^2) ds
        def g(s):
            return 0.5 * s * np.log(s * s + z * z) - s + z * np.arctan(s / z)

        return g(x + a) - g(x - a)

    out = strip_coefficients(nx, dx, datum)
    out += (2 / np.pi) * ((4 * log_strip(c) - log_strip(2 * c)) / 3 - dx * math.log(datum))
    q = quadrature_points(dx, h)
    t, wt = np.polynomial.legendre.leggauss(q)
    for tx, wx in zip(t * a, wt * a):
        out += wx * _remainder_at(np.abs(x - tx) / h, layer.nu, layer.base, True)
    return out


TORUS = 1.5
"""A layer's preconditioner: the circulant of its kernel on a torus 1.5 times the QP's window along each
axis (:meth:`petroll.solver.influence.InfluenceOperator.pc_torus`), not on the window itself; a half-space
keeps the window's. The factor is a measured choice, not a derived one: the fewest operator applications
per step of `petroll bench layer` among the factors tried (docs/layer.md#performance)."""


class LayerRectangles(Kernel):
    """dx x dy cells on ``layer`` (:func:`layer_coefficients`): some coefficients negative (the surface
    bulges around a load), the preconditioner's circulant on a torus TORUS times the window."""

    positive = False
    torus = TORUS

    def __init__(self, dx: float, dy: float, layer: Layer):
        super().__init__(dx, dy)
        self.layer = layer

    def table(self, nx: int, ny: int, rows: np.ndarray | None = None) -> np.ndarray:
        return layer_coefficients(nx, ny, self.dx, self.dy, self.layer, rows)


class LayerStrips(Kernel):
    """Plane-strain strips of width dx on ``layer`` with the datum L (m) (:func:`layer_strip_coefficients`;
    a table of shape (nx, 1)), negative coefficients and torus as :class:`LayerRectangles`."""

    positive = False
    torus = TORUS

    def __init__(self, dx: float, dy: float, datum: float, layer: Layer):
        super().__init__(dx, dy)
        self.datum, self.layer = datum, layer

    def table(self, nx: int, ny: int, rows: np.ndarray | None = None) -> np.ndarray:
        out = layer_strip_coefficients(nx, self.dx, self.datum, self.layer)[:, None]
        return out if rows is None else out[rows]
