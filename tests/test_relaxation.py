"""The semidefinite relaxation's certificates (mcfric.core.relaxation).

Checked independently of the solver: the multipliers it returns make ``Z`` positive
semidefinite by numpy's eigenvalues (dense, from the forms), its bounds enclose random
admissible points solved in physical space, and the verification rejects a ``Z`` that is
indefinite by a relative 1e-12.
"""

import numpy as np
import pytest

import mcfric
from mcfric.core import relaxation as rx
from mcfric.core.receptance import contact_space

from .test_certified import F_LIM, K_MAX, random_admissible


def problem(model, freq, beam):
    """The relaxation's arrays at one frequency: ``beam >= 0`` upper of that beam,
    ``beam < 0`` the lower bound of the metric."""
    a, b = model.dampers
    G, q0, ylin, H = contact_space(model.receptances(2 * np.pi * np.array([freq]))[0],
                                   model.force, a, b)
    nd, nb = len(a), model.n_beams
    nn, nv = nd + 1, 2 * nd + 1 + nb
    m = rx.n_forms(nd, nb, True, beam < 0)
    arrays = dict(V=np.empty((nn, nv), complex), idx=np.empty((m + 1, 2), np.int64),
                  S=np.empty((m + 1, 2, 2), complex), x=np.empty(m), cvec=np.empty(m),
                  pos=np.empty(m, bool), simplex=np.empty(m, bool), grow=np.empty(m, bool))
    shift, ys = rx.forms(G[0], q0[0], ylin[0], H[0], np.zeros(nd, complex),
                         np.full(nd, K_MAX + 1j * K_MAX), F_LIM, beam, *arrays.values())
    return arrays, shift, ys, rx.workspace(nn, nv, m)


def cold_solve(a, shift, ws):
    """:func:`mcfric.core.relaxation.solve` from a cold start, to full accuracy."""
    return rx.solve(a["x"], shift, a["V"], a["idx"], a["S"], a["cvec"], a["pos"],
                    a["simplex"], a["grow"], -np.inf, ws, np.zeros(2, np.int64), 0.0,
                    np.empty(len(a["x"]) + 1))


def dense_Z(a):
    """``Z = sum_i x_i A_i + A_const`` formed plainly in numpy."""
    V, idx, S, x = a["V"], a["idx"], a["S"], a["x"]
    Z = np.zeros((V.shape[0],) * 2, complex)
    for i in range(len(idx)):
        Vi = V[:, idx[i]]
        Z += (x[i] if i < len(x) else 1.0) * Vi @ S[i] @ Vi.conj().T
    return Z


@pytest.mark.parametrize("freq", [17.0, 52.0, 90.0])
def test_certificates_are_semidefinite_and_enclose_admissible_points(freq):
    model = mcfric.eight_beam(0.25)
    M = random_admissible(model, freq, 2000, 5)
    assert len(M) > 100
    upper = 0.0
    for beam in range(model.n_beams):
        a, shift, ys, ws = problem(model, freq, beam)
        t = cold_solve(a, shift, ws)
        assert np.isfinite(t) and t == a["x"][shift]
        assert np.all(a["x"][:shift] > 0)
        Z = dense_Z(a)
        assert np.linalg.eigvalsh(Z).min() >= -1e-14 * np.abs(Z).max()
        upper = max(upper, np.sqrt(t * ys))
    a, shift, ys, ws = problem(model, freq, -1)
    s = -cold_solve(a, shift, ws)
    lam = a["x"][a["simplex"]]
    assert np.all(lam > 0) and lam.sum() < 1
    Z = dense_Z(a)
    assert np.linalg.eigvalsh(Z).min() >= -1e-14 * np.abs(Z).max()
    lower = np.sqrt(max(s, 0.0) * ys)
    assert lower * (1 - 1e-9) <= M.min() and M.max() <= upper * (1 + 1e-9)
    # not vacuous (tightness: the last test)
    assert lower > 0.0


def test_verification_rejects_an_indefinite_Z():
    """At the least ``t`` that keeps ``Z`` semidefinite (the Schur complement, in numpy),
    ``t`` a relative 1e-12 lower fails the verification and 1e-6 higher passes."""
    model = mcfric.eight_beam(1.1)
    a, shift, ys, ws = problem(model, 90.0, 3)
    cold_solve(a, shift, ws)
    a["x"][shift] = 0.0
    Z = dense_Z(a)
    P, b = Z[:-1, :-1], Z[:-1, -1]
    t_least = -(Z[-1, -1].real - (b.conj() @ np.linalg.solve(P, b)).real)
    verify = (lambda: rx.verified(a["x"], a["V"], a["idx"], a["S"], len(a["x"]), a["pos"],
                                  a["simplex"], ws))
    a["x"][shift] = t_least * (1 - 1e-12)
    assert not verify()
    a["x"][shift] = t_least * (1 + 1e-6)
    assert verify()
    a["x"][0] = -1e-300
    assert not verify()


