"""One contact step: the bound-constrained QP of formulation §3, solved by TAO on the contact window.

Given the known height h = Z + u of every cell (body profile plus preceding displacement, m, positive into
the half-space) and the effective compliance J (1/Pa), the pressure p >= 0 (Pa) minimises

    1/2 p^T (J A) p - p^T (delta - h)        (A: Love's coefficients, cell area folded in)

whose optimality conditions are the contact conditions p >= 0, gap = J A p + h - delta >= 0, p gap = 0.
Only cells of positive rigid interference delta - h can carry pressure (A > 0), so the QP is posed on the
bounding box of those cells (the *window*), exactly. It is solved in scaled variables,
p = p_hat w_ref / (J A_00) with w_ref the largest interference, so that the Hessian A / A_00 has a unit
diagonal and the scaled gap is O(1) whatever the units: ``tol`` is a relative tolerance on the contact
conditions, max |min(p_hat, gap / w_ref)| <= tol, checked after every solve. The pressure's relative L2
error is then 0.4-4 times tol (measured against solves to 1e-12, 64^2-2048^2). ``pressure_tol`` (optional)
bounds that error instead: each QP is solved to the residual tolerance pressure_tol, its error estimated
with the preconditioner (petroll.solver.petsc.WindowQP.error_estimate, 1.2-1.7 times the true one), and
solved on from its answer with the residual tolerance scaled down until the estimate is <= pressure_tol.

Load control (a total force F instead of delta): with ``pk``, inside the QP (Polonsky & Keer's
force-controlled form: sum p = F / cell area held, delta from the constraint's multiplier); with TAO's own
types, by a safeguarded secant iteration on (F(delta) / F)^(2/3) - 1, which is linear in delta for a
Hertzian contact (on F(delta) / F - 1 for line contact, where delta = (2 J F/pi) (ln(2 L/a) + 1/2) is
nearly linear in F; L the grid's datum).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from petroll.errors import SolverError
from petroll.model.grid import Grid
from petroll.model.tao import DEFAULT_TAO_TYPE
from petroll.solver.partition import RowPartition, move_rows
from petroll.solver.influence import InfluenceOperator, influence_operator, spare_cores
from petroll.solver.petsc import WindowQP, contact_options

@dataclass
class StepSolution:
    """A solved contact step. ``pressure`` holds this rank's grid rows (Pa); the rest are global values."""

    pressure: np.ndarray
    delta: float  # penetration, m
    force: float  # total normal force, N
    iterations: int  # TAO iterations, summed over the QPs of a load-control step
    applications: int  # influence-operator applications (Hessian mults and gradient evaluations)
    residual: float  # max |min(p_hat, gap_hat)|, the scaled contact-condition residual
    window: tuple[int, int, int, int]  # cells [i0, i1) x [j0, j1) on which the QP was posed


class BeyondReach(Exception):
    """Load control needs a penetration beyond the ``reach`` its heights were computed for (not an error:
    the caller recomputes the heights for any penetration and solves again)."""


