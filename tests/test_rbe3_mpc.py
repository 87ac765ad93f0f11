"""RBE3 and MPC: parsing, elimination (MSC QRG semantics), hand-calculated models, errors."""

import re
import warnings

import numpy as np
import pytest

import jaxfem
from jaxfem.io import BulkDataError, read_bdf_text


def _build(text: str, **kwargs) -> jaxfem.Model:
    """The models here are constraints and masses without elements: their free masses
    (announced by a warning, tested in test_auto_spc) are not the point."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", ".* carry mass but no stiffness", UserWarning)
        return jaxfem.build_model(read_bdf_text(text, name="m.bdf"), **kwargs)


def _map(model: jaxfem.Model) -> np.ndarray:
    """P (n_node, 6, n_dof): u[node, c] = P[node, c] @ u_solved."""
    d = model.dofs
    p = np.zeros((len(model.node_ids), 6, d.n_dof + 1))
    for node in range(len(model.node_ids)):
        for k in range(d.index.shape[1]):
            p[node, :, d.index[node, k]] += d.coef[node, :, k]
    return p[:, :, :-1]


def _node(model: jaxfem.Model, grid: int) -> int:
    return int(np.flatnonzero(model.node_ids == grid)[0])


def _rigid(model: jaxfem.Model, u0, theta, x0) -> np.ndarray:
    """Solved-DoF vector of the rigid-body motion u(x) = u0 + θ × (x − x0), θ."""
    out = []
    for g, c in model.dofs.labels:
        x = model.xyz[_node(model, g)]
        motion = np.concatenate([u0 + np.cross(theta, x - x0), theta])
        out.append(motion[c - 1])
    return np.array(out)


def _lambdas(model: jaxfem.Model) -> np.ndarray:
    K, M = jaxfem.assemble(model)
    lam, _ = jaxfem.eigh(K, M)
    return np.asarray(lam)


# ---------------------------------------------------------------------------------------
# Parsing


def test_rbe3_qrg_example_fixed_format():
    text = (
        "RBE3    14              100     1234    1.0     123     1       3\n"
        "        5       4.7     1       2       4       6       5.2     2\n"
        "        7       8       9       5.1     1       15      16\n"
        "        ALPHA   6.5-6\n"
    )
    card = read_bdf_text(text)["RBE3"][0]
    assert card.id == 14
    assert (card["REFGRID"], card["REFC"], card["ALPHA"]) == (100, 1234, 6.5e-6)
    assert card["GROUPS"] == ((1.0, 123, (1, 3, 5)), (4.7, 1, (2, 4, 6)), (5.2, 2, (7, 8, 9)), (5.1, 1, (15, 16)))
    assert card.fields["WT3"] == (2, 8) and card.fields["G4,2"] == (3, 8)


def test_mpc_continuation_rows_and_blank_terms():
    card = read_bdf_text("MPC,3,1,2,1.,5,3,-2.\n,,,,,6,1,.5\n,,7,6\n")["MPC"][0]
    assert card.id == 3
    assert card["TERMS"] == ((1, 2, 1.0), (5, 3, -2.0), (6, 1, 0.5), (7, 6, 0.0))
    assert card.fields["G3"] == (2, 6) and card.fields["A4"] == (3, 5)


@pytest.mark.parametrize(
    "text, parts",
    [
        ("RBE3,20,,4,123456,1.,123,1,2\n,3,UM,4,5\n",
         ("m.bdf:2: RBE3 20 field 3 (UM): UM (user-chosen dependent DoFs) is not supported",)),
        ("RBE3,20,,4,123,0.,123,1,2\n", ("m.bdf:1: RBE3 20 field 6 (WT1): weight must be > 0",)),
        ("RBE3,20,,4,123,1,123,1,2\n", ("RBE3 20 field 6 (WT1): expected a real number", "'1'")),
        ("RBE3,20,,4,123,1.,127,1,2\n", ("RBE3 20 field 7 (C1): expected component digits",)),
        ("RBE3,20,,4,123,1.,123,1\n,2.,12\n", ("m.bdf:2: RBE3 20 field 4 (G2,1): a weight group needs at least one grid",)),
        ("RBE3,20,,4,123\n", ("RBE3 20 field 6 (WT1): required field is blank",)),
        ("RBE3,20,5,4,123,1.,123,1\n", ("RBE3 20 field 3: must be blank",)),
        ("RBE3,20,,4,123,1.,123,1,TREF\n", ("RBE3 20 field 9: expected a weight, UM or ALPHA",)),
        ("MPC,1,1,1,0.,2,1,-1.\n", ("m.bdf:1: MPC 1 field 5 (A1): A1 must be nonzero",)),
        ("MPC,1,1,1,,2,1,-1.\n", ("MPC 1 field 5 (A1): A1 must be nonzero",)),
        ("MPC,1,1,7,1.,2,1,-1.\n", ("MPC 1 field 4 (C1): component must be one of 1..6 (a grid) or 0/blank",)),
        ("MPC,1,1,1,1.,2,12,-1.\n", ("MPC 1 field 7 (C2): component must be one of 1..6", "got 12")),
        ("MPC,1,1,1,1.,1,1,2.\n", ("MPC 1 field 6 (G2): grid 1 component 1 is the dependent DoF",)),
        ("MPC,1,1,1,1.,,1,2.\n", ("MPC 1 field 6 (G2): required field is blank",)),
        ("MPC,1,1,1,1.,2,1,-1.,5\n", ("MPC 1 field 9: must be blank",)),
        ("MPC,1,1,1,1.\n3,2,1,-1.\n", ("field 1 is not a card name",)),
        ("MPC,1,1,1,1.\n,3,2,1,-1.\n", ("m.bdf:2: MPC 1 field 2: must be blank",)),
        ("CONM2,20,1,,1.\nCELAS2,20,1.,1,1\n", ("m.bdf:2: CELAS2 20: duplicate element id 20",)),
    ],
)
def test_parse_errors(text, parts):
    with pytest.raises(BulkDataError, match=".*".join(re.escape(p) for p in parts)):
        read_bdf_text(text, name="m.bdf")


# ---------------------------------------------------------------------------------------
# RBE3

SQUARE = """\
GRID,1,,1.,1.,0.
GRID,2,,-1.,1.,0.
GRID,3,,-1.,-1.,0.
GRID,4,,1.,-1.,0.
GRID,5,,0.,0.,0.
RBE3,10,,5,123456,1.,123,1,2
,3,4
CONM2,21,1,,1.
CONM2,22,2,,1.
CONM2,23,3,,1.
CONM2,24,4,,1.
"""


def test_rbe3_square_coefficients():
    model = _build(SQUARE)
    p = _map(model)[_node(model, 5)]
    labels = [tuple(lab) for lab in model.dofs.labels]
    assert sorted(labels) == [(g, c) for g in (1, 2, 3, 4) for c in (1, 2, 3)]  # grid 5 dependent
    column = {lab: k for k, lab in enumerate(labels)}
    xy = {1: (1.0, 1.0), 2: (-1.0, 1.0), 3: (-1.0, -1.0), 4: (1.0, -1.0)}
    expected = np.zeros((6, len(labels)))
    for g, (x, y) in xy.items():
        for c in (1, 2, 3):
            expected[c - 1, column[(g, c)]] = 0.25  # translations: the mean
        # rotations: θx = Σ y_i w_i / Σ y_i², θy = −Σ x_i w_i / Σ x_i², θz = Σ (x_i v_i − y_i u_i) / Σ |r_i|²
        expected[3, column[(g, 3)]] = y / 4.0
        expected[4, column[(g, 3)]] = -x / 4.0
        expected[5, column[(g, 1)]] = -y / 8.0
        expected[5, column[(g, 2)]] = x / 8.0
    np.testing.assert_allclose(p, expected, rtol=1e-14, atol=1e-15)


def test_rbe3_square_reproduces_rigid_motion():
    model = _build(SQUARE)
    u0, theta, x0 = np.array([0.1, -0.2, 0.3]), np.array([1e-3, -2e-3, 3e-3]), np.array([0.3, -0.2, 0.5])
    u = _map(model)[_node(model, 5)] @ _rigid(model, u0, theta, x0)
    np.testing.assert_allclose(u, np.concatenate([u0 + np.cross(theta, -x0), theta]), rtol=1e-13, atol=1e-16)


IRREGULAR = """\
GRID,1,,0.,0.,0.
GRID,2,,2.,.5,-.3
GRID,3,,.4,1.7,.9
GRID,6,,.1,.2,.3
GRID,7,,3.,-1.,2.
GRID,8,,-1.,.5,.25
RBE2,30,1,123456,6
RBE3,40,,7,123456,2.5,123,2,3
,.7,123456,6
RBE3,41,,8,123456,1.,123,1,2
,3,7
"""


def test_rbe3_chains_and_rotations_reproduce_rigid_motion():
    """Unequal weights, rotational components (weight WT·Lc²), an independent grid that is
    RBE2-dependent, and an RBE3 whose independent grid is another RBE3's reference."""
    masses = "".join(f"CONM2,{100 + g},{g},,1.\n,1.,,1.,,,1.\n" for g in (1, 2, 3))
    model = _build(IRREGULAR + masses)
    assert {tuple(lab) for lab in model.dofs.labels} == {(g, c) for g in (1, 2, 3) for c in range(1, 7)}
    u0, theta, x0 = np.array([0.1, -0.2, 0.3]), np.array([0.01, -0.02, 0.03]), np.array([0.3, -0.2, 0.5])
    u = _map(model) @ _rigid(model, u0, theta, x0)
    expected = np.concatenate([u0 + np.cross(theta, model.xyz - x0), np.tile(theta, (len(u), 1))], axis=1)
    np.testing.assert_allclose(u, expected, rtol=1e-12, atol=1e-15)


