"""Material laws in frequency: the complex compliance of a Prony series against the Fourier integral of
its creep compliance J(t), computed by quadrature."""

import numpy as np
import pytest
from scipy import integrate

from petroll.model import materials


@pytest.mark.parametrize("material", [
    materials.sls(E0=100e6, Einf=5e6, nu=0.5, tau_relax=1e-3),
    materials.maxwell(2e6, 0.49, moduli=[30e6, 8e6, 1e6], times=[1e-5, 1e-3, 0.1]),
])
def test_complex_compliance_is_the_fourier_integral_of_the_creep(material):
    rate = lambda t: sum(d / tau * np.exp(-t / tau) for d, tau in zip(material.dJ, material.tau))  # noqa: E731
    # [0, 60 tau_max] in pieces that grow geometrically from tau_min / 100: exp(-60) is below round-off
    cuts = np.concatenate([[0.0], np.geomspace(min(material.tau) / 100, 60 * max(material.tau), 60)])
    for omega in (1e-2, 3.0, 400.0, 2e5, 1e8):
        cos = sum(integrate.quad(rate, a, b, weight="cos", wvar=omega, epsabs=0, limit=200)[0]
                  for a, b in zip(cuts[:-1], cuts[1:]))
        sin = sum(integrate.quad(rate, a, b, weight="sin", wvar=omega, epsabs=0, limit=200)[0]
                  for a, b in zip(cuts[:-1], cuts[1:]))
        expected = material(0.0) + cos - 1j * sin
        np.testing.assert_allclose(material.complex_compliance(omega), expected, rtol=1e-8)
    assert material.complex_compliance(-3.0) == pytest.approx(np.conj(material.complex_compliance(3.0)), rel=1e-14)
    assert material.complex_compliance(0.0) == pytest.approx(material.Jinf, rel=1e-14)
    assert np.isclose(material.complex_compliance(1e15).real, material.J0, rtol=1e-6)
    assert material.complex_compliance(3.0).imag < 0


def test_the_tabulated_complex_compliance_is_the_fourier_integral_of_its_table():
    """A piecewise linear J(t): the closed form per segment against quadrature of J'(t) = const per piece."""
    t = np.array([0.0, 1e-3, 4e-3, 2e-2, 0.1])
    J = np.array([1e-8, 2e-8, 3.5e-8, 4.5e-8, 5e-8])
    table = materials.Tabulated(tuple(t), tuple(J))
    slope = np.diff(J) / np.diff(t)
    for omega in (3.0, 400.0, 2e4):
        cos = sum(s * integrate.quad(lambda u: 1.0, a, b, weight="cos", wvar=omega)[0]
                  for s, a, b in zip(slope, t[:-1], t[1:]))
        sin = sum(s * integrate.quad(lambda u: 1.0, a, b, weight="sin", wvar=omega)[0]
                  for s, a, b in zip(slope, t[:-1], t[1:]))
        np.testing.assert_allclose(table.complex_compliance(omega), J[0] + cos - 1j * sin, rtol=1e-10)


@pytest.mark.slow
def test_the_characteristic_time_is_the_peak_of_the_loss_compliance():
    """An SLS: its creep time (the loss compliance dJ w tau / (1 + w^2 tau^2) peaks at w = 1/tau); a
    three-term Prony series: the peak found by brute force on a grid of 2e5 frequencies; the SLS sampled as a
    table: its creep time to the table's resolution; an elastic material: none."""
    sls = materials.sls(E0=10e6, Einf=2e6, nu=0.5, tau_relax=0.01)
    assert materials.loss_peak_time(sls) == pytest.approx(0.05, rel=1e-8)
    prony = materials.maxwell(2e6, 0.49, moduli=[30e6, 8e6, 1e6], times=[1e-5, 1e-3, 0.1])
    w = np.geomspace(1e-3, 1e8, 200001)
    loss = sum(d * w * tau / (1 + (w * tau) ** 2) for d, tau in zip(prony.dJ, prony.tau))
    assert materials.loss_peak_time(prony) == pytest.approx(1 / w[np.argmax(loss)], rel=2e-4)
    t = np.linspace(0.0, 1.0, 20001)
    table = materials.Tabulated(tuple(t), tuple(sls(t)))
    assert materials.loss_peak_time(table) == pytest.approx(0.05, rel=1e-3)
    assert np.isnan(materials.loss_peak_time(materials.elastic(1e7, 0.3)))
