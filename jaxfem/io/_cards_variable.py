"""Bulk-data cards with variable layouts, read field by field: PELAS, PMASS, PDAMP, PVISC,
SPC, SPC1, RBE2, RBE3, MPC, PARAM, PBARL, PBEAM, PBEAML, PBUSH (MSC Nastran QRG, per card); PCOMP is with
the shells (:mod:`jaxfem.io._cards_shells`), the rigid elements and sets added later in
:mod:`jaxfem.io._cards_rigid`."""

from __future__ import annotations

from ._bulkdata import Card, IdRanges
from ._fields import _INT, _REQUIRED, _WORD, _convert, _id, _Raw, _re, _read


def _groups(raw: _Raw, schema: tuple, starts: tuple[int, ...]) -> list[Card]:
    """One card per group of fields (``schema`` at each of ``starts``; an empty group after
    the first is skipped), e.g. the two properties of a PELAS; nothing after field 9."""
    cards = []
    for start in starts:
        if start and not any(raw.text(i) for i in range(start, start + len(schema))):
            continue
        values, positions = _read(raw, schema, start, True)
        cards.append(raw.card(values, positions))
    raw.end(8)
    return cards


def _pelas(raw: _Raw) -> list[Card]:
    """PELAS: up to two properties (PID, K, GE, S) on one card; GE and S are not used."""
    return _groups(raw, (_id("PID"), ("K", "real", _REQUIRED), _re("GE"), _re("S")), (0, 4))


def _pmass(raw: _Raw) -> list[Card]:
    """PMASS: up to four scalar masses (PID, M) on one card."""
    return _groups(raw, (_id("PID"), ("M", "real", _REQUIRED)), (0, 2, 4, 6))


def _pdamp(raw: _Raw) -> list[Card]:
    """PDAMP: up to four scalar dampers (PID, B) on one card."""
    return _groups(raw, (_id("PID"), ("B", "real", _REQUIRED)), (0, 2, 4, 6))


def _pvisc(raw: _Raw) -> list[Card]:
    """PVISC: up to two viscous dampers (PID, CE, CR; CR blank 0.0) on one card, fields 2-4 and 6-8."""
    return _groups(raw, (_id("PID"), ("CE", "real", _REQUIRED), _re("CR"), None), (0, 4))


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


def _thru(raw: _Raw, start: int, key: str, noun: str) -> IdRanges:
    """Ids from data field ``start`` on, ``Gi THRU Gj`` ranges kept as runs (never expanded),
    blanks skipped; at least one."""
    runs: list[tuple[int, int]] = []
    i = start
    while i < len(raw.texts):
        text = raw.text(i).upper()
        if text == "THRU":
            if not runs:
                raise raw.error(i, "THRU", f"THRU must follow {noun}")
            last = raw.get(i + 1, key, "id", _REQUIRED)
            first, end = runs[-1]
            if last < end:
                raise raw.error(i + 1, key, f"THRU range ends below its start ({end} THRU {last})")
            runs[-1] = (first, last)
            i += 2
            continue
        if text:
            g = raw.get(i, key, "id")
            runs.append((g, g))
        i += 1
    if not runs:
        raise raw.error(start, f"{key}1", "required field is blank")
    return IdRanges(runs)


