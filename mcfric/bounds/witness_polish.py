"""Upper witnesses improved by a gradient method, one beam at a time, where the
certificate stays loose.

The climbs of :mod:`mcfric.core.joint_ascent` and :mod:`mcfric.core.force_ascent` move
a few dampers at a time and aim at the beams of largest force bound. A maximum of
another beam whose basin is narrow in all dampers at once escapes them: on eight beams
at 0.22 N, 122.1 Hz, beam 2 reaches 1.04 % above the witness they found, with damper 1
at the force limit, dampers 0 and 6 open and every ``Im K`` zero, and SLSQP found it
from 2 of 60 random starts (docs/bounds.md). Where the certified upper bound is still
loose at the end, each beam whose proven bound lies above the witness's tolerance is
therefore maximised on its own by scipy's SLSQP in the normalised box coordinates
``(Re K / k_r, Im K / k_i)``, under the force limits ``|p_j| <= F_lim``, with exact
gradients, from the witness and ``STARTS`` random points (drawn from ``seed`` and the
frequency), one frequency after the other. The points it reaches are handed to
:func:`.certified.joint_witnesses`, which pulls them inside the force limit, evaluates
them with the package's kernels and keeps the best: a witness stays an admissible
point, whatever SLSQP's own constraint tolerance.
"""

from __future__ import annotations

import warnings

import numpy as np

#: Random starts per beam (besides the witness): half in the whole box, half with every
#: ``Im K = 0`` (the maxima seen there had no damping).
STARTS = 40
#: SLSQP's iterations per start at most and its tolerance on the objective (relative to
#: the witness's response).
MAX_ITER = 200
FTOL = 1e-10


def response_and_gradient(x, G, q0, ylin_b, H_b, kr, ki):
    """``|y_b|^2`` (m^2) at the normalised point ``x = (Re K / kr, Im K / ki)`` and its
    gradient in ``x``; also the forces ``p`` (N), their ``|p|^2`` and its Jacobian
    (nd, 2 nd).

    With ``T = I + K G`` the forces solve ``T p = K q0``, so ``dp/dK_j`` is column ``j``
    of ``T^-1`` times ``u_j = (q0 - G p)_j`` and ``y_b = ylin_b - H_b p`` moves by
    ``-(H_b T^-1)_j u_j``; both are analytic in ``K_j``, so the derivatives in ``Re K_j``
    and ``Im K_j`` are the real and imaginary parts of one complex number each."""
    nd = len(q0)
    K = x[:nd] * kr + 1j * x[nd:] * ki
    T = np.eye(nd) + K[:, None] * G
    Tinv = np.linalg.inv(T)
    p = Tinv @ (K * q0)
    u = q0 - G @ p
    y = ylin_b - H_b @ p
    dy = -(H_b @ Tinv) * u  # d y / d K_j
    gy = 2.0 * np.conj(y) * dy
    grad = np.concatenate([gy.real * kr, -gy.imag * ki])
    dp = Tinv * u[None, :]  # d p_m / d K_j
    gp = 2.0 * np.conj(p)[:, None] * dp
    jac = np.concatenate([gp.real * kr, -gp.imag * ki], axis=1)
    return abs(y) ** 2, grad, p, np.abs(p) ** 2, jac


def beam_maxima(G, q0, ylin_b, H_b, kr, ki, F_lim, x_starts, scale):
    """SLSQP's local maxima of ``|y_b|`` over the admissible set from each row of
    ``x_starts`` (normalised box coordinates), as describing functions (n_starts, nd;
    N/m; NaN rows where it failed). ``scale`` (m): the response it is measured in."""
    from scipy.optimize import minimize

    nd = len(q0)
    s2 = scale ** 2
    last = {}

    def at(x):
        # SLSQP asks for the objective, the constraints and their Jacobian at the same
        # point one after the other: one solve serves all three
        key = x.tobytes()
        if last.get("key") != key:
            last["key"] = key
            last["value"] = response_and_gradient(x, G, q0, ylin_b, H_b, kr, ki)
        return last["value"]

    def objective(x):
        v, g, *_ = at(x)
        return -v / s2, -g / s2

    cons = {"type": "ineq", "fun": lambda x: 1.0 - at(x)[3] / F_lim ** 2,
            "jac": lambda x: -at(x)[4] / F_lim ** 2}
    out = np.full((len(x_starts), nd), np.nan + 0j)
    for i, x0 in enumerate(x_starts):
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            try:
                r = minimize(objective, x0, jac=True, method="SLSQP",
                             bounds=[(0.0, 1.0)] * (2 * nd), constraints=[cons],
                             options=dict(maxiter=MAX_ITER, ftol=FTOL))
            except (ValueError, np.linalg.LinAlgError):
                continue
        x = np.clip(r.x, 0.0, 1.0)
        if np.all(np.isfinite(x)):
            out[i] = x[:nd] * kr + 1j * x[nd:] * ki
    return out


def starts(K, kr, ki, n, rng):
    """The witness ``K`` (nd,; N/m) in normalised coordinates and ``n`` random points:
    (n + 1, 2 nd)."""
    nd = len(K)
    x = rng.random((n, 2 * nd))
    x[::2, nd:] = 0.0
    return np.vstack([np.r_[np.clip(K.real / kr, 0, 1), np.clip(K.imag / ki, 0, 1)], x])


def polish(args, kr, ki, F_lim, K, wit, freqs, beams, seed=0):
    """Witnesses improved at ``freqs`` by SLSQP's maxima of the beams ``beams[i]`` (a
    list of beam indices per frequency of ``freqs``), each from the witness and
    ``STARTS`` random points. ``args``: the contact-space arrays; ``K`` (n_f, nd; N/m)
    and ``wit`` (n_f; m) are updated in place where a point found is better."""
    from .certified import joint_witnesses

    G, q0, ylin, H = args
    nd = q0.shape[1]
    # one frequency after the other: a few are polished, and SLSQP and the warnings
    # filter are not to be relied on across threads (the result must not depend on them)
    for k, beams_k in zip(freqs, beams):
        rng = np.random.default_rng([seed, int(k)])
        xs = starts(K[k], kr, ki, STARTS, rng)
        # the objective in units of the witness's response (never zero: K = 0 is a start)
        scale = max(wit[k], np.abs(ylin[k]).max(), 1e-30)
        found = [beam_maxima(G[k], q0[k], ylin[k, b], H[k, b], kr, ki, F_lim, xs, scale)
                 for b in beams_k]
        found = np.concatenate(found) if found else np.empty((0, nd), complex)
        found = found[~np.isnan(found[:, 0])]
        if not len(found):
            continue
        one_f = [np.ascontiguousarray(a[k:k + 1]) for a in args]
        Kw, Mw = joint_witnesses(one_f, kr, ki, F_lim, found[None], np.array([np.inf]),
                                 pool=0, climb=len(found), seed=seed + int(k))
        if Mw[0] > wit[k]:
            K[k] = Kw[0]
            wit[k] = Mw[0]
