"""Readers of the supported bulk-data cards: field layouts, value checks, unique ids.

One parser per card name (``_PARSERS``): fixed layouts from a schema with a check of the
values, and the variable layouts read field by field; what Nastran allows but the model
does not support is refused with a located :class:`BulkDataError` (MSC Nastran QRG, per
card). After every card is read, :func:`_finish` merges the DMIG entries per matrix,
applies the GRDSET defaults to the GRID cards and checks ids: two cards with one id in
the same id space (elements, properties, materials, ...) are an error, a rigid element
sharing its id with another element a warning (Nastran accepts it).

The parsers and checks: fixed layouts in :mod:`jaxfem.io._cards_checks`, variable ones in
:mod:`jaxfem.io._cards_variable`, rigid elements and sets in :mod:`jaxfem.io._cards_rigid`,
DMIG and the eigenvalue methods in :mod:`jaxfem.io._cards_matrix`, PCOMP in
:mod:`jaxfem.io._cards_shells`; here the table of parsers and the id spaces.
"""

from __future__ import annotations

import bisect
import warnings
from collections.abc import Callable

from ._bulkdata import BulkDataError, Card, Value, _where
from ._cards_checks import (
    _check_cbar,
    _check_cbeam,
    _check_cbush,
    _check_celas,
    _check_conm1,
    _check_conm2,
    _check_cord2,
    _check_grid,
    _check_mat1,
    _check_pshell,
    _check_scalar_points,
    _check_shell,
    _cord1,
    _fixed,
)
from ._cards_matrix import _dmig, _eigr, _eigrl, _merge_dmig
from ._cards_rigid import _rbar, _rbe1, _rrod, _set_union, _spoint, _suport, _suport1
from ._cards_shells import _pcomp
from ._cards_variable import (
    _mdlprm,
    _mpc,
    _param,
    _pbarl,
    _pbeam,
    _pbeaml,
    _pbush,
    _pdamp,
    _pelas,
    _pmass,
    _pvisc,
    _rbe2,
    _rbe3,
    _spc,
    _spc1,
)
from ._fields import _REQUIRED, _SAME_AS_ID, _id, _int, _Raw, _re

_SHELL_THETA = (("THETA", "num", None), _re("ZOFFS"))


_ORIENT = (("X1", "num", None), _re("X2", None), _re("X3", None))
_WA_WB = tuple(_re(k) for k in ("W1A", "W2A", "W3A", "W1B", "W2B", "W3B"))
_CELAS_ENDS = (_int("G1"), _int("C1"), _int("G2"), _int("C2"))
_POINTS = (_int("S1"), _int("S2"))
_CORD2 = (_id("CID"), _int("RID", 0), *(_re(k) for k in ("A1", "A2", "A3", "B1", "B2", "B3", "C1", "C2", "C3")))
_CONM1 = tuple(_re(f"M{i}{j}") for i in range(1, 7) for j in range(1, i + 1))  # lower triangle, by rows

