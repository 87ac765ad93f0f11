"""Shell and composite bulk data: CQUAD4, CTRIA3, PSHELL, PCOMP, MAT2, MAT8, PARAM K6ROT.

Every card in free, small and large field; the built tables (materials, shell sections,
shell blocks); LAM = SYM, inherited ply fields, THETA against MCID; every refused input
with its located message. The tables are checked on models built without
:func:`jaxfem._assembly.finalize_dofs` (they do not depend on it, and it compiles the
shell element matrices, which takes seconds); one test runs the full build.
"""

import re

import jax
import numpy as np
import pytest

import jaxfem._build
from jaxfem import build_model
from jaxfem._model import MAT1, MAT2, MAT8
from jaxfem.elements._shell import shell_frame
from jaxfem.io import BulkDataError, read_bdf_text

# (name, data fields); rows of 8 data fields, continuations added by the renderer.
DECK = [
    ("GRID", ["1", "", "0.", "0.", "0."]),
    ("GRID", ["2", "", "1.", "0.", "0."]),
    ("GRID", ["3", "", "1.", "1.", "0.02"]),
    ("GRID", ["4", "", "0.", "1.", "0."]),
    ("GRID", ["5", "", "2.", "0.", "0."]),
    ("GRID", ["6", "", "2.", "1.", "0."]),
    # x axis at 30° from basic x in the x-y plane (A origin, B on z, C in the x-z plane)
    ("CORD2R", ["7", "", "0.", "0.", "0.", "0.", "0.", "1.", "0.866025", "0.5", "0."]),
    ("MAT1", ["1", "7.+10", "", "0.3", "2700."]),
    ("MAT8", ["8", "1.4+11", "1.+10", "0.3", "5.+9", "3.+9", "", "1500.", "", "", "", "1.5+9", "", "", "", "",
              "0.01"]),
    ("MAT8", ["12", "1.4+11", "1.+10", "0.3", "5.+9", "3.+9", "2.+9", "1600."]),
    ("MAT2", ["9", "1.+10", "3.+9", "1.+8", "1.2+10", "0.", "3.5+9", "1550.", "1.-6", "", "", "", "", "", "", "",
              "4"]),
    ("PSHELL", ["2", "1", "0.01", "1", "1.2", "1", "0.8", "0.5", "-0.004", "0.004", "1"]),
    ("PSHELL", ["4", "9", "0.002", "", "", "", "", ""]),
    ("PCOMP", ["3", "-0.003", "0.2", "", "HILL", "", "", "SYM", "12", "0.001", "45.", "YES", "", "", "-45.", "",
               "9", "0.0005", "", "", "", "0.0007", "90."]),
    ("PCOMP", ["5", "", "", "", "", "", "", "", "8", "0.001", "0.", ""]),
    ("CQUAD4", ["10", "2", "1", "2", "3", "4", "30.", "0.001", "", "", "1", "0.5", "", "0.6"]),
    ("CQUAD4", ["11", "3", "2", "5", "6", "3", "7", "-0.002"]),
    ("CQUAD4", ["14", "2", "2", "5", "6", "3", "", "", "", "", "", "0.012", "0.012", "0.008", "0.008"]),
    ("CTRIA3", ["12", "5", "2", "5", "6", "-20."]),
    ("CTRIA3", ["13", "4", "1", "2", "4", "7"]),
    ("PARAM", ["K6ROT", "50."]),
    ("SPC1", ["1", "123456", "1", "4"]),
]


def _render(deck, form: str) -> str:
    lines = []
    for name, fields in deck:
        rows = [fields[i : i + 8] for i in range(0, len(fields), 8)]
        for k, row in enumerate(rows):
            if form == "free":
                lines.append(",".join([name if k == 0 else "+"] + row))
            elif form == "small":
                lines.append(f"{name if k == 0 else '+':<8}" + "".join(f"{v:<8}" for v in row))
            else:
                row = row + [""] * (8 - len(row))
                lines.append(f"{name + '*' if k == 0 else '*':<8}" + "".join(f"{v:<16}" for v in row[:4]))
                lines.append(f"{'*':<8}" + "".join(f"{v:<16}" for v in row[4:]))
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def bulks():
    return [read_bdf_text(_render(DECK, form), name=f"{form}.bdf") for form in ("free", "small", "large")]


