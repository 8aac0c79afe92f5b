"""Stresses below the surface: the half-space's stress tensor under a saved surface pressure.

Contact loads the half-space z >= 0 (z into it) with a normal pressure p >= 0 and, with friction, the
tangential tractions t = (t_x, t_y) (those of the body on the half-space). With a constant Poisson's
ratio nu the stresses of a linear viscoelastic half-space under given surface tractions are the elastic ones (they do not depend on the moduli), so those of the current pressure need no history.
Sign: tension positive, so the surface carries sigma_zz = -p.

Method: Love's (1929) potentials of the loaded surface (Johnson, Contact Mechanics, 1985, §3.2):
psi = integral p / rho dA and chi = integral p ln(rho + z) dA (rho the distance to the load point), with

    sigma_xx = [2 nu psi_z - (1 - 2 nu) chi_xx - z psi_xx] / (2 pi)     (yy: x -> y)
    sigma_zz = [psi_z - z psi_zz] / (2 pi)
    sigma_xy = -[(1 - 2 nu) chi_xy + z psi_xy] / (2 pi)
    sigma_xz = -z psi_xz / (2 pi),   sigma_yz = -z psi_yz / (2 pi)

(derived from the displacements 4 pi G u_x = -(1 - 2 nu) chi_x - z psi_x, 4 pi G u_z = 2 (1 - nu) psi
- z psi_z; a point load gives Boussinesq's closed forms). For a pressure uniform on a dx x dy cell every
derivative above is a sum over the cell's corners of a closed-form function of the corner's offset
(u, v) = (x - xi, y - eta): ``corner_terms``. So the stress at every cell centre at depth z from cell-uniform
pressure is an exact discrete convolution with these influence coefficients, applied with zero-padded FFTs
(linear, not periodic: the DC-FFT of petroll/solver/influence.py, rows split over ranks). No truncation,
no aliasing: the result is exact for the cell-uniform pressure to round-off (about 1e-13 of p_max,
measured against quadrature of the point-load solution in tests/test_stress.py); its accuracy against a
smooth pressure is that of the pressure field itself.

Tangential tractions (Cerruti; Johnson 1985, §3.6): a traction t_x on the surface has Love's potentials
F = integral t_x ln(rho + z) dA (X below, per unit traction) and F1 = integral t_x Omega dA, Omega =
z ln(rho + z) - rho (W; W_z = X, both harmonic), and

    2 pi sigma_xx = 2 (1 + nu) X_xz + 2 nu W_xxx - z X_xxx,   2 pi sigma_yy = 2 nu (X_xz + W_xyy) - z X_xyy
    2 pi sigma_zz = -z X_xzz,   2 pi sigma_xy = X_yz + 2 nu W_xxy - z X_xxy
    2 pi sigma_xz = X_zz - z X_xxz,   2 pi sigma_yz = -z X_xyz

(from the displacements 4 pi G u = (2 X_z + 2 nu W_xx - z X_xx, 2 nu W_xy - z X_xy, (1 - 2 nu) X_x - z X_xz);
their point-force limits are Johnson's Eq. 3.87, tests/test_friction_stress.py). Over a cell every
derivative is again a mixed difference over its corners of a closed form (``shear_corner_terms``): where
the derivative has an x and a y, one lower derivative of the point potential; where it has no y, the
integral along v, reduced by harmonicity (X_xx = -X_yy - X_zz) to those of 1/rho. A traction t_y is the
same with x and y exchanged.
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

from petroll.solver.influence import Convolution


COMPONENTS = ("sigma_xx", "sigma_yy", "sigma_zz", "sigma_xy", "sigma_xz", "sigma_yz")
"""The six independent components of the stress tensor, in the order of :func:`cell_stress`."""


def corner_terms(u: np.ndarray, v: np.ndarray, z: float) -> dict[str, np.ndarray]:
    """Corner functions F(u, v) at depth z >= 0 whose mixed difference over a cell's corners gives the
    derivatives of Love's potentials for unit pressure on the cell (d2F/du dv = the point-load value).

    Keys: ``chi_xx``, ``chi_yy``, ``chi_xy``, ``psi_z``, ``psi_xx``, ``psi_yy``, ``psi_xy``, ``psi_xz``,
    ``psi_yz``, ``psi_zz``. u and v must not be 0 (corner offsets from cell centres never are).
    """
    rho = np.sqrt(u * u + v * v + z * z)
    rho_minus_z = (u * u + v * v) / (rho + z)  # rho - z without cancellation
    v_plus = _plus(v, rho, u * u + z * z)  # v + rho, stable for v < 0
    u_plus = _plus(u, rho, v * v + z * z)
    psi_xx = u / (rho * v_plus)
    psi_yy = v / (rho * u_plus)
    return {
        "chi_xx": np.arctan2(u * v * rho_minus_z, u * u * rho + v * v * z),
        "chi_yy": np.arctan2(u * v * rho_minus_z, v * v * rho + u * u * z),
        "chi_xy": np.log(rho + z),
        "psi_z": -np.arctan2(u * v, z * rho),
        "psi_xx": psi_xx,
        "psi_yy": psi_yy,
        "psi_xy": 1.0 / rho,
        "psi_xz": z / (rho * v_plus),
        "psi_yz": z / (rho * u_plus),
        "psi_zz": -(psi_xx + psi_yy),
    }


def strip_terms(u: np.ndarray, z: float) -> dict[str, np.ndarray]:
    """The corner terms of a strip infinitely long along Y (line contact, plane strain): the limits of
    :func:`corner_terms` as the cell's Y-corners go to +-infinity, F(u, +inf) - F(u, -inf), so that their
    difference over the strip's two edges gives the potentials' derivatives (``chi_xy``, ``psi_xy``,
    ``psi_yz``, ``chi_yy`` and ``psi_yy`` vanish). u must not be 0 (edge offsets from centres never are)."""
    r2 = u * u + z * z
    zero = np.zeros(np.shape(r2))
    angle = 2 * np.arctan2(u, z)
    return {"chi_xx": angle, "chi_yy": zero, "chi_xy": zero, "psi_z": -angle, "psi_xx": -2 * u / r2,
            "psi_yy": zero, "psi_xy": zero, "psi_xz": -2 * z / r2, "psi_yz": zero, "psi_zz": 2 * u / r2}


def _plus(a: np.ndarray, rho: np.ndarray, rest: np.ndarray) -> np.ndarray:
    """a + rho with rho^2 = a^2 + rest, computed as rest / (rho - a) where a < 0 (no cancellation)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a >= 0, a + rho, rest / (rho - a))


