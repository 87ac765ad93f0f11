"""Constraints of bulk data and the DoF map: GRID PS, SPC, SPC1, RBE2, RBE3, MPC.

Constrained (grid, component) pairs come from GRID PS and the selected SPC/SPC1 set; an
RBE2 makes the CM components of its GM grids rigid-body functions of its GN grid, an
RBE3 the REFC components of its reference grid weighted least-squares averages of its
independent grids, an MPC of the selected set its first term a combination of the
others (MSC QRG, RBE2, RBE3, MPC); chains are followed. :func:`_dof_map` numbers the
remaining DoFs and writes every node's components as combinations of them
(:class:`jaxfem.DofMap`).
"""

from __future__ import annotations

import numpy as np

from ._grids import _by_id, _Grids, _ints
from ._model import COMPONENTS, DofMap
from ._rigid import _cross_rows, _rigid, _six, rbar, rbe1, rrod
from .io import BulkData, BulkDataError, Card

_SINGULAR_RTOL = 1e-10  # RBE3: eigenvalue of the scaled GᵀWG below rtol·largest = singular

# One term of a dependent DoF: ((grid, component), coefficient, field of the card it comes from)
_Term = tuple[tuple[int, int], float, str]
# (grid, component) of a dependent DoF -> (the card that makes it dependent, its terms)
_Dependent = dict[tuple[int, int], tuple[Card, list[_Term]]]


def _components(code: int) -> list[int]:
    return [int(d) for d in str(code)]


def _selected(bulk: BulkData, names: tuple[str, ...], chosen: int | None, argument: str) -> set[int]:
    """The set ids of the SPC or MPC cards to apply: ``chosen`` (from the case control or
    the caller), or the only set in the file; an SPCADD/MPCADD set is the union of the
    sets it lists (MSC QRG, SPCADD, MPCADD)."""
    cards = [c for name in names for c in bulk[name]]
    adds = {c["SID"]: c for c in bulk[names[0] + "ADD"]}
    sets = sorted({c["SID"] for c in cards} | set(adds))
    kind = names[0]
    if chosen is None and len(sets) > 1:
        first: dict[int, Card] = {}
        for card in sorted(cards + list(adds.values()), key=lambda c: (c.file, c.line)):
            first.setdefault(card["SID"], card)
        where = ", ".join(f"{first[s].name} {s} at {first[s].file}:{first[s].line}" for s in sets)
        raise first[sets[1]].error("SID", f"several {kind} sets {sets} ({where}); choose one in the case control "
                                          f"({kind} = n) or with {argument} (--{argument.replace('_', '-')})")
    if chosen is not None and chosen not in sets:
        raise BulkDataError(f"{bulk.source}: {kind} set {chosen} ({argument} or case control) is not in the "
                            f"bulk data (sets: {sets})")
    sid = chosen if chosen is not None else (sets[0] if sets else None)
    if sid not in adds:
        return set() if sid is None else {sid}
    add = adds[sid]
    for k, member in enumerate(add["S"], 1):
        if member not in {c["SID"] for c in cards}:
            raise add.error(f"S{k}", f"{kind} set {member} is not defined by any {' or '.join(names)} card")
    return set(add["S"])


def _component(grids: _Grids, card: Card, key: str, g: int, c: int) -> int:
    """Component c of point g as stored: a scalar point's component 0 (or 1) is 1."""
    if grids.row.get(g, -1) in grids.scalar_rows:
        if c not in (0, 1):
            raise card.error(key, f"point {g} is a scalar point (SPOINT): its component is 0 or blank, got {c}")
        return 1
    if c == 0:
        raise card.error(key, f"grid {g} needs a component 1..6 (0 or blank is for scalar points), got {c}")
    return c


