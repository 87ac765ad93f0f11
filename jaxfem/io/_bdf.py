"""Strict reader for Nastran bulk data: free field, small field (8) and large field (16).

The reader turns text into :class:`BulkData`: cards of the supported kinds with typed
raw values (int, float, str, tuple, or None for a blank field without default), each
remembering where it came from. Cards of any other kind are listed in
:attr:`BulkData.unknown`, never silently dropped. Every malformed or unsupported entry
raises :class:`BulkDataError` naming file, line, card and field, e.g.
``model.bdf:17: CBAR 1001 field 4 (GA): expected an integer, got '1.5'``.

Format rules (MSC Nastran QRG, "Bulk Data Entry Format"):

- ``$`` starts a comment; blank lines are skipped; anything before ``BEGIN BULK`` (if
  present) and after ``ENDDATA`` is ignored; ``INCLUDE`` is refused.
- A line holding a comma is free field; otherwise fixed columns, 80 at most (tabs
  expand to 8-column stops). Field 1 is the card name (``NAME*`` = large field);
  small-field lines carry 8 data fields, large-field lines 4 (two lines per row of 8).
- A line whose field 1 is blank or starts with ``+``/``*`` continues the card above
  (``*`` = large field). Markers in field 10 of a line and field 1 of the next must
  match when both are given; a field-10 marker with no continuation after it is an error.
- Reals need a decimal point: ``1.``, ``.5``, ``1.E3``, ``1.D-3``, ``7.2+10``, ``-2.5-4``.

Field numbers in messages follow the QRG: 2..9 within each row of eight data fields,
on the physical line where the field is.

Cards (values keyed by QRG field names; see ``_PARSERS``) and what is refused:

- GRID (CD must be 0/blank), CORD2R;
- CBAR, CBEAM: orientation X1-X3 or G0 (``G0`` key), OFFT GGG/BGG only, no pin flags
  PA/PB, CBEAM without BIT and SA/SB; CROD;
- PBAR, PBARL (BAR, ROD, TUBE, BOX; ``DIM1..`` keys), PBEAM (constant section: end-A
  values, footer K1/K2; tapered stations, NSI, CW, M, N refused), PROD, MAT1;
- CONM2 (CID 0/blank or -1), CELAS1 + PELAS (two per card, split), CELAS2 (a grounded
  end has G and C None), CBUSH (GB required, OCID -1/blank) + PBUSH (rows K, B, GE, RCV);
- RBE2 (``GM`` tuple), SPC (one card per G/C/D triplet), SPC1 (``G`` tuple, THRU), PARAM.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

Value = int | float | str | tuple | None

_REQUIRED = object()  # schema default: the field must not be blank
_SAME_AS_ID = object()  # schema default: the card's id (PID = EID on elements)

_INT = re.compile(r"[+-]?\d+")
_REAL = re.compile(r"([+-]?(?:\d+\.\d*|\.\d+))((?:[ED][+-]?|[+-])\d+)?")
_WORD = re.compile(r"[A-Z][A-Z0-9_]*")
_NAME = re.compile(r"[A-Z][A-Z0-9]*")
_BEGIN_BULK = re.compile(r"\s*BEGIN\s+BULK\b")
_ENDDATA = re.compile(r"\s*ENDDATA\b")
_INCLUDE = re.compile(r"\s*INCLUDE\b")


class BulkDataError(ValueError):
    """Malformed, inconsistent or unsupported bulk data; the message says where and what."""


@dataclass(frozen=True)
class Card:
    """One parsed card: name, typed values by QRG field name, and its source.

    Equality compares name and values only, so the same card read from free,
    small- or large-field text compares equal.
    """

    name: str
    values: dict[str, Value]
    file: str = field(compare=False)
    line: int = field(compare=False)  # first line of the card
    fields: dict[str, tuple[int, int]] = field(compare=False, repr=False)  # key -> (line, field)

    def __getitem__(self, key: str) -> Value:
        return self.values[key]

    @property
    def id(self) -> Value:
        """The value of the card's first field (EID, PID, MID, ID, SID, CID, PARAM name)."""
        return next(iter(self.values.values()))

    def error(self, key: str, message: str) -> BulkDataError:
        """A :class:`BulkDataError` located at field ``key`` of this card."""
        line, number = self.fields.get(key, (self.line, None))
        return BulkDataError(f"{_where(self.file, line, self.name, self.id, number, key)}: {message}")


