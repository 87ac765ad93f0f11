"""Materials and cross sections of bulk data: MAT1, MAT2, MAT8, PBAR, PBARL, PBEAM, PROD.

One material table of MAT1, MAT2 and MAT8 (the last two checked in
:mod:`jaxfem._shell_build`; beams and rods need MAT1). MAT1 completes E, G, NU from two
of them (MSC QRG, MAT1 remarks), with −1 < NU ≤ 0.5, E > 0, G ≥ 0 and G > 0 where it is
used (torsion, shells); a PBARL section (BAR,
ROD, TUBE, BOX) gets A, I1, I2, J, K1, K2 from its dimensions (rectangle torsion: Roark
table 10.7; box: Bredt's formula), finite; PBEAM is a constant section (end A); every value is
checked. Tables are sorted by id, with the map id → row that the elements use.
"""

from __future__ import annotations

import numpy as np

from ._grids import _by_id, _f64, _ints
from ._model import MAT1, MAT2, MAT8, BeamSections, Materials, RodSections
from ._shell_build import _mat2_row, _mat8_row
from .io import BulkData, Card

_KINDS = {"MAT1": MAT1, "MAT2": MAT2, "MAT8": MAT8}


def _materials(bulk: BulkData) -> tuple[Materials, dict[int, int]]:
    """MAT1, MAT2 and MAT8 in one table sorted by id, and the map id -> row (fields as
    documented in :class:`jaxfem.Materials`)."""
    cards = _by_id(bulk["MAT1"] + bulk["MAT2"] + bulk["MAT8"])
    readers = {"MAT1": _mat1_row, "MAT2": _mat2_row, "MAT8": _mat8_row}
    rows = [readers[card.name](card) for card in cards]
    n = len(cards)
    E, G, nu, rho, E2, G1z, G2z = np.asarray([r[:7] for r in rows], dtype=np.float64).reshape(-1, 7).T
    ids = _ints([c.id for c in cards])
    materials = Materials(
        ids=ids, kind=_ints([_KINDS[c.name] for c in cards]), E=_f64(E), G=_f64(G), nu=_f64(nu), rho=_f64(rho),
        E2=_f64(E2), G1z=_f64(G1z), G2z=_f64(G2z), Q=_f64(np.reshape([r[7] for r in rows], (n, 3, 3))),
    )
    return materials, {int(m): i for i, m in enumerate(ids)}


def _mat1_row(card: Card) -> tuple:
    """(E, G, nu, rho, E2, G1z, G2z, Q) of a MAT1. Two of E, G, NU given: the third from
    G = E / (2 (1 + NU)); only E (or only G): the other modulus and NU are 0 (MSC QRG,
    MAT1 remarks).

    Ranges, given or derived: −1 < NU ≤ 0.5 (isotropic elasticity: positive bulk and
    shear moduli; 0.5 incompressible), E > 0, G ≥ 0 (G > 0 where it is used: see
    :func:`_material` and :func:`_check_shell_shear`), RHO ≥ 0, all finite.
    """
    E, G, nu = card["E"], card["G"], card["NU"]
    if E is not None and E <= 0.0:
        raise card.error("E", f"E must be > 0, got {E}")
    if G is not None and G < 0.0:
        raise card.error("G", f"G must be >= 0, got {G}")
    if nu is not None and not -1.0 < nu <= 0.5:
        raise card.error("NU", f"NU must lie in (-1, 0.5], got {nu}")
    if nu is None and E is not None and G is not None:
        if G <= 0.0:
            raise card.error("G", f"G must be > 0 to derive NU, got {G}")
        nu = E / (2.0 * G) - 1.0
        if not -1.0 < nu <= 0.5:
            raise card.error("G", f"E = {E:.6g} and G = {G:.6g} give NU = E/(2G) - 1 = {nu:.6g}, outside (-1, 0.5]")
    elif G is None and nu is not None:
        G = E / (2.0 * (1.0 + nu))
    elif E is None and nu is not None:
        E = 2.0 * (1.0 + nu) * G
    E, G, nu = E or 0.0, G or 0.0, nu or 0.0
    if E <= 0.0:
        raise card.error("E", f"E must be > 0, got {E}")
    if not (np.isfinite(E) and np.isfinite(G)):
        raise card.error("E" if card["E"] is None else "G", f"the derived modulus overflows (E = {E}, G = {G})")
    if card["RHO"] < 0.0:
        raise card.error("RHO", f"negative density {card['RHO']}")
    return E, G, nu, card["RHO"], 0.0, 0.0, 0.0, np.zeros((3, 3))


