"""Nastran bulk-data reader: formats, continuations, reals, unknown cards, every error path."""

import re
from pathlib import Path

import pytest

from jaxfem.io import BulkDataError, read_bdf, read_bdf_text

DATA = Path(__file__).parent / "data"


def _raises(text: str, *parts: str) -> str:
    """Parse ``text`` expecting a BulkDataError whose message contains every part, in order."""
    with pytest.raises(BulkDataError, match=".*".join(re.escape(p) for p in parts)) as info:
        read_bdf_text(text, name="m.bdf")
    return str(info.value)


def test_three_formats_give_identical_cards():
    free, small, large = (read_bdf(DATA / f"frame_{k}.bdf") for k in ("free", "small", "large"))
    assert free.cards == small.cards == large.cards  # the fixtures differ in their executive control (SOL)
    assert sum(len(c) for c in free.cards.values()) == 44  # PELAS and SPC cards split per entry
    assert free.unknown == {}


def test_small_field_columns_and_source():
    text = "$ c\nGRID    17      0       1.5     -2.     3.-1    0       123\n"
    (grid,) = read_bdf_text(text, name="m.bdf")["GRID"]
    assert grid.values == {"ID": 17, "CP": 0, "X1": 1.5, "X2": -2.0, "X3": 0.3, "CD": 0, "PS": 123, "SEQID": None}
    assert (grid.file, grid.line, grid.fields["X3"]) == ("m.bdf", 2, (2, 6))


def test_large_field_two_lines_per_row():
    text = (
        "GRID*                 17               0             1.5             -2.*G17\n"
        "*G17                 .3               0\n"
    )
    (grid,) = read_bdf_text(text)["GRID"]
    assert (grid["ID"], grid["X1"], grid["X2"], grid["X3"], grid["CD"]) == (17, 1.5, -2.0, 0.3, 0)
    assert grid.fields["X3"] == (2, 6)  # second physical line, QRG field 6


def test_free_field_large_and_tabs():
    text = "GRID*,5,,1.,2.\n*,3.\nGRID\t6\t\t4.\t5.\t6.\n"
    g5, g6 = read_bdf_text(text)["GRID"]
    assert (g5["X1"], g5["X2"], g5["X3"]) == (1.0, 2.0, 3.0)
    assert (g6["X1"], g6["X2"], g6["X3"]) == (4.0, 5.0, 6.0)


@pytest.mark.parametrize(
    "lines",
    [
        ["CBAR,1,2,3,4,0.,0.,1.,,+A", "+A,,,0.,0.,0.1"],  # explicit markers
        ["CBAR,1,2,3,4,0.,0.,1.", ",,,0.,0.,0.1"],  # implicit: blank field 1
        ["CBAR,1,2,3,4,0.,0.,1.", "+,,,0.,0.,0.1"],  # implicit: + alone
        ["CBAR    1       2       3       4       0.      0.      1.              +A",
         "+A                      0.      0.      0.1"],
        ["CBAR    1       2       3       4       0.      0.      1.",
         "                        0.      0.      0.1"],
        ["CBAR*   1               2               3               4               *",
         "*       0.              0.              1.",
         "*                                       0.              0.",
         "*       0.1"],
    ],
)
def test_continuations(lines):
    (bar,) = read_bdf_text("\n".join(lines) + "\n")["CBAR"]
    assert (bar["X3"], bar["W3A"], bar["OFFT"], bar["PA"]) == (1.0, 0.1, "GGG", None)


@pytest.mark.parametrize(
    "text, value",
    [("7.2+10", 7.2e10), ("1.-3", 1e-3), ("-2.5-4", -2.5e-4), ("1.E3", 1e3), (".5", 0.5), ("1.D-3", 1e-3),
     ("1.", 1.0), ("-.5e+2", -50.0), ("+3.5", 3.5), ("2.0E+00", 2.0), ("1.5d2", 150.0)],
)
def test_nastran_reals(text, value):
    assert read_bdf_text(f"GRID,1,,{text}\n")["GRID"][0]["X1"] == value


@pytest.mark.parametrize("text", ["1", "1.2.3", "E5", "abc", "1.E", "--1."])
def test_bad_reals(text):
    _raises(f"GRID,1,,{text}\n", "m.bdf:1: GRID 1 field 4 (X1): expected a real number", repr(text))


