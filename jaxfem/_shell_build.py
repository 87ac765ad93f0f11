"""Shells of bulk data: MAT2/MAT8 rows, PSHELL/PCOMP sections, CQUAD4/CTRIA3 elements.

Semantics of the MSC Nastran Quick Reference Guide (QRG), entries CQUAD4, CTRIA3,
PSHELL, PCOMP, MAT2, MAT8 and PARAM K6ROT:

- MAT8 (orthotropic): E1, E2, G12 > 0 and ν12²·E2/E1 < 1 (else its plane-stress matrix
  is not positive definite); G1Z, G2Z >= 0, blank = 0 (transverse shear rigid). MAT2: the
  3 × 3 matrix of G11..G33 must be positive definite.
- PSHELL: MID1 (membrane), MID2 (bending), MID3 (transverse shear), MID4 (coupling); T > 0
  is required; MID1 or MID2 must be given, MID3 needs MID2 and MID4 needs MID1 and MID2;
  12I/T³ > 0 with MID2, TS/T > 0 with MID3; blank MID3 is shear rigid. ``z0`` of a
  PSHELL row is −T/2 (unused).
- PCOMP: plies bottom to top; LAM = SYM lists the bottom half, mirrored here (the top half
  is the listed plies in reverse order); Z0 blank = −(total thickness)/2; ply angles
  in radians; a ply of MAT8 with G1Z or G2Z blank (or 0) makes the section shear rigid.
  ``bending_ratio`` and ``shear_ratio`` of a PCOMP row are 1 (unused: the laminate is
  integrated through the plies).
- CQUAD4/CTRIA3: THETA [deg] or MCID (the x axis of that CORD2R projected on the element
  plane; angle from the element x axis about the normal, element frame of
  :func:`jaxfem.elements._shell.shell_frame`); ZOFFS; corner thicknesses T1..Tn over the
  PSHELL T (TFLAG = 1: as given), refused on a PCOMP element.

Geometry checks (located errors): a grid twice in one element; coincident corners; zero
area (area <= 1e-10 · longest side²; collinear triangle corners); a quad that is concave
or has a corner angle >= 180° (a corner cross product (e_{i−1} × e_i)·n not positive,
n the element normal); warping. The warp of a quad is |h| / (half the shorter diagonal),
±h the distances of the corners from the mean plane through their centroid normal to n.
These limits are ours, not Nastran's: warp above :data:`WARP_ERROR` (0.2) is an error,
above :data:`WARP_WARN` (0.05) a ``UserWarning`` naming the element.
"""

from __future__ import annotations

import warnings

import jax
import numpy as np

from ._grids import _by_id, _f64, _Grids, _ints
from ._model import MAT8, Materials, Shells, ShellSections
from .elements import shell_frame
from .io import BulkData, BulkDataError, Card

WARP_ERROR = 0.2  # warp |h| / (half the shorter diagonal) above which a quad is refused
WARP_WARN = 0.05  # ... above which it is reported with a UserWarning
_AREA_TOL = 1e-10  # zero area: area <= tol · (longest side)²
_LENGTH_TOL = 1e-10  # coincident corners: side <= tol · longest side
_CORNER_TOL = 1e-10  # corner angle >= 180°: (e_{i-1} × e_i)·n <= tol · |e_{i-1}| |e_i|
_PARALLEL_TOL = 1e-8  # MCID x axis along the normal: |projection| < tol
_DEFINITE_TOL = 1e-12  # MAT2: smallest eigenvalue of Q <= tol · largest: not positive definite


# ---------------------------------------------------------------------------------------
# Materials


def _mat2_row(card: Card) -> tuple:
    """(E, G, nu, rho, E2, G1z, G2z, Q) of a MAT2: only rho and Q; Q positive definite."""
    g = {k: card[k] for k in ("G11", "G12", "G13", "G22", "G23", "G33")}
    q = np.array([[g["G11"], g["G12"], g["G13"]], [g["G12"], g["G22"], g["G23"]], [g["G13"], g["G23"], g["G33"]]])
    eig = np.linalg.eigvalsh(q)
    if eig[0] <= _DEFINITE_TOL * np.max(np.abs(eig)):
        raise card.error("G11", f"the matrix G11..G33 is not positive definite (eigenvalues {eig.tolist()})")
    _density(card)
    return 0.0, 0.0, 0.0, card["RHO"], 0.0, 0.0, 0.0, q


