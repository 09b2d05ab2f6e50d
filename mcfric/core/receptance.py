"""Modal receptances of the beams (paper Eq. 1) and the contact-space reduction.

Plain numpy (vectorised over frequencies); the numba kernels consume the arrays built here.

Receptance of one beam between positions p and q, ``omega`` in rad/s::

    d_pq(omega) = sum_k u_p^k u_q^k / (w_k^2 + 2 i zeta_k w_k omega - omega^2),  w_k = 2 pi f_k

with mass-normalised mode shapes (kg^-1/2), so receptances are in m/N.
"""

import numpy as np

#: Index of each receptance in the ``rec`` arrays' third axis: contact-contact (d11),
#: contact-drive (d13), output-contact (d21), output-drive (d23).
D11, D13, D21, D23 = 0, 1, 2, 3
#: Position columns of the per-beam shape array ``u``: contact, output, drive.
CONTACT, OUTPUT, DRIVE = 0, 1, 2


def receptance(omega, freq_hz, zeta, u_p, u_q):
    """Receptance between two positions of one beam or many beams.

    Parameters
    ----------
    omega : ndarray, shape (n_f,)
        Angular frequencies, rad/s.
    freq_hz, zeta : ndarray, shape (..., n_modes)
        Natural frequencies (Hz) and modal damping ratios (-).
    u_p, u_q : ndarray, shape (..., n_modes)
        Mass-normalised mode shapes at the two positions, kg^-1/2.

    Returns
    -------
    ndarray of complex, shape (..., n_f)
        Receptance in m/N.
    """
    omega = np.asarray(omega, dtype=float)
    wk = 2.0 * np.pi * np.asarray(freq_hz, dtype=float)[..., None, :]
    zk = np.asarray(zeta, dtype=float)[..., None, :]
    w = omega[:, None]
    num = (np.asarray(u_p, dtype=float) * np.asarray(u_q, dtype=float))[..., None, :]
    # an undamped mode hit exactly gives inf/nan: the kernel flags such points
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.sum(num / (wk * wk + 2j * zk * wk * w - w * w), axis=-1)


def beam_receptances(omega, freq_hz, zeta, u):
    """The four receptances per beam that the harmonic-balance kernel needs.

    Parameters
    ----------
    omega : ndarray, shape (n_f,)
        Angular frequencies, rad/s.
    freq_hz, zeta : ndarray, shape (n_r, n_beams, n_modes)
        Natural frequencies (Hz) and damping ratios (-) per beam; ``n_r`` is 1 for one
        linear rig shared by all samples, or the number of samples (mistuned rigs).
    u : ndarray, shape (n_beams, n_modes, 3)
        Mode shapes (kg^-1/2) at the contact, output and drive positions.

    Returns
    -------
    ndarray of complex, shape (n_r, n_f, 4, n_beams)
        ``rec[r, i, p, b]`` with ``p`` in (:data:`D11`, :data:`D13`, :data:`D21`,
        :data:`D23`), m/N. Contiguous per (r, frequency), the order the kernel reads it.
    """
    freq_hz = np.asarray(freq_hz, dtype=float)
    zeta = np.asarray(zeta, dtype=float)
    u = np.asarray(u, dtype=float)
    n_r, n_beams, _ = freq_hz.shape
    rec = np.empty((n_r, len(omega), 4, n_beams), dtype=np.complex128)
    for p, (i, j) in enumerate(((CONTACT, CONTACT), (CONTACT, DRIVE),
                                (OUTPUT, CONTACT), (OUTPUT, DRIVE))):
        d = receptance(omega, freq_hz, zeta, u[None, :, :, i], u[None, :, :, j])
        rec[:, :, p, :] = np.moveaxis(d, -1, 1)  # (n_r, n_beams, n_f) -> (n_r, n_f, n_beams)
    return rec


def difference_matrix(a, b, n_beams):
    """Difference matrix ``B`` (nd x n_beams): ``q = B y_contact``, row j = e_a - e_b."""
    B = np.zeros((len(a), n_beams))
    B[np.arange(len(a)), a] = 1.0
    B[np.arange(len(a)), b] = -1.0
    return B


def contact_space(rec, force, a, b):
    """Contact-space reduction of the linear array (docs: theory, "Contact-space reduction"), dense.

    With ``K = diag(K_j)`` the damper describing functions, the relative contact
    displacements solve ``(I + G K) q = q0`` and the output is ``y2 = y2_lin - H K q``.

    Parameters
    ----------
    rec : ndarray of complex, shape (n_f, 4, n_beams)
        Receptances of one rig from :func:`beam_receptances` (one ``r`` slice), m/N.
    force : ndarray of complex, shape (n_beams,)
        Force amplitudes at the drive positions, N.
    a, b : ndarray of int, shape (nd,)
        Beams coupled by each damper.

    Returns
    -------
    G : ndarray, shape (n_f, nd, nd)
        ``B D11 B^T``, m/N.
    q0 : ndarray, shape (n_f, nd)
        Relative contact displacement of the uncoupled array ``B D13 F``, m.
    y2_lin : ndarray, shape (n_f, n_beams)
        Output displacement of the uncoupled array ``D23 F``, m.
    H : ndarray, shape (n_f, n_beams, nd)
        ``D21 B^T``: output displacement per unit damper force ``f_j``, m/N.
    """
    n_beams = rec.shape[-1]
    B = difference_matrix(a, b, n_beams)
    d11, d13, d21, d23 = (rec[:, p, :] for p in (D11, D13, D21, D23))
    G = np.einsum("jb,fb,kb->fjk", B, d11, B)
    q0 = (d13 * force) @ B.T
    y2_lin = d23 * force
    H = d21[:, :, None] * B.T[None, :, :]
    return G, q0, y2_lin, H
