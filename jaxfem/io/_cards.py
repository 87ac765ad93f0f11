"""Readers of the supported bulk-data cards: field layouts, value checks, unique ids.

One parser per card name (``_PARSERS``): fixed layouts from a schema with a check of the
values (GRID, CORD2R, CBAR, CBEAM, CROD, PBAR, PROD, MAT1, CONM2, CELAS1, CELAS2, CBUSH,
CQUAD4, CTRIA3, PSHELL, MAT2, MAT8), and the variable layouts read field by field (PELAS,
SPC, SPC1, RBE2, RBE3, MPC, PARAM, PBARL, PBEAM, PBUSH, PCOMP); what Nastran allows but
the model does not support is refused with a located :class:`BulkDataError` (MSC Nastran
QRG, per card). :func:`_check_unique` refuses two cards with one id in the same id space
(elements, properties, materials, ...).
"""

from __future__ import annotations

from collections.abc import Callable

from ._bulkdata import BulkDataError, Card, IdRanges, Value, _where
from ._fields import _INT, _REQUIRED, _SAME_AS_ID, _WORD, _id, _int, _Raw, _re, _read, _Spec


def _fixed(*schema: _Spec, check: Callable | None = None) -> Callable[[_Raw], list[Card]]:
    """Parser of a card with a fixed field layout, with an optional value check."""

    def parse(raw: _Raw) -> list[Card]:
        values, positions = _read(raw, schema)
        raw.end(len(schema))
        if check is not None:
            check(raw, values, positions)
        return [raw.card(values, positions)]

    return parse


def _orientation(raw: _Raw, values: dict, positions: dict, required: bool) -> None:
    """Split field 6 into G0 (integer) or X1..X3 (reals; blanks are 0.0)."""
    x = [values[k] for k in ("X1", "X2", "X3")]
    values["G0"] = None
    positions["G0"] = positions["X1"]
    if isinstance(x[0], int):
        for k in ("X2", "X3"):
            raw.blank(positions[k], k, "must be blank when field 6 is the orientation grid G0")
        if x[0] <= 0:
            raise raw.error(positions["X1"], "G0", f"orientation grid must be positive, got {x[0]}")
        values.update(G0=x[0], X1=None)
    elif any(v is not None for v in x):
        values.update({k: 0.0 if v is None else v for k, v in zip(("X1", "X2", "X3"), x)})
    elif required:
        raise raw.error(
            positions["X1"], "X1/G0",
            "an orientation vector X1, X2, X3 or a grid G0 is required (BAROR is not supported)",
        )


def _no_pins(raw: _Raw, values: dict, positions: dict) -> None:
    for key in ("PA", "PB"):
        if values[key] not in (None, 0):
            raise raw.error(positions[key], key, f"pin flags are not supported, got {values[key]}")


def _offt(raw: _Raw, values: dict, positions: dict) -> None:
    if values["OFFT"] not in ("GGG", "BGG"):
        raise raw.error(
            positions["OFFT"], "OFFT",
            f"OFFT {values['OFFT']!r} is not supported: only GGG or BGG (offsets and orientation "
            "in the grid systems, which are basic here)",
        )


def _check_grid(raw: _Raw, values: dict, positions: dict) -> None:
    if values["CP"] < 0:
        raise raw.error(positions["CP"], "CP", f"coordinate system id must be >= 0, got {values['CP']}")
    if values["CD"] != 0:
        raise raw.error(
            positions["CD"], "CD",
            f"non-basic output systems are not supported: CD must be 0 or blank, got {values['CD']}",
        )


def _check_cord2r(raw: _Raw, values: dict, positions: dict) -> None:
    if values["RID"] < 0:
        raise raw.error(positions["RID"], "RID", f"reference system id must be >= 0, got {values['RID']}")


def _check_cbar(raw: _Raw, values: dict, positions: dict) -> None:
    _orientation(raw, values, positions, required=True)
    _offt(raw, values, positions)
    _no_pins(raw, values, positions)


