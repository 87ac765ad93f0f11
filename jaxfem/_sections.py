"""Materials and cross sections of bulk data: MAT1, MAT2, MAT8, PBAR, PBARL, PBEAM, PBEAML, PROD.

One material table of MAT1, MAT2 and MAT8 (the last two checked in
:mod:`jaxfem._shell_build`; beams and rods need MAT1). MAT1 completes E, G, NU from two
of them (MSC QRG, MAT1 remarks), with −1 < NU ≤ 0.5, E > 0, G ≥ 0 and G > 0 where it is
used (torsion, shells). PBARL and PBEAML sections get A, I1, I2, J, K1, K2 from their
dimensions through Nastran's section library (:mod:`jaxfem._section_library`), finite, in
principal axes; a tapered PBEAM or PBEAML is averaged along the element (with a warning);
every value is checked. Tables are sorted by id, with the map id → row that the elements use.
"""

from __future__ import annotations

import warnings

import numpy as np

from ._grids import _by_id, _f64, _ints
from ._model import MAT1, MAT2, MAT8, BeamSections, Materials, RodSections
from ._section_library import DIMENSIONS, LIMITS, TYPES, principal, section
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


_TAPER_RTOL = 1e-5  # stations equal to 5 significant digits: a constant section
_STATION = ("A", "I1", "I2", "I12", "J", "NSM")  # a PBEAM station after its X/XB
_ROW = ("A", "I1", "I2", "J", "K1", "K2", "nsm", "angle")  # the BeamSections values of a card


def _beam_sections(
    bulk: BulkData, mat_rows: dict[int, int], table: Materials
) -> tuple[BeamSections, dict[int, int]]:
    """PBAR (blank K1/K2 = 0: no shear flexibility), PBEAM (K1/K2 default 1.0; stations:
    :func:`_pbeam_values`), PBARL and PBEAML (:func:`_library_values`); a tapered section
    (stations differing beyond 5 significant digits) gives a ``UserWarning`` naming it."""
    cards = _by_id(bulk["PBAR"] + bulk["PBARL"] + bulk["PBEAM"] + bulk["PBEAML"])
    materials, values, types, dims = [], [], [], []
    for card in cards:
        library = card.name in ("PBARL", "PBEAML")
        if library:
            row, code, dim, tapered = _library_values(card)
        else:
            (row, tapered), code, dim = _pbeam_values(card), -1, ()
        if tapered:
            warnings.warn(f"{card.where()}: tapered {card.name}: its section properties are averaged along "
                          "the element (integral mean over X/XB), an approximation of Nastran's tapered beam",
                          UserWarning, stacklevel=3)
        if row[0] <= 0.0:
            raise card.error("DIM1" if library else "A", f"area must be > 0, got {row[0]}")
        for key, value in zip(_ROW[1:6], row[1:6]):
            if value < 0.0:
                raise card.error(key, f"{key} must be >= 0, got {value}")
        if row[6] < 0.0:
            raise card.error("NSM", f"negative non-structural mass {row[6]}")
        materials.append(_material(card, mat_rows, table, row[3]))
        values.append(row)
        types.append(code)
        dims.append(dim)
    width = max(map(len, dims), default=0)
    columns = np.asarray(values, dtype=np.float64).reshape(-1, len(_ROW)).T
    ids = _ints([c.id for c in cards])
    sections = BeamSections(
        ids=ids,
        material=_ints(materials),
        **{k: _f64(v) for k, v in zip(_ROW, columns)},
        section_type=_ints(types),
        dims=_f64(np.reshape([list(d) + [0.0] * (width - len(d)) for d in dims], (len(cards), width))),
    )
    return sections, {int(p): i for i, p in enumerate(ids)}


def _pbeam_values(card: Card) -> tuple[tuple, bool]:
    """The ``_ROW`` values of a PBAR or PBEAM, and whether tapered. PBEAM ``STATIONS``
    (X/XB, A, I1, I2, I12, J, NSM; blank: the end-A value) follow end A; a tapered
    PBEAM takes the integral mean of each value (:func:`_mean`). A section with I12 ≠ 0
    (I1·I2 > I12², MSC QRG PBAR remark 5) is stored in its principal axes as a PBARL's,
    a PBAR's K1, K2 then ignored (remark 4)."""
    end_a = tuple(card[k] for k in _STATION)
    stations = [(0.0, *end_a)] + [(s[0], *(a if v is None else v for v, a in zip(s[1:], end_a)))
                                  for s in card.values.get("STATIONS", ())]
    for station in stations:
        if station[2] * station[3] <= station[4] ** 2 and station[4] != 0.0:
            raise card.error("I12", f"I1·I2 must exceed I12² (got I1 = {station[2]}, I2 = {station[3]}, "
                                    f"I12 = {station[4]})")
        if station[6] < 0.0:
            raise card.error("NSM", f"negative non-structural mass {station[6]}")
    tapered = _tapered([s[1:] for s in stations])
    a, i1, i2, i12, j, nsm = _mean(card, stations) if tapered else end_a
    k1, k2, angle = card["K1"], card["K2"], 0.0
    if abs(i12) > 1e-12 * (i1 + i2):
        k1, k2 = (0.0, 0.0) if card.name == "PBAR" else (k1, k2)
        angle, i1, i2, k1, k2 = (float(v) for v in principal(i1, i2, i12, k1, k2))
    return (a, i1, i2, j, k1, k2, nsm, angle), tapered


