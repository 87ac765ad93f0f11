"""Units of a universal file: dataset 164 read and checked, and the unit codes and
file-to-SI factors that reading and writing (:mod:`identification._uff_write`) share.

A factor gives file units per SI unit (SI = file value / factor; a file in mm has length
factor 1000); the exponents of each quantity are those of the UFF 58 table (Addendum A).
"""

from __future__ import annotations

import math
import warnings

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
_SI = {"code": 1, "description": "SI", "length": 1.0, "force": 1.0, "temperature": 1.0, "temperature_offset": 273.15}


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


def _frf_factor(units: dict, response: int, excitation: int) -> float:
    """File-to-SI factor of a response/excitation ratio (UFF 58 Addendum A exponents)."""
    numerator = units["length"] if abs(response) <= 3 else 1.0
    denominator = units["force"] if abs(excitation) <= 3 else units["force"] * units["length"]
    return denominator / numerator
