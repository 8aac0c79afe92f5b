"""First guesses for the contact QP of a time step, from the last solutions carried along with the body.

Rolling is stationary in the body's frame once steady: the pressure of step n moved by the body's
displacement is then the answer of step n + 1. The guess is built from the last solutions:

* a body that moves by 1/k of a cell per step (k = 1..MAX_LAG, e.g. square cells and ``steps_per_cell``
  = k along X or Y; k = 1 for a body at rest) has every k-th solution a whole number of cells away. When
  the solutions k, 2k and 3k steps back all are, they are moved along and extrapolated in the body's
  frame: guess = q0 + rho (q0 - q1), q_j the solution (j + 1) k steps back moved along, with
  rho = <q0 - q1, q1 - q2> / |q1 - q2|^2 clipped to [0, 1], the decay ratio of a transient that fades
  geometrically (rho = 0: the plain carried solution);
* otherwise the most recent solution a whole number of cells away is carried, or else the newest one,
  rounded to the nearest whole cell.

Negative values are clipped to zero. Only the first guess depends on this; the QP's tolerance decides
the answer. 3k solutions are kept (k from the last step's move; 3 when no k fits).

:class:`TractionWarmStart` does the same for the tangential tractions of friction (fields (m, rows, ny),
signed: nothing clipped, the QP projects onto its friction disks). The tractions of a transient have
parts that move with the body (its contact, its stick and slip zones) and parts that stay with the
material (what a shift or the contact's entry left in each material point: friction's memory), so they
are extrapolated in both frames at once. With T the carry by one lag (the body's move over k steps) and
q_j the solution jk steps back (j = 1, 2, 3) where it was, the guess is

    (1 + 2 T) q_1 - (2 T + T^2) q_2 + T^2 q_3     (three kept; two: (1 + T) q_1 - T q_2),

the extrapolation whose error vanishes for any field B(x - s) + M(x) + t C(x - s): one steady in the body's
frame, one fixed in the material, one growing linearly in the body's frame (two kept: exact for the first two) --
the roots T, T, 1 of z^3 - (1 + 2 T) z^2 + (2 T + T^2) z - T^2. A body at rest (T = 1) gets quadratic
(linear) extrapolation in time. The QP reads its slip set from the guess (cells on their disk's edge), and
the material's terms leave a slip cell a little inside it: so where the extrapolation in the body's frame
alone, 2 T q_1 - T^2 q_2, is on the edge of the step's bound (exactly so for a slip zone that moves with the
body), the guess is put on the edge. Measured in docs/friction.md.
"""

from __future__ import annotations

import numpy as np

from petroll.solver.partition import roll_field, shift_field

DEPTH = 3
"""Solutions per lag that the extrapolation uses."""

MAX_LAG = 4
"""Largest k (steps per whole cell) for which solutions are kept to extrapolate."""

_WHOLE = 1e-6  # a displacement within this many cells of a whole number of cells counts as whole


