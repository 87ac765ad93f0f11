"""Bulk-data cards with variable layouts, read field by field: PELAS, SPC, SPC1, RBE2,
RBE3, MPC, PARAM, PBARL, PBEAM, PBUSH (MSC Nastran QRG, per card); PCOMP is with the
shells (:mod:`jaxfem.io._cards_shells`)."""

from __future__ import annotations

from ._bulkdata import Card, IdRanges
from ._fields import _INT, _REQUIRED, _WORD, _id, _Raw, _re, _read


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
