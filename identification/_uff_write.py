"""Universal File Format (UFF) writing through pyuff: units, nodes, modes and FRFs.

:func:`write_uff` writes dataset 164 (units), 2411 (nodes), one 55 per mode (normal modes
for real shapes, complex-eigenvalue modes for complex ones) and one binary 58 per FRF and
per coherence function, converting from SI with the unit factors and the UFF 58 unit
exponents of :mod:`identification._uff_units`, so that :func:`read_uff` reads the file back.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Mapping

import numpy as np
import pyuff

from ._data import FRFData, ModalData
from ._uff_channels import _COHERENCE, _FRF
from ._uff_records import _FRF_CODES
from ._uff_units import _UNIT_CODES, _USER_CODE, _frf_factor


def write_uff(
    path: str | os.PathLike,
    *,
    nodes: Mapping[int, np.ndarray] | None = None,
    modes: ModalData | None = None,
    frfs: FRFData | None = None,
    units: str | Mapping[str, float] = "SI",
) -> None:
    """Write a universal file that :func:`read_uff` reads back.

    Writes dataset 164 (units), 2411 (nodes, double precision), one 55 per mode (normal
    modes for real shapes, complex-eigenvalue modes with λ = ω(−ζ + i√(1−ζ²)) for complex
    ones) and one binary 58 per FRF and per coherence function (double precision with
    the frequency axis stored: exact).

    **Arguments:**

    - ``nodes``: {grid id: xyz in m}; every sensor node of ``modes`` must be among them
      when given.
    - ``modes``: sensors along ±X/Y/Z (and rotations about them); dataset 55 stores the
      global components per node, so a sensor along −Z comes back as +Z with its values
      negated, and unmeasured components of a node are written as 0.
    - ``frfs``: sensors along the axes (direction codes ±1..6).
    - ``units``: "SI", or ``{"length": L, "force": F}`` in file units per SI unit (e.g.
      1000 and 1 for mm and N); values are converted from SI as :func:`read_uff` converts
      them back.

    Precision: dataset 55 has the fixed format E13.5, so frequencies, damping, masses
    and shapes keep 6 significant digits; nodes, units and FRFs round-trip exactly.
    """
    length, force, code, description = _write_units(units)
    datasets = [
        {
            "type": 164,
            "units_code": code,
            "units_description": description,
            "temp_mode": 1,
            "length": length,
            "force": force,
            "temp": 1.0,
            "temp_offset": 273.15,
        }
    ]
    if nodes:
        ids = np.array(sorted(int(g) for g in nodes), dtype=np.int64)
        xyz = np.array([np.asarray(nodes[g], dtype=np.float64) for g in ids]).reshape(-1, 3) * length
        zeros = np.zeros(len(ids), dtype=np.int64)
        datasets.append(
            {
                "type": 2411,
                "node_nums": ids,
                "def_cs": zeros,
                "disp_cs": zeros,
                "color": zeros,
                "x": xyz[:, 0],
                "y": xyz[:, 1],
                "z": xyz[:, 2],
            }
        )
    if modes is not None:
        datasets += _mode_datasets(modes, nodes, length, force)
    if frfs is not None:
        datasets += _frf_datasets(frfs, {"length": length, "force": force})
    path = os.fspath(path)
    if os.path.exists(path):
        os.remove(path)
    with warnings.catch_warnings():
        # pyuff 2.5.8 reopens the file for each binary 58 record without closing it (it is
        # closed when the handle goes out of scope); nothing is lost, so its warning is noise.
        warnings.simplefilter("ignore", ResourceWarning)
        pyuff.UFF(path).write_sets(datasets, mode="add")


def _write_units(units: str | Mapping[str, float]) -> tuple[float, float, int, str]:
    if isinstance(units, str):
        if units != "SI":
            raise ValueError(f"units {units!r}: give 'SI' or {{'length': L, 'force': F}} (file units per SI unit)")
        return 1.0, 1.0, 1, "SI"
    unknown = set(units) - {"length", "force"}
    if unknown:
        raise ValueError(f"units keys {sorted(unknown)} unknown; expected 'length' and 'force'")
    length, force = float(units.get("length", 1.0)), float(units.get("force", 1.0))
    if not (length > 0 and force > 0 and math.isfinite(length) and math.isfinite(force)):
        raise ValueError(f"unit factors must be finite and positive, got length {length}, force {force}")
    for code, (label, l_code, f_code) in _UNIT_CODES.items():
        if math.isclose(length, l_code, rel_tol=1e-12) and math.isclose(force, f_code, rel_tol=1e-12):
            return length, force, code, label.split(":")[0]
    return length, force, _USER_CODE, "USER"


def _mode_datasets(modes: ModalData, nodes, length: float, force: float) -> list[dict]:
    sensors = modes.sensors
    codes = sensors.codes
    skew = np.flatnonzero(codes == 0)
    if len(skew):
        raise ValueError(f"sensor {sensors.labels[skew[0]]} is not along an axis; dataset 55 stores X, Y, Z components")
    node_ids = np.array(list(dict.fromkeys(sensors.nodes.tolist())), dtype=np.int64)
    if nodes:
        absent = [int(g) for g in node_ids if int(g) not in nodes]
        if absent:
            raise ValueError(f"sensor node(s) {absent} are not among the nodes written")
    shapes = np.asarray(modes.shapes)
    complex_modes = np.iscomplexobj(shapes)
    n_comp = 6 if np.any(sensors.rotational) else 3
    if complex_modes and n_comp == 6:
        raise ValueError(
            "complex modes with rotational sensors cannot be written: "
            "dataset 55 (pyuff) holds 3 complex values per node"
        )
    if complex_modes and modes.generalised_masses is not None:
        raise ValueError("generalised masses of complex modes cannot be written to dataset 55")
    position = {g: i for i, g in enumerate(node_ids.tolist())}
    row = np.array([position[g] for g in sensors.nodes.tolist()], dtype=np.int64)
    table = np.zeros((len(node_ids), n_comp, modes.n_modes), dtype=shapes.dtype)
    table[row, np.abs(codes) - 1] = np.sign(codes)[:, None] * shapes
    table[:, :3] *= length
    datasets = []
    for k in range(modes.n_modes):
        f, zeta, mode = float(modes.frequencies_hz[k]), float(modes.damping_ratios[k]), int(modes.mode_ids[k])
        record = {
            "type": 55,
            "id1": f"Mode {mode}",
            "model_type": 1,
            "data_ch": 2 if n_comp == 3 else 3,
            "spec_data_type": 8,
            "load_case": 1,
            "mode_n": mode,
            "node_nums": node_ids,
        }
        record.update({f"r{c + 1}": table[:, c, k] for c in range(n_comp)})
        if complex_modes:
            omega = 2 * np.pi * f
            record.update(analysis_type=3, eig=omega * complex(-zeta, math.sqrt(1 - zeta**2)), modal_a=0j, modal_b=0j)
        else:
            mass = 0.0 if modes.generalised_masses is None else float(modes.generalised_masses[k]) * force / length
            record.update(analysis_type=2, freq=f, modal_m=mass, modal_damp_vis=zeta, modal_damp_his=0.0)
        datasets.append(record)
    return datasets


def _frf_datasets(frfs: FRFData, units: dict) -> list[dict]:
    out_codes, in_codes = frfs.outputs.codes, frfs.inputs.codes
    for sensors, codes in ((frfs.outputs, out_codes), (frfs.inputs, in_codes)):
        skew = np.flatnonzero(codes == 0)
        if len(skew):
            raise ValueError(f"FRF DoF {sensors.labels[skew[0]]} is not along an axis; dataset 58 needs codes ±1..6")
    f = np.asarray(frfs.frequencies_hz)
    if len(f) < 2:
        raise ValueError("dataset 58 needs at least two frequency lines")
    values = np.asarray(frfs.values)
    datasets = []
    for o, (out_node, out_code) in enumerate(zip(frfs.outputs.nodes, out_codes)):
        for i, (in_node, in_code) in enumerate(zip(frfs.inputs.nodes, in_codes)):
            common = {
                "type": 58,
                "binary": 1,
                "rsp_node": int(out_node),
                "rsp_dir": int(out_code),
                "ref_node": int(in_node),
                "ref_dir": int(in_code),
                "abscissa_spacing": 0,
                "abscissa_spec_data_type": 18,
                "x": f,
            }
            label = f"{frfs.outputs.labels[o]} / {frfs.inputs.labels[i]}"
            frf = values[:, o, i] / _frf_factor(units, int(out_code), int(in_code))
            datasets.append(
                dict(
                    common,
                    id1=f"FRF {label}",
                    func_type=_FRF,
                    ordinate_spec_data_type=_FRF_CODES[frfs.kind],
                    orddenom_spec_data_type=13,  # excitation force
                    data=frf,
                )
            )
            if frfs.coherence is not None:
                coherence = np.asarray(frfs.coherence, dtype=np.float64)[:, o, i]
                datasets.append(
                    dict(
                        common,
                        id1=f"Coherence {label}",
                        func_type=_COHERENCE,
                        ordinate_spec_data_type=0,
                        orddenom_spec_data_type=0,
                        data=coherence,
                    )
                )
    return datasets
