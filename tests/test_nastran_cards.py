"""The cards real decks carry, each checked against a closed form or an equivalent model
built from cards verified before: scalar points and elements (SPOINT, CELAS3/4,
CMASS1–4, CDAMP, CVISC), CONM1, CONROD, RBAR, RBE1, RROD, DMIG (K2GG, M2GG, B2GG),
SPCADD/MPCADD and the case control's choices."""

import warnings

import numpy as np
import pytest

import jaxfem
from jaxfem.io import BulkDataError, read_bdf_text


def _build(text: str, **kwargs) -> jaxfem.Model:
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", ".* carry mass but no stiffness", UserWarning)
        return jaxfem.build_model(read_bdf_text(text, name="m.bdf"), **kwargs)


def _lam(model: jaxfem.Model, n: int | None = None) -> np.ndarray:
    K, M = jaxfem.assemble(model)
    lam = np.asarray(jaxfem.eigh(K, M)[0])
    return lam if n is None else lam[:n]


# --- scalar points and scalar elements -------------------------------------------------


def test_spoint_spring_mass_chain_matches_the_closed_form():
    """Two scalar points: k1 to ground (CELAS4), k2 between them (CELAS3 + PELAS), masses
    m1, m2 (CMASS4, CMASS3 + PMASS): ω² are the eigenvalues of K = [[k1+k2, −k2], [−k2, k2]],
    M = diag(m1, m2)."""
    k1, k2, m1, m2 = 3.0e4, 1.0e4, 2.0, 0.5
    model = _build(f"SPOINT,1,2\nCELAS4,11,{k1!r},1\nCELAS3,12,5,1,2\nPELAS,5,{k2!r}\n"
                   f"CMASS4,21,{m1!r},1\nCMASS3,22,6,2\nPMASS,6,{m2!r}\n")
    K = np.array([[k1 + k2, -k2], [-k2, k2]])
    expected = np.sort(np.linalg.eigvals(np.linalg.solve(np.diag([m1, m2]), K)).real)
    np.testing.assert_allclose(_lam(model), expected, rtol=1e-12)
    assert [tuple(x) for x in model.dofs.labels] == [(1, 1), (2, 1)]


def test_cmass_on_grid_components_equals_a_conm2_in_that_direction():
    """CMASS2 on components 1, 2, 3 of a grid held by three grounded springs: the same
    eigenvalues as a CONM2 of that mass; CMASS1 between two grids acts on their difference."""
    base = "GRID,1,,0.,0.,0.,,456\nCELAS2,1,100.,1,1\nCELAS2,2,200.,1,2\nCELAS2,3,400.,1,3\n"
    cmass = _build(base + "CMASS2,11,2.,1,1\nCMASS2,12,2.,1,2\nCMASS2,13,2.,1,3\n")
    conm2 = _build(base + "CONM2,11,1,,2.\n")
    np.testing.assert_allclose(_lam(cmass), _lam(conm2), rtol=1e-14)
    np.testing.assert_allclose(_lam(cmass), [50.0, 100.0, 200.0], rtol=1e-14)
    two = _build("GRID,1,,0.,0.,0.,,23456\nGRID,2,,1.,0.,0.,,23456\nCELAS2,1,100.,1,1\nCELAS2,2,100.,2,1\n"
                 "CMASS2,11,1.,1,1\nCMASS2,12,1.,2,1\nCMASS1,13,7,1,1,2,1\nPMASS,7,0.5\n")
    # M = [[1.5, -0.5], [-0.5, 1.5]], K = 100 I: ω² = 100/1 and 100/2
    np.testing.assert_allclose(_lam(two), [50.0, 100.0], rtol=1e-14)


def test_cdamp_gives_the_single_dof_oscillator_frf():
    """k, m on a scalar point and a CDAMP4 b: H(ω) = 1/(k − ω²m + iωb)."""
    k, m, b = 4.0e4, 1.5, 12.0
    model = _build(f"SPOINT,1\nCELAS4,1,{k!r},1\nCMASS4,2,{m!r},1\nCDAMP4,3,{b!r},1\n")
    K, M = (a.todense() for a in jaxfem.assemble(model))
    B = jaxfem.viscous_damping(model).todense()
    np.testing.assert_allclose(np.asarray(B), [[b]], rtol=1e-15)
    omega = np.array([50.0, 163.0, 400.0])
    h = jaxfem.frf_direct(K, M, omega, [0], [0], D=B)
    np.testing.assert_allclose(np.asarray(h).reshape(-1), 1.0 / (k - omega**2 * m + 1j * omega * b), rtol=1e-12)


