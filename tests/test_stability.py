"""The stability suite's fast subset (petroll.studies.stability, docs/stability.md): every run's properties are
asserted by the suite itself (finite, contact conditions on the whole grid, dissipation, Lee-Radok bounds,
smoothness, clear refusals); here each fast case must come out ok or refused as expected. Plus the
integrators' holding test, the relaxation series and the command."""

import math

import numpy as np
import pytest

from petroll.model import materials as mat
from petroll.solver import history as integrators
from petroll.studies import stability
from petroll.errors import SolverError

FAST = [case for case in stability.cases() if case.fast]


@pytest.mark.slow
@pytest.mark.parametrize("case", FAST, ids=[f"{c.axis}:{c.name}" for c in FAST])
def test_fast_map_case_holds_its_properties(comm, case):
    row = stability.run_case(case, comm)
    assert row.status == ("refused" if case.refuse else "ok"), f"{row.failures} {row.note}"
    if row.status == "ok":
        assert row.contact <= 10 and row.p_min >= 0
        assert math.isnan(row.dissipation) or row.dissipation >= -1e-6
        assert math.isnan(row.smooth) or row.smooth <= 1


@pytest.mark.slow
def test_refinement_in_dt_and_dx_converges(comm):
    rows = stability.refinement(comm, fast=True)
    assert len(rows) == 3
    for row in rows:
        assert row.status == "ok", row.failures


def test_results_scale_as_the_analytic_scalings_say(comm):
    """Moduli 1e-3 and 1e12 Pa, radii 1e-6 and 10 m: F / (E R^2), mu_r, delta / R, area / R^2 unchanged."""
    rows = stability.scaling(comm, fast=True)
    for row in rows:
        assert row.status == "ok", row.failures


def test_the_sweep_finds_what_the_old_default_integrator_did_wrong(comm):
    """Evidence kept as a test: with the creep-form (exponential) integrator, unguarded, a held penetration
    with E0/Einf = 100 at dt = T/10 loses the contact (force 0 below the relaxed Hertz force); the
    relaxation form holds it at the relaxed value."""
    case = next(c for c in stability.cases() if c.name == "held penetration, E0/Einf = 100, dt = T/10")
    old = stability.run_case(case, comm, integrator="exponential", guard=False)
    assert old.status == "FAIL" and any("below the relaxed elastic force: 0 <" in f for f in old.failures)
    new = stability.run_case(case, comm)
    assert new.status == "ok", new.failures


# -- the integrators ----------------------------------------------------------------------------------------
MATERIALS = {
    "sls": mat.sls(10e6, 2e6, 0.5, tau_creep=0.05),
    "sls-1e4": mat.sls(1e8, 1e4, 0.5, tau_creep=1.0),
    "kelvin-3": mat.kelvin(2e6, 0.4, [1e-7, 3e-8, 2e-7], [1e-3, 0.1, 10.0]),
    "maxwell-9": mat.maxwell(1e5, 0.5, [1.1e6] * 9, list(np.geomspace(1e-4, 1e4, 9))),
}


@pytest.mark.parametrize("name", MATERIALS)
def test_relaxation_series_is_the_convolution_inverse_of_the_creep_compliance(name):
    """int_0^t G(t - s) dJ(s) = 1 for all t, and G(0) J(0) = G(inf) J(inf) = 1."""
    material = MATERIALS[name]
    Ginf, dG, theta = mat.relaxation_series(material)
    assert all(d > 0 for d in dG) and all(t > 0 for t in theta)
    assert (Ginf + sum(dG)) * material.J0 == pytest.approx(1, rel=1e-12)
    assert Ginf * material.Jinf == pytest.approx(1, rel=1e-14)
    # J is a sum of exponentials: the convolution has a closed form
    for t in (0.1 * min(theta), min(material.tau), max(material.tau), 10 * max(material.tau)):
        total = Ginf * material(0.0) + sum(d * math.exp(-t / th) for d, th in zip(dG, theta)) * material(0.0)
        for dJ, tau in zip(material.dJ, material.tau):  # dJ(s) = dJ/tau exp(-s/tau) ds
            total += Ginf * dJ * -math.expm1(-t / tau)
            for d, th in zip(dG, theta):  # int_0^t exp(-(t - s)/th) exp(-s/tau) ds
                rate = 1 / th - 1 / tau
                part = (math.exp(-t / tau) - math.exp(-t / th)) / rate
                total += d * dJ / tau * part
        assert total == pytest.approx(1, abs=1e-9)


@pytest.mark.parametrize("name", MATERIALS)
def test_the_relaxation_integrator_holds_a_penetration_exactly_at_any_step(name):
    material = MATERIALS[name]
    Ginf, dG, theta = mat.relaxation_series(material)
    for dt in (1e-6, 1e-3, 0.1, 10.0, 1e4):
        p = integrators.holding_response(material, "relaxation", dt, steps=12)
        exact = [Ginf + sum(d * math.exp(-n * dt / th) for d, th in zip(dG, theta)) for n in range(12)]
        assert p == pytest.approx(exact, rel=1e-10)
        assert integrators.holding_violation(material, "relaxation", dt) <= 1e-14


def amplification(material, integrator: str, dt: float) -> float:
    """docs/stability.md: what one step multiplies the held cell's pressure excess p - 1/Jinf by, for a
    one-term Prony material (E = exp(-dt/tau), beta = tau (1 - E)/dt, rho = 1 - J0/Jinf)."""
    (tau,), (dJ,) = material.tau, material.dJ
    E = math.exp(-dt / tau)
    if integrator == "paper":
        return (E * material.Jinf - dJ) / material.J0
    beta, rho = tau * (1 - E) / dt, 1 - material.J0 / material.Jinf
    return (E - rho * beta) / (1 - rho * beta)


