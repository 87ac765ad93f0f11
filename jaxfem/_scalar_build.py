"""Build the scalar elements, CONM1 and the direct input matrices of bulk data.

CELAS1–4 (springs), CMASS1–4 with PMASS, CDAMP1–4 with PDAMP, CVISC with PVISC, CONM1
and DMIG (MSC QRG, per card). An end of a scalar element is a grid with a component
1..6 in its CD system, a scalar point (SPOINT, component 0 or blank) or ground (blank or
0); a DMIG term names (point, component) the same way. Direct matrices are those the
subcase names in K2GG, M2GG, B2GG (``name`` or ``factor*name``, summed), scaled by PARAM
CK2, CM2, CB2; M2GG is not scaled by WTMASS (MSC QRG, M2GG remark 4).
"""

from __future__ import annotations

import re

import numpy as np

from ._constraints import _component
from ._grids import _by_id, _f64, _Grids, _ints
from ._model import Springs
from ._scalar_model import Conm1, Dampers, DirectMatrices, ScalarMasses
from .io import BulkData, BulkDataError, Card

_SYMMETRY_RTOL = 1e-8  # a square (IFO 1) DMIG is used when A − Aᵀ is below rtol·max|A|


_SCALAR_ELEMENTS = tuple(f"{kind}{n}" for kind in ("CELAS", "CMASS", "CDAMP") for n in (1, 2, 3, 4))


def implicit_spoints(bulk: BulkData) -> set[int]:
    """Ids that scalar elements name as scalar points (S1/S2 of CELAS3/4, CMASS3/4, CDAMP3/4;
    G with component 0 or blank of the others): Nastran needs no SPOINT for them (MSC QRG,
    SPOINT remark 2); those that are GRIDs are kept as grids (and then need a component)."""
    ids: set[int] = set()
    for card in (c for name in _SCALAR_ELEMENTS for c in bulk[name]):
        if "S1" in card.values:
            ids |= {card[k] for k in ("S1", "S2") if card[k]}
        else:
            ids |= {card[g] for g, c in (("G1", "C1"), ("G2", "C2")) if card[g] and not card[c]}
    return ids


def _ends(card: Card, grids: _Grids) -> tuple[list[int], list[int]]:
    """Rows (−1: ground) and stored components of the two ends of a scalar element."""
    keys = (("G1", "C1"), ("G2", "C2")) if "G1" in card.values else (("S1", None), ("S2", None))
    nodes, comps = [], []
    for g, c in keys:
        point = card[g]
        if not point:
            nodes.append(-1)
            comps.append(0)
            continue
        nodes.append(grids(card, g))
        comps.append(_component(grids, card, c or g, point, (card[c] or 0) if c else 0))
    if nodes == [-1, -1]:
        raise card.error(keys[0][0], "both ends are grounded")
    return nodes, comps


_PROPERTIES = ("PBAR", "PBARL", "PBEAM", "PBEAML", "PROD", "PELAS", "PBUSH", "PSHELL", "PCOMP", "PMASS", "PDAMP",
               "PVISC")


def _properties(bulk: BulkData) -> dict[int, Card]:
    return {c.id: c for name in _PROPERTIES for c in bulk[name]}


def _value(card: Card, key: str, properties: dict[int, Card], kind: str) -> float:
    """The element's own value ``key`` or that of its property (PELAS, PMASS, PDAMP, PVISC)."""
    if key in card.values:
        return card[key]
    prop = properties.get(card["PID"])
    if prop is None:
        raise card.error("PID", f"property {card['PID']} is not defined")
    if prop.name != kind:
        raise card.error("PID", f"property {card['PID']} is a {prop.name}; {card.name} needs {kind}")
    return prop[key]