def test_cvisc_damps_along_its_axis():
    """CVISC from a fixed grid 1 to grid 2 along (3, 4, 0)/5: B on grid 2's translations is
    CE n nᵀ."""
    model = _build("GRID,1,,0.,0.,0.,,123456\nGRID,2,,3.,4.,0.,,456\nCROD,1,1,1,2\nPROD,1,1,1.e-4,1.e-8\n"
                   "MAT1,1,7.e10,,0.3,2700.\nCVISC,5,6,1,2\nPVISC,6,20.,0.\nCELAS2,7,1.,2,3\nCELAS2,8,1.,2,1\n")
    B = np.asarray(jaxfem.viscous_damping(model).todense())
    assert [tuple(x) for x in model.dofs.labels] == [(2, 1), (2, 2), (2, 3)]
    n = np.array([0.6, 0.8, 0.0])
    np.testing.assert_allclose(B, 20.0 * np.outer(n, n), atol=1e-14)


def test_scalar_point_component_must_be_0_and_grid_component_1_to_6():
    with pytest.raises(BulkDataError, match="scalar point"):
        _build("SPOINT,1\nCELAS2,1,10.,1,3\nCMASS4,2,1.,1\n")


# --- masses and rods --------------------------------------------------------------------

BAR = """GRID,1,,0.,0.,0.,,123456
GRID,2,,1.,0.,0.
MAT1,1,7.e10,,0.3,2700.
PBAR,1,1,4.e-4,2.e-8,3.e-8,4.e-8
CBAR,1,1,1,2,0.,0.,1.
"""


def test_conm1_equals_the_conm2_it_writes_out():
    """CONM1 with M11=M22=M33=m and the rotational block equal to a CONM2's inertia
    (with its sign convention), in a CID rotated 90° about z: the same model."""
    conm2 = _build(BAR + "CONM2,5,2,,3.,,,,\n,0.1,0.01,0.2,,,0.3\n")
    rot = "CORD2R,7,,0.,0.,0.,0.,0.,1.\n,0.,1.,0.\n"
    # basic tensor [[0.1, −0.01, 0], [−0.01, 0.2, 0], [0, 0, 0.3]]; in system 7 (x' = y, y' = −x):
    # M44 = 0.2, M55 = 0.1, M54 = x'ᵀ I y' = 0.01, M66 = 0.3
    conm1 = _build(BAR + rot + "CONM1,5,2,7,3.,,3.,,\n,3.,,,,0.2,,,\n,0.01,0.1,,,,,,0.3\n")
    np.testing.assert_allclose(_lam(conm1), _lam(conm2), rtol=1e-12)


def test_conrod_equals_crod_with_prod():
    crod = _build("GRID,1,,0.,0.,0.,,123456\nGRID,2,,2.,1.,0.,,456\nGRID,3,,0.,2.,0.,,123456\n"
                  "MAT1,1,7.e10,,0.3,2700.\nPROD,4,1,1.e-4,2.e-9,,0.05\nCROD,1,4,1,2\nCROD,2,4,2,3\nCONM2,9,2,,1.")
    conrod = _build("GRID,1,,0.,0.,0.,,123456\nGRID,2,,2.,1.,0.,,456\nGRID,3,,0.,2.,0.,,123456\n"
                    "MAT1,1,7.e10,,0.3,2700.\nCONROD,1,1,2,1,1.e-4,2.e-9,,0.05\nCONROD,2,2,3,1,1.e-4,2.e-9,,0.05\n"
                    "CONM2,9,2,,1.")
    np.testing.assert_allclose(_lam(conrod), _lam(crod), rtol=1e-14)


# --- rigid elements ---------------------------------------------------------------------

