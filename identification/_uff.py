"""Universal File Format (UFF) reading through pyuff.

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

The parts: the file's dataset structure (:mod:`identification._uff_blocks`), units
(:mod:`identification._uff_units`), coordinate systems and nodes
(:mod:`identification._uff_systems`), modes and FRFs (:mod:`identification._uff_records`),
time histories (:mod:`identification._uff_time`) and the channels of channel-only records
(:mod:`identification._uff_channels`).
"""

from __future__ import annotations

import os
import warnings

import equinox as eqx
import pyuff

from ._uff_blocks import read_records
from ._uff_lines import trace_lines
from ._uff_records import _frfs, _modes
from ._uff_systems import _SYSTEM_TYPES, _global, _nodes, _systems
from ._uff_time import _time_histories
from ._uff_units import _units

_READ = (15, 18, 55, 58, 164, 2411, 2420)
# header (151), model header (2400), elements (2412), trace lines (82, read_trace_lines), function
# qualifiers of dataset 58 (1858), groups (2429, 2467): they describe, they hold no measured data
_DESCRIPTIVE = (82, 151, 1858, 2400, 2412, 2429, 2467)


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

def read_trace_lines(path: str | os.PathLike) -> list[tuple[int, int]]:
    """The trace lines (datasets 82) of a universal file as node-id pairs, each once
    (:func:`identification._uff_lines.trace_lines`); empty when it has none. The file is
    checked whole as by :func:`read_uff` (:func:`read_records`)."""
    path = os.fspath(path)
    return trace_lines(read_records(path, lambda kind: kind == 82)[0], path)

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
