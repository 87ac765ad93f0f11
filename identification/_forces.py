"""Force appropriation methods at given exciters, thesis §3.4 and §5.4.1.

Each turns the responses at one frequency into a force vector (unit norm, largest
component positive): :func:`force_thesis`, the method of §3.4.2, superposes runs so as to
minimise the real-part response relative to the total (eq. 3.55, eq. 3.56, eq. 3.57,
eq. 3.58, eq. 3.59; predicted response eq. 3.60, eq. 3.61); :func:`force_lewis_wrisley`
takes mass × deflection at the exciters, as the appropriated force balances the damping
forces (eq. 3.52; Lewis & Wrisley 1950); :func:`force_asher` the null vector of the real
admittance at the exciters (Asher 1958); :func:`force_hunt` the eigenproblem of eq. 3.58
on the exciter responses weighted by the reduced mass matrix (Hunt et al. 1984). Full
references in :mod:`identification._phase_resonance`. NumPy/SciPy in float64/complex128.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sl
from jaxtyping import Complex, Float

from ._sine import _complex_array, _real_array

_SINGULAR_TOL = 1e-12  # relative smallest eigenvalue below which a Gram matrix is singular


def _normalise(f: np.ndarray) -> np.ndarray:
    """Unit Euclidean norm, largest-magnitude component positive (a force direction)."""
    f = f / np.linalg.norm(f)
    return f if f[np.argmax(np.abs(f))] > 0 else -f


def _gram_eig(R: np.ndarray, T: np.ndarray) -> tuple[float, np.ndarray] | None:
    """Smallest eigenpair of ``(R − λT)φ = 0`` (eq. 3.58); None where T is singular."""
    T = 0.5 * (T + T.T)
    tmax = float(np.max(np.linalg.eigvalsh(T)))
    if tmax <= 0 or float(np.min(np.linalg.eigvalsh(T))) <= _SINGULAR_TOL * tmax:
        return None
    lam, vec = sl.eigh(0.5 * (R + R.T), T)
    return float(lam[0]), vec[:, 0]


def force_thesis(
    U: Complex[np.ndarray, "n c"], forces: Float[np.ndarray, "e c"] | None = None
) -> Float[np.ndarray, " e"] | None:
    """Optimised force vector of thesis §3.4.2, eq. 3.55, eq. 3.56, eq. 3.57,
    eq. 3.58, eq. 3.59.

    The C runs (columns of ``U``: complex responses at all n measured DoFs, at one
    resonance frequency) are superposed with weights φ minimising
    ``φᵀ Re(U)ᵀRe(U) φ / φᵀ (Re(U)ᵀRe(U) + Im(U)ᵀIm(U)) φ`` (eq. 3.57): the eigenvector
    of the smallest eigenvalue of eq. 3.58. The force is ``[f̂¹ … f̂ᶜ] φ`` (eq. 3.59);
    the predicted response ``U φ`` (eq. 3.60, eq. 3.61) gives the predicted MIF.

    **Arguments:** ``U`` (n, C); ``forces`` (e, C) force vector of each run at the e
    exciters, or None for unit single-point runs (then e = C and the force is φ).

    **Returns:** the force vector (unit norm, largest component positive), or None where
    the runs are linearly dependent over the measured DoFs (e.g. C > 2n).
    """
    U = _complex_array("U", U, 2)
    F = np.eye(U.shape[1]) if forces is None else _real_array("forces", forces, 2)
    if F.shape[1] != U.shape[1]:
        raise ValueError(f"forces has {F.shape[1]} runs (columns) but U has {U.shape[1]}")
    R = U.real.T @ U.real
    pair = _gram_eig(R, R + U.imag.T @ U.imag)  # eq. 3.57, eq. 3.58
    if pair is None:
        return None
    f = F @ pair[1]  # eq. 3.59
    return _normalise(f) if np.linalg.norm(f) > 0 else None


def _mass_factor(name: str, masses, c: int) -> np.ndarray:
    """L with L Lᵀ = reduced mass matrix M_e (given as (c,) diagonal or (c, c))."""
    m = _real_array(name, masses)
    if m.shape == (c,):
        if np.any(m <= 0):
            raise ValueError(f"{name} must be positive, got {m.tolist()} (an exciter at a DoF without mass?)")
        return np.diag(np.sqrt(m))
    if m.shape != (c, c):
        raise ValueError(f"{name} must have shape ({c},) or ({c}, {c}), got {m.shape}")
    try:
        return np.linalg.cholesky(0.5 * (m + m.T))
    except np.linalg.LinAlgError:
        raise ValueError(f"{name} must be symmetric positive definite") from None


def force_lewis_wrisley(
    H_ee: Complex[np.ndarray, "c c"], masses: Float[np.ndarray, " c"] | Float[np.ndarray, "c c"]
) -> Float[np.ndarray, " c"]:
    """Force ∝ mass × deflection at the exciters, Lewis & Wrisley (1950); thesis §3.4, §5.4.1.

    Under damping proportional to mass the appropriated force ``ωDφ`` (eq. 3.52) is
    proportional to ``Mφ``; with the mass model reduced to the exciter points, M_e, the
    tuning sets ``f ← M_e Im(û_e)`` and repeats with the measured quadrature deflection
    at the exciters. Its fixed point is the eigenvector of ``M_e Im(H_ee)`` with the
    largest |eigenvalue| (found from the symmetric form ``Lᵀ Im(H_ee) L``, M_e = LLᵀ).

    **Arguments:** ``H_ee`` (C, C) admittance (m/N) between the exciters at the mode's
    frequency; ``masses`` (C,) lumped masses or (C, C) reduced mass matrix (kg).

    **Returns:** the force vector (unit norm, largest component positive).
    """
    H = _complex_array("H_ee", H_ee, 2)
    if H.shape[0] != H.shape[1]:
        raise ValueError(f"H_ee must be square (exciters × exciters), got shape {H.shape}")
    L = _mass_factor("masses", masses, H.shape[0])
    S = L.T @ (0.5 * (H.imag + H.imag.T)) @ L
    mu, v = np.linalg.eigh(S)
    return _normalise(L @ v[:, np.argmax(np.abs(mu))])


def force_hunt(
    H_ee: Complex[np.ndarray, "c c"], masses: Float[np.ndarray, " c"] | Float[np.ndarray, "c c"]
) -> Float[np.ndarray, " c"] | None:
    """Force from the real/total response eigenproblem at the exciters, Hunt et al. (1984).

    As thesis eq. 3.57, eq. 3.58 but, as the thesis describes Hunt's method (§5.4.1), with
    the responses at the exciter locations only and weighted by the reduced mass matrix:
    ``(Re Hᵀ M_e Re H) φ = λ (Re Hᵀ M_e Re H + Im Hᵀ M_e Im H) φ``, smallest λ.

    **Arguments:** ``H_ee`` (C, C) admittance between the exciters (m/N); ``masses``
    (C,) lumped masses or (C, C) reduced mass matrix (kg).

    **Returns:** the force vector (unit norm, largest component positive), or None when
    H_ee is singular.
    """
    H = _complex_array("H_ee", H_ee, 2)
    if H.shape[0] != H.shape[1]:
        raise ValueError(f"H_ee must be square (exciters × exciters), got shape {H.shape}")
    L = _mass_factor("masses", masses, H.shape[0])
    Re, Im = L.T @ H.real, L.T @ H.imag  # ‖L^T x‖² = xᵀ M_e x
    R = Re.T @ Re
    pair = _gram_eig(R, R + Im.T @ Im)
    return None if pair is None else _normalise(pair[1])


def force_asher(H_ee: Complex[np.ndarray, "c c"]) -> tuple[Float[np.ndarray, " c"], float]:
    """Null vector of the real admittance at the exciters, Asher (1958); thesis §3.4, §5.4.1.

    A normal mode needs ``Re(û_e) = Re(H_ee) f = 0``, non-trivial only where
    ``det Re(H_ee(ω)) = 0`` (Asher's indicator |H| = 0). At such a frequency the force
    is the eigenvector of Re(H_ee) with the smallest |eigenvalue|; :func:`appropriate`
    searches the frequency.

    **Arguments:** ``H_ee`` (C, C) admittance between the exciters (m/N).

    **Returns:** ``(force, ratio)``: the force (unit norm, largest component positive)
    and |smallest| / |largest| eigenvalue of Re(H_ee), 0 at an exact zero of the
    determinant.
    """
    H = _complex_array("H_ee", H_ee, 2)
    if H.shape[0] != H.shape[1]:
        raise ValueError(f"H_ee must be square (exciters × exciters), got shape {H.shape}")
    mu, v = np.linalg.eigh(0.5 * (H.real + H.real.T))
    i = int(np.argmin(np.abs(mu)))
    big = float(np.max(np.abs(mu)))
    return _normalise(v[:, i]), (float(abs(mu[i]) / big) if big > 0 else 0.0)
