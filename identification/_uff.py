"""Universal File Format (UFF) reading through pyuff, and the unit codes it shares with writing.

Datasets: 164 (units), 18 and 2420 (coordinate systems), 15 and 2411 (nodes), 55 (mode
shapes at nodes), 58/58b (FRFs and coherence). Everything read is converted to SI with the factors of dataset 164, which
give file units per SI unit (SI = file value / factor; a file in mm has length factor
1000), using the unit exponents of the UFF 58 table (Addendum A):

- coordinates and translational shape values: ÷ length factor (rotations are in rad);
- generalised (modal) masses, force/length: × length / force;
- FRF values, response/excitation: translational response ÷ length, excitation force
  × force, excitation moment × length·force (so a receptance in mm/N is ÷ 1000).

Coordinate systems: a node's coordinates are given in its definition system and its
measured components (shape values, FRF directions) along the axes of its displacement
system. Rectangular, cylindrical (r, θ, z) and spherical (r, θ from +z, φ from +x in the
xy plane; angles in degrees) systems are supported. Dataset 18 defines a system by its
origin, a point on +x and a point in the +xz plane, given in a reference system; in
dataset 2420 rows 1–3 of the transformation matrix are the local x, y, z axes in global
coordinates and row 4 the origin. Coordinates are converted to global, and every sensor
direction becomes the global direction of its local axis at the node (a skew direction
when the system is rotated).

Frequencies are in Hz in every unit system. :func:`write_uff`
(:mod:`identification._uff_write`) converts from SI with the same factors.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import numpy as np
import pyuff

from ._csv import MAX_ID
from ._data import FRFData, ModalData, Sensors
from ._uff_lines import trace_lines

LENGTH_UNITS = {"m": 1.0, "mm": 1000.0, "cm": 100.0, "in": 1.0 / 0.0254}  # file units per metre

# Unit codes of dataset 164 and their factors (file units per SI unit): length, force.
_LBF = 1.0 / 4.4482216152605
_KGF = 1.0 / 9.80665
_UNIT_CODES = {
    1: ("SI: m, N", 1.0, 1.0),
    2: ("BG: ft, lbf", 1.0 / 0.3048, _LBF),
    3: ("MG: m, kgf", 1.0, _KGF),
    4: ("BA: ft, poundal", 1.0 / 0.3048, 1.0 / 0.138254954376),
    5: ("MM: mm, mN", 1000.0, 1000.0),
    6: ("CM: cm, cN", 100.0, 100.0),
    7: ("IN: in, lbf", 1.0 / 0.0254, _LBF),
    8: ("GM: mm, kgf", 1000.0, _KGF),
}
_USER_CODE = 9
_FACTOR_RTOL = 1e-4  # factors written with few digits still match their unit code
_AXIS_RTOL = 1e-9  # two FRF records share a frequency axis
_MOTION_TYPES = (0, 1, 8, 11, 12)  # unknown, general, displacement, velocity, acceleration
_FRF_SPEC_TYPES = {8: "receptance", 11: "mobility", 12: "accelerance"}
_FRF_CODES = {kind: code for code, kind in _FRF_SPEC_TYPES.items()}
_FORCE_SPEC_TYPES = (0, 9, 13)  # unknown (a type-4 function is per unit force), reaction, excitation
_FRF, _COHERENCE = 4, 6  # dataset 58 function types
_NORMAL_MODE, _COMPLEX_MODES = 2, (3, 7)  # dataset 55 analysis types
_READ = (15, 18, 55, 58, 164, 2411, 2420)
# header (151), model header (2400), elements (2412), trace lines (82, read_trace_lines), function
# qualifiers of dataset 58 (1858), groups (2429, 2467): they describe, they hold no measured data
_DESCRIPTIVE = (82, 151, 1858, 2400, 2412, 2429, 2467)
_SYSTEM_TYPES = {0: "rectangular", 1: "cylindrical", 2: "spherical"}
_ORTHO_TOL = 1e-6  # axes written with 7 digits are still orthonormal
_SI = {"code": 1, "description": "SI", "length": 1.0, "force": 1.0, "temperature": 1.0, "temperature_offset": 273.15}


def read_uff(path: str | os.PathLike, *, length_units: str | None = None,
             dof_map: dict[str, tuple[int, int]] | None = None) -> dict:
    """Read nodes, units, modes and FRFs from a universal file, in SI.

    ``length_units`` ("m", "mm", "cm" or "in"): the unit of the file's lengths when it
    has no dataset 164 (the exporter did not say); it overrides a dataset 164, with a
    ``UserWarning``, when the two differ. Forces stay as the file or SI says.

    **Returns:** a dict with

    - ``"nodes"``: {node id: xyz (3,) in m, global axes} from datasets 15 and 2411,
      transformed from their definition systems (datasets 18 and 2420);
    - ``"units"``: the dataset-164 system: ``code``, ``description``, ``length``,
      ``force``, ``temperature``, ``temperature_offset`` (file units per SI unit), and
      ``declared``: False when the file has no dataset 164 (SI is then assumed, with a
      ``UserWarning``, unless ``length_units`` is given);
    - ``"systems"``: {system label: {"type": "rectangular" | "cylindrical" |
      "spherical", "axes": (3, 3) rows = local x, y, z in global, "origin": (3,) m}} of
      the file's coordinate systems;
    - ``"modes"``: :class:`ModalData` of all dataset-55 normal (analysis type 2) and
      complex (3, 7) modes, or None. Sensors are the global components of each node
      (3, or 6 with rotations); a component that is zero in every mode counts as not
      measured (UFF note: unused values are written as 0) and is dropped. Frequency:
      the record's frequency, or |λ|/2π of a complex eigenvalue λ with ζ = −Re λ/|λ|;
      damping: the viscous ratio (a hysteretic value is not converted and warned about);
      generalised masses only when every mode gives one;
    - ``"frfs"``: :class:`FRFData` of all dataset-58 FRF records (function type 4),
      with the coherence records (type 6) when every FRF has one, or None. The kind
      follows the ordinate type: displacement, velocity, acceleration.
    - ``"time"``: :class:`TimeHistories` of all dataset-58 time records (function type
      1: force, displacement, velocity, acceleration channels, in SI), or None.
    - ``"lines"``: the trace lines of datasets 82 as node-id pairs (:func:`read_trace_lines`).

    ``dof_map``: {channel name: (node, direction code)} for channel-only records (node
    0, direction 0; the name is the response or reference entity name, or ID line 1 of
    a time record); a row overrides the record's DoF. Without a row for such a channel,
    or with a row naming no channel of the file, ``ValueError`` names the channels.

    Sensor directions are global: a component measured along a local axis of the
    node's displacement system becomes that axis in global coordinates.

    Every dataset between -1 delimiters is accounted for: it is read, or named with its
    line in a ``UserWarning`` when its type holds nothing jaxfem reads (or pyuff does not
    know it). Raises ``ValueError`` naming the dataset number and the line it starts at
    for a dataset not closed by a -1 line (a truncated file) and for text outside any
    dataset (a -1 line missing), and naming the datasets pyuff would merge or lose when
    its split of the file differs.

    Raises ``ValueError`` naming the record and item for: an unreadable dataset,
    contradicting unit records, a coordinate system that is not orthonormal, degenerate,
    of unknown type or defined twice differently, nodes defined twice differently, a mode referencing
    a node absent from the node datasets, NaN values, a DoF twice in one mode, modes
    with different DoF sets, FRF records on different frequency axes, duplicate or
    missing (output, input) pairs, and FRFs of mixed or unknown kinds.
    """
    path = os.fspath(path)
    records, blocks = read_records(path)
    by_type: dict[int, list[tuple[int, dict]]] = {}
    for number, record in records:
        by_type.setdefault(int(record["type"]), []).append((number, record))
    unread = {kind: [n for n, _ in records] for kind, records in by_type.items()
              if kind not in _READ and kind not in _DESCRIPTIVE}
    if unread:  # types pyuff does not know land here too: it returns them as {"type": number}
        listing = "; ".join(f"type {kind} (#{', #'.join(str(n) for n in numbers[:5])}"
                            + (f" and {len(numbers) - 5} more" if len(numbers) > 5 else "") + ")"
                            + f" at line{'s' if len(numbers) > 1 else ''} "
                            + ", ".join(str(blocks[n - 1].line) for n in numbers[:5])
                            for kind, numbers in sorted(unread.items()))
        warnings.warn(f"{path}: datasets not read, ignored: {listing}; jaxfem reads modes from dataset 55 and FRFs "
                      "and time histories from 58" + (" (2414 holds analysis results: export them as 55)"
                                                      if 2414 in unread else ""), stacklevel=2)
    units = _units(by_type.get(164, []), path, length_units)
    systems = _systems(by_type.get(18, []), by_type.get(2420, []), units["length"], path)
    node_records = sorted(by_type.get(15, []) + by_type.get(2411, []), key=lambda record: record[0])
    nodes, frames = _nodes(node_records, units["length"], systems, path)
    modes = _modes(by_type.get(55, []), nodes, units, path)
    frfs = _frfs(by_type.get(58, []), units, path, dof_map)
    if frames and modes is not None:
        modes = eqx.tree_at(lambda m: m.sensors, modes, _global(modes.sensors, frames))
    if frames and frfs is not None:
        frfs = eqx.tree_at(lambda f: (f.outputs, f.inputs), frfs,
                           (_global(frfs.outputs, frames), _global(frfs.inputs, frames)))
    time = _time_histories(by_type.get(58, []), units, path, dof_map)
    local = sorted({int(g) for g in time.nodes} & set(frames)) if time is not None else []
    if local:
        warnings.warn(f"{path}: time channels at nodes {local} measure along the local axes of their displacement "
                      "systems; FRFs made from them keep those local direction codes", stacklevel=2)
    return {
        "nodes": nodes,
        "units": units,
        "systems": {label: {"type": _SYSTEM_TYPES[sys.kind], "axes": sys.axes, "origin": sys.origin}
                    for label, sys in systems.items() if label != 0},
        "modes": modes,
        "frfs": frfs,
        "lines": trace_lines(by_type.get(82, []), path),
        "time": time,
    }


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


def read_trace_lines(path: str | os.PathLike) -> list[tuple[int, int]]:
    """The trace lines (datasets 82) of a universal file as node-id pairs, each once
    (:func:`identification._uff_lines.trace_lines`); empty when it has none. The file is
    checked whole as by :func:`read_uff` (:func:`read_records`)."""
    path = os.fspath(path)
    return trace_lines(read_records(path, lambda kind: kind == 82)[0], path)


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


def _units(records: list[tuple[int, dict]], path: str, length_units: str | None) -> dict:
    if length_units is not None and length_units not in LENGTH_UNITS:
        raise ValueError(f"length units {length_units!r}: use one of {', '.join(LENGTH_UNITS)}")
    if not records:
        if length_units is None:
            warnings.warn(f"{path}: no units dataset (164); SI units assumed", stacklevel=3)
            return dict(_SI, declared=False)
        return dict(_SI, length=LENGTH_UNITS[length_units], declared=False,
                    description=f"lengths in {length_units} (given), forces in N")
    units = _declared(records, path)
    if length_units is not None and not math.isclose(units["length"], LENGTH_UNITS[length_units],
                                                     rel_tol=_FACTOR_RTOL):
        warnings.warn(f"{path}: the units dataset gives {units['length']:.6g} length units per metre; lengths "
                      f"taken in {length_units} as given instead", stacklevel=3)
        units["length"] = LENGTH_UNITS[length_units]
    return units


def _declared(records: list[tuple[int, dict]], path: str) -> dict:
    (first_number, first), *others = records
    units = {
        "code": int(first["units_code"]),
        "description": str(first["units_description"]).strip(),
        "length": float(first["length"]),
        "force": float(first["force"]),
        "temperature": float(first["temp"]),
        "temperature_offset": float(first["temp_offset"]),
        "declared": True,
    }
    for number, record in others:
        if (int(record["units_code"]), record["length"], record["force"], record["temp"], record["temp_offset"]) != (
            units["code"], units["length"], units["force"], units["temperature"], units["temperature_offset"]
        ):
            raise ValueError(
                f"{path}: units dataset #{number} (code {record['units_code']}, length {record['length']}, force "
                f"{record['force']}) contradicts units dataset #{first_number} (code {units['code']}, length "
                f"{units['length']}, force {units['force']})"
            )
    for name in ("length", "force"):
        if not (math.isfinite(units[name]) and units[name] > 0):
            raise ValueError(f"{path}: units dataset #{first_number}: {name} factor {units[name]} is not positive")
    if units["code"] in _UNIT_CODES:
        label, length, force = _UNIT_CODES[units["code"]]
        if not (math.isclose(units["length"], length, rel_tol=_FACTOR_RTOL)
                and math.isclose(units["force"], force, rel_tol=_FACTOR_RTOL)):
            raise ValueError(
                f"{path}: units dataset #{first_number} declares code {units['code']} ({label}) but gives length "
                f"factor {units['length']} and force factor {units['force']}; that code means {length:.10g} and "
                f"{force:.10g} (file units per SI unit)"
            )
    return units


class _System(NamedTuple):
    kind: int  # 0 rectangular, 1 cylindrical, 2 spherical
    axes: np.ndarray  # (3, 3): rows are the local x, y, z axes in global coordinates
    origin: np.ndarray  # (3,) m, global
    where: str


_GLOBAL = _System(0, np.eye(3), np.zeros(3), "global")


def _systems(records18: list, records2420: list, length: float, path: str) -> dict[int, _System]:
    """Coordinate systems of datasets 2420 (matrix) and 18 (three points in a reference
    system, resolved in order of reference), in global coordinates; 0 is global."""
    systems = {0: _GLOBAL}

    def add(label: int, system: _System) -> None:
        if system.kind not in _SYSTEM_TYPES:
            raise ValueError(f"{path}: {system.where}: coordinate system {label} has type {system.kind} (expected "
                             "0 rectangular, 1 cylindrical or 2 spherical)")
        old = systems.get(label)
        if old is not None and not (old.kind == system.kind and np.allclose(old.axes, system.axes, atol=_ORTHO_TOL)
                                    and np.allclose(old.origin, system.origin, rtol=1e-9, atol=1e-12)):
            raise ValueError(f"{path}: coordinate system {label} of {system.where} differs from {old.where}")
        systems[label] = system

    for number, r in records2420:
        for label, kind, matrix in zip(r["CS_sys_labels"], r["CS_types"], r["CS_matrices"]):
            m = np.asarray(matrix, dtype=np.float64)
            where = f"dataset #{number}"
            if m.shape != (4, 3) or not np.all(np.isfinite(m)):
                raise ValueError(f"{path}: {where}: coordinate system {int(label)}: matrix {m.tolist()} is not 4 "
                                 "finite rows of 3")
            if not np.allclose(m[:3] @ m[:3].T, np.eye(3), atol=_ORTHO_TOL):
                raise ValueError(f"{path}: {where}: coordinate system {int(label)}: rows 1-3 of the matrix "
                                 f"{m[:3].tolist()} are not orthonormal axes")
            add(int(label), _System(int(kind), m[:3], m[3] / length, where))
    pending = {}
    for number, r in records18:
        for i, label in enumerate(np.asarray(r["cs_num"]).astype(int).tolist()):
            pending[label] = (number, i, r)
    while pending:
        ready = [label for label, (_, i, r) in pending.items() if int(r["ref_cs_num"][i]) in systems]
        if not ready:
            raise ValueError(f"{path}: coordinate systems {sorted(pending)} (dataset 18) refer to systems "
                             f"{sorted({int(r['ref_cs_num'][i]) for _, i, r in pending.values()})} that are not "
                             "defined (or refer to each other in a circle)")
        for label in ready:
            number, i, r = pending.pop(label)
            where = f"dataset #{number}"
            if int(r["method"][i]) != 1:
                raise ValueError(f"{path}: {where}: coordinate system {label}: method of definition "
                                 f"{int(r['method'][i])} (only 1: origin, +x axis, +xz plane)")
            ref = systems[int(r["ref_cs_num"][i])]
            o, xp, zp = (_to_global(ref, np.asarray(r[k][i], dtype=np.float64).reshape(1, 3), length)[0]
                         for k in ("ref_o", "x_point", "xz_point"))
            x, y = xp - o, np.cross(zp - o, xp - o)  # y is normal to the xz plane
            if not (np.linalg.norm(x) > 0 and np.linalg.norm(y) > 1e-9 * np.linalg.norm(x) * np.linalg.norm(zp - o)):
                raise ValueError(f"{path}: {where}: coordinate system {label}: origin, +x point and +xz point "
                                 f"{[o.tolist(), xp.tolist(), zp.tolist()]} m do not define axes")
            x, y = x / np.linalg.norm(x), y / np.linalg.norm(y)
            add(label, _System(int(r["cs_type"][i]), np.stack([x, y, np.cross(x, y)]), o, where))
    return systems


def _to_global(system: _System, coords: np.ndarray, length: float) -> np.ndarray:
    """Global xyz [m] of file coordinates (n, 3) in ``system``: x, y, z; r, θ, z; or
    r, θ, φ (angles in degrees, lengths in file units)."""
    c = np.asarray(coords, dtype=np.float64)
    if system.kind == 1:
        t = np.radians(c[:, 1])
        local = np.column_stack([c[:, 0] * np.cos(t), c[:, 0] * np.sin(t), c[:, 2]]) / length
    elif system.kind == 2:
        t, f = np.radians(c[:, 1]), np.radians(c[:, 2])
        local = c[:, :1] * np.column_stack([np.sin(t) * np.cos(f), np.sin(t) * np.sin(f), np.cos(t)]) / length
    else:
        local = c / length
    return system.origin + local @ system.axes


def _frame(system: _System, x: np.ndarray) -> np.ndarray:
    """Rows: the global directions of the local components 1, 2, 3 at global point ``x``
    (the axes; for curvilinear systems e_r, e_θ, e_z or e_r, e_θ, e_φ there)."""
    if system.kind == 0:
        return system.axes
    p = (x - system.origin) @ system.axes.T
    f = math.atan2(p[1], p[0])
    if system.kind == 1:
        local = np.array([[math.cos(f), math.sin(f), 0.0], [-math.sin(f), math.cos(f), 0.0], [0.0, 0.0, 1.0]])
    else:
        t = math.atan2(math.hypot(p[0], p[1]), p[2])
        local = np.array([[math.sin(t) * math.cos(f), math.sin(t) * math.sin(f), math.cos(t)],
                          [math.cos(t) * math.cos(f), math.cos(t) * math.sin(f), -math.sin(t)],
                          [-math.sin(f), math.cos(f), 0.0]])
    return local @ system.axes


def _nodes(records: list[tuple[int, dict]], length: float, systems: dict[int, _System],
           path: str) -> tuple[dict[int, np.ndarray], dict[int, np.ndarray]]:
    """Global node coordinates [m], and the displacement frames of nodes whose measured
    directions are not the global axes."""
    nodes: dict[int, np.ndarray] = {}
    frames: dict[int, np.ndarray] = {}
    where: dict[int, int] = {}
    undefined: dict[int, list[int]] = {}
    for number, record in records:
        ids = np.asarray(record["node_nums"], dtype=np.float64).astype(np.int64)
        raw = np.column_stack([record["x"], record["y"], record["z"]]).astype(np.float64)
        used = [np.asarray(record[k], dtype=np.float64).astype(np.int64) for k in ("def_cs", "disp_cs")]
        for label in set(used[0].tolist()) | set(used[1].tolist()):
            if label not in systems:
                undefined.setdefault(label, []).extend(ids[(used[0] == label) | (used[1] == label)].tolist())
        for g, c, d, x in zip(ids.tolist(), used[0].tolist(), used[1].tolist(), raw):
            if not np.all(np.isfinite(x)):
                raise ValueError(f"{path}: node dataset #{number}: node {g} has coordinates {x.tolist()}")
            x = _to_global(systems.get(c, _GLOBAL), x.reshape(1, 3), length)[0]
            if g in nodes and not np.allclose(nodes[g], x, rtol=1e-12, atol=0.0):
                raise ValueError(
                    f"{path}: node {g} is at {nodes[g].tolist()} m in dataset #{where[g]} but at {x.tolist()} m "
                    f"in dataset #{number}"
                )
            nodes[g], where[g] = x, number
            frame = _frame(systems.get(d, _GLOBAL), x)
            if not np.allclose(frame, np.eye(3), rtol=0.0, atol=1e-12):
                frames[g] = frame
    if undefined:
        listing = "; ".join(f"system {label}: nodes {sorted(set(g))}" for label, g in sorted(undefined.items()))
        warnings.warn(f"{path}: nodes name coordinate systems that the file does not define (datasets 18/2420), "
                      f"taken as global: {listing}", stacklevel=3)
    return nodes, frames


def _global(sensors: Sensors, frames: dict[int, np.ndarray]) -> Sensors:
    """``sensors`` with each direction, given in its node's displacement frame, in global axes."""
    directions = np.array([d @ frames[int(g)] if int(g) in frames else d
                           for g, d in zip(sensors.nodes, sensors.directions)]).reshape(-1, 3)
    return Sensors.from_vectors(sensors.nodes, directions, sensors.rotational)


