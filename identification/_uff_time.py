"""Time histories of a universal file (dataset 58, function type 1), in SI.

A time record holds one channel: its DoF in record 6 (response node, direction), its
quantity in record 9 field 1 (ordinate specific data type), the sampling in record 7
(abscissa minimum and increment, or the abscissa values when spacing is uneven).
Channel-only records get their DoFs from a DoF map (:mod:`identification._uff_channels`).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from ._uff_channels import _TIME, _channel_name, _mapped

_TIME_AXIS_TYPES = (0, 17)  # abscissa specific data type: unknown, time
_TIME_QUANTITIES = {8: "displacement", 11: "velocity", 12: "acceleration", 9: "force", 13: "force"}
_COMPLEX_ORDINATES = (5, 6)  # record 7 field 1: single and double precision complex
_SAMPLING_RTOL = 1e-5  # the abscissa increment is written E13.5: 6 significant digits


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


def _samples(r: dict, where: str) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Abscissa, real ordinates, sample interval and start time of a time record; ``ValueError`` if unfit."""
    if int(r["abscissa_spec_data_type"]) not in _TIME_AXIS_TYPES:
        raise ValueError(f"{where}: abscissa specific data type {r['abscissa_spec_data_type']} is not "
                         "time (17) (record 8, field 1)")
    if int(r["ord_data_type"]) in _COMPLEX_ORDINATES or np.iscomplexobj(r["data"]):
        raise ValueError(f"{where}: ordinate data type {r['ord_data_type']} is complex; a time history "
                         "is real (record 7, field 1)")
    x = np.asarray(r["x"], dtype=np.float64)
    data = np.asarray(r["data"], dtype=np.float64)
    if len(data) < 2 or len(x) != len(data):
        raise ValueError(f"{where}: {len(data)} sample(s); a time history needs at least 2 "
                         "(record 7, field 2)")
    dt, t0 = _sampling(x, where)
    return x, data, dt, t0


def _si_factor(quantity: str, code: int, units: dict) -> float:
    """Divisor to SI: force (× length for a moment), length for translational motion, 1 for rotation."""
    if quantity == "force":
        return units["force"] * (units["length"] if abs(code) > 3 else 1.0)
    return units["length"] if abs(code) <= 3 else 1.0


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
        x, data, dt, t0 = _samples(r, f"{path}: {where}")
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
        data = data / _si_factor(quantity, code, units)
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
