"""Describing function identities (docs/theory.md) against the plain formulas in naive.py."""

import math

import numba
import numpy as np
import pytest

from mcfric.core.friction import describing_function, describing_function_derivative, log_normal

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


@numba.njit
def _log_normal_all(x, out):
    for i in range(x.size):
        out[i] = log_normal(x[i])


@numba.njit
def _libm_log_all(x, out):
    for i in range(x.size):
        out[i] = math.log(x[i])


def test_log_normal_within_one_ulp_of_libm():
    """The branch-free log of the two-beam kernel over the whole normal range, its ends,
    the mantissa's split at sqrt(2), and around 1 (where log cancels)."""
    rng = np.random.default_rng(0)
    tiny, huge = np.finfo(float).tiny, np.finfo(float).max
    x = np.concatenate([
        np.exp(rng.uniform(np.log(tiny), np.log(huge), 2_000_000)),
        np.linspace(0.5, 2.0, 2_000_001),                        # one binade and more, densely
        1.0 + np.linspace(-1e-6, 1e-6, 200_001),
        np.nextafter(1.0, 0.0) ** np.arange(1, 100), np.nextafter(1.0, 2.0) ** np.arange(1, 100),
        np.sqrt(2.0) * (1 + np.linspace(-1e-12, 1e-12, 20_001)),
        np.ldexp(1.0, np.arange(-1022, 1024)), np.ldexp(np.sqrt(2.0), np.arange(-1022, 1023)),
        [tiny, np.nextafter(tiny, 1.0), huge, np.nextafter(huge, 0.0), 1.0, 2.0, 0.5]])
    ours = np.empty_like(x)
    _log_normal_all(x, ours)
    ref = np.empty_like(x)
    _libm_log_all(x, ref)
    assert ours[x == 1.0].max() == 0.0 == ours[x == 1.0].min()
    nz = ref != 0.0
    ulp = np.abs(ours[nz] - ref[nz]) / np.spacing(np.abs(ref[nz]))
    assert ulp.max() <= 1.0
    assert np.mean(ours != ref) < 0.1