@dataclass(frozen=True)
class BulkData:
    """Parsed bulk data: supported cards by name (file order) and unknown card locations."""

    cards: dict[str, list[Card]]
    unknown: dict[str, list[tuple[str, int]]]  # card name -> [(file, line), ...]
    source: str = field(compare=False)

    def __getitem__(self, name: str) -> list[Card]:
        """Cards of one kind in file order (empty list if none)."""
        return self.cards.get(name, [])

    def unknown_summary(self) -> str:
        """One line per unsupported card kind, with its count and first locations."""
        out = []
        for name, places in sorted(self.unknown.items()):
            where = ", ".join(f"{f}:{n}" for f, n in places[:3])
            more = f", ... ({len(places) - 3} more)" if len(places) > 3 else ""
            out.append(f"{name} x{len(places)} ({where}{more})")
        return "; ".join(out)

    def report(self) -> str:
        """Plain-text summary: counts of the parsed cards and the unsupported (ignored) ones."""
        lines = [f"{self.source}: bulk data"]
        lines += [f"  {name:<8} {len(cards)}" for name, cards in sorted(self.cards.items())]
        if self.unknown:
            lines.append(f"  unsupported cards, ignored: {self.unknown_summary()}")
        return "\n".join(lines)


def read_bdf(path: str | Path) -> BulkData:
    """Read a Nastran bulk-data file (see the module docstring for the accepted format)."""
    path = Path(path)
    return read_bdf_text(path.read_text(encoding="utf-8", errors="replace"), name=str(path))


def read_bdf_text(text: str, name: str = "<string>") -> BulkData:
    """Parse bulk data held in a string; ``name`` stands for the file in messages."""
    cards: dict[str, list[Card]] = {}
    unknown: dict[str, list[tuple[str, int]]] = {}
    for raw in _logical_cards(text, name):
        parser = _PARSERS.get(raw.name)
        if parser is None:
            unknown.setdefault(raw.name, []).append((name, raw.line))
            continue
        cards.setdefault(raw.name, []).extend(parser(raw))
    _check_unique(cards)
    return BulkData(cards=cards, unknown=unknown, source=name)


def _where(file, line, card, ident=None, number=None, key=None) -> str:
    out = f"{file}:{line}: {card}" + ("" if ident is None else f" {ident}")
    if number is not None:
        out += f" field {number}" + (f" ({key})" if key else "")
    return out


# ---------------------------------------------------------------------------------------
# Lines -> logical cards


@dataclass
class _Line:
    number: int
    first: str  # field 1: card name or continuation marker
    data: list[str]  # 8 (small) or 4 (large) data fields, stripped, original case
    last: str  # field 10: continuation marker
    large: bool


def _split(file: str, number: int, text: str, card: str | None) -> _Line | None:
    """Fields of one physical line; None for blank and comment lines."""
    text = text.split("$", 1)[0].rstrip()
    if not text.strip():
        return None
    if "," in text:
        parts = [p.strip() for p in text.split(",")]
        first = parts[0].upper()
        large = first.endswith("*") or first.startswith("*")
        n = 4 if large else 8
        if len(parts) > n + 2:
            raise BulkDataError(
                f"{_where(file, number, card or first)}: free-field line has {len(parts)} fields; "
                f"at most {n + 2} (field 1, {n} data fields, continuation field)"
            )
        data = (parts[1 : n + 1] + [""] * n)[:n]
        last = parts[n + 1] if len(parts) > n + 1 else ""
        return _Line(number, first, data, last, large)
    text = text.expandtabs(8)
    if len(text) > 80:
        raise BulkDataError(
            f"{_where(file, number, card or text[:8].strip().upper())}: fixed-format line is "
            f"{len(text)} columns long; at most 80 (use free field for longer lines)"
        )
    first = text[:8].strip().upper()
    large = first.endswith("*") or first.startswith("*")
    width, n = (16, 4) if large else (8, 8)
    data = [text[8 + i * width : 8 + (i + 1) * width].strip() for i in range(n)]
    return _Line(number, first, data, text[72:80].strip(), large)


