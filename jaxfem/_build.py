"""Build a :class:`jaxfem.Model` from parsed bulk data, validating every reference.

Errors are :class:`jaxfem.io.BulkDataError` naming file, line, card, id and field, e.g.
``frame.bdf:31: CBAR 12 field 5 (GB): grid 9 is not defined``. Here the PARAMs and the
elements; grids and axes are in :mod:`jaxfem._grids`, materials and sections in
:mod:`jaxfem._sections`, shells in :mod:`jaxfem._shell_build`, constraints and the DoF
map in :mod:`jaxfem._constraints`.
"""

from __future__ import annotations

import difflib
import warnings

import numpy as np

from ._assembly import finalize_dofs
from ._constraints import _dof_map
from ._grids import (
    _axis,
    _by_id,
    _check_lengths,
    _coincident,
    _coordinate_systems,
    _f64,
    _Grids,
    _ints,
    _orientation,
)
from ._model import Beams, Bushes, Masses, Model, Rods, Springs, require_float64
from ._sections import _beam_sections, _check_shell_shear, _materials, _rod_sections
from ._shell_build import _k6rot, _shell_elements
from .io import BulkData, Card, UnsupportedCardsError


def build_model(
    bulk: BulkData, spc_set: int | None = None, mpc_set: int | None = None, *, allow_unsupported: bool = False
) -> Model:
    """Model pytree of the bulk data (SI units), with DoF map and auto-SPC applied.

    **Arguments:**

    - ``bulk``: from :func:`jaxfem.io.read_bdf`. Unsupported cards that may define
      structure (elements, properties, materials, rigid elements, constraint sets,
      coordinate systems, matrices: all but those listed in
      :data:`jaxfem.io._bulkdata._NO_EFFECT`) raise :class:`jaxfem.io.UnsupportedCardsError`
      naming them, their count and first lines; the others (solution control, loads,
      output) are reported with a ``UserWarning``. PARAMs: see :func:`_check_params`.
    - ``spc_set``: SPC/SPC1 set id to apply; ``None`` takes the only one in the file
      (an error if there are several). GRID PS constraints always apply.
    - ``mpc_set``: MPC set id to apply, chosen as ``spc_set``. RBE2 and RBE3 always
      apply; dependent DoFs are eliminated (see :func:`jaxfem._constraints._dof_map`).
    - ``allow_unsupported``: build without the unsupported structural cards (a
      ``UserWarning`` names them) instead of refusing them.

    **Returns:** :class:`jaxfem.Model` with grids sorted by id, element blocks sorted by
    element id, ``k_scale = m_scale = 1``, lumped mass unless PARAM COUPMASS > 0
    (Nastran default COUPMASS = -1), ``k6rot`` from PARAM K6ROT (default 100.0), then
    :func:`jaxfem._assembly.finalize_dofs`. Materials are MAT1, MAT2 and MAT8 in one
    table (beams and rods need MAT1); shells are CQUAD4 (``quads``) and CTRIA3 (``trias``)
    on PSHELL or PCOMP sections, with the geometry checks of :mod:`jaxfem._shell_build`
    (a warped quad above its warning limit gives a ``UserWarning``).
    """
    require_float64()
    _check_unknown(bulk, allow_unsupported)
    params = {c.id: c for c in bulk["PARAM"]}
    _check_params(params)
    _check_spring_rates(bulk)
    lumped = _lumped(params)
    frames = _coordinate_systems(bulk["CORD2R"])
    grids = _Grids(bulk["GRID"], frames)
    materials, mat_rows = _materials(bulk)
    properties = {c.id: c for name in ("PBAR", "PBARL", "PBEAM", "PROD", "PELAS", "PBUSH", "PSHELL", "PCOMP")
                  for c in bulk[name]}
    beam_sections, beam_rows = _beam_sections(bulk, mat_rows, materials)
    rod_sections, rod_rows = _rod_sections(bulk["PROD"], mat_rows, materials)
    _check_shell_shear(bulk, materials, mat_rows)
    shell_sections, quads, trias = _shell_elements(bulk, grids, frames, properties, materials, mat_rows)
    model = Model(
        node_ids=grids.ids,
        xyz=grids.xyz,
        materials=materials,
        beam_sections=beam_sections,
        rod_sections=rod_sections,
        shell_sections=shell_sections,
        beams=_beams(bulk, grids, properties, beam_rows),
        rods=_rods(bulk["CROD"], grids, properties, rod_rows),
        springs=_springs(bulk, grids, properties),
        bushes=_bushes(bulk["CBUSH"], grids, properties, frames),
        quads=quads,
        trias=trias,
        masses=_masses(bulk["CONM2"], grids),
        dofs=_dof_map(bulk, grids, spc_set, mpc_set),
        lumped=lumped,
        k6rot=_k6rot(params),
    )
    return finalize_dofs(model)


