"""First guesses for the contact QP of a time step, from the last solutions carried along with the body.

Rolling is stationary in the body's frame once steady: the pressure of step n moved by the body's
displacement is then the answer of step n + 1. The guess is built from the last ``DEPTH`` solutions:

* moved by whole cells (exact when the body moved by whole cells: square cells and ``steps_per_cell``
  = 1 along X or Y, or a body at rest), the most recent such solution is taken; otherwise the last one,
  rounded to the nearest whole cell;
* when the last three solutions all sit whole cells from the body's new position, they are extrapolated
  in the body's frame: guess = q0 + rho (q0 - q1), q_k the solution k + 1 steps back moved along, with
  rho = <q0 - q1, q1 - q2> / |q1 - q2|^2 clipped to [0, 1], the decay ratio of a transient that fades
  geometrically (rho = 0: the plain carried solution). Negative values are clipped to zero.

Only the first guess depends on this; the QP's tolerance decides the answer.
"""

from __future__ import annotations

import numpy as np

from petroll.grid import shift_field

DEPTH = 3
"""Solutions kept (fields of this rank's rows): the extrapolation needs three."""

_WHOLE = 1e-6  # a displacement within this many cells of a whole number of cells counts as whole


class WarmStart:
    """The last solutions of a run (pressure on this rank's rows, Pa, with the body position sx, sy, m).

    ``depth`` solutions are kept: DEPTH (the default) extrapolates, 1 only carries the last solution along,
    0 keeps none (every step starts from p = 0; for benchmarks).
    """

    def __init__(self, scene_grid, rows, comm, depth: int = DEPTH):
        self.grid, self.rows, self.comm, self.depth = scene_grid, rows, comm, depth
        self.recent: list[tuple[np.ndarray, float, float]] = []  # oldest first

    def record(self, pressure: np.ndarray, sx: float, sy: float) -> None:
        """Keep the solution of the step just solved, with the body's position (m)."""
        kept = [*self.recent, (pressure, float(sx), float(sy))]
        self.recent = kept[max(len(kept) - self.depth, 0) :]

    def guess(self, sx: float, sy: float) -> np.ndarray | None:
        """The first guess for the body at (sx, sy) (m); None before the first step (start from p = 0)."""
        if not self.recent:
            return None
        cells = [self._cells(sx - x, sy - y) for _, x, y in self.recent]
        whole = [c for c in cells if c is not None]
        if len(whole) == DEPTH:
            q0, q1, q2 = (self._carry(p, c) for (p, _, _), c in zip(self.recent[::-1], cells[::-1]))
            d1, d2 = q0 - q1, q1 - q2
            dots = self.comm.allreduce(np.array([float((d1 * d2).sum()), float((d2 * d2).sum())]))
            rho = min(max(dots[0] / dots[1], 0.0), 1.0) if dots[1] > 0 else 0.0
            return np.maximum(q0 + rho * d1, 0.0)
        for (p, _, _), c in zip(self.recent[::-1], cells[::-1]):
            if c is not None:
                return self._carry(p, c)
        p, x, y = self.recent[-1]
        return self._carry(p, (int(round((sx - x) / self.grid.dx)), int(round((sy - y) / self.grid.dy))))

    def _cells(self, mx: float, my: float) -> tuple[int, int] | None:
        """The move (mx, my) (m) in whole cells, or None if it is not a whole number of cells."""
        fx, fy = mx / self.grid.dx, my / self.grid.dy
        di, dj = int(round(fx)), int(round(fy))
        return (di, dj) if abs(fx - di) <= _WHOLE and abs(fy - dj) <= _WHOLE else None

    def _carry(self, pressure: np.ndarray, cells: tuple[int, int]) -> np.ndarray:
        if cells == (0, 0):
            return pressure
        return shift_field(pressure, cells[0], cells[1], self.rows, self.comm)
