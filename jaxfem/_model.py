"""The finite-element model as a pytree.

Updatable values (material constants, section values, spring rates, masses, element
scale factors) are float64 array leaves, so ``K(p)`` and ``M(p)`` are differentiable in
any of them. Connectivity and DoF maps are integer NumPy arrays: they are never
differentiated, and their shapes fix the shapes of everything downstream.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, Int

from ._scalar_model import Conm1, Dampers, DirectMatrices, ScalarMasses

COMPONENTS = 6  # DoFs per grid: T1 T2 T3 R1 R2 R3 (Nastran components 1..6)
# Element blocks of a Model that carry stiffness (k_scale), mass (m_scale), or that join
# grids as structure (drawn, localised, edited).
STIFFNESS_BLOCKS = ("beams", "rods", "springs", "bushes", "quads", "trias")
MASS_BLOCKS = ("beams", "rods", "masses", "quads", "trias")
STRUCTURAL_BLOCKS = ("beams", "rods", "bushes", "quads", "trias")
ELEMENT_BLOCKS = STIFFNESS_BLOCKS + ("masses",)  # every element block


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


MAT1, MAT2, MAT8 = 1, 2, 8  # Materials.kind


class Materials(eqx.Module):
    """Materials (MAT1, MAT2, MAT8), one row per material id; moduli in Pa, rho in kg/m³.

    MAT1 (isotropic): E, G, nu; E2, G1z, G2z are 0 (shells take E, G in their place).
    MAT8 (orthotropic, shells): E = E1, G = G12, nu = NU12, and E2, G1z, G2z (0 when
    G1Z/G2Z are blank: transverse shear rigid). MAT2 (anisotropic, shells): the
    plane-stress matrix Q = [[G11, G12, G13], [G12, G22, G23], [G13, G23, G33]]; as a
    transverse-shear material (MID3) its upper 2 × 2 block. Q is 0 for MAT1 and MAT8.
    """

    ids: Int[np.ndarray, " nmat"]
    kind: Int[np.ndarray, " nmat"]  # MAT1, MAT2 or MAT8
    E: Float[Array, " nmat"]
    G: Float[Array, " nmat"]
    nu: Float[Array, " nmat"]
    rho: Float[Array, " nmat"]
    E2: Float[Array, " nmat"]
    G1z: Float[Array, " nmat"]
    G2z: Float[Array, " nmat"]
    Q: Float[Array, "nmat 3 3"]


class BeamSections(eqx.Module):
    """Bar/beam sections (PBAR, PBARL, PBEAM, PBEAML), one row per property id.

    A in m², I1/I2/J in m⁴, nsm in kg/m. K1/K2 are shear area factors; 0 means
    no shear flexibility (Euler–Bernoulli), as a blank field in Nastran. I1, I2, K1, K2
    are in the section's principal axes, turned by ``angle`` [rad] about the element x
    from the element axes of the card (0 unless a PBARL/PBEAML has I12 ≠ 0; the builder
    turns the elements' v by it). ``section_type``: the TYPE of a constant PBARL/PBEAML
    section, as its index in ``jaxfem._section_library.TYPES`` (−1: PBAR, PBEAM, tapered
    PBEAML); ``dims``: its DIM1..DIMn [m] (0 beyond n and on the other rows).
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
    angle: Float[Array, " nsec"]
    section_type: Int[np.ndarray, " nsec"]
    dims: Float[Array, "nsec ndim"]

    def with_dims(self, rows: np.ndarray, dims: Float[Array, "n ndim"]) -> tuple[BeamSections, Float[Array, " n"]]:
        """These sections with the library sections of ``rows`` (``section_type`` ≥ 0) given
        the dimensions ``dims``: their A, I1, I2, J, K1, K2 and principal angle recomputed as
        the builder does (:mod:`jaxfem._section_library`), pure JAX, differentiable in
        ``dims``; K1, K2 stay 0 where they are 0 (a CBAR section with I12 ≠ 0).

        **Returns:** ``(sections, turn)``, ``turn[i]`` the change of the principal angle of
        row ``rows[i]`` [rad], by which the v of its elements turns.
        """
        from . import _section_library as library

        keys = ("A", "I1", "I2", "J", "K1", "K2", "angle")
        out = {k: getattr(self, k) for k in keys}
        turns = []
        for i, r in enumerate(rows):
            name = library.TYPES[int(self.section_type[r])]
            a, i_1, i_2, i12, j, k1, k2 = library.section(name, dims[i, : library.DIMENSIONS[name]])
            theta, i_1, i_2, k1, k2 = library.principal(i_1, i_2, i12, k1, k2)
            k1, k2 = jnp.where(self.K1[r] > 0.0, k1, 0.0), jnp.where(self.K2[r] > 0.0, k2, 0.0)
            for k, value in zip(keys, (a, i_1, i_2, j, k1, k2, theta)):
                out[k] = out[k].at[r].set(value)
            turns.append(theta - self.angle[r])
        new = (*(out[k] for k in keys), self.dims.at[rows].set(dims))
        sections = eqx.tree_at(lambda s: (s.A, s.I1, s.I2, s.J, s.K1, s.K2, s.angle, s.dims), self, new)
        return sections, jnp.stack(turns)


class RodSections(eqx.Module):
    """Rod sections (PROD): A in m², J in m⁴, nsm in kg/m."""

    ids: Int[np.ndarray, " nsec"]
    material: Int[np.ndarray, " nsec"]
    A: Float[Array, " nsec"]
    J: Float[Array, " nsec"]
    nsm: Float[Array, " nsec"]


class ShellSections(eqx.Module):
    """Shell properties (PSHELL, PCOMP), one row per property id.

    PSHELL: ``materials`` holds the rows of MID1 (membrane), MID2 (bending), MID3
    (transverse shear), MID4 (membrane–bending coupling), −1 where blank; ``t`` the
    thickness T [m], ``bending_ratio`` 12I/T³, ``shear_ratio`` TS/T. PCOMP
    (``composite``): plies bottom to top (LAM = SYM already mirrored), ``ply_material``
    rows (−1 pads), ``ply_t`` [m] and ``ply_theta`` [rad] from the element's material
    axis, ``z0`` the bottom surface [m]; ``t`` is the sum of the ply thicknesses.
    ``nsm`` in kg/m². ``membrane``, ``bending`` and ``shear`` scale the laminate's A,
    D and transverse-shear matrix (updating factors, 1 by default; B is scaled by
    √(membrane·bending)). ``shear_rigid``: no transverse-shear flexibility (blank
    MID3, or MAT8 plies without G1Z/G2Z). See :func:`jaxfem.elements.laminate`.
    """

    ids: Int[np.ndarray, " nsec"]
    composite: np.ndarray  # bool (nsec,)
    shear_rigid: np.ndarray  # bool (nsec,)
    materials: Int[np.ndarray, "nsec 4"]
    ply_material: Int[np.ndarray, "nsec nply"]
    t: Float[Array, " nsec"]
    bending_ratio: Float[Array, " nsec"]
    shear_ratio: Float[Array, " nsec"]
    nsm: Float[Array, " nsec"]
    z0: Float[Array, " nsec"]
    ply_t: Float[Array, "nsec nply"]
    ply_theta: Float[Array, "nsec nply"]
    membrane: Float[Array, " nsec"]
    bending: Float[Array, " nsec"]
    shear: Float[Array, " nsec"]


class Shells(eqx.Module):
    """Shell elements of one shape: CQUAD4 (4 grids) or CTRIA3 (3 grids).

    ``theta``: material axis 1 measured from the projected G1→G2 side about the element
    normal [rad] (THETA, or MCID's x-axis projected); ``zoffs``: reference plane offset
    along the normal [m]; ``t_ratio``: corner thickness T1..T4 over the property's T
    (1 where blank). ``parts``: factors on each element's membrane, bending and
    transverse-shear stiffness (columns; applied as the section's ``membrane``,
    ``bending``, ``shear``; 1 by default); ``nsm``: non-structural mass added to the
    element's section [kg/m², 0 by default]. Both are element-wise updating values (a
    delamination, a repair, insulation over a region).
    """

    ids: Int[np.ndarray, " n"]
    pids: Int[np.ndarray, " n"]
    section: Int[np.ndarray, " n"]  # row in ShellSections
    nodes: Int[np.ndarray, "n nn"]
    theta: Float[Array, " n"]
    zoffs: Float[Array, " n"]
    t_ratio: Float[Array, "n nn"]
    k_scale: Float[Array, " n"]
    m_scale: Float[Array, " n"]
    parts: Float[Array, "n 3"]
    nsm: Float[Array, " n"]


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
    cbeam: np.ndarray | None = None  # bool (n,): a CBEAM (lumped mass with torsional inertia), else a CBAR


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

    Single-point constraints remove components; RBE2, RBE3 and MPC make dependent
    components combinations of independent DoFs (constraint elimination).
    ``u[node, c] = coef[node, c] @ u_solved[index[node]]``, u in basic axes; index ==
    n_dof is padding. ``labels`` name the solved DoFs by their grid's global components,
    those of its displacement (CD) system, whose axes in basic are ``cd[node]`` (MSC QRG,
    GRID CD); a scalar point's one DoF is component 1.
    """

    index: Int[np.ndarray, "nnode w"]
    coef: Float[np.ndarray, "nnode 6 w"]
    labels: Int[np.ndarray, "ndof 2"]  # (node id, component 1..6) per solved DoF
    massless: Int[np.ndarray, " nb"]  # solved DoFs without mass (condensed statically)
    auto_spc: Int[np.ndarray, "nauto 2"]  # (node id, component) with neither mass nor stiffness, removed
    n_dof: int = eqx.field(static=True)
    cd: Float[np.ndarray, "nnode 3 3"] | None = None  # axes of each grid's CD system (None: all basic)


class Viscoelastic(eqx.Module):
    """A frequency-dependent stiffness law on a group of elements (a visco-elastic layer).

    The stiffness of the weighted elements is ``K_g·(1 + a·ln(f/f_ref))`` at frequency f
    (Hz): the modulus law ``E(f) = E0 (1 + a ln(f/f_ref))``, a straight line in log f as
    for visco-elastic materials in their transition region (Nashif, Jones & Henderson
    1985, ch. 3). ``weights``: one array per block of :data:`STIFFNESS_BLOCKS`, 1 for
    elements of the layer, 0 elsewhere (traced, so candidate groups can be batched).
    """

    weights: tuple[Float[Array, " n"], ...]
    a: Float[Array, ""]
    f_ref: Float[Array, ""]


class StructuralDamping(eqx.Module):
    """Structural (hysteretic) loss factors of elements, Nastran's GE: the damping matrix
    ``G = Σ_e η_e K_e`` adds ``iG`` to the dynamic stiffness (Ewins, *Modal Testing*,
    §2.3), and mode n gets the modal loss factor ``φ_nᵀGφ_n / φ_nᵀKφ_n`` (modal strain
    energy; :func:`jaxfem.modal_loss_factors`). ``eids``: elements with stiffness;
    ``eta``: their loss factors (dimensionless, ≥ 0)."""

    eids: tuple[int, ...] = eqx.field(static=True, converter=lambda ids: tuple(int(i) for i in ids))
    eta: Float[Array, " e"]


_ROWS: dict[int, tuple[np.ndarray, dict[int, int]]] = {}  # id(node_ids) → (node_ids, grid id → row)


def _rows_of(node_ids: np.ndarray) -> dict[int, int]:
    """Grid id → row, made once per ``node_ids`` array (models edited from one another share
    it; a diagnosis asks for rows some 10⁴ times on a 33,000-DoF model)."""
    hit = _ROWS.get(id(node_ids))
    if hit is None or hit[0] is not node_ids:
        while len(_ROWS) >= 8:
            _ROWS.pop(next(iter(_ROWS)))
        hit = _ROWS[id(node_ids)] = (node_ids, {int(n): i for i, n in enumerate(np.asarray(node_ids))})
    return hit[1]


class Model(eqx.Module):
    """A structural model: grids, elements by type, properties, materials, constraints.

    Build one with ``jaxfem.build_model(jaxfem.io.read_bdf(path))``. Values are in the
    deck's own consistent units (SI: m, kg, N/m, Pa; or mm–t–s, in–lbf–s, ...), masses
    after PARAM WTMASS; frequencies in Hz do not depend on the unit system.
    """

    node_ids: Int[np.ndarray, " nnode"]
    xyz: Float[np.ndarray, "nnode 3"]
    materials: Materials
    beam_sections: BeamSections
    rod_sections: RodSections
    shell_sections: ShellSections
    beams: Beams
    rods: Rods
    springs: Springs
    bushes: Bushes
    quads: Shells
    trias: Shells
    masses: Masses
    dofs: DofMap
    lumped: bool = eqx.field(static=True)  # PARAM COUPMASS: False = consistent mass
    k6rot: float = eqx.field(static=True, default=100.0)  # PARAM K6ROT: shell drilling stiffness
    viscoelastic: Viscoelastic | None = None  # frequency-dependent stiffness, see jaxfem.modes
    damping: StructuralDamping | None = None  # element loss factors, see jaxfem.damping_matrix
    scalar_masses: ScalarMasses | None = None  # CMASS1-4
    dampers: Dampers | None = None  # CDAMP1-4, CVISC: the viscous damping matrix, see jaxfem.viscous_damping
    conm1: Conm1 | None = None  # CONM1 6 x 6 masses
    direct: DirectMatrices | None = None  # DMIG selected by K2GG, M2GG, B2GG
    scalar_rows: np.ndarray | None = None  # rows of the scalar points (one DoF, component 1; at the origin)

    def with_effect(self, effect) -> Model:
        """This model with a physical effect added (``updating.Effect``; see its ``apply``)."""
        return effect.apply(self)

    @property
    def n_dof(self) -> int:
        """Number of independent DoFs after SPC, RBE2 and auto-SPC elimination."""
        return self.dofs.n_dof

    def node_index(self, node_ids: Sequence[int]) -> np.ndarray:
        """Rows of the given grid ids; ValueError naming any id that is not a grid."""
        lookup = _rows_of(self.node_ids)
        missing = [int(n) for n in node_ids if int(n) not in lookup]
        if missing:
            raise ValueError(f"grid id(s) {missing} not in the model")
        return np.array([lookup[int(n)] for n in node_ids], dtype=np.int64)

    def segments(self) -> tuple[np.ndarray, np.ndarray]:
        """Lines to draw: two-grid elements (beams, rods, bushes, springs between two grids)
        and the edges of shells, ``(rows (k, 2) of grid indices, element ids (k,))``;
        grounded springs left out."""
        rows, ids = [], []
        for block in (self.beams, self.rods, self.bushes, self.springs, self.quads, self.trias):
            nodes = np.asarray(block.nodes)
            nn = nodes.shape[1]
            edges = [(a, (a + 1) % nn) for a in range(nn)] if nn > 2 else [(0, 1)]
            for a, b in edges:
                n = nodes[:, [a, b]]
                keep = (n >= 0).all(axis=1)
                rows.append(n[keep])
                ids.append(np.asarray(block.ids)[keep])
        return np.concatenate(rows).astype(np.int64), np.concatenate(ids).astype(np.int64)

    def restricted(self, eids: Sequence[int]) -> Model:
        """The same grids and DoFs with only the elements ``eids`` (of any block): what
        they alone assemble into K and M."""
        eids = np.asarray(eids, np.int64)
        blocks = tuple(jax.tree.map(lambda a, keep=np.flatnonzero(np.isin(getattr(self, n).ids, eids)): a[keep],
                                    getattr(self, n)) for n in ELEMENT_BLOCKS)
        return eqx.tree_at(lambda m: tuple(getattr(m, n) for n in ELEMENT_BLOCKS), self, blocks)

    def element_ids(self, pids: Sequence[int] | None = None) -> np.ndarray:
        """All element ids, or those whose property id is in ``pids`` (CONM2 has none)."""
        blocks = [getattr(self, name) for name in STIFFNESS_BLOCKS]
        ids = [b.ids[np.isin(b.pids, pids)] if pids is not None else b.ids for b in blocks]
        if pids is None:
            ids.append(self.masses.ids)
        return np.concatenate(ids).astype(np.int64)


class Opaque:
    """A static, non-pytree holder: keeps NumPy structure out of tracing. Hashed and
    compared by content (NumPy arrays by their bytes), so that equal structures share
    compiled code."""

    def __init__(self, value):
        self.value = value
        self._key = None

    def _content(self):
        if self._key is None:
            leaves, treedef = jax.tree.flatten(self.value)
            self._key = (treedef, tuple(_leaf_key(x) for x in leaves))
        return self._key

    def __hash__(self) -> int:
        return hash(self._content())

    def __eq__(self, other) -> bool:
        return isinstance(other, Opaque) and (self is other or self._content() == other._content())


def _leaf_key(x):
    """A hashable stand-in for one leaf of an :class:`Opaque`: an array by its dtype,
    shape and a digest of its bytes; a tracer or another unhashable object by identity."""
    if isinstance(x, (np.ndarray, jax.Array)) and not isinstance(x, jax.core.Tracer):
        a = np.ascontiguousarray(x)
        return a.dtype.str, a.shape, hashlib.blake2b(a.reshape(-1).view(np.uint8), digest_size=16).digest()
    try:
        hash(x)
        return x
    except TypeError:
        return "id", id(x)


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

    for name in STIFFNESS_BLOCKS:
        block = getattr(model, name)
        block = eqx.tree_at(lambda b: b.k_scale, block, scaled(block, "k_scale", stiffness_groups, alpha))
        model = eqx.tree_at(lambda m: getattr(m, name), model, block)
    for name in MASS_BLOCKS:
        block = getattr(model, name)
        block = eqx.tree_at(lambda b: b.m_scale, block, scaled(block, "m_scale", mass_groups, beta))
        model = eqx.tree_at(lambda m: getattr(m, name), model, block)
    return model
