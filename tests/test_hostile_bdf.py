"""Hostile bulk data (issue 19): every failure a located message, no data lost silently.

One regression test per reported case (the message names file, line, card and field),
then two properties: generated valid decks round-trip, and mutated decks end in a
ValueError or a model, never another exception.
"""

import re
import time
import warnings
from unittest import mock

import numpy as np
import pytest
from typer.testing import CliRunner

import jaxfem._build
from jaxfem._build import build_model
from jaxfem.io import BulkDataError, IdRanges, UnsupportedCardsError, read_bdf, read_bdf_text
from updating.cli import app

# A cantilever: line 1 GRID 1 (clamped), line 2 GRID 2, line 3 CBAR 10, line 4 PBAR 1, line 5 MAT1 1.
BAR = (
    "GRID,1,,0.,0.,0.,,123456\n"
    "GRID,2,,1.,0.,0.\n"
    "CBAR,10,1,1,2,0.,0.,1.\n"
    "PBAR,1,1,1.-3,1.-6,1.-6,2.-6\n"
    "MAT1,1,2.1+11,,0.3,7850.\n"
)


def _read_fails(text: str, *parts: str) -> str:
    with pytest.raises(BulkDataError, match=".*".join(re.escape(p) for p in parts)) as info:
        read_bdf_text(text, name="m.bdf")
    return str(info.value)


def _build(text: str, **kwargs):
    return build_model(read_bdf_text(text, name="m.bdf"), **kwargs)


def _build_fails(text: str, *parts: str, **kwargs) -> str:
    with pytest.raises(BulkDataError, match=".*".join(re.escape(p) for p in parts)) as info:
        _build(text, **kwargs)
    return str(info.value)


# --- 1. raw tracebacks that are now located errors -----------------------------------------


def test_mat1_nu_minus_one_with_g_blank():
    """Was ZeroDivisionError in G = E / (2 (1 + NU))."""
    _build_fails(BAR.replace("2.1+11,,0.3", "2.1+11,,-1."), "m.bdf:5: MAT1 1 field 5 (NU): NU must lie in (-1, 0.5]")


@pytest.mark.parametrize(
    "old, new, parts",
    [
        ("GRID,2,", "GRID,123456789012345678901,", ("m.bdf:2: GRID field 2 (ID): expected an id in 1..99,999,999",)),
        ("CBAR,10,", "CBAR,9223372036854775808,", ("m.bdf:3: CBAR field 2 (EID): expected an id in 1..99,999,999",)),
        ("CBAR,10,1,", "CBAR,10,100000000,", ("m.bdf:3: CBAR 10 field 3 (PID): expected an id in 1..99,999,999",
                                              "'100000000'")),
        ("PBAR,1,1,", "PBAR,1,1" + "9" * 5000 + ",", ("m.bdf:4: PBAR 1 field 3 (MID): expected an id", "99999...")),
        ("GRID,2,,1.,0.,0.", "GRID,2,,1.,0.,0.,,,4294967296", ("m.bdf:2: GRID 2 field 9 (SEQID): integer out of range",)),
    ],
)
def test_ids_beyond_nastran_range(old, new, parts):
    """Were OverflowError in the int64 arrays (and int() refuses 5,000 digits)."""
    _read_fails(BAR.replace(old, new), *parts)


def test_pbarl_tube_dimension_overflowing_its_properties():
    """Was OverflowError in r**4."""
    text = BAR.replace("PBAR,1,1,1.-3,1.-6,1.-6,2.-6", "PBARL,1,1,,TUBE\n,1.E200,0.1")
    _build_fails(text, "m.bdf:5: PBARL 1 field 2 (DIM1): DIM1 = 1e+200: the section properties", "overflow")