def _check_cbeam(raw: _Raw, values: dict, positions: dict) -> None:
    _orientation(raw, values, positions, required=True)
    if not isinstance(values["OFFT"], str):
        raise raw.error(positions["OFFT"], "OFFT/BIT", "BIT (p-element twist) is not supported")
    _offt(raw, values, positions)
    _no_pins(raw, values, positions)
    for key in ("SA", "SB"):
        if values[key] is not None:
            raise raw.error(positions[key], key, "warping scalar points SA/SB are not supported")


def _check_mat1(raw: _Raw, values: dict, positions: dict) -> None:
    if values["E"] is None and values["G"] is None:
        raise raw.error(positions["E"], "E", "E and G may not both be blank")


def _check_conm2(raw: _Raw, values: dict, positions: dict) -> None:
    if values["CID"] not in (0, -1):
        raise raw.error(
            positions["CID"], "CID",
            f"CID {values['CID']} is not supported: offsets and inertia must be in the basic "
            "system (CID 0 or blank; -1 for an absolute CG position)",
        )


def _check_celas(raw: _Raw, values: dict, positions: dict) -> None:
    """Ground is G blank or 0 (stored as None, component None); a grid needs component 1..6."""
    ends = (("G1", "C1"), ("G2", "C2"))
    for g, c in ends:
        if values[g] is not None and values[g] < 0:
            raise raw.error(positions[g], g, f"grid id must be >= 0, got {values[g]}")
        if not values[g]:
            if values[c] not in (None, 0):
                raise raw.error(positions[c], c, "component must be blank or 0 for a grounded end")
            values[g] = values[c] = None
        elif values[c] is None or not 1 <= values[c] <= 6:
            raise raw.error(
                positions[c], c,
                f"component of grid {values[g]} must be 1..6 (scalar points are not supported), got {values[c]}",
            )
    if values["G1"] is None and values["G2"] is None:
        raise raw.error(positions["G1"], "G1", "both ends are grounded")


def _check_cbush(raw: _Raw, values: dict, positions: dict) -> None:
    if not values["GB"]:
        raise raw.error(positions["GB"], "GB", "grounded CBUSH elements (GB blank) are not supported")
    if values["GB"] < 0:
        raise raw.error(positions["GB"], "GB", f"grid id must be positive, got {values['GB']}")
    _orientation(raw, values, positions, required=False)
    if values["CID"] is not None and values["CID"] < 0:
        raise raw.error(positions["CID"], "CID", f"CID must be >= 0 or blank, got {values['CID']}")
    if not 0.0 <= values["S"] <= 1.0:
        raise raw.error(positions["S"], "S", f"S must lie in [0, 1], got {values['S']}")
    if values["OCID"] != -1:
        raise raw.error(positions["OCID"], "OCID", "spring offsets (OCID >= 0) are not supported")
    for key in ("S1", "S2", "S3"):
        raw.blank(positions[key], key, "spring offsets are not supported")


# ---------------------------------------------------------------------------------------
# Cards with variable layouts


def _pelas(raw: _Raw) -> list[Card]:
    """PELAS: up to two properties (PID, K, GE, S) on one card; GE and S are not used."""
    cards = []
    for start in (0, 4):
        if start and not any(raw.text(i) for i in range(4, 8)):
            break
        values, positions = _read(raw, (_id("PID"), ("K", "real", _REQUIRED), _re("GE"), _re("S")), start, True)
        cards.append(raw.card(values, positions))
    raw.end(8)
    return cards


def _spc(raw: _Raw) -> list[Card]:
    """SPC: one card per (G, C, D) triplet; D (enforced displacement) is checked by the builder."""
    head, head_positions = _read(raw, (_id("SID"),))
    cards = []
    for start in (1, 4):
        if start == 4 and not any(raw.text(i) for i in range(4, 7)):
            break
        values, positions = _read(raw, (_id("G"), ("C", "dof", _REQUIRED), _re("D")), start)
        cards.append(raw.card({**head, **values}, {**head_positions, **positions}))
    raw.end(7)
    return cards


