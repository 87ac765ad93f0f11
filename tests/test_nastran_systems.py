"""Coordinate systems (CORD1R/C/S, CORD2R/C/S, GRID CP and CD) and PARAM WTMASS, each
checked against an equivalent model written in basic coordinates or in mass units."""

import warnings

import numpy as np
import pytest

import jaxfem
from jaxfem.io import BulkDataError, read_bdf_text

# A bent frame of CBARs with masses and a grounded spring: grids 1..5, fixed at 1.
FRAME = """BEGIN BULK
{grids}
MAT1,1,7.e10,,0.33,2700.
PBAR,1,1,4.e-4,2.e-8,3.e-8,4.e-8
CBAR,11,1,1,2,0.,0.,1.
CBAR,12,1,2,3,0.,0.,1.
CBAR,13,1,3,4,1.,0.,0.
CBAR,14,1,4,5,1.,0.,0.
CONM2,21,3,,0.8,,,,,
,1.e-3,,1.e-3,,,1.e-3
CONM2,22,5,,0.5
CELAS2,31,2.e5,5,{spring_c},
SPC1,1,123456,1
{extra}
ENDDATA
"""
BASIC_GRIDS = """GRID,1,,0.,0.,0.
GRID,2,,0.5,0.,0.
GRID,3,,1.,0.,0.
GRID,4,,1.,0.5,0.
GRID,5,,1.,1.,0.{cd5}"""


def _build(text: str, **kwargs) -> jaxfem.Model:
    return jaxfem.build_model(read_bdf_text(text, name="m.bdf"), **kwargs)


def _modes(model: jaxfem.Model, n: int = 8):
    K, M = jaxfem.assemble(model)
    lam, phi = jaxfem.eigh(K, M)
    return np.asarray(lam[:n]), np.asarray(phi[:, :n])


def _frame(grids: str = BASIC_GRIDS.format(cd5=""), spring_c: int = 2, extra: str = "") -> jaxfem.Model:
    return _build(FRAME.format(grids=grids, spring_c=spring_c, extra=extra))


def _basic_shape(model: jaxfem.Model, phi: np.ndarray, grid: int) -> np.ndarray:
    """Translations of ``grid`` in basic axes for every mode (3 × n)."""
    row = int(np.flatnonzero(model.node_ids == grid)[0])
    index, coef = model.dofs.index[row], model.dofs.coef[row]
    padded = np.vstack([phi, np.zeros((1, phi.shape[1]))])
    return coef[:3] @ padded[index]


def test_grids_placed_in_cylindrical_spherical_and_chained_systems_equal_basic():
    """Grid 4 at (1, 0.5, 0) and 5 at (1, 1, 0) written in a CORD2C about (1, 0, 0) and a
    CORD2S whose reference is a CORD2R: the model equals the basic one to rounding."""
    grids = """GRID,1,,0.,0.,0.
GRID,2,,0.5,0.,0.
GRID,3,,1.,0.,0.
GRID,4,7,0.5,90.,0.
GRID,5,9,1.,90.,90.
CORD2C,7,,1.,0.,0.,1.,0.,1.
,2.,0.,0.
CORD2R,8,,1.,0.,0.,1.,0.,1.
,2.,0.,0.
CORD2S,9,8,0.,0.,0.,0.,0.,1.
,1.,0.,0."""
    model, basic = _frame(grids), _frame()
    np.testing.assert_allclose(model.xyz, basic.xyz, atol=1e-14)
    np.testing.assert_allclose(_modes(model)[0], _modes(basic)[0], rtol=1e-9)


def test_cord1_systems_are_defined_by_grids():
    """CORD1C 7: origin grid 3 (1, 0, 0), z towards grid 6 above it, x–z plane through
    grid 2, so x = −basic x and y = −basic y: grid 4 at R = 0.5, θ = −90° is (1, 0.5, 0)."""
    grids = """GRID,1,,0.,0.,0.
GRID,2,,0.5,0.,0.
GRID,3,,1.,0.,0.
GRID,6,,1.,0.,1.
GRID,4,7,0.5,-90.,0.
GRID,5,,1.,1.,0.
CORD1C,7,3,6,2"""
    model = _frame(grids, extra="CONM2,23,6,,0.1\nSPC1,1,123456,6")
    np.testing.assert_allclose(model.xyz[model.node_index([4])[0]], [1.0, 0.5, 0.0], atol=1e-14)


def test_cylindrical_displacement_system_equals_the_basic_model():
    """Grid 5 at (1, 1, 0), θ = 45° of a CORD2C about basic z, with CD in that system:
    its global components are e_R, e_θ, z. A spring on component 2 (e_θ) differs from
    one along basic y; on component 3 (z, common to both) the models are equal, with
    equal basic mode shapes."""
    cyl = "CORD2C,7,,0.,0.,0.,0.,0.,1.\n,1.,0.,0."
    model = _frame(BASIC_GRIDS.format(cd5=",7") + "\n" + cyl)
    basic = _frame()
    lam, phi = _modes(model)
    lam0, phi0 = _modes(basic)
    assert not np.allclose(lam, lam0, rtol=1e-6)
    # Component 3 (z) is the same axis in both: springs on it give identical models.
    model = _frame(BASIC_GRIDS.format(cd5=",7") + "\n" + cyl, spring_c=3)
    basic = _frame(spring_c=3)
    lam, phi = _modes(model)
    lam0, phi0 = _modes(basic)
    np.testing.assert_allclose(lam, lam0, rtol=1e-9)
    for k in range(len(lam)):
        a, b = _basic_shape(model, phi, 5)[:, k], _basic_shape(basic, phi0, 5)[:, k]
        assert min(np.linalg.norm(a - b), np.linalg.norm(a + b)) < 1e-9 * max(np.linalg.norm(b), 1.0)
    labels = {tuple(x) for x in model.dofs.labels}
    assert (5, 1) in labels and (5, 2) in labels
    np.testing.assert_allclose(model.dofs.cd[model.node_index([5])[0]][:, 0], [2**-0.5, 2**-0.5, 0.0], atol=1e-15)


