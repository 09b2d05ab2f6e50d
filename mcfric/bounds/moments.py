"""A second-order moment relaxation of a chain's largest response, with a verified bound.

The relaxation of :mod:`mcfric.core.relaxation` (one matrix of products of the damper
forces, first order) is loose on long chains near resonances: there the bound can be
twice the largest admissible response. This is the next level of the same hierarchy
(Lasserre's moment relaxations), kept small by the chain's structure: in the real
coordinates ``x = (Re p, Im p) / F_lim`` every constraint of damper ``j``
(:mod:`mcfric.core.quadratic_forms`) involves only dampers ``j - 1 .. j + 1``, and a
beam's response only its own two, so the moments are those of monomials of degree <= 4
within each *clique* of three neighbouring dampers (six variables): one moment matrix
(28 x 28) per clique and one localising matrix (7 x 7) per constraint (Waki, Kim, Kojima
and Muramatsu's correlative sparsity).

It is solved by Clarabel (an interior-point conic solver, a dependency of mcfric), whose
answer is a floating-point approximation and proves nothing by itself. The bound is
therefore rebuilt from its dual, a sum-of-squares certificate: with the dual blocks
``Z_i`` made positive semidefinite with a margin (checked by their eigenvalues),
``r = q + A^T z`` the residual of the dual equations and ``s(x) = b - A y(x)`` the
constraint blocks at the moments ``y(x)`` of an admissible point,

    0 <= z . s(x) = z . b - (r - q) . y(x)   =>   f(x) <= c_0 + z . b + ||r||_1,

since every moment of an admissible point is at most 1 in modulus (``|x_i| <= 1``).
Rounding of the constraint coefficients is covered by a relative margin.

On a chain that is its own mirror image a beam's dual, reversed, is verified as the
mirror beam's certificate (:func:`mirrored_bound`, a tenth of a second instead of a
solve).
"""

from __future__ import annotations

import functools
import itertools
import math

import numpy as np

from .. import threads
from ..core.quadratic_forms import PER_DAMPER, admissible_forms, response_form

#: Relative margin for the rounding of the constraint coefficients and of the sums that
#: make the bound (the same spirit as the first-order relaxation's assembly margin).
MARGIN = 1e-10
#: Margin by which the dual blocks are made positive definite, relative to their norm.
PSD_MARGIN = 1e-9
#: Dampers per clique (neighbours of a chain).
WIDTH = 3
#: Clarabel's stopping tolerances (duality gap, absolute and relative, and feasibility;
#: its default 1e-8): the bound is rebuilt from whatever dual comes out, so a looser stop
#: only loosens it a little, by far less than the certificate's tolerance
#: (docs/performance.md). The scaled objective is of order one (the forces in units of
#: their proven limits; the first-order bound of it 0.5-6 on eight beams), so the
#: absolute gap is about a relative one.
SOLVER_TOL = 1e-5
#: Clarabel's static regularization of its KKT matrix (its default 1e-8): at the
#: default it often stopped short (``AlmostSolved``, ``NumericalError``) on the thin
#: parts of the branch and bound; with this it solves them, for tighter bounds at the
#: same cost (measured: docs/bounds.md, second-order moments).
STATIC_REGULARIZATION = 1e-7


def available():
    """Whether Clarabel is importable. It is a core dependency; an environment built
    without it gets a one-line error from :func:`mcfric.bounds.certified.check_moments`
    instead of a traceback."""
    try:
        import clarabel  # noqa: F401
    except ImportError:
        return False
    return True


def is_chain(G):
    """Whether the contact-space receptance ``G`` (nd, nd) couples only neighbouring
    dampers (a chain; rings and other graphs are not treated here)."""
    nd = G.shape[-1]
    band = np.abs(np.subtract.outer(np.arange(nd), np.arange(nd))) <= 1
    return bool(np.all(G[..., ~band] == 0))


