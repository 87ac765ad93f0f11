"""jaxfem.mass_properties: Nastran's grid-point weight generator against hand computations."""

import warnings

import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from jaxfem._mass_properties import _component_mass, _rigid_rows
from jaxfem.io import read_bdf_text

# Beams with NSM (one with offsets WA = WB = 0.1 z), a rod with NSM, a quad and a triangle
# with NSM, a CONM2 with offset and inertia on grid 3, a CONM2 on grid 10 that an RBE2
# makes dependent, grid 1 clamped (its share of the beam mass counts all the same).
MIXED = """BEGIN BULK
GRID,1,,0.,0.,0.
GRID,2,,1.,0.,0.
GRID,3,,2.,0.,0.
GRID,5,,0.,1.,0.
GRID,6,,1.,1.,0.
GRID,7,,1.,2.,0.
GRID,8,,0.,2.,0.
GRID,9,,2.,1.5,0.
GRID,10,,2.5,0.,0.
MAT1,1,7.e10,,0.3,2700.
PBAR,1,1,1.e-4,1.e-8,2.e-8,3.e-8,0.5
PROD,2,1,2.e-4,1.e-9,,0.3
PSHELL,3,1,0.002,1,,1,,0.4
CBAR,1,1,1,2,0.,1.,0.
CBAR,2,1,2,3,0.,1.,0.
,,,0.,0.,0.1,0.,0.,0.1
CROD,3,2,3,6
CQUAD4,4,3,5,6,7,8
CTRIA3,5,3,6,9,7
CONM2,6,3,0,1.5,0.,0.,0.2
,0.1,0.01,0.2,0.,0.02,0.3
CONM2,7,10,,0.6
RBE2,8,3,123456,10
SPC1,1,123456,1
ENDDATA
"""

# (mass [kg], its centre [m]): (ρA + NSM)·L at the middle of each beam (between the offset
# ends) and rod, (ρt + NSM)·area at each shell's centroid, the CONM2s at grid + offset.
RHO = 2700.0
PARTS = [
    ((RHO * 1e-4 + 0.5) * 1.0, (0.5, 0.0, 0.0)),
    ((RHO * 1e-4 + 0.5) * 1.0, (1.5, 0.0, 0.1)),
    ((RHO * 2e-4 + 0.3) * np.sqrt(2.0), (1.5, 0.5, 0.0)),
    ((RHO * 0.002 + 0.4) * 1.0, (0.5, 1.5, 0.0)),
    ((RHO * 0.002 + 0.4) * 0.5, (4.0 / 3.0, 1.5, 0.0)),
    (1.5, (2.0, 0.0, 0.2)),
    (0.6, (2.5, 0.0, 0.0)),
]
HAND_MASS = sum(m for m, _ in PARTS)
HAND_CG = sum(m * np.array(x) for m, x in PARTS) / HAND_MASS


def _build(text: str) -> jaxfem.Model:
    with warnings.catch_warnings():  # free CONM2 grids: "mass but no stiffness"
        warnings.simplefilter("ignore", UserWarning)
        return jaxfem.build_model(read_bdf_text(text))


def _coupmass(value: int | None) -> str:
    return MIXED if value is None else MIXED.replace("ENDDATA", f"PARAM,COUPMASS,{value}\nENDDATA")


@pytest.mark.parametrize("coupmass", [None, 1])
def test_mixed_model_mass_and_cg_equal_the_hand_computation(coupmass):
    """Lumped (default) and consistent mass: total mass and CG as by hand to 1e-12, every
    direction the same mass, and the mass of each block."""
    model = _build(_coupmass(coupmass))
    assert model.lumped == (coupmass is None)
    p = jaxfem.mass_properties(model)
    assert p.mass == pytest.approx(HAND_MASS, rel=1e-12)
    np.testing.assert_allclose(p.direction_mass, HAND_MASS, rtol=1e-12)
    np.testing.assert_allclose(p.cg, HAND_CG, rtol=0, atol=1e-12 * np.abs(HAND_CG).max())
    np.testing.assert_array_equal(p.s, np.eye(3))
    assert p.by_block == pytest.approx({"beams": PARTS[0][0] + PARTS[1][0], "rods": PARTS[2][0], "quads": PARTS[3][0],
                                        "trias": PARTS[4][0], "masses": 2.1}, rel=1e-12)


def test_lumped_and_consistent_mass_agree():
    lumped, consistent = (jaxfem.mass_properties(_build(_coupmass(v))) for v in (None, 1))
    assert lumped.mass == pytest.approx(consistent.mass, rel=1e-12)
    np.testing.assert_allclose(lumped.cg, consistent.cg, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lumped.m0[:3], consistent.m0[:3], rtol=0, atol=1e-12 * HAND_MASS)


