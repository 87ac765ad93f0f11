"""Executive and case control: the solution and, per subcase, the choices of a modal solution.

MSC Nastran QRG, "Executive Control Statements" and "Case Control Commands": statements
before ``CEND`` are executive control (``SOL`` is read: a number or a name); the rest, up to
``BEGIN BULK``, is case control. A deck without ``CEND`` is taken as case control
throughout (a ``SOL`` there is read too). Read per subcase: ``SPC``, ``MPC``, ``METHOD``,
``SUPORT1`` (set ids), ``K2GG``, ``M2GG``, ``B2GG``, ``K2PP``, ``M2PP``, ``B2PP`` (matrix
selections ``name`` or ``factor*name``, comma separated, kept as written), ``TITLE``,
``SUBTITLE``, ``LABEL`` (text). Commands above the first ``SUBCASE`` are defaults that
every subcase inherits; without ``SUBCASE`` there is one subcase, id 1. Keywords are
case-insensitive and may be abbreviated to their first four characters (``METH = 1``);
``$`` starts a comment; a line ending with a comma goes on on the next line (not for the
texts). Every other command (output requests, ``SET``, ``ECHO``, ...) is listed in
:attr:`CaseControl.ignored`; after ``OUTPUT(PLOT)`` or ``OUTPUT(XYPLOT)`` the plot
commands are listed as one.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from ._bulkdata import BulkDataError, _where
from ._fields import _INT, _real

_SETS = ("SPC", "MPC", "METHOD", "SUPORT1")
_MATRICES = ("K2GG", "M2GG", "B2GG", "K2PP", "M2PP", "B2PP")
_TEXTS = ("TITLE", "SUBTITLE", "LABEL")
_KEYWORDS = ("SUBCASE", "SOL") + _SETS + _MATRICES + _TEXTS
_OTHER_CASES = ("SUBCOM", "SYM", "SYMCOM", "REPCASE")  # combination cases: their commands are ignored
_STATEMENT = re.compile(r"\s*([A-Za-z][A-Za-z0-9]*)\s*(\([^)]*\))?\s*=?\s*(.*?)\s*$")
_SET_ID = re.compile(r"\d+")
_TERM = re.compile(r"\s*(?:([+-]?[0-9.]+(?:[ED]?[+-]?\d+)?)\s*\*\s*)?([A-Z][A-Z0-9_]*)\s*")


@dataclass(frozen=True)
class Subcase:
    """One subcase of the case control, defaults above the first ``SUBCASE`` included.

    ``spc``, ``mpc``, ``method``, ``suport1``: set ids (None when not chosen); ``k2gg`` ...
    ``b2pp``: the matrix selection as written (None when not chosen; see
    :meth:`selection`); ``title``, ``subtitle``, ``label``: text. ``where`` is
    ``file:line`` of the ``SUBCASE`` command (of the first case-control line for the
    implicit subcase 1), ``places`` that of each command read, by keyword.
    """

    id: int
    spc: int | None = None
    mpc: int | None = None
    method: int | None = None
    suport1: int | None = None
    k2gg: str | None = None
    m2gg: str | None = None
    b2gg: str | None = None
    k2pp: str | None = None
    m2pp: str | None = None
    b2pp: str | None = None
    title: str = ""
    subtitle: str = ""
    label: str = ""
    where: str = field(default="", compare=False)
    places: dict[str, str] = field(default_factory=dict, compare=False, repr=False)

    def selection(self, key: str) -> tuple[tuple[float, str], ...]:
        """``((factor, NAME), ...)`` of the matrix selection ``key`` (``"K2GG"``, ...)."""
        if key.upper() not in _MATRICES:
            raise ValueError(f"{key!r} is not a matrix selection (one of {', '.join(_MATRICES)})")
        text = getattr(self, key.lower())
        return () if text is None else _matrix_terms(text, self.places.get(key.upper(), self.where), key.upper())


@dataclass(frozen=True)
class CaseControl:
    """Executive and case control: ``sol`` (a number, a name, or None), the subcases in
    order, and the commands not read with their ``file:line`` (``ignored``)."""

    sol: int | str | None
    subcases: tuple[Subcase, ...]
    ignored: tuple[tuple[str, str], ...] = field(default=(), compare=False)
    where: str = field(default="", compare=False)

    def subcase(self, id: int | None = None) -> Subcase:
        """The subcase ``id`` (None: the first)."""
        if id is None:
            return self.subcases[0]
        for subcase in self.subcases:
            if subcase.id == id:
                return subcase
        ids = ", ".join(str(s.id) for s in self.subcases)
        raise BulkDataError(f"{self.where}: case control has no SUBCASE {id} (subcases: {ids})")

    def to_json(self) -> dict:
        """Plain data: SOL, the subcases' choices, the ignored commands."""
        keys = ("id",) + tuple(k.lower() for k in _SETS + _MATRICES + _TEXTS)
        return {
            "sol": self.sol,
            "subcases": [{k: getattr(s, k) for k in keys} | {"where": s.where} for s in self.subcases],
            "ignored": [list(item) for item in self.ignored],
        }