def _monomials(variables, degree, nv):
    out = []
    for d in range(degree + 1):
        for c in itertools.combinations_with_replacement(variables, d):
            e = [0] * nv
            for i in c:
                e[i] += 1
            out.append(tuple(e))
    return out


def _svec_index(n):
    """Clarabel's PSD-triangle order: the upper triangle column by column."""
    ii, jj = [], []
    for j in range(n):
        for i in range(j + 1):
            ii.append(i)
            jj.append(j)
    return np.array(ii), np.array(jj)


@functools.lru_cache(maxsize=8)
def structure(nd):
    """Index tables of the relaxation for ``nd`` dampers (cached: they depend on nd only).

    Returns a dict: ``cliques`` (dampers), ``n_moments``, ``moment`` (per clique, the
    moment index of each entry of its moment matrix in svec order), ``local`` (per
    clique, shape (n_svec7, n_loc, n_loc): the moment index of basis_i * basis_j * z_a *
    z_b for the clique's local coordinates ``a, b`` (its six variables and the constant)),
    ``coords`` (per clique, the global coordinates of those, the constant last),
    ``clique_of`` (per damper, the clique holding its constraints) and ``first`` (the
    moment index of each variable ``x_i``)."""
    nv = 2 * nd
    if nd <= WIDTH:
        cliques = [list(range(nd))]
    else:
        cliques = [list(range(c, c + WIDTH)) for c in range(nd - WIDTH + 1)]
    zero = (0,) * nv
    unit = [tuple(int(i == k) for i in range(nv)) for k in range(nv)] + [zero]

    def add(*es):
        return tuple(map(sum, zip(*es)))

    variables = [d + [nd + j for j in d] for d in cliques]
    index = {zero: 0}

    def idx(e):
        if e not in index:
            index[e] = len(index)
        return index[e]

    moment, local, coords = [], [], []
    for v in variables:
        b2 = _monomials(v, 2, nv)
        ii, jj = _svec_index(len(b2))
        moment.append(np.array([idx(add(b2[i], b2[j])) for i, j in zip(ii, jj)]))
        b1 = _monomials(v, 1, nv)
        ii, jj = _svec_index(len(b1))
        co = v + [nv]
        table = np.empty((len(ii), len(co), len(co)), np.int64)
        for r, (i, j) in enumerate(zip(ii, jj)):
            for a, ca in enumerate(co):
                for b, cb in enumerate(co):
                    table[r, a, b] = idx(add(b1[i], b1[j], unit[ca], unit[cb]))
        local.append(table)
        coords.append(np.array(co))
    clique_of = [min(max(j - 1, 0), len(cliques) - 1) for j in range(nd)]
    first = np.array([index[unit[i]] for i in range(nv)])
    return dict(cliques=cliques, n_moments=len(index), moment=moment, local=local,
                coords=coords, clique_of=clique_of, first=first)


def _blocks(st, Mc, nd):
    """The constraint blocks ``s = b - A y'`` (``y'``: the moments but the constant one)
    as a sparse ``A``, the vector ``b`` and the block sizes."""
    import scipy.sparse as sp

    rows, cols, vals, sizes = [], [], [], []
    offset = 0
    for c, mom in enumerate(st["moment"]):
        n = int(round((math.sqrt(8 * len(mom) + 1) - 1) / 2))
        ii, jj = _svec_index(n)
        rows.append(offset + np.arange(len(mom)))
        cols.append(mom)
        vals.append(np.where(ii == jj, 1.0, math.sqrt(2.0)))
        sizes.append(n)
        offset += len(mom)
    for j in range(nd):
        c = st["clique_of"][j]
        table, co = st["local"][c], st["coords"][c]
        n = int(round((math.sqrt(8 * table.shape[0] + 1) - 1) / 2))
        ii, jj = _svec_index(n)
        scale = np.where(ii == jj, 1.0, math.sqrt(2.0))
        for f in range(PER_DAMPER * j, PER_DAMPER * (j + 1)):
            M = Mc[f][np.ix_(co, co)]
            rows.append(offset + np.repeat(np.arange(len(ii)), M.size))
            cols.append(table.reshape(len(ii), -1).ravel())
            vals.append((scale[:, None] * M.ravel()[None, :]).ravel())
            sizes.append(n)
            offset += len(ii)
    S = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(offset, st["n_moments"]))
    b = np.asarray(S[:, 0].todense()).ravel()
    return -S[:, 1:].tocsc(), b, sizes


