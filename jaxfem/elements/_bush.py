"""Two-node spring (Nastran CBUSH/PBUSH) with uncoupled stiffnesses in element axes."""

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._beam import rigid_offset, to_basic

_BAR = np.array([[1.0, -1.0], [-1.0, 1.0]])


def bush_stiffness(
    xa: Float[ArrayLike, "3"],
    xb: Float[ArrayLike, "3"],
    axes: Float[ArrayLike, "3 3"],
    k: Float[ArrayLike, "6"],
    s: Float[ArrayLike, ""],
) -> Float[Array, "12 12"]:
    """CBUSH stiffness in basic axes (MSC Nastran QRG, CBUSH/PBUSH).

    Six uncoupled springs K1..K6 along/about the element axes act on the relative
    motion of two coincident end points at the spring point p = xa + s (xb - xa),
    each rigidly linked to its grid: ``K = Tᵀ Λᵀ ([[1, -1], [-1, 1]] ⊗ diag(k)) Λ T``
    with T = rigid_offset(p - xa, p - xb).

    Args:
        xa, xb: grid positions in basic axes [m], shape (3,); may coincide.
        axes: (3, 3) rows are the element x, y, z unit vectors in basic axes.
        k: (6,) stiffnesses K1..K3 [N/m] and K4..K6 [N·m/rad].
        s: spring location as a fraction of A→B [-] (Nastran S, default 0.5).

    Returns:
        (12, 12) symmetric stiffness on [grid A 6 DoFs, grid B 6 DoFs].
    """
    xa = jnp.asarray(xa)
    xb = jnp.asarray(xb)
    p = xa + s * (xb - xa)
    k_local = jnp.kron(_BAR, jnp.diag(jnp.asarray(k)))
    t = rigid_offset(p - xa, p - xb)
    return t.T @ to_basic(axes, k_local) @ t
