"""Every run checked independently of the solver's own test (the properties of the package docstring):
the :class:`Checker` watches a simulation step by step, :func:`check_series` judges its series."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from petroll.studies.stability.cases import Case
from petroll.studies.stability.scenes import R_of, hertz_force


@dataclass
class Row:
    """One line of the map. Ratios are relative; ``contact`` is in units of [solver] tol."""

    axis: str
    case: str
    status: str = "ok"  # ok | refused | FAIL
    steps: int = 0
    its: int = 0  # largest TAO iteration count of a step
    contact: float = math.nan  # whole-grid contact residual / tol
    p_min: float = math.nan  # smallest pressure, Pa
    dissipation: float = math.nan  # smallest increment of the dissipated energy / work done
    bounds: str = ""  # range of (F - F_inf) / (F_0 - F_inf) (same-grid elastic forces)
    resistance: float = math.nan  # smallest V . F_res / (|V| F)
    smooth: float = math.nan  # largest force change / the change allowed
    force: float = math.nan  # last force, N
    mu_r: str = ""  # last mu_r, or its range
    wall: float = 0.0  # s
    failures: list[str] = field(default_factory=list)
    note: str = ""

    def finish(self) -> "Row":
        if self.failures:
            self.status = "FAIL"
        return self


class Checker:
    """Watches a Simulation: records what each contact solve was given, and checks each step on the whole
    grid against the material's own state (all collective)."""

    def __init__(self, sim, reference: bool):
        from petroll.solver.history import PronyHistory, RelaxationHistory

        self.sim, self.comm = sim, sim.comm
        scene, solver = sim.scene, sim.solver
        self.tol = scene.solver.tol
        self.last = None
        original = solver.solve_penetration

        def solve_penetration(height, compliance, delta, warm=None):
            self.last = (height, compliance, delta)
            return original(height, compliance, delta, warm)

        solver.solve_penetration = solve_penetration  # this instance only
        g = scene.grid
        self.conv = solver.influence.window(g.nx, g.ny)
        self.diagonal, self.area = solver.influence.diagonal, g.cell_area
        history = sim.history
        self.kind = ("relaxation" if isinstance(history, RelaxationHistory)
                     else "creep" if isinstance(history, PronyHistory) else None)
        self.work, self.max_work = 0.0, 0.0
        self.previous = None  # (p, A W) of the previous step
        self.dissipated: list[float] = []
        self.contact, self.p_min = 0.0, math.inf
        # same-grid elastic references (unit compliance) at each step's position and penetration
        self.reference = None
        if reference:
            from petroll.solver.contact import ContactSolver

            self.reference = ContactSolver(g, self.comm, tol=self.tol)
            self.unit: list[tuple[float, float, float]] = []  # force, force_x, force_y with J = 1
            self.unit_warm = None

    def _sum(self, a) -> float:
        return self.comm.allreduce(float(np.sum(a)))

    def _max(self, a, initial: float = -math.inf) -> float:
        return self.comm.allreduce(float(np.max(a, initial=initial)), op=MPI.MAX)

    def after_step(self, record) -> None:
        sim, conv = self.sim, self.conv
        p = sim.pressure
        self.p_min = min(self.p_min, -self._max(-p))
        height, compliance, delta = self.last or (None, None, None)
        self.last = None
        interference = delta - height if height is not None else None  # None: no solve (zero load)
        w_ref = self._max(interference, initial=0.0) if height is not None else 0.0
        if w_ref > 0:
            gap = compliance * conv(p) - interference  # J_eff A p + Z + u - delta
            natural = np.minimum(p * compliance * self.diagonal / w_ref, gap / w_ref)
            self.contact = max(self.contact, self._max(np.abs(natural), initial=0.0) / self.tol)
        if self.kind is not None:
            self._energy(p)
        if self.reference is not None:
            self._elastic(record)

    def _energy(self, p) -> None:
        """Work of the pressure on the surface (trapezoidal) minus the energy stored in the material."""
        conv, history = self.conv, self.sim.history
        if self.kind == "creep":  # Kelvin chain: W = J0 p + sum dJ_r (p - q_r)
            m = history.material
            W = m.J0 * p + sum((d * (p - q) for d, q in zip(m.dJ, history.q)), np.zeros_like(p))
            stored = 0.5 * m.J0 * self._sum(p * conv(p))
            for d, q in zip(m.dJ, history.q):
                e = p - q
                stored += 0.5 * d * self._sum(e * conv(e))
        else:  # Maxwell branches: p = Ginf W + sum dG_k s_k
            W = history.displacement
            stored = 0.5 * history.Ginf * self._sum(W * conv(W))
            for d, s in zip(history.dG, history.q):
                stored += 0.5 * d * self._sum(s * conv(s))
        AW = conv(W)
        stored *= self.area
        p0, AW0 = self.previous if self.previous is not None else (np.zeros_like(p), np.zeros_like(p))
        self.work += 0.5 * self._sum((p0 + p) * (AW - AW0)) * self.area
        self.previous = (p.copy(), AW)
        self.max_work = max(self.max_work, abs(self.work), abs(stored))
        self.dissipated.append(self.work - stored)

    def _elastic(self, record) -> None:
        scene, solver = self.sim.scene, self.reference
        g = scene.grid
        x = g.x[solver.r0 : solver.r1, None] - record.sx
        y = g.y[None, :] - record.sy
        step = solver.solve_penetration(scene.body.height(x, y), 1.0, record.delta, self.unit_warm)
        self.unit_warm = step.pressure
        sx, sy = scene.body.slope(x, y)
        sums = np.array([(step.pressure * sx).sum(), (step.pressure * sy).sum()])
        self.comm.Allreduce(MPI.IN_PLACE, sums, op=MPI.SUM)
        self.unit.append((step.force, *(sums * g.cell_area)))