def _objective(st, My, H_beam):
    """``|y_b|^2`` as moments: its coefficients (constant first), in a clique holding
    the beam's own dampers (``H_beam != 0``)."""
    own = set(np.flatnonzero(H_beam != 0).tolist())
    c = next((i for i, d in enumerate(st["cliques"]) if own <= set(d)), None)
    if c is None:
        raise ValueError("moments: a beam's own dampers are not neighbours (not a chain)")
    table, co = st["local"][c], st["coords"][c]
    # row 0 of the local table: basis_0 * basis_0 = 1, so entry (a, b) is z_a z_b
    coef = np.zeros(st["n_moments"])
    np.add.at(coef, table[0].ravel(), My[np.ix_(co, co)].ravel())
    return coef


def _unsvec(v, n):
    ii, jj = _svec_index(n)
    Z = np.zeros((n, n))
    w = np.where(ii == jj, v, v / math.sqrt(2.0))
    Z[ii, jj] = w
    Z[jj, ii] = w
    return Z


def _svec(Z):
    ii, jj = _svec_index(Z.shape[0])
    return np.where(ii == jj, Z[ii, jj], Z[ii, jj] * math.sqrt(2.0))


def _verified_dual(z, sizes):
    """The dual blocks made positive definite: negative eigenvalues clipped, then a shift
    of ``PSD_MARGIN`` times the block's norm; returns the vector, or None if a block's
    smallest computed eigenvalue is not clearly positive (a backward-stable eigensolver
    errs by a small multiple of n u ||Z||, far below the shift)."""
    out, o = [], 0
    for n in sizes:
        m = n * (n + 1) // 2
        Z = _unsvec(z[o:o + m], n)
        w, V = np.linalg.eigh(Z)
        norm = max(np.abs(w).max(), 1e-300)
        Zp = (V * np.maximum(w, 0.0)) @ V.T + PSD_MARGIN * norm * np.eye(n)
        Zp = 0.5 * (Zp + Zp.T)
        if np.linalg.eigvalsh(Zp).min() < 0.5 * PSD_MARGIN * norm:
            return None
        out.append(_svec(Zp))
        o += m
    return np.concatenate(out)


def box(nd, kr, ki):
    """The whole box as a part ``(lo, hi)``: each damper's rectangle ``[0, kr] x [0,
    ki]`` (N/m) by its corners."""
    return np.zeros(nd, np.complex128), np.full(nd, complex(kr, ki))


def _to_metres(value, sy):
    """The bound of ``|y_b|`` (m) from a verified dual value of the scaled objective,
    widened by ``MARGIN``."""
    return math.sqrt(max(value, 0.0) * sy) * (1 + MARGIN)


def force_limits(G, q0, kr, ki, F_lim, part=None):
    """Proven bounds of every damper force ``|p_j|`` (N) over the admissible set, at
    most ``F_lim``: each the first-order relaxation's (:mod:`mcfric.core.relaxation`)
    verified bound of the "response" ``p_j`` (``ylin = 0``, ``H = -I``), ``F_lim`` where
    it does not verify. Where the responses that matter need only small forces (near the
    first resonances at small drives) they are a tenth of ``F_lim``, and the second order
    in ``p / F_lim`` is badly scaled there (below). ``part``: ``(lo, hi)`` (N/m), the
    bounds over that part of the box instead (:mod:`.moments_branch`)."""
    nd = q0.shape[0]
    part = box(nd, kr, ki) if part is None else part
    H = -np.eye(nd, dtype=np.complex128)
    zero = np.zeros(nd, np.complex128)
    out = np.full(nd, float(F_lim))
    for j in range(nd):
        b = first_order_bound(G, q0, zero, H, F_lim, j, part)
        if 0.0 < b < math.inf:  # not verified (inf) keeps F_lim
            # outwards again, past the rounding of the coefficients built from it
            out[j] = min(out[j], b * (1.0 + 1e-12))
    return out


