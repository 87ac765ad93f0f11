"""Bulk-data text to logical cards and typed fields: the tokenizer of the reader.

Physical lines are split into fields, free field (commas), small field (8 columns) or
large field (16 columns, ``NAME*``), and continuation lines are joined to their card
(markers checked; text in field 10 with no continuation after it is a comment, with a
warning); each data field is then typed as an id, integer, real (decimal point
required, Nastran exponents such as ``1.D-3`` and ``7.2+10``), number, word, DoF digits
or anything, against a schema of (key, kind, default) per field (MSC Nastran QRG, "Bulk
Data Entry Format"). Errors are :class:`BulkDataError` naming file, line, card and field.

What every field must be, whatever its card (the one check per input kind):

- lines end at ``\\n`` or ``\\r\\n`` only (not at form feeds or U+2028, which
  ``str.splitlines`` would split on, moving every later line number); a leading UTF-8
  byte-order mark is dropped (both in :mod:`jaxfem.io._deck`, which reads the files);
- a field holds printable ASCII only: Python's ``int``/``float`` would read full-width or
  Arabic-Indic digits, and ``str.upper`` folds ``ı`` into ``I``;
- a real is finite in 64-bit floating point (``1.E400`` is refused, not read as inf; NaN
  and inf are not Nastran reals);
- an id is an integer in 1..99,999,999 (QRG: "0 < ID < 100,000,000"), any other integer
  fits in 32 bits, so that no value overflows the int64 arrays of the model.
"""

from __future__ import annotations

import math
import re
import unicodedata
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field

from ._bulkdata import BulkDataError, Card, Value, _where

_REQUIRED = object()  # schema default: the field must not be blank
_SAME_AS_ID = object()  # schema default: the card's id (PID = EID on elements)

_INT = re.compile(r"[+-]?\d+", re.ASCII)
_REAL = re.compile(r"([+-]?(?:\d+\.\d*|\.\d+))((?:[ED][+-]?|[+-])\d+)?", re.ASCII)
_WORD = re.compile(r"[A-Z][A-Z0-9_]*")
_NAME = re.compile(r"[A-Z][A-Z0-9]*")
_DEQATN = re.compile(r"DEQATN\*?(?![A-Z0-9])", re.IGNORECASE)
_SPACE = " \t\r\f\v"  # ASCII white space: strip() alone would also remove U+00A0, U+3000, ...
_ID_MAX = 99_999_999  # QRG: ids are integers 0 < ID < 100,000,000
_INT_MAX = 2**31 - 1  # other integers: 32-bit