def cell_stress(x: np.ndarray, y: np.ndarray, z: float, dx: float, dy: float, nu: float) -> np.ndarray:
    """Stresses (6, ...) at (x, y, z) relative to the centre of a dx x dy cell carrying unit pressure
    (compressive), in the order of :data:`COMPONENTS`; tension positive. x, y broadcast; z >= 0; the point
    must not lie on a vertical line through the cell's edges (cell centres never do)."""
    return _stresses(cell_sums(corner_terms, x, y, z, dx, dy), z, nu)


def cell_stress_table(ox: np.ndarray, oy: np.ndarray, z: float, dx: float, dy: float,
                      nu: float) -> np.ndarray:
    """:func:`cell_stress` at the cell centres offset by ox[i] dx, oy[j] dy (integer 1-D arrays): (6, len(ox),
    len(oy)). Neighbouring cells share corners, so each corner's terms are evaluated once (4x fewer)."""
    return _stresses(table_sums(corner_terms, ox, oy, z, dx, dy), z, nu)


def cell_sums(terms, x: np.ndarray, y: np.ndarray, z: float, dx: float, dy: float) -> dict[str, np.ndarray]:
    """The mixed differences over the corners of a dx x dy cell of the corner functions ``terms(u, v, z)``
    (a dict) at (x, y, z) relative to its centre: each function's integral over the cell."""
    a, b = dx / 2, dy / 2
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    total: dict[str, np.ndarray] = {}
    for su, sv, sign in ((a, b, 1.0), (a, -b, -1.0), (-a, b, -1.0), (-a, -b, 1.0)):
        for k, t in terms(x + su, y + sv, z).items():
            total[k] = total.get(k, 0.0) + sign * t
    return total


def table_sums(terms, ox: np.ndarray, oy: np.ndarray, z: float, dx: float, dy: float) -> dict[str, np.ndarray]:
    """:func:`cell_sums` at the cell centres offset by ox[i] dx, oy[j] dy (integer 1-D arrays), each of shape
    (len(ox), len(oy)). Neighbouring cells share corners, so each corner's terms are evaluated once."""
    ox, oy = np.asarray(ox, dtype=np.int64).ravel(), np.asarray(oy, dtype=np.int64).ravel()
    cu, cv = np.union1d(2 * ox - 1, 2 * ox + 1), np.union1d(2 * oy - 1, 2 * oy + 1)  # in half cells
    # the corners 2o - 1 and 2o + 1 of a cell are neighbours in cu (all odd): its sum is a mixed difference
    i, j = np.searchsorted(cu, 2 * ox - 1)[:, None], np.searchsorted(cv, 2 * oy - 1)[None, :]
    return {k: np.diff(np.diff(t, axis=0), axis=1)[i, j]
            for k, t in terms(cu[:, None] * (dx / 2), cv[None, :] * (dy / 2), z).items()}