def first_order_bound(G, q0, ylin, H, F_lim, beam, part, goal=0.0):
    """The first-order relaxation's (:mod:`mcfric.core.relaxation`) verified bound of
    ``|y_beam|`` (m) over ``part`` (``(lo, hi)``, N/m) and the force limit ``F_lim`` (N);
    ``inf`` where it does not verify. It stops once it proves ``goal`` (m): milliseconds,
    where the second order takes about a second."""
    from ..core import relaxation as rx

    nd, nb = q0.shape[0], H.shape[0]
    V, idx, S, x, cvec, pos, simplex, grow, ws = rx.buffers(nd, nb, bool(np.isfinite(F_lim)),
                                                            False)
    lo, hi = part
    theta = np.full(len(x) + 1, np.nan)
    b = rx.relaxed_bound(G, q0, ylin, H, lo, hi, float(F_lim), np.int64(beam), float(goal),
                         V, idx, S, x, cvec, pos, simplex, grow, ws, np.zeros(5, np.int64),
                         theta, lo, hi)
    return b if b >= 0.0 else math.inf  # NaN: not verified


def problem(G, q0, ylin, H, kr, ki, F_lim, beam, limits=None, part=None):
    """The relaxation at one frequency for beam ``beam``, in Clarabel's form: maximise
    ``c_0 - q . y'`` subject to ``b - A y'`` in the PSD cones of ``sizes``; returns
    ``(A, b, q, c_0, sizes, sy)``, the objective scaled by ``1 / sy`` (m^2).

    ``limits`` (nd,; N): proven bounds of the damper forces over the admissible set
    (:func:`force_limits`; default ``F_lim``). The variables are then ``x_j = p_j /
    limits_j`` and the force forms ``1 - |x_j|^2``: the admissible set is unchanged, and
    every moment of an admissible point is still at most 1 in modulus. ``part``: a pair
    ``(lo, hi)`` of complex arrays (nd,; N/m), each damper's rectangle in a part of the
    box (:mod:`.moments_branch`); default the box."""
    nd = q0.shape[0]
    n = 2 * nd + 1
    st = structure(nd)
    scale = np.full(nd, float(F_lim)) if limits is None else limits
    if part is None:
        part = box(nd, kr, ki)
    Mc = np.empty((PER_DAMPER * nd, n, n))
    admissible_forms(G, q0, part[0], part[1], scale, Mc)
    My = np.empty((n, n))
    response_form(ylin, H, scale, beam, My)
    sy = np.abs(My).max()
    coef = _objective(st, My / sy, H[beam])
    A, b, sizes = _blocks(st, Mc, nd)
    return A, b, -coef[1:], coef[0], sizes, sy


