"""An effect's free parameters as traced masks on a model, for fits that share one compiled solver.

Many candidate effects of one model structure share one compiled solver: what differs
between them (which elements a factor scales, the law's reference frequency) is an
array argument, not a new model.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Float

import jaxfem
from jaxfem import Model

from jaxfem import MASS_BLOCKS as M_BLOCKS
from jaxfem import STIFFNESS_BLOCKS as K_BLOCKS

SHELL_BLOCKS = ("quads", "trias")
PARTS = ("membrane", "bending", "shear")  # the columns of Shells.parts
THETA_MAX = 25.0  # |log-factor| beyond which a trial step is clipped (e^25 ≈ 7e10)


class Extension(eqx.Module):
    """An effect's free parameters θ as masks on the model's element scales.

    ``k_scale ← k_scale·exp(θ₀·k_log) + k_add·exp(θ₀)`` per stiffness block (likewise
    for mass), so θ₀ is a log-factor on a group (``k_log``) or wakes dormant elements
    (``k_add``: added springs or masses present with scale 0). With ``visco`` set, θ₁
    gives the law ``a = a₀ + (e^θ₁ − 1)`` on the ``k_log`` group (reference ``f_ref``),
    the parameterisation of :class:`~updating.FrequencyDependentStiffness`; with
    ``split`` set, θ₁ is a second log-factor, on ``k_log_2`` (a joint's rotations); with
    ``height`` set, θ₁ moves point masses' CG (a payload standing on its footprint):
    ``offset ← offset + θ₁·offset_1``, ``inertia ← inertia + θ₁·inertia_1 + θ₁²·inertia_2``
    (the exact CONM2 of a box whose CG height grows linearly in θ₁).
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
    offset_1: Float[Array, "n 3"]
    inertia_1: Float[Array, "n 3 3"]
    inertia_2: Float[Array, "n 3 3"]
    split: Bool[Array, ""]
    height: Bool[Array, ""]
    visco: bool = eqx.field(static=True)

    @property
    def n_params(self) -> int:
        return 2 if self.visco or bool(self.split) or bool(self.height) else 1

    def scales_only(self) -> bool:
        """Whether θ₀ only multiplies whole elements' stiffness or mass by e^θ₀ (a group's
        factor): then K(θ₀) = K(0) + (e^θ₀ − 1) ∂K/∂θ₀ exactly, and likewise M (on the host)."""
        unit = all(np.isin(np.asarray(m), (0.0, 1.0)).all() for m in self.k_log + self.m_log)
        inert = not any(np.any(np.asarray(m)) for m in self.k_add + self.m_add + self.part_log + self.nsm_add)
        return unit and inert and not (self.visco or bool(self.split) or bool(self.height))

    def __call__(self, model: Model, theta: Float[Array, " e"]) -> Model:
        theta = jnp.clip(theta, -THETA_MAX, THETA_MAX)  # a wild trial step stays finite
        s = jnp.exp(theta[0])
        # θ₁ enters through masks that are zero unless it is this extension's (``split``,
        # ``height``): one compiled fit serves every extension of one or two parameters
        second = theta[1] if theta.shape[0] > 1 else jnp.zeros((), theta.dtype)
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
        model = eqx.tree_at(lambda m: (m.masses.offset, m.masses.inertia), model, (
            model.masses.offset + second * self.offset_1,
            model.masses.inertia + second * self.inertia_1 + second ** 2 * self.inertia_2))
        if self.visco:
            a = self.a0 + jnp.expm1(jnp.minimum(theta[1], 1.0))  # a step of at most e − 1
            law = jaxfem.Viscoelastic(self.k_log, a, self.f_ref)
            model = eqx.tree_at(lambda m: m.viscoelastic, model, law, is_leaf=lambda x: x is None)
        return model


def extension(model: Model, *, k_log=(), k_add=(), m_log=(), m_add=(), f_ref: float | None = None,
              a0: float = 0.0, k_log_2=(), part_log=(), part: str = "shear", nsm_add=(), nsm: float = 0.0,
              height: dict | None = None) -> Extension:
    """Masks from element ids: ``k_log`` etc. list the element ids of each role; a law
    (``visco``) when ``f_ref`` (Hz) is given, its coefficient starting at ``a0``; a second
    log-factor (``split``) when ``k_log_2`` lists elements; the shells ``part_log`` get the
    log-factor on their ``part`` ("membrane", "bending" or "shear"), the shells ``nsm_add``
    the non-structural mass ``nsm`` (kg/m²) at θ₀ = 0; ``height``: {CONM2 id:
    (offset_1 (3,), inertia_1 (3, 3), inertia_2 (3, 3))}, θ₁ moving their CG."""

    def masks(blocks, ids):
        ids = np.asarray(list(ids), np.int64)
        return tuple(jnp.asarray(np.isin(getattr(model, b).ids, ids), dtype=jnp.float64) for b in blocks)

    if (f_ref is not None) + bool(len(k_log_2)) + bool(height) > 1:
        raise ValueError("an extension has one second parameter: a frequency law, a second factor or a CG height")
    c = model.masses
    moves = {"offset_1": np.zeros((len(c.ids), 3)), "inertia_1": np.zeros((len(c.ids), 3, 3)),
             "inertia_2": np.zeros((len(c.ids), 3, 3))}
    for eid, values in (height or {}).items():
        row = np.flatnonzero(np.asarray(c.ids) == eid)
        if len(row) != 1:
            raise ValueError(f"extension: CONM2 {eid} is not in the model")
        for (name, array), value in zip(moves.items(), values):
            array[row[0]] = value
    column = np.arange(3) == PARTS.index(part)
    parts = tuple(m[:, None] * jnp.asarray(column, dtype=jnp.float64) for m in masks(SHELL_BLOCKS, part_log))
    return Extension(masks(K_BLOCKS, k_log), masks(K_BLOCKS, k_add), masks(M_BLOCKS, m_log),
                     masks(M_BLOCKS, m_add), jnp.asarray(f_ref or 1.0), jnp.asarray(float(a0)),
                     masks(K_BLOCKS, k_log_2), parts, tuple(m * nsm for m in masks(SHELL_BLOCKS, nsm_add)),
                     *(jnp.asarray(a) for a in moves.values()), jnp.asarray(len(k_log_2) > 0),
                     jnp.asarray(bool(height)), f_ref is not None)
