"""Measured data of a universal file in SI: mode shapes (dataset 55) and FRFs with their
coherence (dataset 58, function types 4 and 6)."""

from __future__ import annotations

import warnings

import numpy as np

from ._data import FRFData, ModalData, Sensors
from ._uff_channels import _COHERENCE, _FRF, _TIME, _mapped
from ._uff_units import _frf_factor

_AXIS_RTOL = 1e-9  # two FRF records share a frequency axis
_MOTION_TYPES = (0, 1, 8, 11, 12)  # unknown, general, displacement, velocity, acceleration
_FRF_SPEC_TYPES = {8: "receptance", 11: "mobility", 12: "accelerance"}
_FRF_CODES = {kind: code for code, kind in _FRF_SPEC_TYPES.items()}
_FORCE_SPEC_TYPES = (0, 9, 13)  # unknown (a type-4 function is per unit force), reaction, excitation
_NORMAL_MODE, _COMPLEX_MODES = 2, (3, 7)  # dataset 55 analysis types


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
        column = _mode_column(r, name, nodes, length)
        freq, zeta, mass = _mode_spectrum(r, name, units)
        freqs.append(freq)
        zetas.append(zeta)
        masses.append(mass)
        if r["analysis_type"] == _NORMAL_MODE and r["modal_damp_his"] != 0 and r["modal_damp_vis"] == 0:
            hysteretic.append(mode)
        columns.append((name, column))
        ids.append(mode)
    if hysteretic:
        warnings.warn(
            f"{path}: modes {hysteretic} give only a hysteretic damping value, which is not converted; their "
            "viscous damping ratio is 0",
            stacklevel=3,
        )
    shapes, sensors = _shapes(columns)
    masses = np.asarray(masses)
    if np.any(masses > 0) and not np.all(masses > 0):
        warnings.warn(
            f"{path}: only modes {np.asarray(ids)[masses > 0].tolist()} give a modal mass; generalised masses dropped",
            stacklevel=3,
        )
    try:
        return ModalData(
            np.asarray(freqs),
            shapes,
            sensors,
            damping_ratios=np.asarray(zetas),
            generalised_masses=masses if np.all(masses > 0) else None,
            mode_ids=np.asarray(ids),
        )
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err


def _mode_column(r: dict, name: str, nodes: dict, length: float) -> dict[tuple[int, int], float]:
    """Shape values of one dataset-55 record by DoF (node, direction code), translations in SI."""
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
    return column


def _mode_spectrum(r: dict, name: str, units: dict) -> tuple[float, float, float]:
    """Natural frequency (Hz), viscous damping ratio and modal mass (SI; 0 for a complex mode) of one record."""
    length = units["length"]
    if r["analysis_type"] == _NORMAL_MODE:
        return float(r["freq"]), float(r["modal_damp_vis"]), float(r["modal_m"]) * length / units["force"]
    lam = complex(r["eig"])
    if not (np.isfinite(lam) and abs(lam) > 0):
        raise ValueError(f"{name}: eigenvalue {lam} is not finite and non-zero")
    return abs(lam) / (2 * np.pi), -lam.real / abs(lam), 0.0


def _shapes(columns: list[tuple[str, dict]]) -> tuple[np.ndarray, Sensors]:
    """Mode-shape matrix (measured DoFs × modes) and its sensors; every mode must give every DoF."""
    order = list(dict.fromkeys(dof for _, column in columns for dof in column))
    for name, column in columns:
        missing = [_label(*dof) for dof in order if dof not in column]
        if missing:
            raise ValueError(f"{name} lacks DoFs {missing} present in other modes (shapes must be complete)")
    shapes = np.array([[column[dof] for _, column in columns] for dof in order])
    measured = np.any(shapes != 0, axis=1)
    sensors = Sensors.from_components([g for g, _ in order], [c for _, c in order])
    sensors = Sensors(sensors.nodes[measured], sensors.directions[measured], sensors.rotational[measured])
    return shapes[measured], sensors


def _label(node: int, code: int) -> str:
    return Sensors.from_components([node], [code]).labels[0]


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
        key = _frf_key(number, r, path)
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
            record_kind = _frf_kind(r, name, path)
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
    values = _stack(frfs, outputs, inputs)
    coh = None
    if coherence:
        if set(coherence) == set(frfs):
            coh = _stack(coherence, outputs, inputs)
        else:
            warnings.warn(f"{path}: coherence is not given for every FRF; ignored", stacklevel=3)
    sensors = [Sensors.from_components([g for g, _ in dofs], [c for _, c in dofs]) for dofs in (outputs, inputs)]
    try:
        return FRFData(axis[1], values, sensors[0], sensors[1], kind[1], coherence=coh)
    except ValueError as err:
        raise ValueError(f"{path}: {err}") from err


def _frf_key(number: int, r: dict, path: str) -> tuple[int, int, int, int]:
    """(response node, direction, reference node, direction) of a dataset-58 record; codes must be ±1..6."""
    key = (int(r["rsp_node"]), int(r["rsp_dir"]), int(r["ref_node"]), int(r["ref_dir"]))
    if key[1] == 0 or key[3] == 0 or abs(key[1]) > 6 or abs(key[3]) > 6:
        unnamed = " (and no channel name for a DoF map)" if 0 in (key[1], key[3]) else ""
        raise ValueError(f"{path}: dataset #{number}: direction codes {key[1]}, {key[3]} are not ±1..6{unnamed}")
    return key


def _frf_kind(r: dict, name: str, path: str) -> str:
    """FRF kind (receptance, mobility, accelerance) of a record of motion per unit force."""
    record_kind = _FRF_SPEC_TYPES.get(int(r["ordinate_spec_data_type"]))
    if record_kind is None:
        raise ValueError(
            f"{path}: {name}: ordinate type {r['ordinate_spec_data_type']} is not displacement (8), "
            "velocity (11) or acceleration (12)"
        )
    if int(r["orddenom_spec_data_type"]) not in _FORCE_SPEC_TYPES:
        raise ValueError(f"{path}: {name}: denominator type {r['orddenom_spec_data_type']} is not a force")
    return record_kind


def _stack(table: dict, outputs: list, inputs: list) -> np.ndarray:
    """Array (frequencies × outputs × inputs) of the records keyed by output + input DoFs."""
    return np.stack([np.stack([table[o + i][1] for i in inputs], axis=-1) for o in outputs], axis=1)