def beam_bound(G, q0, ylin, H, kr, ki, F_lim, beam, limits=None, part=None):
    """A verified upper bound of ``|y_b|`` (m) over the admissible set at one frequency
    (``inf`` where the dual cannot be verified), and the relaxation's first moments as
    damper forces (N; a start for a witness; NaN where the solver did not converge).

    Parameters
    ----------
    G, q0, ylin, H : ndarray of complex
        One frequency's contact-space arrays; ``G`` must be a chain's (:func:`is_chain`).
    kr, ki, F_lim : float
        The box (N/m) and the force limit (N, finite).
    beam : int
    limits : ndarray of float, optional
        Proven bounds of the damper forces (N, :func:`force_limits`), used as the
        variables' scales and force limits; default ``F_lim``.
    part : tuple of ndarray, optional
        ``(lo, hi)``: the corners of each damper's rectangle (N/m) in a part of the box;
        the bound is then over that part. Default the box.

    Returns
    -------
    value : float
    p : ndarray of complex
    z : ndarray or None
        The solver's dual (for :func:`mirrored_bound`; None where it is not finite).
    """
    import clarabel

    nd = q0.shape[0]
    p = np.full(nd, np.nan + 0j)
    if not np.abs(H[beam]).max() > 0:
        return abs(ylin[beam]), p, None
    A, b, q, c0, sizes, sy = problem(G, q0, ylin, H, kr, ki, F_lim, beam, limits, part)
    best, best_z = math.inf, None
    # the bound holds for any dual, so one left by a solver that stopped short is
    # verified too (often within 1 % where the forces' scales are tight). Where it stops
    # short, its path depends on the data's last bits, so it solves once more with
    # Clarabel's default regularization and iterative refinement, and the better
    # verified bound is kept
    for refine in (False, True):
        sol = _solve(clarabel, A, b, q, sizes, refine)
        z = np.asarray(sol.z)
        solved = str(sol.status) in ("Solved", "AlmostSolved")
        value = (_to_metres(dual_bound(A, b, q, c0, z, sizes), sy)
                 if np.all(np.isfinite(z)) else math.inf)
        if value < best:
            best, best_z = value, z
            if solved:
                x = np.asarray(sol.x)[structure(nd)["first"] - 1]
                p = (F_lim if limits is None else limits) * (x[:nd] + 1j * x[nd:])
        if solved:
            break
    return best, p, best_z


def _solve(clarabel, A, b, q, sizes, refine):
    """Clarabel's solution of the relaxation in the form :func:`problem` returns, at
    ``SOLVER_TOL``: with ``STATIC_REGULARIZATION`` and no iterative refinement of the KKT
    solves, or, if ``refine``, with both at Clarabel's defaults."""
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.max_threads = 1
    if not refine:
        settings.static_regularization_constant = STATIC_REGULARIZATION
    # the bound is rebuilt from whatever dual comes out, so the KKT solves need no
    # refinement to full precision (that took about 40 % of the time, for bounds the same
    # to about 1e-4: docs/performance.md)
    settings.iterative_refinement_enable = refine
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = SOLVER_TOL
    settings.tol_ktratio = max(SOLVER_TOL, settings.tol_ktratio)
    # a frequency's relaxations are many solves in one task: Ctrl-C stops it between them
    threads.check()
    P = A[:0].T @ A[:0]  # an all-zero (n_moments - 1)^2 sparse matrix
    solver = clarabel.DefaultSolver(P.tocsc(), q, A, b,
                                    [clarabel.PSDTriangleConeT(s) for s in sizes], settings)
    return solver.solve()


def describing_functions(p, G, q0, kr, ki):
    """The describing functions (N/m) that forces ``p`` (N; the relaxation's first
    moments) take at their displacements ``q0 - G p``, clipped to the box ``kr``, ``ki``
    (N/m; zero where not finite)."""
    with np.errstate(all="ignore"):
        K = p / (q0 - G @ p)
    return np.clip(np.nan_to_num(K.real), 0, kr) + 1j * np.clip(np.nan_to_num(K.imag), 0, ki)