def check_series(case: Case, scene, checker: Checker, records, row: Row) -> None:
    """The per-run properties (package docstring) from the step records and the checker's findings."""
    names = ("t", "force", "force_x", "force_y", "delta", "mu_r", "dissipation", "residual", "sx", "sy")
    s = {n: np.array([getattr(r, n) for r in records], dtype=float) for n in names}
    row.its = max(r.iterations for r in records)
    row.force = float(s["force"][-1])
    mu = s["mu_r"]
    row.mu_r = f"{mu[-1]:.3g}" if np.ptp(mu) <= 1e-12 else f"{mu.min():.3g}..{mu.max():.3g}"
    _finite_and_contact(s, checker, row)
    _dissipation(checker, row)
    _trend_and_hertz(case, scene, s, row)
    if checker.reference is not None:
        _bounds_and_smoothness(case, scene, s, checker, row)
    else:
        scale = max(float(np.max(np.abs(s["force"]))), 1e-300)
        level = (s["force"] / scale if scene.penetration is not None
                 else s["delta"] / max(np.abs(s["delta"]).max(), 1e-300))
        zigzag(level, 1e-3, row)
    if case.monotone:
        _resistance(scene, records, s, row)


def _finite_and_contact(s: dict, checker: Checker, row: Row) -> None:
    """No NaN/inf in the series; the contact conditions on the whole grid; no negative pressure."""
    bad = [n for n, v in s.items() if not np.all(np.isfinite(v))]
    if bad:
        row.failures.append(f"NaN/inf in {bad}")
    row.contact, row.p_min = checker.contact, checker.p_min
    if not checker.contact <= 10:
        row.failures.append(f"contact conditions violated on the grid by {checker.contact:.3g} tol")
    if not checker.p_min >= 0:
        row.failures.append(f"negative pressure {checker.p_min:g} Pa")


def _dissipation(checker: Checker, row: Row) -> None:
    """The energy dissipated in the material never decreases (to 1e-6 of the work done)."""
    if checker.dissipated and checker.max_work > 0:
        d = np.array(checker.dissipated) / checker.max_work
        row.dissipation = float(min(d.min(), np.diff(d).min(initial=0.0)))
        if row.dissipation < -1e-6:
            row.failures.append(f"dissipated energy decreases by {-row.dissipation:.3g} of the work")


def _trend_and_hertz(case: Case, scene, s: dict, row: Row) -> None:
    """A held penetration's force never increases, a held load's penetration never decreases; the first
    step's force is Hertz's where the case says so."""
    force = s["force"]
    if case.trend is not None:
        name, sign = ("force", -1) if case.trend == "force down" else ("delta", 1)
        v = s[name]
        wrong = sign * np.diff(v) < -1e-9 * max(float(np.max(np.abs(v))), 1e-300)
        if np.any(wrong):
            k = int(np.argmax(wrong)) + 1
            row.failures.append(f"not monotone: {name} goes {'up' if sign < 0 else 'down'} at step {k}")
    if case.hertz is not None:
        expected = hertz_force(float(scene.penetration(0.0)), scene.material.J0, R_of(scene))
        error = abs(force[0] / expected - 1)
        note = f"first force / Hertz - 1 = {force[0] / expected - 1:.2e}"
        row.note = f"{row.note}; {note}" if row.note else note
        if not error <= case.hertz:
            row.failures.append(f"first force {force[0]:.6g} N is not Hertz's {expected:.6g} N to "
                                f"{case.hertz:g}")