def _modes(records: list[tuple[int, dict]], nodes: dict, units: dict, path: str) -> ModalData | None:
    modes = [(n, r) for n, r in records if r["analysis_type"] in (_NORMAL_MODE, *_COMPLEX_MODES)]
    skipped = sorted({int(r["analysis_type"]) for _, r in records} - {_NORMAL_MODE, *_COMPLEX_MODES})
    if skipped:
        warnings.warn(f"{path}: dataset-55 records of analysis type(s) {skipped} are not modes; ignored", stacklevel=3)
    if not modes:
        return None
    length = units["length"]
    columns, freqs, zetas, masses, ids = [], [], [], [], []
    hysteretic = []
    for number, r in modes:
        mode = int(r["mode_n"])
        name = f"{path}: dataset #{number} (mode {mode})"
        if r["spec_data_type"] not in _MOTION_TYPES:
            raise ValueError(
                f"{name}: specific data type {r['spec_data_type']} is not a motion (expected 0, 1, 8, 11, 12)"
            )
        if r["data_ch"] not in (2, 3):
            raise ValueError(f"{name}: data characteristic {r['data_ch']} is not a 3- or 6-DoF vector")
        n_comp = 3 if r["data_ch"] == 2 else 6
        node_ids = np.asarray(r["node_nums"], dtype=np.int64)
        values = np.column_stack([np.asarray(r[f"r{c}"]) for c in range(1, n_comp + 1)])
        values[:, :3] = values[:, :3] / length
        uniq, counts = np.unique(node_ids, return_counts=True)
        if np.any(counts > 1):
            raise ValueError(f"{name}: node(s) {uniq[counts > 1].tolist()} appear twice (duplicate DoFs)")
        if nodes:
            absent = [int(g) for g in node_ids if int(g) not in nodes]
            if absent:
                raise ValueError(f"{name}: node(s) {absent} are not defined in the node datasets (15/2411)")
        dofs = [(int(g), c) for g in node_ids for c in range(1, n_comp + 1)]
        column = dict(zip(dofs, values.reshape(-1)))
        bad = [dof for dof, v in column.items() if not np.isfinite(v)]
        if bad:
            raise ValueError(f"{name}: value {column[bad[0]]} at DoF {_label(*bad[0])}")
        if r["analysis_type"] == _NORMAL_MODE:
            freqs.append(float(r["freq"]))
            zetas.append(float(r["modal_damp_vis"]))
            masses.append(float(r["modal_m"]) * length / units["force"])
            if r["modal_damp_his"] != 0 and r["modal_damp_vis"] == 0:
                hysteretic.append(mode)
        else:
            lam = complex(r["eig"])
            if not (np.isfinite(lam) and abs(lam) > 0):
                raise ValueError(f"{name}: eigenvalue {lam} is not finite and non-zero")
            freqs.append(abs(lam) / (2 * np.pi))
            zetas.append(-lam.real / abs(lam))
            masses.append(0.0)
        columns.append((name, column))
        ids.append(mode)
    if hysteretic:
        warnings.warn(
            f"{path}: modes {hysteretic} give only a hysteretic damping value, which is not converted; their "
            "viscous damping ratio is 0",
            stacklevel=3,
        )
    order = list(dict.fromkeys(dof for _, column in columns for dof in column))
    for name, column in columns:
        missing = [_label(*dof) for dof in order if dof not in column]
        if missing:
            raise ValueError(f"{name} lacks DoFs {missing} present in other modes (shapes must be complete)")
    shapes = np.array([[column[dof] for _, column in columns] for dof in order])
    measured = np.any(shapes != 0, axis=1)
    sensors = Sensors.from_components([g for g, _ in order], [c for _, c in order])
    sensors = Sensors(sensors.nodes[measured], sensors.directions[measured], sensors.rotational[measured])
    masses = np.asarray(masses)
    if np.any(masses > 0) and not np.all(masses > 0):
        warnings.warn(
            f"{path}: only modes {np.asarray(ids)[masses > 0].tolist()} give a modal mass; generalised masses dropped",
            stacklevel=3,
        )
    try:
        return ModalData(
            np.asarray(freqs),
            shapes[measured],
            sensors,
            damping_ratios=np.asarray(zetas),
            generalised_masses=masses if np.all(masses > 0) else None,
            mode_ids=np.asarray(ids),
        )
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err


