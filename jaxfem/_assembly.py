"""Assembly of K(p) and M(p): vmapped element matrices, constraint elimination, scatter.

Each element matrix (basic axes, grid DoFs) is transformed to the solved DoFs with the
per-node constraint map of :class:`jaxfem.DofMap` (SPC removal and RBE2 elimination,
``u_grid = T u_solved``), ``A_e ← T_eᵀ A_e T_e``, and kept element-stacked in an
:class:`ElementMatrix`.
"""

from __future__ import annotations

import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from ._eager import compiled_when_eager
from ._matrix import ElementMatrix
from ._model import COMPONENTS, DofMap, Model, check_float64
from .elements import (
    beam_lumped_torsion,
    beam_mass,
    beam_stiffness,
    bush_stiffness,
    conm2_mass,
    laminates,
    rigid_offset,
    rod_mass,
    rod_stiffness,
    shell_mass,
    shell_stiffness,
)


def _columns(model: Model, rows: np.ndarray) -> np.ndarray:
    """The DoF-map columns that any of grid ``rows`` uses (the others are padding for all
    of them: one RBE3 grid widens the map, not every block's element matrices)."""
    used = np.flatnonzero((model.dofs.index[rows] < model.n_dof).reshape(-1, model.dofs.index.shape[1]).any(axis=0))
    return used if used.size else np.arange(1)


