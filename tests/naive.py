"""Naive reference implementation for tests of ``mcfric`` (slow, plain, obviously correct).

Friction-damped beam arrays, single-harmonic describing-function harmonic balance, following
the conventions of docs/theory.md (sections "The rig" to "Single-harmonic balance", and
"Response bounds").

This module is formulated in PHYSICAL BEAM SPACE (the paper's Section 2.2): the full FRF matrix
D over the contact, output and drive positions of every beam, the physical damper stiffness
matrix Kphys = -B_c^T diag(K) B_c, and Y = (I - D Kphys)^-1 D F_ext solved directly.
It deliberately does NOT use the contact-space reduction (I + G diag(K)) q = q0 used by the package.

It must stay independent of mcfric: never import mcfric here, and do not copy its code.
Only numpy and scipy are used.
"""
import numpy as np
from scipy import optimize

# ----------------------------------------------------------------------------- linear pieces


def receptance(omega, freq_hz, zeta, u_p, u_q):
    """Receptance of one beam (paper Eq. 1). omega rad/s scalar or array; freq_hz, zeta, u_p, u_q:
    (n_modes,) arrays. Returns complex, shape of omega."""
    omega = np.asarray(omega, dtype=float)
    total = np.zeros(omega.shape, dtype=complex)
    for f, z, a, b in zip(np.atleast_1d(freq_hz), np.atleast_1d(zeta), np.atleast_1d(u_p), np.atleast_1d(u_q)):
        wk = 2.0 * np.pi * f
        total = total + a * b / (wk ** 2 + 2j * z * wk * omega - omega ** 2)
    return total


def describing_function(s, kc):
    """K(s) for Coulomb friction + tangential stiffness kc (docs/theory.md, "Describing function"): for 0<s<1 the
    partial-slip formulas, for s>=1 K=kc. Scalar in, complex out. Handles s==0 (K=0)."""
    s = float(s)
    if s < 0:
        raise ValueError("s must be >= 0")
    if s == 0.0:
        return 0j
    if s >= 1.0:
        return complex(kc)
    re = kc / np.pi * (np.arccos(1.0 - 2.0 * s) - 2.0 * (1.0 - 2.0 * s) * np.sqrt(s * (1.0 - s)))
    im = 4.0 * kc / np.pi * s * (1.0 - s)
    return complex(re, im)


def describing_function_derivative(s, kc):
    """dK/ds (complex) for 0<s<1 from the closed forms (docs/theory.md, "Describing function"); 0 for s>1.
    At s == 1 exactly the left (partial-slip) derivative is returned: d(Re K)/ds = 0, d(Im K)/ds = -4 kc/pi."""
    s = float(s)
    if s > 1.0:
        return 0j
    return complex(8.0 * kc / np.pi * np.sqrt(s * (1.0 - s)), 4.0 * kc / np.pi * (1.0 - 2.0 * s))


def pairs_for(n_beams, circular=False):
    """Damper list [(a_j, b_j)], 0-based: chain (j, j+1) for j<n-1; circular adds (n-1, 0)."""
    pairs = [(j, j + 1) for j in range(n_beams - 1)]
    if circular and n_beams > 2:
        pairs.append((n_beams - 1, 0))
    return pairs


def _dofs(n_beams, contact, output, drive):
    """Physical degrees of freedom: list of (beam, position) over the distinct positions, and a lookup dict."""
    positions = sorted({contact, output, drive})
    dofs = [(b, p) for b in range(n_beams) for p in positions]
    return dofs, {d: i for i, d in enumerate(dofs)}


def _frf_matrix(omega, beams, dofs):
    """Full physical FRF matrix D (block-diagonal over beams: no linear coupling between beams)."""
    n = len(dofs)
    D = np.zeros((n, n), dtype=complex)
    for i, (bi, pi) in enumerate(dofs):
        for k, (bk, pk) in enumerate(dofs):
            if bi == bk:
                bm = beams[bi]
                u = np.asarray(bm["u"], dtype=float)
                D[i, k] = receptance(omega, bm["freq_hz"], bm["zeta"], u[:, pi], u[:, pk])
    return D