def strip_sums(terms, ox: np.ndarray, z: float, dx: float) -> dict[str, np.ndarray]:
    """The differences over the two edges of strips of width dx offset by ox[i] dx (integers) of the strip
    functions ``terms(u, z)``, each of shape (len(ox), 1)."""
    ox = np.asarray(ox, dtype=np.int64).ravel()
    edges = np.union1d(2 * ox - 1, 2 * ox + 1)  # in half strips; a strip's two edges are neighbours
    i = np.searchsorted(edges, 2 * ox - 1)
    return {k: np.diff(t)[i, None] for k, t in terms(edges * (dx / 2), z).items()}


def strip_stress_table(ox: np.ndarray, z: float, dx: float, nu: float) -> np.ndarray:
    """The plane-strain stresses (6, len(ox), 1) at the centres of strips offset by ox[i] dx (integers) from
    a strip of width dx carrying unit pressure (line contact); sigma_xy = sigma_yz = 0 and sigma_yy =
    nu (sigma_xx + sigma_zz)."""
    return _stresses(strip_sums(strip_terms, ox, z, dx), z, nu)


def _stresses(t: dict[str, np.ndarray], z: float, nu: float) -> np.ndarray:
    """The six stresses (6, ...) from the cell sums of the corner terms (module docstring)."""
    s = [2 * nu * t["psi_z"] - (1 - 2 * nu) * t["chi_xx"] - z * t["psi_xx"],
         2 * nu * t["psi_z"] - (1 - 2 * nu) * t["chi_yy"] - z * t["psi_yy"],
         t["psi_z"] - z * t["psi_zz"],
         -(1 - 2 * nu) * t["chi_xy"] - z * t["psi_xy"],
         -z * t["psi_xz"],
         -z * t["psi_yz"]]
    return np.stack(np.broadcast_arrays(*s)) / (2 * np.pi)


def shear_corner_terms(u: np.ndarray, v: np.ndarray, z: float) -> dict[str, np.ndarray]:
    """Corner functions at depth z of the derivatives of X and W (``SHEAR``) a unit traction t_x on a cell
    needs; u, v must not be 0."""
    rho = np.sqrt(u * u + v * v + z * z)
    s2 = u * u + z * z
    x_xz = np.arcsinh(v / np.sqrt(s2))
    return {"X_xz": x_xz, "X_xzz": -v * z / (rho * s2), "X_xxz": -v * u / (rho * s2),
            "X_xxx": v / rho * (z / s2 - 1 / (rho + z)), "W_xxx": v / (rho + z) - x_xz,
            "X_zz": -np.arctan2(u * v, z * rho), "X_yz": np.arcsinh(u / np.sqrt(v * v + z * z)),
            "X_xyy": v / (rho * (rho + z)), "X_xxy": u / (rho * (rho + z)), "X_xyz": 1 / rho,
            "W_xyy": -v / (rho + z), "W_xxy": -u / (rho + z)}


def strip_shear_terms(u: np.ndarray, z: float) -> dict[str, np.ndarray]:
    """:func:`shear_corner_terms` of a strip along Y (plane strain): F(u, +inf) - F(u, -inf) but for
    terms constant in u (they cancel in the difference over the strip's edges); the y-derivatives vanish."""
    s2 = u * u + z * z
    zero = np.zeros(np.shape(s2))
    return {"X_xz": -np.log(s2), "X_xzz": -2 * z / s2, "X_xxz": -2 * u / s2, "X_xxx": 2 * z / s2,
            "W_xxx": np.log(s2), "X_zz": -2 * np.arctan2(u, z), "X_yz": zero, "X_xyy": zero, "X_xxy": zero,
            "X_xyz": zero, "W_xyy": zero, "W_xxy": zero}


def _shear_stresses(t: dict[str, np.ndarray], z: float, nu: float) -> np.ndarray:
    """The six stresses (6, ...) of a unit traction t_x from the cell sums of the shear corner terms."""
    s = [2 * (1 + nu) * t["X_xz"] + 2 * nu * t["W_xxx"] - z * t["X_xxx"],
         2 * nu * (t["X_xz"] + t["W_xyy"]) - z * t["X_xyy"],
         -z * t["X_xzz"],
         t["X_yz"] + 2 * nu * t["W_xxy"] - z * t["X_xxy"],
         t["X_zz"] - z * t["X_xxz"],
         -z * t["X_xyz"]]
    return np.stack(np.broadcast_arrays(*s)) / (2 * np.pi)


def cell_shear_stress(x: np.ndarray, y: np.ndarray, z: float, dx: float, dy: float, nu: float) -> np.ndarray:
    """Stresses (6, ...) at (x, y, z) relative to the centre of a dx x dy cell carrying a unit traction along
    +X on the half-space (:func:`cell_stress`'s conventions)."""
    return _shear_stresses(cell_sums(shear_corner_terms, x, y, z, dx, dy), z, nu)


