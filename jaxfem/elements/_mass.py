"""Concentrated grid mass (Nastran CONM2)."""

import jax.numpy as jnp
import jax.scipy.linalg as jsl
from jaxtyping import Array, ArrayLike, Float

from ._beam import skew


def conm2_mass(
    m: Float[ArrayLike, ""],
    offset: Float[ArrayLike, "3"],
    inertia: Float[ArrayLike, "3 3"],
) -> Float[Array, "6 6"]:
    """CONM2 6×6 mass at its grid, in basic axes (MSC Nastran QRG, CONM2).

    ``M = Tᵀ blockdiag(m I₃, I_cg) T`` with ``T = [[I, -skew(X)], [0, I]]``, i.e. the
    CG velocity is v_grid + ω × X (rigid-body kinetic energy about an offset point).

    Args:
        m: mass [kg].
        offset: X, CG position minus grid position in basic axes [m], shape (3,).
        inertia: (3, 3) inertia tensor about the CG in basic axes [kg·m²], already
            in tensor form [[I11, -I21, -I31], [-I21, I22, -I32], [-I31, -I32, I33]].

    Returns:
        (6, 6) symmetric mass on [T1, T2, T3, R1, R2, R3] of the grid.
    """
    eye = jnp.eye(3)
    t = jnp.block([[eye, -skew(offset)], [jnp.zeros((3, 3)), eye]])
    return t.T @ jsl.block_diag(m * eye, jnp.asarray(inertia)) @ t