def _damper_force_shapes(pairs, index, contact):
    """Matrix P (n_dofs, nd): column j is the physical force vector of a unit damper force f_j = 1,
    i.e. docs/theory.md 'beam forces B^T f': +1 at (a_j, contact) and -1 at (b_j, contact).
    (f_j = -K_j q_j then puts -K_j q_j on beam a_j and +K_j q_j on beam b_j.)"""
    P = np.zeros((len(index), len(pairs)))
    for j, (a, b) in enumerate(pairs):
        P[index[(a, contact)], j] += 1.0
        P[index[(b, contact)], j] -= 1.0
    return P


def _assemble(omega, beams, F, contact, output, drive):
    """Full physical FRF matrix D, external force vector Fext (at the drive points) and the dof lookup."""
    dofs, index = _dofs(len(beams), contact, output, drive)
    D = _frf_matrix(omega, beams, dofs)
    Fext = np.zeros(len(dofs), dtype=complex)
    for b in range(len(beams)):
        Fext[index[(b, drive)]] += F[b]
    return D, Fext, index


def _solve_physical(D, Fext, index, pairs, K, contact, output):
    """Y = (I - D Kphys)^-1 D Fext with the physical damper stiffness matrix Kphys assembled from K."""
    n_beams = len({b for (b, p) in index})
    Kphys = np.zeros(D.shape, dtype=complex)
    for j, (a, b) in enumerate(pairs):
        ia, ib = index[(a, contact)], index[(b, contact)]
        # force on a: -K (y_a - y_b); force on b: +K (y_a - y_b)
        Kphys[ia, ia] -= K[j]
        Kphys[ia, ib] += K[j]
        Kphys[ib, ia] += K[j]
        Kphys[ib, ib] -= K[j]
    Y = np.linalg.solve(np.eye(D.shape[0]) - D @ Kphys, D @ Fext)
    y_contact = np.array([Y[index[(b, contact)]] for b in range(n_beams)])
    y_output = np.array([Y[index[(b, output)]] for b in range(n_beams)])
    q = np.array([y_contact[a] - y_contact[b] for (a, b) in pairs], dtype=complex)
    return dict(y_contact=y_contact, y_output=y_output, q=q)


def beam_space_response(omega, beams, pairs, F, K, contact=0, output=1, drive=2):
    """Linear response of the array with given complex damper describing functions K (nd,).
    Builds the full physical FRF D (block-diagonal over beams, over the contact, output and drive
    positions of every beam), the physical damper stiffness matrix Kphys (f_j = -K_j q_j on beam a_j,
    +K_j q_j on beam b_j, q_j = y_{a_j,contact} - y_{b_j,contact}) and solves (I - D Kphys) Y = D Fext.
    Returns dict(y_contact=(n_beams,), y_output=(n_beams,), q=(nd,)), all complex."""
    D, Fext, index = _assemble(omega, beams, F, contact, output, drive)
    return _solve_physical(D, Fext, index, pairs, K, contact, output)


def linear_stuck_response(omega, beams, pairs, F, kc, contact=0, output=1, drive=2):
    """K = kc for every damper (mu0 N0 -> infinity limit); returns y_output (n_beams,) complex."""
    K = np.asarray(kc, dtype=float).astype(complex)
    return beam_space_response(omega, beams, pairs, F, K, contact, output, drive)["y_output"]


def uncoupled_response(omega, beams, F, contact=0, output=1, drive=2):
    """No dampers; y_output = d_23 F per beam (computed from Eq. 1 directly)."""
    out = []
    for b, bm in enumerate(beams):
        u = np.asarray(bm["u"], dtype=float)
        out.append(receptance(omega, bm["freq_hz"], bm["zeta"], u[:, output], u[:, drive]) * F[b])
    return np.array(out, dtype=complex)


# ----------------------------------------------------------------------------- nonlinear solve


def describing_function_cubic(s, kc):
    """K(s) of the stiffening spring f = kc (z + z^3 / (0.75 a^2)), a = mu0 N0 / kc:
    K = kc (1 + (A/a)^2) = kc (1 + 1/s^2) (the harmonic-balance term of a cubic spring)."""
    return complex(kc * (1.0 + 1.0 / float(s) ** 2))