def _mat8_row(card: Card) -> tuple:
    """(E, G, nu, rho, E2, G1z, G2z, Q) of a MAT8: E = E1, G = G12, nu = NU12, blank G1Z/G2Z 0."""
    e1, e2, nu, g12 = card["E1"], card["E2"], card["NU12"], card["G12"]
    for key, value in (("E1", e1), ("E2", e2), ("G12", g12)):
        if value <= 0.0:
            raise card.error(key, f"{key} must be > 0, got {value}")
    if nu * nu * e2 / e1 >= 1.0:
        raise card.error(
            "NU12", f"not positive definite: NU12² · E2 / E1 = {nu * nu * e2 / e1:.6g} must be < 1 (NU12 = {nu})"
        )
    gz = []
    for key in ("G1Z", "G2Z"):
        value = card[key] or 0.0
        if value < 0.0:
            raise card.error(key, f"{key} must be >= 0, got {value}")
        gz.append(value)
    _density(card)
    return e1, g12, nu, card["RHO"], e2, gz[0], gz[1], np.zeros((3, 3))


def _density(card: Card) -> None:
    if card["RHO"] < 0.0:
        raise card.error("RHO", f"negative density {card['RHO']}")


# ---------------------------------------------------------------------------------------
# Sections


def _material_row(card: Card, key: str, mid: int | None, mat_rows: dict[int, int]) -> int:
    if mid is None:
        return -1
    if mid not in mat_rows:
        raise card.error(key, f"material {mid} is not defined (MAT1, MAT2 or MAT8)")
    return mat_rows[mid]


def _pshell_row(card: Card, mat_rows: dict[int, int]) -> dict:
    """PSHELL: material rows of MID1..MID4 (-1 blank) and the checks of the module docstring."""
    mids = {k: card[k] for k in ("MID1", "MID2", "MID3", "MID4")}
    rows = [_material_row(card, k, mid, mat_rows) for k, mid in mids.items()]
    if card["T"] <= 0.0:
        raise card.error("T", f"T must be > 0, got {card['T']}")
    if mids["MID1"] is None and mids["MID2"] is None:
        raise card.error("MID1", "MID1 or MID2 is required (a PSHELL needs membrane or bending stiffness)")
    if mids["MID3"] is not None and mids["MID2"] is None:
        raise card.error("MID3", "transverse shear (MID3) needs a bending material MID2")
    if mids["MID4"] is not None and (mids["MID1"] is None or mids["MID2"] is None):
        raise card.error("MID4", "membrane-bending coupling (MID4) needs MID1 and MID2")
    if mids["MID2"] is not None and card["BENDING"] <= 0.0:
        raise card.error("BENDING", f"12I/T**3 must be > 0, got {card['BENDING']}")
    if mids["MID3"] is not None and card["SHEAR"] <= 0.0:
        raise card.error("SHEAR", f"TS/T must be > 0, got {card['SHEAR']}")
    return dict(
        composite=False, shear_rigid=mids["MID3"] is None, materials=rows, plies=[], t=card["T"],
        bending_ratio=card["BENDING"], shear_ratio=card["SHEAR"], z0=-0.5 * card["T"],
    )


def _pcomp_row(card: Card, materials: Materials, mat_rows: dict[int, int]) -> dict:
    """PCOMP plies bottom to top (LAM = SYM: the listed plies, then the same in reverse)."""
    rows = [_material_row(card, f"MID{k}", mid, mat_rows) for k, mid in enumerate(card["MID"], 1)]
    plies = list(zip(rows, card["T"], np.radians(card["THETA"]).tolist()))
    if card["LAM"] == "SYM":
        plies += plies[::-1]
    total = sum(t for _, t, _ in plies)
    used = np.array([row for row, _, _ in plies])
    no_shear = (np.asarray(materials.G1z)[used] == 0.0) | (np.asarray(materials.G2z)[used] == 0.0)
    rigid = bool(np.any((materials.kind[used] == MAT8) & no_shear))
    return dict(
        composite=True, shear_rigid=rigid, materials=[-1] * 4, plies=plies, t=total, bending_ratio=1.0,
        shear_ratio=1.0, z0=-0.5 * total if card["Z0"] is None else card["Z0"],
    )


