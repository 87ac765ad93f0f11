"""The viscous damping matrix of the model's dampers: CDAMP1–4, CVISC and B2GG.

``B`` on the solved DoFs, for :func:`jaxfem.frf_direct` (its ``D``): a CDAMP is
``b [[1, −1], [−1, 1]]`` on its two (point, component) DoFs (as a spring); a CVISC is
``CE n nᵀ`` on the translations and ``CR n nᵀ`` on the rotations of its two grids,
``[[X, −X], [−X, X]]``, with n the unit axis GA→GB (MSC QRG, CDAMP1, CVISC); B2GG is added
as the subcase selects it. Units: force·time/length (moment·time/rad for CR).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ._assembly import _UNIT, _reduce, node_transform, scalar_transform
from ._matrix import ElementMatrix
from ._model import Model


def _cvisc(model: Model, rows: np.ndarray):
    """12 × 12 basic blocks of the CVISC rows."""
    d = model.dampers
    xa, xb = model.xyz[d.nodes[rows, 0]], model.xyz[d.nodes[rows, 1]]
    n = (xb - xa) / np.linalg.norm(xb - xa, axis=1, keepdims=True)
    nn = np.einsum("ei,ej->eij", n, n)
    zero = np.zeros_like(nn)
    half = jnp.concatenate([
        jnp.concatenate([d.b[rows, None, None] * nn, zero], axis=2),
        jnp.concatenate([zero, d.br[rows, None, None] * nn], axis=2)], axis=1)  # (e, 6, 6)
    return jnp.concatenate([jnp.concatenate([half, -half], axis=2), jnp.concatenate([-half, half], axis=2)], axis=1)


def viscous_damping(model: Model) -> ElementMatrix:
    """B (solved DoFs) of the model's CDAMP, CVISC and B2GG; an empty matrix without any."""
    blocks, indices = [], []
    d = model.dampers
    if d is not None:
        scalar, axial = np.flatnonzero(~d.axial), np.flatnonzero(d.axial)
        if len(scalar):
            t, idx = scalar_transform(model, d.nodes[scalar], d.components[scalar])
            blocks.append(_reduce(t, d.b[scalar, None, None] * _UNIT))
            indices.append(idx)
        if len(axial):
            t, idx = node_transform(model, d.nodes[axial])
            blocks.append(_reduce(t, _cvisc(model, axial)))
            indices.append(idx)
    if model.direct is not None:
        t, idx = scalar_transform(model, model.direct.nodes[None], model.direct.components[None])
        blocks.append(_reduce(t, model.direct.b[None]))
        indices.append(idx)
    return ElementMatrix(blocks=tuple(blocks), indices=tuple(indices), massless=np.zeros(0, np.int64),
                         size=model.n_dof)
