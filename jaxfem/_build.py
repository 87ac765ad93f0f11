"""Build a :class:`jaxfem.Model` from parsed bulk data, validating every reference.

Errors are :class:`jaxfem.io.BulkDataError` naming file, line, card, id and field, e.g.
``frame.bdf:31: CBAR 12 field 5 (GB): grid 9 is not defined``.
"""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np

from ._assembly import finalize_dofs
from ._model import (
    COMPONENTS,
    BeamSections,
    Beams,
    Bushes,
    DofMap,
    Masses,
    Materials,
    Model,
    RodSections,
    Rods,
    Springs,
    require_float64,
)
from .io._bdf import BulkData, BulkDataError, Card

_PARALLEL_TOL = 1e-8  # |x̂ × v| < tol·|v|: orientation vector along the element axis
_LENGTH_TOL = 1e-10  # zero length: L <= tol·(distance of the end points from the origin)


def build_model(bulk: BulkData, spc_set: int | None = None) -> Model:
    """Model pytree of the bulk data (SI units), with DoF map and auto-SPC applied.

    **Arguments:**

    - ``bulk``: from :func:`jaxfem.io.read_bdf`. Unsupported cards are reported with a
      ``UserWarning`` (see :meth:`BulkData.report`).
    - ``spc_set``: SPC/SPC1 set id to apply; ``None`` takes the only one in the file
      (an error if there are several). GRID PS constraints always apply.

    **Returns:** :class:`jaxfem.Model` with grids sorted by id, element blocks sorted by
    element id, ``k_scale = m_scale = 1``, lumped mass unless PARAM COUPMASS > 0
    (Nastran default COUPMASS = -1), then :func:`jaxfem._assembly.finalize_dofs`.
    """
    require_float64()
    if bulk.unknown:
        warnings.warn(f"{bulk.source}: unsupported bulk-data cards ignored: {bulk.unknown_summary()}", stacklevel=2)
    params = {c.id: c for c in bulk["PARAM"]}
    _check_wtmass(params)
    lumped = _lumped(params)
    frames = _coordinate_systems(bulk["CORD2R"])
    grids = _Grids(bulk["GRID"], frames)
    materials, mat_rows = _materials(bulk["MAT1"])
    properties = {c.id: c for name in ("PBAR", "PBARL", "PBEAM", "PROD", "PELAS", "PBUSH") for c in bulk[name]}
    beam_sections, beam_rows = _beam_sections(bulk, mat_rows)
    rod_sections, rod_rows = _rod_sections(bulk["PROD"], mat_rows)
    model = Model(
        node_ids=grids.ids,
        xyz=grids.xyz,
        materials=materials,
        beam_sections=beam_sections,
        rod_sections=rod_sections,
        beams=_beams(bulk, grids, properties, beam_rows),
        rods=_rods(bulk["CROD"], grids, properties, rod_rows),
        springs=_springs(bulk, grids, properties),
        bushes=_bushes(bulk["CBUSH"], grids, properties, frames),
        masses=_masses(bulk["CONM2"], grids),
        dofs=_dof_map(bulk, grids, spc_set),
        lumped=lumped,
    )
    return finalize_dofs(model)


def _f64(values) -> jax.Array:
    return jnp.asarray(np.asarray(values, dtype=np.float64))


def _ints(values, *shape: int) -> np.ndarray:
    return np.asarray(values, dtype=np.int64).reshape(-1, *shape)


def _by_id(cards: list[Card]) -> list[Card]:
    return sorted(cards, key=lambda c: c.id)


def _check_wtmass(params: dict[str, Card]) -> None:
    wtmass = params.get("WTMASS")
    if wtmass is not None and wtmass["V1"] != 1.0:
        raise wtmass.error("V1", "PARAM WTMASS other than 1.0 is not supported (write the file in SI)")


def _lumped(params: dict[str, Card]) -> bool:
    """Lumped mass unless PARAM COUPMASS > 0 (MSC QRG, PARAM COUPMASS: default -1)."""
    coupmass = params.get("COUPMASS")
    if coupmass is None:
        return True
    if not isinstance(coupmass["V1"], int):
        raise coupmass.error("V1", f"COUPMASS must be an integer, got {coupmass['V1']!r}")
    return coupmass["V1"] <= 0


# ---------------------------------------------------------------------------------------
# Geometry


