"""Structural (hysteretic) damping of elements and the modal strain energies it acts through.

An element with loss factor η_e (Nastran GE) adds ``iη_e K_e`` to the dynamic stiffness
(Ewins, *Modal Testing*, §2.3): ``G = Σ_e η_e K_e`` (:func:`damping_matrix`). To first
order in the damping the real modes stay, and mode n gets the modal loss factor

    η_n = φ_nᵀ G φ_n / φ_nᵀ K φ_n = Σ_e η_e E_en / λ_n,   E_en = φ_nᵀ K_e φ_n

(modal strain energy; Ungar & Kerwin 1962, Johnson & Kienholz 1982), i.e. the viscous
ratio ζ_n = η_n / 2 at resonance. The element energies E come from one reverse-mode
derivative of the assembly, which is linear in each element's ``k_scale``
(:func:`element_strain_energies`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ._assembly import assemble
from ._model import STIFFNESS_BLOCKS, Model


def stiffness_ids(model: Model) -> Int[np.ndarray, " nk"]:
    """Ids of the elements with stiffness, in the order of :data:`jaxfem.STIFFNESS_BLOCKS`."""
    return np.concatenate([np.asarray(getattr(model, b).ids, dtype=np.int64) for b in STIFFNESS_BLOCKS])


def with_k_scale(model: Model, factor: Float[Array, " nk"]) -> Model:
    """``model`` with each stiffness element's ``k_scale`` multiplied by ``factor`` (in the
    order of :func:`stiffness_ids`)."""
    start = 0
    for name in STIFFNESS_BLOCKS:
        block = getattr(model, name)
        n = len(block.ids)
        model = eqx.tree_at(lambda m, name=name: getattr(m, name).k_scale, model,
                            block.k_scale * factor[start:start + n])
        start += n
    return model


def _loss_weights(model: Model) -> Float[Array, " nk"]:
    """η_e per stiffness element (order of :func:`stiffness_ids`), 0 where none is set."""
    ids = stiffness_ids(model)
    if model.damping is None:
        return jnp.zeros(len(ids))
    d = model.damping
    missing = sorted(set(d.eids) - set(ids.tolist()))
    if missing:
        raise ValueError(f"structural damping on element(s) {missing[:10]}: not elements with stiffness")
    at = {e: i for i, e in enumerate(d.eids)}
    pick = np.asarray([at.get(int(e), -1) for e in ids])
    return jnp.where(jnp.asarray(pick >= 0), jnp.asarray(d.eta)[np.maximum(pick, 0)], 0.0)


def damping_matrix(model: Model):
    """``G = Σ_e η_e K_e`` (N/m) of the model's element loss factors (``model.damping``;
    zero without), as the stiffness operator of :func:`jaxfem.assemble`."""
    return assemble(with_k_scale(model, _loss_weights(model)))[0]


def element_strain_energies(model: Model, phi: Float[Array, "n m"]) -> Float[Array, "nk m"]:
    """``E_en = φ_nᵀ K_e φ_n`` (J for unit modal amplitude; ``φ`` mass-normalised gives
    Σ_e E_en = λ_n) of every stiffness element (rows in the order of :func:`stiffness_ids`)
    and mode (columns of ``phi``, solved DoFs)."""
    phi = jnp.asarray(phi)

    def modal(weights):  # φ_nᵀ K(weights) φ_n: linear in the element weights
        return jnp.sum(phi * assemble(with_k_scale(model, weights))[0].matmul(phi), axis=0)

    return jax.jacrev(modal)(jnp.ones(len(stiffness_ids(model)))).T


def modal_loss_factors(model: Model, lam: Float[Array, " m"], phi: Float[Array, "n m"]) -> Float[Array, " m"]:
    """η_n = φ_nᵀGφ_n / λ_n of the model's element loss factors (module docstring) for
    mass-normalised modes (λ in (rad/s)², φ on the solved DoFs); the viscous ratio at
    resonance is η_n / 2."""
    phi = jnp.asarray(phi)
    return jnp.sum(phi * damping_matrix(model).matmul(phi), axis=0) / jnp.asarray(lam)