def test_chain_of_rigid_elements_longer_than_the_recursion_limit():
    """1,200 RBE2s, each grid dependent on the next higher one (was RecursionError): the
    chain reduces to the 6 DoFs of the last grid, and grid 1 follows it rigidly."""
    n = 1200
    lines = [f"GRID,{i},,{float(i)},0.,0." for i in range(1, n + 2)]
    lines += [f"RBE2,{10000 + i},{i + 1},123456,{i}" for i in range(1, n + 1)]
    lines += [f"CONM2,1,{n + 1},,1.\n,1.,,1.,,,1."]
    with pytest.warns(UserWarning, match=rf"\({n + 1}, 1\).* carry mass but no stiffness"):  # a mass and no element
        model = _build("\n".join(lines))
    assert model.n_dof == 6
    coef = np.asarray(model.dofs.coef)[0]  # grid 1: u_y = u_y(last) + θ_z(last) · (x_1 − x_last)
    index = np.asarray(model.dofs.index)[0]
    labels = {tuple(map(int, model.dofs.labels[k])): k for k in range(6)}
    assert coef[1, list(index).index(labels[(n + 1, 6)])] == pytest.approx(1.0 - (n + 1))


def test_rigid_element_loop_is_still_named():
    text = BAR + "GRID,3,,2.,0.,0.\nRBE2,30,2,1,3\nRBE2,31,3,1,2\n"
    _build_fails(text, "m.bdf:8: RBE2 31 field 3 (GN): rigid elements/MPCs depend on each other in a loop: "
                       "RBE2 31 at m.bdf:8 (grid 2 component 1) -> RBE2 30 at m.bdf:7 (grid 3 component 1) -> RBE2 31")


def test_chain_of_coordinate_systems_longer_than_the_recursion_limit():
    lines = ["CORD2R,1,,0.,0.,0.,0.,0.,1.\n,1.,0.,0."]
    lines += [f"CORD2R,{i},{i - 1},1.,0.,0.,1.,0.,1.\n,2.,0.,0." for i in range(2, 1501)]
    lines += ["GRID,1,1500,0.,0.,0.", "CONM2,1,1,,1."]
    with pytest.warns(UserWarning, match=r"\(1, 1\), \(1, 2\), \(1, 3\) carry mass but no stiffness"):
        model = _build("\n".join(lines))
    np.testing.assert_allclose(model.xyz, [[1499.0, 0.0, 0.0]])


# --- 2. reals and digits ---------------------------------------------------------------------


@pytest.mark.parametrize("text", ["1.E400", "-1.+999", "1.D309", "1" * 400 + "."])
def test_real_overflowing_to_inf(text):
    _read_fails(BAR.replace("GRID,2,,1.,", f"GRID,2,,{text},"),
                "m.bdf:2: GRID 2 field 4 (X1): real number out of range")


@pytest.mark.parametrize("text", ["nan", "NaN.", "inf", "-inf", "1.E+inf"])
def test_nan_and_inf_are_not_reals(text):
    _read_fails(BAR.replace("GRID,2,,1.,", f"GRID,2,,{text},"),
                "m.bdf:2: GRID 2 field 4 (X1): expected a real number with a decimal point", repr(text))


@pytest.mark.parametrize(
    "old, new, parts",
    [
        ("GRID,2,,1.,", "GRID,2,,\u0661.,", ("m.bdf:2: GRID 2 field 4 (X1): character '\u0661' (U+0661 ARABIC-INDIC "
                                            "DIGIT ONE) is not allowed",)),
        ("GRID,2,", "GRID,\uff12,", ("m.bdf:2: GRID field 2 (ID): character '\uff12' (U+FF12 FULLWIDTH DIGIT TWO)",)),
        ("CBAR,10,1,1,2", "CBAR,10,1,1,\u0662", ("m.bdf:3: CBAR 10 field 5 (GB): character",)),
        ("GRID,2,", "GR\u0131D,2,", ("m.bdf:2: GR\u0131D field 1: character '\u0131' (U+0131 LATIN SMALL LETTER "
                                     "DOTLESS I)",)),
        ("GRID,2,,1.,", "GRID,2,,\u00a01.,", ("m.bdf:2: GRID 2 field 4 (X1): character '\\xa0' (U+00A0 NO-BREAK",)),
        ("0.,0.,1.\n", "0.,0.,1.,,+\u00e9\n+\u00e9,,,0.1\n", ("m.bdf:3: CBAR field 10: character '\u00e9'",)),
    ],
)
def test_non_ascii_in_fields_refused(old, new, parts):
    """Python's int()/float() read these digits, str.upper() folds 'ı' to 'I', strip()
    removes a no-break space: all would have been accepted."""
    _read_fails(BAR.replace(old, new, 1), *parts)