def springs(bulk: BulkData, grids: _Grids) -> Springs:
    """CELAS1 (k from PELAS), CELAS2 (k inline), CELAS3 (PELAS) and CELAS4 (inline) on scalar points."""
    cards = _by_id(bulk["CELAS1"] + bulk["CELAS2"] + bulk["CELAS3"] + bulk["CELAS4"])
    pelas = _properties(bulk)
    k, nodes, comps = [], [], []
    for card in cards:
        k.append(_value(card, "K", pelas, "PELAS"))
        n, c = _ends(card, grids)
        nodes.append(n)
        comps.append(c)
    n = len(cards)
    return Springs(
        ids=_ints([c.id for c in cards]),
        pids=_ints([c["PID"] if "PID" in c.values else 0 for c in cards]),
        nodes=_ints(nodes, 2),
        components=_ints(comps, 2),
        k=_f64(k),
        k_scale=_f64(np.ones(n)),
    )


def scalar_masses(bulk: BulkData, grids: _Grids, wtmass: float) -> ScalarMasses | None:
    """CMASS1–4 (m × WTMASS); None without any."""
    cards = _by_id([c for name in ("CMASS1", "CMASS2", "CMASS3", "CMASS4") for c in bulk[name]])
    if not cards:
        return None
    pmass = _properties(bulk)
    m, nodes, comps = [], [], []
    for card in cards:
        m.append(_value(card, "M", pmass, "PMASS") * wtmass)
        n, c = _ends(card, grids)
        nodes.append(n)
        comps.append(c)
    return ScalarMasses(ids=_ints([c.id for c in cards]),
                        pids=_ints([c["PID"] if "PID" in c.values else 0 for c in cards]),
                        nodes=_ints(nodes, 2), components=_ints(comps, 2), m=_f64(m), m_scale=_f64(np.ones(len(m))))


def dampers(bulk: BulkData, grids: _Grids) -> Dampers | None:
    """CDAMP1–4 (b) and CVISC (CE, CR of PVISC); None without any."""
    scalar = [c for name in ("CDAMP1", "CDAMP2", "CDAMP3", "CDAMP4") for c in bulk[name]]
    cards = _by_id(scalar + bulk["CVISC"])
    if not cards:
        return None
    pdamp = pvisc = _properties(bulk)
    b, br, nodes, comps = [], [], [], []
    for card in cards:
        if card.name == "CVISC":
            b.append(_value(card, "CE", pvisc, "PVISC"))
            br.append(_value(card, "CR", pvisc, "PVISC"))
            nodes.append([grids(card, "G1"), grids(card, "G2")])
            comps.append([0, 0])
        else:
            b.append(_value(card, "B", pdamp, "PDAMP"))
            br.append(0.0)
            n, c = _ends(card, grids)
            nodes.append(n)
            comps.append(c)
    return Dampers(ids=_ints([c.id for c in cards]), nodes=_ints(nodes, 2), components=_ints(comps, 2),
                   axial=np.array([c.name == "CVISC" for c in cards]), b=_f64(b), br=_f64(br))


_CONM1_KEYS = tuple(f"M{i}{j}" for i in range(1, 7) for j in range(1, i + 1))


def conm1(bulk: BulkData, grids: _Grids, wtmass: float) -> Conm1 | None:
    """CONM1: the lower triangle M11, M21, M22, ... M66 in system CID (its axes at the
    grid), to basic: diag(R, R) M diag(R, R)ᵀ, times WTMASS; None without any."""
    cards = _by_id(bulk["CONM1"])
    if not cards:
        return None
    nodes, mats = [], []
    for card in cards:
        g = grids(card, "G")
        m = np.zeros((6, 6))
        for key in _CONM1_KEYS:
            i, j = int(key[1]) - 1, int(key[2]) - 1
            m[i, j] = m[j, i] = card[key]
        eig = np.linalg.eigvalsh(m)
        if eig[0] < -1e-12 * max(np.max(np.abs(eig)), np.finfo(float).tiny):
            raise card.error("M11", f"indefinite mass matrix: eigenvalues {eig.tolist()} must be >= 0")
        r = np.kron(np.eye(2), grids.frame(card, "CID").axes_at(grids.xyz[g]))
        nodes.append(g)
        mats.append(r @ m @ r.T * wtmass)
    return Conm1(ids=_ints([c.id for c in cards]), nodes=np.asarray(nodes, np.int64),
                 m=_f64(np.reshape(mats, (-1, 6, 6))), m_scale=_f64(np.ones(len(cards))))


