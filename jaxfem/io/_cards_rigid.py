"""Rigid elements RBAR, RROD, RBE1, the supports SUPORT and SUPORT1, the set unions SPCADD
and MPCADD, and SPOINT (MSC Nastran QRG, per card); RBE2 and RBE3 are with the other
variable layouts (:mod:`jaxfem.io._cards_variable`)."""

from __future__ import annotations

from ._bulkdata import Card
from ._cards_variable import _thru
from ._fields import _REQUIRED, _id, _int, _Raw, _re, _read


def _digits(value: int | None) -> set[str]:
    return set(str(value)) if value else set()


def _rbar(raw: _Raw) -> list[Card]:
    """RBAR: EID, GA, GB, CNA, CNB (independent), CMA, CMB (dependent; component digits, 0
    or blank stored None), ALPHA; TREF on the continuation. CNA and CNB hold six components
    in all; CMA and CMB blank make every other component dependent (QRG, RBAR); a
    component may not be both at one grid."""
    values, positions = _read(raw, (_id("EID"), _id("GA"), _id("GB")))
    for i, key in enumerate(("CNA", "CNB", "CMA", "CMB"), 3):
        values[key], positions[key] = _component(raw, i, key) or None, i
    more, more_positions = _read(raw, (_re("ALPHA"), _re("TREF")), 7)
    values.update(more)
    positions.update(more_positions)
    raw.end(9)
    independent = len(_digits(values["CNA"])) + len(_digits(values["CNB"]))
    if independent != 6:
        raise raw.error(positions["CNA"], "CNA", f"CNA and CNB must hold six components in all, got {independent}")
    for n, m in (("CNA", "CMA"), ("CNB", "CMB")):
        both = _digits(values[n]) & _digits(values[m])
        if both:
            raise raw.error(positions[m], m, f"component(s) {''.join(sorted(both))} are in both {n} and {m}")
    return [raw.card(values, positions)]


def _rrod(raw: _Raw) -> list[Card]:
    """RROD: EID, GA, GB, CMA, CMB, ALPHA, TREF; one of CMA and CMB is the dependent
    translation (1, 2 or 3) and the other blank, or both blank (QRG, RROD: the solver
    chooses)."""
    schema = (_id("EID"), _id("GA"), _id("GB"), _int("CMA"), _int("CMB"), _re("ALPHA"), _re("TREF"))
    values, positions = _read(raw, schema)
    raw.end(len(schema))
    for key in ("CMA", "CMB"):
        if values[key] is not None and not 1 <= values[key] <= 3:
            raise raw.error(positions[key], key, f"expected a translation 1, 2 or 3, got {values[key]}")
    if values["CMA"] is not None and values["CMB"] is not None:
        raise raw.error(positions["CMB"], "CMB", "only one of CMA and CMB may be given")
    return [raw.card(values, positions)]


def _pairs(raw: _Raw, i: int, end: int, keys: tuple[str, str], out: list, positions: dict) -> int:
    """Grid/component pairs from data field ``i`` up to ``end`` (blanks skipped) appended
    to ``out``; stops at a word or a real (UM, ALPHA). The index where it stopped."""
    while i < end:
        text = raw.text(i)
        if not text:
            i += 1
            continue
        if not text.lstrip("+-").isdigit():
            break
        k = len(out) + 1
        g, c = f"{keys[0]}{k}", f"{keys[1]}{k}"
        out.append((raw.get(i, g, "id"), raw.get(i + 1, c, "dof", _REQUIRED)))
        positions.update({g: i, c: i + 1})
        i += 2
    return i