def test_relaxation_tightens_the_eight_beam_certificate():
    """With the relaxation the certified bounds come closer to their witnesses than the
    branch and bound alone, and still enclose the witnesses."""
    import mcfric.bounds.certified as certified
    from mcfric.bounds import compute_bounds

    model = mcfric.eight_beam(0.25)
    f = np.linspace(20, 140, 13)
    on = compute_bounds(model, f, K_MAX, F_lim=F_LIM, budget=50, moments=False).certificate
    try:
        certified.RELAX = False
        off = compute_bounds(model, f, K_MAX, F_lim=F_LIM, budget=50, moments=False).certificate
    finally:
        certified.RELAX = True
    assert np.all(on.upper <= off.upper) and np.all(on.lower >= off.lower)
    assert np.all(on.upper >= on.upper_witness) and np.all(on.lower <= on.lower_witness)
    assert np.median(on.upper_gap) < 0.5 * np.median(off.upper_gap)
    assert np.count_nonzero(on.lower_tight) > np.count_nonzero(off.lower_tight)


@pytest.mark.parametrize("freq", [52.0, 126.0])
def test_rounded_candidates(freq):
    """The rounded candidates at the relaxation's solution, eight beams, the beam of
    largest bound: the first is ``p_j / q_j`` of the leading eigenvector of ``Z^-1``
    (numpy's, from the dense ``Z``) clipped to the box; both lie in the box; and the
    measure by which the second is chosen (how far ``p_j / q_j`` leaves the box and
    ``p_j`` the force limit) agrees with numpy's at random points of the span of the
    three leading eigenvectors."""
    model = mcfric.eight_beam(1.1)
    best = None
    for beam in range(model.n_beams):
        a, shift, ys, ws = problem(model, freq, beam)
        t = cold_solve(a, shift, ws)
        if best is None or t * ys > best[0]:
            best = (t * ys, a, ws)
    _, a, ws = best
    V = a["V"]
    nd = V.shape[0] - 1
    K = np.empty((2, nd), complex)
    assert rx.rounded(a["x"], V, a["idx"], a["S"], K_MAX, K_MAX, F_LIM, ws, K)
    lam, U = np.linalg.eigh(np.linalg.inv(dense_Z(a)))

    def unclipped(z):
        z = z / z[nd]
        p = z[:nd] * np.diag(V[:nd, nd:2 * nd])
        return p / (V[:, :nd].conj().T @ z), p

    def leaving(z):
        Kz, p = unclipped(z)
        out = (np.maximum(-Kz.real, 0) + np.maximum(Kz.real - K_MAX, 0)
               + np.maximum(-Kz.imag, 0) + np.maximum(Kz.imag - K_MAX, 0)) / K_MAX
        return out.sum() + np.maximum(np.abs(p) / F_LIM - 1, 0).sum()

    K0, _ = unclipped(U[:, -1])
    np.testing.assert_allclose(K[0], np.clip(K0.real, 0, K_MAX) + 1j * np.clip(K0.imag, 0,
                                                                                 K_MAX),
                               rtol=1e-6, atol=1e-6 * K_MAX)
    assert np.all((K.real >= 0) & (K.real <= K_MAX) & (K.imag >= 0) & (K.imag <= K_MAX))
    # the measure the second candidate minimises, at random points of the span
    rng = np.random.default_rng(0)
    W = U[:, -3:] * np.sqrt(np.maximum(lam[-3:], 0))
    Kc = np.empty(nd, complex)
    for _ in range(20):
        z = W @ (rng.normal(size=3) + 1j * rng.normal(size=3))
        v = rx._candidate(z.copy(), V, K_MAX, K_MAX, F_LIM, Kc)
        Kz, _ = unclipped(z)
        assert v == pytest.approx(leaving(z), rel=1e-9, abs=1e-12)
        np.testing.assert_allclose(Kc, np.clip(Kz.real, 0, K_MAX)
                                   + 1j * np.clip(Kz.imag, 0, K_MAX), rtol=1e-9)
