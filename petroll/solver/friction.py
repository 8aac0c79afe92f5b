"""Friction's modes over the tangential problem of petroll.solver.tangential: the quasi-static shift
(Cattaneo), transient rolling (Kalker's instationary theory) and steady rolling solved directly.

Frames. petroll's grid is fixed to the half-space and the body moves (its reference point at s(t)). Kalker's
slip of two opposing material points is S = W + u - u' over a step (petroll.solver.tangential), u the
relative tangential displacement (body minus half-space) and u' the same points' one step earlier. The
half-space's points stay on their cells. The body's surface points in the contact move relative to the
half-space only by the rigid slip (their velocity there is the creepage times the rolling speed, Kalker's
linear theory neglects its transport of u), so in the grid's frame both bodies' material points stay on
their cells over a step and u' is the previous step's u on the same cell: a shift and transient rolling
are the same problem, step by step, with W the step's rigid slip at each cell and u' = c K q' from the
previous step's tractions q' (:class:`Stepping`). A body of the same material ([body] material = "same")
adds its compliance to c (quasi-identical bodies: no coupling with the normal problem).

Viscoelastic bodies (:class:`ShearMemory`): with a constant Poisson's ratio the shear creep function is the
normal one's shape, c(t) = J(t)/(1 - nu) (J the surface creep compliance (1 - nu^2) D(t), both bodies'), so
the tangential displacement is u = K s with s = integral c(t - t') dq(t'), the hereditary integral the
normal problem's integrators (petroll.solver.history) turn into s^(n+1) = c_eff q^(n+1) + v^(n+1), v from
the past tractions. A step's problem is then the elastic one with the compliance c_eff and the history's
displacement K v on its right-hand side: u' is replaced by u' - K v (u' = K s' from the sources s' of the
last steps; elastic: s = c q).

Steady rolling (:class:`SteadyRolling`) is stationary in the body's frame, where the material streams
backwards through the contact: with one cell rolled per step (the transient run's steps_per_cell = 1 on
square cells, as the normal problem's steady mode) the point now at cell i was at the cell ahead of it a
step earlier, so u'_i = u_{i+1} (i + 1 ahead along the motion; order 2: the second-order upwind
difference) and the steady tractions are those of the step's QP with u' read from their own displacement:
a nonsymmetric problem, solved by the semismooth Newton method of petroll.solver.steady_friction.

Rigid slip of a step at the cell centred at (x, y) in the body's frame (reference point at the origin),
rolling a distance dq along the motion: W = dq (xi - phi y_m, eta + phi x_m) with (x_m, y_m) the point's
mean position over the step (it moves from dq ahead to the cell; order 2: its position at the step's end),
creepages xi, eta (rigid slip velocity of the body relative to the half-space over the rolling speed) and
spin phi (1/m). A shift: W the body's rigid tangential displacement over the step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from petroll.errors import SolverError
from petroll.solver.steady_friction import SteadyNewton
from petroll.solver.tangential import TangentialSolution, TangentialSolver
from petroll.solver.wake import TangentialWake
from petroll.solver.warm import TractionWarmStart


def rigid_slip(x: np.ndarray, y: np.ndarray, creepage, spin: float, distance: float,
               direction=(0.0, 0.0)) -> np.ndarray:
    """The rigid slip of a step, W (m, shape (2,) + broadcast shape of x, y): distance x (xi - phi y_m,
    eta + phi x_m), (x_m, y_m) = (x, y) + distance/2 ``direction`` (the unit vector from which the material
    arrives: ahead of the cell along the motion in the body's frame) relative to the spin centre, at (x, y)
    (m) relative to it. ``creepage`` (xi, eta) dimensionless, ``spin`` 1/m, ``distance`` m."""
    xm = np.asarray(x, dtype=float) + 0.5 * distance * direction[0]
    ym = np.asarray(y, dtype=float) + 0.5 * distance * direction[1]
    xm, ym = np.broadcast_arrays(xm, ym)
    return distance * np.stack([creepage[0] - spin * ym, creepage[1] + spin * xm])


def cattaneo_mindlin(bound: np.ndarray, force, cell_area: float, comm: MPI.Comm) -> np.ndarray:
    """A first guess of the tractions (Pa, (m, rows, ny)) that carry the tangential ``force`` (N, an
    m-vector) on the traction bound ``bound`` g = mu p (Pa, this rank's rows) from rest: Cattaneo and
    Mindlin's, q = F/|F| (g - g*) (sum q dA = F), g* the bound of the contact at a smaller load (what the
    normal problem's start from Hertz's pressure is to it). For a Hertz pressure g^2 is quadratic in
    the position, and the smaller contact's g*^2 = g^2 - (1 - k^2) g0^2 (g0 the largest bound, k the stick
    zone's size over the contact's: (1 - |F|/(mu P))^(1/3), line contact ^(1/2)); any other pressure takes
    the same formula as a guess."""
    force = np.asarray(force, dtype=float).reshape(-1)
    sums = np.array([float(bound.sum()), float(bound.max(initial=0.0))])
    capacity, g0 = comm.allreduce(sums[0]) * cell_area, comm.allreduce(sums[1], op=MPI.MAX)
    size = float(np.hypot.reduce(force))
    if not (size > 0 and capacity > 0):
        return np.zeros((len(force), *bound.shape))
    k = max(1.0 - size / capacity, 0.0) ** (1 / (len(force) + 1))
    inner = np.sqrt(np.clip(bound * bound - (1 - k * k) * g0 * g0, 0.0, None))
    return (force / size)[:, None, None] * (bound - inner)


class ShearMemory:
    """The tangential creep function's hereditary history (module docstring): a normal-problem ``history``
    (petroll.solver.history, on fields of shape (m, rows, ny): its integrators act cell by cell) of the
    scene's surface creep compliance J(t), fed with the tractions times ``factor`` = 1/(1 - nu), so that
    its effective compliance and preceding field are c_eff (1/Pa) and v (m/m: u = K v) of the tangential
    displacement."""

    def __init__(self, history, factor: float):
        self.history, self.factor = history, factor

    def compliance(self, dt: float) -> float:
        """c_eff (1/Pa) of the next step, of length dt (s; 0: a jump, the instantaneous J(0))."""
        return self.factor * self.history.compliance(dt)

    def preceding(self, dt: float) -> np.ndarray | None:
        """v (u = K v) of the next step (None: no memory yet)."""
        return self.history.preceding(dt)

    def advance(self, traction: np.ndarray, dt: float) -> None:
        """Take the solved tractions (Pa) of the step of length dt into the history."""
        self.history.advance(self.factor * traction, dt)


class Stepping:
    """Shift and transient rolling step by step in the grid's frame (module docstring), with the tangential
    ``solver``: the tractions of the last steps kept (this rank's rows), u' = c K q' left to the QP's
    gradient (elastic; viscoelastic: u' computed on the box of the new contact and the sources). Each
    step starts from the tractions of the last steps carried along with the body (``warm``,
    petroll.solver.warm.TractionWarmStart: at k steps per cell, those k, 2k and 3k steps back, extrapolated
    in the body's and the material's frame); a shift from rest under force control from Cattaneo and
    Mindlin's (:func:`cattaneo_mindlin`).

    :meth:`shift`: a quasi-static step (rate-independent: first order, u' = the last step's u), the
    body's rigid tangential displacement changed by ``increment`` or found from the force; ``shift``
    accumulates it (m). :meth:`roll`: a rolling step; with ``order`` 2 (default) and a previous rolling
    step, the slip rate is the second-order backward difference at the step's end (BDF2, variable steps:
    du/dt = [a0 u^n - a1 u^(n-1) + a2 u^(n-2)]/dt, a0 = (1 + 2 r)/(1 + r), a1 = 1 + r, a2 = r^2/(1 + r),
    r = dt_n/dt_(n-1)), written as the QP's form (dt/a0) w + u - (a1 u' - a2 u'')/a0 with the rigid slip
    w taken at the step's end; first order otherwise (the slip of the step, w at the step's mean
    position). A rolling run with one cell per step converges to :class:`SteadyRolling` of the same
    order.

    ``memory``: a viscoelastic material's :class:`ShearMemory` (None: elastic, c the solver's): each step
    then takes its compliance and history displacement from it at the step's length ``dt`` (s), and the
    displacement sources s of the last two steps (u = K s) are kept beside the tractions. Their field spans
    the track rolled so far (the material relaxes behind the body): ``wake`` (a
    petroll.solver.wake.TangentialWake) computes its displacement on the box of the contact and of the
    sources above the history cut-off, so that a step's cost stops growing with the track (None: on every
    non-zero cell)."""

    def __init__(self, solver: TangentialSolver, order: int = 2, memory: ShearMemory | None = None,
                 wake: TangentialWake | None = None):
        if order not in (1, 2):
            raise ValueError(f"order {order}: 1 or 2")
        self.solver, self.order, self.memory, self.wake = solver, order, memory, wake
        self.traction = solver.zeros()  # q^(n-1), Pa
        self.older = None  # q^(n-2) when the last step was a rolling one (with its distance)
        self.source = solver.zeros() if memory is not None else None  # viscoelastic: s^(n-1), u = K s (m)
        self.source_older = None  # s^(n-2) beside ``older``
        self.last_distance = None
        self.shift_total = np.zeros(solver.m)  # the body's rigid tangential displacement of the shifts, m
        self.creepage = np.zeros(solver.m)  # the last rolling step's (given or found)
        self.scale = 0.0  # the last rolling step's rolled distance in the QP's form (m): its slip is the
        # slip velocity over the rolling speed times it (order 2: distance/a0)
        self.warm = TractionWarmStart(solver.grid, solver.rows, solver.comm)  # the steps' first guesses

    def _previous(self, bound: np.ndarray, weights=(1.0, 0.0), dt: float = 0.0):
        """(u' (m, this rank's rows) or None, its source X or None, the step's compliance c (1/Pa; None: the
        solver's), the history's v or None) of a step of length ``dt`` (s), from w0 X^(n-1) - w1 X^(n-2)
        (``weights``; w1 = 0: X^(n-1) alone), X the last steps' tractions (elastic: u' = c K X, left to the
        QP's gradient) or displacement sources (viscoelastic: u' = K (X - v), the history's displacement
        moved to the right-hand side, computed here on the box of the new contact and of the field: the
        history reaches along the wake, cut off by ``wake``)."""
        newer, older = (self.traction, self.older) if self.memory is None else (self.source, self.source_older)
        field = newer if weights[1] == 0 else weights[0] * newer - weights[1] * older
        if self.memory is None:
            return None, field, None, None
        compliance, v = self.memory.compliance(dt), self.memory.preceding(dt)
        if v is not None:
            field = field - v
        if self.wake is not None:
            return self.wake.displacement(field, bound), None, compliance, v
        cells = (bound > 0) | np.any(field != 0, axis=0)
        return self.solver.displacement(field, self.solver.box(cells), 1.0), None, compliance, v

    def _remember(self, solution: TangentialSolution, compliance, v, dt: float, rolled: bool) -> None:
        """Keep a viscoelastic step's sources (s = c q + v) and advance the history by the step."""
        if self.memory is None:
            return
        source = compliance * solution.traction + (0.0 if v is None else v)
        self.source_older = self.source if rolled else None
        self.source = source
        self.memory.advance(solution.traction, dt)

    def shift(self, bound: np.ndarray, increment=None, force=None, tol: float | None = None,
              dt: float = 0.0, centre=(0.0, 0.0)) -> TangentialSolution:
        """One quasi-static step on the traction bound ``bound`` (Pa, this rank's rows): the body shifted by
        ``increment`` (m, an m-vector) relative to the half-space, or by the amount that makes the total
        traction ``force`` (N; N/m in line contact; the force the half-space exerts on the body: it
        opposes the shift); ``dt`` the step's length (s; a viscoelastic history's step, 0: a jump);
        ``centre`` the body's reference point (m; where the first guesses of later steps are carried
        from)."""
        solver = self.solver
        previous, earlier, compliance, v = self._previous(bound, dt=dt)
        rigid = None
        if force is None:
            increment = np.zeros(solver.m) if increment is None else np.asarray(increment, dtype=float)
            rigid = np.broadcast_to(increment[:, None, None], (solver.m, *solver.local_shape))
        warm = self.warm.guess(*centre, bound)
        if warm is None and force is not None:  # from rest
            warm = cattaneo_mindlin(bound, force, solver.grid.cell_area, solver.comm)
        solution = solver.solve(bound, rigid, previous, warm, force, tol, compliance, earlier)
        self.warm.record(solution.traction, *centre)
        self._remember(solution, compliance, v, dt, rolled=False)
        self.shift_total = self.shift_total + (solution.shift if force is not None else increment)
        self.traction, self.older, self.last_distance = solution.traction, None, None
        return solution

    def roll(self, bound: np.ndarray, centre, distance: float, direction, creepage=(0.0, 0.0),
             spin: float = 0.0, force=None, tol: float | None = None, dt: float = 0.0) -> TangentialSolution:
        """One rolling step on the traction bound ``bound`` (Pa, this rank's rows): the body's reference
        point now at ``centre`` (m), having rolled ``distance`` (m) > 0 along the unit vector ``direction``
        over the step, at the creepage (xi, eta) and spin phi (1/m), or at the tangential ``force`` (N),
        the creepage then found (``creepage`` attribute; the spin given); ``dt`` the step's length (s; a
        viscoelastic history's step). Returns the step's solution (its
        ``slip``: the slip of the step, m; ``shift``: the uniform slip found under force control)."""
        solver, grid = self.solver, self.solver.grid
        x = grid.x[solver.r0 : solver.r1, None] - centre[0]
        y = grid.y[None, :] - centre[1]
        given = (0.0, 0.0) if force is not None else creepage
        if self.order == 2 and self.older is not None:
            r = distance / self.last_distance
            a0, a1, a2 = (1 + 2 * r) / (1 + r), 1 + r, r * r / (1 + r)
            weights = (a1 / a0, a2 / a0)
            rigid = rigid_slip(x, y, given, spin, distance / a0)[: solver.m]
            scale = distance / a0
        else:  # first order: relative to the body the point moved from distance x direction ahead
            weights = (1.0, 0.0)
            rigid = rigid_slip(x, y, given, spin, distance, direction)[: solver.m]
            scale = distance
        if self.last_distance is None:  # after a shift: its trend is not the rolling's
            self.warm.forget()
        previous, earlier, compliance, v = self._previous(bound, weights, dt)
        solution = solver.solve(bound, rigid, previous, self.warm.guess(*centre, bound), force, tol, compliance,
                                earlier)
        self.warm.record(solution.traction, *centre)
        self._remember(solution, compliance, v, dt, rolled=True)
        self.creepage = (np.asarray(creepage, dtype=float)[: solver.m] if force is None
                         else solution.shift / scale)
        self.older, self.traction, self.last_distance = self.traction, solution.traction, distance
        self.scale = scale
        return solution