def _library_values(card: Card) -> tuple[tuple, int, tuple, bool]:
    """``(row, type code, dims, tapered)`` of a PBARL or PBEAML (MSC Nastran QRG, PBARL and
    PBEAML), from :mod:`jaxfem._section_library`.

    PBEAML: ``DIMS`` per station (end A first, end B last), ``XXB`` their X/XB, ``NSM`` per
    station; tapered, the properties' integral mean (:func:`_mean`) with code −1 and no
    dims (not a ``dim`` parameter). The section is stored in its principal axes
    (:func:`jaxfem._section_library.principal`); a PBARL with I12 ≠ 0 has K1 = K2 = 0, as
    Nastran ignores K1, K2 of a PBAR with I12 ≠ 0 (MSC Nastran QRG, PBAR remark 4).
    """
    name = card["TYPE"]
    stations = _station_dims(card)
    nsm = card["NSM"] if card.name == "PBEAML" else (card["NSM"],)
    xs = card["XXB"] if card.name == "PBEAML" else (0.0,)
    if not len(xs) == len(nsm) == len(stations):
        raise card.error("XXB", f"{len(stations)} stations of dimensions, {len(xs)} X/XB and {len(nsm)} NSM")
    if min(nsm) < 0.0:
        raise card.error("NSM", f"negative non-structural mass {min(nsm)}")
    tapered = _tapered([(*d, m) for d, m in zip(stations, nsm)])
    props = [(*_library(card, d), m) for d, m in zip(stations, nsm)]
    a, i1, i2, i12, j, k1, k2, mass = _mean(card, [(x, *p) for x, p in zip(xs, props)]) if tapered else props[0]
    if abs(i12) <= 1e-12 * (i1 + i2):
        angle = 0.0
    else:
        k1, k2 = (0.0, 0.0) if card.name == "PBARL" else (k1, k2)
        angle, i1, i2, k1, k2 = (float(v) for v in principal(i1, i2, i12, k1, k2))
    row = (a, i1, i2, j, k1, k2, mass, angle)
    return (row, -1, (), True) if tapered else (row, TYPES.index(name), stations[0], False)


def _station_dims(card: Card) -> list[tuple[float, ...]]:
    """DIM1..DIMn of each station (a PBARL has one), each > 0 and drawing the shape
    (:data:`jaxfem._section_library.LIMITS`)."""
    name, n = card["TYPE"], DIMENSIONS[card["TYPE"]]
    if card.name == "PBEAML":
        stations = [tuple(d) for d in card["DIMS"]]
    else:
        stations = [tuple(card[f"DIM{k}"] for k in range(1, n + 1))]
    for dims in stations:
        if len(dims) != n:
            raise card.error("DIMS", f"TYPE {name} has {n} dimensions, got {len(dims)}")
        for k, d in enumerate(dims, 1):
            if d <= 0.0:
                raise card.error(f"DIM{k}", f"dimensions must be > 0, got {d}")
        if name in LIMITS and not LIMITS[name][2](dims):
            raise card.error(LIMITS[name][0], LIMITS[name][1].format(d=list(dims)) + f" (TYPE {name})")
    return stations


def _library(card: Card, dims: tuple[float, ...]) -> tuple[float, ...]:
    """``(A, I1, I2, I12, J, K1, K2)`` of one station, finite (a located error where the
    dimensions overflow or underflow them: DIM1 = 1.E200 overflows r⁴)."""
    try:
        values = tuple(float(v) for v in section(card["TYPE"], tuple(float(d) for d in dims)))
    except (OverflowError, ZeroDivisionError):  # float ** raises where float * gives inf
        values = (np.inf,)
    if not np.all(np.isfinite(values)):
        k = int(np.argmax(np.abs(np.log(dims)))) + 1
        raise card.error(f"DIM{k}", f"DIM{k} = {dims[k - 1]}: the section properties (A, I1, I2, J) overflow "
                                    "or underflow a 64-bit real")
    return values


def _tapered(stations: list[tuple]) -> bool:
    """Whether station values differ from end A's beyond 5 significant digits."""
    return not np.allclose(stations, stations[0], rtol=_TAPER_RTOL, atol=0.0)


def _mean(card: Card, stations: list[tuple]) -> tuple[float, ...]:
    """The integral mean over X/XB of the values of ``stations`` ``(X/XB, values...)``,
    linear between stations (trapezoidal rule), X/XB ascending in [0, 1]."""
    table = np.asarray(stations, dtype=np.float64)
    x = table[:, 0]
    if x[0] != 0.0 or x[-1] > 1.0 or np.any(np.diff(x) < 0.0):
        raise card.error("XXB", f"station positions X/XB must ascend from 0 to at most 1, got {x.tolist()}")
    if x[-1] == 0.0:
        return tuple(table[-1, 1:])
    return tuple(np.trapezoid(table[:, 1:], x, axis=0) / x[-1])


def _section_angle(card: Card) -> float:
    """The principal-axis angle θ [rad] of a beam property card, by which its elements' v
    turns (see :func:`jaxfem._build._beams`): 0 but for a section with I12 ≠ 0."""
    return (_library_values(card) if card.name in ("PBARL", "PBEAML") else _pbeam_values(card))[0][7]


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

