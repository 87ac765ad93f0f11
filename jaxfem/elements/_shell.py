"""Flat shell elements: MITC4 quadrilateral and MITC3 triangle, with laminate properties.

Element frame (:func:`shell_frame`): normal n from the diagonals (quad) or the sides
(triangle), x along the G1→G2 side projected on the mean plane, y = n × x. Corners are
projected on the mean plane through their centroid; a warped quad is tied to its grids
by rigid links over the warping heights h_i (MacNeal 1994, *Finite Elements: their design
and performance*, §9.4), so rigid-body motions of the grids stay strain-free.
"""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float


def shell_frame(xyz: Float[ArrayLike, "nn 3"]) -> Float[Array, "3 3"]:
    """Rows x, y, n of the element frame in basic axes, for 3 or 4 corner positions [m]."""
    xyz = jnp.asarray(xyz)
    if xyz.shape[0] == 4:
        n = jnp.cross(xyz[2] - xyz[0], xyz[3] - xyz[1])
    else:
        n = jnp.cross(xyz[1] - xyz[0], xyz[2] - xyz[0])
    n = n / jnp.linalg.norm(n)
    side = xyz[1] - xyz[0]
    x = side - (side @ n) * n
    x = x / jnp.linalg.norm(x)
    return jnp.stack([x, jnp.cross(n, x), n])