def _shell_sections(bulk: BulkData, materials: Materials, mat_rows: dict[int, int]) -> tuple[ShellSections, dict]:
    """PSHELL and PCOMP rows sorted by property id, and the map pid -> row."""
    cards = _by_id(bulk["PSHELL"] + bulk["PCOMP"])
    rows = []
    for card in cards:
        if card["NSM"] < 0.0:
            raise card.error("NSM", f"negative non-structural mass {card['NSM']}")
        rows.append(_pshell_row(card, mat_rows) if card.name == "PSHELL" else _pcomp_row(card, materials, mat_rows))
    n = len(rows)
    nply = max([1] + [len(r["plies"]) for r in rows])
    ply_material = np.full((n, nply), -1, np.int64)
    ply_t, ply_theta = np.zeros((n, nply)), np.zeros((n, nply))
    for i, r in enumerate(rows):
        for j, (row, t, theta) in enumerate(r["plies"]):
            ply_material[i, j], ply_t[i, j], ply_theta[i, j] = row, t, theta
    ids = _ints([c.id for c in cards])
    ones = _f64(np.ones(n))
    sections = ShellSections(
        ids=ids,
        composite=np.array([r["composite"] for r in rows], dtype=bool),
        shear_rigid=np.array([r["shear_rigid"] for r in rows], dtype=bool),
        materials=_ints([r["materials"] for r in rows], 4),
        ply_material=ply_material,
        t=_f64([r["t"] for r in rows]),
        bending_ratio=_f64([r["bending_ratio"] for r in rows]),
        shear_ratio=_f64([r["shear_ratio"] for r in rows]),
        nsm=_f64([c["NSM"] for c in cards]),
        z0=_f64([r["z0"] for r in rows]),
        ply_t=_f64(ply_t),
        ply_theta=_f64(ply_theta),
        membrane=ones,
        bending=ones,
        shear=ones,
    )
    return sections, {int(p): i for i, p in enumerate(ids)}


# ---------------------------------------------------------------------------------------
# Elements


def _shell_property(card: Card, properties: dict[int, Card]) -> Card:
    prop = properties.get(card["PID"])
    if prop is None:
        raise card.error("PID", f"property {card['PID']} is not defined")
    if prop.name not in ("PSHELL", "PCOMP"):
        raise card.error("PID", f"property {card['PID']} is a {prop.name}; {card.name} needs PSHELL or PCOMP")
    return prop


def _corners(card: Card, keys: tuple[str, ...], xyz: np.ndarray) -> None:
    """Located errors for a grid given twice, coincident corners and zero area."""
    for j, key in enumerate(keys):
        for earlier in keys[:j]:
            if card[key] == card[earlier]:
                raise card.error(key, f"grid {card[key]} is given twice ({earlier} and {key})")
    nn = len(keys)
    sides = np.roll(xyz, -1, axis=0) - xyz
    lengths = np.linalg.norm(sides, axis=1)
    longest = lengths.max()
    for i in range(nn):
        if lengths[i] <= _LENGTH_TOL * longest:
            a, b = keys[i], keys[(i + 1) % nn]
            raise card.error(b, f"corners {a} and {b} coincide (grids {card[a]} and {card[b]})")
    if nn == 3:
        area = 0.5 * np.linalg.norm(np.cross(xyz[1] - xyz[0], xyz[2] - xyz[0]))
        if area <= _AREA_TOL * longest**2:
            raise card.error("G3", f"zero area: corners G1, G2, G3 are collinear (area {area:.3g})")
    else:
        area = 0.5 * np.linalg.norm(np.cross(xyz[2] - xyz[0], xyz[3] - xyz[1]))
        if area <= _AREA_TOL * longest**2:
            raise card.error("G4", f"zero area (area {area:.3g})")