def _constraints(bulk: BulkData, grids: _Grids, spc_set: int | None) -> dict[tuple[int, int], Card]:
    """(grid, component) -> constraining card: GRID PS, the selected SPC/SPC1 set, and
    None for the components 2..6 that a scalar point does not have."""
    selected = _selected(bulk, ("SPC", "SPC1"), spc_set, "spc_set")
    fixed: dict[tuple[int, int], Card] = {}
    for card in grids.cards:
        for c in _components(card["PS"]) if card["PS"] else ():
            fixed[(card.id, c)] = card
    for row in grids.scalar_rows:
        fixed.update({(int(grids.ids[row]), c): None for c in range(2, COMPONENTS + 1)})
    for card in bulk["SPC"] + bulk["SPC1"]:
        if card["SID"] not in selected:
            continue
        if card.name == "SPC" and card["D"] != 0.0:
            raise card.error("D", f"enforced displacement {card['D']} is not supported (D must be 0.0)")
        if card.name == "SPC":
            grids(card, "G")
        for g in (card["G"],) if card.name == "SPC" else grids.listed(card, "G"):
            for c in _components(card["C"]):
                fixed[(g, _component(grids, card, "C", g, c))] = card
    return fixed


def _global_rigid(grids: _Grids, g: int, ref: int) -> np.ndarray:
    """R6_gᵀ G R6_ref: the global (CD) components of grid ``g`` from those of grid ``ref``
    when both move as one rigid body (R6 = diag(R, R), R the CD axes of the grid)."""
    a, b = grids.row[g], grids.row[ref]
    return _six(grids.axes(a)).T @ _rigid(grids.xyz[a] - grids.xyz[b]) @ _six(grids.axes(b))


def _rbe2_terms(card: Card, grids: _Grids, g: int, c: int) -> list[_Term]:
    """u_gc = Σ_j A[c, j] u_mj with A = R6_gᵀ G(x_g − x_m) R6_m (:func:`_global_rigid`): in
    basic axes u_g = u_m + θ_m × (x_g − x_m), θ_g = θ_m."""
    m = card["GN"]
    a = _global_rigid(grids, g, m)[c - 1]
    return [((m, j + 1), float(a[j]), "GN") for j in range(6) if a[j] != 0.0]


def _describe(v: np.ndarray, x_ref: np.ndarray) -> str:
    """A rigid-body motion [u; θ] of the reference grid in words, for messages."""

    def fmt(x: np.ndarray) -> str:
        return ", ".join(f"{float(y):.3g}" for y in np.where(np.abs(x) < 1e-9, 0.0, x) + 0.0)

    t, a = v[:3], v[3:]
    if np.linalg.norm(a) <= 1e-8 * np.linalg.norm(t):
        t = t / np.linalg.norm(t)
        return f"translation along [{fmt(t * np.sign(t[np.argmax(np.abs(t))]))}]"
    scale = np.linalg.norm(a) * np.sign(a[np.argmax(np.abs(a))])
    t, a = t / scale, a / scale
    if abs(t @ a) > 1e-8 * max(np.linalg.norm(t), 1.0):
        return f"rotation [{fmt(a)}] with translation [{fmt(t)}]"
    return f"rotation about [{fmt(a)}] through ({fmt(x_ref + np.cross(a, t))})"  # u = θ × (x_ref − p)


def rbe3_matrix(r: np.ndarray, components, weights, axes=None) -> tuple[np.ndarray, np.ndarray]:
    """T (6 × m) with [u_ref; θ_ref] = T u_m, and the undetermined motions (k × 6, none: k = 0).

    One row per independent component: its grid's offset ``r`` (m × 3, x_i − x_ref),
    its component 1..6 and weight. T = (GᵀWG)⁻¹GᵀW (MSC QRG, RBE3): G stacks one
    rigid-body row per independent component, W = diag(WT, WT·Lc² for rotations),
    Lc = mean |r_i|; ``axes`` (m × 3 × 3, default basic): the axes each row's component is
    measured in (its grid's CD system). Solved in the scaled unknowns [u_ref; Lc·θ_ref] so
    that the singularity test has no units; the undetermined motions are [u; θ] of the
    null space.
    """
    r, w = np.asarray(r, float).reshape(-1, 3), np.array(weights, float)
    lc = float(np.mean(np.linalg.norm(r, axis=1)))
    scale = lc if lc > 0.0 else 1.0
    g_rows = np.zeros((len(r), 6))
    for n, c in enumerate(components):
        e = np.eye(3) if axes is None else axes[n]
        axis = e[:, (c - 1) % 3]
        if c <= 3:  # u_gc = e_c·u_ref + (r × e_c)·θ_ref
            g_rows[n, :3] = axis
            g_rows[n, 3:] = axis @ _cross_rows(r[n]) / scale
        else:
            # θ_gc = e_c·θ_ref, measured as Lc·θ with weight WT·Lc²/scale² (WT, or 0 if Lc = 0)
            g_rows[n, 3:] = axis
            w[n] *= (lc / scale) ** 2
    a = g_rows.T @ (w[:, None] * g_rows)
    eig, vec = np.linalg.eigh(a)
    null = eig <= _SINGULAR_RTOL * max(eig[-1], np.finfo(float).tiny)
    unscale = np.array([1.0, 1.0, 1.0] + [1.0 / scale] * 3)
    if null.any():
        return np.zeros((6, len(r))), (unscale[:, None] * vec[:, null]).T
    t = np.linalg.solve(a, g_rows.T * w)  # scaled: [u_ref; Lc θ_ref] = t [u; Lc θ]
    measured = np.array([1.0 if c <= 3 else scale for c in components])
    return t * measured * unscale[:, None], np.zeros((0, 6))


