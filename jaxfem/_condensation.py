"""Static condensation in NumPy: the transformation onto retained DoFs (Guyan 1965).

The condensed DoFs c follow the retained DoFs r statically: the rows of ``K u = 0`` at
the condensed DoFs, ``K_cr u_r + K_cc u_c = 0``, give

    u_c = −K_cc⁻¹ K_cr u_r,        u = T u_r,        T = [I; −K_cc⁻¹ K_cr]

(rows in DoF order, I at the retained rows), so that ``Tᵀ K T = K_rr − K_rc K_cc⁻¹ K_cr``
is the condensed stiffness and ``Tᵀ M T`` the Guyan mass. It is exact for DoFs without
mass (rotations of a lumped-mass model: :func:`identification.appropriate`) and a
Rayleigh–Ritz approximation otherwise.

Host-side float64 (not traced, not differentiated). :func:`jaxfem.eigh` condenses the
massless DoFs of its eigenproblem in JAX with the same T, its Cholesky factor of K_cc
reused by the derivative rule.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from jaxtyping import Float


def static_condensation(K: Float[np.ndarray, "n n"], retained: Sequence[int] | np.ndarray) -> Float[np.ndarray, "n r"]:
    """The static-condensation transformation ``T = [I; −K_cc⁻¹ K_cr]`` onto ``retained``.

    ``T`` has one row per DoF of ``K`` and one column per retained DoF, in the order of
    ``retained``: ``T[retained[j], j] = 1``, other retained rows 0, and at the condensed
    DoFs c (all others, ascending) ``T[c] = −K_cc⁻¹ K_cr`` (one solve with K_cc). Then
    ``Tᵀ K T = K_rr − K_rc K_cc⁻¹ K_cr`` and a mode on the retained DoFs φ_r extends as
    ``T φ_r`` (``φ_c = −K_cc⁻¹ K_cr φ_r``).

    **Arguments:** ``K``: (n, n) stiffness (its c × c and c × r blocks are used);
    ``retained``: distinct DoF indices in 0..n−1.

    **Raises:** ``ValueError`` for a non-square ``K`` or bad indices;
    ``numpy.linalg.LinAlgError`` (a ``ValueError``) naming the condensed DoFs when
    ``K_cc`` is singular: they form a mechanism, which nothing retained holds.
    """
    K = np.asarray(K)
    if K.ndim != 2 or K.shape[0] != K.shape[1]:
        raise ValueError(f"K must be a square matrix, got shape {K.shape}")
    n = K.shape[0]
    r = np.asarray(retained, dtype=np.int64).reshape(-1)
    if np.any((r < 0) | (r >= n)) or len(np.unique(r)) != len(r):
        raise ValueError(f"retained DoFs must be distinct indices in 0..{n - 1}, got {np.asarray(retained).tolist()}")
    c = np.setdiff1d(np.arange(n), r)
    T = np.zeros((n, len(r)))
    T[r, np.arange(len(r))] = 1.0
    if len(c):
        try:
            T[c] = -np.linalg.solve(K[np.ix_(c, c)], K[np.ix_(c, r)])
        except np.linalg.LinAlgError:
            shown = ", ".join(str(i) for i in c[:8]) + (f" and {len(c) - 8} more" if len(c) > 8 else "")
            raise np.linalg.LinAlgError(
                f"static condensation: K_cc, the stiffness of the {len(c)} condensed DoFs ({shown}), is singular: "
                "they form a mechanism that the retained DoFs do not hold"
            ) from None
    return T
