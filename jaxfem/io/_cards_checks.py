"""Fixed-layout bulk-data cards: the parser made from a field schema (:func:`_fixed`) and
the value checks of GRID, CORD2R, CBAR, CBEAM, MAT1, CONM2, CELAS1/2, CBUSH, CQUAD4,
CTRIA3 and PSHELL (MSC Nastran QRG, per card); what the model does not support is
refused with a located :class:`BulkDataError`."""

from __future__ import annotations

from collections.abc import Callable

from ._bulkdata import Card
from ._fields import _Raw, _read, _Spec


def _fixed(*schema: _Spec, check: Callable | None = None) -> Callable[[_Raw], list[Card]]:
    """Parser of a card with a fixed field layout, with an optional value check."""

    def parse(raw: _Raw) -> list[Card]:
        values, positions = _read(raw, schema)
        raw.end(len(schema))
        if check is not None:
            check(raw, values, positions)
        return [raw.card(values, positions)]

    return parse


def _orientation(raw: _Raw, values: dict, positions: dict, required: bool) -> None:
    """Split field 6 into G0 (integer) or X1..X3 (reals; blanks are 0.0)."""
    x = [values[k] for k in ("X1", "X2", "X3")]
    values["G0"] = None
    positions["G0"] = positions["X1"]
    if isinstance(x[0], int):
        for k in ("X2", "X3"):
            raw.blank(positions[k], k, "must be blank when field 6 is the orientation grid G0")
        if x[0] <= 0:
            raise raw.error(positions["X1"], "G0", f"orientation grid must be positive, got {x[0]}")
        values.update(G0=x[0], X1=None)
    elif any(v is not None for v in x):
        values.update({k: 0.0 if v is None else v for k, v in zip(("X1", "X2", "X3"), x)})
    elif required:
        raise raw.error(
            positions["X1"], "X1/G0",
            "an orientation vector X1, X2, X3 or a grid G0 is required (BAROR is not supported)",
        )


def _no_pins(raw: _Raw, values: dict, positions: dict) -> None:
    for key in ("PA", "PB"):
        if values[key] not in (None, 0):
            raise raw.error(positions[key], key, f"pin flags are not supported, got {values[key]}")


def _offt(raw: _Raw, values: dict, positions: dict) -> None:
    if values["OFFT"] not in ("GGG", "BGG"):
        raise raw.error(
            positions["OFFT"], "OFFT",
            f"OFFT {values['OFFT']!r} is not supported: only GGG or BGG (offsets and orientation "
            "in the grid systems, which are basic here)",
        )


def _check_grid(raw: _Raw, values: dict, positions: dict) -> None:
    if values["CP"] < 0:
        raise raw.error(positions["CP"], "CP", f"coordinate system id must be >= 0, got {values['CP']}")
    if values["CD"] != 0:
        raise raw.error(
            positions["CD"], "CD",
            f"non-basic output systems are not supported: CD must be 0 or blank, got {values['CD']}",
        )


def _check_cord2r(raw: _Raw, values: dict, positions: dict) -> None:
    if values["RID"] < 0:
        raise raw.error(positions["RID"], "RID", f"reference system id must be >= 0, got {values['RID']}")


def _check_cbar(raw: _Raw, values: dict, positions: dict) -> None:
    _orientation(raw, values, positions, required=True)
    _offt(raw, values, positions)
    _no_pins(raw, values, positions)


def _check_cbeam(raw: _Raw, values: dict, positions: dict) -> None:
    _orientation(raw, values, positions, required=True)
    if not isinstance(values["OFFT"], str):
        raise raw.error(positions["OFFT"], "OFFT/BIT", "BIT (p-element twist) is not supported")
    _offt(raw, values, positions)
    _no_pins(raw, values, positions)
    for key in ("SA", "SB"):
        if values[key] is not None:
            raise raw.error(positions[key], key, "warping scalar points SA/SB are not supported")


def _check_mat1(raw: _Raw, values: dict, positions: dict) -> None:
    if values["E"] is None and values["G"] is None:
        raise raw.error(positions["E"], "E", "E and G may not both be blank")


