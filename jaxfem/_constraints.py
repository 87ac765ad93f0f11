"""Constraints of bulk data and the DoF map: GRID PS, SPC, SPC1, RBE2.

Constrained (grid, component) pairs come from GRID PS and the selected SPC/SPC1 set; an
RBE2 makes the CM components of its GM grids rigid-body functions of its GN grid (MSC
QRG, RBE2), chains followed. :func:`_dof_map` numbers the remaining DoFs and writes
every node's components as combinations of them (:class:`jaxfem.DofMap`).
"""

from __future__ import annotations

import numpy as np

from ._grids import _by_id, _Grids, _ints
from ._model import COMPONENTS, DofMap
from .io import BulkData, BulkDataError, Card


def _components(code: int) -> list[int]:
    return [int(d) for d in str(code)]


def _constraints(bulk: BulkData, grids: _Grids, spc_set: int | None) -> dict[tuple[int, int], Card]:
    """(grid, component) -> constraining card: GRID PS and the selected SPC/SPC1 set."""
    spcs = bulk["SPC"] + bulk["SPC1"]
    sets = sorted({c["SID"] for c in spcs})
    if spc_set is None and len(sets) > 1:
        raise BulkDataError(f"{bulk.source}: several SPC sets {sets}; choose one with spc_set")
    if spc_set is not None and spc_set not in sets:
        raise BulkDataError(f"{bulk.source}: SPC set {spc_set} is not in the file (sets: {sets})")
    selected = spc_set if spc_set is not None else (sets[0] if sets else None)
    fixed: dict[tuple[int, int], Card] = {}
    for card in grids.cards:
        for c in _components(card["PS"]) if card["PS"] else ():
            fixed[(card.id, c)] = card
    for card in spcs:
        if card["SID"] != selected:
            continue
        if card.name == "SPC" and card["D"] != 0.0:
            raise card.error("D", f"enforced displacement {card['D']} is not supported (D must be 0.0)")
        for g in (card["G"],) if card.name == "SPC" else card["G"]:
            grids(card, "G", g)
            for c in _components(card["C"]):
                fixed[(g, c)] = card
    return fixed


def _dof_map(bulk: BulkData, grids: _Grids, spc_set: int | None) -> DofMap:
    """Independent DoFs and the map ``u[node, c] = coef[node, c] @ u_solved[index[node]]``.

    Independent DoFs are the (grid, component) pairs, in ascending order, that are
    neither constrained (SPC, SPC1, GRID PS) nor RBE2-dependent. An RBE2 makes the CM
    components of each GM grid rigid-body functions of its GN grid (MSC QRG, RBE2):
    translations u_s = u_m + θ_m × (x_s − x_m), rotations θ_s = θ_m; chains (a GN that
    is itself dependent) are followed to independent DoFs.
    """
    fixed = _constraints(bulk, grids, spc_set)
    dependent: dict[tuple[int, int], tuple[Card, int]] = {}
    for card in _by_id(bulk["RBE2"]):
        grids(card, "GN")
        for g in card["GM"]:
            grids(card, "GM", g)
            if g == card["GN"]:
                raise card.error("GM", f"grid {g} is both the independent grid GN and a dependent grid")
            for c in _components(card["CM"]):
                if (g, c) in fixed:
                    other = fixed[(g, c)]
                    raise card.error(
                        "CM", f"grid {g} component {c} is both RBE2-dependent and constrained by "
                        f"{other.name} at {other.file}:{other.line}",
                    )
                if (g, c) in dependent:
                    other = dependent[(g, c)][0]
                    raise card.error(
                        "CM",
                        f"grid {g} component {c} is already dependent on RBE2 {other.id} at {other.file}:{other.line}",
                    )
                dependent[(g, c)] = (card, card["GN"])

    labels = [
        (int(g), c)
        for g in grids.ids
        for c in range(1, COMPONENTS + 1)
        if (g, c) not in fixed and (g, c) not in dependent
    ]
    number = {label: i for i, label in enumerate(labels)}
    rows: dict[tuple[int, int], dict[int, float]] = {}

    def row(g: int, c: int, chain: tuple[int, ...] = ()) -> dict[int, float]:
        """Coefficients of (grid g, component c) on the independent DoFs."""
        if (g, c) in rows:
            return rows[(g, c)]
        if (g, c) in number:
            return {number[(g, c)]: 1.0}
        if (g, c) in fixed:
            return {}
        card, m = dependent[(g, c)]
        if card.id in chain:
            raise card.error("GN", f"RBE2 elements depend on each other in a loop {chain + (card.id,)}")
        out = dict(row(m, c, chain + (card.id,)))
        if c <= 3:  # (θ × r)_c = Σ_j S[c, j] θ_j with r = x_s − x_m
            r = grids.xyz[grids.row[g]] - grids.xyz[grids.row[m]]
            s = np.array([[0.0, r[2], -r[1]], [-r[2], 0.0, r[0]], [r[1], -r[0], 0.0]])
            for j in range(3):
                if s[c - 1, j] != 0.0:
                    for dof, value in row(m, 4 + j, chain + (card.id,)).items():
                        out[dof] = out.get(dof, 0.0) + s[c - 1, j] * value
        rows[(g, c)] = out
        return out

    node_rows = [[row(int(g), c) for c in range(1, COMPONENTS + 1)] for g in grids.ids]
    used = [sorted(set().union(*r)) for r in node_rows]
    w = max((len(u) for u in used), default=0)
    n_dof = len(labels)
    index = np.full((len(used), w), n_dof, dtype=np.int64)
    coef = np.zeros((len(used), COMPONENTS, w))
    for n, (dofs, comps) in enumerate(zip(used, node_rows)):
        index[n, : len(dofs)] = dofs
        for c, coefficients in enumerate(comps):
            for k, dof in enumerate(dofs):
                coef[n, c, k] = coefficients.get(dof, 0.0)
    return DofMap(
        index=index,
        coef=coef,
        labels=_ints(labels, 2),
        massless=np.zeros(0, dtype=np.int64),
        auto_spc=np.zeros((0, 2), dtype=np.int64),
        n_dof=n_dof,
    )
