"""The quadratic forms of the admissible set and the barrier Newton ascent over all damper
forces (mcfric.core.quadratic_forms, mcfric.core.force_newton), checked by plain complex
arithmetic, central differences and physical-space solves."""

import numpy as np
import pytest

import mcfric
from mcfric.core import force_newton
from mcfric.core.quadratic_forms import PER_DAMPER, admissible_forms, response_form

from .test_certified import F_LIM, K_MAX, physical_grid
from .test_force_ascent import arrays

K_IM = 0.7 * K_MAX


def forms_at(G, q0, ylin, H, beam):
    nd = len(q0)
    n = 2 * nd + 1
    Mc = np.empty((PER_DAMPER * nd, n, n))
    admissible_forms(G, q0, np.zeros(nd, complex), np.full(nd, complex(K_MAX, K_IM)),
                     np.full(nd, F_LIM), Mc)
    My = np.empty((n, n))
    response_form(ylin, H, np.full(nd, F_LIM), beam, My)
    return Mc, My


def test_forms_equal_the_constraints_written_plainly():
    """Eight beams at 73 Hz, 50 random force vectors: every box and disc form is a fixed
    positive multiple of ``|q_j|^2`` times ``Re K``, ``k_max - Re K``, ``Im K``,
    ``k_max_im - Im K`` and ``rho^2 - |K - m|^2`` computed from ``p`` and ``q = q0 - G
    p`` directly; the force form is ``1 - |p_j / F_lim|^2`` and the response form
    ``|y_b|^2``."""
    model = mcfric.eight_beam(0.25)
    G, q0, ylin, H = (x[0] for x in arrays(model, np.array([73.0])))
    Mc, My = forms_at(G, q0, ylin, H, 3)
    rng = np.random.default_rng(1)
    m, rho2 = 0.5 * (K_MAX + 1j * K_IM), 0.25 * (K_MAX ** 2 + K_IM ** 2)
    ratios = []
    for _ in range(50):
        p = F_LIM * rng.uniform(0, 1, 7) * np.exp(2j * np.pi * rng.uniform(size=7))
        q = q0 - G @ p
        K = p / q
        z = np.concatenate([p.real, p.imag, [F_LIM]]) / F_LIM
        plain = np.stack([K.real, K_MAX - K.real, K.imag, K_IM - K.imag,
                          rho2 - np.abs(K - m) ** 2], axis=1) * np.abs(q[:, None]) ** 2
        got = np.einsum("a,cab,b->c", z, Mc, z).reshape(7, PER_DAMPER)
        ratios.append(got[:, :5] / plain)
        assert got[:, 5] == pytest.approx(1 - np.abs(p / F_LIM) ** 2, rel=1e-9, abs=1e-12)
        assert z @ My @ z == pytest.approx(abs(ylin[3] - H[3] @ p) ** 2, rel=1e-9)
    ratios = np.array(ratios)
    assert np.all(ratios > 0)
    assert np.allclose(ratios, ratios[0], rtol=1e-6)


def plain_phi(z, Mc, My, tau):
    g = np.einsum("a,cab,b->c", z, Mc, z)
    return np.log(z @ My @ z) + tau * np.log(g).sum()


def test_gradient_and_hessian_match_central_differences():
    """Eight beams at 45 Hz, beam 3, a strictly admissible point: the kernel's value equals
    the plain numpy objective, its gradient and Hessian central differences of it."""
    model = mcfric.eight_beam(0.25)
    G, q0, ylin, H = (x[0] for x in arrays(model, np.array([45.0])))
    Mc, My = forms_at(G, q0, ylin, H, 3)
    n = Mc.shape[1]
    sup = np.empty((len(Mc), n), np.int64)
    ns = np.empty(len(Mc), np.int64)
    force_newton.supports(Mc, sup, ns)
    assert ns.max() == 7  # on a chain: three dampers' forces and the constant
    rng = np.random.default_rng(0)
    K = 0.3 * K_MAX * (rng.uniform(0.2, 0.8, 7) + 1j * rng.uniform(0.2, 0.8, 7))
    q = np.linalg.solve(np.eye(7) + G * K[None, :], q0)
    p = K * q / F_LIM
    z = np.concatenate([p.real, p.imag, [1.0]])
    # inside every constraint (the forms are scaled by their largest coefficient)
    assert np.einsum("a,cab,b->c", z, Mc, z).min() > 1e-5
    tau = 1e-3
    g, Hs, w = np.zeros(n - 1), np.zeros((n - 1, n - 1)), np.zeros(n)
    v = force_newton._phi(z, Mc, sup, ns, My, tau, g, Hs, True, w)
    assert v == pytest.approx(plain_phi(z, Mc, My, tau), rel=1e-12)
    h = 1e-8
    for a in range(n - 1):
        e = np.zeros(n)
        e[a] = h
        num = (plain_phi(z + e, Mc, My, tau) - plain_phi(z - e, Mc, My, tau)) / (2 * h)
        assert g[a] == pytest.approx(num, rel=1e-5, abs=1e-6 * np.abs(g).max())
        gp, gm = np.zeros(n - 1), np.zeros(n - 1)
        force_newton._phi(z + e, Mc, sup, ns, My, tau, gp, np.zeros_like(Hs), True, w)
        force_newton._phi(z - e, Mc, sup, ns, My, tau, gm, np.zeros_like(Hs), True, w)
        assert Hs[a] == pytest.approx((gp - gm) / (2 * h), rel=1e-4,
                                      abs=1e-5 * np.abs(Hs).max())


@pytest.mark.parametrize("freq", [20.0, 73.0, 130.0])
def test_climb_is_admissible_and_never_loses(freq):
    """Eight beams, 1.1 N, 6 random admissible starts: the result is admissible in a
    physical-space solve, attains its value there and is no lower than the best start."""
    model = mcfric.eight_beam(1.1)
    G, q0, ylin, H = arrays(model, np.array([freq]))
    rng = np.random.default_rng(2)
    K0 = 10.0 ** rng.uniform(-3, 0, (6, 1)) * (rng.uniform(0, K_MAX, (6, 7))
                                                + 1j * rng.uniform(0, K_MAX, (6, 7)))
    M0, force0 = physical_grid(model, freq, K0)
    keep = force0 < 0.99
    starts = np.ascontiguousarray(K0[keep][None])
    K_out = np.zeros((1, 7), complex)
    M_out = np.full(1, -np.inf)
    force_newton.climb_frequencies(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, starts,
                                   np.zeros(1), np.full(1, np.inf), np.arange(1), K_out,
                                   M_out)
    W = K_out[0]
    assert np.all((W.real >= 0) & (W.real <= K_MAX) & (W.imag >= 0) & (W.imag <= K_MAX))
    M, force = physical_grid(model, freq, W[None])
    assert force[0] <= 1.0 + 1e-12
    assert M[0] == pytest.approx(M_out[0], rel=1e-9)
    assert M_out[0] >= M0[keep].max() * (1 - 1e-9)
