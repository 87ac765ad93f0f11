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

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._assembly import finalize_dofs
from ._constraints import _dof_map
from ._coordinates import CORDS
from ._grids import (
    _axis,
    _by_id,
    _check_lengths,
    _coincident,
    _f64,
    _Grids,
    _ints,
    _orientation,
)
from ._model import Beams, Bushes, Masses, Model, Rods, require_float64
from ._scalar_build import conm1, dampers, direct_matrices, implicit_spoints, scalar_masses, springs
from ._section_library import turn
from ._sections import _beam_sections, _check_shell_shear, _materials, _rod_sections, _section_angle
from ._shell_build import _k6rot, _shell_elements
from .io import BulkData, BulkDataError, Card, UnsupportedCardsError


def build_model(
    bulk: BulkData, spc_set: int | None = None, mpc_set: int | None = None, *, subcase: int | None = None,
    allow_unsupported: bool = False,
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
    _check_model_parameters(bulk)
    _check_spring_rates(bulk)
    case = _subcase(bulk, subcase)
    _check_p_set_matrices(case)
    spc_set = spc_set if spc_set is not None else getattr(case, "spc", None)
    mpc_set = mpc_set if mpc_set is not None else getattr(case, "mpc", None)
    wtmass = _wtmass(params)
    grids = _Grids(bulk["GRID"], [c for name in CORDS for c in bulk[name]], bulk["SPOINT"], implicit_spoints(bulk))
    materials, mat_rows = _materials(bulk)
    properties = {c.id: c for name in ("PBAR", "PBARL", "PBEAM", "PBEAML", "PROD", "PELAS", "PBUSH", "PSHELL", "PCOMP")
                  for c in bulk[name]}
    beam_sections, beam_rows = _beam_sections(bulk, mat_rows, materials)
    rod_sections, rods = _rod_elements(bulk, grids, properties, mat_rows, materials)
    _check_shell_shear(bulk, materials, mat_rows)
    shell_sections, quads, trias = _shell_elements(bulk, grids, grids.frames, properties, materials, mat_rows)
    model = Model(
        node_ids=grids.ids,
        xyz=grids.xyz,
        materials=materials,
        beam_sections=beam_sections,
        rod_sections=rod_sections,
        shell_sections=shell_sections,
        beams=_beams(bulk, grids, properties, beam_rows),
        rods=rods,
        springs=springs(bulk, grids),
        bushes=_bushes(bulk["CBUSH"], grids, properties),
        quads=quads,
        trias=trias,
        masses=_masses(bulk["CONM2"], grids),
        dofs=_dof_map(bulk, grids, spc_set, mpc_set),
        lumped=_lumped(params),
        k6rot=_k6rot(params),
        scalar_masses=scalar_masses(bulk, grids, wtmass),
        dampers=dampers(bulk, grids),
        conm1=conm1(bulk, grids, wtmass),
        direct=direct_matrices(bulk, grids, case, params),
        scalar_rows=np.array(sorted(grids.scalar_rows), dtype=np.int64) if grids.scalar_rows else None,
    )
    return finalize_dofs(_weight_to_mass(model, wtmass))


def _subcase(bulk: BulkData, subcase: int | None):
    """The case control's subcase ``subcase`` (None: the first), or None without case control."""
    control = getattr(bulk, "case_control", None)
    if control is None:
        if subcase is not None:
            raise BulkDataError(f"{bulk.source}: subcase {subcase} chosen, but the deck has no case control")
        return None
    return control.subcase(subcase)


def _check_p_set_matrices(case) -> None:
    """K2PP, M2PP, B2PP: read, not applied, with a warning (Nastran adds them to the dynamic
    response and complex-eigenvalue equations, not to the real modes, MSC QRG K2PP)."""
    for key in ("k2pp", "m2pp", "b2pp"):
        if getattr(case, key, None):
            warnings.warn(f"{case.places.get(key.upper(), case.where)}: {key.upper()} = {getattr(case, key)} not "
                          "applied: direct matrices on the p-set enter Nastran's dynamic response, not its real "
                          "modes", stacklevel=3)


def _wtmass(params: dict[str, Card]) -> float:
    """PARAM WTMASS (default 1.0): the factor from the deck's mass input (often weight) to mass."""
    card = params.get("WTMASS")
    if card is None:
        return 1.0
    if not isinstance(card["V1"], float) or card["V1"] <= 0.0:
        raise card.error("V1", f"WTMASS must be a real > 0, got {card['V1']!r}")
    return card["V1"]


def _weight_to_mass(model: Model, wtmass: float) -> Model:
    """Densities, non-structural masses and CONM2 masses and inertias times WTMASS, as
    Nastran scales the structural mass matrix (MSC QRG, PARAM WTMASS); CONM1 and CMASS
    are scaled where they are built, M2GG not at all."""
    if wtmass == 1.0:
        return model
    leaves = lambda m: (m.materials.rho, m.beam_sections.nsm, m.rod_sections.nsm, m.shell_sections.nsm,  # noqa: E731
                        m.quads.nsm, m.trias.nsm, m.masses.m, m.masses.inertia)
    return eqx.tree_at(leaves, model, tuple(x * wtmass for x in leaves(model)))


def _rod_elements(bulk: BulkData, grids: _Grids, properties: dict[int, Card], mat_rows: dict[int, int],
                  materials) -> tuple:
    """CROD on PROD sections and CONROD with its own section (a row with id −EID, pid 0)."""
    prods, rows = _rod_sections(bulk["PROD"], mat_rows, materials)
    own = [Card("CONROD", {"EID": c.id, **{k: c[k] for k in ("MID", "A", "J", "NSM")}}, c.file, c.line, c.fields)
           for c in bulk["CONROD"]]
    if not own:
        return prods, _rods(bulk["CROD"], grids, properties, rows)
    conrods, conrod_rows = _rod_sections(own, mat_rows, materials)
    conrods = eqx.tree_at(lambda s: s.ids, conrods, -conrods.ids)  # no PROD id: a pids target never names it
    sections = jax.tree.map(lambda a, b: np.concatenate([a, b]) if isinstance(a, np.ndarray)
                            else jnp.concatenate([a, b]), prods, conrods)
    rows.update({-eid: len(prods.ids) + r for eid, r in conrod_rows.items()})
    return sections, _rods(bulk["CROD"] + bulk["CONROD"], grids, properties, rows)


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


# PARAMs (MSC QRG, "Parameters"). Applied: COUPMASS, K6ROT, WTMASS, CK2/CM2/CB2 (scale of
# the direct matrices K2GG, M2GG, B2GG). Output,
# solution control and load scaling, which leave K and M of a normal-modes analysis as
# they are: accepted. SNORM (grid-point normals of shells) is among them: jaxfem's shells
# use element normals with or without it. LGDISP only at -1 (off). Damping (structural,
# Rayleigh, damping-matrix scale): a warning (the modes do not use it; jaxfem's responses
# take damping elsewhere). Stiffness and mass scale factors and large displacements:
# refused. Anything else: a warning naming the known PARAMs closest to it.
_PARAM_DEFAULTS = {"COUPMASS": "the mass is lumped", "K6ROT": "K6ROT = 100.0", "WTMASS": "WTMASS = 1.0",
                   "CK2": "CK2 = 1.0", "CM2": "CM2 = 1.0", "CB2": "CB2 = 1.0"}
_PARAM_NO_EFFECT = frozenset({
    "POST", "POSTEXT", "PATVER", "OGEOM", "AUTOSPC", "AUTOSPCR", "PRGPST", "MAXRATIO", "GRDPNT", "NOCOMPS",
    "SRCOMPS", "SNORM", "LGDISP", "BAILOUT", "EPZERO", "EPPRT", "PRTMAXIM", "NEWSEQ", "OLDSEQ", "SEQOUT",
    "USETPRT", "USETSEL", "OUGCORD", "OMID", "TINY", "LMODES", "LFREQ", "HFREQ", "RESVEC", "DDRMM", "NASPRT",
    "CP1", "CP2",
})
_PARAM_DAMPING = frozenset({"G", "W3", "W4", "GFL", "ALPHA1", "ALPHA2", "CB1", "CB2"})
_PARAM_REFUSED = {k: "scales the stiffness matrix" for k in ("CK1", "CK3")} | {"CM1": "scales the mass matrix"}


def _check_params(params: dict[str, Card]) -> None:
    """PARAM names and values, as listed above: a located error for what would change
    the model unsupported (LGDISP ≥ 0, CK1, CK3, CM1), a
    ``UserWarning`` for damping PARAMs and for unknown names (with the closest known)."""
    known = sorted(set(_PARAM_DEFAULTS) | _PARAM_NO_EFFECT | _PARAM_DAMPING | set(_PARAM_REFUSED))
    for name, card in sorted(params.items(), key=lambda item: item[1].line):
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


def _check_model_parameters(bulk: BulkData) -> None:
    """MDLPRM: the HDF5 output switches (``HDF5``, ``H5...``) have no effect on the model;
    any other model parameter is ignored with a warning naming it (it may select element
    formulations or options jaxfem does not have)."""
    for card in bulk["MDLPRM"]:
        if card["N"] != "HDF5" and not card["N"].startswith("H5"):
            warnings.warn(f"{card.where('N')}: MDLPRM {card['N']} = {card['V']} ignored: it may select element "
                          "formulations or options jaxfem does not have", stacklevel=3)


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
    """CBAR (PBAR/PBARL) and CBEAM (PBEAM/PBEAML); offsets WA/WB and v in basic axes.

    A PBARL/PBEAML section with I12 ≠ 0 (L, Z, ...) is stored in its principal axes,
    turned by θ about the element x from the card's element axes
    (:func:`jaxfem._section_library.principal`, ``BeamSections.angle``). Its elements'
    orientation vector turns with them, about the axis x (offsets included) by Rodrigues'
    formula, v' = v cos θ + (x × v) sin θ + x (x·v)(1 − cos θ): the element axes of v'
    are y' = y cos θ + z sin θ, z' = −y sin θ + z cos θ, where I12' = 0 and the beam's
    I1, I2 are the principal moments.
    """
    cards = _by_id(bulk["CBAR"] + bulk["CBEAM"])
    sections, nodes, v, offsets, angles = [], [], [], [], {}
    for card in cards:
        kinds = ("PBAR", "PBARL") if card.name == "CBAR" else ("PBEAM", "PBEAML")
        prop = _property(card, properties, kinds)
        sections.append(rows[prop.id])
        if prop.id not in angles:
            angles[prop.id] = _section_angle(prop)
        a, b = grids(card, "GA"), grids(card, "GB")
        _check_lengths(card, ("W1A", "W2A", "W3A", "W1B", "W2B", "W3B"))
        wa = np.array([card[k] for k in ("W1A", "W2A", "W3A")])
        wb = np.array([card[k] for k in ("W1B", "W2B", "W3B")])
        axis = _axis(card, grids.xyz[a] + wa, grids.xyz[b] + wb, "GB")
        orientation = _orientation(card, grids, axis)
        theta = angles[prop.id]
        v.append(np.asarray(turn(orientation, axis, theta)) if theta else orientation)
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
        cbeam=np.array([c.name == "CBEAM" for c in cards], dtype=bool),
    )