def _spc1(raw: _Raw) -> list[Card]:
    """SPC1: SID, C, then grids G1, G2, ... with ``Gi THRU Gj`` ranges; blanks skipped.

    ``G`` is an :class:`IdRanges`: a range is kept as (first, last), never expanded (the
    builder checks that its grids exist without listing them).
    """
    values, positions = _read(raw, (_id("SID"), ("C", "dof", _REQUIRED)))
    runs: list[tuple[int, int]] = []
    i = 2
    while i < len(raw.texts):
        text = raw.text(i).upper()
        if text == "THRU":
            if not runs:
                raise raw.error(i, "THRU", "THRU must follow a grid id")
            last = raw.get(i + 1, "G", "id", _REQUIRED)
            first, end = runs[-1]
            if last < end:
                raise raw.error(i + 1, "G", f"THRU range ends below its start ({end} THRU {last})")
            runs[-1] = (first, last)
            i += 2
            continue
        if text:
            g = raw.get(i, "G", "id")
            runs.append((g, g))
        i += 1
    if not runs:
        raise raw.error(2, "G1", "required field is blank")
    return [raw.card({**values, "G": IdRanges(runs)}, {**positions, "G": 2})]


def _rbe2(raw: _Raw) -> list[Card]:
    """RBE2: EID, GN, CM, GM1, GM2, ... (blanks skipped), then optional ALPHA and TREF (unused)."""
    values, positions = _read(raw, (_id("EID"), _id("GN"), ("CM", "dof", _REQUIRED)))
    grids: list[int] = []
    i = 3
    while i < len(raw.texts) and (not raw.text(i) or _INT.fullmatch(raw.text(i))):
        if raw.text(i):
            grids.append(raw.get(i, "GM", "id"))
        i += 1
    if not grids:
        raise raw.error(3, "GM1", "required field is blank")
    values.update(GM=tuple(grids), ALPHA=raw.get(i, "ALPHA", "real", 0.0), TREF=raw.get(i + 1, "TREF", "real", 0.0))
    positions.update(GM=3, ALPHA=i, TREF=i + 1)
    raw.end(i + 2)
    return [raw.card(values, positions)]


def _rbe3(raw: _Raw) -> list[Card]:
    """RBE3: EID, blank, REFGRID, REFC, then weight groups WTi, Ci, Gi,1, Gi,2, ...

    A real starts a group, the field after it is the group's component code, the
    integers after that its grids (blanks skipped). Then optionally the word ``UM``
    (user-chosen dependent DoFs: refused) and the word ``ALPHA`` with ALPHA and TREF
    (kept, unused). ``GROUPS`` = ((WT, C, (grids...)), ...); positions ``WTi``, ``Ci``,
    ``Gi,j`` locate messages.
    """
    values, positions = _read(raw, (_id("EID"), None, _id("REFGRID"), ("REFC", "dof", _REQUIRED)))
    groups: list[tuple[float, int, tuple[int, ...]]] = []
    i = 4
    while i < len(raw.texts) and not _WORD.fullmatch(raw.text(i).upper()):
        if not raw.text(i):
            i += 1
            continue
        k = len(groups) + 1
        weight = raw.get(i, f"WT{k}", "real")
        if weight <= 0.0:
            raise raw.error(i, f"WT{k}", f"weight must be > 0, got {weight}")
        component = raw.get(i + 1, f"C{k}", "dof", _REQUIRED)
        positions.update({f"WT{k}": i, f"C{k}": i + 1})
        grids: list[int] = []
        i += 2
        while i < len(raw.texts) and (not raw.text(i) or _INT.fullmatch(raw.text(i))):
            if raw.text(i):
                key = f"G{k},{len(grids) + 1}"
                grids.append(raw.get(i, key, "id"))
                positions[key] = i
            i += 1
        if not grids:
            raise raw.error(positions[f"C{k}"] + 1, f"G{k},1", "a weight group needs at least one grid")
        groups.append((weight, component, tuple(grids)))
    if not groups:
        raise raw.error(4, "WT1", "required field is blank (an RBE3 needs at least one weight group)")
    word = raw.text(i).upper()
    if word == "UM":
        raise raw.error(i, "UM", "UM (user-chosen dependent DoFs) is not supported")
    if word and word != "ALPHA":
        raise raw.error(i, None, f"expected a weight, UM or ALPHA, got {raw.text(i)!r}")
    values.update(GROUPS=tuple(groups), ALPHA=0.0, TREF=0.0)
    positions["GROUPS"] = 4
    if word:
        values.update(ALPHA=raw.get(i + 1, "ALPHA", "real", 0.0), TREF=raw.get(i + 2, "TREF", "real", 0.0))
        positions.update(ALPHA=i + 1, TREF=i + 2)
        i += 3
    raw.end(i)
    return [raw.card(values, positions)]