def test_rbe3_weighted_mean_with_unequal_weights():
    """Translations only, grids symmetric about the reference: u_ref = Σ w_i u_i / Σ w_i."""
    text = SQUARE.replace("RBE3,10,,5,123456,1.,123,1,2\n,3,4", "RBE3,10,,5,123,1.,123,1,3\n,3.,123,2,4")
    model = _build(text)
    column = {tuple(lab): k for k, lab in enumerate(model.dofs.labels)}
    p = _map(model)[_node(model, 5)]
    for g, w in ((1, 0.125), (3, 0.125), (2, 0.375), (4, 0.375)):
        assert p[0, column[(g, 1)]] == pytest.approx(w, rel=1e-14)
        assert p[2, column[(g, 3)]] == pytest.approx(w, rel=1e-14)
    # REFC 123: the rotations of grid 5 are its own DoFs, without mass or stiffness (auto-SPC)
    assert {(5, c) for c in (4, 5, 6)} <= {tuple(lab) for lab in model.dofs.auto_spc}



def test_rbe3_rotational_weight_uses_mean_distance():
    """Grids at x = 1 and x = −3 (Lc = mean |r_i| = 2, rotational weight Lc² = 4), all six
    components, reference at the origin; θz of grid 1 alone. The y–θz least squares by
    hand: min (u + θ)² + (u − 3θ)² + 4(θ − 1)² + 4θ² gives u = θ = 1/4."""
    text = (
        "GRID,1,,1.,0.,0.\nGRID,2,,-3.,0.,0.\nGRID,5,,0.,0.,0.\nRBE3,10,,5,123456,1.,123456,1,2\n"
        + "".join(f"CONM2,{20 + g},{g},,1.\n,1.,,1.,,,1.\n" for g in (1, 2))
    )
    model = _build(text)
    column = {tuple(lab): k for k, lab in enumerate(model.dofs.labels)}
    p = _map(model)[_node(model, 5)]
    assert p[5, column[(1, 6)]] == pytest.approx(0.25, rel=1e-14)  # θz
    assert p[1, column[(1, 6)]] == pytest.approx(0.25, rel=1e-14)  # u_y
    assert p[5, column[(2, 6)]] == pytest.approx(0.25, rel=1e-14)  # symmetric in the rotations