def _quad_shape(card: Card, xyz: np.ndarray, normal: np.ndarray) -> None:
    """Located error for a concave quad or a corner angle >= 180°; warping check."""
    sides = np.roll(xyz, -1, axis=0) - xyz  # side i: corner i -> i + 1
    lengths = np.linalg.norm(sides, axis=1)
    for i in range(4):
        turn = np.cross(sides[i - 1], sides[i]) @ normal
        if turn <= _CORNER_TOL * lengths[i - 1] * lengths[i]:
            key = f"G{i + 1}"
            raise card.error(key, f"concave quad or corner angle >= 180° at {key} (grid {card[key]})")
    h = np.max(np.abs((xyz - xyz.mean(axis=0)) @ normal))
    half = 0.5 * min(np.linalg.norm(xyz[2] - xyz[0]), np.linalg.norm(xyz[3] - xyz[1]))
    warp = h / half
    if warp > WARP_ERROR:
        raise card.error("G4", f"warped quad: warp {warp:.3g} (|h| / half the shorter diagonal) above {WARP_ERROR}")
    if warp > WARP_WARN:
        warnings.warn(
            f"{card.where('G4')}: warped quad: warp {warp:.3g} "
            f"(|h| / half the shorter diagonal) above {WARP_WARN}",
            UserWarning,
            stacklevel=5,
        )


# The element-by-element checks above cost about 0.2 ms per element (about 10 s of a
# 30 s build of 50,000 quads); these vectorised screens select the elements on which they can fail or
# warn, with margins 10⁴ times the tolerances, so that the exact checks, messages and
# warnings stay those of :func:`_corners` and :func:`_quad_shape`, in element-id order.
_SCREEN = 1e4


