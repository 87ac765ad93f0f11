"""What each parameter kind scales, resolved against a model: the kinds' tables, the scaling of
physical values (:func:`_scale_physical`, pure JAX), the checks that a parameter's targets hold
what its kind scales (:func:`_target_problem`) and private material rows
(:func:`_private_materials`). The parameters themselves: :mod:`updating._parameters`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

import jaxfem
from jaxfem import MAT1, MAT2, MAT8, Model

if TYPE_CHECKING:
    from ._parameters import Parameter

KINDS = ("stiffness", "mass", "E", "G", "rho", "A", "I1", "I2", "J", "dim", "k", "m", "a",
         "membrane", "bending", "transverse_shear", "E1", "E2", "G12", "G1Z", "G2Z", "NU12", "t", "nsm", "theta")
# Material kinds: the Materials column scaled and the material types (MAT1/2/8) it acts on.
_MATERIAL = {
    "E": ("E", (MAT1,)), "G": ("G", (MAT1,)), "rho": ("rho", (MAT1, MAT2, MAT8)),
    "E1": ("E", (MAT8,)), "E2": ("E2", (MAT8,)), "G12": ("G", (MAT8,)),
    "G1Z": ("G1z", (MAT8,)), "G2Z": ("G2z", (MAT8,)), "NU12": ("nu", (MAT8,)),
}
_SECTION = {"A", "I1", "I2", "J"}
# Shell section kinds: the ShellSections factor each scales (A, D, S of the laminate).
_SHELL_FACTOR = {"membrane": "membrane", "bending": "bending", "transverse_shear": "shear"}
_SHELL = set(_SHELL_FACTOR) | {"t", "theta"}
_PIDS_ONLY = set(_MATERIAL) | _SECTION | _SHELL | {"nsm", "a", "dim"}
# Kinds that also take shell element ids: the element's own factor (Shells.parts) or NSM (Shells.nsm).
_SHELL_ELEMENT = {"membrane": 0, "bending": 1, "transverse_shear": 2, "nsm": None}
# Where sections name their material rows: (section table, column).
_MATERIAL_COLUMNS = (("beam_sections", "material"), ("rod_sections", "material"),
                     ("shell_sections", "materials"), ("shell_sections", "ply_material"))


def _rows(ids: np.ndarray, wanted: Sequence[int]) -> np.ndarray:
    return np.flatnonzero(np.isin(ids, np.asarray(wanted, dtype=np.int64)))


def _scale_rows(values: Array, rows: np.ndarray, factor) -> Array:
    mask = np.zeros(values.shape[0])
    mask[rows] = 1.0
    shape = (-1,) + (1,) * (values.ndim - 1)
    return values * (1.0 + (factor - 1.0) * jnp.asarray(mask).reshape(shape))


def _scale_physical(model: Model, p: Parameter, factor) -> Model:
    if p.kind in _SHELL_ELEMENT and p.eids:
        for name in ("quads", "trias"):
            sh, rows = getattr(model, name), _rows(getattr(model, name).ids, p.eids)
            col = _SHELL_ELEMENT[p.kind]
            if col is None:
                model = eqx.tree_at(lambda m: getattr(m, name).nsm, model, _scale_rows(sh.nsm, rows, factor))
            else:
                parts = sh.parts.at[:, col].set(_scale_rows(sh.parts[:, col], rows, factor))
                model = eqx.tree_at(lambda m: getattr(m, name).parts, model, parts)
        return model
    if p.kind in _MATERIAL:
        field_name, types = _MATERIAL[p.kind]
        rows = _material_rows(model, p.pids, types)
        values = getattr(model.materials, field_name)
        return eqx.tree_at(lambda m: getattr(m.materials, field_name), model,
                           _scale_rows(values, rows, factor))
    if p.kind in _SECTION:
        rows = _rows(model.beam_sections.ids, p.pids)
        model = eqx.tree_at(lambda m: getattr(m.beam_sections, p.kind), model,
                            _scale_rows(getattr(model.beam_sections, p.kind), rows, factor))
        if p.kind in ("A", "J"):
            rows = _rows(model.rod_sections.ids, p.pids)
            model = eqx.tree_at(lambda m: getattr(m.rod_sections, p.kind), model,
                                _scale_rows(getattr(model.rod_sections, p.kind), rows, factor))
        return model
    if p.kind == "dim":
        return _scale_dimension(model, p, factor)
    if p.kind in _SHELL:
        sec = model.shell_sections
        rows = _rows(sec.ids, p.pids)
        if p.kind in _SHELL_FACTOR:
            name = _SHELL_FACTOR[p.kind]
            return eqx.tree_at(lambda m: getattr(m.shell_sections, name), model,
                               _scale_rows(getattr(sec, name), rows, factor))
        if p.kind == "t":  # PSHELL T; PCOMP plies and Z0 together (same centre); t = Σ plies
            return eqx.tree_at(lambda m: (m.shell_sections.t, m.shell_sections.z0, m.shell_sections.ply_t), model,
                               tuple(_scale_rows(v, rows, factor) for v in (sec.t, sec.z0, sec.ply_t)))
        plies = np.zeros(sec.ply_theta.shape)  # kind theta: every ply of the target PCOMPs
        plies[rows] = np.asarray(sec.ply_material)[rows] >= 0
        return eqx.tree_at(lambda m: m.shell_sections.ply_theta, model,
                           sec.ply_theta + (factor - 1.0) * jnp.asarray(plies))
    if p.kind == "nsm":
        for name in ("beam_sections", "rod_sections", "shell_sections"):
            sec = getattr(model, name)
            model = eqx.tree_at(lambda m: getattr(m, name).nsm, model,
                                _scale_rows(sec.nsm, _rows(sec.ids, p.pids), factor))
        return model
    if p.kind == "a":
        if model.viscoelastic is None:
            raise ValueError(f"parameter {p.name!r}: kind a needs a model with a frequency law")
        return eqx.tree_at(lambda m: m.viscoelastic.a, model, model.viscoelastic.a + (factor - 1.0))
    if p.kind == "k":
        s, b = model.springs, model.bushes
        srows, brows = _target_rows(model, s, p), _target_rows(model, b, p)
        model = eqx.tree_at(lambda m: m.springs.k, model, _scale_rows(s.k, srows, factor))
        return eqx.tree_at(lambda m: m.bushes.k, model, _scale_rows(b.k, brows, factor))
    c = model.masses  # kind "m"
    rows = np.union1d(_rows(c.ids, p.eids), np.flatnonzero(np.isin(model.node_ids[c.nodes], p.nodes)))
    return eqx.tree_at(lambda m: m.masses.m, model, _scale_rows(c.m, rows, factor))


def _scale_dimension(model: Model, p: Parameter, factor) -> Model:
    """DIM ``p.dim`` of the PBARL/PBEAML sections of ``p.pids`` times ``factor``: their A, I1,
    I2, J, K1, K2 and principal axes recomputed through Nastran's section library
    (:meth:`jaxfem._model.BeamSections.with_dims`), and the v of their elements turned
    about each element's axis x by the turn of the principal axes θ (Rodrigues:
    v cos θ + (x × v) sin θ + x (x·v)(1 − cos θ)). Pure JAX."""
    sec, b = model.beam_sections, model.beams
    rows = _rows(sec.ids, p.pids)
    sections, turn = sec.with_dims(rows, sec.dims[rows].at[:, p.dim - 1].multiply(factor))
    theta = jnp.zeros(len(sec.ids)).at[rows].set(turn)[b.section][:, None]
    xyz = jnp.asarray(model.xyz)
    x = xyz[b.nodes[:, 1]] + b.offsets[:, 1] - xyz[b.nodes[:, 0]] - b.offsets[:, 0]
    x = x / jnp.linalg.norm(x, axis=1, keepdims=True)
    v = b.v * jnp.cos(theta) + jnp.cross(x, b.v) * jnp.sin(theta) \
        + x * jnp.sum(x * b.v, axis=1, keepdims=True) * (1.0 - jnp.cos(theta))
    return eqx.tree_at(lambda m: (m.beam_sections, m.beams.v), model, (sections, v))


def _section_materials(model: Model, pids: Sequence[int]) -> dict[int, np.ndarray]:
    """pid → the material rows its section names (beam, rod, PSHELL roles, PCOMP plies)."""
    out: dict[int, list] = {}
    for name, column in _MATERIAL_COLUMNS:
        sec = getattr(model, name)
        rows = np.asarray(getattr(sec, column))
        for r in _rows(sec.ids, pids):
            out.setdefault(int(sec.ids[r]), []).extend(int(m) for m in np.ravel(rows[r]) if m >= 0)
    return {pid: np.unique(np.asarray(rows, np.int64)) for pid, rows in out.items()}


def _material_rows(model: Model, pids: Sequence[int], types=(MAT1, MAT2, MAT8)) -> np.ndarray:
    """Material rows of the types ``types`` (MAT1, MAT2, MAT8) named by the sections of ``pids``."""
    rows = np.concatenate([np.zeros(0, np.int64), *_section_materials(model, pids).values()])
    rows = np.unique(rows)
    return rows[np.isin(model.materials.kind[rows], types)]


_TYPE_NAMES = {MAT1: "MAT1", MAT2: "MAT2", MAT8: "MAT8"}


class _Ids(list):
    """Ids in a message: the first ten, then how many in all."""

    def __repr__(self) -> str:
        return list.__repr__(self) if len(self) <= 10 else list.__repr__(self[:10])[:-1] + f", … {len(self)} in all]"


def _missing(wanted: Sequence[int], present) -> _Ids:
    present = set(np.asarray(present).tolist())
    return _Ids(int(i) for i in wanted if i not in present)


def _block_problem(model: Model, p: Parameter) -> str | None:
    """Why targets of the element kinds (``stiffness``, ``mass``, ``k``, ``m``) or the beam
    section kinds have nothing ``p`` scales: each named id must hold it (None: fine). A
    target without it would leave its column zero: α stays 0 and the update "converges"."""
    blocks = lambda names: [getattr(model, n) for n in names]  # noqa: E731
    cat = lambda arrays: np.concatenate([np.zeros(0, np.int64)] + [np.asarray(a) for a in arrays])  # noqa: E731
    if p.kind in ("stiffness", "mass"):
        names = jaxfem.STIFFNESS_BLOCKS if p.kind == "stiffness" else jaxfem.MASS_BLOCKS
        eids = _missing(p.eids, cat(b.ids for b in blocks(names)))
        if eids:
            what = "CONM2 masses (no stiffness)" if p.kind == "stiffness" else "springs or bushes (no mass)"
            return f"eids {eids} are {what}: nothing for kind {p.kind} to scale"
        pids = _missing(p.pids, cat(b.pids for b in blocks(n for n in names if n != "masses")))
        if pids:
            other = "" if p.kind == "stiffness" else " (PELAS and PBUSH elements have no mass)"
            return (f"pids {pids} are used by no element with a {p.kind} matrix{other}: "
                    f"nothing for kind {p.kind} to scale")
        return None
    if p.kind == "k":
        sb = blocks(("springs", "bushes"))
        eids = _missing(p.eids, cat(b.ids for b in sb))
        pids = _missing(p.pids, cat(b.pids for b in sb))
        attached = cat(model.node_ids[b.nodes[b.nodes >= 0]] for b in sb)
        nodes = _missing(p.nodes, attached)
        for key, bad, what in (("eids", eids, "are not springs or bushes (CELAS, CBUSH)"),
                               ("pids", pids, "are not PELAS or PBUSH properties"),
                               ("nodes", nodes, "have no spring or bush attached")):
            if bad:
                return f"{key} {bad} {what}: nothing for kind k (spring and bush stiffness) to scale"
        return None
    if p.kind == "m":
        c = model.masses
        for key, bad, what in (("eids", _missing(p.eids, c.ids), "are not CONM2 masses"),
                               ("nodes", _missing(p.nodes, model.node_ids[c.nodes]), "carry no CONM2 mass")):
            if bad:
                return f"{key} {bad} {what}: nothing for kind m (CONM2 mass) to scale"
        return None
    if p.kind == "dim":
        return _dimension_problem(model, p)
    if p.kind in _SECTION:
        rods = p.kind in ("A", "J")
        pids = _missing(p.pids, cat([model.beam_sections.ids] + ([model.rod_sections.ids] if rods else [])))
        if pids:
            held = "PBAR/PBARL/PBEAM" + ("/PROD" if rods else "")
            return f"pids {pids} are not {held} properties: nothing for kind {p.kind} to scale" \
                + ("" if rods else " (a PROD has A and J only)")
    return None


def _dimension_problem(model: Model, p: Parameter) -> str | None:
    """Why the targets of a ``dim`` parameter are not constant PBARL/PBEAML sections with a
    DIM ``p.dim`` (None: fine)."""
    sec = model.beam_sections
    pids = _missing(p.pids, sec.ids[np.asarray(sec.section_type) >= 0])
    if pids:
        return (f"pids {pids} are not PBARL or constant PBEAML properties: kind dim scales a dimension of "
                "Nastran's beam-section library")
    dims = np.asarray(sec.dims)
    rows = _rows(sec.ids, p.pids)
    short = _Ids(int(sec.ids[r]) for r in rows if p.dim > dims.shape[1] or dims[r, p.dim - 1] <= 0.0)
    if short:
        return f"pids {short} have no DIM{p.dim} (their section TYPE has fewer dimensions)"
    return None


def _target_problem(model: Model, p: Parameter) -> str | None:
    """Why the targets of ``p`` have nothing that it scales (None: fine)."""
    problem = _block_problem(model, p)
    if problem or p.kind in ("stiffness", "mass", "k", "m", "dim") or p.kind in _SECTION:
        return problem
    if p.kind in _SHELL_ELEMENT and p.eids:
        shells = np.concatenate([model.quads.ids, model.trias.ids])
        other = sorted(set(p.eids) - set(shells.tolist()))
        if other:
            return f"eids {other[:10]} are not shells (kind {p.kind} on eids acts on CQUAD4/CTRIA3 elements)"
        if p.kind == "nsm" and not any(np.any(np.asarray(getattr(model, n).nsm)[_rows(getattr(model, n).ids, p.eids)])
                                       for n in ("quads", "trias")):
            return "the elements' own NSM is 0: a relative factor cannot change it (an effect sets it first)"
        return None
    if p.kind in _MATERIAL:
        return _material_problem(model, p)
    if p.kind in _SHELL:
        sec = model.shell_sections
        shells = set(sec.ids.tolist())
        other = [pid for pid in p.pids if pid not in shells]
        if other:
            return f"pids {other} are not PSHELL or PCOMP properties (kind {p.kind} acts on shell sections)"
        rows = _rows(sec.ids, p.pids)
        if p.kind == "theta":
            pshell = [int(sec.ids[r]) for r in rows if not sec.composite[r]]
            if pshell:
                return f"pids {pshell} are PSHELL; kind theta rotates the plies of PCOMP properties"
        if p.kind == "transverse_shear":
            rigid = [int(sec.ids[r]) for r in rows if sec.shear_rigid[r]]
            if rigid:
                return f"pids {rigid} are shear rigid (blank MID3, or MAT8 plies without G1Z/G2Z): no S to scale"
        return None
    if p.kind == "nsm":
        values, known = [], set()
        for name in ("beam_sections", "rod_sections", "shell_sections"):
            sec = getattr(model, name)
            rows = _rows(sec.ids, p.pids)
            values.append(np.asarray(sec.nsm)[rows])
            known |= set(sec.ids[rows].tolist())
        other = [pid for pid in p.pids if pid not in known]
        if other:
            return f"pids {other} are not beam, rod or shell properties (kind nsm)"
        if not np.any(np.concatenate(values)):
            return "NSM is 0 on every target property: a relative factor cannot change it"
    return None


def _material_problem(model: Model, p: Parameter) -> str | None:
    """Why the properties of a material kind ``p`` hold no material it scales (None: fine)."""
    _, types = _MATERIAL[p.kind]
    used = _section_materials(model, p.pids)
    kinds = model.materials.kind
    none = [pid for pid in p.pids if not np.isin(kinds[used.get(pid, np.zeros(0, np.int64))], types).any()]
    if none:
        wanted = "/".join(_TYPE_NAMES[t] for t in types)
        return f"pids {none} use no {wanted} material (kind {p.kind} scales {wanted} materials)"
    if p.kind in ("G1Z", "G2Z"):
        sec = model.shell_sections
        rows = _rows(sec.ids, p.pids)
        shear = [np.asarray(sec.ply_material)[r] if sec.composite[r] else np.asarray(sec.materials)[r, 2:3]
                 for r in rows]
        values = np.asarray(getattr(model.materials, _MATERIAL[p.kind][0]))
        bad = [int(sec.ids[r]) for r, m in zip(rows, shear)
               if sec.shear_rigid[r] or not ((kinds[m[m >= 0]] == MAT8) & (values[m[m >= 0]] > 0)).any()]
        if bad:
            return (f"pids {sorted(bad)} have no MAT8 transverse-shear material with {p.kind} > 0 "
                    "(MID3 of a PSHELL, or the plies of a PCOMP not shear rigid)")
    return None


def _target_rows(model: Model, block, p: Parameter) -> np.ndarray:
    """Springs or bushes named by eid or pid, or attached to one of ``p.nodes``."""
    at_node = np.isin(model.node_ids[np.maximum(block.nodes, 0)], p.nodes) & (block.nodes >= 0)
    rows = np.union1d(_rows(block.ids, p.eids), _rows(block.pids, p.pids))
    return np.union1d(rows, np.flatnonzero(at_node.any(axis=1)))


def _element_group(model: Model, p: Parameter) -> np.ndarray:
    return np.union1d(model.element_ids(pids=p.pids) if p.pids else np.zeros(0, np.int64),
                      np.asarray(p.eids, dtype=np.int64))


def _copy_material(mats, row: int):
    """The material table with row ``row`` appended again, under the id −(its id)."""
    copy = jax.tree.map(lambda a: a[row : row + 1], mats)
    copy = eqx.tree_at(lambda m: m.ids, copy, -copy.ids)
    return jax.tree.map(lambda a, b: (np if isinstance(a, np.ndarray) else jnp).concatenate([a, b]), mats, copy)


def _private_materials(model: Model, pids: Sequence[int], types=(MAT1, MAT2, MAT8)) -> Model:
    """Give the sections of ``pids`` their own material rows (copies) where they share one
    (of the types ``types``) with a property outside ``pids``.

    Every reference is redirected: beam and rod ``material``, the PSHELL roles (MID1..MID4)
    and PCOMP plies of shell sections. One copy per shared material, used by all the
    targets' references to it (a PSHELL with MID1 = MID2 keeps one material).
    """
    tables = {}
    for name, column in _MATERIAL_COLUMNS:
        sec = getattr(model, name)
        rows = np.array(getattr(sec, column), dtype=np.int64, copy=True)
        target = np.isin(sec.ids, np.asarray(pids, np.int64)).reshape((-1,) + (1,) * (rows.ndim - 1))
        tables[name, column] = (rows, np.broadcast_to(target, rows.shape) & (rows >= 0))
    by_target = set().union(*(rows[t].tolist() for rows, t in tables.values()))
    by_others = set().union(*(rows[~t & (rows >= 0)].tolist() for rows, t in tables.values()))
    kinds = model.materials.kind
    shared = sorted(m for m in by_target & by_others if kinds[m] in types)
    if not shared:
        return model
    mats = model.materials
    for m in shared:
        new = len(mats.ids)
        mats = _copy_material(mats, m)
        for rows, target in tables.values():
            rows[target & (rows == m)] = new
    model = eqx.tree_at(lambda md: md.materials, model, mats)
    for (name, column), (rows, _) in tables.items():
        model = eqx.tree_at(lambda md: getattr(getattr(md, name), column), model, rows)
    return model


def _column(model: Model, p: Parameter) -> tuple:
    """What ``p`` scales, resolved (an element group, spring rows, ...): two parameters with
    the same key have identical Jacobian columns."""
    if p.kind in ("stiffness", "mass"):
        return p.kind, frozenset(_element_group(model, p).tolist())
    if p.kind == "k":
        return p.kind, frozenset(_target_rows(model, model.springs, p).tolist()), \
            frozenset(_target_rows(model, model.bushes, p).tolist())
    if p.kind == "m":
        c = model.masses
        return p.kind, frozenset(np.union1d(_rows(c.ids, p.eids),
                                            np.flatnonzero(np.isin(model.node_ids[c.nodes], p.nodes))).tolist())
    if p.kind == "a":  # one coefficient of the frequency law, whatever the pids
        return (p.kind,)
    return p.kind, frozenset(p.pids), frozenset(p.eids), p.dim
