"""Viscoelastic line contact (plane strain; docs/line-contact.md): Lee-Radok's step load, the slow-rolling
limit mu_r -> e/R, steady rolling against a second algorithm (a direct steady solve in the body frame,
written here) for V tau/a from 0.01 to 10, and the mid-section of a wide 3-D roller.

The long rolling runs (the steady cases, the sweep) go on one rank per process (COMM_SELF) also under
mpirun: hundreds of small 1-D steps are all collectives, which an oversubscribed machine slows tenfold;
line contact's rank-count independence is checked in tests/test_line.py.

Material: a standard linear solid, J(t) = Jinf - (Jinf - J0) exp(-t/tau), E0/Einf = 5; a is the relaxed
Hertz half-width sqrt(4 P R Jinf/pi) (0.98 mm here).
"""

import math

import numpy as np
import pytest
from mpi4py import MPI
from scipy.integrate import quad
from scipy.special import exp1, expi

from petroll.model.scene import parse_scene
from petroll.solver.simulation import Simulation
from petroll.studies.sweep import sweep

E0, EINF, NU, TAU, R, LOAD = 10e6, 2e6, 0.5, 0.01, 0.01, 200.0
J0, JINF = (1 - NU**2) / E0, (1 - NU**2) / EINF
A_INF = math.sqrt(4 * LOAD * R * JINF / math.pi)
SLS = {"model": "sls", "E0": E0, "Einf": EINF, "nu": NU, "tau_creep": TAU}


def creep(t: float) -> float:
    return JINF - (JINF - J0) * math.exp(-t / TAU)


def relaxation(t: float) -> float:
    """The SLS's relaxation function (the convolution inverse of creep), T = tau J0/Jinf."""
    return 1 / JINF + (1 / J0 - 1 / JINF) * math.exp(-t * JINF / (TAU * J0))


def run_to_end(raw: dict, comm) -> tuple[Simulation, list]:
    sim = Simulation(parse_scene(raw, source="test_line_rolling"), comm)
    return sim, list(sim.steps())


# -- Lee & Radok (1960) in plane strain -------------------------------------------------------------------
def lee_radok(t: float) -> tuple[float, float]:
    """Step load P at t = 0 on a cylinder (the contact only grows): the half-width a(t) = sqrt(4 P R J(t)/pi)
    (Hertz's a^2 = 4 P R J/pi with J replaced by the creep function), and the centre pressure
    p(0, t) = 1/(2 R) [G(t) a(0) + int_0^t G(t - s) a'(s) ds] (the elastic p(0) = a/(2 R J) with 1/J replaced
    by the relaxation function G, Lee-Radok's substitution)."""
    k = 4 * LOAD * R / math.pi

    def rate(s):
        return 0.5 * math.sqrt(k / creep(s)) * (JINF - J0) / TAU * math.exp(-s / TAU)

    a0 = math.sqrt(k * J0)
    centre = (relaxation(t) * a0 + quad(lambda s: relaxation(t - s) * rate(s), 0, t, limit=200)[0]) / (2 * R)
    return math.sqrt(k * creep(t)), centre


@pytest.mark.slow
@pytest.mark.parametrize("material, integrator, tol", [
    ("sls", "relaxation", 5e-3), ("sls", "exponential", 5e-3), ("sls", "paper", 0.08),
    ("tabulated", "paper", 0.08)])
