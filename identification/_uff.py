"""Universal File Format (UFF) reading through pyuff, and the unit codes it shares with writing.

Datasets: 164 (units), 15 and 2411 (nodes), 55 (mode shapes at nodes), 58/58b (FRFs and
coherence). Everything read is converted to SI with the factors of dataset 164, which
give file units per SI unit (SI = file value / factor; a file in mm has length factor
1000), using the unit exponents of the UFF 58 table (Addendum A):

- coordinates and translational shape values: ÷ length factor (rotations are in rad);
- generalised (modal) masses, force/length: × length / force;
- FRF values, response/excitation: translational response ÷ length, excitation force
  × force, excitation moment × length·force (so a receptance in mm/N is ÷ 1000).

Frequencies are in Hz in every unit system. :func:`write_uff`
(:mod:`identification._uff_write`) converts from SI with the same factors.
"""

from __future__ import annotations

import math
import os
import warnings

import numpy as np
import pyuff

from ._data import FRFData, ModalData, Sensors

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
_SI = {"code": 1, "description": "SI", "length": 1.0, "force": 1.0, "temperature": 1.0, "temperature_offset": 273.15}


def read_uff(path: str | os.PathLike) -> dict:
    """Read nodes, units, modes and FRFs from a universal file, in SI.

    **Returns:** a dict with

    - ``"nodes"``: {grid id: xyz (3,) in m} from datasets 15 and 2411;
    - ``"units"``: the dataset-164 system: ``code``, ``description``, ``length``,
      ``force``, ``temperature``, ``temperature_offset`` (file units per SI unit); SI,
      with a ``UserWarning``, when the file has no dataset 164;
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

    Raises ``ValueError`` naming the record and item for: an unreadable dataset,
    contradicting unit records, nodes defined twice differently, a mode referencing
    a node absent from the node datasets, NaN values, a DoF twice in one mode, modes
    with different DoF sets, FRF records on different frequency axes, duplicate or
    missing (output, input) pairs, and FRFs of mixed or unknown kinds.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"no universal file {path}")
    uff = pyuff.UFF(path)
    types = [int(t) for t in uff.get_set_types()]
    records = []
    for i, kind in enumerate(types):
        try:
            records.append((i + 1, uff.read_sets(i)))
        except Exception as err:  # pyuff raises bare Exception for any parse failure
            raise ValueError(f"{path}: dataset #{i + 1} (type {kind}) cannot be parsed: {err}") from err
    by_type: dict[int, list[tuple[int, dict]]] = {}
    for number, record in records:
        by_type.setdefault(int(record["type"]), []).append((number, record))
    units = _units(by_type.get(164, []), path)
    node_records = sorted(by_type.get(15, []) + by_type.get(2411, []), key=lambda record: record[0])
    nodes = _nodes(node_records, units["length"], path)
    return {
        "nodes": nodes,
        "units": units,
        "modes": _modes(by_type.get(55, []), nodes, units, path),
        "frfs": _frfs(by_type.get(58, []), units, path),
    }


def _units(records: list[tuple[int, dict]], path: str) -> dict:
    if not records:
        warnings.warn(f"{path}: no units dataset (164); SI units assumed", stacklevel=3)
        return dict(_SI)
    (first_number, first), *others = records
    units = {
        "code": int(first["units_code"]),
        "description": str(first["units_description"]).strip(),
        "length": float(first["length"]),
        "force": float(first["force"]),
        "temperature": float(first["temp"]),
        "temperature_offset": float(first["temp_offset"]),
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


def _nodes(records: list[tuple[int, dict]], length: float, path: str) -> dict[int, np.ndarray]:
    nodes: dict[int, np.ndarray] = {}
    where: dict[int, int] = {}
    local = set()
    for number, record in records:
        ids = np.asarray(record["node_nums"], dtype=np.float64).astype(np.int64)
        xyz = np.column_stack([record["x"], record["y"], record["z"]]).astype(np.float64) / length
        systems = np.column_stack([record["def_cs"], record["disp_cs"]])
        local.update(int(g) for g in ids[np.any(systems != 0, axis=1)])
        for g, x in zip(ids.tolist(), xyz):
            if not np.all(np.isfinite(x)):
                raise ValueError(f"{path}: node dataset #{number}: node {g} has coordinates {x.tolist()}")
            if g in nodes and not np.array_equal(nodes[g], x):
                raise ValueError(
                    f"{path}: node {g} is at {nodes[g].tolist()} m in dataset #{where[g]} but at {x.tolist()} m "
                    f"in dataset #{number}"
                )
            nodes[g], where[g] = x, number
    if local:
        warnings.warn(
            f"{path}: nodes {sorted(local)} name local coordinate systems; their coordinates and "
            "shapes are taken as global",
            stacklevel=3,
        )
    return nodes


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


def _frfs(records: list[tuple[int, dict]], units: dict, path: str) -> FRFData | None:
    skipped = sorted({int(r["func_type"]) for _, r in records} - {_FRF, _COHERENCE})
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
            raise ValueError(f"{path}: dataset #{number}: direction codes {key[1]}, {key[3]} are not ±1..6")
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