def _material(card: Card, mat_rows: dict[int, int], materials: Materials, j: float) -> int:
    """Row of the MAT1 of a beam or rod section; located error for another kind, and for
    torsion (J > 0) on a MAT1 with G = 0 (E alone given: MSC QRG sets G = NU = 0)."""
    if card["MID"] not in mat_rows:
        raise card.error("MID", f"material {card['MID']} is not defined (MAT1)")
    row = mat_rows[card["MID"]]
    kind = int(materials.kind[row])
    if kind != MAT1:
        what = "rods" if card.name == "PROD" else "beams"
        raise card.error("MID", f"material {card['MID']} is a MAT{kind}; {what} need MAT1")
    if j > 0.0 and float(materials.G[row]) == 0.0:
        raise card.error(
            "J" if "J" in card.values else "MID",
            f"torsion constant J = {j:.6g} needs a shear modulus, but MAT1 {card['MID']} has G = 0 "
            "(only E given); give G or NU on the MAT1",
        )
    return row


def _check_shell_shear(bulk: BulkData, materials: Materials, mat_rows: dict[int, int]) -> None:
    """Shells use G of a MAT1 (in-plane, twisting and transverse shear): a MAT1 with
    G = 0 (only E given) named by a PSHELL MID1..MID3 or a PCOMP ply is refused."""
    for card in bulk["PSHELL"] + bulk["PCOMP"]:
        if card.name == "PSHELL":
            uses = [(k, card[k]) for k in ("MID1", "MID2", "MID3") if card[k] is not None]
        else:
            uses = [(f"MID{k}", mid) for k, mid in enumerate(card["MID"], 1)]
        for key, mid in uses:
            row = mat_rows.get(mid)
            if row is not None and int(materials.kind[row]) == MAT1 and float(materials.G[row]) == 0.0:
                raise card.error(key, f"MAT1 {mid} has G = 0 (only E given), but shells use its shear modulus; "
                                      "give G or NU on the MAT1")


def _rectangle_torsion(a: float, b: float) -> float:
    """Torsion constant of a solid a × b rectangle, Roark (7th ed.) table 10.7 case 4:
    J = l s³ [1/3 − 0.21 (s/l)(1 − s⁴ / (12 l⁴))], l = long side, s = short side."""
    l, s = max(a, b), min(a, b)
    return l * s**3 * (1.0 / 3.0 - 0.21 * s / l * (1.0 - s**4 / (12.0 * l**4)))


def _pbarl_section(card: Card) -> tuple[float, float, float, float, float, float]:
    """(A, I1, I2, J, K1, K2) of a PBARL section [m², m⁴, m⁴, m⁴, -, -].

    Axes as in the QRG PBARL figures: element y vertical, z horizontal; I1 = ∫y² dA
    (plane 1, about z), I2 = ∫z² dA; K1 for shear along y, K2 along z.

    - BAR: DIM1 = width along z, DIM2 = height along y. I1 = DIM1·DIM2³/12,
      I2 = DIM2·DIM1³/12, J of a rectangle (Roark), K1 = K2 = 5/6.
    - ROD: DIM1 = radius r. I1 = I2 = πr⁴/4, J = πr⁴/2, K1 = K2 = 0.9 (solid circle).
    - TUBE: DIM1 = outer radius, DIM2 = inner radius. I = π(ro⁴ − ri⁴)/4, J = 2I,
      K1 = K2 = 0.5 (thin-walled circular tube).
    - BOX: DIM1 = width along z, DIM2 = height along y, DIM3 = thickness of the top and
      bottom walls (normal to y), DIM4 = thickness of the side walls (normal to z).
      J from Bredt's formula on the wall mid-lines,
      J = 2 t3 t4 (DIM1 − t4)² (DIM2 − t3)² / (DIM1 t4 + DIM2 t3 − t4² − t3²);
      K = web-area ratio: K1 = 2·DIM4·DIM2 / A (side walls carry shear along y),
      K2 = 2·DIM3·DIM1 / A (top and bottom walls carry shear along z).

    Dimensions must be > 0 and the properties finite (DIM1 = 1.E200 overflows r⁴).
    """
    dims = [card[f"DIM{k}"] for k in range(1, 5) if f"DIM{k}" in card.values]
    for k, d in enumerate(dims, 1):
        if d <= 0.0:
            raise card.error(f"DIM{k}", f"dimensions must be > 0, got {d}")
    try:
        values = _pbarl_formulas(card, dims)
    except OverflowError:  # float ** raises where float * gives inf
        values = (np.inf,)
    if not np.all(np.isfinite(values)):
        k = int(np.argmax(dims)) + 1
        raise card.error(f"DIM{k}", f"DIM{k} = {dims[k - 1]}: the section properties (A, I1, I2, J) overflow "
                                    "a 64-bit real")
    return values