def test_step_load_follows_lee_radok(material, integrator, tol, comm, shared_dir):
    """The half-width within one strip and the centre pressure (which falls by sqrt(5) as the material
    creeps) to the integrator's order at dt = tau/10 (measured: 1.8e-3, 3.1e-3, 0.062 (first order))."""
    if material == "tabulated":
        t = np.linspace(0, 10 * TAU, 2001)
        if comm.rank == 0:
            np.savetxt(shared_dir / "J.csv", np.c_[t, [creep(s) for s in t]], delimiter=",")
        comm.Barrier()
        mat = {"model": "tabulated", "file": str(shared_dir / "J.csv"), "quantity": "J"}
    else:
        mat = SLS
    dx = A_INF / 30
    raw = {"grid": {"nx": 156, "x": [-78 * dx, 78 * dx]}, "material": mat,
           "body": {"shape": "cylinder", "radius": R}, "motion": {"load": LOAD},
           "time": {"dt": TAU / 10, "end": 4 * TAU}, "solver": {"tol": 1e-10, "integrator": integrator}}
    _, records = run_to_end(raw, comm)
    assert len(records) == 41
    for r in records:
        a, centre = lee_radok(r.t)
        assert abs((r.lead - r.trail) / 2 - a) <= dx
        assert r.p_max == pytest.approx(centre, rel=tol)
    assert records[0].p_max / records[-1].p_max > 2.1  # the creep is seen (sqrt(5) = 2.24 at t -> inf)


# -- steady rolling: the second algorithm ------------------------------------------------------------------
def _log_moment(b: np.ndarray) -> np.ndarray:
    """int_0^inf exp(-t) ln|t + b| dt: ln b + e^b E1(b) (b > 0), ln|b| - e^b Ei(-b) (b < 0), -gamma (b = 0);
    the asymptotic series sum (-1)^k k!/b^(k+1) for the exponential parts where |b| > 40."""
    out = np.empty_like(b)
    big = np.abs(b) > 40
    pos, neg = (b > 0) & ~big, (b < 0) & ~big
    out[pos] = np.log(b[pos]) + np.exp(b[pos]) * exp1(b[pos])
    out[neg] = np.log(-b[neg]) - np.exp(b[neg]) * expi(-b[neg])
    out[b == 0] = -np.euler_gamma
    series, term = np.zeros(big.sum()), 1.0 / b[big]
    for k in range(16):
        series += term
        term = term * (-(k + 1) / b[big])
    out[big] = np.log(np.abs(b[big])) + series
    return out


def steady_rolling(v_tau: float, n: int = 400, half: float = 1.3 * A_INF):
    """Steady rolling at speed V of the cylinder under LOAD on the SLS, solved directly in the body frame
    xi = X - V t on n strips over [-half, half].

    In steady state every point's history is the body-frame field ahead of it: with U = A p (the strip
    kernel, unit compliance) and c = V tau, w(xi) = J0 U(xi) + (Jinf - J0)/c int_0^inf exp(-u/c)
    U(xi + u) du + const. For a strip source the integral is closed-form: with G(v) = v ln|v| - v,
    int_0^inf exp(-t) G(v + c t) dt = v ln|v| - v + c (ln c + m(v/c)), m = _log_moment. The (non-symmetric)
    linear complementarity problem with the load as a constraint is solved by an active set on the
    dense matrices. Returns x, p, mu_r.
    """
    dx = 2 * half / n
    x = -half + (np.arange(n) + 0.5) * dx
    offsets = np.arange(-(n - 1), n) * dx

    def xlogx(v):
        return np.where(v != 0, v * np.log(np.abs(np.where(v != 0, v, 1.0))), 0.0)

    def strip(f):  # -(2/pi) [F(y + dx/2) - F(y - dx/2)] on all offsets, as an n x n Toeplitz matrix
        k = -(2 / np.pi) * (f(offsets + dx / 2) - f(offsets - dx / 2))
        return k[np.arange(n)[:, None] - np.arange(n)[None, :] + n - 1]

    elastic = strip(lambda v: xlogx(v) - v)
    lagged = strip(lambda v: xlogx(v) - v + v_tau * (math.log(v_tau) + _log_moment(v / v_tau)))
    B = J0 * elastic + (JINF - J0) * lagged
    Z = x**2 / (2 * R)
    contact = np.abs(x) < A_INF
    for _ in range(100):
        idx = np.flatnonzero(contact)
        m = len(idx)
        K = np.zeros((m + 1, m + 1))
        K[:m, :m], K[:m, m], K[m, :m] = B[np.ix_(idx, idx)], -1.0, dx
        solution = np.linalg.solve(K, np.concatenate([-Z[idx], [LOAD]]))
        p = np.zeros(n)
        p[idx] = solution[:m]
        gap = Z + B @ p - solution[m]
        negative, inside = p < 0, ~contact & (gap < -1e-12 * abs(solution[m]))
        if not negative.any() and not inside.any():
            return x, p, float((p * x / R).sum() / p.sum())
        contact = (contact & ~negative) if negative.any() else (contact | inside)
    raise AssertionError("the steady active set did not settle")