def _coordinate_systems(cards: list[Card]) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """CORD2R id -> (origin, T) in basic: ``x_basic = origin + T @ x_local``, T columns = axes.

    Axes from points A (origin), B (on z) and C (in the x–z plane), each given in the
    reference system RID (MSC QRG, CORD2R); chains of RID are resolved.
    """
    by_id = {c.id: c for c in cards}
    frames: dict[int, tuple[np.ndarray, np.ndarray]] = {0: (np.zeros(3), np.eye(3))}

    def resolve(card: Card, chain: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        if card.id in frames:
            return frames[card.id]
        rid = card["RID"]
        if rid in chain:
            raise card.error("RID", f"coordinate systems refer to each other in a loop {chain + (rid,)}")
        if rid not in frames and rid not in by_id:
            raise card.error("RID", f"reference system {rid} is not a CORD2R")
        origin, t = frames[rid] if rid in frames else resolve(by_id[rid], chain + (rid,))
        a, b, c = (origin + t @ np.array([card[f"{p}{k}"] for k in (1, 2, 3)], dtype=float) for p in "ABC")
        z, xz = b - a, c - a
        y = np.cross(z, xz)
        if np.linalg.norm(z) == 0.0 or np.linalg.norm(y) <= 1e-12 * np.linalg.norm(z) * np.linalg.norm(xz):
            raise card.error("A1", "points A, B, C do not define axes (coincident or collinear)")
        z, y = z / np.linalg.norm(z), y / np.linalg.norm(y)
        frames[card.id] = (a, np.column_stack([np.cross(y, z), y, z]))
        return frames[card.id]

    for card in cards:
        resolve(card, (card.id,))
    return frames


class _Grids:
    """Grid ids (ascending), positions in basic [m], and row lookup with located errors."""

    def __init__(self, cards: list[Card], frames: dict[int, tuple[np.ndarray, np.ndarray]]):
        cards = _by_id(cards)
        xyz = []
        for card in cards:
            if card["CP"] not in frames:
                raise card.error("CP", f"coordinate system {card['CP']} is not a CORD2R")
            origin, t = frames[card["CP"]]
            xyz.append(origin + t @ np.array([card["X1"], card["X2"], card["X3"]]))
        self.cards = cards
        self.ids = _ints([c.id for c in cards])
        self.xyz = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        self.row = {int(g): i for i, g in enumerate(self.ids)}

    def __call__(self, card: Card, key: str, grid: int | None = None) -> int:
        """Row of grid ``card[key]`` (or ``grid``, listed in field ``key``)."""
        grid = card[key] if grid is None else grid
        if grid not in self.row:
            raise card.error(key, f"grid {grid} is not defined")
        return self.row[grid]


def _property(card: Card, properties: dict[int, Card], kinds: tuple[str, ...]) -> Card:
    prop = properties.get(card["PID"])
    if prop is None:
        raise card.error("PID", f"property {card['PID']} is not defined")
    if prop.name not in kinds:
        raise card.error("PID", f"property {card['PID']} is a {prop.name}; {card.name} needs {' or '.join(kinds)}")
    return prop


def _coincident(xa: np.ndarray, xb: np.ndarray) -> bool:
    return np.linalg.norm(xb - xa) <= _LENGTH_TOL * max(np.linalg.norm(xa), np.linalg.norm(xb))


def _axis(card: Card, xa: np.ndarray, xb: np.ndarray, key: str) -> np.ndarray:
    """Unit vector A→B, or a located error for a zero-length element."""
    if _coincident(xa, xb):
        raise card.error(key, f"zero length: both ends (offsets included) at {xa.tolist()}")
    return (xb - xa) / np.linalg.norm(xb - xa)


def _orientation(card: Card, grids: _Grids, axis: np.ndarray) -> np.ndarray:
    """Orientation vector v in basic (G0: x_G0 − x_GA), not parallel to the element axis."""
    if card["G0"] is not None:
        v = grids.xyz[grids(card, "G0")] - grids.xyz[grids(card, "GA")]
        key = "G0"
    else:
        v = np.array([card["X1"], card["X2"], card["X3"]])
        key = "X1"
    norm = np.linalg.norm(v)
    if norm == 0.0 or np.linalg.norm(np.cross(axis, v)) < _PARALLEL_TOL * norm:
        raise card.error(key, f"orientation vector {v.tolist()} is zero or parallel to the element axis")
    return v


# ---------------------------------------------------------------------------------------
# Materials and sections


def _materials(cards: list[Card]) -> tuple[Materials, dict[int, int]]:
    """MAT1 table. Two of E, G, NU given: the third from G = E / (2 (1 + NU)); only E
    (or only G): the other modulus and NU are 0 (MSC QRG, MAT1 remarks)."""
    cards = _by_id(cards)
    rows = []
    for card in cards:
        E, G, nu = card["E"], card["G"], card["NU"]
        if nu is None and E is not None and G is not None:
            if G <= 0.0:
                raise card.error("G", f"G must be > 0 to derive NU, got {G}")
            nu = E / (2.0 * G) - 1.0
        elif G is None and nu is not None:
            G = E / (2.0 * (1.0 + nu))
        elif E is None and nu is not None:
            E = 2.0 * (1.0 + nu) * G
        E, G, nu = E or 0.0, G or 0.0, nu or 0.0
        if E <= 0.0:
            raise card.error("E", f"E must be > 0, got {E}")
        if G < 0.0:
            raise card.error("G", f"G must be >= 0, got {G}")
        if card["RHO"] < 0.0:
            raise card.error("RHO", f"negative density {card['RHO']}")
        rows.append((E, G, nu, card["RHO"]))
    E, G, nu, rho = np.asarray(rows, dtype=np.float64).reshape(-1, 4).T
    ids = _ints([c.id for c in cards])
    return Materials(ids=ids, E=_f64(E), G=_f64(G), nu=_f64(nu), rho=_f64(rho)), {int(m): i for i, m in enumerate(ids)}


def _material(card: Card, mat_rows: dict[int, int]) -> int:
    if card["MID"] not in mat_rows:
        raise card.error("MID", f"material {card['MID']} is not defined (MAT1)")
    return mat_rows[card["MID"]]


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
    """
    dims = [card[f"DIM{k}"] for k in range(1, 5) if f"DIM{k}" in card.values]
    for k, d in enumerate(dims, 1):
        if d <= 0.0:
            raise card.error(f"DIM{k}", f"dimensions must be > 0, got {d}")
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


def _beam_sections(bulk: BulkData, mat_rows: dict[int, int]) -> tuple[BeamSections, dict[int, int]]:
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
        materials.append(_material(card, mat_rows))
        values.append((area, i1, i2, j, k1, k2, card["NSM"]))
    columns = np.asarray(values, dtype=np.float64).reshape(-1, 7).T
    ids = _ints([c.id for c in cards])
    sections = BeamSections(
        ids=ids,
        material=_ints(materials),
        **{k: _f64(v) for k, v in zip(("A", "I1", "I2", "J", "K1", "K2", "nsm"), columns)},
    )
    return sections, {int(p): i for i, p in enumerate(ids)}


def _rod_sections(cards: list[Card], mat_rows: dict[int, int]) -> tuple[RodSections, dict[int, int]]:
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
        material=_ints([_material(c, mat_rows) for c in cards]),
        A=_f64([c["A"] for c in cards]),
        J=_f64([c["J"] for c in cards]),
        nsm=_f64([c["NSM"] for c in cards]),
    )
    return sections, {int(p): i for i, p in enumerate(ids)}


# ---------------------------------------------------------------------------------------
# Elements


def _beams(bulk: BulkData, grids: _Grids, properties: dict[int, Card], rows: dict[int, int]) -> Beams:
    """CBAR (PBAR/PBARL) and CBEAM (PBEAM); offsets WA/WB and v in basic axes."""
    cards = _by_id(bulk["CBAR"] + bulk["CBEAM"])
    sections, nodes, v, offsets = [], [], [], []
    for card in cards:
        kinds = ("PBAR", "PBARL") if card.name == "CBAR" else ("PBEAM",)
        sections.append(rows[_property(card, properties, kinds).id])
        a, b = grids(card, "GA"), grids(card, "GB")
        wa = np.array([card[k] for k in ("W1A", "W2A", "W3A")])
        wb = np.array([card[k] for k in ("W1B", "W2B", "W3B")])
        axis = _axis(card, grids.xyz[a] + wa, grids.xyz[b] + wb, "GB")
        v.append(_orientation(card, grids, axis))
        nodes.append((a, b))
        offsets.append((wa, wb))
    n = len(cards)
    return Beams(
        ids=_ints([c.id for c in cards]),
        pids=_ints([c["PID"] for c in cards]),
        section=_ints(sections),
        nodes=_ints(nodes, 2),
        v=_f64(np.reshape(v, (n, 3))),
        offsets=_f64(np.reshape(offsets, (n, 2, 3))),
        k_scale=_f64(np.ones(n)),
        m_scale=_f64(np.ones(n)),
    )


def _rods(cards: list[Card], grids: _Grids, properties: dict[int, Card], rows: dict[int, int]) -> Rods:
    cards = _by_id(cards)
    sections, nodes = [], []
    for card in cards:
        sections.append(rows[_property(card, properties, ("PROD",)).id])
        a, b = grids(card, "G1"), grids(card, "G2")
        _axis(card, grids.xyz[a], grids.xyz[b], "G2")
        nodes.append((a, b))
    n = len(cards)
    return Rods(
        ids=_ints([c.id for c in cards]),
        pids=_ints([c["PID"] for c in cards]),
        section=_ints(sections),
        nodes=_ints(nodes, 2),
        k_scale=_f64(np.ones(n)),
        m_scale=_f64(np.ones(n)),
    )


def _springs(bulk: BulkData, grids: _Grids, properties: dict[int, Card]) -> Springs:
    """CELAS1 (k from PELAS) and CELAS2 (k inline); a grounded end is node -1, component 0."""
    cards = _by_id(bulk["CELAS1"] + bulk["CELAS2"])
    k, nodes, components = [], [], []
    for card in cards:
        k.append(_property(card, properties, ("PELAS",))["K"] if card.name == "CELAS1" else card["K"])
        nodes.append([-1 if card[g] is None else grids(card, g) for g in ("G1", "G2")])
        components.append([card[c] or 0 for c in ("C1", "C2")])
    n = len(cards)
    return Springs(
        ids=_ints([c.id for c in cards]),
        pids=_ints([c["PID"] if c.name == "CELAS1" else 0 for c in cards]),
        nodes=_ints(nodes, 2),
        components=_ints(components, 2),
        k=_f64(k),
        k_scale=_f64(np.ones(n)),
    )


def _bushes(cards: list[Card], grids: _Grids, properties: dict[int, Card], frames) -> Bushes:
    """CBUSH/PBUSH K1..K6. Axes rows (x, y, z) in basic: CID >= 0 gives the axes of that
    system (0 = basic); otherwise x along GA→GB and y from the orientation vector as for
    CBAR (z = x × v normalised, y = z × x); coincident grids without CID use basic axes."""
    cards = _by_id(cards)
    axes, nodes, k = [], [], []
    for card in cards:
        k.append(_property(card, properties, ("PBUSH",))["K"])
        a, b = grids(card, "GA"), grids(card, "GB")
        xa, xb = grids.xyz[a], grids.xyz[b]
        if card["CID"] is not None:
            if card["CID"] not in frames:
                raise card.error("CID", f"coordinate system {card['CID']} is not a CORD2R")
            axes.append(frames[card["CID"]][1].T)
        elif _coincident(xa, xb):
            axes.append(np.eye(3))
        else:
            x = _axis(card, xa, xb, "GB")
            if card["G0"] is None and card["X1"] is None:
                raise card.error("X1", "an orientation vector X1, X2, X3, a grid G0 or a CID is required")
            z = np.cross(x, _orientation(card, grids, x))
            z /= np.linalg.norm(z)
            axes.append(np.stack([x, np.cross(z, x), z]))
        nodes.append((a, b))
    n = len(cards)
    return Bushes(
        ids=_ints([c.id for c in cards]),
        pids=_ints([c["PID"] for c in cards]),
        nodes=_ints(nodes, 2),
        axes=_f64(np.reshape(axes, (n, 3, 3))),
        k=_f64(np.reshape(k, (n, 6))),
        s=_f64([c["S"] for c in cards]),
        k_scale=_f64(np.ones(n)),
    )


def _masses(cards: list[Card], grids: _Grids) -> Masses:
    """CONM2: offset X (CID 0) or X − x_G (CID −1), inertia about the CG in the Nastran
    sign convention [[I11, −I21, −I31], [−I21, I22, −I32], [−I31, −I32, I33]]."""
    cards = _by_id(cards)
    nodes, offsets, inertia = [], [], []
    for card in cards:
        g = grids(card, "G")
        if card["M"] < 0.0:
            raise card.error("M", f"negative mass {card['M']}")
        i11, i21, i22, i31, i32, i33 = (card[k] for k in ("I11", "I21", "I22", "I31", "I32", "I33"))
        tensor = np.array([[i11, -i21, -i31], [-i21, i22, -i32], [-i31, -i32, i33]])
        eig = np.linalg.eigvalsh(tensor)
        if eig[0] < -1e-12 * np.max(np.abs(eig)):
            raise card.error("I11", f"indefinite mass: inertia tensor eigenvalues {eig.tolist()} must be >= 0")
        x = np.array([card["X1"], card["X2"], card["X3"]])
        nodes.append(g)
        offsets.append(x - grids.xyz[g] if card["CID"] == -1 else x)
        inertia.append(tensor)
    n = len(cards)
    return Masses(
        ids=_ints([c.id for c in cards]),
        nodes=np.asarray(nodes, dtype=np.int64),
        m=_f64([c["M"] for c in cards]),
        offset=_f64(np.reshape(offsets, (n, 3))),
        inertia=_f64(np.reshape(inertia, (n, 3, 3))),
        m_scale=_f64(np.ones(n)),
    )


# ---------------------------------------------------------------------------------------
# Constraints


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