def _check_conm2(raw: _Raw, values: dict, positions: dict) -> None:
    if values["CID"] not in (0, -1):
        raise raw.error(
            positions["CID"], "CID",
            f"CID {values['CID']} is not supported: offsets and inertia must be in the basic "
            "system (CID 0 or blank; -1 for an absolute CG position)",
        )


def _check_celas(raw: _Raw, values: dict, positions: dict) -> None:
    """Ground is G blank or 0 (stored as None, component None); a grid needs component 1..6."""
    ends = (("G1", "C1"), ("G2", "C2"))
    for g, c in ends:
        if values[g] is not None and values[g] < 0:
            raise raw.error(positions[g], g, f"grid id must be >= 0, got {values[g]}")
        if not values[g]:
            if values[c] not in (None, 0):
                raise raw.error(positions[c], c, "component must be blank or 0 for a grounded end")
            values[g] = values[c] = None
        elif values[c] is None or not 1 <= values[c] <= 6:
            raise raw.error(
                positions[c], c,
                f"component of grid {values[g]} must be 1..6 (scalar points are not supported), got {values[c]}",
            )
    if values["G1"] is None and values["G2"] is None:
        raise raw.error(positions["G1"], "G1", "both ends are grounded")


def _check_cbush(raw: _Raw, values: dict, positions: dict) -> None:
    if not values["GB"]:
        raise raw.error(positions["GB"], "GB", "grounded CBUSH elements (GB blank) are not supported")
    if values["GB"] < 0:
        raise raw.error(positions["GB"], "GB", f"grid id must be positive, got {values['GB']}")
    _orientation(raw, values, positions, required=False)
    if values["CID"] is not None and values["CID"] < 0:
        raise raw.error(positions["CID"], "CID", f"CID must be >= 0 or blank, got {values['CID']}")
    if not 0.0 <= values["S"] <= 1.0:
        raise raw.error(positions["S"], "S", f"S must lie in [0, 1], got {values['S']}")
    if values["OCID"] != -1:
        raise raw.error(positions["OCID"], "OCID", "spring offsets (OCID >= 0) are not supported")
    for key in ("S1", "S2", "S3"):
        raw.blank(positions[key], key, "spring offsets are not supported")


def _check_shell(raw: _Raw, values: dict, positions: dict) -> None:
    """CQUAD4/CTRIA3 field 8: a real is THETA [deg], an integer MCID >= 0, blank THETA 0.0
    (key MCID None unless given); TFLAG 0 (blank) or 1; corner thicknesses T1..Tn (blank:
    the property's T) >= 0 and not all zero."""
    theta = values["THETA"]
    values["MCID"], positions["MCID"] = None, positions["THETA"]
    if theta is None:
        values["THETA"] = 0.0
    elif isinstance(theta, int):
        if theta < 0:
            raise raw.error(positions["THETA"], "MCID", f"material coordinate system id must be >= 0, got {theta}")
        values.update(THETA=None, MCID=theta)
    if values["TFLAG"] not in (0, 1):
        raise raw.error(positions["TFLAG"], "TFLAG", f"TFLAG must be 0 (blank) or 1, got {values['TFLAG']}")
    corners = [k for k in ("T1", "T2", "T3", "T4") if k in values]
    for key in corners:
        if values[key] is not None and values[key] < 0.0:
            raise raw.error(positions[key], key, f"corner thickness must be >= 0, got {values[key]}")
    if all(values[k] == 0.0 for k in corners):
        raise raw.error(positions["T1"], "T1", "corner thicknesses T1..Tn must not all be zero")


def _check_pshell(raw: _Raw, values: dict, positions: dict) -> None:
    if values["T"] is None:
        raise raw.error(
            positions["T"], "T",
            "T is required here (a blank T, thickness from the elements' T1..T4 only, is not supported)",
        )
    for key in ("MID1", "MID2", "MID3", "MID4"):
        mid = values[key]
        if mid is not None and mid <= 0:
            why = (
                "plane strain (MID2 = -1) is not supported" if key == "MID2" and mid == -1
                else f"material id must be positive or blank, got {mid}"
            )
            raise raw.error(positions[key], key, why)
