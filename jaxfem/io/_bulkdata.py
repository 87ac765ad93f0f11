"""What the bulk-data reader returns: cards, the parsed deck, and its located errors.

A :class:`Card` holds its name, typed values keyed by QRG field name (MSC Nastran QRG,
"Bulk Data Entry Format") and where each came from; :class:`BulkData` the supported cards
by name in deck order, the locations of the unsupported ones (split into those that
may define structure and those that cannot change stiffness or mass), the case control
and the files read; a
:class:`BulkDataError` names file, line, card, id and field, e.g.
``model.bdf:17: CBAR 1001 field 4 (GA): expected an integer, got '1.5'``. SPC1 and SPOINT
``THRU`` lists are :class:`IdRanges`, never expanded.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ._case import CaseControl


class BulkDataError(ValueError):
    """Malformed, inconsistent or unsupported bulk data; the message says where and what."""


class UnsupportedCardsError(BulkDataError):
    """Unsupported cards that define structure (elements, properties, materials,
    constraints, ...): the model would be built without them. ``problem`` is the message
    without its remedy, ``names`` the card names."""

    def __init__(self, problem: str, names: list[str]):
        super().__init__(f"{problem}; build_model(..., allow_unsupported=True) builds it without them")
        self.problem = problem
        self.names = names


class IdRanges(Sequence):
    """Ids listed with ``THRU`` (SPC1, SPOINT): runs (first, last) kept as they are, so that
    ``1 THRU 99999999`` is two integers, never a list of 10⁸. Iterates, indexes and
    compares like the tuple of the ids it stands for."""

    __slots__ = ("runs",)

    def __init__(self, runs):
        merged: list[tuple[int, int]] = []
        for a, b in runs:  # contiguous runs merged: (1, 1), (2, 4) is (1, 4)
            if merged and a == merged[-1][1] + 1:
                merged[-1] = (merged[-1][0], b)
            else:
                merged.append((int(a), int(b)))
        self.runs = tuple(merged)

    def __len__(self) -> int:
        return sum(b - a + 1 for a, b in self.runs)

    def __iter__(self) -> Iterator[int]:
        for a, b in self.runs:
            yield from range(a, b + 1)

    def __contains__(self, value) -> bool:
        return any(a <= value <= b for a, b in self.runs)

    def __getitem__(self, i):
        if isinstance(i, slice):
            return tuple(self)[i]
        i = i + len(self) if i < 0 else i
        for a, b in self.runs:
            if 0 <= i <= b - a:
                return a + i
            i -= b - a + 1
        raise IndexError("IdRanges index out of range")

    def __eq__(self, other) -> bool:
        if isinstance(other, IdRanges):
            return self.runs == other.runs
        if isinstance(other, tuple):
            return len(self) == len(other) and all(x == y for x, y in zip(self, other))
        return NotImplemented

    def __hash__(self) -> int:
        return hash(self.runs)

    def __repr__(self) -> str:
        return "IdRanges(" + ", ".join(f"{a}" if a == b else f"{a} THRU {b}" for a, b in self.runs) + ")"


Value = int | float | str | tuple | IdRanges | None

# Unsupported cards that cannot change stiffness or mass (MSC QRG, per card): solution
# control, loads, output, design optimisation, aeroelasticity, reduction sets. Ignored with
# a warning; any other unsupported card is taken to define structure (an element, property,
# material, constraint, coordinate system such as CORD3G, matrix such as DMI, nonstructural
# mass NSM*) and refused by build_model unless allow_unsupported=True. EIGR, EIGRL, SUPORT
# and SUPORT1 have no effect on stiffness or mass either, but they are read (case control
# selects them).
_NO_EFFECT = frozenset({
    "EIGC", "EIGB", "EIGP", "DAREA", "DLOAD", "DPHASE", "DELAY", "LOAD", "LSEQ", "GRAV", "ACCEL", "ACCEL1",
    "RFORCE", "SPCD", "DEFORM", "SET1", "SET2", "SET3", "PLOTEL", "ASET", "ASET1", "BSET", "BSET1", "CSET", "CSET1",
    "QSET", "QSET1", "OMIT", "OMIT1", "USET", "USET1", "SEQGP", "SEQSET", "EPOINT", "DESVAR", "DCONSTR", "DCONADD",
    "DOPTPRM", "DSCREEN", "DLINK", "DEQATN", "DTABLE", "DTI", "DVGRID", "MODTRAK", "AERO", "AEROS", "AESTAT",
    "AELIST", "AEFACT", "AECOMP", "AECOMPL", "AELINK", "AEPARM", "AESCALE", "AEFORCE", "AEPRESS", "AEDW",
    "CSSCHD", "DIVERG", "GUST", "UXVEC", "FLUTTER", "FLFACT", "TRIM", "TRIM2", "NLPARM", "NLPCI", "RANDPS",
    "RANDT1", "ECHOON", "ECHOOFF",
})
_NO_EFFECT_PREFIXES = ("FREQ", "TABLE", "TABD", "TABRND", "TSTEP", "RLOAD", "TLOAD", "PLOAD", "FORCE", "MOMENT",
                       "TEMP", "DRESP", "DVPREL", "DVMREL", "DVCREL", "CAERO", "PAERO", "SPLINE", "MKAERO", "AESURF",
                       "MONPNT", "MONDSP")


_ANONYMOUS = frozenset({"GRDSET", "SPOINT"})  # cards without an id: messages name none


def _no_effect(name: str) -> bool:
    """True for a card that cannot change stiffness or mass (see ``_NO_EFFECT``)."""
    return name in _NO_EFFECT or name.startswith(_NO_EFFECT_PREFIXES)


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

    def where(self, key: str | None = None) -> str:
        """``file:line: NAME id field n (KEY)``: where the card (or its field ``key``) is
        (no id for GRDSET and SPOINT, which have none)."""
        line, number = self.fields.get(key, (self.line, None)) if key is not None else (self.line, None)
        return _where(self.file, line, self.name, None if self.name in _ANONYMOUS else self.id, number, key)

    def error(self, key: str, message: str) -> BulkDataError:
        """A :class:`BulkDataError` located at field ``key`` of this card."""
        return BulkDataError(f"{self.where(key)}: {message}")


@dataclass(frozen=True, eq=False)
class BulkData:
    """Parsed deck: supported cards by name (deck order), unknown card locations, the case
    control (None when the deck has no ``BEGIN BULK``) and every file read, in order.

    Two decks are equal when their cards, case control and unknown card names and counts
    are: a deck split over INCLUDE files equals the deck merged into one.
    """

    cards: dict[str, list[Card]]
    unknown: dict[str, list[tuple[str, int]]]  # card name -> [(file, line), ...]
    source: str
    case_control: CaseControl | None = None
    files: tuple[str, ...] = ()

    def __eq__(self, other) -> bool:
        if not isinstance(other, BulkData):
            return NotImplemented
        return (self.cards, self.case_control, self._unknown_counts()) == (
            other.cards, other.case_control, other._unknown_counts())

    def _unknown_counts(self) -> dict[str, int]:
        return {name: len(places) for name, places in self.unknown.items()}

    def __getitem__(self, name: str) -> list[Card]:
        """Cards of one kind in file order (empty list if none)."""
        return self.cards.get(name, [])

    def structural_unknown(self) -> list[str]:
        """Names of the unsupported cards that may define structure (all but those that
        cannot change stiffness or mass: solution control, loads, output, ...)."""
        return sorted(name for name in self.unknown if not _no_effect(name))

    def unknown_summary(self, names: list[str] | None = None) -> str:
        """One line per unsupported card kind (all, or ``names``), with its count and first locations."""
        out = []
        for name, places in sorted((n, self.unknown[n]) for n in (self.unknown if names is None else names)):
            where = ", ".join(f"{f}:{n}" for f, n in places[:3])
            more = f", ... ({len(places) - 3} more)" if len(places) > 3 else ""
            out.append(f"{name} x{len(places)} ({where}{more})")
        return "; ".join(out)

    def card_status(self) -> dict[str, str]:
        """Per card name in the deck (sorted): ``"read"`` (parsed), ``"ignored"`` (not read,
        no effect on stiffness or mass) or ``"unsupported"`` (not read, may define structure)."""
        status = {name: "read" for name, cards in self.cards.items() if cards}
        status.update({name: "ignored" if _no_effect(name) else "unsupported" for name in self.unknown})
        return dict(sorted(status.items()))

    def report(self) -> str:
        """Plain-text summary: files, case control, counts of the parsed cards and the unsupported ones."""
        lines = [f"{self.source}: bulk data"]
        if len(self.files) > 1:
            lines.append(f"  files read: {', '.join(self.files)}")
        if self.case_control is not None:
            ids = ", ".join(str(s.id) for s in self.case_control.subcases)
            lines.append(f"  case control: SOL {self.case_control.sol}, subcases {ids}")
        lines += [f"  {name:<8} {len(cards)}" for name, cards in sorted(self.cards.items())]
        if self.unknown:
            lines.append(f"  unsupported cards, ignored: {self.unknown_summary()}")
        return "\n".join(lines)


def _where(file, line, card, ident=None, number=None, key=None) -> str:
    out = f"{file}:{line}: {card}" + ("" if ident is None else f" {ident}")
    if number is not None:
        out += f" field {number}" + (f" ({key})" if key else "")
    return out
