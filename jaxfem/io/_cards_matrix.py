"""Direct matrix input DMIG and the eigenvalue methods EIGR and EIGRL (MSC Nastran QRG,
per card).

A DMIG matrix is a header entry (field 3 "0") and column entries, anywhere in the deck:
each is read as its own card, then :func:`_merge_dmig` makes one card per matrix NAME
(at its header) with ``ENTRIES`` = ((GJ, CJ, GI, CI, A), ...) in the order given.
"""

from __future__ import annotations

from ._bulkdata import Card
from ._fields import _REQUIRED, _id, _int, _Raw, _re, _read

_FORMS = {1: "square", 2: "rectangular", 6: "symmetric", 9: "rectangular"}


def _dmig(raw: _Raw) -> list[Card]:
    """DMIG header (NAME, "0", IFO, TIN, TOUT, POLAR, NCOL) or column (NAME, GJ, CJ, then
    Gi, Ci, Ai, Bi per term, two on the first row) entry. Real matrices only (TIN 1, 2;
    B blank or 0.0); IFO 1 (square) or 6 (symmetric); C blank is 0 (a scalar point)."""
    if raw.text(1) == "0":
        return [_dmig_header(raw)]
    values, positions = _read(raw, (("NAME", "word", _REQUIRED), _id("GJ"), _int("CJ", 0), None))
    _check_component(raw, values, positions, "CJ")
    entries = []
    for i in range(4, len(raw.texts), 4):
        if not any(raw.text(j) for j in range(i, i + 4)):
            continue
        k = len(entries) + 1
        term, places = _read(raw, (_id(f"G{k}"), _int(f"C{k}", 0), (f"A{k}", "real", _REQUIRED), _re(f"B{k}")), i)
        _check_component(raw, term, places, f"C{k}")
        if term[f"B{k}"] != 0.0:
            raise raw.error(i + 3, f"B{k}", "imaginary part of a real matrix: must be blank or 0.0")
        entries.append((term[f"G{k}"], term[f"C{k}"], term[f"A{k}"]))
        positions.update(places)
    values["ENTRIES"], positions["ENTRIES"] = tuple(entries), 4
    return [raw.card(values, positions)]


def _check_component(raw: _Raw, values: dict, positions: dict, key: str) -> None:
    if not 0 <= values[key] <= 6:
        raise raw.error(positions[key], key, f"component must be 1..6 (a grid) or 0/blank (a scalar point), got {values[key]}")


def _dmig_header(raw: _Raw) -> Card:
    values, positions = _read(raw, (("NAME", "word", _REQUIRED),))
    more, more_positions = _read(raw, (("IFO", "int", _REQUIRED), ("TIN", "int", _REQUIRED), _int("TOUT", 0),
                                       _int("POLAR", 0), None, _int("NCOL")), 2)
    values.update(more)
    positions.update(more_positions)
    raw.end(8)
    ifo, tin = values["IFO"], values["TIN"]
    if ifo not in _FORMS:
        raise raw.error(positions["IFO"], "IFO", f"expected 1 (square), 2 or 9 (rectangular), 6 (symmetric), got {ifo}")
    if _FORMS[ifo] == "rectangular":
        raise raw.error(positions["IFO"], "IFO", f"rectangular matrices (IFO {ifo}) are not supported (1 or 6 are)")
    if tin in (3, 4):
        raise raw.error(positions["TIN"], "TIN", f"complex matrices (TIN {tin}) are not supported (real: TIN 1 or 2)")
    if tin not in (1, 2):
        raise raw.error(positions["TIN"], "TIN", f"expected 1 or 2 (real single or double precision), got {tin}")
    if not 0 <= values["TOUT"] <= 4:
        raise raw.error(positions["TOUT"], "TOUT", f"expected 0..4, got {values['TOUT']}")
    return raw.card(values, positions)