TETRA = """\
GRID,1,,0.,0.,0.
GRID,2,,1.,0.,0.
GRID,3,,0.,1.,0.
GRID,4,,0.,0.,1.
GRID,5,,.3,.2,.1
MAT1,1,2.1+11,,.3,0.
PROD,1,1,1.-4
CROD,11,1,1,2
CROD,12,1,1,3
CROD,13,1,1,4
CROD,14,1,2,3
CROD,15,1,2,4
CROD,16,1,3,4
CONM2,21,1,,.5
CONM2,22,2,,.5
CONM2,23,3,,.5
CONM2,24,4,,.5
CONM2,25,5,,10.
,2.,,3.,,,4.
RBE3,30,,5,123456,1.,123,1,2
,3,4
"""


def _rigid_mass(points) -> np.ndarray:
    """6 × 6 rigid-body mass about the origin of point masses (m, x, J about x)."""
    out = np.zeros((6, 6))
    for m, x, j in points:
        h = np.hstack([np.eye(3), -np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])])
        out += m * h.T @ h
        out[3:, 3:] += j
    return out


def test_mass_on_rbe3_of_free_truss():
    """A CONM2 on the reference of a free truss: six zero-frequency modes, and the rigid-body
    mass of the model is that of all the masses by hand (the RBE3 carries the reference
    grid rigidly with the truss)."""
    model = _build(TETRA)
    assert model.dofs.n_dof == 12
    lam = _lambdas(model)
    assert np.all(np.abs(lam[:6]) < 1e-8 * lam[6])
    assert lam[6] > 1e6
    r = np.stack([_rigid(model, *e, np.zeros(3)) for e in (
        *((np.eye(3)[i], np.zeros(3)) for i in range(3)), *((np.zeros(3), np.eye(3)[i]) for i in range(3)))], axis=1)
    _, M = jaxfem.assemble(model)
    corners = [(0.5, model.xyz[i], np.zeros((3, 3))) for i in range(4)]
    expected = _rigid_mass(corners + [(10.0, np.array([0.3, 0.2, 0.1]), np.diag([2.0, 3.0, 4.0]))])
    np.testing.assert_allclose(r.T @ np.asarray(M.todense()) @ r, expected, rtol=1e-13, atol=1e-13)