def undetermined(motions: np.ndarray, x_ref: np.ndarray) -> str:
    """The undetermined rigid-body motions of an RBE3's reference grid, in words."""
    return "; ".join(_describe(v, x_ref) for v in motions)


def _rbe3_matrix(card: Card, grids: _Grids) -> tuple[np.ndarray, list[tuple[int, int, str]]]:
    """:func:`rbe3_matrix` of an RBE3 card, over its independent (grid, component, field)
    list; rows in the global (CD) components of REFGRID."""
    ref = grids(card, "REFGRID")
    entries: list[tuple[int, int, str]] = []
    weights: list[float] = []
    for k, (weight, code, members) in enumerate(card["GROUPS"], 1):
        for j, g in enumerate(members, 1):
            key = f"G{k},{j}"
            grids(card, key, g)
            if g == card["REFGRID"]:
                raise card.error(key, f"grid {g} is the reference grid REFGRID and cannot also be an independent grid")
            for c in _components(code):
                entries.append((g, c, key))
                weights.append(weight)
    r = np.array([grids.xyz[grids.row[g]] - grids.xyz[ref] for g, _, _ in entries]).reshape(-1, 3)
    axes = None if grids.cd is None else [grids.axes(grids.row[g]) for g, _, _ in entries]
    t, null = rbe3_matrix(r, [c for _, c, _ in entries], weights, axes)
    if len(null):
        raise card.error(
            "GROUPS",
            f"the independent DoFs do not determine the rigid-body motion of REFGRID {card['REFGRID']} "
            f"(GᵀWG is singular; undetermined: {undetermined(null, grids.xyz[ref])}); add translations (123) "
            "of independent grids that are not all on one line through it, or their rotations (456)",
        )
    return (t if grids.cd is None else _six(grids.axes(ref)).T @ t), entries