def _mpc(raw: _Raw) -> list[Card]:
    """MPC: SID, then terms (Gi, Ci, Ai): two on the first row (fields 3-8), two on each
    continuation row (fields 3-8, field 2 blank); blank terms after the first skipped.

    ``TERMS`` = ((G, C, A), ...); the first term is the dependent DoF (MSC QRG, MPC):
    A1 ≠ 0, C a single component 1..6 (scalar points are not supported), A blank = 0.0.
    """
    values, positions = _read(raw, (_id("SID"),))
    terms: list[tuple[int, int, float]] = []
    for row in range(0, max(len(raw.texts), 8), 8):
        if row:
            raw.blank(row)
        raw.blank(row + 7)
        for start in (row + 1, row + 4):
            if terms and not any(raw.text(k) for k in range(start, start + 3)):
                continue
            k = len(terms) + 1
            term, places = _read(raw, (_id(f"G{k}"), (f"C{k}", "int", _REQUIRED), _re(f"A{k}")), start)
            g, c, a = term.values()
            if not 1 <= c <= 6:
                raise raw.error(
                    start + 1, f"C{k}", f"component must be one of 1..6 (scalar points are not supported), got {c}"
                )
            if k == 1 and a == 0.0:
                raise raw.error(start + 2, "A1", "A1 must be nonzero (the coefficient of the dependent DoF)")
            if k > 1 and (g, c) == terms[0][:2]:
                raise raw.error(
                    start, f"G{k}", f"grid {g} component {c} is the dependent DoF (G1, C1) and cannot be a term again"
                )
            terms.append((g, c, a))
            positions.update(places)
    values["TERMS"] = tuple(terms)
    positions["TERMS"] = 1
    return [raw.card(values, positions)]


def _param(raw: _Raw) -> list[Card]:
    """PARAM: name and up to two values of any type."""
    values, positions = _read(raw, (("N", "word", _REQUIRED), ("V1", "any", None), ("V2", "any", None)))
    raw.end(3)
    return [raw.card(values, positions)]


PBARL_DIMENSIONS = {"BAR": 2, "ROD": 1, "TUBE": 2, "BOX": 4}


def _pbarl(raw: _Raw) -> list[Card]:
    """PBARL: PID, MID, GROUP, TYPE; DIM1..DIMn from field 2 of the first continuation, then NSM."""
    values, positions = _read(
        raw, (_id("PID"), _id("MID"), ("GROUP", "word", "MSCBML0"), ("TYPE", "word", _REQUIRED), None, None, None, None)
    )
    if values["GROUP"] != "MSCBML0":
        raise raw.error(positions["GROUP"], "GROUP", f"section library {values['GROUP']!r} is not supported")
    n = PBARL_DIMENSIONS.get(values["TYPE"])
    if n is None:
        raise raw.error(
            positions["TYPE"], "TYPE",
            f"section type {values['TYPE']!r} is not supported (supported: {', '.join(PBARL_DIMENSIONS)})",
        )
    dims, dim_positions = _read(raw, tuple((f"DIM{k + 1}", "real", _REQUIRED) for k in range(n)), 8)
    values.update(dims, NSM=raw.get(8 + n, "NSM", "real", 0.0))
    positions.update(dim_positions, NSM=8 + n)
    raw.end(9 + n)
    return [raw.card(values, positions)]


_PBEAM_STATION = ("A", "I1", "I2", "I12", "J", "NSM")
_PBEAM_UNSUPPORTED = ("NSI(A)", "NSI(B)", "CW(A)", "CW(B)", "M1(A)", "M2(A)", "M1(B)", "M2(B)",
                      "N1(A)", "N2(A)", "N1(B)", "N2(B)")