def _character_error(text: str) -> str | None:
    """Why a field is refused for its characters (anything but printable ASCII), or None."""
    if text.isascii() and text.isprintable():
        return None
    ch = next(c for c in text if not (c.isascii() and c.isprintable()))
    name = unicodedata.name(ch, "")
    note = ": a byte that is not UTF-8" if ch == "\ufffd" else ""
    return f"character {ch!r} (U+{ord(ch):04X}{' ' + name if name else ''}{note}) is not allowed: bulk data is printable ASCII"


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
    """Fields of one physical line; None for blank and comment lines. Fields 1 and 10 are
    checked for their characters here, data fields when read (:meth:`_Raw.text`)."""
    text = text.split("$", 1)[0].rstrip(_SPACE)
    if not text.strip(_SPACE):
        return None

    def checked(value: str, place: int, first: str = "") -> str:
        """``value`` of field ``place`` (1 or 10); ``first``: field 1 of the line."""
        why = _character_error(value)
        if why is not None:
            head = value if place == 1 else first
            label = card if card and (not head or head.startswith(("+", "*"))) else head.rstrip("*") or "(blank)"
            raise BulkDataError(f"{_where(file, number, label, None, place)}: {why}")
        return value

    if "," in text:
        parts = [p.strip(_SPACE) for p in text.split(",")]
        first = checked(parts[0], 1).upper()
        large = first.endswith("*") or first.startswith("*")
        n = 4 if large else 8
        if len(parts) > n + 2:
            raise BulkDataError(
                f"{_where(file, number, card or first)}: free-field line has {len(parts)} fields; "
                f"at most {n + 2} (field 1, {n} data fields, continuation field)"
            )
        data = (parts[1 : n + 1] + [""] * n)[:n]
        last = checked(parts[n + 1], 10, first) if len(parts) > n + 1 else ""
        return _Line(number, first, data, last, large)
    text = text.expandtabs(8)
    if len(text) > 80:
        raise BulkDataError(
            f"{_where(file, number, card or text[:8].strip().upper())}: fixed-format line is "
            f"{len(text)} columns long; at most 80 (use free field for longer lines)"
        )
    first = checked(text[:8].strip(_SPACE), 1).upper()
    large = first.endswith("*") or first.startswith("*")
    width, n = (16, 4) if large else (8, 8)
    data = [text[8 + i * width : 8 + (i + 1) * width].strip(_SPACE) for i in range(n)]
    return _Line(number, first, data, checked(text[72:80].strip(_SPACE), 10, first), large)


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

    def text(self, i: int, key: str | None = None) -> str:
        """Text of data field ``i`` ("" past the end); a located error for a character
        outside printable ASCII."""
        text = self.texts[i] if i < len(self.texts) else ""
        why = _character_error(text)
        if why is not None:
            raise self.error(i, key, why)
        return text

    def error(self, i: int, key: str | None, message: str) -> BulkDataError:
        line = self.lines[min(i, len(self.lines) - 1)] if self.lines else self.line
        return BulkDataError(f"{_where(self.file, line, self.name, self.ident, i % 8 + 2, key)}: {message}")

    def get(self, i: int, key: str, kind: str, default: object = None) -> Value:
        """Typed value of data field ``i`` (0-based over the whole card)."""
        text = self.text(i, key)
        if not text:
            if default is _REQUIRED:
                raise self.error(i, key, "required field is blank")
            return self.ident if default is _SAME_AS_ID else default
        value = _convert(text, kind)
        if value is None:
            raise self.error(i, key, f"expected {_KIND_NAMES[kind]}, got {text!r}")
        if isinstance(value, float) and not math.isfinite(value):
            raise self.error(i, key, f"real number out of range: {_short(text)!r} overflows a 64-bit real (|x| < 1.8E+308)")
        if kind == "id" and not 1 <= value <= _ID_MAX:
            raise self.error(i, key, f"expected an id in 1..99,999,999, got {_short(text)!r}")
        if isinstance(value, int) and abs(value) > _INT_MAX:
            raise self.error(i, key, f"integer out of range: {_short(text)!r} does not fit in 32 bits (|n| < 2**31)")
        return value

    def blank(self, i: int, key: str | None = None, why: str = "must be blank") -> None:
        if self.text(i, key):
            raise self.error(i, key, f"{why}, got {self.text(i)!r}")

    def end(self, n: int) -> None:
        """Refuse any value at or after data field ``n``."""
        for i in range(n, len(self.texts)):
            self.blank(i, None, f"unexpected value (the {self.name} card has no field here)")

    def card(self, values: dict[str, Value], positions: dict[str, int]) -> Card:
        fields = {k: (self.lines[min(i, len(self.lines) - 1)], i % 8 + 2) for k, i in positions.items()}
        return Card(self.name, values, self.file, self.line, fields)