def _check_unknown(bulk: BulkData, allow_unsupported: bool) -> None:
    """Unsupported cards: an :class:`UnsupportedCardsError` for those that may define
    structure (unless ``allow_unsupported``: then a warning), a warning for the others."""
    structural = bulk.structural_unknown()
    harmless = sorted(set(bulk.unknown) - set(structural))
    if structural and not allow_unsupported:
        raise UnsupportedCardsError(
            f"{bulk.source}: unsupported bulk-data cards that may define structure: "
            f"{bulk.unknown_summary(structural)}: the model would lack them",
            structural,
        )
    if structural:
        warnings.warn(f"{bulk.source}: unsupported bulk-data cards ignored: {bulk.unknown_summary(structural)}",
                      stacklevel=3)
    if harmless:
        warnings.warn(f"{bulk.source}: bulk-data cards without effect on stiffness or mass ignored: "
                      f"{bulk.unknown_summary(harmless)}", stacklevel=3)


# PARAMs (MSC QRG, "Parameters"). Applied: COUPMASS, K6ROT, WTMASS (1.0 only). Output,
# solution control and load scaling, which leave K and M of a normal-modes analysis as
# they are: accepted. SNORM (grid-point normals of shells) is among them: jaxfem's shells
# use element normals with or without it. LGDISP only at -1 (off). Damping (structural,
# Rayleigh, damping-matrix scale): a warning (the modes do not use it; jaxfem's responses
# take damping elsewhere). Stiffness and mass scale factors and large displacements:
# refused. Anything else: a warning naming the known PARAMs closest to it.
_PARAM_DEFAULTS = {"COUPMASS": "the mass is lumped", "K6ROT": "K6ROT = 100.0", "WTMASS": "WTMASS = 1.0"}
_PARAM_NO_EFFECT = frozenset({
    "POST", "POSTEXT", "PATVER", "OGEOM", "AUTOSPC", "AUTOSPCR", "PRGPST", "MAXRATIO", "GRDPNT", "NOCOMPS",
    "SRCOMPS", "SNORM", "LGDISP", "BAILOUT", "EPZERO", "EPPRT", "PRTMAXIM", "NEWSEQ", "OLDSEQ", "SEQOUT",
    "USETPRT", "USETSEL", "OUGCORD", "OMID", "TINY", "LMODES", "LFREQ", "HFREQ", "RESVEC", "DDRMM", "NASPRT",
    "CP1", "CP2",
})
_PARAM_DAMPING = frozenset({"G", "W3", "W4", "GFL", "ALPHA1", "ALPHA2", "CB1", "CB2"})
_PARAM_REFUSED = {k: "scales the stiffness matrix" for k in ("CK1", "CK2", "CK3")} | {
    k: "scales the mass matrix" for k in ("CM1", "CM2")}


