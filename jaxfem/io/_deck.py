"""The input file around the bulk data: INCLUDE files and the sections of a deck.

MSC Nastran QRG, "INCLUDE": the statement may appear anywhere in the input (file
management, executive and case control, bulk data); its file name, quoted or not, is
taken relative to the directory of the including file, else (a file not found there)
relative to that of the main deck, as decks written for Nastran's job directory expect;
a quoted name may be split over several lines (the pieces are joined without their
leading and trailing blanks). Logical symbols (``SYMBOL:path``) are not defined here.
INCLUDE files may include others; a file that includes itself, directly or not, is an
error. ``BEGIN BULK`` separates executive and case control from the bulk data (a deck
without it is all bulk data); ``ENDDATA`` ends the input. Every line keeps the file and
line number it comes from.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

from ._bulkdata import BulkDataError, _where
from ._fields import _SPACE

_BEGIN_BULK = re.compile(r"\s*BEGIN\s+BULK\b")
_ENDDATA = re.compile(r"\s*ENDDATA\b")
_INCLUDE = re.compile(r"\s*INCLUDE\b")
_LINE_END = re.compile(r"\r?\n")
_SYMBOL = re.compile(r"[A-Za-z_][A-Za-z0-9_]+:")  # two characters at least: not a drive letter

_Located = tuple[str, int, str]  # (file, line number, text)


def _head(text: str) -> str:
    """The line before its ``$`` comment, upper case."""
    return text.split("$", 1)[0].upper()


def _deck(text: str, name: str) -> tuple[list[_Located], list[_Located] | None, tuple[str, ...]]:
    """Bulk-data lines, the lines before ``BEGIN BULK`` (None without it) and the files read,
    in order; INCLUDE statements expanded, nothing read after ``ENDDATA``."""
    files = [name]
    path = Path(name)
    stack = ((path.resolve(), name),) if path.is_file() else ()
    lines: list[_Located] = []
    for located in _expand(text, name, stack, files, path.parent):
        if _ENDDATA.match(_head(located[2])):
            break
        lines.append(located)
    begin = next((i for i, (_, _, t) in enumerate(lines) if _BEGIN_BULK.match(_head(t))), None)
    if begin is None:
        return lines, None, tuple(files)
    return lines[begin + 1:], lines[:begin], tuple(files)


def _expand(text: str, file: str, stack: tuple, files: list[str], root: Path) -> Iterator[_Located]:
    """The lines of ``text`` (file ``file``), each INCLUDE replaced by its file's lines;
    ``root``: the directory of the main deck."""
    lines = _LINE_END.split(text.removeprefix("\ufeff"))
    i = 0
    while i < len(lines):
        if not _INCLUDE.match(_head(lines[i])):
            yield file, i + 1, lines[i]
            i += 1
            continue
        path, end = _include_path(lines, i, file)
        yield from _included(path, (file, i + 1), stack, files, root)
        i = end


def _include_path(lines: list[str], i: int, file: str) -> tuple[str, int]:
    """The file name of the INCLUDE statement on line ``i`` (0-based) and the index of the
    line after the statement (a quoted name may go on over several lines)."""
    where = _where(file, i + 1, "INCLUDE")
    rest = lines[i].lstrip(_SPACE)[len("INCLUDE"):].strip(_SPACE)
    if rest[:1] not in ("'", '"'):
        path = rest.split("$", 1)[0].strip(_SPACE)
        if not path:
            raise BulkDataError(f"{where}: INCLUDE without a file name")
        return path, i + 1
    quote, body, parts, j = rest[0], rest[1:], [], i
    while quote not in body:
        parts.append(body.strip(_SPACE))
        j += 1
        if j == len(lines):
            raise BulkDataError(f"{where}: the quoted file name is not closed (no {quote} up to the end of the file)")
        body = lines[j]
    end = body.index(quote)
    parts.append(body[:end].strip(_SPACE))
    tail = body[end + 1:].split("$", 1)[0].strip(_SPACE)
    if tail:
        raise BulkDataError(f"{_where(file, j + 1, 'INCLUDE')}: unexpected text {tail!r} after the file name")
    path = "".join(parts)
    if not path:
        raise BulkDataError(f"{where}: INCLUDE without a file name")
    return path, j + 1


def _included(path: str, at: tuple[str, int], stack: tuple, files: list[str], root: Path) -> Iterator[_Located]:
    """The lines of the file ``path`` included at ``at`` = (file, line)."""
    file, line = at
    where = _where(file, line, "INCLUDE")
    tried = [Path(file).parent / path]
    if (root / path).resolve() != tried[0].resolve():
        tried.append(root / path)
    target = next((t for t in tried if t.is_file()), tried[0])
    name, resolved = str(target), target.resolve()
    if any(resolved == r for r, _ in stack):
        chain = " -> ".join([n for _, n in stack] + [name])
        raise BulkDataError(f"{where}: include loop: {name} is already being read ({chain})")
    try:
        text = target.read_text(encoding="utf-8", errors="replace")
    except OSError as error:
        places = ", then ".join(str(t.resolve()) for t in tried)
        symbol = "; logical symbols (NAME:path) are not supported" if _SYMBOL.match(path) else ""
        raise BulkDataError(f"{where}: cannot read {path!r} (tried {places}): {error.strerror or error}{symbol}") from None
    if name not in files:
        files.append(name)
    yield from _expand(text, name, stack + ((resolved, name),), files, root)
