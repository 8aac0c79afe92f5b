"""The half-space's tangential kernels: Cerruti's uniformly loaded rectangles (3-D) and the plane-strain
strips (line contact), real-space coefficients per unit shear compliance 1/(2 G).

Signs and units. A surface traction t = (t_x, t_y) (Pa) uniform on a dx x dy cell *applied to the
half-space* z >= 0 displaces the surface point at a target cell centre, offset (x, y) = (ox dx, oy dy)
from the cell's centre (target minus source), by

    u_x = (K_xx t_x + K_xy t_y) / (2 G),     u_y = (K_xy t_x + K_yy t_y) / (2 G)

with (Cerruti's point force integrated over the cell; Johnson, Contact Mechanics, 1985, Eq. 3.86)

    K_xx = (1/pi) int int [(1 - nu)/r + nu x^2/r^3] dA,   K_yy: x <-> y,   K_xy = (nu/pi) int int x y/r^3 dA.

K_xx and K_yy are even in both offsets, K_xy odd in each (even in the pair): the 2 x 2 block matrix is
symmetric, block-Toeplitz, positive definite, and at nu = 0 each diagonal block is Love's kernel
(petroll.solver.kernels.love). Closed forms: with f_a(u, v) = u asinh(v/|u|) (whose mixed derivative is
y^2/r^3), f_b(u, v) = v asinh(u/|v|) (x^2/r^3) and -r (x y/r^3), each integral is the mixed difference
F(x+a, y+b) - F(x+a, y-b) - F(x-a, y+b) + F(x-a, y-b) over the cell's corners (a = dx/2, b = dy/2):
K_xx = [f_b + (1 - nu) f_a]/pi, K_yy = [f_a + (1 - nu) f_b]/pi, K_xy = -nu r/pi.

The normal-tangential coupling (a pressure's tangential displacement, a traction's normal one) is
proportional to (1 - 2 nu): the surface point moves *into* the half-space (w, petroll's sign) by

    w = (1 - 2 nu)/2 * (K_zx t_x + K_zy t_y) / (2 G),   K_zx = (1/pi) int int x/r^2 dA  (odd in x, even in y)

(Betti's reciprocity with Boussinesq's radial displacement, which draws the surface towards a normal load),
and a pressure p pushing into the half-space moves it tangentially by u_x = -(1 - 2 nu)/2 K_zx^T p/(2 G)
(the transpose: offsets reversed). Corner function of K_zx: (v/2) ln(u^2 + v^2) + u atan(v/u). It vanishes
for quasi-identical bodies (two of the same material: the bodies' terms cancel; or nu = 1/2).

Plane strain (line contact along X, strips of width dx): a tangential line load's surface displacement
is -(1 - nu)/(pi G) ln|x| per unit load (Johnson Eq. 2.19), the normal line load's kernel times (1 - nu)
relative to 1/(2 G): K_xx = (1 - nu) A_strip with A_strip the strip kernel of
petroll.solver.kernels.love.strip_coefficients (same datum); the coupling K_zx = |x + a| - |x - a|
(the integral of sign(x - s) over the strip, the 3-D K_zx of an infinitely long cell).
"""

from __future__ import annotations

import numpy as np

from petroll.solver.kernels.love import strip_coefficients