def test_spring_and_spc_in_a_rotated_displacement_system_act_along_its_axes():
    """A CD system rotated 90° about z (x' = basic y): a spring on component 1 and an SPC
    on component 2 of grid 5 equal the basic model with the spring on 2 and the SPC on 1."""
    rot = "CORD2R,7,,0.,0.,0.,0.,0.,1.\n,0.,1.,0."
    model = _frame(BASIC_GRIDS.format(cd5=",7") + "\n" + rot, spring_c=1, extra="SPC1,1,2,5")
    basic = _frame(spring_c=2, extra="SPC1,1,1,5")
    np.testing.assert_allclose(_modes(model)[0], _modes(basic)[0], rtol=1e-9)


def test_rbe2_and_rbe3_between_grids_in_local_displacement_systems():
    """RBE2 and RBE3 whose grids have CD systems tilted about x and z: the constrained
    model equals the basic one (rigid-body relations written in each grid's axes)."""
    tilt = "CORD2R,7,,0.,0.,0.,0.,0.3,1.\n,1.,0.,0.2\nCORD2R,8,,0.,0.,0.,0.1,0.,1.\n,0.,1.,0."
    grids = BASIC_GRIDS.format(cd5="").replace("GRID,4,,1.,0.5,0.", "GRID,4,,1.,0.5,0.,7") + "\n" + tilt
    extra = "GRID,6,,1.2,1.,0.,8\nGRID,7,,1.,1.2,0.,7\nRBE2,41,5,123456,6\nRBE3,42,,7,123456,1.,123,4,5\n,6"
    model = _frame(grids, spring_c=3, extra=extra + "\nCONM2,24,6,,0.2\nCONM2,25,7,,0.3")
    basic = _frame(spring_c=3, extra=extra.replace(",8\n", "\n").replace(",7\n", "\n")
                   + "\nCONM2,24,6,,0.2\nCONM2,25,7,,0.3")
    np.testing.assert_allclose(_modes(model)[0], _modes(basic)[0], rtol=1e-10)


def test_conm2_offset_and_inertia_in_a_rotated_system():
    """CONM2 with CID 7 (rotated 90° about z): offset (0.1, 0, 0) and I11 in it equal the
    basic CONM2 with offset (0, 0.1, 0) and I22."""
    rot = "CORD2R,7,,0.,0.,0.,0.,0.,1.\n,0.,1.,0."
    model = _frame(extra=rot + "\nCONM2,23,4,7,0.4,0.1,,,\n,2.e-3,,1.e-4,,,3.e-4")
    basic = _frame(extra="CONM2,23,4,,0.4,0.,0.1,,\n,1.e-4,,2.e-3,,,3.e-4")
    np.testing.assert_allclose(_modes(model)[0], _modes(basic)[0], rtol=1e-9)


def test_undefined_and_looping_systems_are_located_errors():
    with pytest.raises(BulkDataError, match=r"m.bdf:\d+: GRID 5 field 7 \(CD\): coordinate system 9 is not defined"):
        _frame(BASIC_GRIDS.format(cd5=",9"))
    loop = "GRID,1,,0.,0.,0.\nGRID,2,,0.5,0.,0.\nGRID,3,7,1.,0.,0.\nGRID,4,,1.,0.5,0.\nGRID,5,,1.,1.,0.\nCORD1R,7,3,4,5"
    with pytest.raises(BulkDataError, match="refer to each other in a loop"):
        _frame(loop)


def _scaled(c: float, wtmass: str = "") -> str:
    """The frame with every mass input times ``c`` (densities, NSM, CONM2 mass and
    inertia) and an optional PARAM WTMASS."""
    text = FRAME.format(grids=BASIC_GRIDS.format(cd5=""), spring_c=2, extra=wtmass)
    text = text.replace("0.33,2700.", f"0.33,{2700. * c!r}").replace(
        "CONM2,21,3,,0.8,,,,,\n,1.e-3,,1.e-3,,,1.e-3", f"CONM2,21,3,,{0.8 * c!r},,,,,\n,{1e-3 * c!r},,{1e-3 * c!r},,,"
                                                        f"{1e-3 * c!r}")
    text = text.replace("CONM2,22,5,,0.5", f"CONM2,22,5,,{0.5 * c!r}")
    return text.replace("PBAR,1,1,4.e-4,2.e-8,3.e-8,4.e-8", f"PBAR,1,1,4.e-4,2.e-8,3.e-8,4.e-8,{0.1 * c!r}")


def test_wtmass_deck_equals_its_mass_unit_version():
    """Masses given as weights (× g = 9.80665) with PARAM WTMASS 1/g: the same model."""
    g = 9.80665
    weights = _build(_scaled(g, f"PARAM,WTMASS,{1.0 / g!r}"))
    masses = _build(_scaled(1.0))
    np.testing.assert_allclose(_modes(weights)[0], _modes(masses)[0], rtol=1e-9)
    assert weights.materials.rho.dtype == np.float64
    np.testing.assert_allclose(float(weights.masses.m[0]), 0.8, rtol=1e-15)


def test_wtmass_must_be_positive():
    with pytest.raises(BulkDataError, match="WTMASS must be a real > 0"):
        _build(_scaled(1.0, "PARAM,WTMASS,0."))


def test_no_warning_for_a_plain_frame():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _frame()