def _tables(bulk, **kwargs):
    """build_model without the DoF finalisation (no element matrices computed)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(jaxfem._build, "finalize_dofs", lambda model: model)
        return build_model(bulk, **kwargs)


@pytest.fixture(scope="module")
def models(bulks):
    return [_tables(b) for b in bulks]


@pytest.fixture(scope="module")
def model(models):
    return models[0]


def test_three_formats_give_equal_cards(bulks):
    free, small, large = bulks
    assert free == small == large
    assert free.unknown == {}
    names = ("CQUAD4", "CTRIA3", "PSHELL", "PCOMP", "MAT2", "MAT8")
    assert [len(free[n]) for n in names] == [3, 2, 2, 2, 1, 2]
    assert small["PCOMP"][0].fields["THETA4"] == (22, 8)  # ply 4: third line of PCOMP 3, field 8
    assert large["PCOMP"][0].fields["THETA4"][1] == 8


def test_three_formats_build_identical_models(models):
    (first, treedef), *others = [jax.tree_util.tree_flatten(m) for m in models]
    for leaves, other_def in others:
        assert other_def == treedef
        for a, b in zip(first, leaves):
            assert np.asarray(a).dtype == np.asarray(b).dtype
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_card_values(bulks):
    cards = {(c.name, c.id): c for cs in bulks[0].cards.values() for c in cs}
    q10, q11, q14 = (cards["CQUAD4", k] for k in (10, 11, 14))
    assert q10.values == {"EID": 10, "PID": 2, "G1": 1, "G2": 2, "G3": 3, "G4": 4, "THETA": 30.0, "MCID": None,
                          "ZOFFS": 0.001, "TFLAG": 1, "T1": 0.5, "T2": None, "T3": 0.6, "T4": None}
    assert (q11["THETA"], q11["MCID"], q14["THETA"], q14["MCID"], q14["TFLAG"]) == (None, 7, 0.0, None, 0)
    assert cards["CTRIA3", 12]["THETA"] == -20.0 and cards["CTRIA3", 13]["MCID"] == 7
    p2 = cards["PSHELL", 2]
    assert [p2[k] for k in ("MID1", "T", "MID2", "BENDING", "MID3", "SHEAR", "NSM", "Z1", "Z2", "MID4")] == [
        1, 0.01, 1, 1.2, 1, 0.8, 0.5, -0.004, 0.004, 1]
    assert [cards["PSHELL", 4][k] for k in ("MID2", "BENDING", "MID3", "SHEAR", "MID4")] == [None, 1.0, None, 0.833333,
                                                                                             None]
    p3 = cards["PCOMP", 3]
    assert (p3["Z0"], p3["NSM"], p3["FT"], p3["LAM"]) == (-0.003, 0.2, "HILL", "SYM")
    # blank MIDi / Ti take the previous ply's value; blank THETAi is 0.0, SOUTi NO
    assert p3["MID"] == (12, 12, 9, 9)
    assert p3["T"] == (0.001, 0.001, 0.0005, 0.0007)
    assert p3["THETA"] == (45.0, -45.0, 0.0, 90.0)
    assert p3["SOUT"] == ("YES", "NO", "NO", "NO")
    m8 = cards["MAT8", 8]
    assert (m8["G1Z"], m8["G2Z"], m8["XT"], m8["GE"], m8["STRN"]) == (3e9, None, 1.5e9, 0.01, 0.0)
    m2 = cards["MAT2", 9]
    assert (m2["G13"], m2["A1"], m2["MCSID"], m2["SS"]) == (1e8, 1e-6, 4, None)


def test_materials_table(model):
    mat = model.materials
    np.testing.assert_array_equal(mat.ids, [1, 8, 9, 12])
    np.testing.assert_array_equal(mat.kind, [MAT1, MAT8, MAT2, MAT8])
    np.testing.assert_array_equal(mat.E, [7e10, 1.4e11, 0.0, 1.4e11])
    np.testing.assert_array_equal(mat.G, [7e10 / 2.6, 5e9, 0.0, 5e9])
    np.testing.assert_array_equal(mat.nu, [0.3, 0.3, 0.0, 0.3])
    np.testing.assert_array_equal(mat.E2, [0.0, 1e10, 0.0, 1e10])
    np.testing.assert_array_equal(mat.G1z, [0.0, 3e9, 0.0, 3e9])
    np.testing.assert_array_equal(mat.G2z, [0.0, 0.0, 0.0, 2e9])  # blank G2Z: 0
    np.testing.assert_array_equal(mat.rho, [2700.0, 1500.0, 1550.0, 1600.0])
    np.testing.assert_array_equal(mat.Q[2], [[1e10, 3e9, 1e8], [3e9, 1.2e10, 0.0], [1e8, 0.0, 3.5e9]])
    np.testing.assert_array_equal(np.asarray(mat.Q)[[0, 1, 3]], np.zeros((3, 3, 3)))
    assert mat.Q.dtype == np.float64


def test_shell_sections(model):
    sec = model.shell_sections
    np.testing.assert_array_equal(sec.ids, [2, 3, 4, 5])
    np.testing.assert_array_equal(sec.composite, [False, True, False, True])
    np.testing.assert_array_equal(sec.shear_rigid, [False, False, True, True])  # PCOMP 5: MAT8 8, G2Z blank
    np.testing.assert_array_equal(sec.materials, [[0, 0, 0, 0], [-1] * 4, [2, -1, -1, -1], [-1] * 4])
    np.testing.assert_allclose(sec.t, [0.01, 2 * (0.001 + 0.001 + 0.0005 + 0.0007), 0.002, 0.001], rtol=1e-15)
    np.testing.assert_array_equal(sec.bending_ratio, [1.2, 1.0, 1.0, 1.0])
    np.testing.assert_array_equal(sec.shear_ratio, [0.8, 1.0, 0.833333, 1.0])
    np.testing.assert_array_equal(sec.nsm, [0.5, 0.2, 0.0, 0.0])
    np.testing.assert_allclose(sec.z0, [-0.005, -0.003, -0.001, -0.0005], rtol=1e-15)  # PCOMP 5: Z0 blank
    for name in ("membrane", "bending", "shear"):
        np.testing.assert_array_equal(getattr(sec, name), np.ones(4))


def test_lam_sym_mirrors_the_listed_plies(model):
    sec = model.shell_sections
    assert sec.ply_material.shape == sec.ply_t.shape == sec.ply_theta.shape == (4, 8)
    # PCOMP 3 lists plies (12, 45°), (12, -45°), (9, 0°), (9, 90°) bottom up: mirrored about the mid-plane
    np.testing.assert_array_equal(sec.ply_material[1], [3, 3, 2, 2, 2, 2, 3, 3])
    t = [0.001, 0.001, 0.0005, 0.0007]
    np.testing.assert_array_equal(sec.ply_t[1], t + t[::-1])
    np.testing.assert_allclose(sec.ply_theta[1], np.radians([45, -45, 0, 90, 90, 0, -45, 45]), rtol=1e-15)
    # padding: -1 materials, zero thickness; PSHELL rows have no plies
    np.testing.assert_array_equal(sec.ply_material[3], [1] + [-1] * 7)
    np.testing.assert_array_equal(sec.ply_t[3], [0.001] + [0.0] * 7)
    np.testing.assert_array_equal(sec.ply_material[[0, 2]], -np.ones((2, 8)))
    np.testing.assert_array_equal(np.asarray(sec.ply_t)[[0, 2]], np.zeros((2, 8)))


def test_shell_blocks(model):
    q, t = model.quads, model.trias
    np.testing.assert_array_equal(q.ids, [10, 11, 14])
    np.testing.assert_array_equal(q.pids, [2, 3, 2])
    np.testing.assert_array_equal(q.section, [0, 1, 0])
    np.testing.assert_array_equal(q.nodes, [[0, 1, 2, 3], [1, 4, 5, 2], [1, 4, 5, 2]])
    np.testing.assert_allclose(np.asarray(q.theta)[[0, 2]], np.radians([30.0, 0.0]), rtol=1e-15)
    np.testing.assert_array_equal(q.zoffs, [0.001, -0.002, 0.0])
    # TFLAG 1: ratios as given, blanks 1; TFLAG 0: Ti / T
    np.testing.assert_allclose(q.t_ratio, [[0.5, 1.0, 0.6, 1.0], [1.0] * 4, [1.2, 1.2, 0.8, 0.8]], rtol=1e-15)
    np.testing.assert_array_equal(t.ids, [12, 13])
    np.testing.assert_array_equal(t.section, [3, 2])
    np.testing.assert_array_equal(t.nodes, [[1, 4, 5], [0, 1, 3]])
    np.testing.assert_allclose(t.theta, np.radians([-20.0, 30.0]), atol=1e-6)  # CORD2R 7: x at 30°
    np.testing.assert_array_equal(t.t_ratio, np.ones((2, 3)))
    for block in (q, t):
        np.testing.assert_array_equal(block.k_scale, np.ones(len(block.ids)))
        np.testing.assert_array_equal(block.m_scale, np.ones(len(block.ids)))
    assert model.k6rot == 50.0


def test_model_without_shells():
    text = BASE.replace("CQUAD4", "$").replace("CTRIA3", "$").replace("SPC1,1,123456,1,4", "SPC1,1,123456,1,2")
    model = build_model(read_bdf_text(text, name="m.bdf"))
    assert model.quads.nodes.shape == (0, 4) and model.trias.nodes.shape == (0, 3)
    assert model.quads.t_ratio.shape == (0, 4) and model.trias.t_ratio.shape == (0, 3)
    assert model.shell_sections.ply_material.shape == (2, 4)
    with pytest.warns(UserWarning, match=r"\(1, 1\), \(1, 2\), \(1, 3\) carry mass but no stiffness"):
        empty = build_model(read_bdf_text("GRID,1\nCONM2,1,1,,1.\n", name="m.bdf"))
    assert empty.shell_sections.materials.shape == (0, 4) and empty.shell_sections.ply_material.shape == (0, 1)
    assert empty.shell_sections.ply_t.shape == (0, 1) and empty.quads.nodes.shape == (0, 4)
    assert empty.k6rot == 100.0


def _cord2r(cid: int, origin, z, x) -> str:
    a, b, c = origin, origin + z, origin + x
    return f"CORD2R,{cid},," + ",".join(f"{v:.17e}" for v in (*a, *b)) + "\n," + ",".join(f"{v:.17e}" for v in c)


@pytest.mark.parametrize("nn", [3, 4])
@pytest.mark.parametrize("angle", [0.0, 37.5, -120.0])
def test_theta_and_mcid_agree(nn, angle):
    """An MCID system whose x axis is the element x axis rotated by ``angle`` about the
    normal (tilted out of the plane too) gives the same ``theta`` as THETA = angle."""
    xyz = np.array([[0.1, 0.2, 0.3], [1.2, 0.5, 0.1], [1.4, 1.5, 0.6], [0.0, 1.1, 0.75]])[:nn]
    if nn == 4:  # make the quad flat: G4 in the plane of G1, G2, G3
        n = np.cross(xyz[1] - xyz[0], xyz[2] - xyz[0])
        xyz[3] -= ((xyz[3] - xyz[0]) @ n) / (n @ n) * n
    ex, ey, en = np.asarray(shell_frame(xyz))
    a = np.radians(angle)
    in_plane = np.cos(a) * ex + np.sin(a) * ey
    x = np.cos(0.4) * in_plane + np.sin(0.4) * en  # tilted out of the element plane
    z = np.cross(x, np.cross(en, x))  # any axis normal to x
    card = "CQUAD4" if nn == 4 else "CTRIA3"
    grids = "".join(f"GRID,{i + 1},," + ",".join(f"{v:.17e}" for v in p) + "\n" for i, p in enumerate(xyz))
    corners = ",".join(str(i + 1) for i in range(nn))
    text = (grids + "MAT1,1,7.+10,,0.3,2700.\nPSHELL,2,1,0.01,1,,1\n" + _cord2r(9, np.array([5.0, -3.0, 2.0]), z, x)
            + f"\n{card},1,2,{corners},{angle!r}\n{card},2,2,{corners},9\nSPC1,1,123456,1\n")
    model = _tables(read_bdf_text(text, name="m.bdf"))
    block = model.quads if nn == 4 else model.trias
    np.testing.assert_allclose(block.theta[1], block.theta[0], atol=1e-12)
    np.testing.assert_allclose(block.theta[0], a, rtol=1e-15)


BASE = """\
GRID,1,,0.,0.,0.
GRID,2,,1.,0.,0.
GRID,3,,1.,1.,0.
GRID,4,,0.,1.,0.
GRID,5,,2.,0.,0.
MAT1,1,7.+10,,0.3,2700.
MAT8,8,1.4+11,1.+10,0.3,5.+9,3.+9,2.+9,1500.
MAT2,9,1.+10,3.+9,0.,1.+10,0.,3.5+9,1500.
PSHELL,2,1,0.01,1,,1
PCOMP,3,,,,,,,SYM
,8,0.001,45.,,8,,-45.
CQUAD4,10,2,1,2,3,4
CTRIA3,11,3,2,5,3
PBAR,20,1,1.-3,1.-6,1.-6,2.-6
CBAR,21,20,2,5,0.,0.,1.
SPC1,1,123456,1,4
"""


def _fails(text: str, *parts: str) -> str:
    with pytest.raises(BulkDataError, match=".*".join(re.escape(p) for p in parts)) as info:
        _tables(read_bdf_text(text, name="m.bdf"))
    return str(info.value)


def test_full_build_of_shells():
    model = build_model(read_bdf_text(BASE, name="m.bdf"))
    assert len(model.quads.ids) == len(model.trias.ids) == 1
    grids = set(model.dofs.labels[:, 0].tolist())
    assert {2, 3, 5} <= grids and not {1, 4} & grids


@pytest.mark.parametrize(
    "old, new, parts",
    [
        # CQUAD4 / CTRIA3 fields
        ("CQUAD4,10,2,1,2,3,4", "CQUAD4,10,2,1,2,3,4,-3",
         "m.bdf:12: CQUAD4 10 field 8 (MCID): material coordinate system id must be >= 0, got -3"),
        ("CQUAD4,10,2,1,2,3,4", "CQUAD4,10,2,1,2,3,4\n,,,2",
         "m.bdf:13: CQUAD4 10 field 4 (TFLAG): TFLAG must be 0 (blank) or 1, got 2"),
        ("CQUAD4,10,2,1,2,3,4", "CQUAD4,10,2,1,2,3,4\n,,,,0.01,-0.01",
         "m.bdf:13: CQUAD4 10 field 6 (T2): corner thickness must be >= 0, got -0.01"),
        ("CQUAD4,10,2,1,2,3,4", "CQUAD4,10,2,1,2,3,4\n,,,,0.,0.,0.,0.",
         "m.bdf:13: CQUAD4 10 field 5 (T1): corner thicknesses T1..Tn must not all be zero"),
        ("CQUAD4,10,2,1,2,3,4", "CQUAD4,10,2,1,2,3,4,ABC", "m.bdf:12: CQUAD4 10 field 8 (THETA): expected an integer"),
        ("CTRIA3,11,3,2,5,3", "CTRIA3,11,3,2,5,3,,,1.", "m.bdf:13: CTRIA3 11 field 9: must be blank, got '1.'"),
        ("CTRIA3,11,3,2,5,3", "CTRIA3,11,3,2,5,3\n,,,,0.1,0.1,0.1,0.1",
         "m.bdf:14: CTRIA3 11 field 8: unexpected value (the CTRIA3 card has no field here)"),
        # PSHELL fields
        ("PSHELL,2,1,0.01,", "PSHELL,2,1,,", "m.bdf:9: PSHELL 2 field 4 (T): T is required here"),
        ("PSHELL,2,1,0.01,1,", "PSHELL,2,1,0.01,-1,",
         "m.bdf:9: PSHELL 2 field 5 (MID2): plane strain (MID2 = -1) is not supported"),
        ("PSHELL,2,1,", "PSHELL,2,0,", "m.bdf:9: PSHELL 2 field 3 (MID1): material id must be positive or blank"),
        ("PSHELL,2,1,0.01,1,,1", "PSHELL,2,1,0.01,1,,1.", "m.bdf:9: PSHELL 2 field 7 (MID3): expected an integer"),
        # PCOMP fields
        ("PCOMP,3,,,,,,,SYM", "PCOMP,3,,,,,,,MEM",
         "m.bdf:10: PCOMP 3 field 9 (LAM): LAM = MEM is not supported (only blank or SYM)"),
        ("PCOMP,3,,,,,,,SYM", "PCOMP,3,,,,,,,SMEAR", "m.bdf:10: PCOMP 3 field 9 (LAM): LAM = SMEAR is not supported"),
        ("PCOMP,3,,,,,,,SYM", "PCOMP,3,,,,,,,FOO",
         "m.bdf:10: PCOMP 3 field 9 (LAM): expected blank, SYM, MEM, BEND, SMEAR, SMCORE, got 'FOO'"),
        ("PCOMP,3,,,,,,,SYM", "PCOMP,3,,,,XX", "m.bdf:10: PCOMP 3 field 6 (FT): expected one of HILL, HOFF, TSAI"),
        ("PCOMP,3,,,,,,,SYM\n,8,0.001,45.,,8,,-45.", "PCOMP,3,,,,,,,SYM",
         "m.bdf:10: PCOMP 3 field 2 (MID1): PCOMP without plies"),
        ("PCOMP,3,,,,,,,SYM\n,8,0.001,45.,,8,,-45.", "PCOMP,3\n,,,,,,,",
         "m.bdf:11: PCOMP 3 field 2 (MID1): PCOMP without plies"),
        (",8,0.001,45.,,8,", ",,0.001,45.,,8,",
         "m.bdf:11: PCOMP 3 field 2 (MID1): required field is blank (the first ply has no previous ply to take MID"),
        (",8,0.001,45.,,8,", ",8,,45.,,8,",
         "m.bdf:11: PCOMP 3 field 3 (T1): required field is blank (the first ply has no previous ply to take T"),
        (",8,0.001,45.,,8,", ",8,0.001,45.,,8,-0.001,",
         "m.bdf:11: PCOMP 3 field 7 (T2): ply thickness must be > 0, got -0.001"),
        (",8,0.001,45.,,8,", ",8,0.,45.,,8,", "m.bdf:11: PCOMP 3 field 3 (T1): ply thickness must be > 0, got 0.0"),
        (",8,0.001,45.,,8,,-45.", ",8,0.001,45.,MAYBE,8,,-45.",
         "m.bdf:11: PCOMP 3 field 5 (SOUT1): expected YES or NO, got 'MAYBE'"),
        # MAT8, MAT2 fields and values
        ("MAT8,8,1.4+11,", "MAT8,8,,", "m.bdf:7: MAT8 8 field 3 (E1): required field is blank"),
        ("MAT8,8,1.4+11,1.+10,", "MAT8,8,1.4+11,,", "m.bdf:7: MAT8 8 field 4 (E2): required field is blank"),
        ("0.3,5.+9,3.+9,2.+9", ",5.+9,3.+9,2.+9", "m.bdf:7: MAT8 8 field 5 (NU12): required field is blank"),
        ("0.3,5.+9,3.+9,2.+9", "0.3,,3.+9,2.+9", "m.bdf:7: MAT8 8 field 6 (G12): required field is blank"),
        ("MAT8,8,1.4+11,", "MAT8,8,-1.4+11,", "m.bdf:7: MAT8 8 field 3 (E1): E1 must be > 0"),
        ("MAT8,8,1.4+11,1.+10,", "MAT8,8,1.4+11,0.,", "m.bdf:7: MAT8 8 field 4 (E2): E2 must be > 0, got 0.0"),
        ("0.3,5.+9,3.+9,2.+9", "0.3,-5.+9,3.+9,2.+9", "m.bdf:7: MAT8 8 field 6 (G12): G12 must be > 0"),
        ("0.3,5.+9,3.+9,2.+9", "4.,5.+9,3.+9,2.+9",
         "m.bdf:7: MAT8 8 field 5 (NU12): not positive definite: NU12² · E2 / E1 = 1.14286 must be < 1"),
        ("0.3,5.+9,3.+9,2.+9", "0.3,5.+9,3.+9,-2.+9", "m.bdf:7: MAT8 8 field 8 (G2Z): G2Z must be >= 0"),
        ("2.+9,1500.", "2.+9,-1.", "m.bdf:7: MAT8 8 field 9 (RHO): negative density -1.0"),
        ("MAT2,9,1.+10,3.+9,", "MAT2,9,1.+10,3.+10,",
         "m.bdf:8: MAT2 9 field 3 (G11): the matrix G11..G33 is not positive definite"),
        ("0.,3.5+9,1500.", "0.,,1500.", "m.bdf:8: MAT2 9 field 3 (G11): the matrix G11..G33 is not positive definite"),
        ("MAT8,8,", "MAT8,1,", "m.bdf:7: MAT8 1: duplicate material id 1, already defined by MAT1 at m.bdf:6"),
        # PSHELL / PCOMP values and references
        ("PSHELL,2,1,", "PSHELL,2,7,", "m.bdf:9: PSHELL 2 field 3 (MID1): material 7 is not defined"),
        ("PSHELL,2,1,0.01,1,,1", "PSHELL,2,1,0.01,1,,6",
         "m.bdf:9: PSHELL 2 field 7 (MID3): material 6 is not defined"),
        ("PSHELL,2,1,0.01,1,,1", "PSHELL,2,1,0.01,1,,1\n,,,6",
         "m.bdf:10: PSHELL 2 field 4 (MID4): material 6 is not defined"),
        ("PSHELL,2,1,0.01,", "PSHELL,2,1,-0.01,", "m.bdf:9: PSHELL 2 field 4 (T): T must be > 0, got -0.01"),
        ("PSHELL,2,1,0.01,1,,1", "PSHELL,2,,0.01,,,",
         "m.bdf:9: PSHELL 2 field 3 (MID1): MID1 or MID2 is required"),
        ("PSHELL,2,1,0.01,1,,1", "PSHELL,2,1,0.01,,,1",
         "m.bdf:9: PSHELL 2 field 7 (MID3): transverse shear (MID3) needs a bending material MID2"),
        ("PSHELL,2,1,0.01,1,,1", "PSHELL,2,,0.01,1,,1\n,,,1",
         "m.bdf:10: PSHELL 2 field 4 (MID4): membrane-bending coupling (MID4) needs MID1 and MID2"),
        ("PSHELL,2,1,0.01,1,,1", "PSHELL,2,1,0.01,1,0.,1", "m.bdf:9: PSHELL 2 field 6 (BENDING): 12I/T**3 must be > 0"),
        ("PSHELL,2,1,0.01,1,,1", "PSHELL,2,1,0.01,1,,1,-0.5", "m.bdf:9: PSHELL 2 field 8 (SHEAR): TS/T must be > 0"),
        ("PSHELL,2,1,0.01,1,,1", "PSHELL,2,1,0.01,1,,1,,-1.",
         "m.bdf:9: PSHELL 2 field 9 (NSM): negative non-structural mass -1.0"),
        (",8,0.001,45.,,8,,-45.", ",8,0.001,45.,,8,,-45.\n,6",
         "m.bdf:12: PCOMP 3 field 2 (MID3): material 6 is not defined"),
        ("PCOMP,3,,,", "PCOMP,3,,-0.1,", "m.bdf:10: PCOMP 3 field 4 (NSM): negative non-structural mass -0.1"),
        ("PCOMP,3,", "PSHELL,2,1,0.01\nPCOMP,3,",
         "m.bdf:10: PSHELL 2: duplicate property id 2, already defined by PSHELL at m.bdf:9"),
        # elements: references
        ("CQUAD4,10,2,", "CQUAD4,10,6,", "m.bdf:12: CQUAD4 10 field 3 (PID): property 6 is not defined"),
        ("CQUAD4,10,2,", "CQUAD4,10,20,",
         "m.bdf:12: CQUAD4 10 field 3 (PID): property 20 is a PBAR; CQUAD4 needs PSHELL or PCOMP"),
        ("CQUAD4,10,2,1,2,3,4", "CQUAD4,10,2,1,2,3,7", "m.bdf:12: CQUAD4 10 field 7 (G4): grid 7 is not defined"),
        ("CQUAD4,10,2,1,2,3,4", "CQUAD4,10,2,1,2,3,4,6", "m.bdf:12: CQUAD4 10 field 8 (MCID): coordinate system 6"),
        ("CTRIA3,11,3,2,5,3", "CTRIA3,11,3,2,5,3\n,,,,0.001",
         "m.bdf:14: CTRIA3 11 field 5 (T1): corner thicknesses are not supported with PCOMP 3"),
        ("CTRIA3,11,3,2,5,3", "CORD2R,6,,0.,0.,0.,1.,0.,0.\n,0.,0.,1.\nCTRIA3,11,3,2,5,3,6",
         "m.bdf:15: CTRIA3 11 field 7 (MCID): the x axis of coordinate system 6 is normal to the element"),
        ("CBAR,21,20,", "CBAR,21,2,", "m.bdf:15: CBAR 21 field 3 (PID): property 2 is a PSHELL; CBAR needs PBAR"),
        ("CTRIA3,11,", "CTRIA3,10,",
         "m.bdf:13: CTRIA3 10: duplicate element id 10, already defined by CQUAD4 at m.bdf:12"),
        # element geometry
        ("CQUAD4,10,2,1,2,3,4", "CQUAD4,10,2,1,2,3,2",
         "m.bdf:12: CQUAD4 10 field 7 (G4): grid 2 is given twice (G2 and G4)"),
        ("CTRIA3,11,3,2,5,3", "CTRIA3,11,3,2,5,2",
         "m.bdf:13: CTRIA3 11 field 6 (G3): grid 2 is given twice (G1 and G3)"),
        ("GRID,5,,2.,0.,0.", "GRID,5,,1.,0.,0.",
         "m.bdf:13: CTRIA3 11 field 5 (G2): corners G1 and G2 coincide (grids 2 and 5)"),
        ("GRID,5,,2.,0.,0.", "GRID,5,,1.,2.,0.",
         "m.bdf:13: CTRIA3 11 field 6 (G3): zero area: corners G1, G2, G3 are collinear"),
        ("GRID,3,,1.,1.,0.\nGRID,4,,0.,1.,0.", "GRID,3,,2.,0.,0.\nGRID,4,,3.,0.,0.",
         "m.bdf:12: CQUAD4 10 field 7 (G4): zero area"),
        ("GRID,3,,1.,1.,0.", "GRID,3,,0.3,0.3,0.",
         "m.bdf:12: CQUAD4 10 field 6 (G3): concave quad or corner angle >= 180° at G3 (grid 3)"),
        ("GRID,3,,1.,1.,0.", "GRID,3,,0.5,0.5,0.",
         "m.bdf:12: CQUAD4 10 field 6 (G3): concave quad or corner angle >= 180° at G3"),
        ("CQUAD4,10,2,1,2,3,4", "CQUAD4,10,2,1,3,2,4", "m.bdf:12: CQUAD4 10 field 7 (G4): zero area"),  # bow tie
        ("GRID,3,,1.,1.,0.", "GRID,3,,1.,1.,1.",
         "m.bdf:12: CQUAD4 10 field 7 (G4): warped quad: warp 0.289 (|h| / half the shorter diagonal) above 0.2"),
        # beams and rods need MAT1
        ("PBAR,20,1,", "PBAR,20,8,", "m.bdf:14: PBAR 20 field 3 (MID): material 8 is a MAT8; beams need MAT1"),
        ("PBAR,20,1,", "PBAR,20,9,", "m.bdf:14: PBAR 20 field 3 (MID): material 9 is a MAT2; beams need MAT1"),
        ("PBAR,20,", "PROD,22,8,1.-4\nPBAR,20,",
         "m.bdf:14: PROD 22 field 3 (MID): material 8 is a MAT8; rods need MAT1"),
        # PARAM K6ROT
        ("SPC1", "PARAM,K6ROT,-1.\nSPC1", "m.bdf:16: PARAM K6ROT field 3 (V1): K6ROT must be >= 0, got -1.0"),
        ("SPC1", "PARAM,K6ROT,100\nSPC1", "m.bdf:16: PARAM K6ROT field 3 (V1): K6ROT must be a real number"),
    ],
)
def test_refused(old, new, parts):
    assert old in BASE
    message = _fails(BASE.replace(old, new, 1), parts)
    assert message.startswith("m.bdf:")


def test_warped_quad_warns_with_its_location():
    text = BASE.replace("GRID,3,,1.,1.,0.", "GRID,3,,1.,1.,0.3")
    with pytest.warns(UserWarning, match=re.escape("m.bdf:12: CQUAD4 10 field 7 (G4): warped quad: warp 0.104 "
                                                   "(|h| / half the shorter diagonal) above 0.05")):
        model = _tables(read_bdf_text(text, name="m.bdf"))
    assert len(model.quads.ids) == 1
    # below the warning limit: no warning (warnings are errors in this suite)
    _tables(read_bdf_text(BASE.replace("GRID,3,,1.,1.,0.", "GRID,3,,1.,1.,0.1"), name="m.bdf"))


def test_pcomp_written_one_ply_per_line_equals_two_per_line():
    """A blank ply slot is no ply (decks write one ply per continuation line)."""
    one = read_bdf_text("PCOMP,3\n,8,0.001,45.\n,8,0.002,-45.\n,9,0.003\n", name="m.bdf")["PCOMP"][0]
    two = read_bdf_text("PCOMP,3\n,8,0.001,45.,,8,0.002,-45.\n,9,0.003\n", name="m.bdf")["PCOMP"][0]
    assert one == two and one["T"] == (0.001, 0.002, 0.003) and one["MID"] == (8, 8, 9)
