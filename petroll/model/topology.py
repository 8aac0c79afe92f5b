"""A grid's topology: what differs between a windowed half-space, a grid periodic along both axes or along
one, and line contact, in one place (``Grid.topology``; the scene's [grid] keys pick it).

- :class:`Windowed`: a 3-D half-space that does not repeat. Each step's QP is posed on a window, the
  bounding box of the cells that can touch (grown to fast FFT lengths); a window that reaches the grid's
  edge is refused; the operator is a linear convolution (zero-padded FFTs).
- :class:`Line`: line contact (plane strain) that does not repeat. Its window may span the grid (the
  strips' displacement spreads over all of it), a layer's grown by ``GROW`` cells; after each solve the
  contact itself must stay off the grid's end strips.
- :class:`PeriodicAlong`: a 3-D grid that repeats along one axis. The QP covers the whole grid; the
  contact must stay off the edges of the other axis.
- :class:`Periodic`: every axis repeats (a line-contact grid: along X). The QP covers the whole grid, which
  has no edge; a 3-D one reports the contact's statistics over the cell (petroll.solver.rough).

Along a repeating axis a body's offsets from its reference point wrap around to its nearest image, the
warm start is rolled instead of shifted, and steady motion is sliding (solved by petroll.solver.sliding)
rather than rolling (petroll.solver.steady). The kernel each topology's operator applies is picked in
petroll.solver.kernels (``grid_kernel``), the only other place that tells them apart.
"""

from __future__ import annotations

import numpy as np
import scipy.fft

from petroll.errors import SolverError

GROW = 1
"""Cells added at both ends of a line-contact layer's QP window: its contact often grows a cell beyond the
interference and the previous step's contact (the bulge ahead of a rolling body), which the ring would find
only after a solve, to be solved again (docs/layer.md#performance measures the saving; in 3-D the windows
are not grown: there it saves nothing)."""