def _label(node: int, code: int) -> str:
    return Sensors.from_components([node], [code]).labels[0]


def _frf_factor(units: dict, response: int, excitation: int) -> float:
    """File-to-SI factor of a response/excitation ratio (UFF 58 Addendum A exponents)."""
    numerator = units["length"] if abs(response) <= 3 else 1.0
    denominator = units["force"] if abs(excitation) <= 3 else units["force"] * units["length"]
    return denominator / numerator


def _frfs(records: list[tuple[int, dict]], units: dict, path: str, dof_map: dict | None = None) -> FRFData | None:
    records = _mapped(records, dof_map, path, (_FRF, _COHERENCE))  # channel-only records get their DoFs
    skipped = sorted({int(r["func_type"]) for _, r in records} - {_FRF, _COHERENCE, _TIME})  # _TIME: _time_histories
    if skipped:
        warnings.warn(f"{path}: dataset-58 function type(s) {skipped} are not FRFs or coherence; ignored", stacklevel=3)
    groups: dict[int, dict[tuple[int, int, int, int], tuple[str, dict]]] = {_FRF: {}, _COHERENCE: {}}
    axis = None
    kind = None
    for number, r in records:
        func = int(r["func_type"])
        if func not in groups:
            continue
        key = (int(r["rsp_node"]), int(r["rsp_dir"]), int(r["ref_node"]), int(r["ref_dir"]))
        if key[1] == 0 or key[3] == 0 or abs(key[1]) > 6 or abs(key[3]) > 6:
            unnamed = " (and no channel name for a DoF map)" if 0 in (key[1], key[3]) else ""
            raise ValueError(f"{path}: dataset #{number}: direction codes {key[1]}, {key[3]} are not ±1..6{unnamed}")
        name = f"dataset #{number} ({_label(key[0], key[1])} / {_label(key[2], key[3])})"
        if key in groups[func]:
            raise ValueError(f"{path}: {name} repeats {groups[func][key][0]}")
        x = np.asarray(r["x"], dtype=np.float64)
        if axis is None:
            axis = (name, x)
        elif len(x) != len(axis[1]) or not np.allclose(x, axis[1], rtol=_AXIS_RTOL, atol=0.0):
            raise ValueError(f"{path}: {name} has a frequency axis different from {axis[0]}")
        data = np.asarray(r["data"])
        if func == _FRF:
            record_kind = _FRF_SPEC_TYPES.get(int(r["ordinate_spec_data_type"]))
            if record_kind is None:
                raise ValueError(
                    f"{path}: {name}: ordinate type {r['ordinate_spec_data_type']} is not displacement (8), "
                    "velocity (11) or acceleration (12)"
                )
            if int(r["orddenom_spec_data_type"]) not in _FORCE_SPEC_TYPES:
                raise ValueError(f"{path}: {name}: denominator type {r['orddenom_spec_data_type']} is not a force")
            if kind is None:
                kind = (name, record_kind)
            elif record_kind != kind[1]:
                raise ValueError(f"{path}: {name} is a {record_kind} but {kind[0]} is a {kind[1]}")
            data = data.astype(np.complex128) * _frf_factor(units, key[1], key[3])
        if func == _COHERENCE:
            data = np.real(data)
        bad = np.flatnonzero(~np.isfinite(data))
        if len(bad):
            raise ValueError(f"{path}: {name}: value {data[bad[0]]} at {x[bad[0]]} Hz")
        groups[func][key] = (name, data)
    frfs, coherence = groups[_FRF], groups[_COHERENCE]
    if not frfs:
        if coherence:
            warnings.warn(f"{path}: coherence records without FRFs; ignored", stacklevel=3)
        return None
    outputs = list(dict.fromkeys(k[:2] for k in frfs))
    inputs = list(dict.fromkeys(k[2:] for k in frfs))
    missing = [f"{_label(*o)} / {_label(*i)}" for o in outputs for i in inputs if o + i not in frfs]
    if missing:
        raise ValueError(f"{path}: FRFs missing for (output / input) pairs {missing}")
    values = np.stack([np.stack([frfs[o + i][1] for i in inputs], axis=-1) for o in outputs], axis=1)
    coh = None
    if coherence:
        if set(coherence) == set(frfs):
            coh = np.stack([np.stack([coherence[o + i][1] for i in inputs], axis=-1) for o in outputs], axis=1)
        else:
            warnings.warn(f"{path}: coherence is not given for every FRF; ignored", stacklevel=3)
    sensors = [Sensors.from_components([g for g, _ in dofs], [c for _, c in dofs]) for dofs in (outputs, inputs)]
    try:
        return FRFData(axis[1], values, sensors[0], sensors[1], kind[1], coherence=coh)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err


