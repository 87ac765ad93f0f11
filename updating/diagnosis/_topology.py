"""What the effects need to know of a model's topology: RBE2 masters, SPC'd components,
elements at a grid, property groups and their halves, total mass, stiffness scales."""

from __future__ import annotations

import functools
from collections.abc import Iterator, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from identification import shell_centres
from jaxfem import FAST_COMPILE, STIFFNESS_BLOCKS, STRUCTURAL_BLOCKS, Model, compiled_when_eager
from jaxfem.elements import laminates, shell_mass, shell_stiffness


def _own(model: Model, row: int) -> set[int]:
    return _components(model).get(int(model.node_ids[row]), set())


def per_model(fn):
    """``fn(model)`` computed once per model (by identity; the last four kept): the
    effects ask it for every grid and every candidate."""
    last: dict[int, tuple[Model, object]] = {}

    def cached(model: Model):
        if id(model) in last and last[id(model)][0] is model:
            return last[id(model)][1]
        out = fn(model)
        while len(last) >= 4:
            last.pop(next(iter(last)))
        last[id(model)] = (model, out)
        return out

    return functools.wraps(fn)(cached)


@per_model
def _components(model: Model) -> dict[int, set[int]]:
    """Grid id → its components that are solved DoFs."""
    out: dict[int, set[int]] = {}
    for n, c in np.asarray(model.dofs.labels).tolist():
        out.setdefault(n, set()).add(c)
    return out


@per_model
def _auto_spc(model: Model) -> dict[int, set[int]]:
    """Grid id → its components removed by auto-SPC."""
    out: dict[int, set[int]] = {}
    for n, c in model.dofs.auto_spc:
        out.setdefault(int(n), set()).add(int(c))
    return out


@per_model
def masters(model: Model) -> dict[int, int]:
    """RBE2-dependent grid → the grid whose DoFs carry it (from the DoF map)."""
    owner = np.asarray(model.dofs.labels[:, 0])
    out = {}
    for row, node in enumerate(model.node_ids):
        idx = model.dofs.index[row]
        idx = idx[idx < model.n_dof]
        owners = set(owner[idx].tolist())
        if idx.size and int(node) not in owners and len(owners) == 1:
            out[int(node)] = owners.pop()
    return out


def constrained_components(model: Model, node: int) -> list[int]:
    """Components of a grid removed by SPC (not by RBE2 nor auto-SPC)."""
    row = int(model.node_index([node])[0])
    if int(node) in masters(model):
        return []
    auto = _auto_spc(model).get(int(node), set())
    idx = model.dofs.index[row]
    if np.any((idx < model.n_dof) & ~np.isin(model.dofs.labels[np.minimum(idx, model.n_dof - 1), 0], [node])):
        return []
    own = _own(model, row)
    return [c for c in range(1, 7) if c not in own and c not in auto]