_STRESS_ROW = tuple(_re(k) for k in ("C1", "C2", "D1", "D2", "E1", "E2", "F1", "F2"))  # checked, values dropped


def _pbeam(raw: _Raw) -> list[Card]:
    """PBEAM with a constant section: end-A values; K1, K2 (default 1.0) from the footer.

    Layout (QRG): end-A row; stress-recovery row unless field 2 of the next row is a
    word; station rows (SO, X/XB, A, I1, I2, I12, J, NSM; followed by a stress-recovery
    row when SO = YES) whose non-blank section values must equal end A (tapered beams
    are refused); footer K1, K2, S1, S2, NSI(A), NSI(B), CW(A), CW(B), M1(A)..N2(B).
    S1/S2 (taper shear relief) have no effect on a constant section; NSI, CW, M and N
    must be blank or zero.
    """
    schema = (_id("PID"), _id("MID"), ("A", "real", _REQUIRED)) + tuple(_re(k) for k in _PBEAM_STATION[1:])
    values, positions = _read(raw, schema)
    i = 8
    if not _WORD.fullmatch(raw.text(i).upper()):
        _read(raw, _STRESS_ROW, i)
        i += 8
    while _WORD.fullmatch(raw.text(i).upper()):
        so = raw.get(i, "SO", "word")
        if so not in ("YES", "YESA", "NO"):
            raise raw.error(i, "SO", f"expected YES, YESA or NO, got {so!r}")
        xxb = raw.get(i + 1, "X/XB", "real", _REQUIRED)
        for k, key in enumerate(_PBEAM_STATION, i + 2):
            station = raw.get(k, key, "real")
            if station is not None and station != values[key]:
                raise raw.error(
                    k, key, f"tapered PBEAM is not supported: {key} = {station} at X/XB = {xxb}, {values[key]} at end A"
                )
        i += 8
        if so == "YES":
            _read(raw, _STRESS_ROW, i)
            i += 8
    footer, footer_positions = _read(raw, (_re("K1", 1.0), _re("K2", 1.0), _re("S1"), _re("S2")), i)
    for k, key in enumerate(_PBEAM_UNSUPPORTED, i + 4):
        if raw.get(k, key, "real", 0.0) != 0.0:
            raise raw.error(k, key, f"{key} must be blank or 0.0 (not supported)")
    raw.end(i + 16)
    return [raw.card({**values, **footer}, {**positions, **footer_positions})]


_PBUSH_ROWS = {"K": 6, "B": 6, "GE": 6, "RCV": 4}


def _pbush(raw: _Raw) -> list[Card]:
    """PBUSH: PID and rows keyed K, B, GE, RCV (keyword in field 3 of each row).

    Only K1..K6 (blank = 0.0) are used by the model; B (viscous damping), GE (structural
    damping) and RCV (stress recovery) are parsed and kept but not used.
    """
    values, positions = _read(raw, (_id("PID"),))
    values["K"], positions["K"] = (0.0,) * 6, 1
    seen: set[str] = set()
    for row in range(0, len(raw.texts), 8):
        if row:
            raw.blank(row)
        keyword = raw.get(row + 1, "K/B/GE/RCV", "word")
        if keyword is None:
            for i in range(row + 2, row + 8):
                raw.blank(i, None, "a value needs a row keyword (K, B, GE or RCV) in field 3")
            continue
        if keyword not in _PBUSH_ROWS:
            raise raw.error(row + 1, "K/B/GE/RCV", f"row {keyword!r} is not supported (K, B, GE, RCV are)")
        if keyword in seen:
            raise raw.error(row + 1, keyword, f"row {keyword} is given twice")
        seen.add(keyword)
        n = _PBUSH_ROWS[keyword]
        default = 0.0 if keyword == "K" else None
        values[keyword] = tuple(raw.get(row + 2 + k, f"{keyword}{k + 1}", "real", default) for k in range(n))
        positions[keyword] = row + 2
        positions.update({f"{keyword}{k + 1}": row + 2 + k for k in range(n)})
        for i in range(row + 2 + n, row + 8):
            raw.blank(i)
    return [raw.card(values, positions)]