def test_comments_blank_lines_executive_and_enddata():
    text = (
        "SOL 103\nCEND\nTITLE = x\nBEGIN BULK $ from here\n"
        "$ GRID,99\n\nGRID,1,,0.,0.,0. $ trailing\n"
        "ENDDATA\nGRID,2,,whatever\n"
    )
    bulk = read_bdf_text(text)
    assert [g.id for g in bulk["GRID"]] == [1]
    assert bulk["GRID"][0].line == 7


def test_unknown_cards_are_collected_with_locations():
    text = "GRID,1\nCHEXA,1,1,1,2,3,4,5,6\n,7,8\nCHEXA,2,1,1,2,3,4,5,6\nFREQ1,10,1.,1.,10\n"
    bulk = read_bdf_text(text, name="m.bdf")
    assert bulk.unknown == {"CHEXA": [("m.bdf", 2), ("m.bdf", 4)], "FREQ1": [("m.bdf", 5)]}
    assert "CHEXA x2 (m.bdf:2, m.bdf:4)" in bulk.report()
    assert "GRID     1" in bulk.report()


def test_variable_cards():
    text = (
        "SPC1,3,123,1,THRU,4,\n,9\n"
        "SPC,3,1,12,0.,2,3\n"
        "RBE2,7,1,123456,2,,3\n,4,1.-5\n"
        "PELAS,41,1.+5,,,42,2.+5\n"
        "PARAM,COUPMASS,1\nPARAM,WTMASS,1.\n"
    )
    bulk = read_bdf_text(text)
    assert bulk["SPC1"][0].values == {"SID": 3, "C": 123, "G": (1, 2, 3, 4, 9)}
    assert [(c["G"], c["C"], c["D"]) for c in bulk["SPC"]] == [(1, 12, 0.0), (2, 3, 0.0)]
    assert (bulk["RBE2"][0]["GM"], bulk["RBE2"][0]["ALPHA"]) == ((2, 3, 4), 1e-5)
    assert [(p.id, p["K"]) for p in bulk["PELAS"]] == [(41, 1e5), (42, 2e5)]
    assert [(p.id, p["V1"]) for p in bulk["PARAM"]] == [("COUPMASS", 1), ("WTMASS", 1.0)]


def test_element_defaults_and_orientation_grid():
    bulk = read_bdf_text("CBAR,5,,1,2,9\nCBUSH,6,,1,2\nCELAS2,7,1.,3,2\nCONM2,8,1\n")
    bar = bulk["CBAR"][0]
    assert (bar["PID"], bar["G0"], bar["X1"], bar["OFFT"]) == (5, 9, None, "GGG")
    bush = bulk["CBUSH"][0]
    assert (bush["PID"], bush["S"], bush["CID"], bush["X1"], bush["G0"]) == (6, 0.5, None, None, None)
    assert (bulk["CELAS2"][0]["G2"], bulk["CELAS2"][0]["C2"]) == (None, None)
    assert (bulk["CONM2"][0]["M"], bulk["CONM2"][0]["CID"]) == (0.0, 0)


def test_pbeam_constant_section_with_stations_and_footer():
    text = (
        "PBEAM,4,1,3.-3,9.-6,4.-6,,1.2-5,0.5\n"
        ",0.1,0.1\n"
        ",YES,0.5,3.-3\n,0.1,0.1\n"
        ",YESA,1.\n"
        ",0.8,,0.1\n"
    )
    (beam,) = read_bdf_text(text)["PBEAM"]
    assert (beam["A"], beam["I12"], beam["NSM"], beam["K1"], beam["K2"], beam["S2"]) == (3e-3, 0.0, 0.5, 0.8, 1.0, 0.0)
    (short,) = read_bdf_text("PBEAM,4,1,3.-3\n")["PBEAM"]
    assert (short["K1"], short["K2"], short["J"]) == (1.0, 1.0, 0.0)


def test_pbush_rows():
    (bush,) = read_bdf_text("PBUSH,5,K,1.,,3.\n,,RCV,1.,1.\n,,B,2.\n")["PBUSH"]
    assert bush["K"] == (1.0, 0.0, 3.0, 0.0, 0.0, 0.0)
    assert (bush["B"][0], bush["RCV"]) == (2.0, (1.0, 1.0, None, None))


def test_pbarl_dimensions_and_nsm():
    (box,) = read_bdf_text("PBARL,2,1,,BOX\n,0.1,0.12,0.006,0.005,1.5\n")["PBARL"]
    assert (box["DIM1"], box["DIM4"], box["NSM"], box["GROUP"]) == (0.1, 0.005, 1.5, "MSCBML0")


# --- errors: each names file, line, card (and id) and field ------------------------------