CONM2S = """BEGIN BULK
GRID,1,,0.,0.,0.
GRID,2,,1.,2.,0.
GRID,3,,-1.,0.5,2.
CONM2,1,1,,2.,0.1,0.,0.3
,0.5,0.05,0.4,0.02,-0.03,0.6
CONM2,2,2,-1,3.,1.2,2.,0.5
,0.2,-0.01,0.3,0.,0.04,0.25
CONM2,3,3,,1.5
,0.1,,0.1,,,0.1
ENDDATA
"""


def _tensor(i11, i21, i22, i31, i32, i33):
    """CONM2's inertia fields as a tensor (Nastran's sign convention)."""
    return np.array([[i11, -i21, -i31], [-i21, i22, -i32], [-i31, -i32, i33]])


def test_conm2_inertia_about_the_cg_is_the_parallel_axis_sum():
    masses = [2.0, 3.0, 1.5]
    centres = [np.array([0.1, 0.0, 0.3]), np.array([1.2, 2.0, 0.5]), np.array([-1.0, 0.5, 2.0])]
    own = [_tensor(0.5, 0.05, 0.4, 0.02, -0.03, 0.6), _tensor(0.2, -0.01, 0.3, 0.0, 0.04, 0.25), 0.1 * np.eye(3)]
    m = sum(masses)
    cg = sum(mi * c for mi, c in zip(masses, centres)) / m
    inertia = sum(j + mi * (np.dot(c - cg, c - cg) * np.eye(3) - np.outer(c - cg, c - cg))
                  for mi, c, j in zip(masses, centres, own))
    p = jaxfem.mass_properties(_build(CONM2S))
    assert p.mass == pytest.approx(m, rel=1e-12)
    np.testing.assert_allclose(p.cg, cg, rtol=1e-12)
    np.testing.assert_allclose(p.inertia, inertia, rtol=0, atol=1e-12 * np.abs(inertia).max())
    np.testing.assert_allclose(p.i_s, 2 * np.diag(np.diag(inertia)) - inertia, atol=1e-12 * np.abs(inertia).max())
    np.testing.assert_allclose(p.principal_inertia, np.sort(np.linalg.eigvalsh(inertia))[::-1], rtol=1e-12)
    axes = p.principal_axes
    np.testing.assert_allclose(axes.T @ inertia @ axes, np.diag(p.principal_inertia), atol=1e-12 * np.abs(inertia).max())
    assert np.linalg.det(axes) == pytest.approx(1.0)


def test_reference_grid_moves_m0_only():
    """About grid 2: M0 is the origin's moved rigidly (Tᵀ M0 T); mass, CG and inertia stay."""
    model = _build(CONM2S)
    origin, at2 = jaxfem.mass_properties(model), jaxfem.mass_properties(model, reference=2)
    x = np.array([1.0, 2.0, 0.0])
    skew = np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])
    t = np.block([[np.eye(3), skew], [np.zeros((3, 3)), np.eye(3)]])
    np.testing.assert_allclose(at2.m0, t.T @ origin.m0 @ t, atol=1e-12 * np.abs(at2.m0).max())
    np.testing.assert_allclose(at2.cg, origin.cg, atol=1e-12)
    np.testing.assert_allclose(at2.inertia, origin.inertia, atol=1e-12)
    np.testing.assert_allclose(at2.direction_cg + np.where(np.eye(3) > 0, 0.0, x), origin.direction_cg, atol=1e-12)
    assert at2.reference_grid == 2 and at2.reference.tolist() == x.tolist()
    with pytest.raises(ValueError, match="grid id"):
        jaxfem.mass_properties(model, reference=99)


NASTRAN_EXAMPLE = """BEGIN BULK
GRID,1,,0.,0.,0.
GRID,2,,1.,0.,0.
GRID,3,,0.5,1.,0.
GRID,4,,0.5,0.,1.
CONM2,1,1,,2.
CONM2,2,2,,3.
CONM2,3,3,,3.
CONM2,4,4,,5.
ENDDATA
"""