class WarmStart:
    """The last solutions of a run (pressure on this rank's rows, Pa, with the body position sx, sy, m).

    ``depth``: DEPTH (the default) extrapolates, 1 only carries solutions along, 0 keeps none (every
    step starts from p = 0; for benchmarks).
    """

    needed = DEPTH  # solutions per lag the extrapolation takes

    def __init__(self, scene_grid, rows, comm, depth: int = DEPTH):
        self.grid, self.rows, self.comm, self.depth = scene_grid, rows, comm, depth
        self.recent: list[tuple[np.ndarray, float, float]] = []  # oldest first

    def record(self, pressure: np.ndarray, sx: float, sy: float) -> None:
        """Keep the solution of the step just solved, with the body's position (m)."""
        kept = [*self.recent, (pressure, float(sx), float(sy))]
        keep = self.depth * (self._lag(kept) or 1)
        self.recent = kept[max(len(kept) - keep, 0) :]

    def guess(self, sx: float, sy: float) -> np.ndarray | None:
        """The first guess for the body at (sx, sy) (m); None before the first step (start from p = 0)."""
        if not self.recent:
            return None
        cells = [self._cells(sx - x, sy - y) for _, x, y in self.recent]
        lag = self._lag(self.recent)
        if lag and len(self.recent) >= self.needed * lag:
            chosen = [len(self.recent) - j * lag for j in range(1, self.needed + 1)]  # k, 2k, 3k steps back
            if all(cells[i] is not None for i in chosen):
                return self.extrapolate([self._carry(self.recent[i][0], cells[i]) for i in chosen])
        return self._nearest(sx, sy, cells)

    def _nearest(self, sx: float, sy: float, cells) -> np.ndarray:
        """The most recent solution a whole number of ``cells`` away carried along, else the newest one
        rounded to whole cells."""
        for (p, _, _), c in zip(self.recent[::-1], cells[::-1]):
            if c is not None:
                return self._carry(p, c)
        p, x, y = self.recent[-1]
        return self._carry(p, (int(round((sx - x) / self.grid.dx)), int(round((sy - y) / self.grid.dy))))

    def extrapolate(self, carried: list[np.ndarray]) -> np.ndarray:
        """The guess from the solutions k, 2k, 3k steps back carried along (module docstring)."""
        q0, q1, q2 = carried
        d1, d2 = q0 - q1, q1 - q2
        dots = self.comm.allreduce(np.array([float((d1 * d2).sum()), float((d2 * d2).sum())]))
        rho = min(max(dots[0] / dots[1], 0.0), 1.0) if dots[1] > 0 else 0.0
        return np.maximum(q0 + rho * d1, 0.0)

    def _lag(self, kept) -> int | None:
        """k: the last step moved the body by 1/k of a whole number of cells (k <= MAX_LAG), else None."""
        if len(kept) < 2:
            return 1
        (_, x0, y0), (_, x1, y1) = kept[-2], kept[-1]
        return next((k for k in range(1, MAX_LAG + 1) if self._cells(k * (x1 - x0), k * (y1 - y0))), None)

    def _cells(self, mx: float, my: float) -> tuple[int, int] | None:
        """The move (mx, my) (m) in whole cells, or None if it is not a whole number of cells."""
        fx, fy = mx / self.grid.dx, my / self.grid.dy
        di, dj = int(round(fx)), int(round(fy))
        return (di, dj) if abs(fx - di) <= _WHOLE and abs(fy - dj) <= _WHOLE else None

    def _carry(self, pressure: np.ndarray, cells: tuple[int, int]) -> np.ndarray:
        """``pressure`` moved by ``cells``, around along a periodic grid's repeating axes (a field of
        components (m, rows, ny): each)."""
        if cells == (0, 0):
            return pressure
        if pressure.ndim == 3:
            return np.stack([self._carry(component, cells) for component in pressure])
        roll, cells = self.grid.topology.split_move(cells)
        if roll != (0, 0):  # wrap along the repeating axes first, then shift along the others
            pressure = roll_field(pressure, *roll, self.rows, self.comm)
        if cells == (0, 0):
            return pressure
        return shift_field(pressure, cells[0], cells[1], self.rows, self.comm)


class TractionWarmStart(WarmStart):
    """The last tangential tractions of a run ((m, rows, ny), Pa, with the body's position) and the first
    guess of the next step's (module docstring: extrapolated in the body's and the material's frame from
    the solutions k, 2k and 3k steps back): ``depth`` 3 (default) or 2 extrapolates, 1 only carries."""

    def guess(self, sx: float, sy: float, bound: np.ndarray | None = None) -> np.ndarray | None:
        """The first guess for the body at (sx, sy) (m) on the step's traction bound ``bound`` (Pa, this
        rank's rows; None: no cell put on its edge); None before the first step."""
        if not self.recent:
            return None
        cells = [self._cells(sx - x, sy - y) for _, x, y in self.recent]
        lag = self._lag(self.recent)
        levels = 0 if not lag else min(self.depth, len(self.recent) // lag)
        if levels >= 2:
            chosen = [len(self.recent) - j * lag for j in range(1, levels + 1)]  # k, 2k (, 3k) steps back
            if all(cells[i] is not None for i in chosen):
                _, bx, by = self.recent[chosen[0]]  # the body one lag back
                ahead = [self._carry(self.recent[i][0], cells[i]) for i in chosen[:2]]  # T^j q_j
                here = [self._carry(q, self._cells(bx - x, by - y))  # T^(j-1) q_j
                        for q, x, y in (self.recent[i] for i in chosen)]
                body = 2 * ahead[0] - ahead[1]
                if levels == 2:
                    guess = ahead[0] + here[0] - here[1]
                else:
                    guess = body + here[0] - 2 * here[1] + here[2]
                return guess if bound is None else _on_edge(guess, body, bound)
        return self._nearest(sx, sy, cells)

    def forget(self) -> None:
        """Keep only the newest solution (the motion changes: a shift's trend is no rolling step's)."""
        self.recent = self.recent[-1:]


EDGE = 1e-9
"""A guess in the body's frame within this fraction of its bound counts as on the disk's edge."""


def _on_edge(guess: np.ndarray, body: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """``guess`` with its cells put on the edge |q| = bound where ``body`` is on it (directions kept)."""
    size = np.sqrt((guess * guess).sum(axis=0))
    edge = (bound > 0) & (np.sqrt((body * body).sum(axis=0)) >= bound * (1 - EDGE))
    return np.where(edge & (size > 0), guess * (bound / np.where(size > 0, size, 1.0)), guess)