# ---------------------------------------------------------------------------------------
# Shells and composites (MSC QRG: CQUAD4, CTRIA3, PSHELL, PCOMP, MAT2, MAT8)


def _check_shell(raw: _Raw, values: dict, positions: dict) -> None:
    """CQUAD4/CTRIA3 field 8: a real is THETA [deg], an integer MCID >= 0, blank THETA 0.0
    (key MCID None unless given); TFLAG 0 (blank) or 1; corner thicknesses T1..Tn (blank:
    the property's T) >= 0 and not all zero."""
    theta = values["THETA"]
    values["MCID"], positions["MCID"] = None, positions["THETA"]
    if theta is None:
        values["THETA"] = 0.0
    elif isinstance(theta, int):
        if theta < 0:
            raise raw.error(positions["THETA"], "MCID", f"material coordinate system id must be >= 0, got {theta}")
        values.update(THETA=None, MCID=theta)
    if values["TFLAG"] not in (0, 1):
        raise raw.error(positions["TFLAG"], "TFLAG", f"TFLAG must be 0 (blank) or 1, got {values['TFLAG']}")
    corners = [k for k in ("T1", "T2", "T3", "T4") if k in values]
    for key in corners:
        if values[key] is not None and values[key] < 0.0:
            raise raw.error(positions[key], key, f"corner thickness must be >= 0, got {values[key]}")
    if all(values[k] == 0.0 for k in corners):
        raise raw.error(positions["T1"], "T1", "corner thicknesses T1..Tn must not all be zero")


def _check_pshell(raw: _Raw, values: dict, positions: dict) -> None:
    if values["T"] is None:
        raise raw.error(
            positions["T"], "T",
            "T is required here (a blank T, thickness from the elements' T1..T4 only, is not supported)",
        )
    for key in ("MID1", "MID2", "MID3", "MID4"):
        mid = values[key]
        if mid is not None and mid <= 0:
            why = (
                "plane strain (MID2 = -1) is not supported" if key == "MID2" and mid == -1
                else f"material id must be positive or blank, got {mid}"
            )
            raise raw.error(positions[key], key, why)


_PCOMP_FAILURE = ("HILL", "HOFF", "TSAI", "STRN")
_PCOMP_LAM_REFUSED = ("MEM", "BEND", "SMEAR", "SMCORE")