def _check_params(params: dict[str, Card]) -> None:
    """PARAM names and values, as listed above: a located error for what would change
    the model unsupported (WTMASS ≠ 1, LGDISP ≥ 0, CK1..CK3, CM1, CM2), a
    ``UserWarning`` for damping PARAMs and for unknown names (with the closest known)."""
    known = sorted(set(_PARAM_DEFAULTS) | _PARAM_NO_EFFECT | _PARAM_DAMPING | set(_PARAM_REFUSED))
    for name, card in sorted(params.items(), key=lambda item: item[1].line):
        if name == "WTMASS" and card["V1"] != 1.0:
            raise card.error("V1", "PARAM WTMASS other than 1.0 is not supported (write the file in SI)")
        if name == "LGDISP" and card["V1"] not in (None, -1):
            raise card.error("V1", f"PARAM LGDISP {card['V1']} (large displacements) is not supported; only -1")
        if name in _PARAM_REFUSED:
            raise card.error("N", f"PARAM {name} {_PARAM_REFUSED[name]} and is not supported; remove it")
        where = card.where()
        if name in _PARAM_DAMPING:
            warnings.warn(f"{where}: PARAM {name} (damping) ignored: normal modes do not use it", stacklevel=3)
        elif name not in known:
            close = difflib.get_close_matches(name, known, n=3, cutoff=0.6)
            hint = f" (did you mean {' or '.join(close)}?)" if close else ""
            effect = f": {_PARAM_DEFAULTS[close[0]]}" if close and close[0] in _PARAM_DEFAULTS else ""
            warnings.warn(f"{where}: unknown PARAM {name}{hint} ignored{effect}", stacklevel=3)


def _lumped(params: dict[str, Card]) -> bool:
    """Lumped mass unless PARAM COUPMASS > 0 (MSC QRG, PARAM COUPMASS: default -1)."""
    coupmass = params.get("COUPMASS")
    if coupmass is None:
        return True
    if not isinstance(coupmass["V1"], int):
        raise coupmass.error("V1", f"COUPMASS must be an integer, got {coupmass['V1']!r}")
    return coupmass["V1"] <= 0


def _property(card: Card, properties: dict[int, Card], kinds: tuple[str, ...]) -> Card:
    prop = properties.get(card["PID"])
    if prop is None:
        raise card.error("PID", f"property {card['PID']} is not defined")
    if prop.name not in kinds:
        raise card.error("PID", f"property {card['PID']} is a {prop.name}; {card.name} needs {' or '.join(kinds)}")
    return prop


def _beams(bulk: BulkData, grids: _Grids, properties: dict[int, Card], rows: dict[int, int]) -> Beams:
    """CBAR (PBAR/PBARL) and CBEAM (PBEAM); offsets WA/WB and v in basic axes."""
    cards = _by_id(bulk["CBAR"] + bulk["CBEAM"])
    sections, nodes, v, offsets = [], [], [], []
    for card in cards:
        kinds = ("PBAR", "PBARL") if card.name == "CBAR" else ("PBEAM",)
        sections.append(rows[_property(card, properties, kinds).id])
        a, b = grids(card, "GA"), grids(card, "GB")
        _check_lengths(card, ("W1A", "W2A", "W3A", "W1B", "W2B", "W3B"))
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


def _check_spring_rates(bulk: BulkData) -> None:
    """Spring stiffness K of CELAS2 and PELAS, K1..K6 of PBUSH: >= 0 (a negative spring
    makes K indefinite: its negative eigenvalue would read as a 0 Hz mode)."""
    for card in bulk["CELAS2"] + bulk["PELAS"]:
        if card["K"] < 0.0:
            raise card.error("K", f"negative spring stiffness {card['K']}")
    for card in bulk["PBUSH"]:
        for k, value in enumerate(card["K"], 1):
            if value < 0.0:
                raise card.error(f"K{k}", f"negative spring stiffness K{k} = {value}")


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
        _check_lengths(card, ("X1", "X2", "X3"))
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
