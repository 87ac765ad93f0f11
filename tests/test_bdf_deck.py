"""Nastran decks as Nastran reads them: INCLUDE files, executive and case control, field-10
comments, and what becomes of each card (read, ignored, unsupported)."""

import re
import warnings
from pathlib import Path

import pytest

from jaxfem.io import BulkDataError, CaseControl, Subcase, read_bdf, read_bdf_text

BULK = (
    "GRID,1,,0.,0.,0.,,123456\n"
    "GRID,2,,1.,0.,0.\n"
    "CBAR,10,1,1,2,0.,0.,1.\n"
    "PBAR,1,1,1.-3,1.-6,1.-6,2.-6\n"
    "MAT1,1,2.1+11,,0.3,7850.\n"
    "EIGRL,10,,,6\n"
    "CHEXA,20,1,1,2,3,4,5,6\n,7,8\n"
)
CASE = "SOL 103\nCEND\nTITLE = beam\nMETHOD = 10\nSPC = 1\nSUBCASE 1\nBEGIN BULK\n"


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)


def _raises(text: str, *parts: str, name: str = "m.bdf") -> str:
    with pytest.raises(BulkDataError, match=".*".join(re.escape(p) for p in parts)) as info:
        read_bdf_text(text, name=name)
    return str(info.value)


# --- INCLUDE -----------------------------------------------------------------------------


def test_deck_split_over_include_files_equals_the_merged_deck(tmp_path):
    lines = BULK.splitlines(keepends=True)
    _write(tmp_path, {
        "merged.bdf": CASE + BULK + "ENDDATA\n",
        "split.bdf": "SOL 103\nCEND\nINCLUDE 'case/c.inc'\nBEGIN BULK\nINCLUDE 'model/grids.bdf'\n"
                     + "".join(lines[2:4]) + "INCLUDE \"model/rest.bdf\"\nENDDATA\n",
        "case/c.inc": "TITLE = beam\nMETHOD = 10\nSPC = 1\nSUBCASE 1\n",
        "model/grids.bdf": "".join(lines[:2]),
        "model/rest.bdf": "".join(lines[4:6]) + "INCLUDE 'sub/hexa.bdf'\n",
        "model/sub/hexa.bdf": "".join(lines[6:]),
    })
    merged, split = read_bdf(tmp_path / "merged.bdf"), read_bdf(tmp_path / "split.bdf")
    assert split == merged
    assert split.files == tuple(str(tmp_path / f) for f in (
        "split.bdf", "case/c.inc", "model/grids.bdf", "model/rest.bdf", "model/sub/hexa.bdf"))
    assert merged.files == (str(tmp_path / "merged.bdf"),)
    (grid,) = [g for g in split["GRID"] if g.id == 2]
    assert (grid.file, grid.line) == (str(tmp_path / "model/grids.bdf"), 2)
    assert split.unknown == {"CHEXA": [(str(tmp_path / "model/sub/hexa.bdf"), 1)]}
    assert split.case_control.subcase().places["SPC"] == f"{tmp_path / 'case/c.inc'}:3"


def test_quoted_path_continued_over_lines_and_unquoted(tmp_path):
    _write(tmp_path, {"dir one/deep/g.bdf": "GRID,7,,1.,2.,3.\n", "h.bdf": "GRID,8\n"})
    text = "INCLUDE 'dir one/\n        deep/\n   g.bdf' $ the grids\ninclude h.bdf\n"
    bulk = read_bdf_text(text, name=str(tmp_path / "main.bdf"))
    assert [g.id for g in bulk["GRID"]] == [7, 8]
    assert bulk.files[1:] == (str(tmp_path / "dir one/deep/g.bdf"), str(tmp_path / "h.bdf"))


def test_include_relative_to_the_current_directory_for_a_string(tmp_path, monkeypatch):
    _write(tmp_path, {"g.bdf": "GRID,3\n"})
    monkeypatch.chdir(tmp_path)
    assert [g.id for g in read_bdf_text("INCLUDE 'g.bdf'\n")["GRID"]] == [3]


def test_messages_name_the_included_file(tmp_path):
    _write(tmp_path, {"main.bdf": "GRID,1\nINCLUDE 'bad.bdf'\n", "bad.bdf": "$\nGRID,2,,x\n"})
    with pytest.raises(BulkDataError, match=re.escape(f"{tmp_path / 'bad.bdf'}:2: GRID 2 field 4 (X1)")):
        read_bdf(tmp_path / "main.bdf")


def test_nested_include_relative_to_the_main_deck_when_not_beside_the_including_file(tmp_path):
    """Decks written for Nastran's job directory: a nested path from the main deck's directory."""
    _write(tmp_path, {"jobs/qs/main.bdf": "INCLUDE '../../inc/panel.dat'\n",
                      "inc/panel.dat": "INCLUDE '../../bulk/panel.blk'\n", "bulk/panel.blk": "GRID,4\n"})
    bulk = read_bdf(tmp_path / "jobs/qs/main.bdf")
    assert [g.id for g in bulk["GRID"]] == [4] and bulk.files[-1] == str(tmp_path / "jobs/qs/../../bulk/panel.blk")


