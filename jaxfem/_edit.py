"""Structural edits of a built :class:`jaxfem.Model` (new grids, springs, masses, releases, RBE3s).

Used to add physical effects to a model (a flexible joint, a missing mass, a support
spring) without going back to the bulk data. Every edit returns a new model; the DoF
map is extended in place (new independent DoFs are numbered after the existing ones)
and the massless/auto-SPC bookkeeping is redone by :func:`refresh`.
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._assembly import finalize_dofs
from ._constraints import rbe3_matrix, undetermined
from ._model import COMPONENTS, STIFFNESS_BLOCKS, STRUCTURAL_BLOCKS, Bushes, DofMap, Masses, Model, Springs


def _append(a, b) -> jax.Array:
    """``a`` and ``b`` (float64) joined along the first axis: on the host when both are
    concrete (a jitted concatenate compiles anew for every length: seconds per grid when a
    diagnosis adds dormant elements at tens of grids)."""
    if isinstance(a, jax.core.Tracer) or isinstance(b, jax.core.Tracer):
        return jnp.concatenate([jnp.asarray(a, jnp.float64), jnp.asarray(b, jnp.float64)])
    return jax.device_put(np.concatenate([np.asarray(a, np.float64), np.asarray(b, np.float64)]))


def _new_id(existing: np.ndarray, start: int) -> int:
    return int(max(start, int(np.max(existing, initial=0)) + 1))


def _widen(dofs: DofMap, width: int, n_new: int) -> DofMap:
    """DoF map with at least ``width`` columns and room for ``n_new`` more DoFs (padding moved)."""
    index, coef = dofs.index, dofs.coef
    if index.shape[1] < width:
        pad = width - index.shape[1]
        index = np.pad(index, ((0, 0), (0, pad)), constant_values=dofs.n_dof)
        coef = np.pad(coef, ((0, 0), (0, 0), (0, pad)))
    index = np.where(index == dofs.n_dof, dofs.n_dof + n_new, index)
    return DofMap(index=index, coef=coef, labels=dofs.labels, massless=dofs.massless,
                  auto_spc=dofs.auto_spc, n_dof=dofs.n_dof + n_new, cd=dofs.cd)


def _own_dofs(model: Model, row: int) -> DofMap:
    """The grid in ``row`` gets its own DoF for every component (existing own DoFs kept):
    an SPC or an RBE2 dependency on it is removed."""
    dofs = model.dofs
    node = int(model.node_ids[row])
    own = {int(c): i for i, (n, c) in enumerate(dofs.labels) if n == node}
    missing = [c for c in range(1, COMPONENTS + 1) if c not in own]
    dofs = _widen(dofs, COMPONENTS, len(missing))
    first = dofs.n_dof - len(missing)
    own.update({c: first + k for k, c in enumerate(missing)})
    index, coef = dofs.index.copy(), dofs.coef.copy()
    index[row] = dofs.n_dof
    coef[row] = 0.0
    axes = np.eye(3) if dofs.cd is None else dofs.cd[row]  # basic from global (CD) components
    for c in range(1, COMPONENTS + 1):
        index[row, c - 1] = own[c]
    for c in range(1, COMPONENTS + 1):
        for j in range(1, COMPONENTS + 1):
            if (c - 1) // 3 == (j - 1) // 3:
                coef[row, c - 1, j - 1] = axes[(c - 1) % 3, (j - 1) % 3]
    labels = np.concatenate([dofs.labels, np.array([[node, c] for c in missing], dtype=np.int64).reshape(-1, 2)])
    return DofMap(index=index, coef=coef, labels=labels, massless=dofs.massless,
                  auto_spc=dofs.auto_spc, n_dof=dofs.n_dof, cd=dofs.cd)


def release(model: Model, node: int) -> Model:
    """Free every constrained or RBE2-dependent component of grid ``node``: the grid gets
    six independent DoFs. Elements or constraints that should hold it must be added."""
    row = int(model.node_index([node])[0])
    return eqx.tree_at(lambda m: m.dofs, model, _own_dofs(model, row))


def _with_grid(model: Model, xyz, node: int | None, terms: dict[int, np.ndarray]) -> tuple[Model, int]:
    """``model`` with a new grid at ``xyz`` (m) whose six components are ``terms``
    (independent DoF → its coefficient in each component; none: padding only)."""
    node = _new_id(model.node_ids, 1) if node is None else int(node)
    if node in set(model.node_ids.tolist()):
        raise ValueError(f"grid {node} already exists")
    used = sorted(terms)
    dofs = _widen(model.dofs, len(used), 0)
    index = np.full((1, dofs.index.shape[1]), dofs.n_dof, np.int64)
    coef = np.zeros((1, COMPONENTS, dofs.index.shape[1]))
    index[0, :len(used)] = used
    for k, i in enumerate(used):
        coef[0, :, k] = terms[i]
    cd = None if dofs.cd is None else np.concatenate([dofs.cd, np.eye(3)[None]])
    grown = DofMap(index=np.concatenate([dofs.index, index]), coef=np.concatenate([dofs.coef, coef]),
                   labels=dofs.labels, massless=dofs.massless, auto_spc=dofs.auto_spc, n_dof=dofs.n_dof, cd=cd)
    return eqx.tree_at(lambda m: (m.node_ids, m.xyz, m.dofs), model,
                       (np.append(model.node_ids, node),
                        np.concatenate([model.xyz, np.asarray(xyz, dtype=np.float64).reshape(1, 3)]), grown)), node


def add_grid(model: Model, xyz: Sequence[float], node: int | None = None) -> tuple[Model, int]:
    """A new grid at ``xyz`` (m) with six independent DoFs; returns ``(model, grid id)``."""
    grown, node = _with_grid(model, xyz, node, {})
    return eqx.tree_at(lambda m: m.dofs, grown, _own_dofs(grown, len(model.node_ids))), node


def add_rbe3(model: Model, grids: Sequence[int], xyz: Sequence[float] | None = None,
             components: Sequence[int] = (1, 2, 3), node: int | None = None) -> tuple[Model, int]:
    """A new grid at ``xyz`` (m; default the centroid of ``grids``) whose six components
    are the RBE3 average of ``components`` of ``grids``, equal weights (as the bulk-data
    RBE3 card, :func:`jaxfem._constraints.rbe3_matrix`): a dependent grid, no new DoFs.
    Returns ``(model, grid id)``."""
    rows = model.node_index(grids)
    x = np.asarray(model.xyz)[rows]
    ref = x.mean(axis=0) if xyz is None else np.asarray(xyz, dtype=np.float64).reshape(3)
    entries = [(row, c) for row in rows for c in components]
    t, null = rbe3_matrix(np.repeat(x - ref, len(components), axis=0), [c for _, c in entries],
                          np.ones(len(entries)))
    if len(null):
        raise ValueError(f"RBE3 over grids {list(grids)}: their components {tuple(components)} do not determine "
                         f"the motion of the new grid ({undetermined(null, ref)})")
    dofs = model.dofs
    terms: dict[int, np.ndarray] = {}  # independent DoF → its coefficient in each of the six components
    for k, (row, c) in enumerate(entries):
        for i, a in zip(dofs.index[row], dofs.coef[row, c - 1]):
            if i < dofs.n_dof and a != 0.0:
                terms[int(i)] = terms.get(int(i), np.zeros(COMPONENTS)) + a * t[:, k]
    return _with_grid(model, ref, node, terms)


def add_interpolated_grid(model: Model, grids: Sequence[int], weights: Sequence[float], xyz: Sequence[float],
                          node: int | None = None) -> tuple[Model, int]:
    """A new grid at ``xyz`` (m) that moves with ``grids``: a dependent grid, no new DoFs.
    Its rotation is θ = Σᵢ wᵢ θᵢ and its translation u = Σᵢ wᵢ uᵢ + θ × d, rigidly offset
    by d = xyz − Σᵢ wᵢ xᵢ from the interpolated point (a measured point read by shape
    functions wᵢ; by one nearest grid with w = 1 it is that grid's RBE2). Returns
    ``(model, grid id)``."""
    rows = model.node_index(grids)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    d = np.asarray(xyz, dtype=np.float64).reshape(3) - w @ np.asarray(model.xyz)[rows]
    dofs = model.dofs
    terms: dict[int, np.ndarray] = {}
    for row, wi in zip(rows, w):
        for k, i in enumerate(dofs.index[row]):
            c = dofs.coef[row, :, k]
            if i < dofs.n_dof and np.any(c != 0.0):
                moved = np.concatenate([c[:3] + np.cross(c[3:], d), c[3:]])
                terms[int(i)] = terms.get(int(i), np.zeros(COMPONENTS)) + wi * moved
    return _with_grid(model, xyz, node, terms)


def reconnect(model: Model, eids: Sequence[int], old: int, new: int) -> Model:
    """Elements ``eids`` (beams, rods, bushes, shells) attached to grid ``old`` are moved to grid ``new``."""
    old_row, new_row = model.node_index([old, new])
    wanted = np.asarray(eids, dtype=np.int64)
    for name in STRUCTURAL_BLOCKS:
        block = getattr(model, name)
        hit = np.isin(block.ids, wanted)[:, None] & (block.nodes == old_row)
        if hit.any():
            model = eqx.tree_at(lambda m, name=name: getattr(m, name).nodes, model, np.where(hit, new_row, block.nodes))
    return model


def add_bush(model: Model, node_a: int, node_b: int, k: Sequence[float], eid: int | None = None,
             pid: int = 0, s: float = 0.5) -> tuple[Model, int]:
    """A CBUSH with stiffnesses ``k`` (k1..k6 in N/m and N·m/rad, basic axes) between two
    grids, the spring at ``s`` of the way from A to B (CBUSH S)."""
    rows = model.node_index([node_a, node_b])
    b = model.bushes
    eid = _new_id(model.element_ids(), 1) if eid is None else int(eid)
    new = Bushes(
        ids=np.append(b.ids, eid), pids=np.append(b.pids, pid),
        nodes=np.concatenate([b.nodes, rows[None, :]]),
        axes=_append(b.axes, np.eye(3)[None]), k=_append(b.k, np.reshape(k, (1, 6))),
        s=_append(b.s, [s]), k_scale=_append(b.k_scale, [1.0]),
    )
    return _law_padded(eqx.tree_at(lambda m: m.bushes, model, new)), eid


def add_ground_springs(model: Model, node: int, k: Sequence[float], components: Sequence[int] = (1, 2, 3),
                       ) -> tuple[Model, list[int]]:
    """Scalar springs from grid ``node`` to ground, one per component (CELAS2); returns the eids."""
    row = int(model.node_index([node])[0])
    s = model.springs
    first = _new_id(model.element_ids(), 1)
    eids = [first + i for i in range(len(components))]
    n = len(components)
    new = Springs(
        ids=np.append(s.ids, eids), pids=np.append(s.pids, np.zeros(n, np.int64)),
        nodes=np.concatenate([s.nodes, np.array([[row, -1]] * n, dtype=np.int64).reshape(n, 2)]),
        components=np.concatenate([s.components, np.array([[c, 0] for c in components], dtype=np.int64).reshape(n, 2)]),
        k=_append(s.k, np.broadcast_to(k, (n,))), k_scale=_append(s.k_scale, np.ones(n)),
    )
    return _law_padded(eqx.tree_at(lambda m: m.springs, model, new)), eids


def _law_padded(model: Model) -> Model:
    """A frequency law's weights (:class:`jaxfem.Viscoelastic`) padded with zeros over the
    elements a block gained: they are not in the layer."""
    law = model.viscoelastic
    if law is None:
        return model
    sizes = [len(getattr(model, name).ids) for name in STIFFNESS_BLOCKS]
    weights = tuple(jnp.concatenate([w, jnp.zeros(n - w.shape[0], w.dtype)]) for w, n in zip(law.weights, sizes))
    return eqx.tree_at(lambda m: m.viscoelastic.weights, model, weights)


def add_mass(model: Model, node: int, m: float, eid: int | None = None, inertia=None,
             offset=None) -> tuple[Model, int]:
    """A point mass ``m`` (kg, CONM2) at grid ``node``; ``inertia``: its 3 × 3 tensor
    about its CG (kg·m², basic axes; default none); ``offset``: CG minus grid (m, basic
    axes; default none)."""
    row = int(model.node_index([node])[0])
    c = model.masses
    eid = _new_id(model.element_ids(), 1) if eid is None else int(eid)
    tensor = np.zeros((1, 3, 3)) if inertia is None else np.asarray(inertia, dtype=np.float64).reshape(1, 3, 3)
    new = Masses(
        ids=np.append(c.ids, eid), nodes=np.append(c.nodes, row),
        m=_append(c.m, [m]), offset=_append(c.offset, np.reshape(np.zeros(3) if offset is None else offset, (1, 3))),
        inertia=_append(c.inertia, tensor), m_scale=_append(c.m_scale, [1.0]),
    )
    return eqx.tree_at(lambda mm: mm.masses, model, new), eid


def refresh(model: Model) -> Model:
    """Redo the massless/auto-SPC bookkeeping after edits (see ``finalize_dofs``)."""
    return finalize_dofs(model)