def _pbarl_formulas(card: Card, dims: list[float]) -> tuple[float, float, float, float, float, float]:
    """The formulas of :func:`_pbarl_section`, per section type."""
    kind = card["TYPE"]
    if kind == "BAR":
        b, h = dims
        return b * h, b * h**3 / 12, h * b**3 / 12, _rectangle_torsion(b, h), 5 / 6, 5 / 6
    if kind == "ROD":
        (r,) = dims
        i = np.pi * r**4 / 4
        return np.pi * r**2, i, i, 2 * i, 0.9, 0.9
    if kind == "TUBE":
        ro, ri = dims
        if ri >= ro:
            raise card.error("DIM2", f"inner radius {ri} must be smaller than outer radius {ro}")
        i = np.pi * (ro**4 - ri**4) / 4
        return np.pi * (ro**2 - ri**2), i, i, 2 * i, 0.5, 0.5
    b, h, t3, t4 = dims  # BOX
    if 2 * t4 >= b or 2 * t3 >= h:
        raise card.error("DIM3", f"walls too thick for the box: need 2·DIM4 < DIM1 and 2·DIM3 < DIM2, got {dims}")
    bi, hi = b - 2 * t4, h - 2 * t3
    area = b * h - bi * hi
    j = 2 * t3 * t4 * (b - t4) ** 2 * (h - t3) ** 2 / (b * t4 + h * t3 - t4**2 - t3**2)
    return area, (b * h**3 - bi * hi**3) / 12, (h * b**3 - hi * bi**3) / 12, j, 2 * t4 * h / area, 2 * t3 * b / area


def _beam_sections(
    bulk: BulkData, mat_rows: dict[int, int], table: Materials
) -> tuple[BeamSections, dict[int, int]]:
    """PBAR (blank K1/K2 = 0: no shear flexibility), PBARL (see :func:`_pbarl_section`)
    and PBEAM (constant section, end A; K1/K2 default 1.0)."""
    cards = _by_id(bulk["PBAR"] + bulk["PBARL"] + bulk["PBEAM"])
    materials, values = [], []
    for card in cards:
        if card.name == "PBARL":
            area, i1, i2, j, k1, k2 = _pbarl_section(card)
            key_a = "DIM1"
        else:
            if card["I12"] != 0.0:
                raise card.error("I12", f"I12 = {card['I12']}: unsymmetric sections (I12 != 0) are not supported")
            area, i1, i2, j, k1, k2 = (card[k] for k in ("A", "I1", "I2", "J", "K1", "K2"))
            key_a = "A"
        if area <= 0.0:
            raise card.error(key_a, f"area must be > 0, got {area}")
        for key, value in (("I1", i1), ("I2", i2), ("J", j), ("K1", k1), ("K2", k2)):
            if value < 0.0:
                raise card.error(key, f"{key} must be >= 0, got {value}")
        if card["NSM"] < 0.0:
            raise card.error("NSM", f"negative non-structural mass {card['NSM']}")
        materials.append(_material(card, mat_rows, table, j))
        values.append((area, i1, i2, j, k1, k2, card["NSM"]))
    columns = np.asarray(values, dtype=np.float64).reshape(-1, 7).T
    ids = _ints([c.id for c in cards])
    sections = BeamSections(
        ids=ids,
        material=_ints(materials),
        **{k: _f64(v) for k, v in zip(("A", "I1", "I2", "J", "K1", "K2", "nsm"), columns)},
    )
    return sections, {int(p): i for i, p in enumerate(ids)}


def _rod_sections(
    cards: list[Card], mat_rows: dict[int, int], table: Materials
) -> tuple[RodSections, dict[int, int]]:
    cards = _by_id(cards)
    for card in cards:
        if card["A"] <= 0.0:
            raise card.error("A", f"area must be > 0, got {card['A']}")
        if card["J"] < 0.0:
            raise card.error("J", f"J must be >= 0, got {card['J']}")
        if card["NSM"] < 0.0:
            raise card.error("NSM", f"negative non-structural mass {card['NSM']}")
    ids = _ints([c.id for c in cards])
    sections = RodSections(
        ids=ids,
        material=_ints([_material(c, mat_rows, table, c["J"]) for c in cards]),
        A=_f64([c["A"] for c in cards]),
        J=_f64([c["J"] for c in cards]),
        nsm=_f64([c["NSM"] for c in cards]),
    )
    return sections, {int(p): i for i, p in enumerate(ids)}