class ContactSolver:
    """Solves contact steps on ``grid`` (rows split over ``comm``) with TAO, options prefix ``prefix``.

    Command-line options with that prefix (``-petroll_tao_type tron``, ``-petroll_tao_monitor``, ...)
    override the scene's settings; they never reach other solvers. ``-<prefix>fft_workers N``: FFT threads
    per rank (default: the rank's share of its node's cores, :func:`petroll.solver.influence.spare_cores`).
    ``kernel``: the influence kernel (petroll/solver/kernels) instead of the grid's (a half-space's or
    ``layer``'s).
    """

    def __init__(self, grid: Grid, comm: MPI.Comm, tao_type: str = DEFAULT_TAO_TYPE, tol: float = 1e-8,
                 prefix: str = "petroll_", max_iterations: int = 10000, precondition: bool = True,
                 layer=None, kernel=None, pressure_tol: float | None = None):
        self.grid, self.comm, self.tol, self.prefix = grid, comm, tol, prefix
        self.pressure_tol = pressure_tol
        # read once here and when a window shape's TAO is built
        self.tao_type, self.precondition, self.workers = contact_options(prefix, tao_type, precondition,
                                                                         spare_cores(comm))
        self.max_iterations = max_iterations
        if self.workers < 1:
            raise SolverError(f"-{prefix}fft_workers {self.workers}: the FFT threads per rank must be >= 1")
        self.influence = (influence_operator(grid, comm, layer, self.workers) if kernel is None else
                          InfluenceOperator(kernel, comm, self.workers))
        self.topology = grid.topology  # the window, its edges, the gap's unit (petroll.model.topology)
        # upward displacement per unit pressure (a QP on the whole grid has no ring to check)
        self.lift = None if self.topology.whole else self.influence.lift_bound(grid.nx, grid.ny)
        self.rows = RowPartition(grid.nx, comm.size)
        self.r0, self.r1 = self.rows.range(comm.rank)
        self.work = [0, 0]  # TAO iterations and operator applications of every QP solved so far
        self._qps: dict[tuple[int, int], WindowQP] = {}

    NO_SURFACE_GAP = 1e3
    """The gap (in units of the largest interference) given in the QP to a window cell where the body has no
    surface (Z = +inf): far more than any displacement can close, so its pressure stays 0."""

    MARGIN = 4
    """Width in cells of the ring around a layer's QP window on which the gap is checked (_solve_qp)."""

    kept = 6
    """Window shapes whose TAO, shell matrix and vectors are kept (the most recently used)."""

    @property
    def local_shape(self) -> tuple[int, int]:
        return (self.r1 - self.r0, self.grid.ny)

    def own_rows(self, field) -> np.ndarray:
        """This rank's grid rows of a ``field`` given on the whole grid (nx x ny values) or as these rows."""
        rows = np.asarray(field, dtype=float).reshape(-1, self.grid.ny)
        return rows[self.r0 : self.r1] if len(rows) == self.grid.nx else rows

    # -- displacement control ---------------------------------------------------------------------------
    def solve_penetration(self, height: np.ndarray, compliance: float, delta: float,
                          warm: np.ndarray | None = None) -> StepSolution:
        """Pressure for a given penetration ``delta`` (m); ``height`` is h = Z + u on this rank's rows (m).
        On a periodic half-space (displacements from the deformed surface's mean plane) the mean gap
        mean(h) - delta must be > 0 (SolverError otherwise: the pressure would grow without bound)."""
        if self.influence.mean_free:
            mean = self.comm.allreduce(float(height.sum())) / (self.grid.nx * self.grid.ny)
            if not delta < mean:
                raise SolverError(f"[motion] penetration: {delta:g} m leaves no mean gap on the periodic "
                                  f"grid (the surface's mean height is {mean:g} m above its lowest point): "
                                  "a penetration must be below it; full contact needs [motion] load")
        pressure, its, apps, residual, window, _ = self._solve_qp(delta, height, compliance, warm)
        self._check_inside(pressure)
        force = self.comm.allreduce(float(pressure.sum())) * self.grid.cell_area
        return StepSolution(pressure, delta, force, its, apps, residual, window)

    # -- load control -----------------------------------------------------------------------------------
    def solve_load(self, height: np.ndarray, compliance: float, load: float, radius_hint: float,
                   delta_guess: float | None = None, warm: np.ndarray | None = None,
                   reach: float = math.inf) -> StepSolution:
        """Pressure and penetration for a total normal force ``load`` (N) > 0.

        The first guess is ``delta_guess`` or, without one, Hertz's penetration for a sphere (line contact:
        a cylinder) of radius ``radius_hint`` above the lowest height. Line contact: ``load`` in N/m.
        ``height`` need only be right for penetrations up to ``reach`` (m): no penetration beyond it is
        tried, and :class:`BeyondReach` is raised when the force at ``reach`` is still below the load (the
        force grows with the penetration).
        """
        base = self.comm.allreduce(float(np.min(height, initial=np.inf)), op=MPI.MIN)
        if not load > 0:  # no load: no contact, the body just touches (a pulling load needs adhesion)
            if not load == 0:
                raise SolverError(f"[motion] load: {load:g} N; must be >= 0 (a pulling load needs adhesion, "
                                  "which petroll does not model)")
            return StepSolution(np.zeros(self.local_shape), base, 0.0, 0, 0, 0.0, (0, 0, 0, 0))
        ceiling = math.inf  # a periodic half-space's force grows without bound as delta -> mean(h)
        if self.influence.mean_free:
            ceiling = self.comm.allreduce(float(height.sum())) / (self.grid.nx * self.grid.ny)
        if delta_guess is None or delta_guess <= base:
            delta_guess = base + hertz_penetration(self.grid, compliance, load, radius_hint)
        delta_guess = self._off_the_edge(height, base, min(delta_guess, 0.5 * (base + ceiling)))
        if self.tao_type == "pk":
            if not reach > base:
                raise BeyondReach(f"the load {load:g} N needs a penetration beyond {reach:g} m")
            if warm is None and not self.topology.whole:  # a periodic grid's: made where the QP is posed
                warm = self.hertz_pressure(height, compliance, load, radius_hint, min(delta_guess, reach))
            return self._load_in_pk(height, compliance, load, min(delta_guess, reach), warm, reach)
        power = self.topology.load_power
        rtol = 10 * self.tol
        iterations = applications = 0
        lo = hi = None  # bracketing (delta, phi) pairs with phi < 0 and phi > 0
        previous = None
        delta = min(delta_guess, reach)
        for _ in range(60):
            step = self.solve_penetration(height, compliance, delta, warm)
            iterations += step.iterations
            applications += step.applications
            step.iterations, step.applications = iterations, applications
            if abs(step.force / load - 1) <= rtol:
                self._check_inside(step.pressure)
                return step
            warm = step.pressure
            phi = (step.force / load) ** power - 1
            if phi < 0:
                lo = (delta, phi)
            else:
                hi = (delta, phi)
            if step.force == 0:
                candidate = base + 2 * (delta - base)
            elif previous is None or previous[1] == phi:
                candidate = base + (delta - base) / (1 + phi)  # Hertz scaling F ~ (delta - base)^(1/power)
            else:
                candidate = delta - phi * (delta - previous[0]) / (phi - previous[1])
            if lo is not None and hi is not None and not (lo[0] < candidate < hi[0]):
                candidate = 0.5 * (lo[0] + hi[0])
            if candidate >= ceiling:
                candidate = 0.5 * (delta + ceiling)
            if candidate > reach:
                if delta >= reach:
                    raise BeyondReach(f"the load {load:g} N needs a penetration beyond {reach:g} m")
                candidate = reach
            previous = (delta, phi)
            delta = candidate
        raise SolverError(f"load control did not reach the load {load:g} N within 60 penetrations "
                          f"(last force {step.force:g} N); check the scene's load and body")

    def _off_the_edge(self, height: np.ndarray, base: float, delta: float) -> float:
        """The penetration guess ``delta`` (m), halved towards the lowest height ``base`` until the cells it
        interferes with stay off the grid's edge: a guess from the body's radius hint overshoots where the
        surface is not the sphere it hints at (a textured or rough map), and only the contact found must
        fit on the grid (a QP on the whole grid has no edge to reach)."""
        for _ in range(60):
            box = self._box(delta - height > 0)
            if box is None or not self.topology.at_edge(box):
                break
            delta = base + 0.5 * (delta - base)
        return delta

    def hertz_pressure(self, height: np.ndarray, compliance: float, load: float, radius: float,
                        delta: float) -> np.ndarray:
        """Hertz's pressure (Pa) for ``load`` on a sphere (line contact: a cylinder, N/m) of ``radius`` (m)
        centred on the centroid of the interference delta - height > 0 (m): a cold start for load control
        (this rank's rows; symmetric where the body is). On a QP over the whole grid (a repeating one):
        :meth:`summits_pressure`."""
        g = self.grid
        if self.topology.whole:
            return self.summits_pressure(height, load)
        w = np.maximum(delta - height, 0.0)
        sums = np.array([w.sum(), (w.sum(axis=1) * g.x[self.r0 : self.r1]).sum(), (w.sum(axis=0) * g.y).sum()])
        self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        centre = sums[1:] / sums[0]
        x = g.x[self.r0 : self.r1, None] - centre[0]
        if g.line:
            a = math.sqrt(4 * load * radius * compliance / math.pi)
            r2 = np.broadcast_to(x**2, self.local_shape)
            p0 = 2 * load / (math.pi * a)
        else:
            a = (3 * load * radius * compliance / 4) ** (1 / 3)
            r2 = x**2 + (g.y[None, :] - centre[1]) ** 2
            p0 = 3 * load / (2 * math.pi * a * a)
        return p0 * np.sqrt(np.clip(1 - r2 / (a * a), 0.0, None))

    SUMMITS = 0.05
    """The fraction of a periodic grid's cells a cold start under load control loads (:meth:`summits_pressure`)."""

    def summits_pressure(self, height: np.ndarray, load: float) -> np.ndarray:
        """A cold start for load control on a periodic grid (Pa, this rank's rows): the interference
        d - height over the SUMMITS fraction of the cells that stand highest (d found by bisection on that
        count), scaled to ``load`` (N). Measured on rough surfaces at 512^2: the first QP takes 5x fewer
        applications than from a uniform pressure, whose every cell must leave the contact."""
        g, comm = self.grid, self.comm
        extremes = np.array([-height.min(initial=np.inf), height.max(initial=-np.inf)])
        comm.Allreduce(MPI.IN_PLACE, extremes, op=MPI.MAX)
        lo, hi = -extremes[0], extremes[1]
        target = self.SUMMITS * g.nx * g.ny
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if comm.allreduce(int(np.count_nonzero(height < mid))) < target:
                lo = mid
            else:
                hi = mid
        w = np.maximum(hi - height, 0.0)
        total = comm.allreduce(float(w.sum()))
        return w * (load / (g.cell_area * total)) if total > 0 else np.full(w.shape, load / (g.cell_area * g.nx * g.ny))

    def _load_in_pk(self, height: np.ndarray, compliance: float, load: float, delta: float,
                    warm: np.ndarray | None, reach: float) -> StepSolution:
        """Load control inside pk: the force held in the QP (pk's ``total``), the penetration found from the
        constraint's multiplier. The QP is posed on the window of the interference at the guess ``delta``;
        where the penetration found interferes beyond that window, it is solved again on the larger one,
        from the solution (both solves' work counted). BeyondReach as :meth:`solve_load`."""
        iterations = applications = 0
        for _ in range(20):
            pressure, its, apps, residual, window, change = self._solve_qp(delta, height, compliance, warm, load)
            iterations += its
            applications += apps
            found = delta + change
            if found > reach:
                raise BeyondReach(f"the load {load:g} N needs a penetration beyond {reach:g} m")
            needed = self._box(found - height > 0)
            if needed is None or (window[0] <= needed[0] and needed[1] <= window[1] and window[2] <= needed[2]
                                  and needed[3] <= window[3]):
                force = self.comm.allreduce(float(pressure.sum())) * self.grid.cell_area
                self._check_inside(pressure)
                return StepSolution(pressure, found, force, iterations, applications, residual, window)
            # a window too small concentrates the pressure: the penetration found overshoots; halve the
            # step while its interference would reach the grid's edge
            for _ in range(30):
                if not self.topology.at_edge(self._box(found - height > 0)):
                    break
                found = 0.5 * (delta + found)
            delta, warm = found, pressure
        raise SolverError(f"load control did not settle its contact window within 20 solves (load {load:g} N); "
                          "check the scene's load and body")

    # -- the QP -----------------------------------------------------------------------------------------
    def _solve_qp(self, delta: float, height: np.ndarray, compliance: float, warm: np.ndarray | None,
                  load: float | None = None):
        """The QP on the window of the cells that can touch (the interference delta - ``height``, m; on a
        periodic grid made only while the QP is posed, 8 bytes per cell less while it is solved); ``load``
        (N, pk only): the force held, the penetration found with the pressure. Returns the pressure, TAO's
        iterations, the applications, the residual, the window and the penetration's change (m; 0 without
        load).

        With all coefficients positive the cells that can touch are those of positive interference
        (exact). A layer's surface bulges up around a load, so cells beyond them can touch too: the window
        then also covers the warm start's contact, and after each solve the gap is checked on a ring of
        ``MARGIN`` cells around the window (:meth:`_touching`); cells found touching (gap below -tol of the
        largest interference) join the window and the QP is solved again, until the ring is clear. (A cell
        beyond a clear ring touching would need the bulge to rise faster than the body's profile away from
        the contact; the thin incompressible layer's contact, 41 % wider than the interference region, is
        found this way: tests/test_layer.py.)"""
        if self.topology.whole:  # a cell without surface (petroll check refuses them) has no gap
            if not self.comm.allreduce(bool(np.isfinite(delta) and np.isfinite(height).all()), op=MPI.LAND):
                raise SolverError("the body has no surface (Z = +inf) over some cells of the periodic grid: give "
                                  "it a surface over the whole grid, or set [grid] periodic = false")
            return self._solve_window(delta, height, compliance, warm, None, load)
        interference = delta - height
        candidates = interference > 0
        if (not self.influence.positive and warm is not None
                and self.comm.allreduce(bool(candidates.any()), op=MPI.LOR)):
            candidates |= warm > 0
        its = applications = 0
        while True:
            pressure, n, apps, residual, window, change = self._solve_window(delta, height, compliance, warm,
                                                                             candidates, load)
            its, applications = its + n, applications + apps
            if self.influence.positive or window == (0, 0, 0, 0):
                return pressure, its, applications, residual, window, change
            touching = self._touching(pressure, interference + change, compliance, window)
            if not self.comm.allreduce(bool(touching.any()), op=MPI.LOR):
                return pressure, its, applications, residual, window, change
            candidates = candidates | touching
            warm = pressure

    def _touching(self, pressure: np.ndarray, interference: np.ndarray, compliance: float,
                  window: tuple[int, int, int, int]) -> np.ndarray:
        """Cells outside ``window`` but within ``MARGIN`` cells of it whose gap J A p - interference is
        below -tol times the largest interference (this rank's rows; booleans). Nothing is computed when
        the surface's largest possible lift, J max(p) ``lift``, cannot close the ring's gaps; A p on the
        ring by :meth:`_ring_displacement`."""
        g, m = self.grid, self.MARGIN
        i0, i1, j0, j1 = window
        box = (max(i0 - m, 0), min(i1 + m, g.nx), max(j0 - m, 0), min(j1 + m, g.ny))
        ring = np.zeros(self.local_shape, dtype=bool)
        rows = slice(max(box[0], self.r0) - self.r0, max(min(box[1], self.r1), self.r0) - self.r0)
        ring[rows, box[2]:box[3]] = True
        rows = slice(max(i0, self.r0) - self.r0, max(min(i1, self.r1), self.r0) - self.r0)
        ring[rows, j0:j1] = False
        extremes = np.array([interference.max(initial=0.0), np.max(interference, where=ring, initial=-np.inf),
                             pressure.max(initial=0.0)])
        self.comm.Allreduce(MPI.IN_PLACE, extremes, op=MPI.MAX)
        w_ref, closest, p_max = extremes
        if closest + compliance * p_max * self.lift < -self.tol * w_ref:
            return np.zeros(self.local_shape, dtype=bool)
        gap = compliance * self._ring_displacement(pressure, box, ring) - interference
        return ring & (gap < -self.tol * w_ref)

    DIRECT = 4096
    """Largest (ring cells) x (loaded cells) for which :meth:`_ring_displacement` sums directly (measured on
    one core: a line-contact ring, 8 cells around 30 loaded ones, 20 us against 160 us for the box
    convolution; in 3-D the two cost the same near 10^4 products)."""

    def _ring_displacement(self, pressure: np.ndarray, box: tuple[int, int, int, int],
                           ring: np.ndarray) -> np.ndarray:
        """A p (m per unit compliance) on the ``ring`` cells (this rank's rows; other cells: any value) for
        a ``pressure`` (Pa) that vanishes outside ``box``. Summed over the loaded cells directly, with the
        coefficient table, when the ring's cells times the loaded cells are at most ``DIRECT`` (line
        contact: 2 MARGIN ring cells), otherwise one convolution on the box (:meth:`convolve_box`); the
        same A p either way, to round-off."""
        comm = self.comm
        loaded = np.nonzero(pressure > 0)
        counts = np.array([np.count_nonzero(ring), len(loaded[0])])
        comm.Allreduce(MPI.IN_PLACE, counts, op=MPI.SUM)
        if counts[0] * counts[1] > self.DIRECT:
            return self.convolve_box(pressure, box)
        mine = np.stack([loaded[0] + self.r0, loaded[1], pressure[loaded]])
        sources = np.concatenate(comm.allgather(mine), axis=1) if comm.size > 1 else mine
        si, sj, sp = sources[0].astype(int), sources[1].astype(int), sources[2]
        ri, rj = np.nonzero(ring)
        di = np.abs(ri[:, None] + self.r0 - si[None, :])
        dj = np.abs(rj[:, None] - sj[None, :])
        rows = box[1] - box[0]
        table = self.influence.table_rows(rows, box[3] - box[2])(np.arange(rows))
        out = np.zeros(self.local_shape)
        out[ri, rj] = table[di, dj] @ sp
        return out

    def _solve_window(self, delta: float, height: np.ndarray, compliance: float, warm: np.ndarray | None,
                      candidates: np.ndarray, load: float | None):
        grid, comm = self.grid, self.comm
        window = self.topology.window(None if candidates is None else self._box(candidates),
                                      not self.influence.positive)
        if window is None:
            return np.zeros(self.local_shape), 0, 0, 0.0, (0, 0, 0, 0), 0.0
        i0, i1, j0, j1 = window
        grid_ranges, window_ranges = self._box_ranges(i0, i1)
        target = move_rows(delta - height[:, j0:j1], grid_ranges, window_ranges, comm)  # the interference
        w_ref = self._scale(target)
        diagonal = self.influence.diagonal
        to_pressure = w_ref / (compliance * diagonal)  # p = to_pressure * p_hat

        qp = self.window_qp(i1 - i0, j1 - j0)
        if warm is None and load is not None and self.topology.whole:  # a periodic grid's cold start under load
            warm = self.summits_pressure(height, load)  # control (hertz_pressure's), let go once written
        with qp.x as start:  # the start, p_hat >= 0 (0 without a warm one), written straight into the solution
            if warm is None:
                start.fill(0.0)
            else:
                np.divide(move_rows(warm[:, j0:j1], grid_ranges, window_ranges, comm).reshape(-1), to_pressure,
                          out=start)
                np.maximum(start, 0.0, out=start)
        total = None if load is None else load / (grid.cell_area * to_pressure)
        # the scaled gap, written straight into the QP's right-hand side; a cell without surface (Z = +inf, a
        # hole in a height map) inside the window: a gap it cannot close
        with qp.rhs as gaps:
            np.divide(target.reshape(-1), -w_ref, out=gaps)
            np.minimum(gaps, self.NO_SURFACE_GAP, out=gaps)
        del target, warm  # posed: the interference and the start go before the solve's arrays come
        tol = self.tol if self.pressure_tol is None else self.pressure_tol
        x, gap, multiplier, its, applications = qp.solve(total, tol)
        if self.pressure_tol is not None:
            x, gap, multiplier, its, applications, tol = self._to_pressure_tol(qp, (i1 - i0, j1 - j0), total,
                                                                              (x, gap, multiplier, its,
                                                                               applications), tol)
        natural = np.minimum(x, gap)
        residual = comm.allreduce(float(np.abs(natural).max(initial=0.0)), op=MPI.MAX)
        p_window = np.maximum(x, 0.0).reshape(-1, j1 - j0) * to_pressure
        self.work[0] += its
        self.work[1] += applications
        if not residual <= tol:
            raise SolverError(f"TAO ({self.tao_type}) stopped with the contact conditions violated by "
                              f"{residual:.3g} (relative; [solver] tol = {tol:g}); try another "
                              f"-{self.prefix}tao_type or a larger [solver] tol")
        pressure = np.zeros(self.local_shape)
        self._put_box(pressure, p_window, window)
        return pressure, its, applications, residual, window, multiplier * w_ref

    REFINES = 20
    """Most re-solves of one QP on the way to ``pressure_tol`` (each scales the residual tolerance by the
    estimated error's excess, and at least by 0.5: far more than the 1-2 that a 10^-12 target needs)."""

    def _to_pressure_tol(self, qp: WindowQP, shape: tuple[int, int], total: float | None, solved: tuple,
                         tol: float):
        """Re-solve the QP (right-hand side set, its last answer ``solved`` = (x, gap, multiplier, iterations,
        applications) at residual tolerance ``tol`` held in its solution vector) at tighter residual
        tolerances until its estimated relative L2 pressure error is <= ``pressure_tol``; returns the same
        five (work summed) and the final residual tolerance."""
        x, gap, multiplier, its, applications = solved
        inverse = self.influence.window(*shape, inverse=True)
        for _ in range(self.REFINES):
            estimate = qp.error_estimate(x, gap, inverse)
            if estimate <= self.pressure_tol:
                return x, gap, multiplier, its, applications, tol
            tol *= min(0.5, 0.5 * self.pressure_tol / estimate)
            x, gap, multiplier, n, apps = qp.solve(total, tol)
            its, applications = its + n, applications + apps
        raise SolverError(f"the pressure's estimated error {estimate:.3g} stays above [solver] pressure_tol = "
                          f"{self.pressure_tol:g} at the residual tolerance {tol:.3g}; try a larger pressure_tol")

    def _scale(self, target: np.ndarray) -> float:
        """w_ref (m), the QP's unit of gap, from the interference ``target`` (this rank's window rows):
        petroll.model.topology.Topology.gap_unit."""
        extremes = np.array([target.max(initial=-np.inf), -target.min(initial=np.inf)])
        self.comm.Allreduce(MPI.IN_PLACE, extremes, op=MPI.MAX)
        return self.topology.gap_unit(float(extremes[0]), -float(extremes[1]))

    def convolve_box(self, field: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
        """A ``field`` with the Love coefficients (A field, m per unit of field), sources and results both
        restricted to the cells [i0, i1) x [j0, j1) = ``box``: this rank's grid rows, zero outside the box."""
        i0, i1, j0, j1 = box
        grid_ranges, window_ranges = self._box_ranges(i0, i1)
        local = move_rows(field[:, j0:j1], grid_ranges, window_ranges, self.comm)
        out = np.zeros(self.local_shape)
        self._put_box(out, self.influence.window(i1 - i0, j1 - j0)(local), box)
        return out

    def _box_ranges(self, i0: int, i1: int):
        """Row ranges of every rank: on the grid, and for rows i0..i1 split evenly (a window's layout)."""
        part = RowPartition(i1 - i0, self.comm.size)
        return ([self.rows.range(r) for r in range(self.comm.size)],
                [(i0 + a, i0 + b) for a, b in (part.range(r) for r in range(self.comm.size))])

    def _put_box(self, out: np.ndarray, values: np.ndarray, box: tuple[int, int, int, int]) -> None:
        """Write a box's values (held in its window layout) into this rank's grid rows ``out``."""
        i0, i1, j0, j1 = box
        grid_ranges, window_ranges = self._box_ranges(i0, i1)
        dst = [_clip(r, i0, i1) for r in grid_ranges]
        a, b = dst[self.comm.rank]
        out[a - self.r0 : b - self.r0, j0:j1] = move_rows(values, window_ranges, dst, self.comm)

    def window_qp(self, nx: int, ny: int) -> WindowQP:
        """The kept TAO objects of an nx x ny window, built on first use (the newest last)."""
        qp = self._qps.pop((nx, ny), None) or WindowQP(self, nx, ny)
        self._qps[(nx, ny)] = qp
        while len(self._qps) > self.kept:
            self._qps.pop(next(iter(self._qps))).destroy()
        return qp

    def _check_inside(self, pressure: np.ndarray) -> None:
        """SolverError if the contact (p > 0) loads a cell of an edge it must stay off after the solve,
        where the QP's window could not keep it off (line contact's end strips, the edges of a grid that
        repeats along one axis only: petroll.model.topology.Topology.touches_edge)."""
        if self.comm.allreduce(self.topology.touches_edge(pressure, self.r0), op=MPI.LOR):
            raise SolverError(self.topology.edge_message())

    def _box(self, candidates: np.ndarray) -> tuple[int, int, int, int] | None:
        """Bounding box [i0, i1) x [j0, j1) of the candidate cells over all ranks; None when there are none."""
        rows = np.flatnonzero(candidates.any(axis=1)) + self.r0
        cols = np.flatnonzero(candidates.any(axis=0))
        big = self.grid.nx + self.grid.ny
        lo = np.array([rows.min(initial=big), cols.min(initial=big)])
        hi = np.array([rows.max(initial=-1), cols.max(initial=-1)])
        self.comm.Allreduce(MPI.IN_PLACE, lo, op=MPI.MIN)
        self.comm.Allreduce(MPI.IN_PLACE, hi, op=MPI.MAX)
        if hi[0] < 0:
            return None
        return int(lo[0]), int(hi[0]) + 1, int(lo[1]), int(hi[1]) + 1


def hertz_penetration(grid: Grid, compliance: float, load: float, radius: float) -> float:
    """Hertz's penetration (m) of a sphere of ``radius`` (m) under ``load`` (N), or on a line-contact grid of
    a cylinder under ``load`` per length (N/m) relative to the grid's datum L:
    (2 J P/pi) (ln(2 L/a) + 1/2) with a = sqrt(4 P R J/pi) (the Hertz pressure's displacement at the
    centre with the strip kernel's constant, petroll.solver.kernels.love.strip_coefficients)."""
    if grid.line:
        a = math.sqrt(4 * load * radius * compliance / math.pi)
        return 2 * compliance * load / math.pi * (math.log(2 * grid.datum / a) + 0.5)
    return (3 * compliance * load / (4 * math.sqrt(radius))) ** (2 / 3)


def _clip(rows: tuple[int, int], i0: int, i1: int) -> tuple[int, int]:
    """The part of the row range ``rows`` inside [i0, i1) (an empty range at its start if none)."""
    a = max(rows[0], i0)
    return a, max(min(rows[1], i1), a)