def _dof_map(bulk: BulkData, grids: _Grids, spc_set: int | None, mpc_set: int | None = None) -> DofMap:
    """Independent DoFs and the map ``u[node, c] = coef[node, c] @ u_solved[index[node]]``.

    Independent DoFs are the (grid, component) pairs, in ascending order, that are
    neither constrained (SPC, SPC1, GRID PS) nor dependent (MSC QRG, per card):

    - RBE2: the CM components of each GM grid s are rigid-body functions of the GN grid
      m: translations u_s = u_m + θ_m × (x_s − x_m), rotations θ_s = θ_m.
    - RBE3: the REFC components of REFGRID are the weighted least-squares rigid-body
      motion of the independent components. With r_i = x_i − x_ref, each component c
      of grid i with weight w gives a row of G (m × 6): u_ic = e_c·u_ref + (r_i × e_c)·θ_ref
      (c = 1..3), θ_ic = e_c·θ_ref (c = 4..6); W = diag(w for translations, w·Lc² for
      rotations), Lc = mean |r_i|. Then [u_ref; θ_ref] = (GᵀWG)⁻¹GᵀW u_m and the REFC
      rows of that 6 × m matrix are the dependent rows. A singular GᵀWG (one grid or
      grids on one line with translations only) is an error.
    - RBAR, RBE1, RROD: see :mod:`jaxfem._rigid`.
    - MPC (set ``mpc_set``): Σ A_i u_GiCi = 0 with the first term dependent,
      u_G1C1 = −Σ_{i≥2} (A_i/A1) u_GiCi.

    Components are global: those of each grid's CD system (``coef`` is then rotated to
    basic axes, ``DofMap.cd``).

    The terms of a dependent DoF may themselves be dependent or constrained: chains are
    followed to independent DoFs (constrained ones contribute zero); loops and a DoF
    dependent on two cards are located errors. ``spc_set``/``mpc_set``: the set ids to
    apply; ``None`` takes the only set in the file (an error if there are several).
    """
    fixed = _constraints(bulk, grids, spc_set)
    dependent = _dependents(bulk, grids, fixed, mpc_set)
    labels = [
        (int(g), c)
        for g in grids.ids
        for c in range(1, COMPONENTS + 1)
        if (g, c) not in fixed and (g, c) not in dependent
    ]
    number = {label: i for i, label in enumerate(labels)}
    rows: dict[tuple[int, int], dict[int, float]] = {}
    node_rows = [[_row(int(g), c, dependent, fixed, number, rows) for c in range(1, COMPONENTS + 1)] for g in grids.ids]
    n_dof = len(labels)
    index, coef = _node_arrays(node_rows, n_dof)
    if grids.cd is not None:  # global (CD) components to basic: u_basic = diag(R, R) u_global
        coef = np.einsum("nij,njw->niw", np.stack([_six(r) for r in grids.cd]), coef)
    return DofMap(
        index=index,
        coef=coef,
        labels=_ints(labels, 2),
        massless=np.zeros(0, dtype=np.int64),
        auto_spc=np.zeros((0, 2), dtype=np.int64),
        n_dof=n_dof,
        cd=grids.cd,
    )


def _depend(dependent: _Dependent, fixed: dict[tuple[int, int], Card], card: Card, key: str, g: int, c: int,
            terms: list[_Term]) -> None:
    """Make (g, c) dependent on ``card`` through ``terms``; a constrained or already dependent DoF is an error."""
    if (g, c) in fixed:
        other = fixed[(g, c)]
        if other is None:
            raise card.error(key, f"point {g} is a scalar point: it has no component {c}")
        raise card.error(
            key, f"grid {g} component {c} is both {card.name}-dependent and constrained by "
            f"{other.name} at {other.file}:{other.line}",
        )
    if (g, c) in dependent:
        other = dependent[(g, c)][0]
        raise card.error(
            key,
            f"grid {g} component {c} is already dependent on {other.name} {other.id} at {other.file}:{other.line}",
        )
    dependent[(g, c)] = (card, terms)


def _dependents(bulk: BulkData, grids: _Grids, fixed: dict[tuple[int, int], Card], mpc_set: int | None) -> _Dependent:
    """(grid, component) -> (card, terms) of every DoF made dependent by an RBE2, RBE3 or MPC of the selected set."""
    dependent: _Dependent = {}
    for card in _by_id(bulk["RBE2"]):
        grids(card, "GN")
        for g in card["GM"]:
            grids(card, "GM", g)
            if g == card["GN"]:
                raise card.error("GM", f"grid {g} is both the independent grid GN and a dependent grid")
            for c in _components(card["CM"]):
                _depend(dependent, fixed, card, "CM", g, c, _rbe2_terms(card, grids, g, c))
    for card in _by_id(bulk["RBE3"]):
        t, entries = _rbe3_matrix(card, grids)
        for c in _components(card["REFC"]):
            terms = [((g, e), float(a), key) for (g, e, key), a in zip(entries, t[c - 1]) if a != 0.0]
            _depend(dependent, fixed, card, "REFC", card["REFGRID"], c, terms)
    for name, terms_of in (("RBAR", rbar), ("RBE1", rbe1), ("RROD", rrod)):
        for card in _by_id(bulk[name]):
            for g, c, key, terms in terms_of(card, grids):
                _depend(dependent, fixed, card, key, g, c, terms)
    mpc = _selected(bulk, ("MPC",), mpc_set, "mpc_set")
    for card in bulk["MPC"]:
        if card["SID"] not in mpc:
            continue
        for k, (g, _, _) in enumerate(card["TERMS"], 1):
            grids(card, f"G{k}", g)
        (g1, c1, a1), *others = [(g, _component(grids, card, f"C{k}", g, c), a)
                                 for k, (g, c, a) in enumerate(card["TERMS"], 1)]
        terms = [((g, c), -a / a1, f"G{k}") for k, (g, c, a) in enumerate(others, 2) if a != 0.0]
        _depend(dependent, fixed, card, "G1", g1, c1, terms)
    return dependent