HUNG = """\
GRID,1,,.5,.5,0.
GRID,2,,-.5,.5,0.
GRID,3,,-.5,-.5,0.
GRID,4,,.5,-.5,0.
GRID,5,,0.,0.,0.
SPC1,1,12,1,THRU,4
CELAS2,11,1000.,1,3
CELAS2,12,1000.,2,3
CELAS2,13,1000.,3,3
CELAS2,14,1000.,4,3
CONM2,21,1,,.1
CONM2,22,2,,.1
CONM2,23,3,,.1
CONM2,24,4,,.1
CONM2,25,5,,10.
,2.,,3.,,,1.
RBE3,30,,5,123456,1.,123,1,2
,3,4
"""


def test_mass_hung_on_rbe3_over_springs():
    """Four corners (half side a = 0.5) on springs k = 1000 in z, corner masses m0 = 0.1,
    a mass m = 10 (Ixx = 2, Iyy = 3) on the RBE3 at the centre. By hand:
    bounce ω² = 4k/(m + 4m0), pitch ω² = 4ka²/(Ixx + 4m0a²), roll 4ka²/(Iyy + 4m0a²),
    saddle (no motion of the reference) ω² = k/m0."""
    model = _build(HUNG)
    k, m0, m, a = 1000.0, 0.1, 10.0, 0.5
    expected = sorted([4 * k / (m + 4 * m0), 4 * k * a**2 / (2.0 + 4 * m0 * a**2),
                       4 * k * a**2 / (3.0 + 4 * m0 * a**2), k / m0])
    np.testing.assert_allclose(_lambdas(model), expected, rtol=1e-12)
    # static: a force F_z and a moment M_x at the reference, spread by the RBE3
    K, _ = jaxfem.assemble(model)
    p = _map(model)[_node(model, 5)]
    f = p.T @ np.array([0.0, 0.0, 50.0, 20.0, 0.0, 0.0])
    u = p @ np.linalg.solve(np.asarray(K.todense()), f)
    np.testing.assert_allclose(u, [0.0, 0.0, 50.0 / (4 * k), 20.0 / (4 * k * a**2), 0.0, 0.0], rtol=1e-12, atol=1e-18)


# ---------------------------------------------------------------------------------------
# MPC

SERIES = """\
GRID,1,,0.,0.,0.,,23456
GRID,2,,0.,0.,0.,,23456
GRID,3,,1.,0.,0.,,23456
CELAS2,11,3000.,1,1
CELAS2,12,2000.,2,1,3,1
CONM2,21,1,,1.
CONM2,22,2,,.5
CONM2,23,3,,2.
MPC,7,2,1,1.,1,1,-1.
"""