def test_nastran_grdpnt_printout_of_four_point_masses():
    """The f06 of four CONM2 about the basic origin (Nastran's printout, 7 digits)."""
    p = jaxfem.mass_properties(_build(NASTRAN_EXAMPLE))
    m0 = [[13, 0, 0, 0, 5, -3], [0, 13, 0, -5, 0, 7], [0, 0, 13, 3, -7, 0],
          [0, -5, 3, 8, -1.5, -2.5], [5, 0, -7, -1.5, 10, 0], [-3, 7, 0, -2.5, 0, 8]]
    np.testing.assert_allclose(p.m0, m0, atol=1e-12)
    cg = [[0.0, 2.307692e-01, 3.846154e-01], [5.384615e-01, 0.0, 3.846154e-01], [5.384615e-01, 2.307692e-01, 0.0]]
    np.testing.assert_allclose(p.direction_cg, cg, atol=1e-6)
    i_s = [[5.384615, -1.153847e-01, -1.923079e-01], [-1.153847e-01, 4.307692, -1.153846],
           [-1.923079e-01, -1.153846, 3.538461]]
    np.testing.assert_allclose(p.i_s, i_s, atol=2e-6)
    np.testing.assert_allclose(p.principal_inertia, [5.503882, 5.023013, 2.703873], atol=2e-6)
    q = np.array([[8.702303e-01, 4.915230e-01, 3.323378e-02], [3.829170e-01, -7.173043e-01, 5.821075e-01],
                  [3.099580e-01, -4.938418e-01, -8.124324e-01]])
    np.testing.assert_allclose(np.abs(p.q.T @ q), np.eye(3), atol=1e-5)  # columns equal up to sign
    text = p.table()
    assert " 1.300000E+01  0.000000E+00  2.307692E-01  3.846154E-01" in text
    assert "total mass 1.300000E+01" in text
    assert p.to_json()["mass"] == 13.0 and p.to_json()["m0"] == p.m0.tolist()


def test_scalar_mass_source_counts_its_rigid_body_motion():
    """The extension point for scalar masses (CMASS): a mass on one grid component has that
    direction's mass and its moment arm; a mass between two components of one direction,
    moving together in a rigid motion, has none; a grounded end does not move."""
    xyz = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    d = _rigid_rows(jnp.asarray(xyz), jnp.zeros(3))
    m0 = np.asarray(_component_mass(d, np.array([[0]]), np.array([[1]]), jnp.array([[[2.0]]])))
    expected = np.zeros((6, 6))
    row = np.array([1.0, 0.0, 0.0, 0.0, 3.0, -2.0])  # u_x = u0_x + θy z − θz y at (1, 2, 3)
    expected += 2.0 * np.outer(row, row)
    np.testing.assert_allclose(m0, expected, atol=1e-14)
    coupled = jnp.array([[[2.0, -2.0], [-2.0, 2.0]]])
    both = _component_mass(d, np.array([[0, 1]]), np.array([[3, 3]]), coupled)
    assert float(jnp.abs(both[:3, :3]).max()) == 0.0
    grounded = _component_mass(d, np.array([[0, -1]]), np.array([[2, 0]]), coupled)
    assert float(grounded[1, 1]) == 2.0
    # in a CD system turned 90° about z, global component 1 of grid 0 is basic y
    cd = np.array([[[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], np.eye(3)])
    turned = np.asarray(_component_mass(d, np.array([[0]]), np.array([[1]]), jnp.array([[[2.0]]]), cd))
    row = np.array([0.0, 1.0, 0.0, -3.0, 0.0, 1.0])  # u_y = u0_y + θz x − θx z at (1, 2, 3)
    np.testing.assert_allclose(turned, 2.0 * np.outer(row, row), atol=1e-14)


def test_massless_model():
    deck = """BEGIN BULK
GRID,1,,0.,0.,0.
GRID,2,,1.,0.,0.
MAT1,1,7.e10,,0.3
PBAR,1,1,1.e-4,1.e-8,2.e-8,3.e-8
CBAR,1,1,1,2,0.,1.,0.
SPC1,1,123456,1
ENDDATA
"""
    p = jaxfem.mass_properties(_build(deck))
    assert p.mass == 0.0 and p.cg.tolist() == [0.0, 0.0, 0.0]
    assert "total mass 0.000000E+00" in p.table()


SCALAR = """BEGIN BULK
CORD2R,5,,0.,0.,0.,0.,0.,1.
,0.,1.,0.
GRID,1,,0.,0.,0.
GRID,2,,1.,2.,3.,,5
GRID,3,,4.,0.,0.
CMASS2,1,2.,2,1
CMASS2,2,2.,2,2
CMASS2,3,2.,2,3
CMASS2,4,7.,1,1,3,1
CONM1,5,1,,3.,,3.,,
,3.
ENDDATA
"""


def test_scalar_masses_and_conm1_in_the_model():
    """CMASS2 on the three translations of a grid with CD axes (its point mass), one between
    two grids along x (moves with the body: no mass), and a CONM1: 2 + 3 at the right places."""
    bulk = read_bdf_text(SCALAR)
    if {"CMASS2", "CONM1"} & set(bulk.unknown):
        pytest.skip("the model has no scalar masses or CONM1 yet")
    p = jaxfem.mass_properties(_build(SCALAR))
    assert p.mass == pytest.approx(5.0, rel=1e-12)
    np.testing.assert_allclose(p.cg, [0.4, 0.8, 1.2], rtol=1e-12)
    np.testing.assert_allclose(p.direction_mass, 5.0, rtol=1e-12)