def _rods(cards: list[Card], grids: _Grids, properties: dict[int, Card], rows: dict[int, int]) -> Rods:
    cards = _by_id(cards)
    sections, nodes = [], []
    for card in cards:
        own = card.name == "CONROD"
        sections.append(rows[-card.id] if own else rows[_property(card, properties, ("PROD",)).id])
        a, b = grids(card, "G1"), grids(card, "G2")
        _axis(card, grids.xyz[a], grids.xyz[b], "G2")
        nodes.append((a, b))
    n = len(cards)
    return Rods(
        ids=_ints([c.id for c in cards]),
        pids=_ints([0 if c.name == "CONROD" else c["PID"] for c in cards]),
        section=_ints(sections),
        nodes=_ints(nodes, 2),
        k_scale=_f64(np.ones(n)),
        m_scale=_f64(np.ones(n)),
    )


def _check_spring_rates(bulk: BulkData) -> None:
    """Spring stiffness K of CELAS2, CELAS4 and PELAS, K1..K6 of PBUSH: >= 0 (a negative spring
    makes K indefinite: its negative eigenvalue would read as a 0 Hz mode)."""
    for card in bulk["CELAS2"] + bulk["CELAS4"] + bulk["PELAS"]:
        if card["K"] < 0.0:
            raise card.error("K", f"negative spring stiffness {card['K']}")
    for card in bulk["PBUSH"]:
        for k, value in enumerate(card["K"], 1):
            if value < 0.0:
                raise card.error(f"K{k}", f"negative spring stiffness K{k} = {value}")


def _bushes(cards: list[Card], grids: _Grids, properties: dict[int, Card]) -> Bushes:
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
            axes.append(grids.frame(card, "CID").axes_at(xa).T)
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
    """CONM2: offset X (CID 0; R X in system CID ≥ 1 with its axes R at the grid) or
    X − x_G (CID −1), inertia about the CG in the Nastran sign convention [[I11, −I21, −I31],
    [−I21, I22, −I32], [−I31, −I32, I33]] (R I Rᵀ in basic)."""
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
        r = np.eye(3) if card["CID"] in (0, -1) else grids.frame(card, "CID").axes_at(grids.xyz[g])
        nodes.append(g)
        offsets.append(x - grids.xyz[g] if card["CID"] == -1 else r @ x)
        inertia.append(r @ tensor @ r.T)
    n = len(cards)
    return Masses(
        ids=_ints([c.id for c in cards]),
        nodes=np.asarray(nodes, dtype=np.int64),
        m=_f64([c["M"] for c in cards]),
        offset=_f64(np.reshape(offsets, (n, 3))),
        inertia=_f64(np.reshape(inertia, (n, 3, 3))),
        m_scale=_f64(np.ones(n)),
    )