@dataclass
class _Raw:
    """A logical card before typing: name and data-field texts with their line numbers."""

    file: str
    name: str
    line: int
    texts: list[str] = field(default_factory=list)
    lines: list[int] = field(default_factory=list)
    ident: Value = None  # the parsed id, for messages

    def add(self, line: _Line) -> None:
        if not line.large:  # a small-field line is a full row of eight fields
            pad = -len(self.texts) % 8
            self.texts += [""] * pad
            self.lines += [self.lines[-1] if self.lines else line.number] * pad
        self.texts += line.data
        self.lines += [line.number] * len(line.data)

    def text(self, i: int) -> str:
        return self.texts[i] if i < len(self.texts) else ""

    def error(self, i: int, key: str | None, message: str) -> BulkDataError:
        line = self.lines[min(i, len(self.lines) - 1)] if self.lines else self.line
        return BulkDataError(f"{_where(self.file, line, self.name, self.ident, i % 8 + 2, key)}: {message}")

    def get(self, i: int, key: str, kind: str, default: object = None) -> Value:
        """Typed value of data field ``i`` (0-based over the whole card)."""
        text = self.text(i)
        if not text:
            if default is _REQUIRED:
                raise self.error(i, key, "required field is blank")
            return self.ident if default is _SAME_AS_ID else default
        value = _convert(text, kind)
        if value is None:
            expected = "a positive integer" if kind == "id" and _INT.fullmatch(text) else _KIND_NAMES[kind]
            raise self.error(i, key, f"expected {expected}, got {text!r}")
        return value

    def blank(self, i: int, key: str | None = None, why: str = "must be blank") -> None:
        if self.text(i):
            raise self.error(i, key, f"{why}, got {self.text(i)!r}")

    def end(self, n: int) -> None:
        """Refuse any value at or after data field ``n``."""
        for i in range(n, len(self.texts)):
            self.blank(i, None, f"unexpected value (the {self.name} card has no field here)")

    def card(self, values: dict[str, Value], positions: dict[str, int]) -> Card:
        fields = {k: (self.lines[min(i, len(self.lines) - 1)], i % 8 + 2) for k, i in positions.items()}
        return Card(self.name, values, self.file, self.line, fields)


def _logical_cards(text: str, file: str) -> list[_Raw]:
    lines = text.splitlines()
    start = next(
        (i + 1 for i, t in enumerate(lines) if _BEGIN_BULK.match(t.split("$", 1)[0].upper())), 0
    )
    cards: list[_Raw] = []
    previous: _Line | None = None
    for number in range(start + 1, len(lines) + 1):
        text = lines[number - 1]
        head = text.split("$", 1)[0].upper()
        if _ENDDATA.match(head):
            break
        if _INCLUDE.match(head):
            raise BulkDataError(f"{_where(file, number, 'INCLUDE')}: INCLUDE is not supported; merge the files")
        line = _split(file, number, text, cards[-1].name if cards else None)
        if line is None:
            continue
        continuation = not line.first or line.first[0] in "+*"
        if previous is not None and previous.last and not continuation:
            raise BulkDataError(
                f"{_where(file, previous.number, cards[-1].name, cards[-1].text(0) or None, 10)}: "
                f"continuation marker {previous.last!r} but line {number} does not continue the card"
            )
        if continuation:
            if not cards:
                where = _where(file, number, line.first or "(blank)")
                raise BulkDataError(f"{where}: continuation line with no card before it")
            mine, theirs = line.first[1:], previous.last.lstrip("+*") if previous else ""
            if mine and theirs and mine != theirs.upper():
                raise BulkDataError(
                    f"{_where(file, number, cards[-1].name, cards[-1].text(0) or None, 1)}: continuation "
                    f"marker {line.first!r} does not match {previous.last!r} on line {previous.number}"
                )
            cards[-1].add(line)
        else:
            name = line.first.rstrip("*").strip()
            if not _NAME.fullmatch(name):
                raise BulkDataError(f"{_where(file, number, line.first)}: field 1 is not a card name")
            cards.append(_Raw(file, name, number))
            cards[-1].add(line)
        previous = line
    if previous is not None and previous.last:
        raise BulkDataError(
            f"{_where(file, previous.number, cards[-1].name, cards[-1].text(0) or None, 10)}: "
            f"continuation marker {previous.last!r} but the data ends here"
        )
    return cards


# ---------------------------------------------------------------------------------------
# Field types