@dataclass
class SteadySolution:
    """Steady rolling with friction: the tractions as a tangential solution (``solution``: its ``slip`` is
    the slip per unit rolled distance, i.e. the slip velocity over the rolling speed, Kalker's relative
    slip; ``shift`` the uniform part of it found under force control), the creepage (xi, eta) in force
    (given, or found), Newton's iterations and the operator applications (window-sized FFT convolutions,
    line searches and GMRES included)."""

    solution: TangentialSolution
    creepage: np.ndarray
    iterations: int
    applications: int


class SteadyRolling:
    """Steady rolling with Coulomb friction solved directly (module docstring; the method in
    petroll.solver.steady_friction), with the tangential ``solver`` (its grid is the body's frame, the
    body's reference point at ``centre``), the body moving along ``axis`` (0: X, 1: Y) with ``sign`` +1
    (towards increasing index) or -1, the slip's difference along the motion of ``order`` 1 or 2."""

    def __init__(self, solver: TangentialSolver, axis: int, sign: int, order: int = 2):
        if axis not in (0, 1) or sign not in (1, -1) or order not in (1, 2):
            raise ValueError(f"motion along axis {axis} with sign {sign}, order {order}")
        grid = solver.grid
        if grid.line and axis != 0:
            raise ValueError("line contact rolls along X")
        self.solver, self.axis, self.sign, self.order = solver, axis, sign, order
        self.comm = solver.comm
        self.cell = grid.dx if axis == 0 else grid.dy
        # order 2's difference (3 u_t - 4 u_{t+1} + u_{t+2})/2 is written as (3/2)(W' + u - S_2 u): the
        # QP's rigid slip W' = 2/3 W, taken at the cell itself; order 1's at the mean position over the step
        self.distance = self.cell if order == 1 else 2.0 * self.cell / 3.0
        self.applications = 0

    def rigid(self, creepage, spin: float, centre) -> np.ndarray:
        """The rigid slip of a step in the QP's form (m, rows, ny) on this rank's grid rows (module
        docstring; order 2: W' = 2 W/3 at the cell)."""
        solver, grid = self.solver, self.solver.grid
        x = grid.x[solver.r0 : solver.r1, None] - centre[0]
        y = grid.y[None, :] - centre[1]
        ahead = (0.0, 0.0)
        if self.order == 1:
            ahead = (self.sign, 0.0) if self.axis == 0 else (0.0, self.sign)
        return rigid_slip(x, y, creepage, spin, self.distance, ahead)[: solver.m]

    def solve(self, bound: np.ndarray, creepage=(0.0, 0.0), spin: float = 0.0, centre=(0.0, 0.0),
              force: np.ndarray | None = None, start: np.ndarray | None = None,
              tol: float | None = None, memory=None) -> SteadySolution:
        """The steady tractions on the traction bound ``bound`` (Pa, this rank's grid rows) at the creepage
        (xi, eta) and the spin phi (1/m) about ``centre`` (m; the body's reference point), or at the
        tangential force ``force`` (N; N/m in line contact; an m-vector), the creepage then found (the spin
        given). ``start``: a first guess (Pa, (m, rows, ny)); ``tol``: the natural residual's tolerance
        (default the solver's). ``memory``: a viscoelastic material's tangential state machine (h0 (1/Pa),
        s1, M, c) at one cell per step (petroll.solver.history.state_space of the creep function c(t));
        the window then reaches the grid's edge behind the contact (the wake; beyond it is left out)."""
        solver = self.solver
        m, tol = solver.m, solver.tol if tol is None else tol
        box = solver.box(bound > 0)
        if box is None:
            raise SolverError("steady rolling with friction: no contact")
        elastic = memory is None or memory[1] is None
        problem = solver.scaled(bound, self._behind(box, None if elastic else solver.grid),
                                None if elastic else memory[0])
        box, g, q_ref, s_ref = problem.box, problem.g, problem.q_ref, problem.s_ref
        total = None
        if force is not None:
            total = solver.scaled_force(force, problem)
            creepage = (0.0, 0.0)
        b = solver.to_box(self.rigid(creepage, spin, centre), box) / s_ref
        newton = SteadyNewton(problem.apply, problem.precondition, g / q_ref, b, self.comm, problem.nx,
                              self.axis, self.sign, self.order, total, None if elastic else memory)
        q0 = None if start is None else solver.to_box(start, box) / q_ref
        at, iterations = newton.solve(q0, np.zeros(m), tol)
        self.applications += newton.applications
        q = at.q * q_ref
        slip = at.s * s_ref / self.distance  # per unit rolled distance (W' + u - S u over 2/3 dq)
        found = (np.asarray(creepage, dtype=float)[:m] if force is None else at.w * s_ref / self.distance)
        stick = (g > 0) & (np.sqrt((q * q).sum(axis=0)) < g - tol * q_ref)
        sums = np.array(q.sum(axis=(1, 2)), dtype=float)
        self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        solution = TangentialSolution(solver.from_box(q, box), solver.from_box(slip, box),
                                      solver.from_box(stick, box, False), at.w * s_ref, sums * solver.grid.cell_area,
                                      iterations, newton.applications, at.largest, box)
        return SteadySolution(solution, found, iterations, newton.applications)

    def _behind(self, box, wake=None):
        """``box`` grown by ``order`` cells behind it along the motion: the shifted tractions S_k q of
        H (q - S_k q) reach that far behind the contact (SolverError at the grid's edge); with ``wake``
        (the grid: a viscoelastic material's), to the grid's edge behind it."""
        i0, i1, j0, j1 = box
        g, k = self.solver.grid, self.order
        if wake is not None:
            k = max(k, (i0 if self.sign > 0 else g.nx - i1) if self.axis == 0 else (j0 if self.sign > 0 else g.ny - j1))
        if self.axis == 0:
            i0, i1 = (i0 - k, i1) if self.sign > 0 else (i0, i1 + k)
        else:
            j0, j1 = (j0 - k, j1) if self.sign > 0 else (j0, j1 + k)
        if i0 < 0 or j0 < 0 or i1 > g.nx or j1 > g.ny:
            raise SolverError("[grid]: the contact reaches the grid's edge behind the motion; enlarge [grid] x "
                              "and y")
        return i0, i1, j0, j1