def test_error_integer_expected():
    expected = "m.bdf:17: CBAR 1001 field 4 (GA): expected an integer, got '1.5'"
    assert _raises("$\n" * 16 + "CBAR,1001,1,1.5,2,0.,0.,1.\n", expected) == expected


@pytest.mark.parametrize(
    "text, parts",
    [
        ("GRID,x\n", ("m.bdf:1: GRID field 2 (ID): expected an integer, got 'x'",)),
        ("GRID,0\n", ("m.bdf:1: GRID field 2 (ID): expected an id in 1..99,999,999, got '0'",)),
        ("CBAR,1,1,1\n", ("m.bdf:1: CBAR 1 field 5 (GB): required field is blank",)),
        ("PROD,3,1\n", ("m.bdf:1: PROD 3 field 4 (A): required field is blank",)),
        ("MAT1,3,,,0.3\n", ("m.bdf:1: MAT1 3 field 3 (E): E and G may not both be blank",)),
        ("GRID,1,,0.,0.,0.,,127\n", ("GRID 1 field 8 (PS): expected component digits 1-6",)),
        ("RBE2,1,2,112,3\n", ("RBE2 1 field 4 (CM): expected component digits",)),
        ("GRID,1,,0.,0.,0.,-2\n", ("m.bdf:1: GRID 1 field 7 (CD): coordinate system id must be >= -1, got -2",)),
        ("CBAR,1,1,1,2,0.,0.,1.,GOO\n", ("CBAR 1 field 9 (OFFT): OFFT 'GOO' is not supported",)),
        ("CBAR,1,1,1,2,0.,0.,1.\n,1\n", ("m.bdf:2: CBAR 1 field 2 (PA): pin flags are not supported",)),
        ("CBAR,1,1,1,2,0.,0.,1.\n,,456\n", ("m.bdf:2: CBAR 1 field 3 (PB): pin flags",)),
        ("CBAR,1,1,1,2\n", ("CBAR 1 field 6 (X1/G0): an orientation vector", "BAROR is not supported")),
        ("CBAR,1,1,1,2,9,1.\n", ("CBAR 1 field 7 (X2): must be blank when field 6 is the orientation grid G0",)),
        ("CBEAM,1,1,1,2,0.,0.,1.,0.5\n", ("CBEAM 1 field 9 (OFFT/BIT): BIT",)),
        ("CBEAM,1,1,1,2,0.,0.,1.\n,\n,5\n", ("m.bdf:3: CBEAM 1 field 2 (SA): warping scalar points",)),
        ("CONM2,1,2,-3,1.\n", ("m.bdf:1: CONM2 1 field 4 (CID): CID must be >= -1, got -3",)),
        ("CBUSH,1,1,2\n", ("CBUSH 1 field 5 (GB): grounded CBUSH elements",)),
        ("CBUSH,1,1,2,3,,,,0\n,0.5,2\n", ("m.bdf:2: CBUSH 1 field 3 (OCID): spring offsets",)),
        ("CBUSH,1,1,2,3,,,,0\n,1.5\n", ("CBUSH 1 field 2 (S): S must lie in [0, 1]",)),
        ("CELAS2,1,1.,2,7\n", ("CELAS2 1 field 5 (C1): component of point 2 must be 1..6 (a grid) or 0/blank",)),
        ("CELAS2,1,1.,,2\n", ("CELAS2 1 field 5 (C1): component must be blank or 0 for a grounded end",)),
        ("CELAS1,1,1,0,0,0,0\n", ("CELAS1 1 field 4 (G1): both ends are grounded",)),
        ("PBARL,2,1,,FOO\n,1.,2.\n", ("PBARL 2 field 5 (TYPE): section type 'FOO' is not in the MSC library",)),
        ("PBARL,2,1,MYLIB,BAR\n,1.,2.\n", ("PBARL 2 field 4 (GROUP): section library 'MYLIB'",)),
        ("PBARL,2,1,,BAR\n,1.\n", ("m.bdf:2: PBARL 2 field 3 (DIM2): required field is blank",)),
        ("PBARL,2,1,,ROD\n,1.,0.1,7.\n", ("m.bdf:2: PBARL 2 field 4: unexpected value",)),
        ("PBEAM,4,1,1.,1.,1.\n,\n,YESA,.5,2.\n", ("m.bdf:3: PBEAM 4 field 3 (X/XB): the last station must be end B",)),
        ("PBEAM,4,1,1.,1.,1.\n,\n,MAYBE,1.\n", ("PBEAM 4 field 2 (SO): expected YES, YESA or NO",)),
        ("PBEAM,4,1,1.\n,\n,,,,,,,1.\n", ("m.bdf:3: PBEAM 4 field 8 (CW(A)): CW(A) must be blank or 0.0",)),
        ("PBUSH,5,M,1.\n", ("PBUSH 5 field 3 (K/B/GE/RCV): row 'M' is not supported",)),
        ("PBUSH,5,K,1.\n,,K,2.\n", ("m.bdf:2: PBUSH 5 field 3 (K): row K is given twice",)),
        ("PBUSH,5,K,1.\n,,,2.\n", ("m.bdf:2: PBUSH 5 field 4: a value needs a row keyword",)),
        ("SPC1,1,123,THRU,4\n", ("SPC1 1 field 4 (THRU): THRU must follow a grid id",)),
        ("SPC1,1,123,5,THRU,4\n", ("SPC1 1 field 6 (G): THRU range ends below its start",)),
        ("SPC1,1,123\n", ("SPC1 1 field 4 (G1): required field is blank",)),
        ("SPC,1,2,0\n", ("SPC 1 field 4 (C): expected component digits",)),
        ("RBE2,1,2,123\n", ("RBE2 1 field 5 (GM1): required field is blank",)),
        ("RBE2,1,2,123,3,THRU,5\n", ("RBE2 1 field 6 (ALPHA): expected a real number", "'THRU'")),
        ("PELAS,41,1.,,,42\n", ("PELAS 42 field 7 (K): required field is blank",)),
        ("PARAM,COUPMASS,1,2,3\n", ("PARAM COUPMASS field 5: unexpected value",)),
        ("PBAR,1,1,1.,1.,1.,1.,0.,7.\n", ("PBAR 1 field 9: must be blank, got '7.'",)),
    ],
)
def test_field_errors(text, parts):
    _raises(text, *parts)