def solve_point(omega, beams, pairs, F, mu0, N0, kc, contact=0, output=1, drive=2, starts=None,
                tol=1e-12, accept=1e-10, law="coulomb", first=False):
    """Nonlinear single-harmonic solve at one frequency (see module docstring for the formulation).
    Unknowns are s_j of the active dampers (mu0 N0 > 0 and kc > 0), solved in x = log s.
    tol: solver xtol; accept: a candidate is kept only if max_j |r_j|/(mu0_j N0_j) <= accept,
    r_j = s_j kc_j A_j(s) - mu0_j N0_j checked directly (solver flags are ignored).
    starts: optional list of s-vectors over the active dampers (or over all dampers).
    law: "coulomb" (the paper's damper) or "cubic" (describing_function_cubic).
    first: stop at the first root accepted (the full search's first root, found sooner).
    Returns a list of distinct roots dict(s, y_output, y_contact, residual); s is 0 for
    mu0 N0 == 0 dampers (also when kc == 0 too) and inf for kc == 0 dampers with mu0 N0 > 0.
    Note: if q_j vanishes identically (e.g. identical beams driven in phase) the stuck root is s = inf;
    rounding then makes A_j ~ 1e-21 and a huge finite s (~1e16) is returned; the response is still right."""
    mu0, N0, kc = (np.asarray(v, dtype=float) for v in (mu0, N0, kc))
    nd = len(pairs)
    fl = mu0 * N0                                   # friction limits mu0 N0
    active = [j for j in range(nd) if fl[j] > 0 and kc[j] > 0]
    s_fixed = np.array([0.0 if fl[j] == 0 else np.inf for j in range(nd)])

    def full_s(s_act):
        s = s_fixed.copy()
        s[active] = s_act
        return s

    D, Fext, index = _assemble(omega, beams, F, contact, output, drive)     # built once per frequency

    def response(s_act):
        s = full_s(s_act)
        df = describing_function if law == "coulomb" else describing_function_cubic
        K = np.array([df(s[j], kc[j]) if j in active else 0j for j in range(nd)])
        return _solve_physical(D, Fext, index, pairs, K, contact, output)

    def rel_residual(s_act):                      # r_j / (mu0_j N0_j)
        A = np.abs(response(s_act)["q"])[active]
        return (s_act * kc[active] * A - fl[active]) / fl[active]

    def g_log(x):                                 # log(s kc A / mu0 N0): linear in x on the stuck branch
        s_act = np.exp(np.clip(x, -700, 700))
        A = np.abs(response(s_act)["q"])[active]
        return np.log(np.maximum(s_act * kc[active] * A, 1e-300) / fl[active])

    def g_rel(x):
        return rel_residual(np.exp(np.clip(x, -700, 700)))

    if not active:
        r = response(np.zeros(0))
        return [dict(s=full_s(np.zeros(0)), y_output=r["y_output"], y_contact=r["y_contact"], residual=0.0)]

    na = len(active)
    if starts is None:
        q_stuck = np.abs(_solve_physical(D, Fext, index, pairs, kc.astype(complex), contact, output)["q"])
        s_lin = fl[active] / (kc[active] * np.maximum(q_stuck[active], 1e-300))
        rng = np.random.default_rng(0)
        starts = [np.ones(na), s_lin, np.full(na, 0.5), np.full(na, 0.1), np.full(na, 0.01)]
        starts += [10.0 ** rng.uniform(-2.5, 1.0, na) for _ in range(4)]
    starts = [np.asarray(s0, dtype=float) for s0 in starts]
    starts = [s0[active] if len(s0) == nd and na != nd else s0 for s0 in starts]

    def attempts(x0):
        """Candidates from a few solvers; exceptions and flags are ignored, residuals decide."""
        for g in (g_log, g_rel):
            for run in (lambda: optimize.fsolve(g, x0, xtol=tol, full_output=True)[0],
                        lambda: optimize.root(g, x0, method="hybr", options=dict(xtol=tol)).x,
                        lambda: optimize.root(g, x0, method="lm", options=dict(xtol=tol, ftol=tol)).x):
                try:
                    x = np.asarray(run(), dtype=float)
                except Exception:
                    continue
                if np.all(np.isfinite(x)):
                    yield x

    def polish(x):
        best, best_r = x, np.max(np.abs(g_rel(x)))
        for g in (g_log, g_rel, g_log):
            try:
                y = optimize.root(g, best, method="hybr", options=dict(xtol=tol)).x
            except Exception:
                continue
            ry = np.max(np.abs(g_rel(y))) if np.all(np.isfinite(y)) else np.inf
            if ry < best_r:
                best, best_r = y, ry
        return best, best_r

    roots = []
    for s0 in starts:
        x0 = np.log(np.clip(s0, 1e-8, 1e8))
        for x in attempts(x0):
            r = np.max(np.abs(g_rel(x)))
            if not np.isfinite(r) or r > 1e-3:
                continue                            # far from a root: not worth polishing
            x, r = polish(x)
            if r > accept:
                continue
            s_act = np.exp(x)
            if any(np.all(np.abs(s_act - rt["_s"]) <= 1e-6 * np.maximum(np.abs(s_act), np.abs(rt["_s"])))
                   for rt in roots):
                continue
            resp = response(s_act)
            roots.append(dict(_s=s_act, s=full_s(s_act), y_output=resp["y_output"],
                              y_contact=resp["y_contact"], residual=float(r)))
            if first:
                break
        if first and roots:
            break
    for rt in roots:
        del rt["_s"]
    return roots


