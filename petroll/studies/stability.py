"""The stability suite (issue 6): sweep small scenes over the axes where a method like petroll's breaks,
and check every run's physics, not only that it finished.

    petroll stability [--fast] [--out DIR]      (writes DIR/stability.csv and DIR/stability.md)

Axes: the time step (1e-4 T ... 1e3 T, fixed and varying), the stiffness ratio E0/Einf (1 ... 1e4) and
Prony series spread over 8 decades, the speed V tau / a (1e-3 ... 1e3) and a speed reversing through zero,
penetrations shrinking to zero / lost and regained, loads going to zero, coarse, fine and elongated grids
and a body reaching the grid edge, large penetrations, extreme magnitudes (moduli 1e-3 ... 1e12 Pa,
radii 1e-6 ... 10 m) that must scale as the analytic scalings say, and refinement in dt and dx.

Every step of every run is checked independently of the solver's own convergence test:

- ``finite``: no NaN/inf in the per-step series;
- ``contact``: the contact conditions on the *whole* grid (not only the solver's window), recomputed from
  the solved pressure: max |min(p_hat, gap_hat)| in the solver's own scaling (p_hat = p J_eff A_00 / w_ref,
  gap_hat = gap / w_ref, w_ref the largest rigid interference) <= 10 tol, and pressure >= 0 everywhere;
- ``dissipation``: the energy dissipated in the material, the work of the pressure on the surface
  (trapezoidal in time) minus the energy stored in the material's internal state, never decreases (to
  1e-6 of the work done); Prony materials;
- ``bounds`` (displacement control, Prony): the force never exceeds the same-grid elastic force with J0 at
  the same body position and penetration; where the penetration never decreases and the motion never
  reverses it is also at least the one with Jinf (Lee-Radok; with V . F_res >= 0 there too);
- ``smooth``: between two steps the force changes by at most what the elastic response changes plus the
  relaxation possible in that time, 2 (F_0 - F_inf)(1 - exp(-dt / theta_min)), the resisting force
  likewise (times the largest slope of the profile in contact); no zig-zag (more than two alternating
  increments larger than 1e-3 of the scale); the scene's own jumps (t = 0) are exempt;
- refused cases: a PetrollError whose one-line message contains the expected words.

Each run is one row of the map; the refinement and scaling studies add rows with measured errors.
"""

from __future__ import annotations

import copy
import csv
import datetime
import math
import pathlib
import time as clock
from dataclasses import dataclass, field

import numpy as np
from mpi4py import MPI

from petroll.errors import PetrollError

# the reference scene: a sphere on an SLS half-space (nu = 0.5: J = 0.75 / E)
R, NU, E0, DELTA, T = 0.01, 0.5, 10e6, 2e-5, 0.05  # m, -, Pa, m, s (T: the creep, retardation, time)
A = math.sqrt(R * DELTA)  # Hertz contact radius, m


def sls(ratio: float = 5.0, e0: float = E0, tau: float = T) -> dict:
    """An SLS [material] with E0 / Einf = ratio and creep time tau; ratio 1 is elastic."""
    if ratio == 1:
        return {"model": "elastic", "E": e0, "nu": NU}
    return {"model": "sls", "E0": e0, "Einf": e0 / ratio, "nu": NU, "tau_creep": tau}


def scene(n: int = 16, half: float = 2.0, length: float = 0.0, material: dict | None = None,
          motion: dict | None = None, time: dict | None = None, radius: float = R, delta: float = DELTA,
          ny: int | None = None, tol: float = 1e-8, integrator: str | None = None, back: float = 0.0) -> dict:
    """A sphere scene dict: n cells over [-half a, half a] along X, ny (default n) over the same along Y,
    and X longer by ``length`` a ahead (rolling) and ``back`` a behind; a = sqrt(radius delta)."""
    a = math.sqrt(radius * delta)
    ny = ny or n
    dx = 2 * half * a / n
    behind = int(round(back * a / dx))
    nx = n + int(round(length * a / dx)) + behind
    x0 = -half * a - behind * dx
    raw = {
        "grid": {"nx": nx, "ny": ny, "x": [x0, x0 + nx * dx], "y": [-half * a, half * a]},
        "material": material or sls(),
        "body": {"shape": "sphere", "radius": radius},
        "motion": motion or {"penetration": delta},
        "solver": {"tol": tol},
    }
    if integrator:
        raw["solver"]["integrator"] = integrator
    if time:
        raw["time"] = time
    return raw


def hertz_force(delta: float, J: float, radius: float = R) -> float:
    return 4 * math.sqrt(radius) * delta**1.5 / (3 * J)