TWO_MASSES = """GRID,1,,0.,0.,0.
GRID,2,,1.,0.5,0.2
GRID,3,,2.,0.,0.,,123456
MAT1,1,7.e10,,0.3,0.
PBAR,1,1,4.e-4,2.e-8,3.e-8,4.e-8
CBAR,1,1,2,3,0.,0.,1.
CELAS2,7,1.e4,1,1
CELAS2,8,2.e4,1,5
CONM2,11,1,,2.,,,,\n,0.1,,0.2,,,0.3
CONM2,12,2,,1.,,,,\n,0.05,,0.05,,,0.05
"""


def test_rbar_and_rbe1_equal_the_rbe2():
    rbe2 = _lam(_build(TWO_MASSES + "RBE2,20,2,123456,1\n"))
    for rigid in ("RBAR,20,2,1,123456,,,123456", "RBAR,20,2,1,123,456", "RBAR,20,1,2,,123456",
                  "RBE1,20,2,123456,,,,,\n,UM,1,123456"):
        np.testing.assert_allclose(_lam(_build(TWO_MASSES + rigid + "\n")), rbe2, rtol=1e-10, err_msg=rigid)


def test_rbar_without_six_independent_components_is_a_located_error():
    with pytest.raises(BulkDataError, match=r"RBAR 20 field \d \(CNA\).*six"):
        _build(TWO_MASSES + "RBAR,20,2,1,12,456\n")


def test_rrod_holds_the_distance_between_two_masses():
    """Two masses on x (1 and 2 kg) joined by an RROD, a spring k to ground in x: ω² = k/3
    for the axial mode; the y mode is untouched (k_y/m each)."""
    text = ("GRID,1,,0.,0.,0.,,3456\nGRID,2,,1.,0.,0.,,3456\nCELAS2,1,300.,1,1\nCELAS2,2,100.,1,2\n"
            "CELAS2,3,400.,2,2\nCONM2,11,1,,1.\nCONM2,12,2,,2.\nRROD,20,1,2,,1\n")
    np.testing.assert_allclose(_lam(_build(text)), [100.0, 100.0, 200.0], rtol=1e-12)


# --- direct matrices, set combinations and the case control -----------------------------

CASE = """SOL 103
CEND
{case}
BEGIN BULK
GRID,1,,0.,0.,0.,,23456
GRID,2,,1.,0.,0.,,23456
CELAS2,1,100.,1,1,2,1
CONM2,11,1,,1.
CONM2,12,2,,1.
SPC1,1,1,1
SPC1,2,1,2
{bulk}
ENDDATA
"""


def test_dmig_stiffness_and_mass_equal_springs_and_masses():
    """K2GG adds a grounded spring 300 on grid 2 (symmetric form, IFO 6) and M2GG a mass
    0.5 coupling grids 1 and 2 (square form, IFO 1, both triangles)."""
    dmig = ("DMIG,KX,0,6,2,0\nDMIG,KX,2,1,,2,1,300.\n"
            "DMIG,MX,0,1,2,0\nDMIG,MX,1,1,,1,1,0.5,\n,2,1,-0.5\nDMIG,MX,2,1,,1,1,-0.5,\n,2,1,0.5\n")
    model = _build(CASE.format(case="SPC = 1\nK2GG = KX\nM2GG = MX", bulk=dmig))
    same = _build(CASE.format(case="SPC = 1", bulk="CELAS2,2,300.,2,1\nCMASS1,13,7,1,1,2,1\nPMASS,7,0.5"))
    np.testing.assert_allclose(_lam(model), _lam(same), rtol=1e-13)
    plain = _build(CASE.format(case="SPC = 1", bulk=dmig))  # not selected: not used
    np.testing.assert_allclose(_lam(plain), [100.0], rtol=1e-14)


def test_case_control_selects_spc_set_and_subcase():
    bulk = ""
    first = _build(CASE.format(case="SPC = 1", bulk=bulk))
    assert {tuple(x) for x in first.dofs.labels} == {(2, 1)}
    two = _build(CASE.format(case="SUBCASE 1\n SPC = 1\nSUBCASE 2\n SPC = 2", bulk=bulk), subcase=2)
    assert {tuple(x) for x in two.dofs.labels} == {(1, 1)}
    override = _build(CASE.format(case="SPC = 1", bulk=bulk), spc_set=2)
    assert {tuple(x) for x in override.dofs.labels} == {(1, 1)}


