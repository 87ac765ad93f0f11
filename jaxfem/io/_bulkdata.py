"""What the bulk-data reader returns: cards, the parsed file, and its located errors.

A :class:`Card` holds its name, typed values keyed by QRG field name (MSC Nastran QRG,
"Bulk Data Entry Format") and where each came from; :class:`BulkData` the supported cards
by name in file order and the locations of the unsupported ones; a
:class:`BulkDataError` names file, line, card, id and field, e.g.
``model.bdf:17: CBAR 1001 field 4 (GA): expected an integer, got '1.5'``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

Value = int | float | str | tuple | None


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


def _where(file, line, card, ident=None, number=None, key=None) -> str:
    out = f"{file}:{line}: {card}" + ("" if ident is None else f" {ident}")
    if number is not None:
        out += f" field {number}" + (f" ({key})" if key else "")
    return out