def test_logical_symbols_are_named_when_missing():
    _raises("INCLUDE 'MYBULK:panel.blk'\n", "m.bdf:1: INCLUDE: cannot read 'MYBULK:panel.blk'",
            "logical symbols (NAME:path) are not supported")


def test_missing_include_names_the_including_file_and_the_path_tried(tmp_path):
    _write(tmp_path, {"main.bdf": "GRID,1\n$\nINCLUDE 'sub/none.bdf'\n"})
    message = _raises((tmp_path / "main.bdf").read_text(), f"{tmp_path / 'main.bdf'}:3: INCLUDE: cannot read "
                      f"'sub/none.bdf' (tried {tmp_path / 'sub/none.bdf'})", name=str(tmp_path / "main.bdf"))
    assert "No such file" in message


def test_include_loop_is_a_located_error(tmp_path):
    _write(tmp_path, {"a.bdf": "GRID,1\nINCLUDE 'b.bdf'\n", "b.bdf": "$\nINCLUDE 'a.bdf'\n"})
    with pytest.raises(BulkDataError, match=re.escape(f"{tmp_path / 'b.bdf'}:2: INCLUDE: include loop: "
                                                      f"{tmp_path / 'a.bdf'} is already being read")):
        read_bdf(tmp_path / "a.bdf")


@pytest.mark.parametrize(
    "text, parts",
    [
        ("INCLUDE\n", ("m.bdf:1: INCLUDE: INCLUDE without a file name",)),
        ("INCLUDE 'a.bdf\nGRID,1\n", ("m.bdf:1: INCLUDE: the quoted file name is not closed",)),
        ("INCLUDE 'a.bdf' GRID\n", ("m.bdf:1: INCLUDE: unexpected text 'GRID' after the file name",)),
    ],
)
def test_malformed_include(text, parts):
    _raises(text, *parts)


def test_a_card_ends_in_its_file(tmp_path):
    _write(tmp_path, {"main.bdf": "CBAR,1,1,1,2,0.,0.,1.,,+A\nINCLUDE 'c.bdf'\n", "c.bdf": "+A,,,0.1\n"})
    with pytest.raises(BulkDataError, match=re.escape(f"{tmp_path / 'c.bdf'}:1: CBAR 1 field 1: continuation of the "
                                                      f"card at {tmp_path / 'main.bdf'}:1")):
        read_bdf(tmp_path / "main.bdf")


def test_nothing_is_read_after_enddata(tmp_path):
    bulk = read_bdf_text("GRID,1\nENDDATA\nINCLUDE 'missing.bdf'\nGRID,2\n", name=str(tmp_path / "m.bdf"))
    assert [g.id for g in bulk["GRID"]] == [1] and bulk.case_control is None


# --- executive and case control ----------------------------------------------------------------


def test_case_control_defaults_subcases_abbreviations_continuation():
    text = (
        "ID x,y\nSOL SEMODES\nTIME 10\nCEND\n"
        "title = Wing $ comment\nMETH = 10\nspc=1\n"
        "K2GG = KAAX,\n  2.5*KBB\n"
        "SET 5 = 1, 2,\n 3, 4\nDISPLACEMENT(PLOT) = ALL\n"
        "SUBCASE 1\n  LABEL = free, with commas,\n"
        "SUBC 20\n  SPC = 2\n  MPC = 7\n  SUPO = 3\n  METHOD(STRUCTURE) = 11\n  M2GG = MX\n  SUBTITLE=second\n"
        "BEGIN BULK\nGRID,1\n"
    )
    control = read_bdf_text(text, name="m.bdf").case_control
    assert isinstance(control, CaseControl) and control.sol == "SEMODES"
    first, second = control.subcases
    assert first == Subcase(1, spc=1, method=10, k2gg="KAAX,2.5*KBB", title="Wing", label="free, with commas,")
    assert second == Subcase(20, spc=2, mpc=7, method=11, suport1=3, k2gg="KAAX,2.5*KBB", m2gg="MX", title="Wing",
                             subtitle="second")
    assert control.subcase() is first and control.subcase(20) is second
    assert second.selection("K2GG") == ((1.0, "KAAX"), (2.5, "KBB")) and second.selection("b2gg") == ()
    with pytest.raises(ValueError, match="'SPC' is not a matrix selection"):
        second.selection("SPC")
    assert (first.where, second.where) == ("m.bdf:13", "m.bdf:15")
    assert (second.places["SPC"], second.places["METHOD"], second.places["K2GG"]) == ("m.bdf:16", "m.bdf:19", "m.bdf:8")
    assert control.ignored == (("ID", "m.bdf:1"), ("TIME", "m.bdf:3"), ("SET", "m.bdf:10"),
                               ("DISPLACEMENT(PLOT)", "m.bdf:12"))
    assert control.to_json()["subcases"][1]["spc"] == 2