def test_the_steady_solve_has_the_known_limits():
    """The second algorithm itself: relaxed Hertz shifted by e at slow speed (mu_r -> e/R), instantaneous
    Hertz at high speed (half-width a0 = a sqrt(J0/Jinf), peak 2P/(pi a0))."""
    v_tau = 1e-3 * A_INF
    _, _, mu = steady_rolling(v_tau)
    assert mu == pytest.approx(v_tau * (1 - J0 / JINF) / R, rel=0.01)
    x, p, mu = steady_rolling(1e3 * A_INF)
    a0 = A_INF * math.sqrt(J0 / JINF)
    assert p.max() == pytest.approx(2 * LOAD / (math.pi * a0), rel=2e-3)
    assert abs(x[p > 0].max() - a0) < 0.02 * a0 and abs(x[p > 0].min() + a0) < 0.02 * a0
    assert 0 < mu < 0.01 * a0 / R


STEADY_CASES = {  # V tau/a: (a/dx, rolled distance / a, steps per cell); 2-D memory: 2.5 V tau to settle
    0.01: (20, 2.5, 4), 0.1: (20, 3.0, 1), 1.0: (20, 6.0, 1), 10.0: (10, 25.0, 1)}


@pytest.fixture(scope="module")
def rolled():
    """petroll rolled from rest to steady state at each V tau/a of STEADY_CASES (the last step's record)."""
    out = {}
    for v_tau_a, (per, distance, steps) in STEADY_CASES.items():
        dx = A_INF / per
        lo, hi = -1.6 * A_INF, (distance + 1.6) * A_INF
        raw = {"grid": {"nx": int(round((hi - lo) / dx)), "x": [lo, hi]}, "material": SLS,
               "body": {"shape": "cylinder", "radius": R},
               "motion": {"load": LOAD, "velocity": v_tau_a * A_INF / TAU},
               "time": {"steps_per_cell": steps, "distance": distance * A_INF}}
        sim, records = run_to_end(raw, MPI.COMM_SELF)
        out[v_tau_a] = (records[-1], sim.scene.grid.dx)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("v_tau_a", list(STEADY_CASES))
def test_steady_rolling_agrees_with_the_direct_steady_solve(v_tau_a, rolled):
    """mu_r within 1.5 % (measured 0.16 % to 0.44 %; it peaks at 0.38 a/R near V tau/a = 1), the patch's
    edges within 1.5 strips and the peak pressure within 2 %."""
    record, dx = rolled[v_tau_a]
    x, p, mu = steady_rolling(v_tau_a * A_INF)
    h = x[1] - x[0]
    assert record.force == pytest.approx(LOAD, rel=1e-6)
    assert record.mu_r == pytest.approx(mu, rel=0.015)
    assert abs(record.lead - (x[p > 0].max() + h / 2)) <= 1.5 * dx
    assert abs(record.trail - (x[p > 0].min() - h / 2)) <= 1.5 * dx
    assert record.p_max == pytest.approx(p.max(), rel=0.02)