# Time histories (dataset 58, function type 1) and channel-only records -----------------
#
# A time record holds one channel: its DoF in record 6 (response node, direction), its
# quantity in record 9 field 1 (ordinate specific data type), the sampling in record 7
# (abscissa minimum and increment, or the abscissa values when spacing is uneven).
# Channel-only exports write node 0, direction 0 and a channel name; the name read is the
# response entity name (record 6 field 5; pyuff ``rsp_ent_name``), for a time record the
# ID line 1 (``id1``) when that is blank or NONE; the excitation of an FRF is named by
# the reference entity name (record 6 field 8, ``ref_ent_name``).

_TIME = 1  # dataset 58 function type: time response
_TIME_AXIS_TYPES = (0, 17)  # abscissa specific data type: unknown, time
_TIME_QUANTITIES = {8: "displacement", 11: "velocity", 12: "acceleration", 9: "force", 13: "force"}
_COMPLEX_ORDINATES = (5, 6)  # record 7 field 1: single and double precision complex
_SAMPLING_RTOL = 1e-5  # the abscissa increment is written E13.5: 6 significant digits
_NO_NAME = ("", "NONE")  # pyuff writes NONE for an absent entity name


def _channel_name(record: dict, role: str) -> str:
    """The channel name of a record's response (``"rsp"``) or reference (``"ref"``)."""
    name = str(record.get(f"{role}_ent_name", "")).strip()
    if name.upper() in _NO_NAME and role == "rsp" and int(record["func_type"]) == _TIME:
        name = str(record.get("id1", "")).strip()
    return "" if name.upper() in _NO_NAME else name