def test_mpc_tie_equals_merged_grid():
    tied = _build(SERIES)
    merged = _build(
        SERIES.replace("CELAS2,12,2000.,2,1,3,1", "CELAS2,12,2000.,1,1,3,1")
        .replace("CONM2,22,2,", "CONM2,22,1,")
        .replace("MPC,7,2,1,1.,1,1,-1.\n", "")
    )
    k1, k2, m1, m3 = 3000.0, 2000.0, 1.5, 2.0
    by_hand = np.sort(np.linalg.eigvals(np.linalg.solve(np.diag([m1, m3]), [[k1 + k2, -k2], [-k2, k2]])).real)
    np.testing.assert_allclose(_lambdas(tied), by_hand, rtol=1e-12)
    np.testing.assert_allclose(_lambdas(merged), by_hand, rtol=1e-12)
    assert tied.dofs.n_dof == 2 and [tuple(x) for x in tied.dofs.labels] == [(1, 1), (3, 1)]


LEVER = """\
GRID,1,,0.,0.,0.,,23456
GRID,2,,1.,0.,0.,,23456
CELAS2,11,400.,2,1
CELAS2,12,100.,1,1
CONM2,21,1,,2.
MPC,1,1,1,3.,2,1,-6.
"""


def test_mpc_lever():
    """3 u1 − 6 u2 = 0: u1 = 2 u2; the mass m on grid 1, springs k2 on grid 2 and k1 on
    grid 1: ω² = (k2 + 4 k1) / (4 m)."""
    model = _build(LEVER)
    assert [tuple(x) for x in model.dofs.labels] == [(2, 1)]
    assert _map(model)[_node(model, 1), 0, 0] == 2.0
    np.testing.assert_allclose(_lambdas(model), [(400.0 + 4 * 100.0) / (4 * 2.0)], rtol=1e-14)


def test_mpc_chain_through_rbe2_and_set_choice():
    """u1 = 2 u3 with grid 3 an RBE2 slave of grid 2 (same x): u1 = 2 u2; set 8 is ignored
    when set 1 is chosen."""
    text = LEVER.replace("MPC,1,1,1,3.,2,1,-6.", "GRID,3,,1.,0.,0.,,23456\nRBE2,30,2,1,3\nMPC,1,1,1,1.,3,1,-2.\n"
                         "MPC,8,2,1,1.,1,1,-1.")
    model = _build(text, mpc_set=1)
    assert [tuple(x) for x in model.dofs.labels] == [(2, 1)]
    assert _map(model)[_node(model, 1), 0, 0] == 2.0
    other = _build(text, mpc_set=8)  # u2 = u1: grid 3 follows; grid 1 solved
    assert [tuple(x) for x in other.dofs.labels] == [(1, 1)]
    np.testing.assert_allclose(_map(other)[:, 0, 0], [1.0, 1.0, 1.0])
    np.testing.assert_allclose(_lambdas(other), [500.0 / 2.0], rtol=1e-14)


# ---------------------------------------------------------------------------------------
# Build errors

BASE = """\
GRID,1,,0.,0.,0.
GRID,2,,1.,0.,0.
GRID,3,,0.,1.,0.
GRID,4,,1.,1.,0.
CONM2,11,1,,1.
CONM2,12,2,,1.
CONM2,13,3,,1.
CONM2,14,4,,1.
"""


