"""Readers of the supported bulk-data cards: field layouts, value checks, unique ids.

One parser per card name (``_PARSERS``): fixed layouts from a schema with a check of the
values (GRID, CORD2R, CBAR, CBEAM, CROD, PBAR, PROD, MAT1, CONM2, CELAS1, CELAS2, CBUSH,
CQUAD4, CTRIA3, PSHELL, MAT2, MAT8), and the variable layouts read field by field (PELAS,
SPC, SPC1, RBE2, RBE3, MPC, PARAM, PBARL, PBEAM, PBUSH, PCOMP); what Nastran allows but
the model does not support is refused with a located :class:`BulkDataError` (MSC Nastran
QRG, per card). :func:`_check_unique` refuses two cards with one id in the same id space
(elements, properties, materials, ...).

The parsers and checks: fixed layouts in :mod:`jaxfem.io._cards_checks`, variable ones in
:mod:`jaxfem.io._cards_variable`, PCOMP in :mod:`jaxfem.io._cards_shells`; here the table
of parsers and the id spaces.
"""

from __future__ import annotations

from collections.abc import Callable

from ._bulkdata import BulkDataError, Card, Value, _where
from ._cards_checks import (
    _check_cbar,
    _check_cbeam,
    _check_cbush,
    _check_celas,
    _check_conm2,
    _check_cord2r,
    _check_grid,
    _check_mat1,
    _check_pshell,
    _check_shell,
    _fixed,
)
from ._cards_shells import _pcomp
from ._cards_variable import _mpc, _param, _pbarl, _pbeam, _pbush, _pelas, _rbe2, _rbe3, _spc, _spc1
from ._fields import _REQUIRED, _SAME_AS_ID, _id, _int, _Raw, _re

_SHELL_THETA = (("THETA", "num", None), _re("ZOFFS"))


_ORIENT = (("X1", "num", None), _re("X2", None), _re("X3", None))
_WA_WB = tuple(_re(k) for k in ("W1A", "W2A", "W3A", "W1B", "W2B", "W3B"))
_CELAS_ENDS = (_int("G1"), _int("C1"), _int("G2"), _int("C2"))

_PARSERS: dict[str, Callable[[_Raw], list[Card]]] = {
    "GRID": _fixed(
        _id("ID"), _int("CP", 0), _re("X1"), _re("X2"), _re("X3"), _int("CD", 0), ("PS", "dof", None), _int("SEQID"),
        check=_check_grid,
    ),
    "CORD2R": _fixed(
        _id("CID"), _int("RID", 0), *(_re(k) for k in ("A1", "A2", "A3", "B1", "B2", "B3", "C1", "C2", "C3")),
        check=_check_cord2r,
    ),
    "CBAR": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("GA"), _id("GB"), *_ORIENT, ("OFFT", "word", "GGG"),
        _int("PA"), _int("PB"), *_WA_WB,
        check=_check_cbar,
    ),
    "CBEAM": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("GA"), _id("GB"), *_ORIENT, ("OFFT", "any", "GGG"),
        _int("PA"), _int("PB"), *_WA_WB, _int("SA"), _int("SB"),
        check=_check_cbeam,
    ),
    "CROD": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), _id("G1"), _id("G2")),
    "PBAR": _fixed(
        _id("PID"), _id("MID"), _re("A"), _re("I1"), _re("I2"), _re("J"), _re("NSM"), None,
        *(_re(k) for k in ("C1", "C2", "D1", "D2", "E1", "E2", "F1", "F2")),
        _re("K1"), _re("K2"), _re("I12"),
    ),
    "PBARL": _pbarl,
    "PBEAM": _pbeam,
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
    "CELAS1": _fixed(_id("EID"), _id("PID", _SAME_AS_ID), *_CELAS_ENDS, check=_check_celas),
    "CELAS2": _fixed(_id("EID"), ("K", "real", _REQUIRED), *_CELAS_ENDS, _re("GE"), _re("S"), check=_check_celas),
    "PELAS": _pelas,
    "CBUSH": _fixed(
        _id("EID"), _id("PID", _SAME_AS_ID), _id("GA"), _int("GB"), *_ORIENT, _int("CID"),
        _re("S", 0.5), _int("OCID", -1), _re("S1", None), _re("S2", None), _re("S3", None),
        check=_check_cbush,
    ),
    "PBUSH": _pbush,
    "RBE2": _rbe2,
    "RBE3": _rbe3,
    "MPC": _mpc,
    "SPC": _spc,
    "SPC1": _spc1,
    "PARAM": _param,
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

# Id spaces in which two cards may not share an id (Nastran: element ids are unique across
# all element kinds, property ids across all property kinds).
_ID_SPACES = {
    "grid": ("GRID",),
    "coordinate system": ("CORD2R",),
    "element": ("CBAR", "CBEAM", "CROD", "CELAS1", "CELAS2", "CBUSH", "CONM2", "RBE2", "RBE3", "CQUAD4", "CTRIA3"),
    "property": ("PBAR", "PBARL", "PBEAM", "PROD", "PELAS", "PBUSH", "PSHELL", "PCOMP"),
    "material": ("MAT1", "MAT2", "MAT8"),
    "PARAM": ("PARAM",),
}


def _check_unique(cards: dict[str, list[Card]]) -> None:
    for space, names in _ID_SPACES.items():
        seen: dict[Value, Card] = {}
        for card in sorted((c for name in names for c in cards.get(name, [])), key=lambda c: c.line):
            other = seen.setdefault(card.id, card)
            if other is not card:
                raise BulkDataError(
                    f"{_where(card.file, card.line, card.name, card.id)}: duplicate {space} id "
                    f"{card.id}, already defined by {other.name} at {other.file}:{other.line}"
                )