def test_spcadd_is_the_union_of_its_sets():
    model = _build(CASE.format(case="SPC = 9", bulk="SPCADD,9,1,2\nGRID,3,,2.,0.,0.,,23456\nCELAS2,3,5.,3,1\n"
                                                   "CONM2,13,3,,1."))
    assert {tuple(x) for x in model.dofs.labels} == {(3, 1)}
    with pytest.raises(BulkDataError, match="SPC set 4 is not defined"):
        _build(CASE.format(case="SPC = 9", bulk="SPCADD,9,1,4"))


def test_lumped_cbeam_has_torsional_inertia_and_cbar_has_none():
    """A cantilever rod section (r = 1) of nine CBARs and a last CBEAM, tip CONM2 inertia I:
    with lumped mass only the CBEAM's ρ(I1+I2)L/2 and I twist, so torsion is the 2-DoF system
    of grids 10 and 11 (Nastran's beam_modes example gives 3554.9 Hz)."""
    grids = "".join(f"GRID,{i + 1},,{float(i)!r},0.,0.\n" for i in range(11))
    bars = "".join(f"CBAR,{i},1,{i},{i + 1},0.,1.,0.\n" for i in range(1, 10))
    text = (grids + bars + "CBEAM,10,3,10,11,0.,1.,0.\nCONM2,21,11,,2.59-3,,,,\n,2.59-3,,2.59-3,,,2.59-3\n"
            "MAT1,2,3.+7,1.1628+7,,7.4851-4\nPBARL,1,2,,ROD\n,1.\nPBEAML,3,2,,ROD\n,1.\nSPC1,1,123456,1\n")
    lam = _lam(_build(text))
    k, inertia = 1.1628e7 * np.pi / 2, 7.4851e-4 * np.pi / 2 / 2  # GJ/L; ρ(I1+I2)L/2
    K = np.array([[k / 9 + k, -k], [-k, k]])
    torsion = np.linalg.eigvals(np.linalg.solve(np.diag([inertia, inertia + 2.59e-3]), K)).real.min()
    assert np.min(np.abs(lam / torsion - 1.0)) < 1e-9
    np.testing.assert_allclose(np.sqrt(torsion) / (2 * np.pi), 3554.92, rtol=1e-5)


def test_p_set_matrices_and_model_parameters_are_named_when_not_applied():
    with pytest.warns(UserWarning, match=r"m.bdf:4: K2PP = KX not applied"):
        _build(CASE.format(case="SPC = 1\nK2PP = KX", bulk="DMIG,KX,0,6,2,0\nDMIG,KX,2,1,,2,1,300."))
    with pytest.warns(UserWarning, match=r"MDLPRM QRSHEAR = 1 ignored"):
        _build(CASE.format(case="SPC = 1", bulk="MDLPRM,HDF5,1,QRSHEAR,1"))


def test_modes_command_follows_method_suport_and_subcase(tmp_path):
    from typer.testing import CliRunner

    from updating.cli import app

    deck = tmp_path / "deck.bdf"
    deck.write_text(CASE.format(case="METHOD = 5\nSUBCASE 1\n SPC = 1\nSUBCASE 2\n SPC = 2",
                                bulk="EIGRL,5,,,1\nSUPORT,1,1\nGRID,3,,2.,0.,0.,,23456\nCELAS2,3,5.,3,1\n"
                                     "CONM2,13,3,,1."))
    result = CliRunner().invoke(app, ["modes", str(deck), "--subcase", "2", "--json", str(tmp_path / "m.json")])
    assert result.exit_code == 0, result.output
    assert "METHOD: EIGRL 5" in result.output and "SUPORT: 1 reference DoFs" in result.output
    import json

    data = json.loads((tmp_path / "m.json").read_text())
    # subcase 2 fixes grid 2: grid 1 (1 kg) on k = 100 and grid 3 (k = 5): one mode asked (ND = 1)
    np.testing.assert_allclose(data["eigenvalues"], [5.0], rtol=1e-12)


