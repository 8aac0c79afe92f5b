"""Steady rolling at constant velocity solved directly in the body frame (no transient).

For J(t) = Jinf - sum_i dJ_i exp(-t / tau_i) and a body moving at constant speed V along the direction d,
a material point now at body-frame position x was, a time s ago, at x + V s d (ahead of the body: the
material arrives from ahead). The steady surface displacement is therefore

    u = A (J0 p + sum_i dJ_i E_i p),    (E_i p)(x) = int_0^inf exp(-eta / L_i) p(x + eta d) deta / L_i,

L_i = V tau_i. With p interpolated linearly between cell centres along d (so that a filter length far
below the cell still shifts the field by L: E p = p + L dp/dx + ...), E_i at a cell centre is exact as the
one-sided recursion

    (E p)_k = alpha p_k + beta p_{k+1} + r (E p)_{k+1},   r = e^{-t}, t = dx / L,
    beta = (1 - e^{-t} (1 + t)) / t,   alpha = 1 - e^{-t} - beta,

(k + 1 the next cell ahead). With the memory m(p) = sum_i dJ_i E_i p,
the steady state is a fixed point of elastic contact problems with a compliance Jc (Simulation.solve_steady:
J at the time to cross the contact) and the known height Z + A (m(p_old) - (Jc - J0) p_old), solved by the
ContactSolver; Anderson mixing of that field accelerates it.
"""

from __future__ import annotations

import numpy as np


def creep_filter(p: np.ndarray, length: float, cell: float, axis: int, sign: int) -> np.ndarray:
    """E p of the module docstring on a whole (nx, ny) field: ``length`` = V tau (m), ``cell`` the cell
    size along ``axis`` (m), ``sign`` = +1 when the motion is towards increasing index along ``axis``."""
    q = np.moveaxis(p, axis, 0)
    if sign < 0:
        q = q[::-1]
    t = cell / length
    r = np.exp(-t)
    beta = -np.expm1(-t) / t - r if t > 1e-3 else t / 2 - t * t / 3  # (1 - e^-t (1 + t)) / t
    alpha = -np.expm1(-t) - beta
    out = np.empty_like(q)
    ahead = np.zeros(q.shape[1:])  # (E p) and p of the next cell ahead; none beyond the grid (p = 0)
    p_ahead = np.zeros(q.shape[1:])
    for k in range(q.shape[0] - 1, -1, -1):  # from the front backwards
        ahead = alpha * q[k] + beta * p_ahead + r * ahead
        out[k], p_ahead = ahead, q[k]
    if sign < 0:
        out = out[::-1]
    return np.moveaxis(out, 0, axis)


def memory(p: np.ndarray, material, speed: float, cell: float, axis: int, sign: int) -> np.ndarray:
    """m(p) = sum_i dJ_i E_i p (Pa * 1/Pa, >= 0 for p >= 0): J0 A p + A m(p) is the steady displacement."""
    m = np.zeros_like(p)
    for dJ, tau in zip(material.dJ, material.tau):
        m += dJ * creep_filter(p, speed * tau, cell, axis, sign)
    return m


class Anderson:
    """Anderson mixing of a fixed point x = g(x) keeping ``depth`` differences (type II)."""

    def __init__(self, depth: int = 6):
        self.depth, self.xs, self.fs = depth, [], []

    def next(self, x: np.ndarray, gx: np.ndarray) -> np.ndarray:
        f = gx - x
        self.xs.append(gx)
        self.fs.append(f)
        if len(self.fs) > self.depth + 1:
            self.xs.pop(0)
            self.fs.pop(0)
        if len(self.fs) == 1:
            return gx
        df = np.array([a - b for a, b in zip(self.fs[1:], self.fs[:-1])]).reshape(len(self.fs) - 1, -1)
        dg = np.array([a - b for a, b in zip(self.xs[1:], self.xs[:-1])]).reshape(len(self.xs) - 1, -1)
        gamma = np.linalg.lstsq(df.T, f.ravel(), rcond=None)[0]
        return gx - (gamma @ dg).reshape(gx.shape)