SWAPPED = [1, 0, 2, 3, 5, 4]
"""The components of a traction t_y's stresses among those of t_x with x and y exchanged."""


def shear_stress_table(ox: np.ndarray, oy: np.ndarray, z: float, dx: float, dy: float, nu: float,
                       axis: int = 0) -> np.ndarray:
    """:func:`cell_shear_stress` at the cell centres offset by ox[i] dx, oy[j] dy (integer 1-D arrays) for a
    unit traction along X (``axis`` 0) or Y (1, by exchanging x and y): (6, len(ox), len(oy))."""
    if axis == 1:
        return shear_stress_table(oy, ox, z, dy, dx, nu)[SWAPPED].transpose(0, 2, 1)
    return _shear_stresses(table_sums(shear_corner_terms, ox, oy, z, dx, dy), z, nu)


def strip_shear_stress_table(ox: np.ndarray, z: float, dx: float, nu: float) -> np.ndarray:
    """The plane-strain stresses (6, len(ox), 1) of a unit traction along X on a strip of width dx."""
    return _shear_stresses(strip_sums(strip_shear_terms, ox, z, dx), z, nu)


def von_mises(s: np.ndarray) -> np.ndarray:
    """Von Mises equivalent stress (Pa) of stresses ``s`` (6, ...) in the order of :data:`COMPONENTS`."""
    xx, yy, zz, xy, xz, yz = s
    return np.sqrt(0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2) + 3 * (xy**2 + xz**2 + yz**2))


def max_shear(s: np.ndarray) -> np.ndarray:
    """Maximum shear stress (Tresca, Pa): half the largest difference of principal stresses of ``s``
    (6, ...) in the order of :data:`COMPONENTS`."""
    xx, yy, zz, xy, xz, yz = s
    rows = (np.stack([xx, xy, xz], -1), np.stack([xy, yy, yz], -1), np.stack([xz, yz, zz], -1))
    tensor = np.stack(rows, -1)
    principal = np.linalg.eigvalsh(tensor)
    return 0.5 * (principal[..., -1] - principal[..., 0])


class SubsurfaceStress:
    """The stresses below cell-uniform pressure on an nx x ny grid of dx x dy cells, rows split over ``comm``
    (:class:`petroll.solver.partition.RowPartition`, as every field). ``line``: a line-contact grid (ny = 1
    strips, plane strain: :func:`strip_stress_table`).

    ``at(p, z, traction)`` takes this rank's rows of the pressure (Pa, shape (local rows, ny)) and, with
    friction, of the tangential tractions on the half-space (Pa, (m, local rows, ny), m = 2, line contact
    1; None: none) and returns the six components (6, local rows, ny) in Pa at depth z >= 0 (m) below the
    cell centres, tension positive. Collective. The loads' transforms are computed once per field and
    reused for every depth.
    """

    def __init__(self, nx: int, ny: int, dx: float, dy: float, nu: float, comm: MPI.Comm = MPI.COMM_SELF,
                 line: bool = False):
        if line and ny != 1:
            raise ValueError(f"a line-contact grid has ny = 1, not {ny}")
        self.nx, self.ny, self.dx, self.dy, self.nu, self.comm, self.line = nx, ny, dx, dy, nu, comm, line
        self.fft = Convolution(None, nx, ny, comm)
        self.r0, self.r1 = self.fft.r0, self.fft.r1
        self._field: tuple[np.ndarray, list[np.ndarray]] | None = None

    def at(self, p: np.ndarray, z: float, traction: np.ndarray | None = None) -> np.ndarray:
        if z < 0:
            raise ValueError(f"depth z = {z} must be >= 0")
        if self._field is None or self._field[0] is not p:
            loads = [p] + ([] if traction is None else list(traction))
            self._field = (p, [self.fft.forward(np.asarray(f, dtype=float)) for f in loads])
        spectra = self._field[1]
        dx, dy, nu = self.dx, self.dy, self.nu
        # offsets are target minus source cell: the unit-load cell is centred at the source
        if self.line:
            tables = [lambda ox, oy: strip_stress_table(ox, z, dx, nu),
                      lambda ox, oy: strip_shear_stress_table(ox, z, dx, nu)]
        else:
            tables = [lambda ox, oy: cell_stress_table(ox, oy, z, dx, dy, nu),
                      lambda ox, oy: shear_stress_table(ox, oy, z, dx, dy, nu, 0),
                      lambda ox, oy: shear_stress_table(ox, oy, z, dx, dy, nu, 1)]
        total = None
        for spectrum, table in zip(spectra, tables):
            kernels = self.fft.kernel_spectrum(table)
            part = [spectrum * k for k in kernels]
            total = part if total is None else [a + b for a, b in zip(total, part)]
        return np.stack([self.fft.backward(t) for t in total])
