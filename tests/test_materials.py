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
    assert material.complex_compliance(-3.0) == np.conj(material.complex_compliance(3.0))
    assert material.complex_compliance(0.0) == material.Jinf
    assert np.isclose(material.complex_compliance(1e15).real, material.J0, rtol=1e-6)
    assert material.complex_compliance(3.0).imag < 0
