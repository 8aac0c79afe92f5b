"""Steady rolling at constant velocity solved directly in the body frame (no transient).

A body moving at constant speed V along the direction d (+X, -X, +Y or -Y): in its frame the material
streams backwards, and a material point now at body-frame cell j was at j + V s d a time s ago (the
material arrives from ahead). The transient run's time integrator ([solver] integrator, step dt) turns a
point's pressure history into its displacement in pressure space W (w = A W, formulation §4): a linear,
time-invariant, causal filter of that history, whose response to a unit pressure pulse is h[s] (s steps
later; :func:`pulse_response`, computed by the integrator itself). In steady state the history of the point
at j is the body-frame field ahead of it, so

    W_j = sum_s h[s] p(j + s c),     c = V dt / (cell along d),

with p interpolated linearly between cell centres along d: a correlation with a per-cell kernel H
(:func:`memory_kernel`). With c = 1 (the body crosses one cell per step: [time] steps_per_cell = 1 on square
cells) there is no interpolation and this is exactly the steady state of the transient run with that step
and integrator: the long transient converges to it. Smaller c refines the time integration of the same
body-frame field (c -> 0: the exact hereditary law for p linear between cell centres).

Simulation.solve_steady finds p by a fixed point over elastic contact problems: compliance Jc (J at the
time to cross the contact) and the known height Z + A (W(p_old) - Jc p_old), Anderson-mixed.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import fftconvolve

from petroll.solver.history import make_history


def pulse_response(material, integrator: str, dt: float, steps: int) -> np.ndarray:
    """W (1/Pa) of one material point at steps 0 ... steps - 1 after it carried a unit pressure over step
    0 only (zero before and after), as ``integrator`` computes it with steps of dt (s): h[0] = J_eff.
    The history is guarded: a step at which the integrator cannot hold a penetration is refused
    (SolverError), as in a transient run."""
    history = make_history(material, integrator, (1, 1))
    pulse, rest = np.ones((1, 1)), np.zeros((1, 1))
    h = np.empty(steps)
    for s in range(steps):
        p = pulse if s == 0 else rest
        v = history.preceding(dt)
        h[s] = history.compliance(dt) * p[0, 0] + (0.0 if v is None else v[0, 0])
        history.advance(p, dt)
    return h


def memory_kernel(h: np.ndarray, c: float, cells: int) -> np.ndarray:
    """H[m], m = 0 ... cells - 1: W_j = sum_m H[m] p_{j+m} (module docstring) from the pulse response h
    of steps that cross c cells each (p linear between cell centres; c = 1: H = h)."""
    position = np.arange(len(h)) * c
    i = np.floor(position + 1e-12).astype(int)
    f = np.clip(position - i, 0.0, 1.0)
    H = np.zeros(cells + 1)
    inside = i < cells
    np.add.at(H, i[inside], (1 - f[inside]) * h[inside])
    np.add.at(H, i[inside] + 1, f[inside] * h[inside])
    return H[:cells]


class SteadyMemory:
    """W(p) of the module docstring on a body-frame field, motion along ``axis`` (0: X, 1: Y) with ``sign``
    +1 towards increasing index. ``behind``: cells added behind the field (its wake, where p = 0):
    ``__call__`` takes and returns fields on the extended grid."""

    def __init__(self, material, integrator: str, speed: float, dt: float, cell: float, axis: int,
                 sign: int, cells: int):
        c = speed * dt / cell
        steps = math.ceil(cells / c) + 1
        self.kernel = memory_kernel(pulse_response(material, integrator, dt, steps), c, cells)
        self.axis, self.sign = axis, sign

    def __call__(self, p: np.ndarray) -> np.ndarray:
        q = np.moveaxis(p, self.axis, 0)
        if self.sign > 0:  # reversed so that "ahead" is towards lower index: a causal convolution
            q = q[::-1]
        w = fftconvolve(q, self.kernel[:, None], axes=0)[: q.shape[0]]
        if self.sign > 0:
            w = w[::-1]
        return np.moveaxis(w, 0, self.axis)


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