class Topology:
    """The base: a grid that does not repeat (``grid``: petroll.model.grid.Grid)."""

    whole = False
    """The contact QP is posed on the whole grid (no window): along a repeating axis every cell can touch."""
    load_power = 2 / 3
    """Load control's secant works on (F(delta) / F)^power - 1, nearly linear in delta (Hertz: 2/3)."""
    statistics = False
    """The run reports the contact's fraction of the cell, its mean gap and the pressure's spectrum."""
    edge_axes: tuple[int, ...] = (0, 1)
    """The axes (0: X, 1: Y) along which the grid has edges a contact must stay off."""

    def __init__(self, grid):
        self.grid = grid

    @property
    def repeats(self) -> tuple[bool, bool]:
        """Whether the grid repeats along X, Y."""
        return (False, False)

    def offsets(self, x, y, sx: float, sy: float) -> tuple[np.ndarray, np.ndarray]:
        """Offsets (x - sx, y - sy) (m) of points from a body's reference point at (sx, sy), taken along a
        repeating axis to the nearest image of the reference point: in [-L/2, L/2), L the grid's length."""
        g = self.grid
        out = []
        for value, s, wraps, length in ((x, sx, self.repeats[0], g.x1 - g.x0), (y, sy, self.repeats[1],
                                                                                 g.y1 - g.y0)):
            offset = np.asarray(value, dtype=float) - s
            out.append(offset - length * np.floor(offset / length + 0.5) if wraps else offset)
        return out[0], out[1]

    def wrapped(self, sx: float, sy: float) -> tuple[float, float]:
        """A position (m) moved by whole periods into the grid along its repeating axes (the same body to
        the solver: its offsets wrap around them)."""
        g = self.grid
        if self.repeats[0]:
            sx = g.x0 + (sx - g.x0) % (g.x1 - g.x0)
        if self.repeats[1]:
            sy = g.y0 + (sy - g.y0) % (g.y1 - g.y0)
        return float(sx), float(sy)

    def edge_points(self, x: np.ndarray, y: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """The grid's edge rows and columns along :attr:`edge_axes`, as broadcastable (x, y) pairs from the
        cell coordinates ``x`` (nx,) and ``y`` (ny,) (cell centres or their offsets)."""
        x, y = np.asarray(x), np.asarray(y)
        edges = {0: (x[[0, -1]][:, None], y[None, :]), 1: (x[:, None], y[[0, -1]][None, :])}
        return [edges[axis] for axis in self.edge_axes]

    def split_move(self, cells: tuple[int, int]) -> tuple[tuple[int, int], tuple[int, int]]:
        """A move of a field by ``cells`` split into the part rolled around the repeating axes and the part
        shifted along the others (cells leaving the grid lost, zeros entering)."""
        roll = (cells[0] * self.repeats[0], cells[1] * self.repeats[1])
        return roll, (cells[0] - roll[0], cells[1] - roll[1])

    def steady_velocity(self, value: np.ndarray) -> tuple[str, bool]:
        """A steady solve's rule for its constant velocity ``value`` ([vx, vy], m/s): (what is allowed, in
        words; whether ``value`` breaks it). Rolling: along X or Y."""
        return ('with [time] mode = "steady" it must be a constant non-zero [vx, 0] or [0, vy] (m/s)',
                np.count_nonzero(value) != 1)

    # -- the contact QP's window ----------------------------------------------------------------------
    def at_edge(self, box: tuple[int, int, int, int]) -> bool:
        """Whether a box of cells [i0, i1) x [j0, j1) touches the grid's edge where a window may not."""
        g = self.grid
        return box[0] == 0 or box[2] == 0 or box[1] == g.nx or box[3] == g.ny

    def window(self, box: tuple[int, int, int, int] | None, bulges: bool) -> tuple[int, int, int, int] | None:
        """The QP's window for the cells that can touch, whose bounding box (over all ranks) is ``box``
        (None: there are none): that box grown to fast FFT lengths. SolverError when it reaches the grid's
        edge. ``bulges``: the kernel lifts the surface around a load (a layer)."""
        if box is None:
            return None
        i0, i1, j0, j1 = box
        g = self.grid
        if self.at_edge(box):
            raise SolverError(
                f"[grid]: the contact region (cells where the body interferes with the surface, X in "
                f"[{g.x0 + i0 * g.dx:g}, {g.x0 + i1 * g.dx:g}], Y in [{g.y0 + j0 * g.dy:g}, "
                f"{g.y0 + j1 * g.dy:g}]) reaches the grid edge; enlarge [grid] x and y or reduce the "
                f"penetration or load")
        return self._fast(i0, i1, j0, j1)

    def _fast(self, i0: int, i1: int, j0: int, j1: int) -> tuple[int, int, int, int]:
        g = self.grid
        return (*fast_range(i0, i1, g.nx, real=False), *fast_range(j0, j1, g.ny, real=True))

    def gap_unit(self, largest: float, lowest: float) -> float:
        """w_ref (m), the QP's unit of gap, from the largest and the lowest interference over the window:
        the largest (contact is made at positive interference only)."""
        return max(largest, 0.0)

    def touches_edge(self, pressure: np.ndarray, r0: int) -> bool:
        """Whether a solved ``pressure`` (this rank's rows, from grid row ``r0``) loads a cell of an edge
        the contact must stay off after the solve (where the window could not keep it off)."""
        return False

    def edge_message(self) -> str:
        """What :meth:`touches_edge` found, as the one-line error."""
        raise NotImplementedError


class Windowed(Topology):
    """A 3-D half-space that does not repeat (module docstring)."""


class Line(Topology):
    """Line contact (plane strain) that does not repeat (module docstring)."""

    load_power = 1.0
    edge_axes = (0,)

    def at_edge(self, box) -> bool:
        return False  # the window may span the grid: only the solved contact must stay inside

    def window(self, box, bulges: bool):
        if box is None:
            return None
        grow, g = GROW if bulges else 0, self.grid
        i0, i1, j0, j1 = box
        return self._fast(max(i0 - grow, 0), min(i1 + grow, g.nx), max(j0 - grow, 0), min(j1 + grow, g.ny))

    def touches_edge(self, pressure, r0) -> bool:
        """In plane strain the rigid interference delta - Z - u exceeds J A p > 0 wherever A p is, and A p
        (logarithmic) spreads over the whole grid, so the interference region is wider than the contact
        (by about sqrt(ln(2 L/a) + 1/2) for Hertz, L the datum): the contact itself is what must fit."""
        ends = [i - r0 for i in (0, self.grid.nx - 1) if 0 <= i - r0 < len(pressure)]
        return bool(np.any(pressure[ends] > 0))

    def edge_message(self) -> str:
        g = self.grid
        return (f"[grid]: the contact reaches an end of the grid (X = {g.x0:g} or {g.x1:g}); "
                "enlarge [grid] x or reduce the load")


class Periodic(Topology):
    """A grid that repeats along every axis it has (module docstring)."""

    whole = True
    load_power = 1.0
    edge_axes = ()

    @property
    def repeats(self) -> tuple[bool, bool]:
        return (True, not self.grid.line)

    @property
    def statistics(self) -> bool:
        return not self.grid.line

    def steady_velocity(self, value):
        return 'with [time] mode = "steady" it must be a constant non-zero [vx, vy] (m/s)', not np.any(value)

    def at_edge(self, box) -> bool:
        return False

    def window(self, box, bulges: bool):
        return 0, self.grid.nx, 0, self.grid.ny

    def gap_unit(self, largest: float, lowest: float) -> float:
        """On a repeating grid contact can be made at negative interference: the interference's range (or
        |its largest value| for a flat one; 1 for none)."""
        spread = largest - lowest
        return spread if spread > 0 else abs(largest) or 1.0


class PeriodicAlong(Periodic):
    """A 3-D grid that repeats along ``axis`` (0: X, 1: Y) only (module docstring)."""

    statistics = False

    def __init__(self, grid, axis: int):
        super().__init__(grid)
        self.axis = axis
        self.edge_axes = (1 - axis,)

    @property
    def repeats(self) -> tuple[bool, bool]:
        return (self.axis == 0, self.axis == 1)

    def steady_velocity(self, value):
        a = self.axis
        return (f'with [time] mode = "steady" on a grid periodic along {"xy"[a]} only it must be a constant '
                f'non-zero {("[vx, 0]", "[0, vy]")[a]} (m/s)', value[a] == 0 or value[1 - a] != 0)

    def touches_edge(self, pressure, r0) -> bool:
        if self.axis == 1:  # the X ends
            ends = [i - r0 for i in (0, self.grid.nx - 1) if 0 <= i - r0 < len(pressure)]
            return bool(np.any(pressure[ends] > 0))
        return bool(np.any(pressure[:, [0, self.grid.ny - 1]] > 0))

    def edge_message(self) -> str:
        g = self.grid
        axis, (a, b) = ("x", (g.x0, g.x1)) if self.axis == 1 else ("y", (g.y0, g.y1))
        return (f"[grid]: the contact reaches the grid's edge along {axis} ({a:g} or {b:g}), which does not "
                f"repeat; enlarge [grid] {axis} or reduce the load")


def topology(grid) -> Topology:
    """The topology of ``grid`` (petroll.model.grid.Grid) from its ``line`` and ``periodic`` values."""
    along_x, along_y = grid.periodic
    if along_x and (along_y or grid.line):
        return Periodic(grid)
    if along_x or along_y:
        return PeriodicAlong(grid, 0 if along_x else 1)
    return Line(grid) if grid.line else Windowed(grid)


def fast_range(i0: int, i1: int, n: int, real: bool) -> tuple[int, int]:
    """[i0, i1) grown about its centre, within [0, n), to a length scipy.fft transforms fast (``real``: a
    real transform's), where one fits: the window's preconditioner transforms it unpadded. The QP stays
    exact on a larger box (its extra cells have no interference, so no pressure)."""
    m = i1 - i0
    length = scipy.fft.next_fast_len(m, real=real)
    if length > n:
        return i0, i1
    a = min(max(0, i0 - (length - m) // 2), n - length)
    return a, a + length