def _pcomp(raw: _Raw) -> list[Card]:
    """PCOMP: PID, Z0, NSM, SB, FT, TREF, GE, LAM; then plies MIDi, Ti, THETAi, SOUTi,
    two per continuation row (MSC QRG, PCOMP).

    ``MID``, ``T``, ``THETA`` [deg], ``SOUT`` are tuples over the plies as listed (LAM =
    SYM: the bottom half; the builder mirrors it). A blank MIDi or Ti takes the previous
    ply's value (QRG remark), so the first ply needs both; THETAi blank is 0.0, SOUTi NO.
    LAM blank or SYM only; an empty ply slot between plies is refused; positions
    ``MIDi``, ``Ti``, ``THETAi``, ``SOUTi`` (i from 1, as listed) locate messages.
    """
    head = (_id("PID"), _re("Z0", None), _re("NSM"), _re("SB", None), ("FT", "word", None), _re("TREF"),
            _re("GE"), ("LAM", "word", None))
    values, positions = _read(raw, head)
    if values["FT"] is not None and values["FT"] not in _PCOMP_FAILURE:
        raise raw.error(positions["FT"], "FT", f"expected one of {', '.join(_PCOMP_FAILURE)}, got {values['FT']!r}")
    lam = values["LAM"]
    if lam in _PCOMP_LAM_REFUSED:
        raise raw.error(positions["LAM"], "LAM", f"LAM = {lam} is not supported (only blank or SYM)")
    if lam not in (None, "SYM"):
        raise raw.error(positions["LAM"], "LAM", f"expected blank, SYM, {', '.join(_PCOMP_LAM_REFUSED)}, got {lam!r}")
    mids: list[int] = []
    ts: list[float] = []
    thetas: list[float] = []
    souts: list[str] = []
    gap = None
    for i in range(8, len(raw.texts), 4):
        if not any(raw.text(j) for j in range(i, i + 4)):
            gap = i if gap is None else gap
            continue
        k = len(mids) + 1
        if gap is not None:
            raise raw.error(gap, f"MID{k}", f"empty ply slot before ply {k}: plies must follow each other")
        for j, key in ((i, "MID"), (i + 1, "T")):
            if k == 1 and not raw.text(j):
                raise raw.error(
                    j, f"{key}1", f"required field is blank (the first ply has no previous ply to take {key} from)"
                )
        mid = raw.get(i, f"MID{k}", "id", mids[-1] if mids else None)
        t = raw.get(i + 1, f"T{k}", "real", ts[-1] if ts else None)
        if t <= 0.0:
            raise raw.error(i + 1, f"T{k}", f"ply thickness must be > 0, got {t}")
        sout = raw.get(i + 3, f"SOUT{k}", "word", "NO")
        if sout not in ("YES", "NO"):
            raise raw.error(i + 3, f"SOUT{k}", f"expected YES or NO, got {sout!r}")
        mids.append(mid)
        ts.append(t)
        thetas.append(raw.get(i + 2, f"THETA{k}", "real", 0.0))
        souts.append(sout)
        positions.update({f"MID{k}": i, f"T{k}": i + 1, f"THETA{k}": i + 2, f"SOUT{k}": i + 3})
    if not mids:
        raise raw.error(8, "MID1", "PCOMP without plies")
    values.update(MID=tuple(mids), T=tuple(ts), THETA=tuple(thetas), SOUT=tuple(souts))
    positions.update(MID=8, T=9, THETA=10, SOUT=11)
    return [raw.card(values, positions)]


_SHELL_THETA = (("THETA", "num", None), _re("ZOFFS"))


_ORIENT = (("X1", "num", None), _re("X2", None), _re("X3", None))
_WA_WB = tuple(_re(k) for k in ("W1A", "W2A", "W3A", "W1B", "W2B", "W3B"))
_CELAS_ENDS = (_int("G1"), _int("C1"), _int("G2"), _int("C2"))