def _known(dof: tuple[int, int], rows: dict[tuple[int, int], dict[int, float]], number: dict[tuple[int, int], int],
           fixed: dict[tuple[int, int], Card]) -> dict[int, float] | None:
    """Coefficients of an independent, constrained or already expanded DoF, else None."""
    if dof in rows:
        return rows[dof]
    if dof in number:
        return {number[dof]: 1.0}
    return {} if dof in fixed else None


def _loop_error(dependent: _Dependent, path: list[tuple[int, int]], keys: list[str], i: int,
                dof: tuple[int, int]) -> BulkDataError:
    """The located error of a dependency loop: from ``dof`` = ``path[i]`` along the path back to it."""
    path_text = " -> ".join(
        f"{other.name} {other.id} at {other.file}:{other.line} (grid {d[0]} component {d[1]})"
        for d in path[i:] + [dof]
        for other in (dependent[d][0],)
    )
    return dependent[dof][0].error(keys[i], f"rigid elements/MPCs depend on each other in a loop: {path_text}")


def _row(g: int, c: int, dependent: _Dependent, fixed: dict[tuple[int, int], Card], number: dict[tuple[int, int], int],
         rows: dict[tuple[int, int], dict[int, float]]) -> dict[int, float]:
    """Coefficients of (grid g, component c) on the independent DoFs, stored in ``rows``: a depth-first
    expansion with an explicit stack (a chain of rigid elements may be as long as the
    file). ``path`` holds the dependent DoFs being expanded, ``keys[i]`` the field
    followed from ``path[i]`` to ``path[i + 1]``, ``todo[i]`` the terms of ``path[i]``
    not yet looked at."""
    done = _known((g, c), rows, number, fixed)
    if done is not None:
        return done
    path, keys, todo = [(g, c)], [], [iter(dependent[(g, c)][1])]
    on_path = {(g, c): 0}
    while path:
        for (h, e), _, key in todo[-1]:
            if _known((h, e), rows, number, fixed) is not None:
                continue
            if (h, e) in on_path:  # a loop: from (h, e) along the path back to it
                raise _loop_error(dependent, path, keys + [key], on_path[(h, e)], (h, e))
            on_path[(h, e)] = len(path)
            path.append((h, e))
            keys.append(key)
            todo.append(iter(dependent[(h, e)][1]))
            break
        else:  # every term of path[-1] is known: combine them
            dof = path.pop()
            out: dict[int, float] = {}
            for term, a, _ in dependent[dof][1]:
                for d, value in _known(term, rows, number, fixed).items():
                    out[d] = out.get(d, 0.0) + a * value
            rows[dof] = out
            todo.pop()
            del on_path[dof]
            if keys:
                keys.pop()
    return rows[(g, c)]


def _node_arrays(node_rows: list[list[dict[int, float]]], n_dof: int) -> tuple[np.ndarray, np.ndarray]:
    """``index`` (nodes × w, padded with ``n_dof``) and ``coef`` (nodes × 6 × w) of :class:`DofMap` from each
    node's component rows."""
    used = [sorted(set().union(*r)) for r in node_rows]
    w = max((len(u) for u in used), default=0)
    index = np.full((len(used), w), n_dof, dtype=np.int64)
    coef = np.zeros((len(used), COMPONENTS, w))
    for n, (dofs, comps) in enumerate(zip(used, node_rows)):
        index[n, : len(dofs)] = dofs
        for c, coefficients in enumerate(comps):
            for k, dof in enumerate(dofs):
                coef[n, c, k] = coefficients.get(dof, 0.0)
    return index, coef
