"""An effect's free parameters as traced masks on a model, for fits that share one compiled solver.

Many candidate effects of one model structure share one compiled solver: what differs
between them (which elements a factor scales, the law's reference frequency) is an
array argument, not a new model.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

import jaxfem
from jaxfem import Model

from jaxfem import MASS_BLOCKS as M_BLOCKS
from jaxfem import STIFFNESS_BLOCKS as K_BLOCKS

SHELL_BLOCKS = ("quads", "trias")
PARTS = ("membrane", "bending", "shear")  # the columns of Shells.parts
_THETA_MAX = 25.0  # |log-factor| beyond which a trial step is clipped (e^25 ≈ 7e10)


class Extension(eqx.Module):
    """An effect's free parameters θ as masks on the model's element scales.

    ``k_scale ← k_scale·exp(θ₀·k_log) + k_add·exp(θ₀)`` per stiffness block (likewise
    for mass), so θ₀ is a log-factor on a group (``k_log``) or wakes dormant elements
    (``k_add``: added springs or masses present with scale 0). With ``visco`` set, θ₁
    gives the law ``a = a₀ + (e^θ₁ − 1)`` on the ``k_log`` group (reference ``f_ref``),
    the parameterisation of :class:`~updating.FrequencyDependentStiffness`; with
    ``split`` set, θ₁ is a second log-factor, on ``k_log_2`` (a joint's rotations).
    """

    k_log: tuple[Float[Array, " n"], ...]
    k_add: tuple[Float[Array, " n"], ...]
    m_log: tuple[Float[Array, " n"], ...]
    m_add: tuple[Float[Array, " n"], ...]
    f_ref: Float[Array, ""]
    a0: Float[Array, ""]
    k_log_2: tuple[Float[Array, " n"], ...]
    part_log: tuple[Float[Array, "n 3"], ...]
    nsm_add: tuple[Float[Array, " n"], ...]
    visco: bool = eqx.field(static=True)
    split: bool = eqx.field(static=True)

    @property
    def n_params(self) -> int:
        return 2 if self.visco or self.split else 1

    def __call__(self, model: Model, theta: Float[Array, " e"]) -> Model:
        theta = jnp.clip(theta, -_THETA_MAX, _THETA_MAX)  # a wild trial step stays finite
        s = jnp.exp(theta[0])
        second = theta[-1] if self.split else 0.0
        for name, log, log2, add in zip(K_BLOCKS, self.k_log, self.k_log_2, self.k_add):
            blk = getattr(model, name)
            model = eqx.tree_at(lambda m, name=name: getattr(m, name).k_scale, model,
                                blk.k_scale * jnp.exp(theta[0] * log + second * log2) + add * s)
        for name, log, add in zip(M_BLOCKS, self.m_log, self.m_add):
            blk = getattr(model, name)
            model = eqx.tree_at(lambda m, name=name: getattr(m, name).m_scale, model,
                                blk.m_scale * jnp.exp(theta[0] * log) + add * s)
        for name, part, nsm in zip(SHELL_BLOCKS, self.part_log, self.nsm_add):
            blk = getattr(model, name)
            model = eqx.tree_at(lambda m, name=name: (getattr(m, name).parts, getattr(m, name).nsm), model,
                                (blk.parts * jnp.exp(theta[0] * part), blk.nsm + nsm * s))
        if self.visco:
            a = self.a0 + jnp.expm1(jnp.minimum(theta[1], 1.0))  # a step of at most e − 1
            law = jaxfem.Viscoelastic(self.k_log, a, self.f_ref)
            model = eqx.tree_at(lambda m: m.viscoelastic, model, law, is_leaf=lambda x: x is None)
        return model


def extension(model: Model, *, k_log=(), k_add=(), m_log=(), m_add=(), f_ref: float | None = None,
              a0: float = 0.0, k_log_2=(), part_log=(), part: str = "shear", nsm_add=(), nsm: float = 0.0
              ) -> Extension:
    """Masks from element ids: ``k_log`` etc. list the element ids of each role; a law
    (``visco``) when ``f_ref`` (Hz) is given, its coefficient starting at ``a0``; a second
    log-factor (``split``) when ``k_log_2`` lists elements; the shells ``part_log`` get the
    log-factor on their ``part`` ("membrane", "bending" or "shear"), the shells ``nsm_add``
    the non-structural mass ``nsm`` (kg/m²) at θ₀ = 0."""

    def masks(blocks, ids):
        ids = np.asarray(list(ids), np.int64)
        return tuple(jnp.asarray(np.isin(getattr(model, b).ids, ids), dtype=jnp.float64) for b in blocks)

    if f_ref is not None and len(k_log_2):
        raise ValueError("an extension has a frequency law or a second factor, not both")
    column = np.arange(3) == PARTS.index(part)
    parts = tuple(m[:, None] * jnp.asarray(column, dtype=jnp.float64) for m in masks(SHELL_BLOCKS, part_log))
    return Extension(masks(K_BLOCKS, k_log), masks(K_BLOCKS, k_add), masks(M_BLOCKS, m_log),
                     masks(M_BLOCKS, m_add), jnp.asarray(f_ref or 1.0), jnp.asarray(float(a0)),
                     masks(K_BLOCKS, k_log_2), parts, tuple(m * nsm for m in masks(SHELL_BLOCKS, nsm_add)),
                     f_ref is not None, len(k_log_2) > 0)
