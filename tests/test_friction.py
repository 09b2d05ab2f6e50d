"""Describing function identities (physics.md section 2) against the plain formulas in naive.py."""

import numpy as np
import pytest

from mcfric.core.friction import describing_function, describing_function_derivative

from . import naive

KC = 7300.0


def test_matches_plain_formula():
    s = np.concatenate([np.linspace(1e-6, 1.0, 997), [0.0, 1.0, 1.5, 40.0, np.inf]])
    ours = describing_function(s, KC)
    ref = np.array([naive.describing_function(v, KC) for v in s])
    np.testing.assert_allclose(ours, ref, rtol=1e-13, atol=1e-12 * KC)


def test_continuous_at_stick_limit():
    below = describing_function(np.array([1.0 - 1e-12]), KC)[0]
    at = describing_function(np.array([1.0]), KC)[0]
    above = describing_function(np.array([1.0 + 1e-12]), KC)[0]
    assert abs(at - KC) == 0.0
    assert abs(below - KC) < 1e-9 * KC
    assert abs(above - KC) == 0.0
    # Re K is C1 at s = 1 (slope 0 from both sides); Im K has a kink (slope -4 kc/pi from below)
    d = describing_function_derivative(np.array([1.0 - 1e-10, 1.0 + 1e-10]), KC)
    assert abs(d[0].real) < 1e-3 * KC and d[1] == 0
    assert d[0].imag == pytest.approx(-4 * KC / np.pi, rel=1e-8)


@pytest.mark.parametrize("s0", [1e-4, 0.01, 0.2, 0.5, 0.77, 0.999])
def test_derivative_matches_finite_differences(s0):
    h = 1e-7 * s0
    fd = (describing_function(np.array([s0 + h]), KC)[0]
          - describing_function(np.array([s0 - h]), KC)[0]) / (2 * h)
    d = describing_function_derivative(np.array([s0]), KC)[0]
    assert abs(d - fd) <= 1e-6 * abs(d) + 1e-9 * KC


def test_gross_slip_limit_is_four_over_pi():
    """|K| A -> (4/pi) mu0 N0 as s -> 0: the first harmonic of a saturated Coulomb force."""
    mu0, N0 = 0.6, 0.5
    s = np.logspace(-10, -2, 9)
    A = mu0 * N0 / (KC * s)
    force = np.abs(describing_function(s, KC)) * A
    limit = 4 / np.pi * mu0 * N0
    assert np.all(force < limit * (1 + 1e-12))
    assert abs(force[0] / limit - 1) < 1e-4
    # monotone approach from below
    assert np.all(np.diff(force) < 0)


def test_dissipation_and_stiffness_signs():
    s = np.linspace(1e-6, 2.0, 500)
    K = describing_function(s, KC)
    assert np.all(K.real >= 0) and np.all(K.imag >= 0)
    assert np.all(K.real <= KC * (1 + 1e-15)) and np.all(K.imag <= KC)