@dataclass
class Case:
    """One run of the map. ``dts``: an explicit step sequence after the sudden start (instead of the
    scene's clock); ``monotone``: the penetration never decreases and the motion never reverses (the
    lower Lee-Radok bound and V . F_res >= 0 are asserted); ``refuse``: the case must end in a PetrollError
    whose message contains each of these words."""

    axis: str
    name: str
    raw: dict
    fast: bool = False
    dts: list[float] | None = None
    monotone: bool = False
    refuse: tuple[str, ...] = ()
    warn: bool = False  # the scene must draw a PetrollWarning
    hertz: float | None = None  # the first step's force must be Hertz's (sphere, J0) to this relative error
    trend: str | None = None  # "force down": the force never increases (a held penetration relaxes);
    #                           "delta up": the penetration never decreases (a held load creeps)
    max_steps: int = 300


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


# -- one run, checked independently -----------------------------------------------------------------------
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


def run_case(case: Case, comm: MPI.Comm = MPI.COMM_WORLD, integrator: str | None = None,
             guard: bool = True) -> Row:
    """Run one case on ``comm`` (collective) and check it; never raises for what the run does.
    ``integrator``: use this one where the case does not choose; ``guard=False``: accept every step."""
    return _run(case, comm, integrator, guard)[0]


def _run(case: Case, comm: MPI.Comm, integrator: str | None = None, guard: bool = True):
    """(row, records, scene) of one case; records and scene are None where it did not run."""
    import warnings

    from petroll.model.limits import PetrollWarning
    from petroll.model.materials import Prony
    from petroll.model.scene import parse_scene
    from petroll.solver.simulation import Simulation

    row = Row(case.axis, case.name)
    start = clock.perf_counter()
    records = []
    checker = scene = None
    raw = copy.deepcopy(case.raw)
    if integrator and "integrator" not in raw["solver"] and raw["material"]["model"] != "tabulated":
        raw["solver"]["integrator"] = integrator
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", PetrollWarning)
            scene = parse_scene(raw, source=f"<{case.name}>")
        for w in caught:
            if issubclass(w.category, PetrollWarning):
                row.note = "warning: " + str(w.message).split(": ", 1)[1]
        sim = Simulation(scene, comm)
        sim.history.guard = guard
        reference = scene.penetration is not None and isinstance(scene.material, Prony)
        checker = Checker(sim, reference)
        for record in sim.steps(dts=case.dts):
            records.append(record)
            checker.after_step(record)
            if sim.dt_next is not None and len(records) >= case.max_steps:
                raise RuntimeError(f"more than {case.max_steps} steps: too long a case for the suite")
    except PetrollError as exc:
        message = " ".join(str(exc).split())
        row.steps, row.note = len(records), message
        row.wall = clock.perf_counter() - start
        if case.refuse:
            row.status = "refused"
            missing = [w for w in case.refuse if w not in message]
            if missing:
                row.failures.append(f"refused without naming {missing}")
        else:
            row.failures.append("error: " + message)
        return row.finish(), None, None
    except Exception as exc:  # a crash: recorded, so that the sweep goes on
        row.steps, row.wall = len(records), clock.perf_counter() - start
        row.failures.append(f"crash: {type(exc).__name__}: {' '.join(str(exc).split())}")
        return row.finish(), None, None
    row.wall, row.steps = clock.perf_counter() - start, len(records)
    if case.refuse:
        row.failures.append(f"not refused (expected an error naming {list(case.refuse)})")
    if case.warn and not row.note.startswith("warning"):
        row.failures.append("no warning (expected one)")
    check_series(case, scene, checker, records, row)
    return row.finish(), records, scene