# ----------------------------------------------------------------------------- bounds pieces


def force_bound(omega, beams, pairs, F, F_lim, output=1, contact=0, drive=2):
    """The force-only bound (paper Eq. 10; docs/theory.md, "Response bounds") at the output position:
    |(D F)_i| + F_lim * sum_j |(D B^T)_ij| per beam i. Returns (n_beams,) float."""
    n_beams = len(beams)
    D, Fext, index = _assemble(omega, beams, F, contact, output, drive)
    DF = D @ Fext
    DBT = D @ _damper_force_shapes(pairs, index, contact)    # (n_dofs, nd)
    out = np.zeros(n_beams)
    for i in range(n_beams):
        row = index[(i, output)]
        out[i] = abs(DF[row]) + F_lim * sum(abs(DBT[row, j]) for j in range(len(pairs)))
    return out


def metric_over_box_grid(omega, beams, pairs, F, k_max_re, k_max_im, n_grid, F_lim=None,
                         contact=0, output=1, drive=2):
    """Brute-force grid for ONE damper: M = max_b |y_output_b| for K = kr + i ki on an n_grid x n_grid
    grid over [0,k_max_re] x [0,k_max_im] (edges included); with F_lim, points with |K||q| > F_lim are
    discarded. Returns (min, max) of M over admissible points ((nan, nan) if none)."""
    if len(pairs) != 1:
        raise ValueError("metric_over_box_grid handles exactly one damper")
    D, Fext, index = _assemble(omega, beams, F, contact, output, drive)
    values = []
    for kr in np.linspace(0.0, k_max_re, n_grid):
        for ki in np.linspace(0.0, k_max_im, n_grid):
            K = np.array([complex(kr, ki)])
            r = _solve_physical(D, Fext, index, pairs, K, contact, output)
            if F_lim is not None and abs(K[0]) * abs(r["q"][0]) > F_lim:
                continue
            values.append(np.max(np.abs(r["y_output"])))
    if not values:
        return (np.nan, np.nan)
    return (min(values), max(values))


# ----------------------------------------------------------------------------- self-check

TABLE1 = dict(freq_hz=np.array([16.20, 105.8]), zeta=np.array([0.0017, 0.0071]),
              u=np.array([[2.55, 0.99, 0.48], [-1.84, 2.18, 1.42]]))