def _bounds_and_smoothness(case: Case, scene, s: dict, checker: Checker, row: Row) -> None:
    """Displacement control on a Prony material: the force between the same-grid elastic forces with J0
    and (where the penetration never decreases) Jinf, changing no faster than the material can relax, and
    no zig-zag beyond the grid's ripple."""
    m, force, n = scene.material, s["force"], len(s["force"])
    scale = max(float(np.max(np.abs(force))), 1e-300)
    unit = np.array(checker.unit)
    f0, finf = unit[:, 0] / m.J0, unit[:, 0] / m.Jinf
    spread = np.maximum(f0 - finf, 0.0)
    slack = 1e-6 * scale + 2 * checker.tol * f0
    if np.any(force > f0 + slack):
        k = int(np.argmax(force - f0))
        row.failures.append(f"force above the instantaneous elastic force: {force[k]:.6g} > {f0[k]:.6g} N at "
                            f"step {k}")
    if spread.max() > 0:
        ratio = (force - finf) / np.where(spread > 0, spread, 1.0)
        row.bounds = f"{ratio.min():.3g}..{ratio.max():.3g}"
    if case.monotone and np.any(force < finf - slack):
        k = int(np.argmin(force - finf))
        row.failures.append(f"force below the relaxed elastic force: {force[k]:.6g} < {finf[k]:.6g} N at "
                            f"step {k}")
    if n > 1:
        _smoothness(scene, s, unit, spread, scale, row)
    # the grid ripple (the body crossing cells) is not an oscillation: the threshold includes the
    # non-smooth part (second difference) of the elastic force at the same positions
    ripple = np.abs(np.diff(f0, 2)) if n > 2 else np.zeros(0)
    zigzag(force / scale, 1e-3 + 2 * ripple / scale if n > 2 else 1e-3, row)


def _smoothness(scene, s: dict, unit: np.ndarray, spread: np.ndarray, scale: float, row: Row) -> None:
    """Force and resisting force change between steps by at most what the elastic response changes plus
    the relaxation possible in that time (the sudden start, the scene's jump, left out)."""
    from petroll.model.materials import relaxation_series

    m, force, n = scene.material, s["force"], len(s["force"])
    theta = min(relaxation_series(m)[2], default=math.inf)
    relax = 2 * np.maximum(spread[:-1], spread[1:]) * -np.expm1(-np.diff(s["t"]) / theta)
    slope = math.sqrt(2 * max(s["delta"].max(), 0.0) / R_of(scene)) * 1.5
    allowed_f = np.abs(np.diff(unit[:, 0] / m.J0)) + relax + 1e-6 * scale
    allowed_x = (np.abs(np.diff(unit[:, 1] / m.J0)) + np.abs(np.diff(unit[:, 2] / m.J0))
                 + slope * relax + 1e-6 * scale * slope)
    change_x = np.abs(np.diff(s["force_x"])) + np.abs(np.diff(s["force_y"]))
    use = np.ones(n - 1, dtype=bool)
    use[0] = False
    if np.any(use):
        ratio_f = np.abs(np.diff(force))[use] / allowed_f[use]
        ratio_x = change_x[use] / allowed_x[use]
        row.smooth = float(max(ratio_f.max(), ratio_x.max()))
        if row.smooth > 1:
            row.failures.append(f"force or resisting force changed {row.smooth:.3g} times faster than the "
                                "material can relax")


def _resistance(scene, records, s: dict, row: Row) -> None:
    """Where the penetration never decreases and the motion never reverses: V . F_res >= 0."""
    velocity = np.array([np.asarray(scene.velocity(r.t), dtype=float) for r in records])
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
    force = s["force"]
    if np.any(speed > 0):
        moving = (speed > 0) & (force > 0)
        power = s["dissipation"][moving] / (force[moving] * speed[moving])
        row.resistance = float(power.min(initial=0.0))
        if row.resistance < -1e-7:
            row.failures.append(f"the resisting force drives the body: V . F_res = {row.resistance:.3g} "
                                "|V| F")


def zigzag(level: np.ndarray, threshold, row: Row) -> None:
    """Flag more than two alternating increments above ``threshold`` (a number, or one per interior step)
    in ``level``; the sudden start's step is left out."""
    d = np.diff(level)
    if len(d) < 3:
        return
    threshold = np.broadcast_to(np.asarray(threshold, dtype=float), (len(d) - 1,))
    zig = (d[:-1] * d[1:] < 0) & (np.minimum(np.abs(d[:-1]), np.abs(d[1:])) > threshold)
    zig[0] = False
    if np.count_nonzero(zig) > 2:
        row.failures.append(f"zig-zag: {np.count_nonzero(zig)} alternating increments")
