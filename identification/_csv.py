"""CSV tables of a test set-up (sensor lists, channel maps): read whole, every value checked.

One reader for every such table, so that each refuses the same things by name (file,
line, column): bytes that are not UTF-8, a missing column, a row with more fields than
the header or an empty field, an id that is not ASCII digits or out of range.
"""

from __future__ import annotations

import csv
import os
import re
from collections.abc import Iterator

_INTEGER = re.compile(r"[+-]?[0-9]+\Z")  # ASCII digits only: int() would take '١' or '１'
MAX_ID = 2**31 - 1  # ids are 32-bit integers in the test formats (UFF I10, Nastran I8)


def table_rows(path: str | os.PathLike, columns: tuple[str, ...], what: str) -> Iterator[tuple[int, dict[str, str]]]:
    """``(line, {column: text})`` for every non-blank row of a CSV file whose header names
    at least ``columns`` (case, spaces and a UTF-8 BOM ignored); texts stripped.

    ``what`` names the table in errors (``sensor list``). Raises ``ValueError`` naming the
    file (and line) for bytes that are not UTF-8, a missing column, more fields than the
    header, an empty field in ``columns``, and for a file without rows.
    """
    path = os.fspath(path)
    with open(path, "rb") as f:
        data = f.read()
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        line = err.object[:err.start].count(b"\n") + 1
        raise ValueError(f"{path}, line {line}: byte {err.object[err.start]:#04x} is not UTF-8 (save the "
                         f"{what} as UTF-8)") from None
    reader = csv.DictReader(text.splitlines(keepends=True), skipinitialspace=True)
    fields = [(name or "").strip().lower() for name in (reader.fieldnames or [])]
    missing = [c for c in columns if c not in fields]
    if missing:
        raise ValueError(f"{path}, line 1: missing column(s) {missing}; the {what}'s header must be "
                         f"{','.join(columns)}")
    reader.fieldnames = fields
    n = 0
    for row in reader:
        line = reader.line_num
        if None in row:
            raise ValueError(f"{path}, line {line}: more fields than the header's {len(fields)}")
        for name in columns:
            if row[name] is None or not row[name].strip():
                raise ValueError(f"{path}, line {line}: field {name!r} is empty")
        n += 1
        yield line, {name: (value or "").strip() for name, value in row.items()}
    if not n:
        raise ValueError(f"{path}: no rows under the header {','.join(columns)}")


def integer(text: str, where: str, low: int, high: int = MAX_ID, what: str = "an integer") -> int:
    """``text`` as an integer in ``low..high`` (ASCII digits); ``ValueError`` starting with ``where``."""
    if not _INTEGER.match(text):
        raise ValueError(f"{where}: {text!r} is not {what}")
    value = int(text)
    if not low <= value <= high:
        raise ValueError(f"{where}: {value} is outside {low}..{high:,}")
    return value