_KIND_NAMES = {
    "id": "an integer",
    "int": "an integer",
    "real": "a real number with a decimal point",
    "num": "an integer or a real number",
    "word": "a word",
    "any": "a number or a word",
    "dof": "component digits 1-6 without repeats (e.g. 123456)",
}


def _real(text: str) -> float | None:
    m = _REAL.fullmatch(text.upper())
    if m is None:
        return None
    mantissa, exponent = m.groups()
    return float(mantissa + ("e" + exponent.lstrip("ED") if exponent else ""))


def _convert(text: str, kind: str) -> Value:
    """Typed value of a non-blank field, or None when it is not of that kind."""
    upper = text.upper()
    is_int = _INT.fullmatch(text) is not None
    if kind in ("int", "id", "dof"):
        if not is_int:
            return None
        value = int(text)
        if kind == "id" and value <= 0:
            return None
        if kind == "dof" and not (set(text) <= set("123456") and len(set(text)) == len(text)):
            return None
        return value
    if kind == "real":
        return _real(text)
    if kind == "word":
        return upper if _WORD.fullmatch(upper) else None
    if kind == "num":
        return int(text) if is_int else _real(text)
    if is_int:  # "any"
        return int(text)
    real = _real(text)
    return real if real is not None else (upper if _WORD.fullmatch(upper) else None)


# ---------------------------------------------------------------------------------------
# Card schemas: one (key, kind, default) per data field, None for a field that must be blank

_Spec = tuple[str, str, object] | None


def _id(key: str, default: object = _REQUIRED) -> _Spec:
    return (key, "id", default)


def _int(key: str, default: object = None) -> _Spec:
    return (key, "int", default)


def _re(key: str, default: object = 0.0) -> _Spec:
    return (key, "real", default)


def _read(raw: _Raw, schema: tuple[_Spec, ...], start: int = 0, ident: bool = False) -> tuple[dict, dict]:
    """Values and positions of the fields ``start, start+1, ...`` described by ``schema``.

    The first value becomes the card id in messages when ``start == 0`` or ``ident``.
    """
    values: dict[str, Value] = {}
    positions: dict[str, int] = {}
    for i, spec in enumerate(schema, start):
        if spec is None:
            raw.blank(i)
            continue
        key, kind, default = spec
        values[key] = raw.get(i, key, kind, default)
        positions[key] = i
        if i == start and (start == 0 or ident):
            raw.ident = values[key]
    return values, positions


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
    """SPC1: SID, C, then grids G1, G2, ... with ``Gi THRU Gj`` ranges; blanks skipped."""
    values, positions = _read(raw, (_id("SID"), ("C", "dof", _REQUIRED)))
    grids: list[int] = []
    i = 2
    while i < len(raw.texts):
        text = raw.text(i).upper()
        if text == "THRU":
            if not grids:
                raise raw.error(i, "THRU", "THRU must follow a grid id")
            last = raw.get(i + 1, "G", "id", _REQUIRED)
            if last < grids[-1]:
                raise raw.error(i + 1, "G", f"THRU range ends below its start ({grids[-1]} THRU {last})")
            grids.extend(range(grids[-1] + 1, last + 1))
            i += 2
            continue
        if text:
            grids.append(raw.get(i, "G", "id"))
        i += 1
    if not grids:
        raise raw.error(2, "G1", "required field is blank")
    return [raw.card({**values, "G": tuple(grids)}, {**positions, "G": 2})]


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
_STRESS_ROW = tuple(_re(k) for k in ("C1", "C2", "D1", "D2", "E1", "E2", "F1", "F2"))  # not used


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
        for i in range(row + 2 + n, row + 8):
            raw.blank(i)
    return [raw.card(values, positions)]


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
    "SPC": _spc,
    "SPC1": _spc1,
    "PARAM": _param,
}

# Id spaces in which two cards may not share an id (Nastran: element ids are unique across
# all element kinds, property ids across all property kinds).
_ID_SPACES = {
    "grid": ("GRID",),
    "coordinate system": ("CORD2R",),
    "element": ("CBAR", "CBEAM", "CROD", "CELAS1", "CELAS2", "CBUSH", "CONM2", "RBE2"),
    "property": ("PBAR", "PBARL", "PBEAM", "PROD", "PELAS", "PBUSH"),
    "material": ("MAT1",),
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
