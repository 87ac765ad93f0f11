"""Small damped spring–mass chains with exact FRFs and modes, for the identification tests."""

import numpy as np
import scipy.linalg as sl

from identification import FRFData, Sensors


def chain(masses, springs, *, grounded=True, coupling=None):
    """M, K of a chain: spring j joins mass j−1 and j (spring 0 to ground when grounded).

    ``coupling``: extra (i, j, k) springs between masses i and j.
    """
    n = len(masses)
    M = np.diag(np.asarray(masses, dtype=np.float64))
    K = np.zeros((n, n))
    for j, k in enumerate(springs):
        if j == 0:
            if grounded:
                K[0, 0] += k
            continue
        K[np.ix_([j - 1, j], [j - 1, j])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    for i, j, k in coupling or ():
        K[np.ix_([i, j], [i, j])] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    return M, K


def modes(M, K, zeta):
    """Exact undamped frequencies (Hz), mass-normalised modes and the modal damping ratios."""
    lam, phi = sl.eigh(K, M)
    return np.sqrt(lam) / (2 * np.pi), phi, np.broadcast_to(np.asarray(zeta, dtype=np.float64), lam.shape).copy()


def receptance(M, K, zeta, f_hz, out_dofs, in_dofs):
    """Exact receptance (nf, n_out, n_in) with modal (proportional) viscous damping ζ_r."""
    fn, phi, z = modes(M, K, zeta)
    wn, w = 2 * np.pi * fn, 2 * np.pi * np.asarray(f_hz)
    den = wn[None, :] ** 2 - w[:, None] ** 2 + 2j * z[None, :] * wn[None, :] * w[:, None]
    return np.einsum("or,ir,kr->koi", phi[out_dofs], phi[in_dofs], 1 / den)


def frf_data(h, f_hz, out_dofs, in_dofs, *, noise=0.0, seed=0, kind="receptance", coherence=None):
    """FRFData with complex Gaussian noise of ``noise`` × |H| on every value."""
    rng = np.random.default_rng(seed)
    e = (rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape)) / np.sqrt(2)
    h = h * (1 + noise * e)
    w = 2 * np.pi * np.asarray(f_hz)[:, None, None]
    h = h * (1j * w) ** {"receptance": 0, "mobility": 1, "accelerance": 2}[kind]
    out = Sensors.from_components(np.asarray(out_dofs) + 1, [3] * len(out_dofs))
    inp = Sensors.from_components(np.asarray(in_dofs) + 1, [3] * len(in_dofs))
    return FRFData(f_hz, h, out, inp, kind, coherence=coherence)