@pytest.mark.parametrize(
    "cards, parts, kwargs",
    [
        ("RBE3,20,,4,123,1.,123,1\n",
         ("m.bdf:9: RBE3 20 field 6 (GROUPS): the independent DoFs do not determine the rigid-body motion of "
          "REFGRID 4", "add translations (123) of independent grids that are not all on one line"), {}),
        ("RBE3,20,,4,123,1.,123,1,2\n",
         ("m.bdf:9: RBE3 20 field 6 (GROUPS):", "undetermined: rotation about [1, 0, 0] through (1, 0, 0)"), {}),
        ("RBE3,20,,1,123,1.,456,2,3\n", ("RBE3 20 field 6 (GROUPS):", "undetermined: translation along"), {}),
        ("RBE3,20,,4,123,1.,123,1,2\n,4\n",
         ("m.bdf:10: RBE3 20 field 2 (G1,3): grid 4 is the reference grid REFGRID",), {}),
        ("RBE3,20,,4,123,1.,123,1,\n,9\n", ("m.bdf:10: RBE3 20 field 2 (G1,2): grid 9 is not defined",), {}),
        ("RBE3,20,,9,123,1.,123,1,2\n,3\n", ("m.bdf:9: RBE3 20 field 4 (REFGRID): grid 9 is not defined",), {}),
        ("SPC1,1,1,4\nRBE3,20,,4,123,1.,123,1,2\n,3\n",
         ("m.bdf:10: RBE3 20 field 5 (REFC): grid 4 component 1 is both RBE3-dependent and constrained by "
          "SPC1 at m.bdf:9",), {}),
        ("RBE2,30,1,1,4\nRBE3,20,,4,123,1.,123,1,2\n,3\n",
         ("m.bdf:10: RBE3 20 field 5 (REFC): grid 4 component 1 is already dependent on RBE2 30 at m.bdf:9",), {}),
        ("RBE2,30,1,1,2\nMPC,1,2,1,1.,3,1,-1.\n",
         ("m.bdf:10: MPC 1 field 3 (G1): grid 2 component 1 is already dependent on RBE2 30 at m.bdf:9",), {}),
        ("MPC,1,2,1,1.,3,1,-1.\nMPC,1,2,1,1.,4,1,-1.\n",
         ("m.bdf:10: MPC 1 field 3 (G1): grid 2 component 1 is already dependent on MPC 1 at m.bdf:9",), {}),
        ("MPC,1,1,1,1.,9,1,-1.\n", ("m.bdf:9: MPC 1 field 6 (G2): grid 9 is not defined",), {}),
        ("MPC,1,1,1,1.,2,1,-1.\nMPC,1,2,1,1.,1,1,-1.\n",
         ("m.bdf:9: MPC 1 field 6 (G2): rigid elements/MPCs depend on each other in a loop: MPC 1 at m.bdf:9 "
          "(grid 1 component 1) -> MPC 1 at m.bdf:10 (grid 2 component 1) -> MPC 1 at m.bdf:9",), {}),
        ("RBE2,30,1,1,2\nMPC,1,1,1,1.,2,1,-1.\n",
         ("m.bdf:10: MPC 1 field 6 (G2): rigid elements/MPCs depend on each other in a loop: MPC 1 at "
          "m.bdf:10 (grid 1 component 1) -> RBE2 30 at m.bdf:9 (grid 2 component 1) -> MPC 1",), {}),
        ("RBE3,20,,4,123,1.,123,1,2\n,3\nMPC,1,1,3,1.,4,3,-1.\n",
         ("m.bdf:11: MPC 1 field 6 (G2): rigid elements/MPCs depend on each other in a loop", "RBE3 20 at m.bdf:9"),
         {}),
        ("MPC,1,1,1,1.,2,1,-1.\nMPC,2,3,1,1.,4,1,-1.\n",
         ("m.bdf:10: MPC 2 field 2 (SID): several MPC sets [1, 2] (MPC 1 at m.bdf:9, MPC 2 at m.bdf:10); "
          "choose one in the case control (MPC = n) or with mpc_set (--mpc-set)",), {}),
        ("MPC,1,1,1,1.,2,1,-1.\n", ("m.bdf: MPC set 3 (mpc_set or case control) is not in the bulk data (sets: [1])",),
         {"mpc_set": 3}),
        ("", ("m.bdf: MPC set 1 (mpc_set or case control) is not in the bulk data (sets: [])",), {"mpc_set": 1}),
        ("MPC,1,1,0,1.,2,1,-1.\n", ("m.bdf:9: MPC 1 field 4 (C1): grid 1 needs a component 1..6 (0 or blank is for "
                                    "scalar points), got 0",), {}),
    ],
)
def test_build_errors(cards, parts, kwargs):
    with pytest.raises(BulkDataError, match=".*".join(re.escape(p) for p in parts)):
        _build(BASE + cards, **kwargs)


def test_two_mpc_sets_build_with_a_choice():
    text = BASE + "MPC,1,1,1,1.,2,1,-1.\nMPC,2,3,1,1.,4,1,-1.\n"
    labels = {tuple(x) for x in _build(text, mpc_set=2).dofs.labels}
    assert (1, 1) in labels and (3, 1) not in labels