def _mapped(records: list[tuple[int, dict]], dof_map: dict | None, path: str, funcs: tuple[int, ...]):
    """The dataset-58 records with the DoFs of ``dof_map`` {channel: (node, direction)}
    (a row overrides the DoF written in the record). Raises ``ValueError`` for a row that
    names no channel of the file, and for a record of a function type in ``funcs`` whose
    channel has no DoF (direction 0) and no row."""
    from ._time_data import check_dof_map

    dof_map = None if dof_map is None else check_dof_map(dof_map)
    names, out, unmapped = set(), [], []
    for number, r in records:
        func = int(r["func_type"])
        if func not in (_TIME, _FRF, _COHERENCE):
            out.append((number, r))
            continue
        r = dict(r)
        for role in ("rsp",) if func == _TIME else ("rsp", "ref"):
            name = _channel_name(r, role)
            names.add(name)
            if dof_map and name in dof_map:
                r[f"{role}_node"], r[f"{role}_dir"] = dof_map[name]
            elif func in funcs and int(r[f"{role}_dir"]) == 0 and name:  # unnamed: refused by the reader
                unmapped.append(repr(name))
        out.append((number, r))
    names.discard("")
    if dof_map:
        absent = [c for c in dof_map if c not in names]
        if absent:
            raise ValueError(f"{path}: DoF map rows name channel(s) {', '.join(map(repr, absent))} absent from the "
                             f"file; its channels are {', '.join(map(repr, sorted(names))) or 'unnamed'}")
    if unmapped:
        unmapped = list(dict.fromkeys(unmapped))
        listing = ", ".join(unmapped[:20]) + (f" and {len(unmapped) - 20} more" if len(unmapped) > 20 else "")
        what = "time-history" if funcs == (_TIME,) else "FRF"
        if dof_map:
            raise ValueError(f"{path}: {what} channel(s) {listing} have no DoF in the file (direction 0) "
                             "and no row in the DoF map")
        raise ValueError(f"{path}: {what} records have no DoF (direction 0) for channel(s) {listing}: map "
                         "the channels to DoFs (dof_map; jaxfem: --dof-map CSV with columns channel,node,direction)")
    return out


