"""Two-node rod (Nastran CROD/PROD): axial and torsional stiffness, translational mass.

All functions act on one element and return matrices in basic axes on
[grid A (T1, T2, T3, R1, R2, R3), grid B (...)].
"""

import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
from jaxtyping import Array, ArrayLike, Float

_BAR = np.array([[1.0, -1.0], [-1.0, 1.0]])
_CONSISTENT = np.array([[2.0, 1.0], [1.0, 2.0]]) / 6.0
_LUMPED = np.eye(2) / 2.0


def rod_stiffness(
    xa: Float[ArrayLike, "3"],
    xb: Float[ArrayLike, "3"],
    E: Float[ArrayLike, ""],
    G: Float[ArrayLike, ""],
    A: Float[ArrayLike, ""],
    J: Float[ArrayLike, ""],
) -> Float[Array, "12 12"]:
    """CROD stiffness: axial EA/L and torsion GJ/L along the rod axis e.

    ``K = [[1, -1], [-1, 1]] ⊗ blockdiag(EA/L·e eᵀ, GJ/L·e eᵀ)``
    (Przemieniecki 1968, *Theory of Matrix Structural Analysis*, ch. 5, pin-jointed bar,
    and the same form for uniform torsion).

    Args:
        xa, xb: grid positions in basic axes [m], shape (3,).
        E, G: Young's and shear moduli [Pa]; A: area [m²]; J: torsion constant [m⁴].

    Returns:
        (12, 12) symmetric stiffness [N/m, N·m/rad].
    """
    d = jnp.asarray(xb) - jnp.asarray(xa)
    L = jnp.linalg.norm(d)
    e = d / L
    ee = jnp.outer(e, e)
    return jnp.kron(_BAR, jsl.block_diag(E * A / L * ee, G * J / L * ee))


def rod_mass(
    xa: Float[ArrayLike, "3"],
    xb: Float[ArrayLike, "3"],
    rho: Float[ArrayLike, ""],
    A: Float[ArrayLike, ""],
    nsm: Float[ArrayLike, ""],
    lumped: bool,
) -> Float[Array, "12 12"]:
    """CROD mass: translational only, the same in all three directions.

    Consistent: m'L/6·[[2, 1], [1, 2]] per direction (linear interpolation,
    Przemieniecki 1968, ch. 11, pin-jointed bar); lumped: m'L/2 per node per direction.
    m' = rho·A + nsm.

    Args:
        xa, xb: grid positions in basic axes [m], shape (3,).
        rho: density [kg/m³]; A: area [m²]; nsm: non-structural mass [kg/m].
        lumped: static Python bool selecting the lumped matrix.

    Returns:
        (12, 12) symmetric mass [kg]; rotational rows/columns are zero.
    """
    L = jnp.linalg.norm(jnp.asarray(xb) - jnp.asarray(xa))
    pattern = _LUMPED if lumped else _CONSISTENT
    translations = jsl.block_diag(jnp.eye(3), jnp.zeros((3, 3)))
    return (rho * A + nsm) * L * jnp.kron(pattern, translations)
