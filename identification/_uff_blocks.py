"""The dataset structure of a universal file, checked independently of pyuff.

:func:`read_records` reads the datasets a caller wants through pyuff after checking that
pyuff splits the file into the datasets its own -1 delimiters give (:func:`_blocks`,
:func:`_check_split`), and that each record it parsed is whole (:func:`_check_record`):
a truncated file, a missing delimiter or a mangled line is named with its dataset and
line instead of merging, losing or misreading datasets.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import pyuff

from ._csv import MAX_ID


class _Block(NamedTuple):
    """One dataset of a universal file as its delimiters give it."""

    number: int  # the dataset number (58 for 58b)
    line: int  # line of the opening -1 (1-based; newline bytes inside binary data count)
    start: int  # byte offset of the opening -1
    end: int  # byte offset of the closing -1
    binary: bool


# A delimiter is a line holding -1 in columns 1-6 (format I6), blank after that.
_DELIMITER = re.compile(rb"^    -1[ \t]*\r?$", re.MULTILINE)
# After the binary data of a 58b the closing -1 follows at once (UFF 58b note), or on the
# next line as some writers put it.
_BINARY_CLOSE = re.compile(rb"(?:\r?\n)?(    -1)[ \t]*\r?(?:\n|\Z)")
_TEXT = re.compile(rb"\S")

def read_records(path: str, wanted: Callable[[int], bool] = lambda kind: True
                 ) -> tuple[list[tuple[int, dict]], list[_Block]]:
    """``[(dataset number in file, pyuff record), ...]`` of the datasets whose type is
    ``wanted``, and every dataset's :class:`_Block`; the file's split checked against its
    own delimiters (:func:`_blocks`, :func:`_check_split`) and each record checked whole
    (:func:`_check_record`). Raises ``ValueError`` naming the dataset and its line."""
    if not os.path.isfile(path):
        raise FileNotFoundError(f"no universal file {path}")
    with open(path, "rb") as handle:
        blocks = _blocks(handle.read(), path)
    uff = pyuff.UFF(path)
    types = [int(t) for t in uff.get_set_types()]
    _check_split(uff, types, blocks, path)
    records = []
    for i, kind in enumerate(types):
        if not wanted(kind):
            continue
        try:
            record = uff.read_sets(i)
        except Exception as err:  # pyuff raises bare Exception for any parse failure
            raise ValueError(f"{path}: dataset #{i + 1} (type {kind}) cannot be parsed (it starts at line "
                             f"{blocks[i].line}): {err}") from err
        _check_record(record, f"{path}: dataset #{i + 1} (type {kind}, from line {blocks[i].line})")
        records.append((i + 1, record))
    return records, blocks


def _blocks(data: bytes, path: str) -> list[_Block]:
    """Every dataset of a universal file from its delimiter structure, independently of pyuff.

    A dataset is a -1 line, a dataset number line (I6, then ``b`` for binary 58), its
    records and a closing -1 line; only blank lines lie between datasets. The binary data
    of a 58b is skipped by its size (:func:`_binary_end`), so bytes in it that look like a
    delimiter do not split it.

    Raises ``ValueError`` naming the dataset number and the line it starts at when a
    dataset is not closed (a truncated file), and naming the line of any text outside a
    dataset (a -1 line missing: pyuff would merge datasets or drop one).
    """
    blocks: list[_Block] = []
    counted = [0, 1]  # offset up to which lines are counted, line number there

    def line_at(offset: int) -> int:
        counted[1] += data.count(b"\n", counted[0], offset)
        counted[0] = offset
        return counted[1]

    def text_at(offset: int) -> str:
        end = data.find(b"\n", offset)
        return data[offset:len(data) if end < 0 else end].rstrip().decode("utf-8", errors="replace")[:40]

    def after(block: _Block | None) -> str:
        return (f"after dataset {block.number} that starts at line {block.line}" if block is not None
                else "before the first -1 delimiter")

    pos = 0
    while True:
        opening = _DELIMITER.search(data, pos)
        gap_end = len(data) if opening is None else opening.start()
        stray = _TEXT.search(data, pos, gap_end)
        if stray is not None:
            line = line_at(data.rfind(b"\n", 0, stray.start()) + 1)
            raise ValueError(f"{path}: line {line} ({text_at(stray.start())!r}) lies outside any dataset "
                             f"({after(blocks[-1] if blocks else None)}): a -1 delimiter line is missing there, "
                             "and datasets would be merged or lost")
        if opening is None:
            return blocks
        line = line_at(opening.start())
        head_start = opening.end() + 1
        head_end = data.find(b"\n", head_start)
        head_end = len(data) if head_end < 0 else head_end
        head = data[head_start:head_end].rstrip(b"\r")
        try:
            number = int(head[:6])
        except ValueError:
            number = None
        if head_start >= len(data) or number is None or number < 1:  # (another -1 reads as -1)
            got = "the end of the file" if head_start >= len(data) else repr(text_at(head_start).strip())
            raise ValueError(f"{path}: line {line + 1}: the -1 delimiter at line {line} is not followed by a "
                             f"dataset number (got {got}; {after(blocks[-1] if blocks else None)})")
        binary = head[6:7].lower() == b"b"
        if binary and number == 58:
            closing = _binary_end(data, head, head_end, line, path)
        else:
            closing = _DELIMITER.search(data, head_end)
            if closing is None:
                raise ValueError(f"{path}: dataset {number} that starts at line {line} is not closed by a -1 line: "
                                 "the file is truncated")
        end = closing.start(1 if closing.re is _BINARY_CLOSE else 0)
        blocks.append(_Block(number, line, opening.start(), end, binary))
        pos = closing.end()


def _binary_end(data: bytes, head: bytes, head_end: int, line: int, path: str) -> re.Match:
    """The closing -1 of a binary 58 (group 1), found from the size of its data.

    The size is that of record 7 of the ASCII header (ordinate data type 2, 4 real or 5,
    6 complex in 4 or 8 bytes; ``num_pts`` points; the abscissa stored too when uneven),
    or the byte count of the 58b line: pyuff 2.5.8 writes 8 × num_pts there whatever the
    data, so a file passes when either size is followed by the closing -1."""
    where = f"{path}: dataset 58b that starts at line {line}"
    try:
        n_ascii, n_bytes = (int(field) for field in head[7:].split()[2:4])
    except ValueError:
        raise ValueError(f"{where}: its header line does not give the number of ASCII lines and bytes (format "
                         "I6, A1, I6, I6, I12, I12)") from None
    pos, lines = head_end + 1, []
    for _ in range(n_ascii):
        newline = data.find(b"\n", pos)
        if newline < 0:
            raise ValueError(f"{where}: the file ends within its {n_ascii} header lines: the file is truncated")
        lines.append(data[pos:newline])
        pos = newline + 1
    sizes = [n_bytes]
    try:
        kind, n_points, even = (int(field) for field in lines[6].split()[:3])
        per_point = (1 if kind in (2, 4) else 2) + (0 if even else 1)
        sizes.insert(0, n_points * per_point * (4 if kind in (2, 5) else 8))
    except (IndexError, ValueError):
        pass  # record 7 unreadable: pyuff names it when it parses the record
    for size in dict.fromkeys(sizes):
        closing = _BINARY_CLOSE.match(data, pos + size) if pos + size <= len(data) else None
        if closing is not None:
            return closing
    if pos + sizes[0] > len(data):
        raise ValueError(f"{where}: its header gives {sizes[0]} bytes of binary data, the file holds "
                         f"{len(data) - pos} after the header: the file is truncated")
    expected = " or ".join(str(size) for size in dict.fromkeys(sizes))
    raise ValueError(f"{where}: no -1 delimiter right after its {expected} bytes of binary data: the file is "
                     "truncated or the sizes in its header are wrong")


def _check_split(uff: pyuff.UFF, types: list[int], blocks: list[_Block], path: str) -> None:
    """Raise ``ValueError`` naming the datasets pyuff missed unless it split the file into
    the datasets of :func:`_blocks`.

    pyuff takes any ``    -1`` followed by a line end as a delimiter (one at the end of a
    data line, or inside binary data) and pairs them in order, so a stray one shifts every
    later dataset."""
    found = [int(t) for t in types]
    spans = getattr(uff, "_block_ind", None)  # pyuff's byte offsets: opening -1, one before the closing -1
    if spans is not None and len(spans) == len(found):
        found_at = {(int(start), int(end) + 1, kind) for (start, end), kind in zip(np.reshape(spans, (-1, 2)), found)}
        missed = [(i, b) for i, b in enumerate(blocks) if (b.start, b.end, b.number) not in found_at]
        agree = not missed and len(found) == len(blocks)
    else:  # pyuff's internals changed: compare the sequences of dataset numbers
        agree = found == [b.number for b in blocks]
        missed = [] if agree else [(i, b) for i, b in enumerate(blocks) if i >= len(found) or found[i] != b.number]
    if agree:
        return
    listing = ", ".join(f"#{i + 1} (type {b.number}{'b' if b.binary else ''}, line {b.line})" for i, b in missed[:5])
    listing += f" and {len(missed) - 5} more" if len(missed) > 5 else ""
    raise ValueError(f"{path}: the file's -1 delimiters give {len(blocks)} datasets, pyuff finds {len(found)}"
                     + (f" and misses {listing}" if missed else "")
                     + ": a line ending in '    -1', or such bytes inside binary data, confuses its split; "
                     "the file cannot be read without losing datasets")


# per dataset type: the per-node (or per-line) arrays that must be equally long, and the id fields
_ARRAYS = {15: ("node_nums", "def_cs", "disp_cs", "x", "y", "z"), 2411: ("node_nums", "def_cs", "disp_cs", "x", "y", "z"),
           55: ("node_nums", "r1", "r2", "r3", "r4", "r5", "r6"), 58: ("x", "data")}
_IDS = ("node_nums", "def_cs", "disp_cs", "mode_n", "rsp_node", "ref_node", "cs_num", "ref_cs_num", "CS_sys_labels")


def _check_record(record: dict, where: str) -> None:
    """What pyuff parsed from a record is whole: its per-node arrays equally long (a
    mangled fixed-format line gives ragged ones), its ids integers in 0..2³¹−1, and a
    dataset 58 of a defined ordinate type (2, 4 real; 5, 6 complex) with its data."""
    if int(record.get("type", 0)) == 58:
        kind = record.get("ord_data_type")
        if kind not in (2, 4, 5, 6):
            raise ValueError(f"{where}: record 7's ordinate data type is {kind!r}; UFF 58 defines 2, 4 (real) "
                             "and 5, 6 (complex): its data cannot be read")
        if "x" not in record or "data" not in record:
            raise ValueError(f"{where}: no data values were parsed from it")
    lengths = {key: len(np.atleast_1d(record[key])) for key in _ARRAYS.get(int(record.get("type", 0)), ())
               if key in record}
    if len(set(lengths.values())) > 1:
        raise ValueError(f"{where}: its fields have different lengths {lengths}: a line of it is malformed")
    for key in _IDS:
        if key in record:
            try:
                ids = np.atleast_1d(np.asarray(record[key], dtype=np.float64))
            except (TypeError, ValueError, OverflowError):
                raise ValueError(f"{where}: {key} is not a list of numbers") from None
            bad = ~np.isfinite(ids) | (ids != np.round(ids)) | (np.abs(ids) > MAX_ID)
            if np.any(bad):
                raise ValueError(f"{where}: {key} {ids[bad][0]:.10g} is not an integer within ±{MAX_ID}")