def test_case_control_without_subcase_or_cend():
    control = read_bdf_text("SOL 103\nMETHOD = 4\nBEGIN BULK\n", name="m.bdf").case_control
    assert control.sol == 103 and control.subcases == (Subcase(1, method=4),)
    assert read_bdf_text("GRID,1\n").case_control is None


def test_unknown_subcase_lists_the_ids():
    control = read_bdf_text("SUBCASE 1\nSUBCASE 3\nBEGIN BULK\n", name="m.bdf").case_control
    with pytest.raises(BulkDataError, match=re.escape("m.bdf:1: case control has no SUBCASE 2 (subcases: 1, 3)")):
        control.subcase(2)


def test_plot_requests_and_combinations_are_ignored():
    text = "SUBCASE 1\nSPC = 1\nSUBCOM 2\nSPC = 5\nOUTPUT(PLOT)\nSPC = 9\nBEGIN BULK\n"
    control = read_bdf_text(text, name="m.bdf").case_control
    assert [s.spc for s in control.subcases] == [1]
    assert [k for k, _ in control.ignored] == ["SUBCOM", "OUTPUT(PLOT)", "SPC"]


@pytest.mark.parametrize(
    "text, parts",
    [
        ("SPC = ALL\n", ("m.bdf:1: SPC: expected a set id (integer > 0), got 'ALL'",)),
        ("CEND\nMETH = 0\n", ("m.bdf:2: METHOD: expected a set id",)),
        ("SUBCASE 2\nSUBCASE 2\n", ("m.bdf:2: SUBCASE: subcase ids must increase: 2 after 2 at m.bdf:1",)),
        ("SUBCASE\n", ("m.bdf:1: SUBCASE: expected a subcase id (integer > 0), got ''",)),
        ("K2GG = 2.*\n", ("m.bdf:1: K2GG = 2.*: expected matrix names",)),
        ("SOL\n", ("m.bdf:1: SOL: SOL without a solution number or name",)),
    ],
)
def test_case_control_errors(text, parts):
    _raises(text + "BEGIN BULK\n", *parts)


# --- tolerance: field-10 comments ----------------------------------------------------------------


@pytest.mark.parametrize(
    "text, where",
    [
        ("GRID,1,,0.,0.,0.,,,,+C1\n", "m.bdf:1: GRID 1 field 10: text '+C1'"),
        ("GRID    2       0       1.      0.      0.                              NOTE\nGRID,3\n",
         "m.bdf:1: GRID 2 field 10: text 'NOTE'"),
    ],
)
def test_field_10_without_continuation_is_a_comment(text, where):
    with pytest.warns(UserWarning, match=re.escape(where) + ".*taken as a comment"):
        bulk = read_bdf_text(text, name="m.bdf")
    assert bulk["GRID"][0]["X3"] == 0.0


def test_many_field_10_comments_give_four_warnings():
    text = "".join(f"GRID,{i},,0.,0.,0.,,,,c{i}\n" for i in range(1, 8))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read_bdf_text(text, name="m.bdf")
    assert [str(w.message)[:11] for w in caught] == ["m.bdf:1: GR", "m.bdf:2: GR", "m.bdf:3: GR", "4 more note"]
    assert "the last: m.bdf:7: GRID 7 field 10: text 'c7'" in str(caught[-1].message)


def test_deqatn_equations_and_character_params_are_read():
    text = ("DEQATN  5       F(RTIP,RROOT) = RTIP - RROOT;\n        G = 2.*F\n"
            "PARAM,UNITSYS,LBF-IN\nGRID,1\n")
    bulk = read_bdf_text(text, name="m.bdf")
    assert bulk.unknown == {"DEQATN": [("m.bdf", 1)]} and bulk.card_status()["DEQATN"] == "ignored"
    assert bulk["PARAM"][0]["V1"] == "LBF-IN" and [g.line for g in bulk["GRID"]] == [4]
    _raises("PARAM,WTMASS,1.2.3\n", "m.bdf:1: PARAM WTMASS field 3 (V1): expected a number or a word, got '1.2.3'")


def test_field_10_marker_with_its_continuation_is_silent():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        (bar,) = read_bdf_text("CBAR,1,1,1,2,0.,0.,1.,,+A\n+A,,,0.1\n")["CBAR"]
    assert bar["W1A"] == 0.1


# --- what became of each card --------------------------------------------------------------------


def test_card_status_and_report():
    bulk = read_bdf_text(CASE + BULK + "FREQ1,2,1.,1.,10\nDSCREEN,STRESS\nCAERO1,1\n", name="m.bdf")
    status = bulk.card_status()
    assert status == {"CAERO1": "ignored", "CBAR": "read", "CHEXA": "unsupported", "DSCREEN": "ignored",
                      "EIGRL": "read", "FREQ1": "ignored", "GRID": "read", "MAT1": "read", "PBAR": "read"}
    assert bulk.structural_unknown() == ["CHEXA"]
    assert "case control: SOL 103, subcases 1" in bulk.report()