def test_non_ascii_in_comments_is_fine():
    bulk = read_bdf_text("$ ρ = 7850 kg/m³, ν = 0.3\u2028still the comment\n" + BAR)
    assert len(bulk["GRID"]) == 2


# --- 3. lines ----------------------------------------------------------------------------------


@pytest.mark.parametrize("separator", ["\f", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029", "\x0b"])
def test_only_newlines_end_lines(separator):
    """str.splitlines would split at these and move every later line number."""
    text = f"GRID,1,,0.,0.,0. ${separator}comment\n\nGRID,2,,x\n"
    _read_fails(text, "m.bdf:3: GRID 2 field 4 (X1): expected a real number")


def test_form_feed_page_break_is_a_blank_line():
    text = "GRID,1,,0.,0.,0.\r\n\f\r\nGRID,2,,1.,0.,0.\r\nGRID,3,,x\r\n"
    bulk_text = text.replace("GRID,3,,x\r\n", "")
    assert [g.line for g in read_bdf_text(bulk_text)["GRID"]] == [1, 3]
    _read_fails(text, "m.bdf:4: GRID 3 field 4 (X1)")


def test_form_feed_inside_a_field_is_named():
    _read_fails("GRID,1,,0.,0\f.,0.\n", "m.bdf:1: GRID 1 field 5 (X2): character '\\x0c'")


def test_byte_order_mark_dropped(tmp_path):
    path = tmp_path / "m.bdf"
    path.write_text("GRID,1,,0.,0.,x\n", encoding="utf-8-sig")
    with pytest.raises(BulkDataError) as info:
        read_bdf(path)
    assert str(info.value).startswith(f"{path}:1: GRID 1 field 6 (X3)") and "\ufeff" not in str(info.value)
    path.write_text(BAR, encoding="utf-8-sig")
    assert [g.id for g in read_bdf(path)["GRID"]] == [1, 2]


def test_bytes_that_are_not_utf8_are_named(tmp_path):
    path = tmp_path / "m.bdf"
    path.write_bytes(b"$ caf\xe9 comment is fine\nGRID,1,,0.,0.,1\xe9.\n")
    with pytest.raises(BulkDataError, match=re.escape("m.bdf:2: GRID 1 field 6 (X3): character '\ufffd' (U+FFFD "
                                                      "REPLACEMENT CHARACTER: a byte that is not UTF-8)")):
        read_bdf(path)


# --- 4. physical ranges --------------------------------------------------------------------


@pytest.mark.parametrize(
    "mat1, parts",
    [
        ("MAT1,1,2.1+11,,0.6,7850.", ("m.bdf:5: MAT1 1 field 5 (NU): NU must lie in (-1, 0.5], got 0.6",)),
        ("MAT1,1,2.1+11,,-1.5,7850.", ("MAT1 1 field 5 (NU): NU must lie in (-1, 0.5], got -1.5",)),
        ("MAT1,1,2.1+11,,-1.,7850.", ("MAT1 1 field 5 (NU): NU must lie in (-1, 0.5], got -1.0",)),  # was 1/0
        ("MAT1,1,2.1+11,,20.,7850.", ("MAT1 1 field 5 (NU): NU must lie in (-1, 0.5], got 20.0",)),  # was accepted
        ("MAT1,1,2.1+11,8.+10,0.7,7850.", ("MAT1 1 field 5 (NU): NU must lie in (-1, 0.5], got 0.7",)),  # all given
        ("MAT1,1,2.1+11,2.+10,,7850.", ("MAT1 1 field 4 (G): E = 2.1e+11 and G = 2e+10 give NU = E/(2G) - 1 = 4.25,",
                                        "outside (-1, 0.5]")),
        ("MAT1,1,,-8.+10,0.3,7850.", ("MAT1 1 field 4 (G): G must be >= 0, got -80000000000.0",)),
        ("MAT1,1,,1.+308,0.3,7850.", ("MAT1 1 field 3 (E): the derived modulus overflows",)),
        ("MAT1,1,2.1+11,,0.3,-1.", ("MAT1 1 field 6 (RHO): negative density",)),
    ],
)
def test_material_ranges(mat1, parts):
    _build_fails(BAR.replace("MAT1,1,2.1+11,,0.3,7850.", mat1), *parts)


def test_nu_half_is_accepted():
    model = _build(BAR.replace("2.1+11,,0.3", "2.1+11,,0.5"))
    assert float(model.materials.G[0]) == pytest.approx(2.1e11 / 3.0)


def test_shear_modulus_zero_where_used():
    """MAT1 with E alone: G = NU = 0 (QRG); refused where G is used (torsion, shells),
    accepted for a rod without torsion."""
    e_only = BAR.replace("MAT1,1,2.1+11,,0.3,7850.", "MAT1,1,2.1+11,,,7850.")
    _build_fails(e_only, "m.bdf:4: PBAR 1 field 7 (J): torsion constant J = 2e-06 needs a shear modulus, but MAT1 1")
    shell = ("GRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\nGRID,3,,1.,1.,0.\nGRID,4,,0.,1.,0.\nCQUAD4,1,7,1,2,3,4\n"
             "PSHELL,7,1,0.01,1\nMAT1,1,7.+10,,,2700.\n")
    _build_fails(shell, "m.bdf:6: PSHELL 7 field 3 (MID1): MAT1 1 has G = 0 (only E given), but shells use")
    rod = ("GRID,1,,0.,0.,0.,,23456\nGRID,2,,1.,0.,0.,,23456\nCROD,1,2,1,2\nPROD,2,1,1.-4\nMAT1,1,2.1+11,,,7850.\n")
    assert _build(rod).n_dof == 2


@pytest.mark.parametrize(
    "old, new, parts",
    [
        ("GRID,2,,1.,0.,0.", "GRID,2,,1.,3.5+184,0.",
         ("m.bdf:2: GRID 2 field 5 (X2): X2 = 3.5e+184 is beyond ±1e100 m: lengths, areas and volumes would overflow",)),
        ("CBAR,10,1,1,2,0.,0.,1.", "CBAR,10,1,1,2,0.,0.,1.+200", ("m.bdf:3: CBAR 10 field 8 (X3): X3 = 1e+200 is beyond",)),
        ("CBAR,10,1,1,2,0.,0.,1.", "CBAR,10,1,1,2,0.,0.,1.\n,,,1.+101", ("m.bdf:4: CBAR 10 field 4 (W1A): W1A = 1e+101",)),
        ("GRID,2,,1.,0.,0.", "GRID,2,,1.-150,0.,0.", ("m.bdf:3: CBAR 10 field 5 (GB): zero length",)),
    ],
)
def test_geometry_that_would_overflow(old, new, parts):
    """Found by the mutation property: a coordinate of 3.5e184 made |x|² overflow (a
    RuntimeWarning, then inf in K); a length of 1e-150 makes L³ underflow to 0."""
    _build_fails(BAR.replace(old, new), *parts)


@pytest.mark.parametrize(
    "extra, parts",
    [
        ("CELAS2,20,-2.5+6,2,1\n", ("m.bdf:6: CELAS2 20 field 3 (K): negative spring stiffness -2500000.0",)),
        ("CELAS1,20,21,2,1\nPELAS,21,-1.\n", ("m.bdf:7: PELAS 21 field 3 (K): negative spring stiffness",)),
        ("CBUSH,20,21,1,2,,,,0\nPBUSH,21,K,1.,-1.\n", ("m.bdf:7: PBUSH 21 field 5 (K2): negative spring stiffness K2",)),
        ("CONM2,20,2,,-1.\n", ("m.bdf:6: CONM2 20 field 5 (M): negative mass -1.0",)),
    ],
)
def test_negative_springs_and_masses(extra, parts):
    """A negative spring (λ = −2.5e6) was shown as a 0.0 Hz mode."""
    _build_fails(BAR + extra, *parts)


# --- 5. PARAM ----------------------------------------------------------------------------------


def test_misspelt_param_warns_with_the_closest_name():
    expected = "m.bdf:6: PARAM COUPMAS: unknown PARAM COUPMAS (did you mean COUPMASS?) ignored: the mass is lumped"
    with pytest.warns(UserWarning, match=re.escape(expected)):
        model = _build(BAR + "PARAM,COUPMAS,1\n")
    assert model.lumped


def test_unknown_param_without_close_name_warns():
    with pytest.warns(UserWarning, match=re.escape("m.bdf:6: PARAM ZZTOP: unknown PARAM ZZTOP ignored")):
        _build(BAR + "PARAM,ZZTOP,1\n")


def test_damping_param_warns():
    with pytest.warns(UserWarning, match=re.escape("PARAM G: PARAM G (damping) ignored: normal modes do not use it")):
        _build(BAR + "PARAM,G,0.02\n")


def test_harmless_params_are_silent():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _build(BAR + "PARAM,POST,-1\nPARAM,AUTOSPC,YES\nPARAM,GRDPNT,0\nPARAM,LGDISP,-1\nPARAM,K6ROT,100.\n"
                     "PARAM,MAXRATIO,1.+7\nPARAM,WTMASS,1.\n")


@pytest.mark.parametrize(
    "param, parts",
    [
        ("PARAM,WTMASS,-1.", ("m.bdf:6: PARAM WTMASS field 3 (V1): WTMASS must be a real > 0, got -1.0",)),
        ("PARAM,LGDISP,1", ("m.bdf:6: PARAM LGDISP field 3 (V1): PARAM LGDISP 1 (large displacements)",)),
        ("PARAM,CK1,1.5", ("m.bdf:6: PARAM CK1 field 2 (N): PARAM CK1 scales the stiffness matrix and is not",)),
        ("PARAM,CM1,2.", ("PARAM CM1 field 2 (N): PARAM CM1 scales the mass matrix",)),
    ],
)
def test_params_that_change_the_model_are_refused(param, parts):
    _build_fails(BAR + param + "\n", *parts)


# --- 6. unsupported cards --------------------------------------------------------------------


def test_unsupported_structural_cards_refused_with_count_and_first_line():
    """A stiffened panel whose stiffeners were unsupported gave the modes of the rest."""
    text = BAR + "CQUAD8,30,1,1,2,3,4\nCBEND,31,1,1,2\nCQUAD8,32,1,1,2,3,4\nPSOLID,5,1\nEIGRL,1,,,5\n"
    message = _build_fails(
        text, "m.bdf: unsupported bulk-data cards that may define structure: CBEND x1 (m.bdf:7); "
              "CQUAD8 x2 (m.bdf:6, m.bdf:8); PSOLID x1 (m.bdf:9): the model would lack them; "
              "build_model(..., allow_unsupported=True) builds it without them")
    assert "EIGRL" not in message
    with pytest.raises(UnsupportedCardsError) as info:
        _build(text)
    assert info.value.names == ["CBEND", "CQUAD8", "PSOLID"]


@pytest.mark.parametrize("card", ["MAT9,3,1.", "BAROR,,7", "CORD3G,5,POINT,1", "DMI,K,0,6,1", "NSM1,1,PBAR,1.,1",
                                  "CHEXA,20,1,1,2,3,4,5,6\n,7,8"])
def test_each_kind_of_structural_card_is_refused(card):
    _build_fails(BAR + card + "\n", "unsupported bulk-data cards that may define structure: " + card[:card.index(",")])


def test_opt_in_builds_without_them_and_says_so():
    with pytest.warns(UserWarning, match=re.escape("m.bdf: unsupported bulk-data cards ignored: CQUAD8 x1 (m.bdf:6)")):
        model = _build(BAR + "CQUAD8,30,1,1,2,3,4\n", allow_unsupported=True)
    assert model.n_dof == 6


def test_cards_without_effect_on_k_and_m_warn():
    expected = ("m.bdf: bulk-data cards without effect on stiffness or mass ignored: AECOMP x1 (m.bdf:8); "
                "EIGC x1 (m.bdf:6); FREQ1 x1 (m.bdf:7)")
    with pytest.warns(UserWarning, match=re.escape(expected)):
        _build(BAR + "EIGC,1,CLAN\nFREQ1,2,1.,1.,100\nAECOMP,WING,SET1,1\n")


# --- 7. SPC1 THRU ------------------------------------------------------------------------------


def test_spc1_thru_is_not_expanded():
    """SPC1 ... THRU 99999999 built a list of 10⁸ grids before naming the missing one."""
    text = BAR + "SPC1,1,123456,1,THRU,99999999\n"
    start = time.perf_counter()
    bulk = read_bdf_text(text, name="m.bdf")
    assert bulk["SPC1"][0]["G"].runs == ((1, 99999999),)
    _build_fails(text, "m.bdf:6: SPC1 1 field 4 (G): grid 3 is not defined (1 THRU 99999999 lists it)")
    assert time.perf_counter() - start < 2.0


def test_spc1_thru_over_existing_grids():
    text = BAR + "GRID,3,,2.,0.,0.\nCBAR,11,1,2,3,0.,0.,1.\nSPC1,1,123456,1,THRU,2\n"
    (spc1,) = read_bdf_text(text)["SPC1"]
    assert spc1["G"] == (1, 2) and spc1["G"] == IdRanges([(1, 1), (2, 2)]) and 2 in spc1["G"]
    assert _build(text).n_dof == 6


def test_id_ranges_behave_like_the_tuple():
    ids = IdRanges([(5, 5), (7, 9), (10, 12), (20, 20)])
    assert ids.runs == ((5, 5), (7, 12), (20, 20))
    assert len(ids) == 8 and ids[1] == 7 and ids[-1] == 20 and ids[2:4] == (8, 9) and 11 in ids and 6 not in ids
    assert ids == (5, 7, 8, 9, 10, 11, 12, 20) and ids != (5, 7) and repr(ids) == "IdRanges(5, 7 THRU 12, 20)"
    with pytest.raises(IndexError):
        ids[8]


# --- 8. jaxfem modes -------------------------------------------------------------------------


runner = CliRunner()


def _modes(tmp_path, text: str, *args: str):
    path = tmp_path / "m.bdf"
    path.write_text(text)
    return runner.invoke(app, ["modes", str(path), *args]), path


@pytest.mark.parametrize(
    "text, args, expected",
    [
        (BAR, ("-n", "0"), "error: -n/--n-modes must be at least 1, got 0"),
        (BAR, ("-n", "-3"), "error: -n/--n-modes must be at least 1, got -3"),
        (BAR.replace("7850.", "0."), (), "no DoF carries mass"),
        (BAR.replace("1.,0.,0.", "1.,0.,x"), (), "m.bdf:2: GRID 2 field 6 (X3): expected a real number"),
        (BAR + "CQUAD8,30,1,1,2,3,4\n", (), "CQUAD8 x1 (PATH:6): the model would lack them; --allow-unsupported builds"),
    ],
)
def test_modes_command_errors_are_one_line(tmp_path, text, args, expected):
    result, path = _modes(tmp_path, text, *args)
    assert result.exit_code == 2, result.output
    assert result.output.startswith("error: ") and result.output.count("\n") == 1, result.output
    assert expected.replace("PATH", str(path)) in result.output
    assert "Traceback" not in result.output and "f [Hz]" not in result.output


# --- properties ----------------------------------------------------------------------------------

try:
    from hypothesis import given, settings
    from hypothesis import strategies as st
except ImportError:  # in the test extra; without it only the properties are skipped
    given = None

_PROPERTY = dict(max_examples=200, deadline=None, database=None)  # no .hypothesis folder written


def _build_unfinalized(text: str):
    """build_model without :func:`jaxfem._assembly.finalize_dofs` (auto-SPC and the
    massless-mechanism check, which assemble the model: compiled once per model
    structure, coordinates included, about 1 s each; the tests above run it)."""
    with mock.patch.object(jaxfem._build, "finalize_dofs", lambda model: model):
        return _build(text)


# Grid, property, material and element ids of the generated decks: a few fixed sets, since
# build_model compiles once per model structure (ids included, see jaxfem._eager).
_ID_SETS = ((1, 2, 3, 4, 5, 6, 7), (99_999_999, 12_345_678, 40, 7, 99_999_998, 500, 3))


def _real(x: float) -> str:
    return f"{x:.17e}"  # a decimal point and 17 digits: reads back to the same double


if given is not None:

    @st.composite
    def _decks(draw):
        """A free-free chain of one or two CBARs on random coordinates (x rising by >= 0.1
        so that no bar is short or parallel to its orientation vector z) and section and
        material values, consistent mass."""
        n = draw(st.sampled_from((2, 3)))
        ids = draw(st.sampled_from(_ID_SETS))
        grid_ids, pid, mid, eids = ids[:n], ids[3], ids[4], ids[5:5 + n - 1]
        x = np.cumsum([draw(st.floats(-1e3, 1e3))] + draw(st.lists(st.floats(0.1, 10.0), min_size=n - 1,
                                                                   max_size=n - 1)))
        yz = draw(st.lists(st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)), min_size=n, max_size=n))
        xyz = [(float(x[i]), *yz[i]) for i in range(n)]
        mat = (draw(st.floats(1e6, 1e12)), draw(st.floats(-0.99, 0.5)), draw(st.floats(1.0, 1e4)))
        sec = (draw(st.floats(1e-6, 1.0)), *(draw(st.floats(1e-12, 1e-2)) for _ in range(3)))
        lines = ["PARAM,COUPMASS,1", f"MAT1,{mid},{_real(mat[0])},,{_real(mat[1])},{_real(mat[2])}",
                 f"PBAR,{pid},{mid}," + ",".join(_real(v) for v in sec)]
        lines += [f"GRID,{g},," + ",".join(_real(c) for c in p) for g, p in zip(grid_ids, xyz)]
        lines += [f"CBAR,{e},{pid},{grid_ids[k]},{grid_ids[k + 1]},0.,0.,1." for k, e in enumerate(eids)]
        return "\n".join(lines) + "\n", dict(zip(grid_ids, xyz)), mat, sec

    @settings(**_PROPERTY)
    @given(_decks())
    def test_generated_decks_round_trip(deck):
        text, xyz, (E, nu, rho), (A, I1, I2, J) = deck
        model = _build_unfinalized(text)
        order = sorted(xyz)
        np.testing.assert_array_equal(model.node_ids, order)
        np.testing.assert_array_equal(model.xyz, [xyz[g] for g in order])
        mat, sec = model.materials, model.beam_sections
        assert (float(mat.E[0]), float(mat.nu[0]), float(mat.rho[0])) == (E, nu, rho)
        assert float(mat.G[0]) == pytest.approx(E / (2.0 * (1.0 + nu)), rel=1e-15)
        assert [float(v[0]) for v in (sec.A, sec.I1, sec.I2, sec.J)] == [A, I1, I2, J]

    _CHARACTERS = list("0123456789.,+-E* $\tDXT") + ["", "\u0661", "\uff11", "\f", "\r", "\x00", "\ufeff", "\u2028",
                                                       "\u00e9", "\u0131", "999999999", "E400", "\n"]

    @settings(**_PROPERTY)
    @given(_decks(), st.data())
    def test_mutated_decks_fail_with_a_located_value_error_or_build(deck, data):
        """One character replaced, deleted or doubled, or one line deleted or doubled: the
        result is a model or a ValueError (a BulkDataError names the file and, for a card,
        the line), never another exception; the only warnings are jaxfem's UserWarnings."""
        text = deck[0]
        lines = text.split("\n")
        kind = data.draw(st.sampled_from(["replace", "delete", "double", "delete line", "double line"]))
        if kind.endswith("line"):
            k = data.draw(st.integers(0, len(lines) - 1))
            lines[k:k + 1] = [] if kind == "delete line" else [lines[k], lines[k]]
            text = "\n".join(lines)
        else:
            i = data.draw(st.integers(0, len(text) - 1))
            new = {"replace": data.draw(st.sampled_from(_CHARACTERS)), "delete": "", "double": text[i] * 2}[kind]
            text = text[:i] + new + text[i + 1:]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                model = _build_unfinalized(text)
            except BulkDataError as err:
                assert re.match(r"m\.bdf(:\d+)?: ", str(err)), str(err)
            except ValueError as err:
                raise AssertionError(f"a ValueError that is not a BulkDataError: {err}") from err
            else:
                assert np.all(np.isfinite(np.asarray(model.xyz)))
        assert all(w.category is UserWarning for w in caught), [str(w.message) for w in caught]

else:

    def test_properties_need_hypothesis():
        pytest.skip("hypothesis is not installed (pip install jaxfem[test])")