def check_series(case: Case, scene, checker: Checker, records, row: Row) -> None:
    """The per-run properties (module docstring) from the step records and the checker's findings."""
    names = ("t", "force", "force_x", "force_y", "delta", "mu_r", "dissipation", "residual", "sx", "sy")
    s = {n: np.array([getattr(r, n) for r in records], dtype=float) for n in names}
    row.its = max(r.iterations for r in records)
    bad = [n for n, v in s.items() if not np.all(np.isfinite(v))]
    if bad:
        row.failures.append(f"NaN/inf in {bad}")
    row.contact, row.p_min = checker.contact, checker.p_min
    if not checker.contact <= 10:
        row.failures.append(f"contact conditions violated on the grid by {checker.contact:.3g} tol")
    if not checker.p_min >= 0:
        row.failures.append(f"negative pressure {checker.p_min:g} Pa")
    force, mu = s["force"], s["mu_r"]
    row.force = float(force[-1])
    row.mu_r = f"{mu[-1]:.3g}" if np.ptp(mu) <= 1e-12 else f"{mu.min():.3g}..{mu.max():.3g}"
    scale = max(float(np.max(np.abs(force))), 1e-300)
    if checker.dissipated and checker.max_work > 0:
        d = np.array(checker.dissipated) / checker.max_work
        row.dissipation = float(min(d.min(), np.diff(d).min(initial=0.0)))
        if row.dissipation < -1e-6:
            row.failures.append(f"dissipated energy decreases by {-row.dissipation:.3g} of the work")
    n = len(records)
    velocity = np.array([np.asarray(scene.velocity(r.t), dtype=float) for r in records])
    speed = np.hypot(velocity[:, 0], velocity[:, 1])
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
    if checker.reference is not None:
        m = scene.material
        unit = np.array(checker.unit)
        f0, finf = unit[:, 0] / m.J0, unit[:, 0] / m.Jinf
        spread = np.maximum(f0 - finf, 0.0)
        slack = 1e-6 * scale + 2 * checker.tol * f0
        if np.any(force > f0 + slack):
            k = int(np.argmax(force - f0))
            row.failures.append(f"force above the instantaneous elastic force: {force[k]:.6g} > "
                                f"{f0[k]:.6g} N at step {k}")
        if spread.max() > 0:
            ratio = (force - finf) / np.where(spread > 0, spread, 1.0)
            row.bounds = f"{ratio.min():.3g}..{ratio.max():.3g}"
        if case.monotone and np.any(force < finf - slack):
            k = int(np.argmin(force - finf))
            row.failures.append(f"force below the relaxed elastic force: {force[k]:.6g} < {finf[k]:.6g} N at "
                                f"step {k}")
        if n > 1:
            from petroll.model.materials import relaxation_series

            theta = min(relaxation_series(m)[2], default=math.inf)
            dt = np.diff(s["t"])
            relax = 2 * np.maximum(spread[:-1], spread[1:]) * -np.expm1(-dt / theta)
            slope = math.sqrt(2 * max(s["delta"].max(), 0.0) / R_of(scene)) * 1.5
            allowed_f = np.abs(np.diff(f0)) + relax + 1e-6 * scale
            allowed_x = (np.abs(np.diff(unit[:, 1] / m.J0)) + np.abs(np.diff(unit[:, 2] / m.J0))
                         + slope * relax + 1e-6 * scale * slope)
            change_x = np.abs(np.diff(s["force_x"])) + np.abs(np.diff(s["force_y"]))
            use = np.ones(n - 1, dtype=bool)
            use[0] = False  # the sudden start (t = 0) is the scene's jump
            if np.any(use):
                ratio_f = np.abs(np.diff(force))[use] / allowed_f[use]
                ratio_x = change_x[use] / allowed_x[use]
                row.smooth = float(max(ratio_f.max(), ratio_x.max()))
                if row.smooth > 1:
                    row.failures.append(f"force or resisting force changed {row.smooth:.3g} times faster "
                                        "than the material can relax")
        # the grid ripple (the body crossing cells) is not an oscillation: the threshold includes the
        # non-smooth part (second difference) of the elastic force at the same positions
        ripple = np.abs(np.diff(f0, 2)) if n > 2 else np.zeros(0)
        ripple = np.concatenate([[0.0], ripple, [0.0]])  # at the step between increments k and k + 1
        _zigzag(force / scale, 1e-3 + 2 * ripple[1:-1] / scale if n > 2 else 1e-3, row)
    else:
        level = force / scale if scene.penetration is not None else s["delta"] / max(np.abs(s["delta"]).max(),
                                                                                      1e-300)
        _zigzag(level, 1e-3, row)
    if case.monotone and np.any(speed > 0):
        moving = (speed > 0) & (force > 0)
        power = s["dissipation"][moving] / (force[moving] * speed[moving])
        row.resistance = float(power.min(initial=0.0))
        if row.resistance < -1e-7:
            row.failures.append(f"the resisting force drives the body: V . F_res = {row.resistance:.3g} "
                                "|V| F")


def R_of(scene) -> float:
    return float(getattr(scene.body, "radius", None) or scene.body.radius_hint)


def _zigzag(level: np.ndarray, threshold, row: Row) -> None:
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


# -- the map ------------------------------------------------------------------------------------------------
def _rolling(v: float, n: int = 16, length: float = 3.0, ratio: float = 5.0, steps: float = 1.0,
             **kw) -> dict:
    """Rolling along +X at V = v a / T (v = V T / a), steps_per_cell steps per cell, over ``length`` a."""
    motion = {"velocity": [v * A / T, 0.0], "penetration": DELTA}
    return scene(n=n, length=length, material=sls(ratio), motion=motion,
                 time={"steps_per_cell": steps, "distance": length * A}, **kw)