def _spc1(raw: _Raw) -> list[Card]:
    """SPC1: SID, C, then grids G1, G2, ... with ``Gi THRU Gj`` ranges; blanks skipped.

    ``G`` is an :class:`IdRanges`: a range is kept as (first, last), never expanded (the
    builder checks that its grids exist without listing them).
    """
    values, positions = _read(raw, (_id("SID"), ("C", "dof", _REQUIRED)))
    return [raw.card({**values, "G": _thru(raw, 2, "G", "a grid id")}, {**positions, "G": 2})]


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
    A1 ≠ 0, C a single component 1..6 at a grid, 0 or blank (stored 0) at a scalar point
    (the builder checks which the point is), A blank = 0.0.
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
            term, places = _read(raw, (_id(f"G{k}"), (f"C{k}", "int", 0), _re(f"A{k}")), start)
            g, c, a = term.values()
            if not 0 <= c <= 6:
                raise raw.error(
                    start + 1, f"C{k}", f"component must be one of 1..6 (a grid) or 0/blank (a scalar point), got {c}"
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
    """PARAM: name and up to two values: numbers, or character values (upper case) such as
    ``LBF-IN`` when they start with a letter (QRG, "Parameters")."""
    values, positions = _read(raw, (("N", "word", _REQUIRED),))
    for i, key in ((1, "V1"), (2, "V2")):
        text = raw.text(i, key)
        word = text[:1].isalpha() and _convert(text, "any") is None
        values[key], positions[key] = text.upper() if word else raw.get(i, key, "any"), i
    raw.end(3)
    return [raw.card(values, positions)]


def _mdlprm(raw: _Raw) -> list[Card]:
    """MDLPRM: pairs of model-parameter name and value, one card each (MSC QRG, MDLPRM)."""
    cards = []
    for start in range(0, len(raw.texts), 2):
        if raw.text(start) or start == 0:
            values, positions = _read(raw, (("N", "word", _REQUIRED), ("V", "any", None)), start, True)
            cards.append(raw.card(values, positions))
    return cards


# DIMs per cross-section TYPE of the MSC library MSCBML0 (QRG, PBARL and PBEAML, Figure 1)
PBARL_DIMENSIONS = {
    "ROD": 1, "TUBE": 2, "TUBE2": 2, "I": 6, "CHAN": 4, "T": 4, "BOX": 4, "BAR": 2, "CROSS": 4, "H": 4,
    "T1": 4, "I1": 4, "CHAN1": 4, "Z": 4, "CHAN2": 4, "T2": 4, "BOX1": 6, "HEXA": 3, "HAT": 4, "HAT1": 5,
    "DBOX": 10, "L": 4,
}


def _library_type(raw: _Raw, values: dict, positions: dict) -> int:
    """The number of DIMs of a PBARL/PBEAML section (GROUP MSCBML0, TYPE of the library)."""
    if values["GROUP"] != "MSCBML0":
        raise raw.error(positions["GROUP"], "GROUP", f"section library {values['GROUP']!r} is not supported")
    n = PBARL_DIMENSIONS.get(values["TYPE"])
    if n is None:
        raise raw.error(
            positions["TYPE"], "TYPE",
            f"section type {values['TYPE']!r} is not in the MSC library (types: {', '.join(PBARL_DIMENSIONS)})",
        )
    return n


def _dims(raw: _Raw, start: int, n: int, kind: str, suffix: str = "") -> list[float]:
    """DIM1..DIMn from data field ``start``; DBOX: DIM5..DIM8 default to DIM4, DIM9 and
    DIM10 to DIM6 (QRG, PBARL remarks)."""
    dims: list[float] = []
    for k in range(n):
        default = dims[3] if kind == "DBOX" and 4 <= k <= 7 else dims[5] if kind == "DBOX" and k >= 8 else _REQUIRED
        dims.append(raw.get(start + k, f"DIM{k + 1}{suffix}", "real", default))
    return dims


_HEAD = (_id("PID"), _id("MID"), ("GROUP", "word", "MSCBML0"), ("TYPE", "word", _REQUIRED), None, None, None, None)


def _pbarl(raw: _Raw) -> list[Card]:
    """PBARL: PID, MID, GROUP, TYPE; DIM1..DIMn from field 2 of the first continuation, then NSM."""
    values, positions = _read(raw, _HEAD)
    n = _library_type(raw, values, positions)
    values.update({f"DIM{k + 1}": v for k, v in enumerate(_dims(raw, 8, n, values["TYPE"]))})
    values["NSM"] = raw.get(8 + n, "NSM", "real", 0.0)
    positions.update({f"DIM{k + 1}": 8 + k for k in range(n)}, NSM=8 + n)
    raw.end(9 + n)
    return [raw.card(values, positions)]


def _pbeaml(raw: _Raw) -> list[Card]:
    """PBEAML: PID, MID, GROUP, TYPE; then, packed from field 2 of the first continuation,
    DIM1(A)..DIMn(A), NSM(A), and per station SO, X/XB, DIM1..DIMn, NSM (QRG, PBEAML).

    ``DIMS`` = per-station tuples of DIMs, ``XXB`` their X/XB and ``NSM`` theirs, end A
    (0.0) first and end B (1.0) last (see :func:`_stations` for the blank fields); SO
    (YES or NO, default YES) is checked, not kept; X/XB blank is 1.0.
    """
    values, positions = _read(raw, _HEAD)
    n = _library_type(raw, values, positions)
    end_a = _dims(raw, 8, n, values["TYPE"], "(A)") + [raw.get(8 + n, "NSM(A)", "real", 0.0)]
    given, i = [], 9 + n
    while any(raw.text(j) for j in range(i, len(raw.texts))):
        k = len(given) + 1
        so = raw.get(i, f"SO({k})", "word", "YES")
        if so not in ("YES", "NO"):
            raise raw.error(i, f"SO({k})", f"expected YES or NO, got {so!r}")
        keys = [f"DIM{d + 1}({k})" for d in range(n)] + [f"NSM({k})"]
        section = [raw.get(i + 2 + d, key, "real") for d, key in enumerate(keys)]
        given.append((raw.get(i + 1, f"X({k})/XB", "real", 1.0), section, i + 1))
        i += n + 3
    stations = _stations(raw, end_a, given)
    values.update(DIMS=tuple(s[1:-1] for s in stations), XXB=tuple(s[0] for s in stations),
                  NSM=tuple(s[-1] for s in stations))
    positions.update(DIMS=8, XXB=given[0][2] if given else 8, NSM=8 + n)
    return [raw.card(values, positions)]


def _stations(raw: _Raw, end_a: list[float], given: list[tuple[float, list, int]]) -> tuple[tuple, ...]:
    """``((X/XB, values...), ...)`` from end A (0.0) to end B (1.0) of a PBEAM or PBEAML.

    ``given``: (X/XB, values with None for blank, field index of X/XB) per station
    continuation, in any order; the last by X/XB must be end B (1.0). No station: end B is
    end A. Blank fields at end B take end A's values, blank fields at an intermediate
    station the linear interpolation between A and B at its X/XB (QRG, PBEAM and PBEAML
    remarks). A value equal to end A's to 5 significant digits is end A's.
    """
    given = sorted(given, key=lambda station: station[0])
    for (x, _, i), after in zip(given, given[1:] + [None]):
        if not 0.0 < x <= 1.0:
            raise raw.error(i, "X/XB", f"X/XB must lie in (0, 1], got {x}")
        if after is not None and after[0] == x:
            raise raw.error(after[2], "X/XB", f"two stations at X/XB = {x}")
    if given and given[-1][0] != 1.0:
        raise raw.error(given[-1][2], "X/XB", f"the last station must be end B (X/XB = 1.0), got {given[-1][0]}")
    end_b = [a if v is None else v for a, v in zip(end_a, given[-1][1])] if given else list(end_a)
    rows = [(0.0, *end_a)]
    for x, section, _ in given[:-1]:
        rows.append((x, *(a + (b - a) * x if v is None else v for v, a, b in zip(section, end_a, end_b))))
    rows.append((1.0, *end_b))
    return tuple((row[0], *(a if f"{v:.4e}" == f"{a:.4e}" else v for v, a in zip(row[1:], end_a))) for row in rows)


_PBEAM_STATION = ("A", "I1", "I2", "I12", "J", "NSM")
_PBEAM_UNSUPPORTED = ("NSI(A)", "NSI(B)", "CW(A)", "CW(B)", "M1(A)", "M2(A)", "M1(B)", "M2(B)",
                      "N1(A)", "N2(A)", "N1(B)", "N2(B)")
_STRESS_ROW = tuple(_re(k) for k in ("C1", "C2", "D1", "D2", "E1", "E2", "F1", "F2"))  # checked, values dropped


def _pbeam(raw: _Raw) -> list[Card]:
    """PBEAM: end-A values A, I1, I2, I12, J, NSM; K1, K2 (default 1.0), S1, S2 from the
    footer; ``STATIONS`` = ((X/XB, A, I1, I2, I12, J, NSM), ...) from end A (0.0) to end B
    (1.0), see :func:`_stations` (a constant section has end B equal to end A).

    Layout (QRG): end-A row; stress-recovery row unless field 2 of the next row is a
    word; station rows (SO, X/XB, A, I1, I2, I12, J, NSM; followed by a stress-recovery
    row when SO = YES); footer K1, K2, S1, S2, NSI(A), NSI(B), CW(A), CW(B), M1(A)..N2(B).
    NSI, CW, M and N must be blank or zero.
    """
    schema = (_id("PID"), _id("MID"), ("A", "real", _REQUIRED)) + tuple(_re(k) for k in _PBEAM_STATION[1:])
    values, positions = _read(raw, schema)
    i = 8
    if not _WORD.fullmatch(raw.text(i).upper()):
        _read(raw, _STRESS_ROW, i)
        i += 8
    given = []
    while _WORD.fullmatch(raw.text(i).upper()):
        so = raw.get(i, "SO", "word")
        if so not in ("YES", "YESA", "NO"):
            raise raw.error(i, "SO", f"expected YES, YESA or NO, got {so!r}")
        section = [raw.get(k, key, "real") for k, key in enumerate(_PBEAM_STATION, i + 2)]
        given.append((raw.get(i + 1, "X/XB", "real", _REQUIRED), section, i + 1))
        i += 8
        if so == "YES":
            _read(raw, _STRESS_ROW, i)
            i += 8
    footer, footer_positions = _read(raw, (_re("K1", 1.0), _re("K2", 1.0), _re("S1"), _re("S2")), i)
    for k, key in enumerate(_PBEAM_UNSUPPORTED, i + 4):
        if raw.get(k, key, "real", 0.0) != 0.0:
            raise raw.error(k, key, f"{key} must be blank or 0.0 (not supported)")
    raw.end(i + 16)
    footer["STATIONS"] = _stations(raw, [values[k] for k in _PBEAM_STATION], given)
    footer_positions["STATIONS"] = given[0][2] if given else positions["A"]
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