def _structural(model: Model) -> Iterator[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """(block name, element ids, pids, node rows) of beams, rods, bushes and shells."""
    for name in STRUCTURAL_BLOCKS:
        b = getattr(model, name)
        if len(b.ids):
            yield name, b.ids, b.pids, b.nodes


@per_model
def _attached(model: Model) -> dict[int, list[tuple[int, int, int, int]]]:
    """Grid row → (block, position, element id, pid) of each structural element on it."""
    out: dict[int, list] = {}
    for b, (_, ids, pids, nodes) in enumerate(_structural(model)):
        for i, (e, p, row) in enumerate(zip(ids.tolist(), pids.tolist(), np.asarray(nodes).tolist())):
            for r in set(row) - {-1}:
                out.setdefault(r, []).append((b, i, e, p))
    return out


def elements_at(model: Model, node: int | Sequence[int]) -> dict[int, int]:
    """Structural element id → pid of the elements attached to a grid (to any of several),
    in block and element order."""
    attached = _attached(model)
    hits = sorted({a for r in model.node_index(np.atleast_1d(node)).tolist() for a in attached.get(r, ())})
    return {e: p for _, _, e, p in hits}


def structural_pids(model: Model) -> list[int]:
    """Property ids of beams, rods and shells."""
    return sorted({int(p) for b in (model.beams, model.rods, model.quads, model.trias) for p in b.pids})


def stiffness_pids(model: Model) -> list[int]:
    """Property ids of the elements with stiffness (pid 0, an added element, excluded)."""
    return sorted({int(p) for name in STIFFNESS_BLOCKS for p in getattr(model, name).pids if p > 0})


def halves(model: Model, pid: int) -> list[tuple[np.ndarray, str]]:
    """A group split in two at the median of its longest extent (left/right, in/outboard)."""
    rows, ids = [], []
    for name in ("beams", "rods", "quads", "trias"):
        b = getattr(model, name)
        hit = b.pids == pid
        rows.append(model.xyz[b.nodes[hit]].mean(axis=1))
        ids.append(b.ids[hit])
    centre, ids = np.concatenate(rows), np.concatenate(ids)
    if len(ids) < 4:
        return []
    axis = int(np.argmax(np.ptp(centre, axis=0)))
    cut = float(np.median(centre[:, axis]))
    low = centre[:, axis] <= cut
    if low.all() or not low.any():
        return []
    name = "xyz"[axis]
    cut = 0.0 if abs(cut) < 1e-9 * np.ptp(centre[:, axis]) else cut  # the median of a symmetric group: 0, not 1e-17
    return [(ids[low], f"pid {pid}, {name} ≤ {cut:.3g} m"), (ids[~low], f"pid {pid}, {name} > {cut:.3g} m")]


def element_grids(model: Model, eids) -> list[int]:
    """Grids of the structural elements ``eids`` (beams, rods, bushes, shells), in id order."""
    eids = np.asarray(list(eids), np.int64)
    rows = [nodes[np.isin(ids, eids)].ravel() for _, ids, _, nodes in _structural(model)]
    return sorted({int(model.node_ids[r]) for r in np.concatenate(rows)}) if rows else []


def property_groups(model: Model, pids: list[int], *, split: bool) -> list[tuple[int, tuple[int, ...], str]]:
    """(pid, eids, label) of each property group (eids empty: the whole group) and, with
    ``split``, of both :func:`halves` of the structural ones."""
    structural = structural_pids(model)
    out = []
    for pid in pids:
        out.append((pid, (), f"pid {pid}"))
        if split and pid in structural:
            out += [(pid, tuple(int(e) for e in ids), label) for ids, label in halves(model, pid)]
    return out


@per_model
def total_mass(model: Model) -> float:
    """Structural plus lumped mass (kg), with the current mass factors.

    Beams and rods: (ρA + nsm) × the grid-to-grid length; shells (CQUAD4, CTRIA3): the
    mass per area I0 of the laminate (ρt or Σ ρ_k t_k of the plies, + nsm) times the
    corner thickness ratio, integrated over the flat element area (the element's own
    mass, :func:`jaxfem.elements.shell_mass`); CONM2: m. Each element times its m_scale.
    """
    b, sec, mat = model.beams, model.beam_sections, model.materials
    xyz = model.xyz
    total = 0.0
    if len(b.ids):
        length = np.linalg.norm(xyz[b.nodes[:, 1]] - xyz[b.nodes[:, 0]], axis=1)
        s = b.section
        total += float(jnp.sum((mat.rho[sec.material[s]] * sec.A[s] + sec.nsm[s]) * length * b.m_scale))
    r, rs = model.rods, model.rod_sections
    if len(r.ids):
        length = np.linalg.norm(xyz[r.nodes[:, 1]] - xyz[r.nodes[:, 0]], axis=1)
        s = r.section
        total += float(jnp.sum((mat.rho[rs.material[s]] * rs.A[s] + rs.nsm[s]) * length * r.m_scale))
    for name in ("quads", "trias"):
        if len(getattr(model, name).ids):
            total += float(_shell_mass(model, name))
    return total + float(jnp.sum(model.masses.m * model.masses.m_scale))


@compiled_when_eager(compiler_options=FAST_COMPILE)
def _shell_mass(model: Model, name: str):
    """Mass of the shells of block ``name`` (compiled whole: run eagerly it compiled some 240
    small programs, 18 s on a 33,000-DoF model)."""
    sh = getattr(model, name)
    lam = laminates(model.shell_sections, model.materials, sh.section, sh.theta, sh.zoffs, sh.parts, sh.nsm)
    me = jax.vmap(lambda x, lm, ratio: shell_mass(x, lm, ratio, True))(jnp.asarray(model.xyz)[sh.nodes], lam,
                                                                       sh.t_ratio)
    # Lumped: the element mass on each translation of each grid; trace / 3 = its mass.
    translations = np.tile(np.arange(6) < 3, sh.nodes.shape[1])
    return jnp.sum(jnp.sum(jnp.diagonal(me, axis1=1, axis2=2)[:, translations], axis=1) / 3.0 * sh.m_scale)


def _beam_stiffness_scale(model: Model, eids) -> tuple[float, float]:
    """(max E·A/L, max E·I/L) of beams and rods among ``eids`` (N/m, N·m/rad)."""
    ea, ei = [0.0], [0.0]
    for name, sec_name in (("beams", "beam_sections"), ("rods", "rod_sections")):
        b, sec = getattr(model, name), getattr(model, sec_name)
        hit = np.isin(b.ids, np.asarray(list(eids), np.int64))
        if not hit.any():
            continue
        s = b.section[hit]
        length = np.linalg.norm(model.xyz[b.nodes[hit, 1]] - model.xyz[b.nodes[hit, 0]], axis=1)
        e = np.asarray(model.materials.E)[sec.material[s]]
        ea.extend((e * np.asarray(sec.A)[s] / length).tolist())
        inertia = np.maximum(np.asarray(sec.I1)[s], np.asarray(sec.I2)[s]) if name == "beams" else np.asarray(sec.J)[s]
        ei.extend((e * inertia / length).tolist())
    return max(ea), max(ei)


def joint_reference(model: Model, nodes, side_eids) -> dict[str, float]:
    """Starting values of a joint: rotations 10·E·I/L and translations 100·E·A/L of the
    stiffest beam or rod of the released side (a joint slightly softer than rigid); with
    shells only, the same multiples of their diagonal stiffness at the grids (E·A/L and
    4·E·I/L for a beam: 100× and 2.5×)."""
    ea, ei = _beam_stiffness_scale(model, side_eids)
    if ei <= 0:
        ea, four_ei = shell_stiffness_scale(model, side_eids, nodes)
        ei = four_ei / 4.0
    if ei <= 0:
        raise ValueError(f"joint at grid(s) {list(nodes)}: no beam, rod or shell on the released side")
    return {"k_trans": 100.0 * ea, "k_rot": 10.0 * ei}


def shell_size(model: Model) -> float:
    """Typical shell element size (m): the median length of the shells' edges."""
    _, _, corners = shell_centres(model)
    if not len(corners):
        return 0.0
    xyz = np.asarray(model.xyz)
    valid = corners >= 0
    nxt = np.where(np.roll(valid, -1, axis=1), np.roll(corners, -1, axis=1), corners[:, :1])
    edges = np.linalg.norm(xyz[np.maximum(corners, 0)] - xyz[np.maximum(nxt, 0)], axis=2)[valid]
    return float(np.median(edges))


def patch_elements(model: Model, node: int, radius: float) -> tuple[int, ...]:
    """Shells whose centres lie within ``radius`` (m) of grid ``node``, and at least those
    attached to it (a patch, :class:`~updating.diagnosis._patch_effects.AbstractPatch`)."""
    ids, centres, corners = shell_centres(model)
    row = model.node_index([node])[0]
    inside = np.linalg.norm(centres - np.asarray(model.xyz)[row], axis=1) <= radius * (1 + 1e-9)
    return tuple(int(e) for e in ids[inside | (corners == row).any(axis=1)])


def shell_stiffness_scale(model: Model, eids, nodes) -> tuple[float, float]:
    """(largest translational, largest rotational) diagonal stiffness that the shells among
    ``eids`` put on the grids ``nodes`` (N/m, N·m/rad; 0 without shells)."""
    rows = set(model.node_index(list(nodes)).tolist())
    kt, kr = [0.0], [0.0]
    for name in ("quads", "trias"):
        sh = getattr(model, name)
        hit = np.isin(sh.ids, np.asarray(list(eids), np.int64))
        if not hit.any():
            continue
        lam = laminates(model.shell_sections, model.materials, sh.section[hit], sh.theta[hit], sh.zoffs[hit],
                        sh.parts[hit], sh.nsm[hit])
        ke = jax.vmap(shell_stiffness, in_axes=(0, 0, 0, None))(jnp.asarray(model.xyz)[sh.nodes[hit]], lam,
                                                                sh.t_ratio[hit], model.k6rot)
        diag = np.asarray(jnp.diagonal(ke, axis1=1, axis2=2)).reshape(hit.sum(), -1, 6)
        at = np.isin(sh.nodes[hit], list(rows))
        kt.append(float(diag[at][:, :3].max(initial=0.0)))
        kr.append(float(diag[at][:, 3:].max(initial=0.0)))
    return max(kt), max(kr)


def shell_area(model: Model, eids) -> float:
    """Total area (m²) of the shells among ``eids`` (each quad as its two triangles)."""
    ids, _, corners = shell_centres(model)
    rows = corners[np.isin(ids, np.asarray(list(eids), np.int64))]
    xyz = np.asarray(model.xyz)
    area = 0.0
    for a, b, c in ((0, 1, 2), (0, 2, 3)):
        tri = rows[:, [a, b, c]]
        ok = (tri >= 0).all(axis=1)
        p = xyz[tri[ok]]
        area += 0.5 * float(np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())
    return area