def _load_scene(load_program, ratio: float = 5.0, n: int = 16, end: float = 2 * T, dt: float = T / 10,
                **kw) -> dict:
    """Load control on a grid that holds the relaxed contact of the largest load."""
    peak = load_program if isinstance(load_program, (int, float)) else max(
        abs(load_program.get("mean", 0)) + abs(load_program.get("amplitude", 0)),
        abs(load_program.get("start", 0)), abs(load_program.get("end", 0)))
    j_inf = (1 - NU**2) * ratio / E0
    a_inf = (3 * peak * R * j_inf / 4) ** (1 / 3)
    delta_inf = a_inf**2 / R
    raw = scene(n=n, half=2.0, material=sls(ratio), motion={"load": load_program}, delta=delta_inf,
                time={"dt": dt, "end": end}, **kw)
    return raw


def cases() -> list[Case]:
    """Every run of the map; ``fast`` marks the subset the test suite runs."""
    F0 = hertz_force(DELTA, (1 - NU**2) / E0)  # the reference force, N
    out: list[Case] = []
    add = out.append
    # -- time step: a step penetration held, fixed dt from 1e-4 T to 1e3 T, then varying steps
    for x in (1e-4, 1e-2, 1e-1, 1.0, 10.0, 1e3):
        add(Case("dt", f"held penetration, dt = {x:g} T", scene(time={"dt": x * T, "end": 8 * x * T}),
                 fast=x in (1e-2, 1e3), monotone=True, trend="force down"))
    for x in (1e-4, 1.0, 1e3):
        add(Case("dt", f"held load, dt = {x:g} T", _load_scene(F0, dt=x * T, end=8 * x * T), fast=x == 1.0,
                 trend="delta up"))
    growing = list(np.geomspace(1e-4 * T, 1e3 * T, 16))
    rng = np.random.default_rng(6)
    jumping = list(rng.choice([1e-4 * T, 1e-2 * T, 1e3 * T], size=20))
    add(Case("dt", "held penetration, dt growing 1e-4 T -> 1e3 T", scene(time={"dt": T, "end": T}),
             dts=growing, monotone=True, fast=True, trend="force down"))
    add(Case("dt", "held penetration, dt random in {1e-4, 1e-2, 1e3} T", scene(time={"dt": T, "end": T}),
             dts=jumping, monotone=True, trend="force down"))
    add(Case("dt", "held load, dt random in {1e-4, 1e-2, 1e3} T", _load_scene(F0), dts=jumping, fast=True,
             trend="delta up"))
    sinus = {"kind": "sinusoidal", "mean": [A / T, 0.0], "amplitude": [0.9 * A / T, 0.0], "period": 2 * T}
    add(Case("dt", "rolling, speed 0.1..1.9 a/T, dt = dx / (2 |V|) varying",
             scene(length=4, motion={"velocity": sinus, "penetration": DELTA},
                   time={"steps_per_cell": 2, "distance": 4 * A}), monotone=True))
    for integrator, x in (("exponential", 1.0), ("paper", 1.0), ("exponential", 1e-2), ("paper", 1e-2)):
        ok = x < 0.1
        add(Case("dt", f"held penetration, integrator {integrator}, dt = {x:g} T",
                 scene(time={"dt": x * T, "end": 8 * x * T}, integrator=integrator), monotone=True,
                 refuse=() if ok else ("cannot hold a penetration", "time step <=", "relaxation"),
                 fast=not ok))
    # -- stiffness ratio E0/Einf and Prony spreads
    for ratio in (1, 10, 100, 1e3, 1e4):
        add(Case("ratio", f"held penetration, E0/Einf = {ratio:g}, dt = T/10",
                 scene(material=sls(ratio), time={"dt": T / 10, "end": 2 * T}), monotone=True,
                 fast=ratio in (1, 1e4), trend="force down"))
        add(Case("ratio", f"rolling V T/a = 1, E0/Einf = {ratio:g}", _rolling(1.0, ratio=ratio),
                 monotone=True, fast=ratio == 1e4))
    times = [float(t) for t in np.geomspace(1e-4 * T, 1e4 * T, 9)]
    kelvin = {"model": "prony", "series": "kelvin", "Einf": E0 / 100, "nu": NU, "times": times,
              "compliances": [99 / E0 / 9] * 9}
    maxwell = {"model": "prony", "series": "maxwell", "Einf": E0 / 100, "nu": NU, "times": times,
               "moduli": [0.99 * E0 / 9] * 9}
    for label, material in (("kelvin", kelvin), ("maxwell", maxwell)):
        add(Case("ratio", f"held penetration, 9-term {label} series over 8 decades, dt 1e-4 T -> 1e4 T",
                 scene(material=material, time={"dt": T, "end": T}),
                 dts=list(np.geomspace(1e-4 * T, 1e4 * T, 25)), monotone=True, fast=label == "maxwell",
                 trend="force down"))
        motion = {"velocity": [A / T, 0.0], "penetration": DELTA}
        add(Case("ratio", f"rolling V T/a = 1, 9-term {label} series",
                 scene(length=3, material=material, motion=motion,
                       time={"steps_per_cell": 1, "distance": 3 * A}),
                 monotone=True))
    # -- speed
    for v in (1e-3, 1e-2, 1e-1, 1.0, 10.0, 1e2, 1e3):
        add(Case("speed", f"rolling V T/a = {v:g}", _rolling(v), monotone=True, fast=v in (1e-3, 1e3)))
    reverse = {"kind": "sinusoidal", "mean": [0.0, 0.0], "amplitude": [A / T, 0.0], "period": 4 * T}
    add(Case("speed", "speed reversing: V = (a/T) sin(2 pi t / 4T), rolls back over its wake",
             scene(length=2, back=0, motion={"velocity": reverse, "penetration": DELTA},
                   time={"dt": T / 10, "end": 8 * T}), fast=True))
    diagonal = scene(n=16, length=2, ny=22, motion={"velocity": [A / T / math.sqrt(2), A / T / math.sqrt(2)],
                                                     "penetration": DELTA},
                     time={"steps_per_cell": 1, "distance": 1.5 * A})
    diagonal["grid"]["y"] = [-2 * A, 3.5 * A]
    add(Case("speed", "rolling diagonally (45 degrees), V T/a = 1", diagonal, monotone=True))
    # -- penetration and load programs
    shrink = {"kind": "ramp", "start": DELTA, "end": 0.0, "duration": 2 * T}
    add(Case("load", "penetration shrinking to zero over 2T", scene(motion={"penetration": shrink},
                                                                    time={"dt": T / 10, "end": 3 * T}),
             fast=True))
    dip = {"kind": "sinusoidal", "mean": 0.3 * DELTA, "amplitude": DELTA, "period": 2 * T}
    add(Case("load", "penetration 0.3 + sin: contact lost and regained",
             scene(motion={"penetration": dip}, time={"dt": T / 20, "end": 4 * T}), fast=True))
    roll_dip = {"velocity": [A / T, 0.0], "penetration": dip}
    add(Case("load", "rolling while contact is lost and regained",
             scene(length=4, motion=roll_dip, time={"dt": T / 10, "end": 4 * T})))
    to_zero = {"kind": "ramp", "start": F0, "end": 1e-9 * F0, "duration": 2 * T}
    add(Case("load", "load ramp to 1e-9 F", _load_scene(to_zero, dt=T / 10, end=3 * T), fast=True))
    from_zero = {"kind": "ramp", "start": 0.0, "end": F0, "duration": 2 * T}
    add(Case("load", "load ramp from 0", _load_scene(from_zero, dt=T / 10, end=2 * T), fast=True))
    pulling = {"kind": "sinusoidal", "mean": 0.5 * F0, "amplitude": F0, "period": 2 * T}
    add(Case("load", "load going negative (pulling)", _load_scene(pulling, dt=T / 10, end=2 * T),
             refuse=("[motion] load", "adhesion"), fast=True))
    rolling_load = {"velocity": [A / T, 0.0], "load": F0}
    add(Case("load", "rolling under load control, V T/a = 1",
             _load_scene(F0, dt=T / 10, end=1.0 * T) | {"motion": rolling_load}))
    # -- grids
    for cells in (2, 4, 16):
        n = 4 * cells
        add(Case("grid", f"rolling, a/dx = {cells}", _rolling(1.0, n=n), monotone=True, fast=cells == 2))
    for k in (2, 4, 8):
        raw = scene(n=32, ny=32)
        raw["grid"]["nx"] = 32 // k  # dx = k dy
        add(Case("grid", f"held penetration, dx/dy = {k}", raw | {"time": {"dt": T / 10, "end": T}},
                 monotone=True, fast=k == 8))
        raw = scene(n=32 // k, ny=32, time={"dt": T / 10, "end": T})
        raw["grid"]["nx"], raw["grid"]["ny"] = 32, 32 // k  # dy = k dx
        add(Case("grid", f"held penetration, dy/dx = {k}", raw, monotone=True))
    edge = scene(n=16, half=1.2)
    add(Case("grid", "penetration whose interference reaches the grid edge", edge,
             refuse=("[grid]", "edge")))
    add(Case("grid", "rolling off the end of the grid", _rolling(1.0, length=1.0) | {
        "time": {"steps_per_cell": 1, "distance": 3 * A}}, refuse=("[grid]", "edge"), fast=True))
    add(Case("grid", "load control relaxing past the grid edge",
             scene(motion={"load": F0}, material=sls(1e3), time={"dt": T, "end": 5 * T}),
             refuse=("[grid]", "edge")))
    # -- large penetrations: the contact slope (a/R for a sphere) beyond the linear theory
    for ratio in (1e-2, 0.1, 0.5, 1.0):
        delta = ratio * R
        add(Case("large", f"penetration delta/R = {ratio:g} (a/R = {math.sqrt(ratio):.2g})",
                 scene(delta=delta, motion={"penetration": delta}, time={"dt": T / 2, "end": T}),
                 monotone=True, fast=ratio >= 0.1, warn=0.05 < ratio < 1,
                 refuse=("[motion] penetration", "slope", "small slopes") if ratio >= 1 else ()))
    # -- magnitudes: a tiny penetration under a large radius (profile heights 1e-13 of the radius), Hertz
    for radius, delta in ((10.0, 1e-14), (10.0, 1e-12), (1e-6, 1e-12), (10.0, 1e-4)):
        add(Case("scale", f"elastic sphere R = {radius:g} m, delta = {delta:g} m (a/dx = 4): Hertz's force",
                 scene(n=16, radius=radius, delta=delta, motion={"penetration": delta}, material=sls(1)),
                 hertz=0.01, fast=radius == 10 and delta < 1e-13))
    # -- magnitudes: the dimensionless scene of _rolling(1) at other moduli and radii
    for modulus in (1e-3, 1e12):
        for radius in (1e-6, 10.0):
            add(Case("scale", f"rolling V T/a = 1, E0 = {modulus:g} Pa, R = {radius:g} m",
                     scaled(_rolling(1.0), modulus, radius), monotone=True))
    return out


def scaled(raw: dict, modulus: float, radius: float, time_scale: float = 1.0) -> dict:
    """The scene ``raw`` (built on E0, R, T) with moduli times modulus/E0, lengths times radius/R and times
    times time_scale: forces scale by (modulus/E0)(radius/R)^2, pressures by modulus/E0."""
    raw = copy.deepcopy(raw)
    k, lam = modulus / E0, radius / R
    g = raw["grid"]
    g["x"] = [v * lam for v in g["x"]]
    g["y"] = [v * lam for v in g["y"]]
    m = raw["material"]
    for key in ("E", "E0", "Einf"):
        if key in m:
            m[key] *= k
    for key in ("tau_creep", "tau_relax"):
        if key in m:
            m[key] *= time_scale
    raw["body"]["radius"] *= lam
    motion = raw["motion"]
    if isinstance(motion.get("penetration"), (int, float)):
        motion["penetration"] *= lam
    if isinstance(motion.get("load"), (int, float)):
        motion["load"] *= k * lam**2
    if "velocity" in motion and isinstance(motion["velocity"], list):
        motion["velocity"] = [v * lam / time_scale for v in motion["velocity"]]
    t = raw.get("time", {})
    for key in ("dt", "end"):
        if key in t:
            t[key] *= time_scale
    if "distance" in t:
        t["distance"] *= lam
    return raw


# -- refinement and scaling studies -------------------------------------------------------------------------
def _series(case: Case, comm, name: str) -> tuple[Row, np.ndarray | None]:
    row, records, _ = _run(case, comm)
    return row, None if records is None else np.array([getattr(r, name) for r in records])


def _study_row(axis: str, name: str, rows: list[Row], errors: list[float], what: str, need_decrease: bool,
               limit: float | None = None) -> Row:
    """A study's row: the runs' own failures, and the errors (which must decrease, or stay below limit)."""
    out = Row(axis, name, steps=sum(r.steps for r in rows), wall=sum(r.wall for r in rows))
    for r in rows:
        out.failures += [f"{r.case}: {f}" for f in r.failures]
    e = np.array(errors)
    orders = np.log2(e[:-1] / e[1:]) if need_decrease and len(e) > 1 and np.all(e > 0) else np.array([])
    out.note = f"{what}: " + ", ".join(f"{v:.2e}" for v in e) + (
        " (observed orders " + ", ".join(f"{o:.2f}" for o in orders) + ")" if orders.size else "")
    if need_decrease and not np.all(np.diff(e) < 0):
        out.failures.append(f"errors do not decrease under refinement: {out.note}")
    if limit is not None and not e.max() <= limit:
        out.failures.append(f"errors above {limit:g}: {out.note}")
    return out.finish()


def refinement(comm: MPI.Comm = MPI.COMM_WORLD, fast: bool = False) -> list[Row]:
    """dt and dx refinement where the scene is smooth; the errors must decrease."""
    out = []
    # dt: rolling from rest at V T/a = 1 (a/dx = 4), force and resisting force at t = T against dt = T/128
    steps = (4, 8, 16, 32) if fast else (4, 8, 16, 32, 64)
    finest = 2 * steps[-1]
    runs, values = [], []
    for k in (*steps, finest):
        raw = scene(length=1.5, motion={"velocity": [A / T, 0.0], "penetration": DELTA},
                    time={"dt": T / k, "end": T})
        row, records, _ = _run(Case("refine", f"rolling, dt = T/{k}", raw), comm)
        runs.append(row)
        values.append((records[-1].force, records[-1].force_x) if records else (math.nan, math.nan))
    ref = values[-1]
    errors = [abs(f - ref[0]) / abs(ref[0]) + abs(fx - ref[1]) / abs(ref[1]) for f, fx in values[:-1]]
    out.append(_study_row("refine", f"dt: rolling V T/a = 1, force and F_x at t = T, dt = T/{steps[0]} .. "
                          f"T/{steps[-1]} against T/{finest}", runs, errors, "relative errors", True))
    # dx: an elastic sphere against Hertz, a/dx = 2 .. 16
    cells = (2, 4, 8) if fast else (2, 4, 8, 16)
    runs, errors = [], []
    for c in cells:
        row, force = _series(Case("refine", f"Hertz a/dx = {c}", scene(n=4 * c, material=sls(1))), comm,
                             "force")
        runs.append(row)
        hertz = hertz_force(DELTA, (1 - NU**2) / E0)
        errors.append(abs(force[-1] / hertz - 1) if force is not None else math.nan)
    out.append(_study_row("refine", f"dx: elastic sphere against Hertz's force, a/dx = {cells[0]} .. "
                          f"{cells[-1]}", runs, errors, "relative errors", True))
    # dx: a held penetration relaxing (Lee-Radok: F(t) = Hertz with the modulus G(t)) at t = T
    from petroll.model.materials import relaxation_series, sls as make_sls

    Ginf, dG, theta = relaxation_series(make_sls(E0, E0 / 5, NU, tau_creep=T))
    exact = hertz_force(DELTA, 1.0 / (Ginf + sum(d * math.exp(-T / th) for d, th in zip(dG, theta))))
    runs, errors = [], []
    for c in cells:
        raw = scene(n=4 * c, time={"dt": T / 4, "end": T})
        row, force = _series(Case("refine", f"Lee-Radok a/dx = {c}", raw), comm, "force")
        runs.append(row)
        errors.append(abs(force[-1] / exact - 1) if force is not None else math.nan)
    out.append(_study_row("refine", f"dx: held penetration (SLS, E0/Einf = 5) against Lee-Radok at t = T, "
                          f"dt = T/4, a/dx = {cells[0]} .. {cells[-1]}", runs, errors, "relative errors",
                          True))
    return out


def scaling(comm: MPI.Comm = MPI.COMM_WORLD, fast: bool = False) -> list[Row]:
    """The same dimensionless scene at other moduli, radii and time scales: F / (E0 R^2), mu_r, delta / R
    and area / R^2 must agree with the reference run to round-off (1e-6 allowed: the solver tolerance)."""
    combos = [(1e-3, 1e-6, 1.0), (1e12, 10.0, 1.0)] if fast else [
        (1e-3, 1e-6, 1.0), (1e-3, 10.0, 1.0), (1e12, 1e-6, 1.0), (1e12, 10.0, 1.0), (E0, R, 1e-6),
        (E0, R, 1e6), (1.0, 1.0, 1.0)]
    out = []
    for label, base in (("rolling V T/a = 1 (displacement control)", _rolling(1.0)),
                        ("held load (load control)", _load_scene(hertz_force(DELTA, (1 - NU**2) / E0),
                                                                 end=T / 2))):
        ref_row, ref, _ = _run(Case("scale", "reference", base), comm)
        tol = base["solver"]["tol"]
        runs, errors = [ref_row], []
        for modulus, radius, time_scale in combos:
            k, lam = modulus / E0, radius / R
            case = Case("scale", f"E0 = {modulus:g} Pa, R = {radius:g} m, T x {time_scale:g}",
                        scaled(base, modulus, radius, time_scale))
            row, records, _ = _run(case, comm)
            runs.append(row)
            if records is None or ref is None or len(records) != len(ref):
                errors.append(math.inf)
                continue
            worst = 0.0
            for a, b in zip(ref, records):
                pairs = [(a.force, b.force / (k * lam**2)), (a.delta, b.delta / lam),
                         (a.area, b.area / lam**2), (a.t, b.t / time_scale)]
                # mu_r of a symmetric patch (the held load at rest) is zero only to the solver's tolerance:
                # compared where it is larger than that, else it must stay below it
                if abs(a.mu_r) > tol:
                    pairs.append((a.mu_r, b.mu_r))
                elif abs(b.mu_r) > tol:
                    worst = math.inf
                for x, y in pairs:
                    if x != 0:
                        worst = max(worst, abs(x - y) / abs(x))
            errors.append(worst)
        names = ", ".join(f"({m:g} Pa, {r:g} m, T x {t:g})" for m, r, t in combos)
        out.append(_study_row("scale", f"{label} at (E0, R, time scale) = {names}", runs, errors,
                              "largest relative deviation from the reference", False, limit=1e-6))
    return out


# -- the sweep and its table -------------------------------------------------------------------------------
def sweep(fast: bool = False, comm: MPI.Comm = MPI.COMM_WORLD, integrator: str | None = None,
          guard: bool = True, progress=None) -> list[Row]:
    """Every case of the map (``fast``: the CI subset), then the refinement and scaling studies."""
    rows = []
    for case in cases():
        if fast and not case.fast:
            continue
        rows.append(run_case(case, comm, integrator, guard))
        if progress:
            progress(rows[-1])
    if integrator is None:
        for row in (*refinement(comm, fast), *scaling(comm, fast)):
            rows.append(row)
            if progress:
                progress(row)
    return rows


COLUMNS = ("axis", "case", "status", "steps", "its", "contact", "p_min", "dissipation", "bounds",
           "resistance", "smooth", "force", "mu_r", "wall", "note")


def _cell(value) -> str:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.3g}"
    return str(value)