def _asinh_terms(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(u asinh(v/|u|), v asinh(u/|v|)), each with its limit 0 where its divisor is 0."""
    au, av = np.abs(u), np.abs(v)
    with np.errstate(divide="ignore", invalid="ignore"):
        fa = np.where(au > 0, u * np.arcsinh(v / np.where(au > 0, au, 1.0)), 0.0)
        fb = np.where(av > 0, v * np.arcsinh(u / np.where(av > 0, av, 1.0)), 0.0)
    return fa, fb


def _coupling_corner(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(v/2) ln(u^2 + v^2) + u atan(v/u): mixed derivative x/r^2 (each term's limit 0 where it is 0/0)."""
    r2 = u * u + v * v
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(r2 > 0, 0.5 * v * np.log(np.where(r2 > 0, r2, 1.0)), 0.0)
        t2 = np.where(u != 0, u * np.arctan(v / np.where(u != 0, u, 1.0)), 0.0)
    return t1 + t2


def _cell_sums(ox: np.ndarray, oy: np.ndarray, dx: float, dy: float, corner) -> np.ndarray:
    """The mixed differences over each target cell's corners of ``corner(u, v)`` (a stack (m, ...) of
    corner functions), at the integer offsets ox (1-D) x oy (1-D): shape (m, len(ox), len(oy)). Each
    corner is evaluated once (neighbouring cells share corners)."""
    ox = np.asarray(ox, dtype=np.int64).ravel()
    oy = np.asarray(oy, dtype=np.int64).ravel()
    cu, cv = np.union1d(2 * ox - 1, 2 * ox + 1), np.union1d(2 * oy - 1, 2 * oy + 1)  # in half cells
    terms = np.asarray(corner(cu[:, None] * (dx / 2), cv[None, :] * (dy / 2)))
    sums = np.diff(np.diff(terms, axis=-2), axis=-1)
    return sums[..., np.searchsorted(cu, 2 * ox - 1), :][..., np.searchsorted(cv, 2 * oy - 1)]


def cerruti_table(ox: np.ndarray, oy: np.ndarray, dx: float, dy: float, nu: float) -> np.ndarray:
    """K_xx, K_yy, K_xy (m; shape (3, len(ox), len(oy))) at the signed integer cell offsets ox (1-D) and
    oy (1-D), target minus source, for dx x dy cells and Poisson's ratio nu (module docstring)."""

    def corner(u, v):
        fa, fb = _asinh_terms(np.broadcast_to(u, np.broadcast_shapes(np.shape(u), np.shape(v))),
                              np.broadcast_to(v, np.broadcast_shapes(np.shape(u), np.shape(v))))
        return np.stack([fb + (1 - nu) * fa, fa + (1 - nu) * fb, -nu * np.hypot(u, v)])

    return _cell_sums(ox, oy, dx, dy, corner) / np.pi


def rectangle_tangential(x, y, a: float, b: float, nu: float) -> np.ndarray:
    """K_xx, K_yy, K_xy (m; stacked on a first axis of 3) at points (x, y) (m, broadcast) relative to the
    centre of the rectangle |X| < a, |Y| < b carrying unit traction: the four corner terms of the module
    docstring evaluated at each point (a point on an edge's line gets its limit)."""
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    total = 0.0
    for su, sv, sign in ((a, b, 1.0), (a, -b, -1.0), (-a, b, -1.0), (-a, -b, 1.0)):
        u, v = x + su, y + sv
        fa, fb = _asinh_terms(u, v)
        total = total + sign * np.stack([fb + (1 - nu) * fa, fa + (1 - nu) * fb, -nu * np.hypot(u, v)])
    return total / np.pi


def coupling_table(ox: np.ndarray, oy: np.ndarray, dx: float, dy: float) -> np.ndarray:
    """K_zx, K_zy (m; shape (2, len(ox), len(oy))) at the signed integer cell offsets ox, oy (module
    docstring: w = (1 - 2 nu)/2 (K_zx t_x + K_zy t_y)/(2 G), into the half-space)."""
    zx = _cell_sums(ox, oy, dx, dy, lambda u, v: _coupling_corner(u, v)[None])[0]
    zy = _cell_sums(oy, ox, dy, dx, lambda u, v: _coupling_corner(u, v)[None])[0].T
    return np.stack([zx, zy]) / np.pi


def cerruti_point(x, y, nu: float) -> np.ndarray:
    """Cerruti's surface displacements per unit point force and unit shear compliance 1/(2 G), at (x, y)
    from the force (m^-1): (u_x from F_x, u_y from F_y, u_y from F_x = u_x from F_y) =
    [(1 - nu)/r + nu x^2/r^3, (1 - nu)/r + nu y^2/r^3, nu x y/r^3] / pi: the integrand of
    :func:`cerruti_table`, for quadrature."""
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    r = np.hypot(x, y)
    return np.stack([(1 - nu) / r + nu * x * x / r**3, (1 - nu) / r + nu * y * y / r**3, nu * x * y / r**3]) / np.pi


def strip_tangential(nx: int, dx: float, datum: float, nu: float) -> np.ndarray:
    """Line contact: K_xx of strips of width dx at offsets 0 <= k < nx (m, shape (nx,); even in k):
    (1 - nu) times the normal strip kernel with the datum L (module docstring)."""
    return (1 - nu) * strip_coefficients(nx, dx, datum)


def strip_coupling(ox: np.ndarray, dx: float) -> np.ndarray:
    """Line contact: K_zx = |x + a| - |x - a| (m) at the signed strip offsets ox (x = ox dx, a = dx/2)."""
    x = np.asarray(ox, dtype=float) * dx
    return np.abs(x + dx / 2) - np.abs(x - dx / 2)


class Tangential:
    """The tangential kernel of a grid: ``components`` traction components (2: (x, y) on 3-D cells, 1: x
    on line contact's strips), ``values(ox, oy)`` the stack of the symmetric block's distinct kernels at
    signed integer offsets (broadcast arrays): 3-D (K_xx, K_yy, K_xy), line contact (K_xx,); m per unit
    traction per unit shear compliance 1/(2 G). ``diagonal``: K_xx at offset 0."""

    components = 2

    def __init__(self, dx: float, dy: float, nu: float):
        if not 0 <= nu <= 0.5:
            raise ValueError(f"Poisson's ratio {nu} outside [0, 1/2]")
        self.dx, self.dy, self.nu = dx, dy, nu

    def values(self, ox, oy) -> np.ndarray:
        return cerruti_table(np.ravel(ox), np.ravel(oy), self.dx, self.dy, self.nu)

    @property
    def diagonal(self) -> float:
        return float(self.values(np.zeros(1, int), np.zeros(1, int))[0, 0, 0])

    def blocks(self, stack: np.ndarray) -> list[list[np.ndarray]]:
        """The m x m block layout [[xx, xy], [xy, yy]] of a stack of :meth:`values` (or of their spectra)."""
        return [[stack[0], stack[2]], [stack[2], stack[1]]]


class TangentialStrips(Tangential):
    """Line contact: strips of width dx along X, traction q_x only, the datum L (m) of the strip kernel."""

    components = 1

    def __init__(self, dx: float, dy: float, nu: float, datum: float):
        super().__init__(dx, dy, nu)
        self.datum = datum

    def values(self, ox, oy) -> np.ndarray:
        ox = np.abs(np.ravel(ox))
        table = strip_tangential(int(ox.max(initial=0)) + 1, self.dx, self.datum, self.nu)
        return table[ox][None, :, None] * np.ones((1, 1, np.size(oy)))

    def blocks(self, stack: np.ndarray) -> list[list[np.ndarray]]:
        return [[stack[0]]]


class Coupling:
    """The normal-tangential coupling kernels of a grid (module docstring): ``values(ox, oy)`` the stack
    (K_zx, K_zy) at signed integer offsets (3-D) or (K_zx,) (line contact's strips), m per unit traction
    per unit (1 - 2 nu)/2 x 1/(2 G); the normal displacement (into the half-space) of a tangential
    traction applied to the half-space is (1 - 2 nu)/(4 G) sum_j K_zj t_j."""

    def __init__(self, dx: float, dy: float, line: bool = False):
        self.dx, self.dy, self.line = dx, dy, line
        self.components = 1 if line else 2

    def values(self, ox, oy) -> np.ndarray:
        if self.line:
            return strip_coupling(np.ravel(ox), self.dx)[None, :, None] * np.ones((1, 1, np.size(oy)))
        return coupling_table(np.ravel(ox), np.ravel(oy), self.dx, self.dy)


def tangential_kernel(grid, nu: float) -> Tangential:
    """The tangential kernel of a (non-periodic) ``grid`` for Poisson's ratio nu: Cerruti's rectangles, or
    the strips with the grid's datum on a line-contact grid."""
    if grid.topology.whole:
        raise ValueError("friction on a periodic grid is not implemented")
    if grid.line:
        return TangentialStrips(grid.dx, grid.dy, nu, grid.datum)
    return Tangential(grid.dx, grid.dy, nu)