def _matrix_terms(text: str, where: str, key: str) -> tuple[tuple[float, str], ...]:
    """``((factor, NAME), ...)`` of a matrix selection ``name, factor*name, ...`` (QRG, K2GG)."""
    terms = []
    for part in text.strip().removeprefix("(").removesuffix(")").upper().split(","):
        m = _TERM.fullmatch(part)
        factor = None if m is None else m.group(1) or "1"
        value = None if factor is None else float(factor) if _INT.fullmatch(factor) else _real(factor)
        if value is None:
            raise BulkDataError(
                f"{where}: {key} = {text}: expected matrix names, e.g. KAAX or 1.5*KAAX, KBB, got {part.strip()!r}"
            )
        terms.append((value, m.group(2)))
    return tuple(terms)


def _parts(text: str) -> tuple[str, str, str]:
    """Keyword (upper case), describer in parentheses (upper case, or "") and value of a statement."""
    m = _STATEMENT.match(text)
    if m is None:
        return text.split()[0].upper(), "", text
    word, describer, value = m.groups()
    return word.upper(), (describer or "").upper().replace(" ", ""), value


def _keyword(word: str) -> str | None:
    """The keyword ``word`` stands for (first four characters at least), or None."""
    if word in _KEYWORDS:
        return word
    matches = [k for k in _KEYWORDS if len(word) >= 4 and k.startswith(word)]
    return matches[0] if len(matches) == 1 else None


def _statements(lines: list[tuple[str, int, str]]) -> list[tuple[str, int, str]]:
    """Non-blank statements without comments; a line ending with a comma is joined to the next."""
    out: list[tuple[str, int, str]] = []
    going_on = False
    for file, number, text in lines:
        text = text.split("$", 1)[0].rstrip()
        if not text.strip():
            continue
        if going_on:
            out[-1] = (out[-1][0], out[-1][1], out[-1][2] + text.strip())
        else:
            out.append((file, number, text))
        going_on = text.endswith(",") and _keyword(_parts(out[-1][2])[0]) not in _TEXTS
    return out


def _case_control(lines: list[tuple[str, int, str]]) -> CaseControl:
    """The case control of the lines before ``BEGIN BULK``."""
    cend = next((i for i, (_, _, t) in enumerate(lines) if t.split("$", 1)[0].strip().upper() == "CEND"), None)
    executive, case = (lines[:cend], lines[cend + 1:]) if cend is not None else ([], lines)
    state = _State()
    for file, number, text in _statements(executive):
        word = _parts(text)[0]
        if word == "SOL":
            state.solution(file, number, text)
        else:
            state.ignored.append((word, f"{file}:{number}"))
    for file, number, text in _statements(case):
        state.command(file, number, text)
    where = f"{lines[0][0]}:{lines[0][1]}" if lines else ""
    return CaseControl(state.sol, state.subcases(where), tuple(state.ignored), where)


class _State:
    """What the case control says so far: defaults, subcases, ignored commands."""

    def __init__(self):
        self.sol: int | str | None = None
        self.ignored: list[tuple[str, str]] = []
        self.defaults: dict = {}
        self.cases: list[tuple[int, str, dict]] = []  # (id, where, own commands)
        self.target: dict | None = self.defaults  # None: inside a SUBCOM/SYM/plot block
        self.plot = False

    def solution(self, file: str, number: int, text: str) -> None:
        value = _parts(text)[2].split(",")[0].strip().upper()
        if not value:
            raise BulkDataError(f"{_where(file, number, 'SOL')}: SOL without a solution number or name")
        self.sol = int(value) if _SET_ID.fullmatch(value) else value

    def command(self, file: str, number: int, text: str) -> None:
        word, describer, value = _parts(text)
        where = f"{file}:{number}"
        key = _keyword(word)
        if word == "OUTPUT" and any(k in describer for k in ("PLOT", "XY")):
            self.plot = True
        if self.plot or key is None or (key == "METHOD" and "FLUID" in describer):
            self.ignored.append((word + describer, where))
            if word in _OTHER_CASES:
                self.target = None
        elif key == "SUBCASE":
            self.subcase(file, number, value)
        elif key == "SOL":
            self.solution(file, number, text)
        elif self.target is not None:
            self.target[key] = (_value(key, value, file, number), where)

    def subcase(self, file: str, number: int, value: str) -> None:
        if not _SET_ID.fullmatch(value) or int(value) == 0:
            raise BulkDataError(f"{_where(file, number, 'SUBCASE')}: expected a subcase id (integer > 0), got {value!r}")
        ident = int(value)
        if self.cases and ident <= self.cases[-1][0]:
            raise BulkDataError(
                f"{_where(file, number, 'SUBCASE')}: subcase ids must increase: {ident} after {self.cases[-1][0]} "
                f"at {self.cases[-1][1]}"
            )
        self.cases.append((ident, f"{file}:{number}", {}))
        self.target = self.cases[-1][2]

    def subcases(self, where: str) -> tuple[Subcase, ...]:
        cases = self.cases or [(1, where, {})]
        out = []
        for ident, place, own in cases:
            chosen = {**self.defaults, **own}
            values = {k.lower(): v for k, (v, _) in chosen.items()}
            out.append(Subcase(ident, **values, where=place, places={k: w for k, (_, w) in chosen.items()}))
        return tuple(out)


def _value(key: str, value: str, file: str, number: int) -> int | str:
    """The value of a command read: a set id, a matrix selection (checked, kept as written) or a text."""
    if key in _TEXTS:
        return value
    if key in _SETS:
        if not _SET_ID.fullmatch(value) or int(value) == 0:
            raise BulkDataError(f"{_where(file, number, key)}: expected a set id (integer > 0), got {value!r}")
        return int(value)
    _matrix_terms(value, f"{file}:{number}", key)
    return value