_PARSERS: dict[str, Callable[[_Raw], list[Card]]] = {
    "GRID": _fixed(
        _id("ID"), _int("CP"), _re("X1"), _re("X2"), _re("X3"), _int("CD"), ("PS", "dof", None), _int("SEQID"),
        check=_check_grid,
    ),
    "GRDSET": _fixed(None, _int("CP"), None, None, None, _int("CD"), ("PS", "dof", None), _int("SEQID"),
                     check=_check_grid),
    **{name: _fixed(*_CORD2, check=_check_cord2) for name in ("CORD2R", "CORD2C", "CORD2S")},
    **{name: _cord1 for name in ("CORD1R", "CORD1C", "CORD1S")},
    "CBAR": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("GA"), _id("GB"), *_ORIENT, ("OFFT", "any", "GGG"),
        _int("PA"), _int("PB"), *_WA_WB,
        check=_check_cbar,
    ),
    "CBEAM": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("GA"), _id("GB"), *_ORIENT, ("OFFT", "any", "GGG"),
        _int("PA"), _int("PB"), *_WA_WB, _int("SA"), _int("SB"),
        check=_check_cbeam,
    ),
    "CROD": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), _id("G1"), _id("G2")),
    "CONROD": _fixed(_id("EID"), _id("G1"), _id("G2"), _id("MID"), ("A", "real", _REQUIRED), _re("J"), _re("C"),
                     _re("NSM")),
    "PBAR": _fixed(
        _id("PID"), _id("MID"), _re("A"), _re("I1"), _re("I2"), _re("J"), _re("NSM"), None,
        *(_re(k) for k in ("C1", "C2", "D1", "D2", "E1", "E2", "F1", "F2")),
        _re("K1"), _re("K2"), _re("I12"),
    ),
    "PBARL": _pbarl,
    "PBEAM": _pbeam,
    "PBEAML": _pbeaml,
    "PROD": _fixed(_id("PID"), _id("MID"), ("A", "real", _REQUIRED), _re("J"), _re("C"), _re("NSM")),
    "MAT1": _fixed(
        _id("MID"), _re("E", None), _re("G", None), _re("NU", None), _re("RHO"), _re("A"), _re("TREF"), _re("GE"),
        _re("ST", None), _re("SC", None), _re("SS", None), _int("MCSID"),
        check=_check_mat1,
    ),
    "CONM2": _fixed(
        _id("EID"), _id("G"), _int("CID", 0), _re("M"), _re("X1"), _re("X2"), _re("X3"), None,
        *(_re(k) for k in ("I11", "I21", "I22", "I31", "I32", "I33")),
        check=_check_conm2,
    ),
    "CONM1": _fixed(_id("EID"), _id("G"), _int("CID", 0), *_CONM1, check=_check_conm1),
    "CELAS1": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), *_CELAS_ENDS, check=_check_celas),
    "CELAS2": _fixed(_id("EID"), ("K", "real", _REQUIRED), *_CELAS_ENDS, _re("GE"), _re("S"), check=_check_celas),
    "CELAS3": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), *_POINTS, check=_check_scalar_points),
    "CELAS4": _fixed(_id("EID"), ("K", "real", _REQUIRED), *_POINTS, check=_check_scalar_points),
    "PELAS": _pelas,
    **{f"{kind}1": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), *_CELAS_ENDS, check=_check_celas)
       for kind in ("CMASS", "CDAMP")},
    **{f"{kind}2": _fixed(_id("EID"), (key, "real", _REQUIRED), *_CELAS_ENDS, check=_check_celas)
       for kind, key in (("CMASS", "M"), ("CDAMP", "B"))},
    **{f"{kind}3": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), *_POINTS, check=_check_scalar_points)
       for kind in ("CMASS", "CDAMP")},
    **{f"{kind}4": _fixed(_id("EID"), (key, "real", _REQUIRED), *_POINTS, check=_check_scalar_points)
       for kind, key in (("CMASS", "M"), ("CDAMP", "B"))},
    "PMASS": _pmass,
    "PDAMP": _pdamp,
    "CVISC": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), _id("G1"), _id("G2")),
    "PVISC": _pvisc,
    "CBUSH": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("GA"), _int("GB"), *_ORIENT, _int("CID"),
        _re("S", 0.5), _int("OCID", -1), _re("S1", None), _re("S2", None), _re("S3", None),
        check=_check_cbush,
    ),
    "PBUSH": _pbush,
    "RBE2": _rbe2,
    "RBE3": _rbe3,
    "RBAR": _rbar,
    "RROD": _rrod,
    "RBE1": _rbe1,
    "MPC": _mpc,
    "SPC": _spc,
    "SPC1": _spc1,
    "SPCADD": _set_union,
    "MPCADD": _set_union,
    "SPOINT": _spoint,
    "SUPORT": _suport,
    "SUPORT1": _suport1,
    "DMIG": _dmig,
    "EIGRL": _eigrl,
    "EIGR": _eigr,
    "PARAM": _param,
    "MDLPRM": _mdlprm,
    "CQUAD4": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("G1"), _id("G2"), _id("G3"), _id("G4"), *_SHELL_THETA,
        None, None, _int("TFLAG", 0), _re("T1", None), _re("T2", None), _re("T3", None), _re("T4", None),
        check=_check_shell,
    ),
    "CTRIA3": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("G1"), _id("G2"), _id("G3"), *_SHELL_THETA, None,
        None, None, _int("TFLAG", 0), _re("T1", None), _re("T2", None), _re("T3", None),
        check=_check_shell,
    ),
    "PSHELL": _fixed(
        _id("PID"), _int("MID1"), _re("T", None), _int("MID2"), _re("BENDING", 1.0), _int("MID3"),
        _re("SHEAR", 0.833333), _re("NSM"), _re("Z1", None), _re("Z2", None), _int("MID4"),
        check=_check_pshell,
    ),
    "PCOMP": _pcomp,
    "MAT2": _fixed(
        _id("MID"), *(_re(k) for k in ("G11", "G12", "G13", "G22", "G23", "G33", "RHO")),
        *(_re(k) for k in ("A1", "A2", "A3", "TREF", "GE")),
        _re("ST", None), _re("SC", None), _re("SS", None), _int("MCSID"),
    ),
    "MAT8": _fixed(
        _id("MID"), *(("E1", "real", _REQUIRED), ("E2", "real", _REQUIRED), ("NU12", "real", _REQUIRED)),
        ("G12", "real", _REQUIRED), _re("G1Z", None), _re("G2Z", None), _re("RHO"), _re("A1"), _re("A2"), _re("TREF"),
        *(_re(k, None) for k in ("XT", "XC", "YT", "YC", "S")), _re("GE"), _re("F12"), _re("STRN"),
    ),
}

