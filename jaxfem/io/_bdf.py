"""Strict reader for Nastran decks: bulk data in free field, small field (8) and large field
(16), INCLUDE files, executive and case control.

The reader turns text into :class:`BulkData`: cards of the supported kinds with typed
raw values (int, float, str, tuple, or None for a blank field without default), each
remembering the file and line it came from; the case control; the files read. Cards of
any other kind are listed in :attr:`BulkData.unknown`, never silently dropped
(:func:`jaxfem.build_model` refuses those that may define structure, see
:meth:`BulkData.structural_unknown`; :meth:`BulkData.card_status` says, per card name,
what became of it). Every malformed or unsupported entry raises :class:`BulkDataError`
naming file, line, card and field, e.g.
``model.bdf:17: CBAR 1001 field 4 (GA): expected an integer, got '1.5'``.

Format rules (MSC Nastran QRG, "Bulk Data Entry Format", "INCLUDE"):

- Lines end at ``\\n`` or ``\\r\\n`` (a leading UTF-8 byte-order mark is dropped); ``$``
  starts a comment; blank lines are skipped; ``INCLUDE`` anywhere reads another file,
  its path relative to the including file (:mod:`jaxfem.io._deck`); text before
  ``BEGIN BULK`` (if present) is executive and case control (:mod:`jaxfem.io._case`);
  nothing after ``ENDDATA`` is read.
- Fields hold printable ASCII; reals are finite; ids are integers in 1..99,999,999,
  other integers fit in 32 bits (see :mod:`jaxfem.io._fields`).
- A line holding a comma is free field; otherwise fixed columns, 80 at most (tabs
  expand to 8-column stops). Field 1 is the card name (``NAME*`` = large field);
  small-field lines carry 8 data fields, large-field lines 4 (two lines per row of 8).
- A line whose field 1 is blank or starts with ``+``/``*`` continues the card above
  (``*`` = large field), in the same file. Markers in field 10 of a line and field 1 of
  the next must match when both are given; text in field 10 with no continuation after
  it is a comment (a ``UserWarning``).
- Reals need a decimal point: ``1.``, ``.5``, ``1.E3``, ``1.D-3``, ``7.2+10``, ``-2.5-4``.

Field numbers in messages follow the QRG: 2..9 within each row of eight data fields,
on the physical line where the field is.

Cards (values keyed by QRG field names; see ``jaxfem.io._cards._PARSERS``) and what is refused:

- GRID (blank CP, CD, PS, SEQID from GRDSET), GRDSET, SPOINT (``ID`` an :class:`IdRanges`),
  CORD2R/C/S, CORD1R/C/S (two per card);
- CBAR, CBEAM: orientation X1-X3 or G0 (``G0`` key), OFFT GGG/BGG only, no pin flags
  PA/PB, CBEAM without BIT and SA/SB; CROD, CONROD;
- PBAR, PBARL and PBEAML (the MSC library, ``PBARL_DIMENSIONS``; PBARL ``DIM1..``, PBEAML
  ``DIMS``, ``XXB``, ``NSM`` per station), PBEAM (end-A values and ``STATIONS``; NSI, CW,
  M, N refused), PROD, MAT1;
- CONM2, CONM1 (``M11``..``M66``), CELAS1-4 + PELAS, CMASS1-4 + PMASS, CDAMP1-4 + PDAMP
  (two or four properties per card, split), CVISC + PVISC; scalar ends: a grounded end
  has G and C None, a scalar point C 0; CBUSH (GB required, OCID -1/blank) + PBUSH
  (rows K, B, GE, RCV);
- CQUAD4, CTRIA3 (field 8: a real is ``THETA`` [deg], an integer ``MCID``; ``ZOFFS``,
  ``TFLAG`` 0/1, corner thicknesses ``T1..Tn``, blank None), PSHELL (T required; MID1..MID4,
  ``BENDING`` = 12I/T³, ``SHEAR`` = TS/T; plane strain MID2 = -1 refused), PCOMP (``MID``,
  ``T``, ``THETA``, ``SOUT`` tuples over the listed plies, a blank MIDi/Ti taken from the
  ply before; LAM blank or SYM, MEM/BEND/SMEAR/SMCORE refused), MAT2, MAT8 (E1, E2, NU12,
  G12 required);
- RBE2 (``GM`` tuple), RBE3 (``GROUPS`` of (WT, C, grids); UM refused, ALPHA kept
  unused), RBAR, RROD, RBE1 (``GN``, ``CN``, ``GM``, ``CM`` tuples), MPC (``TERMS`` of (G,
  C, A), C 1..6 or 0 at a scalar point, A1 ≠ 0), SPC (one card per G/C/D triplet), SPC1
  (``G`` an :class:`IdRanges`: THRU ranges are not expanded), SPCADD, MPCADD (``S``
  tuple), SUPORT, SUPORT1 (one card per point), PARAM;
- DMIG (one card per matrix: ``IFO`` 1 or 6, real, ``ENTRIES`` of (GJ, CJ, GI, CI, A)),
  EIGRL, EIGR.

Here the entry points; the result types are in :mod:`jaxfem.io._bulkdata`, lines and
fields in :mod:`jaxfem.io._fields`, the card readers in :mod:`jaxfem.io._cards`.
"""

from __future__ import annotations

from pathlib import Path

from ._bulkdata import BulkData, Card
from ._cards import _PARSERS, _finish
from ._case import _case_control
from ._deck import _deck
from ._fields import _logical_cards


def read_bdf(path: str | Path) -> BulkData:
    """Read a Nastran deck (see the module docstring for the accepted format); INCLUDE
    paths are relative to the directory of the including file."""
    path = Path(path)
    return read_bdf_text(path.read_text(encoding="utf-8", errors="replace"), name=str(path))


def read_bdf_text(text: str, name: str = "<string>") -> BulkData:
    """Parse a deck held in a string; ``name`` stands for the file in messages, and INCLUDE
    paths are relative to its directory (the current directory for ``"<string>"``)."""
    bulk, before, files = _deck(text, name)
    read: list[Card] = []
    unknown: dict[str, list[tuple[str, int]]] = {}
    for raw in _logical_cards(bulk):
        parser = _PARSERS.get(raw.name)
        if parser is None:
            unknown.setdefault(raw.name, []).append((raw.file, raw.line))
            continue
        read.extend(parser(raw))
    return BulkData(
        cards=_finish(read),
        unknown=unknown,
        source=name,
        case_control=None if before is None else _case_control(before),
        files=files,
    )
