"""The preceding displacement u = A v of a step, computed on a box of cells only.

``v`` is the history's field (pressure space: u = A v, A the Love coefficients, m) on the whole track.
Most of it is not needed, and a full-track convolution per step would make a step's cost grow with the
track's length:

* sources: cells with |v| > cutoff * max|v| (``[solver] history_cutoff``). Behind a rolling body the
  wake fades like exp(-distance / (V tau)); dropping the rest changes u by at most
  cutoff * max|v| * S everywhere, S the largest row sum of A on the grid (the displacement a unit field on
  every cell would cause). S max|v| is a few to ten times the penetration (7x on the default scene, 12x
  on a 1000-cell track), so the default cutoff 1e-9 bounds the change at about 1e-8 of the penetration,
  the default tolerance's level; with a tighter [solver] tol lower the cutoff too. A cutoff of 0 keeps
  every non-zero cell (exact).
* targets: cells the body can touch. A > 0, so u >= -S max(-v, 0) everywhere; a layer's A has negative
  coefficients too, summing to at most -S_lift over a row (InfluenceOperator.lift_bound), so then
  u >= -S max(-v, 0) - S_lift max(v, 0) (S the row sum of |A|). A cell whose rigid interference
  reach - Z is below that bound cannot be in contact at a penetration <= reach (exact).

u is computed on the bounding box of both (its sides rounded up to multiples of ``QUANTUM`` cells, so
that few kernel shapes are built) and is zero outside it, where no cell can touch. On a periodic grid
(a kernel with negative coefficients everywhere but at its centre, every cell a candidate) u is computed
on the whole grid.

The tangential history of a viscoelastic body with friction (petroll.solver.friction) spans the track too;
:class:`TangentialWake` gives its step's displacement the same cut-off (:func:`sources`,
:func:`bounding_box`).
"""

from __future__ import annotations

import numpy as np
from mpi4py import MPI

QUANTUM = 16
"""Box sides are multiples of this many cells (or the whole grid side)."""


class Wake:
    """Computes u on the boxes of one ContactSolver's grid; ``boxes`` counts the steps that used a box
    smaller than the grid."""

    def __init__(self, solver, cutoff: float):
        self.solver, self.cutoff = solver, cutoff
        g = solver.grid
        self.whole = solver.influence.whole  # a periodic kernel's u is computed on the whole grid
        self.row_sum = None if self.whole else solver.influence.row_sum_bound(g.nx, g.ny)
        self.lift = None if self.whole else solver.influence.lift_bound(g.nx, g.ny)
        self.boxes = 0

    def displacement(self, v: np.ndarray, profile: np.ndarray, reach: float) -> np.ndarray:
        """u = A v (m; this rank's rows) where it matters for a penetration <= ``reach`` (m) of a body of
        rigid heights ``profile`` (m, this rank's rows); see the module docstring for the error bound."""
        comm, g = self.solver.comm, self.solver.grid
        if self.whole:
            return self.solver.influence.window(g.nx, g.ny)(v)
        extremes = np.array([np.abs(v).max(initial=0.0), (-v).max(initial=0.0), v.max(initial=0.0)])
        comm.Allreduce(MPI.IN_PLACE, extremes, op=MPI.MAX)
        largest, negative, positive = extremes
        if largest == 0:
            return np.zeros_like(v)
        with np.errstate(invalid="ignore"):  # inf - inf where a body has no surface: never needed there
            lowest = -self.row_sum * negative - self.lift * positive  # the least u can be
            needed = sources(v, self.cutoff, largest) | (reach - profile > lowest)
        box = bounding_box(needed, self.solver.r0, g.nx, g.ny, comm)
        if box == (0, g.nx, 0, g.ny):
            return self.solver.influence.window(g.nx, g.ny)(v)
        self.boxes += 1
        return self.solver.convolve_box(v, box)


class TangentialWake:
    """The tangential history's displacement of a step, u' = K X (petroll.solver.friction.Stepping: X the
    last steps' displacement sources combined, minus the history's v; (m, rows, ny), K the Cerruti or strip
    kernel of petroll.solver.tangential, m per unit source) on a box of one TangentialSolver's grid, by the
    normal history's rule (module docstring): the sources are the cells where a component of X exceeds
    ``cutoff`` x max|X|; the targets the cells with a traction bound (the step's QP reads u' there only:
    exact). Dropping the other sources changes u' there by at most cutoff x max|X| x S_K, S_K the largest
    row sum of |K| (both components) on the grid: K_xx + |K_xy| <= (1 + (sqrt 2 - 1) nu/2)/r pointwise, so
    S_K is at most 1.21 times the normal problem's S (line contact: K_xx = (1 - nu) x the strip kernel,
    S_K = (1 - nu) S). ``boxes`` counts the steps that used a box smaller than the grid."""

    def __init__(self, solver, cutoff: float):
        self.solver, self.cutoff = solver, cutoff
        self.boxes = 0

    def displacement(self, field: np.ndarray, bound: np.ndarray) -> np.ndarray:
        """u' = K ``field`` (m; this rank's rows, zero outside the box) where the traction bound ``bound``
        (Pa, this rank's rows) is positive; see the class docstring for the error bound."""
        solver, g = self.solver, self.solver.grid
        largest = solver.comm.allreduce(float(np.abs(field).max(initial=0.0)), op=MPI.MAX)
        needed = (bound > 0) | sources(field, self.cutoff, largest)
        box = bounding_box(needed, solver.r0, g.nx, g.ny, solver.comm)
        if box != (0, g.nx, 0, g.ny):
            self.boxes += 1
        return solver.displacement(field, box, 1.0)


def sources(v: np.ndarray, cutoff: float, largest: float) -> np.ndarray:
    """The cells (this rank's rows x ny) a history field ``v`` (rows, ny), or (components, rows, ny), keeps
    as sources: some component's magnitude above ``cutoff`` x ``largest`` (max|v| over all ranks)."""
    kept = np.abs(v) > cutoff * largest
    return kept if kept.ndim == 2 else kept.any(axis=0)


def bounding_box(needed: np.ndarray, r0: int, nx: int, ny: int, comm) -> tuple[int, int, int, int]:
    """The bounding box over all ranks of the ``needed`` cells (this rank's rows from grid row ``r0``, of an
    nx x ny grid), sides rounded up to QUANTUM cells (a single cell's box when none is needed)."""
    rows = np.flatnonzero(needed.any(axis=1)) + r0
    cols = np.flatnonzero(needed.any(axis=0))
    lo = np.array([rows.min(initial=nx), cols.min(initial=ny)])
    hi = np.array([rows.max(initial=-1), cols.max(initial=-1)]) + 1
    comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
    comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
    if hi[0] <= lo[0]:
        lo, hi = np.zeros(2, int), np.ones(2, int)
    i0, i1 = _rounded(int(lo[0]), int(hi[0]), nx)
    j0, j1 = _rounded(int(lo[1]), int(hi[1]), ny)
    return i0, i1, j0, j1


def _rounded(a: int, b: int, n: int) -> tuple[int, int]:
    """[a, b) grown to a multiple of QUANTUM cells (or to [0, n)), staying inside [0, n)."""
    size = min(-(-(b - a) // QUANTUM) * QUANTUM, n)
    start = min(a, n - size)
    return start, start + size