_RIGID = ("RBE2", "RBE3", "RBAR", "RROD", "RBE1")

# Id spaces in which two cards may not share an id (Nastran: element ids are unique across
# all element kinds, property ids across all property kinds); a rigid element may share
# its id with a structural element (a warning, see _check_unique), not with another rigid one.
_ID_SPACES = {
    "grid": ("GRID",),
    "coordinate system": ("CORD2R", "CORD2C", "CORD2S", "CORD1R", "CORD1C", "CORD1S"),
    "element": ("CBAR", "CBEAM", "CROD", "CONROD", "CELAS1", "CELAS2", "CELAS3", "CELAS4", "CMASS1", "CMASS2",
                "CMASS3", "CMASS4", "CDAMP1", "CDAMP2", "CDAMP3", "CDAMP4", "CVISC", "CBUSH", "CONM1", "CONM2",
                "CQUAD4", "CTRIA3"),
    "rigid element": _RIGID,
    "property": ("PBAR", "PBARL", "PBEAM", "PBEAML", "PROD", "PELAS", "PMASS", "PDAMP", "PVISC", "PBUSH", "PSHELL",
                 "PCOMP"),
    "material": ("MAT1", "MAT2", "MAT8"),
    "eigenvalue method": ("EIGR", "EIGRL"),
    "SPCADD set": ("SPCADD",),
    "MPCADD set": ("MPCADD",),
    "PARAM": ("PARAM",),
    "MDLPRM": ("MDLPRM",),
}


def _finish(read: list[Card]) -> dict[str, list[Card]]:
    """The cards read (in deck order) by name, after the passes that need them all: one
    DMIG card per matrix, GRDSET defaults on GRID, unique ids, grids that are not scalar points."""
    read = [c for c in read if c.name != "DMIG"] + _merge_dmig([c for c in read if c.name == "DMIG"])
    _apply_grdset(read)
    _check_unique(read)
    _check_scalar_points_are_not_grids(read)
    cards: dict[str, list[Card]] = {}
    for card in read:
        cards.setdefault(card.name, []).append(card)
    return cards


_GRID_BLANK = {"CP": 0, "CD": 0, "PS": None, "SEQID": None}


def _apply_grdset(read: list[Card]) -> None:
    """GRID fields CP, CD, PS, SEQID left blank take the GRDSET values (QRG, GRDSET: one
    entry at most), else CP = CD = 0; a value given on the GRID (0 too) stays."""
    grdsets = [c for c in read if c.name == "GRDSET"]
    if len(grdsets) > 1:
        first, second = grdsets[:2]
        raise BulkDataError(f"{_where(second.file, second.line, 'GRDSET')}: only one GRDSET is allowed, "
                            f"another at {first.file}:{first.line}")
    defaults = grdsets[0].values if grdsets else {}
    for card in (c for c in read if c.name == "GRID"):
        for key, blank in _GRID_BLANK.items():
            if card.values[key] is None:
                card.values[key] = blank if defaults.get(key) is None else defaults[key]


def _check_unique(read: list[Card]) -> None:
    spaces = {name: space for space, names in _ID_SPACES.items() for name in names}
    seen: dict[tuple[str, Value], Card] = {}
    for card in read:
        space = spaces.get(card.name)
        if space is None:
            continue
        other = seen.setdefault((space, card.id), card)
        if other is not card:
            raise BulkDataError(
                f"{_where(card.file, card.line, card.name, card.id)}: duplicate {space} id "
                f"{card.id}, already defined by {other.name} at {other.file}:{other.line}"
            )
    for card in (c for c in read if c.name in _RIGID and ("element", c.id) in seen):
        other = seen["element", card.id]
        warnings.warn(
            f"{_where(card.file, card.line, card.name, card.id)}: element id {card.id} is also {other.name} "
            f"{other.id} at {other.file}:{other.line} (Nastran accepts a rigid element sharing the id of "
            "another element; both are kept)",
            UserWarning,
            stacklevel=4,
        )


def _check_scalar_points_are_not_grids(read: list[Card]) -> None:
    """A scalar point (SPOINT) id may not be a grid id (one id space for points)."""
    runs = sorted((a, b, c) for c in read if c.name == "SPOINT" for a, b in c["ID"].runs)
    starts = [a for a, _, _ in runs]
    reach = []  # highest id covered by the runs up to each one
    for _, b, _ in runs:
        reach.append(max(b, reach[-1]) if reach else b)
    for grid in (c for c in read if c.name == "GRID" and runs):
        k = bisect.bisect_right(starts, grid.id) - 1
        if k >= 0 and reach[k] >= grid.id:
            spoint = next(c for a, b, c in runs[: k + 1] if a <= grid.id <= b)
            raise grid.error("ID", f"grid {grid.id} is also a scalar point (SPOINT at {spoint.file}:{spoint.line})")