_TERM = re.compile(r"\s*(?:([-+]?[\d.]+(?:[ED][-+]?\d+)?)\s*\*\s*)?([A-Z][A-Z0-9_]*)\s*$")


def _named(text: str | None, where: str) -> list[tuple[float, str]]:
    """``[(factor, name)]`` of a case-control selection ``name, 2.0*name2, ...``."""
    if not text:
        return []
    out = []
    for part in text.upper().split(","):
        m = _TERM.match(part)
        if m is None:
            raise BulkDataError(f"{where}: cannot read the matrix selection {text!r} (expected names or factor*name)")
        out.append((float(m.group(1).replace("D", "E")) if m.group(1) else 1.0, m.group(2)))
    return out


def _dmig(card: Card, grids: _Grids) -> dict[tuple[tuple[int, int], tuple[int, int]], float]:
    """The terms of one DMIG matrix by (row DoF, column DoF), symmetric (IFO 6: one triangle
    given) or square (IFO 1: used when symmetric to 1e-8)."""
    terms: dict = {}
    for gj, cj, gi, ci, a in card["ENTRIES"]:
        col = (grids(card, "GJ", gj), _component(grids, card, "CJ", gj, cj))
        row = (grids(card, "GI", gi), _component(grids, card, "CI", gi, ci))
        terms[(row, col)] = terms.get((row, col), 0.0) + a
        if card["IFO"] == 6 and row != col:
            terms[(col, row)] = terms.get((col, row), 0.0) + a
    if card["IFO"] == 1:
        worst = max((abs(a - terms.get((c, r), 0.0)) for (r, c), a in terms.items()), default=0.0)
        if worst > _SYMMETRY_RTOL * max(map(abs, terms.values()), default=0.0):
            raise card.error("IFO", f"matrix {card.id} is not symmetric (|A − Aᵀ| up to {worst:.3g}): "
                                    "unsymmetric direct matrices are not supported")
    return terms


def direct_matrices(bulk: BulkData, grids: _Grids, subcase, params: dict[str, Card]) -> DirectMatrices | None:
    """Sum of the DMIG matrices the subcase selects (K2GG, M2GG, B2GG), or None."""
    if subcase is None:
        return None
    dmig = {c.id: c for c in bulk["DMIG"]}
    scale = {key: (params[p]["V1"] if p in params else 1.0) for key, p in (("k", "CK2"), ("m", "CM2"), ("b", "CB2"))}
    parts: dict[str, dict] = {"k": {}, "m": {}, "b": {}}
    names = []
    for key, selection in (("k", "K2GG"), ("m", "M2GG"), ("b", "B2GG")):
        for factor, name in _named(getattr(subcase, selection.lower(), None), f"{subcase.where}: {selection}"):
            if name not in dmig:
                raise BulkDataError(f"{subcase.where}: {selection} = {name}: no DMIG {name} in the bulk data")
            names.append(name)
            for dofs, a in _dmig(dmig[name], grids).items():
                parts[key][dofs] = parts[key].get(dofs, 0.0) + factor * scale[key] * a
    if not names:
        return None
    dofs = sorted({d for part in parts.values() for pair in part for d in pair})
    at = {d: i for i, d in enumerate(dofs)}
    mats = {key: np.zeros((len(dofs), len(dofs))) for key in parts}
    for key, part in parts.items():
        for (row, col), a in part.items():
            mats[key][at[row], at[col]] = a
    return DirectMatrices(names=tuple(names), nodes=_ints([d[0] for d in dofs]), components=_ints([d[1] for d in dofs]),
                          **{key: _f64(v) for key, v in mats.items()})