def _logical_cards(lines: Iterable[tuple[str, int, str]]) -> list[_Raw]:
    """Cards of the bulk-data lines ``(file, line number, text)`` (INCLUDE already expanded,
    ENDDATA cut off); a card lies in one file. Text in field 10 with no continuation line
    after it is a comment, as in Nastran: a ``UserWarning`` names it (the first three, then
    one for the rest). DEQATN (an equation
    in free form, QRG DEQATN) is kept as a card without fields, its continuation lines
    (those not starting with a letter) skipped."""
    cards: list[_Raw] = []
    comments: list[str] = []
    previous: tuple[str, _Line] | None = None
    for file, number, text in lines:
        if cards and cards[-1].name == "DEQATN" and not text[:1].isalpha():
            continue  # the equation's continuation lines
        if _DEQATN.match(text):
            cards.append(_Raw(file, "DEQATN", number))
            previous = None
            continue
        line = _split(file, number, text, cards[-1].name if cards else None)
        if line is None:
            continue
        continuation = not line.first or line.first[0] in "+*"
        if previous is not None and previous[1].last and not continuation:
            comments.append(_field10_comment(cards[-1], *previous))
        if continuation:
            if not cards:
                raise BulkDataError(f"{_where(file, number, line.first or '(blank)')}: continuation line with no card before it")
            card = cards[-1]
            if file != card.file:
                raise BulkDataError(
                    f"{_where(file, number, card.name, card.text(0) or None, 1)}: continuation of the card at "
                    f"{card.file}:{card.line}: a card must end in the file where it starts"
                )
            mine, theirs = line.first[1:], previous[1].last.lstrip("+*") if previous else ""
            if mine and theirs and mine != theirs.upper():
                comments.append(
                    f"{_where(file, number, card.name, card.text(0) or None, 1)}: continuation marker "
                    f"{line.first!r} does not match {previous[1].last!r} on line {previous[1].number}: the line "
                    "continues the card above it (as Nastran reads consecutive lines)"
                )
            card.add(line)
        else:
            name = line.first.rstrip("*").strip()
            if not _NAME.fullmatch(name):
                raise BulkDataError(f"{_where(file, number, line.first)}: field 1 is not a card name")
            cards.append(_Raw(file, name, number))
            cards[-1].add(line)
        previous = (file, line)
    if previous is not None and previous[1].last:
        comments.append(_field10_comment(cards[-1], *previous))
    for message in comments[:3]:
        warnings.warn(message, UserWarning, stacklevel=3)
    if len(comments) > 3:
        warnings.warn(f"{len(comments) - 3} more notes on continuation fields (field 10 text taken as a comment, "
                      f"markers that do not match), the last: {comments[-1]}", UserWarning, stacklevel=3)
    return cards


def _field10_comment(card: _Raw, file: str, line: _Line) -> str:
    return (f"{_where(file, line.number, card.name, card.text(0) or None, 10)}: text {line.last!r} with no "
            "continuation line after it is taken as a comment (as Nastran does)")


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


def _short(text: str) -> str:
    return text if len(text) <= 24 else text[:20] + "..."


def _real(text: str) -> float | None:
    m = _REAL.fullmatch(text.upper())
    if m is None:
        return None
    mantissa, exponent = m.groups()
    return float(mantissa + ("e" + exponent.lstrip("ED") if exponent else ""))


def _integer(text: str) -> int:
    """int(text) of an integer field; beyond 20 characters a stand-in that is out of every
    range (int() refuses more than 4,300 digits, and no id or integer field is that long)."""
    return int(text) if len(text) <= 20 else (-1 if text.startswith("-") else 1) * 10**20


def _convert(text: str, kind: str) -> Value:
    """Typed value of a non-blank field, or None when it is not of that kind."""
    upper = text.upper()
    is_int = _INT.fullmatch(text) is not None
    if kind in ("int", "id", "dof"):
        if not is_int:
            return None
        value = _integer(text)
        if kind == "dof" and not (set(text) <= set("123456") and len(set(text)) == len(text)):
            return None
        return value
    if kind == "real":
        return _real(text)
    if kind == "word":
        return upper if _WORD.fullmatch(upper) else None
    if kind == "num":
        return _integer(text) if is_int else _real(text)
    if is_int:  # "any"
        return _integer(text)
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