def node_transform(model: Model, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """T (n_el, 6·nn, nn·w) and solved-DoF indices (n_el, nn·w) for elements on `nodes`."""
    n_el, nn = nodes.shape
    cols = _columns(model, nodes)
    w = len(cols)
    coef = model.dofs.coef[nodes][..., cols]  # (n_el, nn, 6, w)
    t = np.zeros((n_el, nn * COMPONENTS, nn * w))
    for a in range(nn):
        t[:, a * COMPONENTS : (a + 1) * COMPONENTS, a * w : (a + 1) * w] = coef[:, a]
    return t, model.dofs.index[nodes][..., cols].reshape(n_el, nn * w)




def global_coef(model: Model, nodes: np.ndarray, components: np.ndarray) -> np.ndarray:
    """Rows ``coef`` of the global (CD) component ``components`` (1..6) of grid rows
    ``nodes``: u_global = diag(R, R)ᵀ u_basic with R the grid's CD axes."""
    coef = model.dofs.coef[nodes]  # (..., 6, w) basic components
    if model.dofs.cd is None:
        return np.take_along_axis(coef, (components - 1)[..., None, None], axis=-2)[..., 0, :]
    r = model.dofs.cd[nodes]  # (..., 3, 3) columns: CD axes in basic
    c = components - 1
    axis = np.take_along_axis(r, (c % 3)[..., None, None], axis=-1)[..., 0]  # (..., 3)
    half = np.where((c < 3)[..., None, None], coef[..., :3, :], coef[..., 3:, :])
    return np.einsum("...i,...iw->...w", axis, half)


def scalar_transform(model: Model, nodes: np.ndarray, components: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """T (n, d, d·w) and indices (n, d·w) for elements on single DoFs: ``nodes`` (n, d)
    grid rows (-1: ground) and their global ``components`` (n, d) (springs, scalar masses)."""
    cols = _columns(model, nodes[nodes >= 0])
    (n, d), w = nodes.shape, len(cols)
    t = np.zeros((n, d, d * w))
    idx = np.full((n, d * w), model.n_dof, dtype=np.int64)
    for a in range(d):
        grounded = nodes[:, a] < 0
        node = np.where(grounded, 0, nodes[:, a])
        comp = np.where(grounded, 1, components[:, a])
        t[:, a, a * w : (a + 1) * w] = np.where(grounded[:, None], 0.0, global_coef(model, node, comp)[:, cols])
        idx[:, a * w : (a + 1) * w] = np.where(grounded[:, None], model.n_dof, model.dofs.index[node][:, cols])
    return t, idx


def _reduce(t: np.ndarray, a: jax.Array) -> jax.Array:
    return jnp.einsum("eia,eij,ejb->eab", t, a, t)


def _element_blocks(model: Model):
    """Stiffness and mass element blocks in grid DoFs: dict name -> (nodes, K_e, M_e)."""
    out = {}
    lumped = model.lumped
    if len(model.beams.ids):
        b, sec, mat = model.beams, model.beam_sections, model.materials
        s = b.section
        m = sec.material[s]
        xa = model.xyz[b.nodes[:, 0]] + b.offsets[:, 0]
        xb = model.xyz[b.nodes[:, 1]] + b.offsets[:, 1]
        t = jax.vmap(rigid_offset)(b.offsets[:, 0], b.offsets[:, 1])
        ke = jax.vmap(beam_stiffness)(
            xa, xb, b.v, mat.E[m], mat.G[m], sec.A[s], sec.I1[s], sec.I2[s], sec.J[s], sec.K1[s], sec.K2[s]
        )
        me = jax.vmap(lambda *a: beam_mass(*a, lumped=lumped))(
            xa, xb, b.v, mat.rho[m], sec.A[s], sec.nsm[s], sec.I1[s], sec.I2[s], sec.K1[s], sec.K2[s],
            mat.E[m], mat.G[m],
        )
        if lumped and b.cbeam is not None and b.cbeam.any():
            torsion = jax.vmap(beam_lumped_torsion)(xa, xb, mat.rho[m], sec.I1[s], sec.I2[s])
            me = me + b.cbeam.astype(np.float64)[:, None, None] * torsion
        ke = _reduce(t, ke) * b.k_scale[:, None, None]
        me = _reduce(t, me) * b.m_scale[:, None, None]
        out["beams"] = (b.nodes, ke, me)
    if len(model.rods.ids):
        r, sec, mat = model.rods, model.rod_sections, model.materials
        s = r.section
        m = sec.material[s]
        xa, xb = model.xyz[r.nodes[:, 0]], model.xyz[r.nodes[:, 1]]
        ke = jax.vmap(rod_stiffness)(xa, xb, mat.E[m], mat.G[m], sec.A[s], sec.J[s])
        me = jax.vmap(lambda *a: rod_mass(*a, lumped=lumped))(xa, xb, mat.rho[m], sec.A[s], sec.nsm[s])
        out["rods"] = (r.nodes, ke * r.k_scale[:, None, None], me * r.m_scale[:, None, None])
    if len(model.bushes.ids):
        u = model.bushes
        xa, xb = model.xyz[u.nodes[:, 0]], model.xyz[u.nodes[:, 1]]
        ke = jax.vmap(bush_stiffness)(xa, xb, u.axes, u.k, u.s) * u.k_scale[:, None, None]
        out["bushes"] = (u.nodes, ke, None)
    for name in ("quads", "trias"):
        sh = getattr(model, name)
        if len(sh.ids):
            lam = laminates(model.shell_sections, model.materials, sh.section, sh.theta, sh.zoffs, sh.parts, sh.nsm)
            xyz = jnp.asarray(model.xyz)[sh.nodes]
            ke = jax.vmap(shell_stiffness, in_axes=(0, 0, 0, None))(xyz, lam, sh.t_ratio, model.k6rot)
            me = jax.vmap(lambda x, lm, r: shell_mass(x, lm, r, lumped))(xyz, lam, sh.t_ratio)
            out[name] = (sh.nodes, ke * sh.k_scale[:, None, None], me * sh.m_scale[:, None, None])
    if len(model.masses.ids):
        c = model.masses
        me = jax.vmap(conm2_mass)(c.m, c.offset, c.inertia) * c.m_scale[:, None, None]
        out["masses"] = (c.nodes[:, None], None, me)
    if model.conm1 is not None:
        c = model.conm1
        out["conm1"] = (c.nodes[:, None], None, c.m * c.m_scale[:, None, None])
    return out


_UNIT = np.array([[1.0, -1.0], [-1.0, 1.0]])


def _scalar_blocks(model: Model):
    """Blocks on single DoFs: dict name -> (nodes, components, K_e, M_e) in global components."""
    out = {}
    if len(model.springs.ids):
        s = model.springs
        out["springs"] = (s.nodes, s.components, (s.k * s.k_scale)[:, None, None] * _UNIT, None)
    if model.scalar_masses is not None:
        s = model.scalar_masses
        out["scalar_masses"] = (s.nodes, s.components, None, (s.m * s.m_scale)[:, None, None] * _UNIT)
    if model.direct is not None:
        d = model.direct
        out["direct"] = (d.nodes[None], d.components[None], d.k[None], d.m[None])
    return out


@compiled_when_eager
def assemble(model: Model) -> tuple[ElementMatrix, ElementMatrix]:
    """Stiffness and mass matrices of the solved DoFs, K(p) and M(p).

    **Arguments:** a :class:`jaxfem.Model` (any float leaf may be traced).
    **Returns:** ``(K, M)`` as :class:`jaxfem.ElementMatrix` (``.todense()`` for arrays);
    ``M.massless`` lists the DoFs without inertia. Units: N/m and kg (SI).
    """
    for name, leaf in (("xyz", model.xyz), ("materials.E", model.materials.E)):
        check_float64(name, leaf)
    k_blocks, k_idx, m_blocks, m_idx = [], [], [], []
    for nodes, ke, me in _element_blocks(model).values():
        t, idx = node_transform(model, nodes)
        if ke is not None:
            k_blocks.append(_reduce(t, ke))
            k_idx.append(idx)
        if me is not None:
            m_blocks.append(_reduce(t, me))
            m_idx.append(idx)
    for nodes, components, ke, me in _scalar_blocks(model).values():
        t, idx = scalar_transform(model, nodes, components)
        for blocks, indices, a in ((k_blocks, k_idx, ke), (m_blocks, m_idx, me)):
            if a is not None:
                blocks.append(_reduce(t, a))
                indices.append(idx)
    n = model.n_dof
    none = np.zeros(0, np.int64)
    K = ElementMatrix(blocks=tuple(k_blocks), indices=tuple(k_idx), massless=none, size=n)
    M = ElementMatrix(
        blocks=tuple(m_blocks), indices=tuple(m_idx), massless=model.dofs.massless, size=n
    )
    return K, M


def _diagonal(a: ElementMatrix) -> np.ndarray:
    d = np.zeros(a.n + 1)
    for blk, idx in zip(a.blocks, a.indices):
        np.add.at(d, idx, np.asarray(jnp.diagonal(blk, axis1=1, axis2=2)))
    return d[: a.n]


_ZERO = 1e-14  # a diagonal term below this fraction of its grid's scale is no stiffness (mass)
_FLOOR = 1e-8  # a grid's scale is at least this fraction of the model's largest term


def _grid_scale(d: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """Per DoF: the largest |d| over the DoFs of its grid, at least ``_FLOOR`` × max |d|."""
    a = np.abs(d)
    _, group = np.unique(nodes, return_inverse=True)
    per_grid = np.zeros(group.max(initial=-1) + 1)
    np.maximum.at(per_grid, group, a)
    return np.maximum(per_grid[group], max(_FLOOR * a.max(initial=0.0), np.finfo(float).tiny))


def finalize_dofs(model: Model) -> Model:
    """Remove DoFs with neither stiffness nor mass (auto-SPC) and mark massless DoFs.

    A diagonal term counts as zero below 1e-14 of its grid's largest term (of stiffness,
    or of mass), so that a stiff spring or a tiny element elsewhere cannot remove a
    grid's rotations; the grid's scale is floored at 1e-8 of the model's largest term,
    so that round-off on an otherwise unconnected grid counts as nothing. The removed
    DoFs are ``dofs.auto_spc``. Non-finite terms (an overflow in some element) are refused,
    naming their DoFs. Works on the nominal values of the model (the structural
    zero pattern does not change with the parameters). Raises ``ValueError`` naming the
    DoFs when the massless DoFs form a mechanism (their stiffness block is singular).
    """
    dofs = model.dofs
    K, M = assemble(eqx.tree_at(lambda m: m.dofs.massless, model, np.zeros(0, np.int64)))
    dk, dm = _diagonal(K), _diagonal(M)
    for name, d in (("stiffness", dk), ("mass", dm)):
        bad = np.flatnonzero(~np.isfinite(d))
        if len(bad):
            raise ValueError(f"non-finite {name} at {_dof_list(dofs.labels[bad])}: an overflow in the elements "
                             "there (check their thickness, offsets, section and material values)")
    no_k = np.abs(dk) <= _ZERO * _grid_scale(dk, dofs.labels[:, 0])
    no_m = np.abs(dm) <= _ZERO * _grid_scale(dm, dofs.labels[:, 0])
    drop = no_k & no_m
    _warn_free_mass(dofs.labels[no_k & ~no_m])
    keep = np.flatnonzero(~drop)
    new_number = np.full(dofs.n_dof + 1, len(keep), dtype=np.int64)
    new_number[keep] = np.arange(len(keep))
    index = new_number[dofs.index]
    coef = np.where((index == len(keep))[:, None, :], 0.0, dofs.coef)
    massless = np.flatnonzero(no_m[keep])
    new = DofMap(
        index=index,
        coef=coef,
        labels=dofs.labels[keep],
        massless=massless,
        auto_spc=dofs.labels[drop].reshape(-1, 2),
        n_dof=len(keep),
        cd=dofs.cd,
    )
    if len(massless):
        _check_massless_stiffness(K, keep[massless], dofs.labels)
    return eqx.tree_at(lambda m: m.dofs, model, new)


def _warn_free_mass(labels: np.ndarray) -> None:
    """A DoF with mass and no stiffness moves freely: its unit vector is a 0 Hz mode."""
    if len(labels):
        warnings.warn(f"{_dof_list(labels)} carry mass but no stiffness: each moves freely, a 0 Hz mode of its "
                      "own; connect or constrain them (SPC)", UserWarning, stacklevel=4)


def _dof_list(labels: np.ndarray, shown: int = 8) -> str:
    """``3 DoF(s), (node, component) (1, 1), (1, 2), (1, 3)``, the first ``shown`` of them."""
    where = ", ".join(f"({n}, {c})" for n, c in labels[:shown].tolist())
    return f"{len(labels)} DoF(s), (node, component) {where}{' …' if len(labels) > shown else ''}"


def _sparse_block(a: ElementMatrix, dofs: np.ndarray) -> scipy.sparse.csc_matrix:
    """Rows and columns ``dofs`` of an element-stacked matrix as a SciPy CSC matrix (no n × n array)."""
    return a.tocsr()[dofs][:, dofs].tocsc()


def _check_massless_stiffness(K: ElementMatrix, massless: np.ndarray, labels: np.ndarray) -> None:
    """Refuse massless DoFs (rows of K) whose stiffness block is singular: a sparse LU
    without pivoting (symmetric ordering) of that block, whose pivots are all positive
    when it is positive definite."""
    kbb = _sparse_block(K, massless)
    scale = max(float(np.abs(kbb.diagonal()).max(initial=0.0)), np.finfo(float).tiny)
    try:
        lu = scipy.sparse.linalg.splu(kbb, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                      options={"SymmetricMode": True})
        pivots = lu.U.diagonal()
        order = lu.perm_c
    except RuntimeError:  # exactly singular
        pivots, order = np.zeros(len(massless)), np.arange(len(massless))
    bad = pivots <= 1e-12 * scale
    if bad.any():
        worst = massless[order[np.argsort(pivots)[: min(4, int(bad.sum()) + 3)]]]
        labels = [tuple(int(x) for x in labels[i]) for i in worst]
        raise ValueError(
            "massless DoFs without stiffness (a mechanism): the stiffness of the DoFs that "
            f"carry no mass is singular (smallest pivot {pivots.min():.3g}, largest diagonal {scale:.3g}); "
            f"involved (node, component): {labels}. Add mass or stiffness there, or constrain them."
        )