def _suspect_corners(rows: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """Elements (n, nn grid rows; corners (n, nn, 3)) on which :func:`_corners` may fail."""
    nn = rows.shape[1]
    twice = np.zeros(len(rows), dtype=bool)
    for j in range(nn):
        for k in range(j):
            twice |= rows[:, j] == rows[:, k]
    sides = np.roll(xyz, -1, axis=1) - xyz
    lengths = np.linalg.norm(sides, axis=2)
    longest = lengths.max(axis=1, initial=0.0)
    short = (lengths <= _SCREEN * _LENGTH_TOL * longest[:, None]).any(axis=1)
    if nn == 3:
        area = 0.5 * np.linalg.norm(np.cross(xyz[:, 1] - xyz[:, 0], xyz[:, 2] - xyz[:, 0]), axis=1)
    else:
        area = 0.5 * np.linalg.norm(np.cross(xyz[:, 2] - xyz[:, 0], xyz[:, 3] - xyz[:, 1]), axis=1)
    return twice | short | (area <= _SCREEN * _AREA_TOL * longest**2)


def _suspect_shape(xyz: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Quads (corners (n, 4, 3), normals (n, 3)) on which :func:`_quad_shape` may fail or warn."""
    sides = np.roll(xyz, -1, axis=1) - xyz
    lengths = np.linalg.norm(sides, axis=2)
    turn = np.einsum("nij,nj->ni", np.cross(np.roll(sides, 1, axis=1), sides), normal)
    concave = (turn <= _SCREEN * _CORNER_TOL * np.roll(lengths, 1, axis=1) * lengths).any(axis=1)
    h = np.abs(np.einsum("nij,nj->ni", xyz - xyz.mean(axis=1, keepdims=True), normal)).max(axis=1)
    diagonals = np.linalg.norm(xyz[:, 2:] - xyz[:, :2], axis=2)  # corners 1-3 and 2-4
    half = 0.5 * diagonals.min(axis=1)
    return concave | ~(h <= (1.0 - 1e-6) * WARP_WARN * half)


def _theta(card: Card, frame: np.ndarray, frames: dict) -> float:
    """Material angle [rad] from the element x axis: THETA, or MCID's x axis projected."""
    if card["MCID"] is None:
        return float(np.radians(card["THETA"]))
    if card["MCID"] not in frames:
        raise card.error("MCID", f"coordinate system {card['MCID']} is not a CORD2R")
    axis = frames[card["MCID"]].t[:, 0]
    p = axis - (axis @ frame[2]) * frame[2]
    if np.linalg.norm(p) < _PARALLEL_TOL:
        raise card.error("MCID", f"the x axis of coordinate system {card['MCID']} is normal to the element")
    return float(np.arctan2(p @ frame[1], p @ frame[0]))


def _shells(cards: list[Card], nn: int, grids: _Grids, frames: dict, properties: dict[int, Card],
            rows: dict[int, int]) -> Shells:
    cards = _by_id(cards)
    keys = tuple(f"G{k}" for k in range(1, nn + 1))
    t_keys = tuple(f"T{k}" for k in range(1, nn + 1))
    section, nodes, t_ratio = [], [], []
    try:
        for card in cards:
            prop = _shell_property(card, properties)
            nodes.append([grids(card, k) for k in keys])
            given = [k for k in t_keys if card[k] is not None]
            if given and prop.name == "PCOMP":
                raise card.error(given[0], f"corner thicknesses are not supported with PCOMP {prop.id}")
            scale = 1.0 if card["TFLAG"] == 1 else 1.0 / (prop["T"] if prop.name == "PSHELL" else 1.0)
            t_ratio.append([1.0 if card[k] is None else card[k] * scale for k in t_keys])
            section.append(rows[prop.id])
    except BulkDataError:  # an error in the corners of this or an earlier element comes first
        for card, corner_rows in zip(cards, nodes):
            _corners(card, keys, grids.xyz[corner_rows])
        raise
    n = len(cards)
    grid_rows = np.asarray(nodes, dtype=np.int64).reshape(n, nn)
    xyz = grids.xyz[grid_rows]
    for i in np.flatnonzero(_suspect_corners(grid_rows, xyz)):  # the exact checks, in id order, where they may fail
        _corners(cards[i], keys, xyz[i])
    axes = np.asarray(jax.vmap(shell_frame)(xyz)) if n else np.zeros((0, 3, 3))
    if nn == 4:
        for i in np.flatnonzero(_suspect_shape(xyz, axes[:, 2])):
            _quad_shape(cards[i], xyz[i], axes[i, 2])
    theta = [_theta(card, frame, frames) for card, frame in zip(cards, axes)]
    return Shells(
        ids=_ints([c.id for c in cards]),
        pids=_ints([c["PID"] for c in cards]),
        section=_ints(section),
        nodes=_ints(nodes, nn),
        theta=_f64(theta),
        zoffs=_f64([c["ZOFFS"] for c in cards]),
        t_ratio=_f64(np.reshape(t_ratio, (n, nn))),
        k_scale=_f64(np.ones(n)),
        m_scale=_f64(np.ones(n)),
        parts=_f64(np.ones((n, 3))),
        nsm=_f64(np.zeros(n)),
    )


def _shell_elements(bulk: BulkData, grids: _Grids, frames: dict, properties: dict[int, Card],
                    materials: Materials, mat_rows: dict[int, int]) -> tuple[ShellSections, Shells, Shells]:
    """Shell sections and the ``quads`` (CQUAD4) and ``trias`` (CTRIA3) blocks, sorted by id."""
    sections, rows = _shell_sections(bulk, materials, mat_rows)
    quads = _shells(bulk["CQUAD4"], 4, grids, frames, properties, rows)
    trias = _shells(bulk["CTRIA3"], 3, grids, frames, properties, rows)
    return sections, quads, trias


def _k6rot(params: dict[str, Card]) -> float:
    """PARAM K6ROT (MSC QRG: a real >= 0, default 100.0): shell drilling stiffness factor."""
    k6rot = params.get("K6ROT")
    if k6rot is None:
        return 100.0
    value = k6rot["V1"]
    if not isinstance(value, float):
        raise k6rot.error("V1", f"K6ROT must be a real number (with a decimal point), got {value!r}")
    if value < 0.0:
        raise k6rot.error("V1", f"K6ROT must be >= 0, got {value}")
    return value