_PARSERS: dict[str, Callable[[_Raw], list[Card]]] = {
    "GRID": _fixed(
        _id("ID"), _int("CP", 0), _re("X1"), _re("X2"), _re("X3"), _int("CD", 0), ("PS", "dof", None), _int("SEQID"),
        check=_check_grid,
    ),
    "CORD2R": _fixed(
        _id("CID"), _int("RID", 0), *(_re(k) for k in ("A1", "A2", "A3", "B1", "B2", "B3", "C1", "C2", "C3")),
        check=_check_cord2r,
    ),
    "CBAR": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("GA"), _id("GB"), *_ORIENT, ("OFFT", "word", "GGG"),
        _int("PA"), _int("PB"), *_WA_WB,
        check=_check_cbar,
    ),
    "CBEAM": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("GA"), _id("GB"), *_ORIENT, ("OFFT", "any", "GGG"),
        _int("PA"), _int("PB"), *_WA_WB, _int("SA"), _int("SB"),
        check=_check_cbeam,
    ),
    "CROD": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), _id("G1"), _id("G2")),
    "PBAR": _fixed(
        _id("PID"), _id("MID"), _re("A"), _re("I1"), _re("I2"), _re("J"), _re("NSM"), None,
        *(_re(k) for k in ("C1", "C2", "D1", "D2", "E1", "E2", "F1", "F2")),
        _re("K1"), _re("K2"), _re("I12"),
    ),
    "PBARL": _pbarl,
    "PBEAM": _pbeam,
    "PROD": _fixed(_id("PID"), _id("MID"), ("A", "real", _REQUIRED), _re("J"), _re("C"), _re("NSM")),
    "MAT1": _fixed(
        _id("MID"), _re("E", None), _re("G", None), _re("NU", None), _re("RHO"), _re("A"), _re("TREF"), _re("GE"),
        _re("ST", None), _re("SC", None), _re("SS", None), _int("MCSID"),
        check=_check_mat1,
    ),
    "CONM2": _fixed(
        _id("EID"), _id("G"), _int("CID", 0), _re("M"), _re("X1"), _re("X2"), _re("X3"), None,
        *(_re(k) for k in ("I11", "I21", "I22", "I31", "I32", "I33")),
        check=_check_conm2,
    ),
    "CELAS1": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), *_CELAS_ENDS, check=_check_celas),
    "CELAS2": _fixed(_id("EID"), ("K", "real", _REQUIRED), *_CELAS_ENDS, _re("GE"), _re("S"), check=_check_celas),
    "PELAS": _pelas,
    "CBUSH": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("GA"), _int("GB"), *_ORIENT, _int("CID"),
        _re("S", 0.5), _int("OCID", -1), _re("S1", None), _re("S2", None), _re("S3", None),
        check=_check_cbush,
    ),
    "PBUSH": _pbush,
    "RBE2": _rbe2,
    "RBE3": _rbe3,
    "MPC": _mpc,
    "SPC": _spc,
    "SPC1": _spc1,
    "PARAM": _param,
    "CQUAD4": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("G1"), _id("G2"), _id("G3"), _id("G4"), *_SHELL_THETA,
        None, None, _int("TFLAG", 0), _re("T1", None), _re("T2", None), _re("T3", None), _re("T4", None),
        check=_check_shell,
    ),
    "CTRIA3": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("G1"), _id("G2"), _id("G3"), *_SHELL_THETA, None,
        None, None, _int("TFLAG", 0), _re("T1", None), _re("T2", None), _re("T3", None),
        check=_check_shell,
    ),
    "PSHELL": _fixed(
        _id("PID"), _int("MID1"), _re("T", None), _int("MID2"), _re("BENDING", 1.0), _int("MID3"),
        _re("SHEAR", 0.833333), _re("NSM"), _re("Z1", None), _re("Z2", None), _int("MID4"),
        check=_check_pshell,
    ),
    "PCOMP": _pcomp,
    "MAT2": _fixed(
        _id("MID"), *(_re(k) for k in ("G11", "G12", "G13", "G22", "G23", "G33", "RHO")),
        *(_re(k) for k in ("A1", "A2", "A3", "TREF", "GE")),
        _re("ST", None), _re("SC", None), _re("SS", None), _int("MCSID"),
    ),
    "MAT8": _fixed(
        _id("MID"), *(("E1", "real", _REQUIRED), ("E2", "real", _REQUIRED), ("NU12", "real", _REQUIRED)),
        ("G12", "real", _REQUIRED), _re("G1Z", None), _re("G2Z", None), _re("RHO"), _re("A1"), _re("A2"), _re("TREF"),
        *(_re(k, None) for k in ("XT", "XC", "YT", "YC", "S")), _re("GE"), _re("F12"), _re("STRN"),
    ),
}

# Id spaces in which two cards may not share an id (Nastran: element ids are unique across
# all element kinds, property ids across all property kinds).
_ID_SPACES = {
    "grid": ("GRID",),
    "coordinate system": ("CORD2R",),
    "element": ("CBAR", "CBEAM", "CROD", "CELAS1", "CELAS2", "CBUSH", "CONM2", "RBE2", "RBE3", "CQUAD4", "CTRIA3"),
    "property": ("PBAR", "PBARL", "PBEAM", "PROD", "PELAS", "PBUSH", "PSHELL", "PCOMP"),
    "material": ("MAT1", "MAT2", "MAT8"),
    "PARAM": ("PARAM",),
}


def _check_unique(cards: dict[str, list[Card]]) -> None:
    for space, names in _ID_SPACES.items():
        seen: dict[Value, Card] = {}
        for card in sorted((c for name in names for c in cards.get(name, [])), key=lambda c: c.line):
            other = seen.setdefault(card.id, card)
            if other is not card:
                raise BulkDataError(
                    f"{_where(card.file, card.line, card.name, card.id)}: duplicate {space} id "
                    f"{card.id}, already defined by {other.name} at {other.file}:{other.line}"
                )