@pytest.mark.parametrize("integrator", ["paper", "exponential"])
def test_the_creep_forms_hold_a_penetration_as_their_amplification_says(integrator):
    """The held cell's pressure is 1/Jinf + (1/J0 - 1/Jinf) A^n exactly (docs/stability.md's amplification
    A): decaying for small steps, ringing (A < 0) and, for the paper's scheme, growing (A < -1) for large."""
    material = MATERIALS["sls"]
    lo, hi = 1 / material.Jinf, 1 / material.J0
    for dt in (0.001, 0.01, 0.02, 0.05, 0.2):
        A = amplification(material, integrator, dt)
        exact = [lo + (hi - lo) * A**n for n in range(12)]
        held = integrators.holding_response(material, integrator, dt, steps=12)
        assert held == pytest.approx(exact, rel=1e-10)
    assert amplification(material, "paper", 0.2) < -1  # unstable
    assert -1 < amplification(material, "exponential", 0.2) < 0  # ringing


def test_the_guard_refuses_steps_at_which_the_creep_form_schemes_ring_or_blow_up():
    """The largest safe step is where the first undershoot, -A of the range, reaches GUARD_VIOLATION: the
    root of A(dt) = -GUARD_VIOLATION (E0/Einf = 5: 0.0113 s for the paper's scheme, 0.0220 s for the
    exponential one), which the guard's bisection (to 1 % in dt, from below) finds."""
    from scipy.optimize import brentq

    material = MATERIALS["sls"]  # E0/Einf = 5: relaxation time T = 0.01 s, creep time 0.05 s
    limit = integrators.GUARD_VIOLATION
    for integrator, dt in (("paper", 0.05), ("exponential", 0.05)):
        safe = brentq(lambda step: amplification(material, integrator, step) + limit, 1e-4, dt, xtol=1e-14)
        assert integrators.holding_violation(material, integrator, dt) > limit
        history = integrators.make_history(material, integrator, (2, 2))
        history.compliance(0.0)  # the sudden start is always fine
        history.compliance(0.001)
        with pytest.raises(SolverError, match=rf"integrator = '{integrator}' cannot hold a penetration .* "
                                              r"time step <= .* or integrator = \"relaxation\""):
            history.compliance(dt)
        assert safe * math.exp(-0.01) <= integrators.largest_safe_step(material, integrator, dt) <= safe
    unguarded = integrators.make_history(material, "paper", (2, 2), guard=False)
    unguarded.compliance(0.05)  # the unit tests of the recursions use unguarded histories


@pytest.mark.slow
def test_the_guard_covers_tabulated_materials_too():
    """The hereditary sum (the only scheme for a tabulated J) is the paper's: the same limit, no other
    remedy than the time step."""
    sls = MATERIALS["sls"]
    t = np.linspace(0.0, 1.0, 2001)
    table = mat.Tabulated(tuple(t), tuple(sls(t)))
    history = integrators.make_history(table, "paper", (1, 1))
    history.compliance(0.002)
    with pytest.raises(SolverError, match=r"integrator = 'paper' cannot hold .* time step <= [0-9.e-]+ s "
                                          r"\(fixed \[time\] dt, or more steps_per_cell\)$"):
        history.compliance(0.05)


def test_a_relaxation_history_rebuilds_its_displacement_when_its_state_is_set():
    """A restart that sets only pressure and q (the Maxwell fields s_k): the displacement W follows from them."""
    material = MATERIALS["kelvin-3"]
    a = integrators.make_history(material, "relaxation", (3, 4))
    rng = np.random.default_rng(2)
    for dt in (0.0, 0.01, 0.3, 2.0):
        a.advance(rng.random((3, 4)), dt)
    b = integrators.make_history(material, "relaxation", (3, 4))
    b.restore(a.pressure.copy(), [s.copy() for s in a.q])
    assert np.allclose(b.displacement, a.displacement, rtol=1e-12, atol=0)
    assert np.allclose(b.preceding(0.5), a.preceding(0.5), rtol=1e-11, atol=1e-300)


# -- the command -------------------------------------------------------------------------------------------
def test_stability_command_writes_the_map_and_fails_on_a_failed_run(comm, monkeypatch, capsys, shared_dir):
    from petroll.cli import main
    from petroll.studies.stability import runs  # where the sweep finds them

    keep = [c for c in FAST if c.name.startswith("held penetration, dt = 0.01 T")]
    monkeypatch.setattr(runs, "cases", lambda: keep)
    monkeypatch.setattr(runs, "refinement", lambda comm, fast: [])
    monkeypatch.setattr(runs, "scaling", lambda comm, fast: [])
    assert main(["stability", "--fast", "--out", str(shared_dir / "ok")]) == 0
    if comm.rank == 0:
        text = (shared_dir / "ok" / "stability.md").read_text()
        assert "held penetration, dt = 0.01 T | ok |" in text and "1 runs: 1 ok" in text
        assert (shared_dir / "ok" / "stability.csv").read_text().startswith("axis,case,status")
    broken = [stability.Case("dt", "expects a refusal that does not come", keep[0].raw, fast=True,
                              refuse=("never",))]
    monkeypatch.setattr(runs, "cases", lambda: broken)
    assert main(["stability", "--fast", "--out", str(shared_dir / "bad")]) == 1
    if comm.rank == 0:
        assert "petroll: FAIL dt / expects a refusal" in capsys.readouterr().out
