"""The finite-element model as a pytree.

Updatable values (material constants, section values, spring rates, masses, element
scale factors) are float64 array leaves, so ``K(p)`` and ``M(p)`` are differentiable in
any of them. Connectivity and DoF maps are integer NumPy arrays: they are never
differentiated, and their shapes fix the shapes of everything downstream.
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

COMPONENTS = 6  # DoFs per grid: T1 T2 T3 R1 R2 R3 (Nastran components 1..6)


def require_float64() -> None:
    """Raise a clear error when JAX runs in single precision.

    jaxfem computes in float64 only: eigenvalue sensitivities and
    finite-difference checks are meaningless in float32.
    """
    if not jax.config.jax_enable_x64:
        raise RuntimeError(
            "jaxfem needs float64. Call jax.config.update('jax_enable_x64', True) "
            "before building models (the jaxfem command line does this for you)."
        )


def check_float64(name: str, x) -> None:
    """Refuse a floating-point input that is not float64, naming the argument."""
    require_float64()
    for leaf in jax.tree.leaves(x):
        dtype = jnp.result_type(leaf)
        if jnp.issubdtype(dtype, jnp.floating) and dtype != jnp.float64:
            raise TypeError(f"{name} has dtype {dtype}; jaxfem computes in float64 only.")


def _f64(x) -> Array:
    return jnp.asarray(x, dtype=jnp.float64)


class Materials(eqx.Module):
    """Isotropic materials (MAT1), one row per material id.

    E, G in Pa; rho in kg/m³; nu dimensionless.
    """

    ids: Int[np.ndarray, " nmat"]
    E: Float[Array, " nmat"]
    G: Float[Array, " nmat"]
    nu: Float[Array, " nmat"]
    rho: Float[Array, " nmat"]


class BeamSections(eqx.Module):
    """Bar/beam sections (PBAR, PBARL, PBEAM), one row per property id.

    A in m², I1/I2/J in m⁴, nsm in kg/m. K1/K2 are shear area factors; 0 means
    no shear flexibility (Euler–Bernoulli), as a blank field in Nastran.
    """

    ids: Int[np.ndarray, " nsec"]
    material: Int[np.ndarray, " nsec"]  # row in Materials
    A: Float[Array, " nsec"]
    I1: Float[Array, " nsec"]
    I2: Float[Array, " nsec"]
    J: Float[Array, " nsec"]
    K1: Float[Array, " nsec"]
    K2: Float[Array, " nsec"]
    nsm: Float[Array, " nsec"]


class RodSections(eqx.Module):
    """Rod sections (PROD): A in m², J in m⁴, nsm in kg/m."""

    ids: Int[np.ndarray, " nsec"]
    material: Int[np.ndarray, " nsec"]
    A: Float[Array, " nsec"]
    J: Float[Array, " nsec"]
    nsm: Float[Array, " nsec"]


class Beams(eqx.Module):
    """Two-node beams (CBAR, CBEAM). Offsets are end point minus grid, in m, basic axes."""

    ids: Int[np.ndarray, " n"]
    pids: Int[np.ndarray, " n"]
    section: Int[np.ndarray, " n"]  # row in BeamSections
    nodes: Int[np.ndarray, "n 2"]  # rows in Model.node_ids
    v: Float[Array, "n 3"]  # orientation vector, basic axes
    offsets: Float[Array, "n 2 3"]
    k_scale: Float[Array, " n"]
    m_scale: Float[Array, " n"]


class Rods(eqx.Module):
    """Axial/torsional rods (CROD)."""

    ids: Int[np.ndarray, " n"]
    pids: Int[np.ndarray, " n"]
    section: Int[np.ndarray, " n"]  # row in RodSections
    nodes: Int[np.ndarray, "n 2"]
    k_scale: Float[Array, " n"]
    m_scale: Float[Array, " n"]


class Springs(eqx.Module):
    """Scalar springs (CELAS1/CELAS2) between two grid components; -1 node = ground.

    k in N/m (translations) or N·m/rad (rotations).
    """

    ids: Int[np.ndarray, " n"]
    pids: Int[np.ndarray, " n"]  # PELAS id, 0 for CELAS2
    nodes: Int[np.ndarray, "n 2"]  # rows in Model.node_ids, -1 for ground
    components: Int[np.ndarray, "n 2"]  # 1..6 (0 for ground)
    k: Float[Array, " n"]
    k_scale: Float[Array, " n"]


class Bushes(eqx.Module):
    """Generalised springs (CBUSH/PBUSH, stiffness only); axes rows are element x, y, z."""

    ids: Int[np.ndarray, " n"]
    pids: Int[np.ndarray, " n"]
    nodes: Int[np.ndarray, "n 2"]
    axes: Float[Array, "n 3 3"]
    k: Float[Array, "n 6"]
    s: Float[Array, " n"]  # spring location as fraction of GA→GB
    k_scale: Float[Array, " n"]


class Masses(eqx.Module):
    """Lumped masses (CONM2): m in kg, offset in m, inertia about the CG in kg·m²."""

    ids: Int[np.ndarray, " n"]
    nodes: Int[np.ndarray, " n"]
    m: Float[Array, " n"]
    offset: Float[Array, "n 3"]
    inertia: Float[Array, "n 3 3"]
    m_scale: Float[Array, " n"]


class DofMap(eqx.Module):
    """Map from the 6 components of every grid to the independent (solved) DoFs.

    Single-point constraints remove components; RBE2 makes dependent components
    rigid-body combinations of the independent node's DoFs (constraint elimination).
    ``u[node, c] = coef[node, c] @ u_solved[index[node]]``; index == n_dof is padding.
    """

    index: Int[np.ndarray, "nnode w"]
    coef: Float[np.ndarray, "nnode 6 w"]
    labels: Int[np.ndarray, "ndof 2"]  # (node id, component 1..6) per solved DoF
    massless: Int[np.ndarray, " nb"]  # solved DoFs without mass (condensed statically)
    auto_spc: Int[np.ndarray, "nauto 2"]  # (node id, component) with neither mass nor stiffness, removed
    n_dof: int = eqx.field(static=True)


class Viscoelastic(eqx.Module):
    """A frequency-dependent stiffness law on a group of elements (a visco-elastic layer).

    The stiffness of the weighted elements is ``K_g·(1 + a·ln(f/f_ref))`` at frequency f
    (Hz): the modulus law ``E(f) = E0 (1 + a ln(f/f_ref))``, a straight line in log f as
    for visco-elastic materials in their transition region (Nashif, Jones & Henderson
    1985, ch. 3). ``weights`` per stiffness block (beams, rods, springs, bushes): 1 for
    elements of the layer, 0 elsewhere (traced, so candidate groups can be batched).
    """

    beams: Float[Array, " nb"]
    rods: Float[Array, " nr"]
    springs: Float[Array, " ns"]
    bushes: Float[Array, " nu"]
    a: Float[Array, ""]
    f_ref: Float[Array, ""]


class Model(eqx.Module):
    """A structural model: grids, elements by type, properties, materials, constraints.

    Build one with ``jaxfem.build_model(jaxfem.io.read_bdf(path))``. All lengths in
    m, masses in kg, stiffnesses in N/m, moduli in Pa (SI; Nastran files carry no
    units, so the file must be written in SI).
    """

    node_ids: Int[np.ndarray, " nnode"]
    xyz: Float[np.ndarray, "nnode 3"]
    materials: Materials
    beam_sections: BeamSections
    rod_sections: RodSections
    beams: Beams
    rods: Rods
    springs: Springs
    bushes: Bushes
    masses: Masses
    dofs: DofMap
    lumped: bool = eqx.field(static=True)  # PARAM COUPMASS: False = consistent mass
    viscoelastic: Viscoelastic | None = None  # frequency-dependent stiffness, see jaxfem.modes

    def with_effect(self, effect) -> Model:
        """This model with a physical effect added (``updating.Effect``; see its ``apply``)."""
        return effect.apply(self)

    @property
    def n_dof(self) -> int:
        """Number of independent DoFs after SPC, RBE2 and auto-SPC elimination."""
        return self.dofs.n_dof

    def node_index(self, node_ids: Sequence[int]) -> np.ndarray:
        """Rows of the given grid ids; ValueError naming any id that is not a grid."""
        lookup = {int(n): i for i, n in enumerate(self.node_ids)}
        missing = [int(n) for n in node_ids if int(n) not in lookup]
        if missing:
            raise ValueError(f"grid id(s) {missing} not in the model")
        return np.array([lookup[int(n)] for n in node_ids], dtype=np.int64)

    def segments(self) -> tuple[np.ndarray, np.ndarray]:
        """Two-grid elements (beams, rods, bushes, springs between two grids) for drawing:
        ``(rows (k, 2) of grid indices, element ids (k,))``; grounded springs left out."""
        rows, ids = [], []
        for block in (self.beams, self.rods, self.bushes, self.springs):
            n = np.asarray(block.nodes).reshape(-1, 2)
            keep = (n >= 0).all(axis=1)
            rows.append(n[keep])
            ids.append(np.asarray(block.ids)[keep])
        return np.concatenate(rows).astype(np.int64), np.concatenate(ids).astype(np.int64)

    def element_ids(self, pids: Sequence[int] | None = None) -> np.ndarray:
        """All element ids, or those whose property id is in ``pids`` (CONM2 has none)."""
        blocks = [self.beams, self.rods, self.springs, self.bushes]
        ids = [b.ids[np.isin(b.pids, pids)] if pids is not None else b.ids for b in blocks]
        if pids is None:
            ids.append(self.masses.ids)
        return np.concatenate(ids).astype(np.int64)


class Opaque:
    """A static, non-pytree holder (hashed by identity): keeps NumPy structure out of tracing."""

    def __init__(self, value):
        self.value = value


def partition(model: Model) -> tuple[Model, Model]:
    """Split a model into ``(values, structure)`` for ``jax.jit``.

    Values are the JAX arrays (the updatable numbers); structure is everything else,
    notably the NumPy connectivity and DoF maps, which must stay concrete. Pass
    ``values`` through ``jit``/``vmap`` and rebuild with ``eqx.combine(values, structure)``
    inside; ``eqx.filter_jit`` on a whole model would trace the NumPy arrays too.
    """
    return eqx.partition(model, lambda x: isinstance(x, jax.Array))


def block_masks(ids: np.ndarray, groups: Sequence[Sequence[int]]) -> np.ndarray:
    """0/1 matrix (n_groups, n_elements) telling which element of a block is in which group."""
    return np.stack([np.isin(ids, np.asarray(g, dtype=np.int64)) for g in groups]).astype(
        np.float64
    ) if len(groups) else np.zeros((0, len(ids)))


def correct(
    model: Model,
    stiffness_groups: Sequence[Sequence[int]] = (),
    alpha: Float[Array, " I"] | None = None,
    mass_groups: Sequence[Sequence[int]] = (),
    beta: Float[Array, " J"] | None = None,
) -> Model:
    """Apply substructure correction factors, thesis eq. 3.1.

    ``K = K0 + Σ_i α_i K_i`` and ``M = M0 + Σ_j β_j M_j``, where ``K_i`` (``M_j``) is
    the stiffness (mass) of the elements whose ids are listed in group i (j). Each
    element's matrix is scaled by ``1 + Σ_i α_i [e ∈ G_i]``, which is exactly eq. 3.1.

    **Arguments:** element-id groups (sequences of ints) and factor arrays of matching
    length. **Returns:** a new model; differentiable in ``alpha`` and ``beta``.
    """
    all_ids = set(model.element_ids().tolist())
    for kind, groups in (("stiffness", stiffness_groups), ("mass", mass_groups)):
        for i, g in enumerate(groups):
            unknown = sorted(set(int(e) for e in g) - all_ids)
            if unknown:
                raise ValueError(f"{kind} group {i} names element ids {unknown} not in the model")
    alpha = _f64(jnp.zeros(0) if alpha is None else alpha)
    beta = _f64(jnp.zeros(0) if beta is None else beta)
    if alpha.shape != (len(stiffness_groups),) or beta.shape != (len(mass_groups),):
        raise ValueError(
            f"alpha has shape {alpha.shape} for {len(stiffness_groups)} stiffness groups; "
            f"beta has shape {beta.shape} for {len(mass_groups)} mass groups"
        )

    def scaled(block, field, groups, factors):
        mask = block_masks(block.ids, groups)
        return getattr(block, field) * (1.0 + factors @ mask)

    k_blocks = ("beams", "rods", "springs", "bushes")
    m_blocks = ("beams", "rods", "masses")
    for name in k_blocks:
        block = getattr(model, name)
        block = eqx.tree_at(lambda b: b.k_scale, block, scaled(block, "k_scale", stiffness_groups, alpha))
        model = eqx.tree_at(lambda m: getattr(m, name), model, block)
    for name in m_blocks:
        block = getattr(model, name)
        block = eqx.tree_at(lambda b: b.m_scale, block, scaled(block, "m_scale", mass_groups, beta))
        model = eqx.tree_at(lambda m: getattr(m, name), model, block)
    return model
