"""Bulk-data text to logical cards and typed fields: the tokenizer of the reader.

Physical lines are split into fields, free field (commas), small field (8 columns) or
large field (16 columns, ``NAME*``), and continuation lines are joined to their card
(markers checked); each data field is then typed as an id, integer, real (decimal point
required, Nastran exponents such as ``1.D-3`` and ``7.2+10``), number, word, DoF digits
or anything, against a schema of (key, kind, default) per field (MSC Nastran QRG, "Bulk
Data Entry Format"). Errors are :class:`BulkDataError` naming file, line, card and field.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from ._bulkdata import BulkDataError, Card, Value, _where

_REQUIRED = object()  # schema default: the field must not be blank
_SAME_AS_ID = object()  # schema default: the card's id (PID = EID on elements)

_INT = re.compile(r"[+-]?\d+")
_REAL = re.compile(r"([+-]?(?:\d+\.\d*|\.\d+))((?:[ED][+-]?|[+-])\d+)?")
_WORD = re.compile(r"[A-Z][A-Z0-9_]*")
_NAME = re.compile(r"[A-Z][A-Z0-9]*")
_BEGIN_BULK = re.compile(r"\s*BEGIN\s+BULK\b")
_ENDDATA = re.compile(r"\s*ENDDATA\b")
_INCLUDE = re.compile(r"\s*INCLUDE\b")


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