if __name__ == "__main__":
    np.set_printoptions(precision=5, linewidth=140)
    # (1) describing function continuity and derivative
    kc = 7000.0
    print("(1) K(1-1e-9) =", describing_function(1 - 1e-9, kc), " K(1) =", describing_function(1.0, kc),
          " K(0) =", describing_function(0.0, kc))
    assert abs(describing_function(1 - 1e-9, kc) - kc) < 1e-3
    worst = 0.0
    for s in np.linspace(0.01, 0.99, 50):
        h = 1e-6
        fd = (describing_function(s + h, kc) - describing_function(s - h, kc)) / (2 * h)
        worst = max(worst, abs(fd - describing_function_derivative(s, kc)) / kc)
    print("    max |dK/ds - finite difference| / kc =", worst)
    assert worst < 1e-6 and describing_function_derivative(2.0, kc) == 0
    # consistency of the physical-space solve with the force balance on the contact points
    beams2 = [TABLE1, TABLE1]
    w, Kt = 2 * np.pi * 40.0, np.array([3000 + 1500j])
    r = beam_space_response(w, beams2, pairs_for(2), np.array([0.22, 0]), Kt)
    d = [receptance(w, TABLE1["freq_hz"], TABLE1["zeta"], TABLE1["u"][:, 0], TABLE1["u"][:, k]) for k in (0, 2)]
    f = -Kt[0] * r["q"][0]
    assert np.allclose(r["y_contact"], [d[1] * 0.22 + d[0] * f, -d[0] * f], rtol=1e-12)

    # (2) two beams, Table 1 modes, F = [0.22, 0], N0 = 0.5
    F2, N0 = np.array([0.22, 0.0]), 0.5
    n_multi2 = 0
    print("(2) two beams")
    for fhz in (10.0, 16.2, 30.0, 60.0, 80.0, 105.8, 150.0):
        for m, k in ((0.05, 5000.0), (0.5, 5000.0), (0.8, 15000.0)):
            roots = solve_point(2 * np.pi * fhz, beams2, pairs_for(2), F2, [m], [N0], [k])
            n_multi2 += len(roots) > 1
            txt = "; ".join(f"s={rt['s'][0]:.6g} |y2|={np.abs(rt['y_output'])} res={rt['residual']:.1e}" for rt in roots)
            print(f"    f={fhz:6.1f} mu0={m:4.2f} kc={k:7.0f}: {len(roots)} root(s) {txt}")
            assert roots, "no root found"
    print("    two-beam points with >1 root:", n_multi2)

    # (3) limits: mu0 huge -> stuck linear; mu0 = 0 -> uncoupled
    print("(3) limits")
    for fhz in (12.0, 40.0, 110.0):
        w = 2 * np.pi * fhz
        rt = solve_point(w, beams2, pairs_for(2), F2, [1e9], [N0], [6000.0])
        lin = linear_stuck_response(w, beams2, pairs_for(2), F2, [6000.0])
        assert len(rt) == 1 and rt[0]["s"][0] > 1 and np.allclose(rt[0]["y_output"], lin, rtol=1e-12, atol=0)
        rt0 = solve_point(w, beams2, pairs_for(2), F2, [0.0], [N0], [6000.0])
        unc = uncoupled_response(w, beams2, F2)
        assert len(rt0) == 1 and np.allclose(rt0[0]["y_output"], unc, rtol=1e-12, atol=0)
        print(f"    f={fhz}: stuck s={rt[0]['s'][0]:.3g} matches linear_stuck; mu0=0 matches uncoupled")

    # (4) eight-beam chain, random samples and frequencies
    print("(4) eight beams")
    rng = np.random.default_rng(12345)
    nb = 8
    beams8 = [TABLE1] * nb
    F8 = 1.1 * np.cos(2 * np.pi * (np.arange(1, nb + 1) - 0.5) / nb)
    n_ok = n_multi = 0
    for t in range(20):
        fhz = rng.uniform(5.0, 150.0)
        mu, k = rng.uniform(0, 1, nb - 1), rng.uniform(0, 15000, nb - 1)
        roots = solve_point(2 * np.pi * fhz, beams8, pairs_for(nb), F8, mu, np.full(nb - 1, N0), k)
        n_ok += bool(roots)
        n_multi += len(roots) > 1
        M = [np.max(np.abs(rt["y_output"])) for rt in roots]
        print(f"    f={fhz:6.1f}: {len(roots)} root(s), M={np.array(M)}, "
              f"res={[float('%.1e' % rt['residual']) for rt in roots]}")
    print(f"    eight-beam: {n_ok}/20 points with an accepted root, {n_multi} with more than one distinct root")