def test_mpcadd_is_the_union_of_its_sets():
    """MPC 1 ties grid 3 to grid 2, MPC 2 grid 4 to grid 2; MPCADD 9 = 1 + 2: grid 2 alone
    carries the three unit masses on the spring k = 100, λ = 100/3."""
    bulk = ("GRID,3,,2.,0.,0.,,23456\nGRID,4,,3.,0.,0.,,23456\nCONM2,13,3,,1.\nCONM2,14,4,,1.\n"
            "MPC,1,3,1,1.,2,1,-1.\nMPC,2,4,1,1.,2,1,-1.\nMPCADD,9,1,2\n")
    model = _build(CASE.format(case="SPC = 1\nMPC = 9", bulk=bulk))
    assert {tuple(x) for x in model.dofs.labels} == {(2, 1)}
    np.testing.assert_allclose(_lam(model), [100.0 / 3.0], rtol=1e-14)


def test_a_deck_split_over_include_files_builds_the_same_model(tmp_path):
    """The deck with its bulk data in two included files (one nested, one quoted path in a
    subfolder) gives the model of the merged deck, eigenvalue for eigenvalue."""
    merged = CASE.format(case="SPC = 1\nK2GG = KX", bulk="DMIG,KX,0,6,2,0\nDMIG,KX,2,1,,2,1,300.")
    head, bulk = merged.split("BEGIN BULK\n")
    cards = bulk.replace("ENDDATA\n", "").splitlines()
    (tmp_path / "parts").mkdir()
    (tmp_path / "parts" / "grids.bdf").write_text("\n".join(cards[:2]) + "\nINCLUDE 'more.bdf'\n")
    (tmp_path / "parts" / "more.bdf").write_text("\n".join(cards[2:]) + "\n")
    main = tmp_path / "main.bdf"
    main.write_text(head + "BEGIN BULK\nINCLUDE 'parts/grids.bdf'\nENDDATA\n")
    from jaxfem.io import read_bdf

    split = jaxfem.build_model(read_bdf(main))
    np.testing.assert_array_equal(_lam(split), _lam(_build(merged)))
    assert read_bdf(main).files == (str(main), str(tmp_path / "parts" / "grids.bdf"),
                                    str(tmp_path / "parts" / "more.bdf"))


def test_pbar_with_i12_equals_the_principal_section_in_turned_axes():
    """PBAR I1 = 3, I2 = 1, I12 = 1 (×1e-8): principal moments 2 ± √2 at θ = 22.5°; the same
    bar as a PBAR of those moments with its orientation vector turned by θ about the axis."""
    frame = ("GRID,1,,0.,0.,0.,,123456\nGRID,2,,1.,0.,0.\nGRID,3,,2.,0.,0.\nMAT1,1,7.e10,,0.3,2700.\n"
             "CBAR,1,1,1,2,{v}\nCBAR,2,1,2,3,{v}\nCONM2,5,3,,0.5\n")
    unsymmetric = _build(frame.format(v="0.,1.,0.") + "PBAR,1,1,1.-4,3.-8,1.-8,2.-8\n,\n,,,1.-8\n")
    c, s = float(np.cos(np.pi / 8)), float(np.sin(np.pi / 8))
    principal = _build(frame.format(v=f"0.,{c!r},{s!r}") + f"PBAR,1,1,1.-4,{(2 + 2**0.5) * 1e-8!r},"
                                                           f"{(2 - 2**0.5) * 1e-8!r},2.-8\n")
    np.testing.assert_allclose(_lam(unsymmetric), _lam(principal), rtol=1e-9)


def test_conrod_errors_name_the_conrod():
    with pytest.raises(BulkDataError, match=r"m.bdf:4: CONROD 7 field 6 \(A\): area must be > 0"):
        _build("GRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\nMAT1,1,7.e10,,0.3,2700.\nCONROD,7,1,2,1,-1.\n")
    with pytest.raises(BulkDataError, match=r"CONROD 7 field 5 \(MID\): material 4 is not defined"):
        _build("GRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\nMAT1,1,7.e10,,0.3,2700.\nCONROD,7,1,2,4,1.\n")