def write_map(rows: list[Row], out: pathlib.Path, title: str = "petroll stability map") -> tuple[pathlib.Path,
                                                                                                pathlib.Path]:
    """DIR/stability.csv (every column) and DIR/stability.md (one table per axis). Call on one rank."""
    out.mkdir(parents=True, exist_ok=True)
    path_csv, path_md = out / "stability.csv", out / "stability.md"
    with open(path_csv, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow([*COLUMNS, "failures"])
        for r in rows:
            writer.writerow([_cell(getattr(r, c)) for c in COLUMNS] + ["; ".join(r.failures)])
    path_md.write_text(markdown(rows, title), encoding="utf-8")
    return path_csv, path_md


AXES = {
    "dt": "Time step (T: the creep time; SLS E0/Einf = 5 unless said)",
    "ratio": "Stiffness ratio and Prony spreads",
    "speed": "Speed (V T / a; a the Hertz radius) and reversal",
    "load": "Penetration and load programs",
    "grid": "Grids",
    "large": "Large penetrations",
    "scale": "Extreme magnitudes (moduli 1e-3 ... 1e12 Pa, radii 1e-6 ... 10 m)",
    "refine": "Refinement",
}


def markdown(rows: list[Row], title: str = "petroll stability map") -> str:
    """The map as Markdown tables, one per axis (columns: docs/stability.md)."""
    date = datetime.date.today().isoformat()
    failed = sum(r.status == "FAIL" for r in rows)
    lines = [f"<!-- {title}, generated {date} by `petroll stability` -->",
             f"{len(rows)} runs: {sum(r.status == 'ok' for r in rows)} ok, "
             f"{sum(r.status == 'refused' for r in rows)} refused as expected, {failed} failed.", ""]
    head = ("| case | status | steps | its | contact/tol | dissipation | bounds | V.F_res | smooth "
            "| force (N) | mu_r | note |")
    for axis, title_axis in AXES.items():
        mine = [r for r in rows if r.axis == axis]
        if not mine:
            continue
        lines += [f"#### {title_axis}", "", head, "|" + "---|" * 12]
        for r in mine:
            note = "; ".join(r.failures) if r.failures else r.note
            note = note.replace("|", "/")
            if len(note) > 220:
                note = note[:217] + "..."
            status = "**FAIL**" if r.status == "FAIL" else r.status
            cells = [r.case, status, str(r.steps), str(r.its), _cell(r.contact), _cell(r.dissipation),
                     r.bounds, _cell(r.resistance), _cell(r.smooth), _cell(r.force), r.mu_r, note]
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def command(out: str | pathlib.Path, fast: bool = False, comm: MPI.Comm = MPI.COMM_WORLD) -> int:
    """``petroll stability``: run the sweep, write the map, print its summary; 0 when nothing failed."""
    import sys

    def progress(row: Row) -> None:
        if comm.rank == 0:
            print(f"{row.axis:7s} {row.status:8s} {row.wall:6.2f} s  {row.case}", file=sys.stderr, flush=True)

    rows = sweep(fast, comm, progress=progress)
    failed = [r for r in rows if r.status == "FAIL"]
    if comm.rank == 0:
        paths = write_map(rows, pathlib.Path(out))
        print(f"petroll: stability: {len(rows)} runs, {len(failed)} failed; wrote {paths[0]} and {paths[1]}")
        for r in failed:
            print(f"petroll: FAIL {r.axis} / {r.case}: {'; '.join(r.failures)}")
    return 1 if failed else 0