def _sampling(x: np.ndarray, where: str) -> tuple[float, float]:
    """Sample interval and start time of an abscissa; ``ValueError`` when it is not uniform."""
    n = len(x)
    dt = (x[-1] - x[0]) / (n - 1)
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"{where}: abscissa from {x[0]} to {x[-1]} s is not increasing (record 7, fields 4-5)")
    tol = 1e-3 * dt + _SAMPLING_RTOL * np.max(np.abs(x))  # uneven spacing: times written E13.5
    off = np.abs(x - (x[0] + dt * np.arange(n)))
    k = int(np.argmax(off))
    if off[k] > tol:
        raise ValueError(f"{where}: sample {k} at {x[k]} s is off the uniform time axis (Δt = {dt:.6g} s from "
                         f"{x[0]} s): time histories need a constant sampling rate")
    return float(dt), float(x[0])


def _time_histories(records: list[tuple[int, dict]], units: dict, path: str, dof_map: dict | None = None):
    """:class:`TimeHistories` of the dataset-58 time records (function type 1), in SI, or None.

    Quantity from record 9 field 1: displacement (8), velocity (11), acceleration (12),
    force (13 excitation, 9 reaction); other quantities (unknown 0, general 1, pressure,
    strain, ...) are ignored with a ``UserWarning``. Values ÷ length for translational
    motion, ÷ force for a force, ÷ force·length for a moment (rotational DoF), unchanged
    for rotational motion (rad). Every channel must have the same number of samples, the
    same sample interval (to 1e-5) and start time; fs = 1/Δt, taken as the nearest whole
    Hz when within 1e-5 (the increment has 6 significant digits in the file).
    """
    from ._time_data import TimeHistories

    records = _mapped(records, dof_map, path, (_TIME,))
    channels, ignored = [], {}
    first = None
    for number, r in records:
        if int(r["func_type"]) != _TIME:
            continue
        name = _channel_name(r, "rsp")
        node, code = int(r["rsp_node"]), int(r["rsp_dir"])
        where = f"dataset #{number}" + (f" (channel {name!r})" if name else "")
        if not 1 <= abs(code) <= 6:
            unnamed = " (and no channel name for a DoF map)" if code == 0 else ""
            raise ValueError(f"{path}: {where}: response direction {code} is not ±1..6 (record 6, field 7){unnamed}")
        spec = int(r["ordinate_spec_data_type"])
        quantity = _TIME_QUANTITIES.get(spec)
        if quantity is None:
            ignored.setdefault(spec, []).append(number)
            continue
        if int(r["abscissa_spec_data_type"]) not in _TIME_AXIS_TYPES:
            raise ValueError(f"{path}: {where}: abscissa specific data type {r['abscissa_spec_data_type']} is not "
                             "time (17) (record 8, field 1)")
        if int(r["ord_data_type"]) in _COMPLEX_ORDINATES or np.iscomplexobj(r["data"]):
            raise ValueError(f"{path}: {where}: ordinate data type {r['ord_data_type']} is complex; a time history "
                             "is real (record 7, field 1)")
        x = np.asarray(r["x"], dtype=np.float64)
        data = np.asarray(r["data"], dtype=np.float64)
        if len(data) < 2 or len(x) != len(data):
            raise ValueError(f"{path}: {where}: {len(data)} sample(s); a time history needs at least 2 "
                             "(record 7, field 2)")
        dt, t0 = _sampling(x, f"{path}: {where}")
        if first is None:
            first = (where, len(data), dt, t0)
        elif len(data) != first[1]:
            raise ValueError(f"{path}: {where} has {len(data)} samples but {first[0]} has {first[1]}: channels must "
                             "be sampled together (record 7, field 2)")
        elif not math.isclose(dt, first[2], rel_tol=_SAMPLING_RTOL):
            raise ValueError(f"{path}: {where} samples at {_rate(dt):.6g} Hz (Δt = {dt:.6g} s) but {first[0]} at "
                             f"{_rate(first[2]):.6g} Hz: mixed sampling rates (record 7, field 5)")
        elif abs(t0 - first[3]) > 1e-3 * dt + _SAMPLING_RTOL * max(abs(t0), abs(first[3])):
            raise ValueError(f"{path}: {where} starts at {t0} s but {first[0]} at {first[3]} s: channels must be "
                             "sampled together (record 7, field 4)")
        if quantity == "force":
            factor = units["force"] * (units["length"] if abs(code) > 3 else 1.0)
        else:
            factor = units["length"] if abs(code) <= 3 else 1.0
        data = data / factor
        bad = np.flatnonzero(~np.isfinite(data))
        if len(bad):
            raise ValueError(f"{path}: {where}: value {data[bad[0]]} at sample {bad[0]} ({x[bad[0]]} s)")
        channels.append((name, node, code, quantity, data))
    if ignored:
        listing = "; ".join(f"type {t}: datasets {', '.join(f'#{n}' for n in numbers)}"
                            for t, numbers in sorted(ignored.items()))
        warnings.warn(f"{path}: time records of quantities other than force, displacement, velocity or "
                      f"acceleration (record 9 field 1 {listing}) ignored", stacklevel=3)
    if not channels:
        return None
    name, node, code, quantity, data = zip(*channels)
    try:
        return TimeHistories(np.column_stack(data), _rate(first[2]), node, code, name, quantity, start_s=first[3])
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err


def _rate(dt: float) -> float:
    """1/Δt, or the nearest whole Hz when within the increment's 6 significant digits."""
    fs = 1.0 / dt
    return float(round(fs)) if round(fs) > 0 and abs(fs - round(fs)) <= _SAMPLING_RTOL * fs else fs


def dataset58_function_types(path: str | os.PathLike) -> set[int]:
    """Function types of the dataset-58 records of a universal file (headers only; a record
    pyuff cannot parse is skipped): 1 time response, 4 FRF, 6 coherence, ..."""
    uff = pyuff.UFF(os.fspath(path))
    found = set()
    for i, kind in enumerate(uff.get_set_types()):
        if int(kind) == 58:
            try:
                found.add(int(uff.read_sets(i, header_only=True)["func_type"]))
            except Exception:  # pyuff raises bare Exception for any parse failure; this is only a hint
                continue
    return found