def _rbe1(raw: _Raw) -> list[Card]:
    """RBE1: EID, independent pairs GN1, CN1, ... (six components in all), then ``UM`` and
    the dependent pairs GM1, CM1, ..., then ALPHA and TREF (QRG, RBE1). Pairs are read
    in field order, blanks skipped. ``GN``/``CN`` and ``GM``/``CM`` are tuples."""
    values, positions = _read(raw, (_id("EID"),))
    independent: list[tuple[int, int]] = []
    i = _pairs(raw, 1, len(raw.texts), ("GN", "CN"), independent, positions)
    if not independent:
        raise raw.error(1, "GN1", "required field is blank (RBE1 needs independent grids)")
    if raw.text(i).upper() != "UM":
        found = repr(raw.text(i)) if raw.text(i) else "nothing"
        raise raw.error(i, "UM", f"expected UM and the dependent grids after the independent ones, got {found}")
    count = sum(len(str(c)) for _, c in independent)
    if count != 6:
        raise raw.error(2, "CN1", f"CN1, CN2, ... must hold six components in all, got {count}")
    dependent: list[tuple[int, int]] = []
    i = _pairs(raw, i + 1, len(raw.texts), ("GM", "CM"), dependent, positions)
    if not dependent:
        raise raw.error(i, "GM1", "required field is blank (RBE1 needs dependent grids after UM)")
    values.update(GN=tuple(g for g, _ in independent), CN=tuple(c for _, c in independent),
                  GM=tuple(g for g, _ in dependent), CM=tuple(c for _, c in dependent),
                  ALPHA=raw.get(i, "ALPHA", "real", 0.0), TREF=raw.get(i + 1, "TREF", "real", 0.0))
    positions.update(GN=positions["GN1"], CN=positions["CN1"], GM=positions["GM1"], CM=positions["CM1"],
                     ALPHA=i, TREF=i + 1)
    raw.end(i + 2)
    return [raw.card(values, positions)]


def _component(raw: _Raw, i: int, key: str) -> int:
    """Component digits at a grid; 0 or blank (0) at a scalar point."""
    return 0 if raw.text(i) in ("", "0") else raw.get(i, key, "dof")


def _suport(raw: _Raw) -> list[Card]:
    """SUPORT: up to four pairs ID, C, one card each (C digits 1-6, 0 or blank at a scalar point)."""
    cards = []
    for start in (0, 2, 4, 6):
        if start and not any(raw.text(i) for i in (start, start + 1)):
            continue
        values, positions = _read(raw, (_id("ID"),), start, True)
        values["C"], positions["C"] = _component(raw, start + 1, "C"), start + 1
        cards.append(raw.card(values, positions))
    raw.end(8)
    return cards


def _suport1(raw: _Raw) -> list[Card]:
    """SUPORT1: SID, then up to three pairs ID, C, one card each (as SUPORT)."""
    head, head_positions = _read(raw, (_id("SID"),))
    cards = []
    for start in (1, 3, 5):
        if start > 1 and not any(raw.text(i) for i in (start, start + 1)):
            continue
        values, positions = _read(raw, (_id("ID"),), start)
        values["C"], positions["C"] = _component(raw, start + 1, "C"), start + 1
        cards.append(raw.card({**head, **values}, {**head_positions, **positions}))
    raw.end(7)
    return cards


def _set_union(raw: _Raw) -> list[Card]:
    """SPCADD, MPCADD: SID, then the set ids S1, S2, ... (blanks skipped) as the tuple ``S``."""
    values, positions = _read(raw, (_id("SID"),))
    sets = [raw.get(i, f"S{k}", "id") for k, i in enumerate((i for i in range(1, len(raw.texts)) if raw.text(i)), 1)]
    if not sets:
        raise raw.error(1, "S1", "required field is blank")
    if values["SID"] in sets:
        raise raw.error(1, "S", f"set {values['SID']} lists itself")
    values["S"], positions["S"] = tuple(sets), 1
    return [raw.card(values, positions)]


def _spoint(raw: _Raw) -> list[Card]:
    """SPOINT: scalar point ids, ``ID1 THRU ID2`` ranges kept as runs: ``ID`` an :class:`IdRanges`."""
    return [raw.card({"ID": _thru(raw, 0, "ID", "a scalar point id")}, {"ID": 0})]
