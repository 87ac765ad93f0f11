"""Strict reader for Nastran bulk data: free field, small field (8) and large field (16).

The reader turns text into :class:`BulkData`: cards of the supported kinds with typed
raw values (int, float, str, tuple, or None for a blank field without default), each
remembering where it came from. Cards of any other kind are listed in
:attr:`BulkData.unknown`, never silently dropped (:func:`jaxfem.build_model` refuses
those that may define structure, see :meth:`BulkData.structural_unknown`). Every malformed or unsupported entry
raises :class:`BulkDataError` naming file, line, card and field, e.g.
``model.bdf:17: CBAR 1001 field 4 (GA): expected an integer, got '1.5'``.

Format rules (MSC Nastran QRG, "Bulk Data Entry Format"):

- Lines end at ``\\n`` or ``\\r\\n`` (a leading UTF-8 byte-order mark is dropped); ``$``
  starts a comment; blank lines are skipped; anything before ``BEGIN BULK`` (if
  present) and after ``ENDDATA`` is ignored; ``INCLUDE`` is refused.
- Fields hold printable ASCII; reals are finite; ids are integers in 1..99,999,999,
  other integers fit in 32 bits (see :mod:`jaxfem.io._fields`).
- A line holding a comma is free field; otherwise fixed columns, 80 at most (tabs
  expand to 8-column stops). Field 1 is the card name (``NAME*`` = large field);
  small-field lines carry 8 data fields, large-field lines 4 (two lines per row of 8).
- A line whose field 1 is blank or starts with ``+``/``*`` continues the card above
  (``*`` = large field). Markers in field 10 of a line and field 1 of the next must
  match when both are given; a field-10 marker with no continuation after it is an error.
- Reals need a decimal point: ``1.``, ``.5``, ``1.E3``, ``1.D-3``, ``7.2+10``, ``-2.5-4``.

Field numbers in messages follow the QRG: 2..9 within each row of eight data fields,
on the physical line where the field is.

Cards (values keyed by QRG field names; see ``jaxfem.io._cards._PARSERS``) and what is refused:

- GRID (CD must be 0/blank), CORD2R;
- CBAR, CBEAM: orientation X1-X3 or G0 (``G0`` key), OFFT GGG/BGG only, no pin flags
  PA/PB, CBEAM without BIT and SA/SB; CROD;
- PBAR, PBARL (BAR, ROD, TUBE, BOX; ``DIM1..`` keys), PBEAM (constant section: end-A
  values, footer K1/K2; tapered stations, NSI, CW, M, N refused), PROD, MAT1;
- CONM2 (CID 0/blank or -1), CELAS1 + PELAS (two per card, split), CELAS2 (a grounded
  end has G and C None), CBUSH (GB required, OCID -1/blank) + PBUSH (rows K, B, GE, RCV);
- CQUAD4, CTRIA3 (field 8: a real is ``THETA`` [deg], an integer ``MCID``; ``ZOFFS``,
  ``TFLAG`` 0/1, corner thicknesses ``T1..Tn``, blank None), PSHELL (T required; MID1..MID4,
  ``BENDING`` = 12I/T³, ``SHEAR`` = TS/T; plane strain MID2 = -1 refused), PCOMP (``MID``,
  ``T``, ``THETA``, ``SOUT`` tuples over the listed plies, a blank MIDi/Ti taken from the
  ply before; LAM blank or SYM, MEM/BEND/SMEAR/SMCORE refused), MAT2, MAT8 (E1, E2, NU12,
  G12 required);
- RBE2 (``GM`` tuple), RBE3 (``GROUPS`` of (WT, C, grids); UM refused, ALPHA kept
  unused), MPC (``TERMS`` of (G, C, A), single components 1..6, A1 ≠ 0), SPC (one card
  per G/C/D triplet), SPC1 (``G`` an :class:`IdRanges`: THRU ranges are not expanded), PARAM.

Here the entry points; the result types are in :mod:`jaxfem.io._bulkdata`, lines and
fields in :mod:`jaxfem.io._fields`, the card readers in :mod:`jaxfem.io._cards`.
"""

from __future__ import annotations

from pathlib import Path

from ._bulkdata import BulkData, Card
from ._cards import _PARSERS, _check_unique
from ._fields import _logical_cards


def read_bdf(path: str | Path) -> BulkData:
    """Read a Nastran bulk-data file (see the module docstring for the accepted format)."""
    path = Path(path)
    return read_bdf_text(path.read_text(encoding="utf-8", errors="replace"), name=str(path))


def read_bdf_text(text: str, name: str = "<string>") -> BulkData:
    """Parse bulk data held in a string; ``name`` stands for the file in messages."""
    cards: dict[str, list[Card]] = {}
    unknown: dict[str, list[tuple[str, int]]] = {}
    for raw in _logical_cards(text, name):
        parser = _PARSERS.get(raw.name)
        if parser is None:
            unknown.setdefault(raw.name, []).append((name, raw.line))
            continue
        cards.setdefault(raw.name, []).extend(parser(raw))
    _check_unique(cards)
    return BulkData(cards=cards, unknown=unknown, source=name)