def test_mismatched_continuation_markers_on_consecutive_lines_are_a_warning():
    """Nastran reads a continuation line right after its card whatever its marker."""
    with pytest.warns(UserWarning, match=r"m.bdf:2: CBAR 1 field 1: continuation marker '\+B' does not match '\+A'"):
        bulk = read_bdf_text("CBAR,1,1,1,2,0.,0.,1.,,+A\n+B,,,0.1\n", name="m.bdf")
    assert bulk["CBAR"][0]["W1A"] == 0.1


@pytest.mark.parametrize(
    "text, parts",
    [
        ("+A,1,2\n", ("m.bdf:1: +A: continuation line with no card before it",)),
        ("GRID,1,2,3,4,5,6,7,8,9,10,11\n", ("m.bdf:1: GRID: free-field line has 12 fields",)),
        ("GRID*,1,2,3,4,5,6\n", ("m.bdf:1: GRID*: free-field line has 7 fields; at most 6",)),
        ("GRID    1" + " " * 80 + "2\n", ("m.bdf:1: GRID: fixed-format line is 90 columns long",)),
        ("INCLUDE 'other.bdf'\n", ("m.bdf:1: INCLUDE: cannot read 'other.bdf' (tried ", "other.bdf): No such file")),
        ("GRID,1\ninclude 'a,b.bdf'\n", ("m.bdf:2: INCLUDE: cannot read 'a,b.bdf'",)),
        ("1.0     2\n", ("m.bdf:1: 1.0: field 1 is not a card name",)),
        ("GRID,1\nGRID,1\n", ("m.bdf:2: GRID 1: duplicate grid id 1, already defined by GRID at m.bdf:1",)),
        ("CROD,7,1,1,2\nCBAR,7,1,1,2,0.,0.,1.\n",
         ("m.bdf:2: CBAR 7: duplicate element id 7, already defined by CROD at m.bdf:1",)),
        ("PBAR,3,1,1.\nPROD,3,1,1.\n", ("m.bdf:2: PROD 3: duplicate property id 3",)),
        ("MAT1,3,1.\nMAT1,3,2.\n", ("duplicate material id 3",)),
        ("PARAM,POST,-1\nPARAM,POST,0\n", ("m.bdf:2: PARAM POST: duplicate PARAM id POST",)),
    ],
)
def test_line_errors(text, parts):
    _raises(text, *parts)


def test_read_bdf_names_the_file(tmp_path):
    path = tmp_path / "model.bdf"
    path.write_text("GRID,1,,0.,0.,x\n")
    with pytest.raises(BulkDataError, match=re.escape(f"{path}:1: GRID 1 field 6 (X3)")):
        read_bdf(path)
