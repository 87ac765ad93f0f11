"""Fixed-layout bulk-data cards: the parser made from a field schema (:func:`_fixed`) and
the value checks of GRID/GRDSET, CORD2R/C/S, CORD1R/C/S, CBAR, CBEAM, MAT1, CONM1, CONM2,
the scalar elements' ends, CBUSH, CQUAD4, CTRIA3 and PSHELL (MSC Nastran QRG, per card);
what the model does not support is refused with a located :class:`BulkDataError`."""

from __future__ import annotations

import warnings
from collections.abc import Callable

from ._bulkdata import Card
from ._fields import _id, _Raw, _read, _Spec


def _fixed(*schema: _Spec, check: Callable | None = None) -> Callable[[_Raw], list[Card]]:
    """Parser of a card with a fixed field layout, with an optional value check."""

    def parse(raw: _Raw) -> list[Card]:
        values, positions = _read(raw, schema)
        raw.end(len(schema))
        if check is not None:
            check(raw, values, positions)
        return [raw.card(values, positions)]

    return parse


def _cord1(raw: _Raw) -> list[Card]:
    """CORD1R/C/S: one or two systems (CID, G1, G2, G3) per card, three distinct grids each."""
    cards = []
    for start in (0, 4):
        if start and not any(raw.text(i) for i in range(4, 8)):
            break
        values, positions = _read(raw, (_id("CID"), _id("G1"), _id("G2"), _id("G3")), start, True)
        grids = [values[k] for k in ("G1", "G2", "G3")]
        if len(set(grids)) < 3:
            raise raw.error(positions["G1"], "G1", f"the grids G1, G2, G3 must differ, got {grids}")
        cards.append(raw.card(values, positions))
    raw.end(8)
    return cards


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
    """GRID and GRDSET: CP >= 0, CD >= -1 (-1: fluid point) or blank; a blank field stays None
    until the GRDSET defaults are applied (:func:`jaxfem.io._cards._apply_grdset`)."""
    for key, low in (("CP", 0), ("CD", -1)):
        if values[key] is not None and values[key] < low:
            raise raw.error(positions[key], key, f"coordinate system id must be >= {low}, got {values[key]}")


def _check_cord2(raw: _Raw, values: dict, positions: dict) -> None:
    if values["RID"] < 0:
        raise raw.error(positions["RID"], "RID", f"reference system id must be >= 0, got {values['RID']}")


def _old_orientation_flag(raw: _Raw, values: dict, positions: dict) -> None:
    """CBAR field 9 as old decks write it: the flag F (1: X1–X3 is a vector, 2: X1 is a
    grid G0) of earlier Nastran, read as OFFT GGG with a warning when it agrees with
    field 6."""
    flag = values["OFFT"]
    if not isinstance(flag, int):
        if not isinstance(flag, str):
            raise raw.error(positions["OFFT"], "OFFT", f"expected a word, got {flag!r}")
        return
    if flag not in (1, 2) or (flag == 2) != (values["G0"] is not None):
        raise raw.error(positions["OFFT"], "OFFT", f"expected a word (GGG, BGG, ...), got {flag}")
    warnings.warn(f"{raw.card(values, positions).where('OFFT')}: {flag} is the orientation flag of earlier "
                  "Nastran versions: read as OFFT GGG", UserWarning, stacklevel=6)
    values["OFFT"] = "GGG"


def _check_cbar(raw: _Raw, values: dict, positions: dict) -> None:
    _orientation(raw, values, positions, required=True)
    _old_orientation_flag(raw, values, positions)
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
    """CONM2 CID: a system id, 0 (basic) or -1 (X1..X3 a position in basic), QRG CONM2."""
    if values["CID"] < -1:
        raise raw.error(positions["CID"], "CID", f"CID must be >= -1, got {values['CID']}")


def _check_conm1(raw: _Raw, values: dict, positions: dict) -> None:
    """CONM1 CID: a system id >= 0 (QRG CONM1)."""
    if values["CID"] < 0:
        raise raw.error(positions["CID"], "CID", f"coordinate system id must be >= 0, got {values['CID']}")


def _check_celas(raw: _Raw, values: dict, positions: dict) -> None:
    """Ends G1/C1, G2/C2 of CELAS1/2, CMASS1/2, CDAMP1/2 (QRG, per card): ground is G blank
    or 0 (stored as G and C None); C is 1..6 at a grid, 0 or blank (stored 0) at a scalar
    point (the builder checks which the point is)."""
    for g, c in (("G1", "C1"), ("G2", "C2")):
        if values[g] is not None and values[g] < 0:
            raise raw.error(positions[g], g, f"grid or scalar point id must be >= 0, got {values[g]}")
        if not values[g]:
            if values[c] not in (None, 0):
                raise raw.error(positions[c], c, "component must be blank or 0 for a grounded end")
            values[g] = values[c] = None
        elif values[c] is None:
            values[c] = 0
        elif not 0 <= values[c] <= 6:
            raise raw.error(
                positions[c], c,
                f"component of point {values[g]} must be 1..6 (a grid) or 0/blank (a scalar point), got {values[c]}",
            )
    if values["G1"] is None and values["G2"] is None:
        raise raw.error(positions["G1"], "G1", "both ends are grounded")


def _check_scalar_points(raw: _Raw, values: dict, positions: dict) -> None:
    """Ends S1, S2 of CELAS3/4, CMASS3/4, CDAMP3/4: scalar point ids, ground blank or 0 (None)."""
    for s in ("S1", "S2"):
        if values[s] is not None and values[s] < 0:
            raise raw.error(positions[s], s, f"scalar point id must be >= 0, got {values[s]}")
        values[s] = values[s] or None
    if values["S1"] is None and values["S2"] is None:
        raise raw.error(positions["S1"], "S1", "both ends are grounded")


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