def mirrored_bound(G, q0, ylin, H, kr, ki, F_lim, beam, limits, z, sign, part=None):
    """A verified upper bound of ``|y_beam|`` (m) from the dual ``z`` that
    :func:`beam_bound` returned for the mirror beam ``nb - 1 - beam``, without solving.

    On a chain that is its own mirror image (dampers and beams in reverse order, ``q0``
    and ``H`` times ``sign``: :func:`mcfric.core.relaxation_branch.mirror_sign`) the map
    ``x -> sign * reversed(x)`` carries every constraint of one beam's relaxation into
    the other's and its objective into the other's, so the dual blocks, permuted and
    signed with it, are a certificate of the mirror beam. It is verified on this beam's
    own problem (:func:`dual_bound`) like any dual, so the bound is valid on any chain;
    where the chain is not a mirror image it is just loose. ``limits`` must then be the
    same on both sides (:func:`certified._second_order` takes the larger of each pair),
    and ``part`` the mirror beam's part reversed.
    """
    A, b, q, c0, sizes, sy = problem(G, q0, ylin, H, kr, ki, F_lim, beam, limits, part)
    src, sgn = _mirror_map(q0.shape[0], int(sign))
    return _to_metres(dual_bound(A, b, q, c0, sgn * z[src], sizes), sy)


@functools.lru_cache(maxsize=8)
def _mirror_map(nd, sign):
    """Indices ``src`` and signs ``sgn`` with ``sgn * z[src]`` the dual of the mirrored
    relaxation: the blocks of clique ``c`` and of damper ``j``'s forms go to clique
    ``n_c - 1 - c`` and damper ``nd - 1 - j``, each entry ``(a, b)`` (monomials ``m_a,
    m_b``) to the entry of the mirrored monomials, times ``sign ** (deg m_a + deg m_b)``."""
    st = structure(nd)
    nv = 2 * nd
    nc = len(st["cliques"])
    flip = [nd - 1 - i if i < nd else 2 * nd - 1 - (i - nd) for i in range(nv)]

    def image(e):
        out = [0] * nv
        for i, k in enumerate(e):
            out[flip[i]] = k
        return tuple(out)

    def variables(c):
        d = st["cliques"][c]
        return d + [nd + j for j in d]

    # (clique, degree) of every block in the dual's order, with its offset
    blocks = [(c, 2) for c in range(nc)]
    blocks += [(st["clique_of"][j], 1) for j in range(nd) for _ in range(PER_DAMPER)]
    target = list(range(nc - 1, -1, -1))
    target += [nc + PER_DAMPER * (nd - 1 - j) + f for j in range(nd) for f in range(PER_DAMPER)]
    offsets = [0]
    for c, deg in blocks:
        n = len(_monomials(variables(c), deg, nv))
        offsets.append(offsets[-1] + n * (n + 1) // 2)
    src = np.empty(offsets[-1], np.int64)
    sgn = np.empty(offsets[-1])
    for i, (c, deg) in enumerate(blocks):
        t = target[i]
        mine = _monomials(variables(c), deg, nv)
        theirs = {e: a for a, e in enumerate(_monomials(variables(blocks[t][0]), deg, nv))}
        pos = [theirs[image(e)] for e in mine]
        par = [sign ** sum(e) for e in mine]
        ii, jj = _svec_index(len(mine))
        # entry (a, b) of block i (the mirror beam's) goes to (pos a, pos b) of block t,
        # in svec order the upper triangle column by column
        for r, (a, b) in enumerate(zip(ii, jj)):
            u, v = sorted((pos[a], pos[b]))
            dest = offsets[t] + v * (v + 1) // 2 + u
            src[dest] = offsets[i] + r
            sgn[dest] = par[a] * par[b]
    return src, sgn


def dual_bound(A, b, q, c0, z, sizes):
    """The verified bound ``c_0 + z . b + ||r||_1`` (plus rounding margins) of the scaled
    objective from any dual vector ``z`` (``inf`` if its blocks cannot be made positive
    definite): valid whatever ``z`` is, only tighter the closer it is to optimal."""
    z = _verified_dual(z, sizes)
    if z is None:
        return math.inf
    r = A.T @ z + q
    # rounding of the coefficients (s(x) may be off by this much) and of the sums below
    slack = MARGIN * (np.abs(z) @ (np.abs(b) + abs(A) @ np.ones(A.shape[1]))
                      + np.abs(q).sum() + abs(c0))
    return c0 + z @ b + np.abs(r).sum() + slack