def test_slow_rolling_limit_through_a_sweep(tmp_path):
    """mu_r -> e/R, e = V int_0^inf (Jinf - J(s)) ds / Jinf = V tau (1 - J0/Jinf) (docs/line-contact.md: the
    same first-order argument as in 3-D); the sweep's mu_r_slow column is that limit and its V tau/a uses
    the contact half-width (area/2). At V tau/a = 0.01 and 0.02 the ratio is 1 - O(V tau/a)."""
    dx = A_INF / 20
    raw = {"grid": {"nx": 144, "x": [-1.6 * A_INF, -1.6 * A_INF + 144 * dx]}, "material": SLS,
           "body": {"shape": "cylinder", "radius": R}, "motion": {"load": LOAD, "velocity": 0.001},
           "time": {"steps_per_cell": 4, "distance": 4 * A_INF}}
    speeds = [f * A_INF / TAU for f in (0.01, 0.02)]
    vary = f"motion.velocity={speeds[0]!r},{speeds[1]!r}"
    table = sweep(parse_scene(raw), vary, tmp_path / "sweep", MPI.COMM_SELF, plot=False)
    c = table.columns
    e = np.array(speeds) * TAU * (1 - J0 / JINF)
    assert np.allclose(c["mu_r_slow"], e / R, rtol=1e-12)
    assert np.allclose(c["mu_r"] / c["mu_r_slow"], 1.0, atol=0.03)
    assert np.allclose(c["a"], A_INF * math.sqrt(J0 / JINF), rtol=1 / 8)  # the first step: J0's half-width
    assert np.all(c["steady"] == 1)
    assert table.line and "force (N/m)" in table.csv.read_text().splitlines()[0]  # per unit length


def test_wide_roller_mid_section_is_plane_strain(comm):
    """A 3-D roller 14 mm wide (rounded edges of 3 mm, 18 relaxed half-widths long) pressed elastically: the
    pressure across its mid-section equals the 2-D answer for the mid-section's own load per length (within
    0.5 % of the peak; measured 0.23 %), with the same contact width."""
    E, nu = 1e7, 0.3
    dx = math.sqrt(4 * 500.0 * R * (1 - nu**2) / E / math.pi) / 8
    nx, ny, dy = 40, 64, 0.25e-3
    elastic = {"model": "elastic", "E": E, "nu": nu}
    wide = parse_scene({"grid": {"nx": nx, "ny": ny, "x": [-nx * dx / 2, nx * dx / 2], "y": [-ny * dy / 2, ny * dy / 2]},
                        "material": elastic, "body": {"shape": "cylinder", "radius": R, "width": 14e-3,
                                                      "edge_radius": 3e-3},
                        "motion": {"penetration": 1.2e-4}, "solver": {"tol": 1e-10}})
    sim3 = Simulation(wide, comm)
    next(sim3.steps())
    rows = np.concatenate(comm.allgather(sim3.pressure))
    middle = rows[:, ny // 2 - 1 : ny // 2 + 1].mean(axis=1)  # the two cell rows either side of y = 0
    line_load = middle.sum() * dx
    sim2 = Simulation(parse_scene({"grid": {"nx": nx, "x": [-nx * dx / 2, nx * dx / 2]}, "material": elastic,
                                   "body": {"shape": "cylinder", "radius": R}, "motion": {"load": line_load},
                                   "solver": {"tol": 1e-10}}), comm)
    next(sim2.steps())
    line = np.concatenate(comm.allgather(sim2.pressure[:, 0]))
    assert 400 < line_load < 700 and (line > 0).sum() >= 14
    assert np.abs(line - middle).max() <= 5e-3 * line.max()
    assert np.array_equal(line > 0, middle > 0)


@pytest.mark.slow
def test_shipped_roller_scene_reaches_the_steady_solve(tmp_path):
    """runs/roller-2d.toml (V tau_creep/a = 0.51, tau_creep = tau_relax E0/Einf = 0.05 s) stops on its
    steady criterion with mu_r within 1 % of the direct steady solve (measured 0.11 %)."""
    from petroll.driver import run
    from petroll.model.scene import load_scene, shipped_scene

    scene = load_scene(shipped_scene("roller-2d.toml"))
    results = run(scene, MPI.COMM_SELF, tmp_path / "roller")
    steady = results.steady
    assert steady.reached and steady.force == pytest.approx(LOAD, rel=1e-6)
    _, _, mu = steady_rolling(float(scene.velocity(0.0)[0]) * 0.05)
    assert steady.mu_r == pytest.approx(mu, rel=0.01)