def _merge_dmig(cards: list[Card]) -> list[Card]:
    """One card per matrix: the header's values and the ``ENTRIES`` of its columns.

    A column needs its header; a NAME has one header; an entry (GJ, CJ, GI, CI) is given
    once and, in a symmetric matrix (IFO 6), in one triangle only (QRG, DMIG).
    """
    headers: dict[str, Card] = {}
    for card in (c for c in cards if "IFO" in c.values):
        other = headers.setdefault(card["NAME"], card)
        if other is not card:
            raise card.error("NAME", f"second header of matrix {card['NAME']}, the first at {other.file}:{other.line}")
    terms: dict[str, list[tuple]] = {name: [] for name in headers}
    seen: dict[str, dict[tuple, Card]] = {name: {} for name in headers}
    for card in (c for c in cards if "GJ" in c.values):
        name = card["NAME"]
        if name not in headers:
            raise card.error("NAME", f"column of matrix {name} without its header (DMIG {name} 0 IFO TIN ...)")
        for k, (gi, ci, a) in enumerate(card["ENTRIES"], 1):
            key = (card["GJ"], card["CJ"], gi, ci)
            mirror = (gi, ci) + key[:2]
            other = seen[name].get(key) or (seen[name].get(mirror) if headers[name]["IFO"] == 6 else None)
            if other is not None:
                what = "twice" if key in seen[name] else "in both triangles of the symmetric matrix"
                raise card.error(
                    f"G{k}", f"term ({gi}, {ci}) of column ({key[0]}, {key[1]}) of {name} is given {what} "
                    f"(also at {other.file}:{other.line})"
                )
            seen[name][key] = card
            terms[name].append((*key, a))
    return [Card("DMIG", {**h.values, "ENTRIES": tuple(terms[n])}, h.file, h.line, h.fields) for n, h in headers.items()]


def _eigrl(raw: _Raw) -> list[Card]:
    """EIGRL: SID, V1, V2 (frequency range [Hz]), ND (roots wanted), MSGLVL, MAXSET, SHFSCL,
    NORM (MASS or MAX); the option=value continuation fields kept as text in ``OPTIONS``."""
    schema = (_id("SID"), _re("V1", None), _re("V2", None), _int("ND"), _int("MSGLVL", 0), _int("MAXSET"),
              _re("SHFSCL", None), ("NORM", "word", None))
    values, positions = _read(raw, schema)
    if values["V1"] is not None and values["V2"] is not None and values["V1"] >= values["V2"]:
        raise raw.error(positions["V2"], "V2", f"V2 must exceed V1, got {values['V1']} and {values['V2']}")
    if values["ND"] is not None and values["ND"] <= 0:
        raise raw.error(positions["ND"], "ND", f"number of roots must be > 0, got {values['ND']}")
    if values["NORM"] not in (None, "MASS", "MAX"):
        raise raw.error(positions["NORM"], "NORM", f"expected MASS or MAX, got {values['NORM']!r}")
    values["OPTIONS"] = tuple(raw.text(i) for i in range(8, len(raw.texts)) if raw.text(i))
    return [raw.card(values, positions)]


_EIGR_METHODS = ("LAN", "AHOU", "HOU", "MHOU", "GIV", "MGIV", "INV", "SINV")


def _eigr(raw: _Raw) -> list[Card]:
    """EIGR: SID, METHOD (default LAN), F1, F2 [Hz], NE, ND; continuation NORM (MASS, MAX or
    POINT; default MASS), G, C (the point of NORM = POINT)."""
    schema = (_id("SID"), ("METHOD", "word", "LAN"), _re("F1", None), _re("F2", None), _int("NE"), _int("ND"),
              None, None, ("NORM", "word", "MASS"), _int("G"), _int("C"))
    values, positions = _read(raw, schema)
    raw.end(len(schema))
    if values["METHOD"] not in _EIGR_METHODS:
        raise raw.error(positions["METHOD"], "METHOD", f"expected one of {', '.join(_EIGR_METHODS)}, got {values['METHOD']!r}")
    if values["F1"] is not None and values["F2"] is not None and values["F1"] >= values["F2"]:
        raise raw.error(positions["F2"], "F2", f"F2 must exceed F1, got {values['F1']} and {values['F2']}")
    if values["NORM"] not in ("MASS", "MAX", "POINT"):
        raise raw.error(positions["NORM"], "NORM", f"expected MASS, MAX or POINT, got {values['NORM']!r}")
    return [raw.card(values, positions)]
