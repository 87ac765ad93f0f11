"""Model builder: the frame fixture in three formats, section formulas, DoF map, validation."""

import re
from pathlib import Path

import jax
import numpy as np
import pytest

from jaxfem._build import build_model
from jaxfem.io import BulkDataError, read_bdf, read_bdf_text

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def models():
    return [build_model(read_bdf(DATA / f"frame_{k}.bdf")) for k in ("free", "small", "large")]


@pytest.fixture(scope="module")
def frame(models):
    return models[0]


def test_three_formats_build_identical_models(models):
    (first, treedef), *others = [jax.tree_util.tree_flatten(m) for m in models]
    for leaves, other_def in others:
        assert other_def == treedef  # static fields (n_dof, lumped) included
        for a, b in zip(first, leaves):
            assert np.asarray(a).dtype == np.asarray(b).dtype
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_grids_in_basic_through_cord2r_chain(frame):
    np.testing.assert_array_equal(frame.node_ids, np.arange(1, 11))
    np.testing.assert_allclose(frame.xyz[4], [1.0, 0.0, 3.0], atol=1e-15)  # CP 10
    np.testing.assert_allclose(frame.xyz[5], [1.0, 1.0, 3.0], atol=1e-15)  # CP 11 (RID 10)


def test_materials_nastran_rule(frame):
    mat = frame.materials
    np.testing.assert_array_equal(mat.ids, [1, 2])
    np.testing.assert_allclose(mat.G, [2.1e11 / 2.6, 2.6e10], rtol=1e-15)
    np.testing.assert_allclose(mat.nu, [0.3, 7.0e10 / 5.2e10 - 1.0], rtol=1e-15)
    np.testing.assert_array_equal(mat.rho, [7850.0, 2700.0])
    assert mat.E.dtype == np.float64


def _rectangles(parts):
    """A, Iy = ∫y² dA, Iz = ∫z² dA of rectangles (width along z, height along y, centre y, z)."""
    a = sum(w * h for w, h, _, _ in parts)
    iy = sum(w * h**3 / 12 + w * h * y**2 for w, h, y, _ in parts)
    iz = sum(h * w**3 / 12 + w * h * z**2 for w, h, _, z in parts)
    return a, iy, iz


def test_beam_sections(frame):
    sec = frame.beam_sections
    np.testing.assert_array_equal(sec.ids, [1, 2, 3, 4, 5])
    np.testing.assert_array_equal(sec.material, [0, 0, 1, 0, 0])
    # PBAR: given values; blank K would be 0, here 0.8 / 0.7
    np.testing.assert_allclose([sec.A[0], sec.I1[0], sec.I2[0], sec.J[0], sec.nsm[0]], [2e-3, 8e-6, 5e-6, 1e-5, 0.5])
    np.testing.assert_allclose([sec.K1[0], sec.K2[0]], [0.8, 0.7])
    # PBARL BOX 0.1 wide (z) x 0.12 high (y), top/bottom walls 0.006, side walls 0.005
    b, h, t3, t4 = 0.1, 0.12, 0.006, 0.005
    walls = [(b, t3, (h - t3) / 2, 0.0), (b, t3, -(h - t3) / 2, 0.0),
             (t4, h - 2 * t3, 0.0, (b - t4) / 2), (t4, h - 2 * t3, 0.0, -(b - t4) / 2)]
    a, iy, iz = _rectangles(walls)
    np.testing.assert_allclose([sec.A[1], sec.I1[1], sec.I2[1]], [a, iy, iz], rtol=1e-12)
    mean_area = (b - t4) * (h - t3)
    bredt = 4 * mean_area**2 / (2 * (b - t4) / t3 + 2 * (h - t3) / t4)
    np.testing.assert_allclose(sec.J[1], bredt, rtol=1e-12)
    np.testing.assert_allclose([sec.K1[1], sec.K2[1]], [2 * t4 * h / a, 2 * t3 * b / a], rtol=1e-12)
    # PBARL TUBE ro 0.03, ri 0.025, NSM 0.2
    ro, ri = 0.03, 0.025
    np.testing.assert_allclose(
        [sec.A[2], sec.I1[2], sec.I2[2], sec.J[2], sec.K1[2], sec.nsm[2]],
        [np.pi * (ro**2 - ri**2), np.pi * (ro**4 - ri**4) / 4, np.pi * (ro**4 - ri**4) / 4,
         np.pi * (ro**4 - ri**4) / 2, 0.5, 0.2], rtol=1e-12,
    )
    # PBEAM: end A values, K1 given, K2 blank -> 1.0
    np.testing.assert_allclose([sec.A[3], sec.I1[3], sec.I2[3], sec.J[3], sec.K1[3], sec.K2[3]],
                               [3e-3, 9e-6, 4e-6, 1.2e-5, 0.85, 1.0])
    # PBARL BAR 0.04 wide (z) x 0.06 high (y): I1 about z is the strong axis
    np.testing.assert_allclose([sec.A[4], sec.I1[4], sec.I2[4]], [0.0024, 0.04 * 0.06**3 / 12, 0.06 * 0.04**3 / 12])
    np.testing.assert_allclose([sec.K1[4], sec.K2[4]], [5 / 6, 5 / 6])
    # Roark's torsion constant against the exact series (Timoshenko & Goodier §109)
    long, short = 0.06, 0.04
    n = np.arange(1, 200, 2)
    series = np.sum(np.tanh(n * np.pi * long / (2 * short)) / n**5)
    exact = long * short**3 / 3 * (1 - 192 / np.pi**5 * short / long * series)
    np.testing.assert_allclose(sec.J[4], exact, rtol=2e-3)


def test_elements(frame):
    beams = frame.beams
    np.testing.assert_array_equal(beams.ids, [101, 102, 103, 104, 201])
    np.testing.assert_array_equal(beams.pids, [1, 2, 3, 5, 4])
    np.testing.assert_array_equal(beams.section, [0, 1, 2, 4, 3])
    np.testing.assert_array_equal(beams.nodes, [[0, 2], [1, 3], [2, 4], [4, 5], [4, 3]])
    np.testing.assert_array_equal(beams.v[1], [-2.0, 0.0, 0.0])  # G0 = 1: x_G0 - x_GA
    np.testing.assert_array_equal(beams.offsets[2], [[0.0, 0.0, 0.05], [0.0, 0.0, 0.05]])
    np.testing.assert_array_equal(beams.k_scale, np.ones(5))
    rods = frame.rods
    np.testing.assert_array_equal(rods.nodes, [[2, 9]])
    np.testing.assert_array_equal(frame.rod_sections.A, [1e-4])
    springs = frame.springs
    np.testing.assert_array_equal(springs.ids, [401, 402, 403])
    np.testing.assert_array_equal(springs.pids, [41, 0, 42])
    np.testing.assert_array_equal(springs.nodes, [[9, 3], [9, -1], [8, -1]])
    np.testing.assert_array_equal(springs.components, [[3, 3], [1, 0], [6, 0]])
    np.testing.assert_array_equal(springs.k, [1e5, 5e4, 2e5])
    masses = frame.masses
    np.testing.assert_array_equal(masses.nodes, [7, 6])
    np.testing.assert_array_equal(masses.offset[0], [0.1, 0.0, 0.05])
    np.testing.assert_array_equal(masses.inertia[0], [[0.1, -0.01, -0.0], [-0.01, 0.2, -0.02], [-0.0, -0.02, 0.3]])
    assert frame.lumped is False  # PARAM COUPMASS 1


def test_bush_axes(frame):
    bushes = frame.bushes
    np.testing.assert_array_equal(bushes.nodes, [[3, 8], [7, 8]])
    np.testing.assert_array_equal(bushes.k[0], [1e6, 2e6, 3e6, 1e4, 2e4, 3e4])
    np.testing.assert_array_equal(bushes.s, [0.3, 0.5])
    axes = np.asarray(bushes.axes[0])
    x = frame.xyz[8] - frame.xyz[3]
    np.testing.assert_allclose(axes @ axes.T, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(axes[0], x / np.linalg.norm(x), rtol=1e-15)
    np.testing.assert_allclose(np.cross(axes[0], axes[1]), axes[2], atol=1e-15)
    assert axes[1] @ [0.0, 0.0, 1.0] > 0.0 and abs(axes[2] @ [0.0, 0.0, 1.0]) < 1e-15  # y in the (x, v) plane
    np.testing.assert_array_equal(bushes.axes[1], np.eye(3))  # coincident grids, no CID


def test_dof_map_labels(frame):
    dofs = frame.dofs
    expected = [(g, c) for g in range(1, 11) for c in range(1, 7)
                if g not in (1, 2, 7) and not (g == 8 and c <= 3) and not (g == 10 and c >= 4)]
    np.testing.assert_array_equal(dofs.labels, expected)
    assert frame.n_dof == 36 and dofs.index.shape == (10, 9)  # grid 8: 6 DoFs of grid 6 and its own rotations
    np.testing.assert_array_equal(dofs.labels[dofs.massless], [(9, c) for c in range(1, 7)])
    assert dofs.auto_spc.shape == (0, 2)
    np.testing.assert_array_equal(dofs.coef[0], 0.0)  # SPC'd grid maps to nothing
    assert np.all(dofs.index[0] == frame.n_dof)


def test_rbe2_slaves_follow_rigid_body_motion(frame):
    dofs = frame.dofs
    u = np.random.default_rng(0).normal(size=frame.n_dof)

    def grid(g):
        row = frame.node_index([g])[0]
        return dofs.coef[row] @ np.append(u, 0.0)[dofs.index[row]]

    u6, u7, u8 = grid(6), grid(7), grid(8)
    x6, x7, x8 = frame.xyz[5], frame.xyz[6], frame.xyz[7]
    np.testing.assert_allclose(u7, np.concatenate([u6[:3] + np.cross(u6[3:], x7 - x6), u6[3:]]), rtol=1e-14)
    # chain RBE2 702 (GN 7, itself dependent): translations of 8 follow 7, rotations are 8's own
    np.testing.assert_allclose(u8[:3], u7[:3] + np.cross(u7[3:], x8 - x7), rtol=1e-14)
    own = [list(map(tuple, dofs.labels)).index((8, c)) for c in (4, 5, 6)]
    np.testing.assert_array_equal(u8[3:], u[own])


BASE = """\
GRID,1,,0.,0.,0.
GRID,2,,1.,0.,0.
GRID,3,,1.,1.,0.
MAT1,1,2.1+11,,0.3,7850.
PBAR,1,1,1.-3,1.-6,1.-6,2.-6
PROD,2,1,1.-4
CBAR,10,1,1,2,0.,0.,1.
CBAR,11,1,2,3,0.,0.,1.
CONM2,20,3,,1.
SPC1,1,123456,1
"""


def _build(text: str, **kwargs):
    return build_model(read_bdf_text(text, name="m.bdf"), **kwargs)


def _fails(text: str, *parts: str, **kwargs) -> None:
    with pytest.raises(BulkDataError, match=".*".join(re.escape(p) for p in parts)):
        _build(text, **kwargs)


@pytest.mark.parametrize(
    "old, new, parts",
    [
        ("CBAR,10,1,1,2,", "CBAR,10,1,1,9,", ("m.bdf:7: CBAR 10 field 5 (GB): grid 9 is not defined",)),
        ("CBAR,10,1,", "CBAR,10,5,", ("m.bdf:7: CBAR 10 field 3 (PID): property 5 is not defined",)),
        ("CBAR,10,1,", "CBAR,10,2,", ("CBAR 10 field 3 (PID): property 2 is a PROD; CBAR needs PBAR or PBARL",)),
        ("PBAR,1,1,", "PBAR,1,7,", ("m.bdf:5: PBAR 1 field 3 (MID): material 7 is not defined",)),
        ("CBAR,10,1,1,2,0.,0.,1.", "CBAR,10,1,1,2,0.,0.,1.\n,,,0.5,0.,0.,-0.5,0.,0.",
         ("m.bdf:7: CBAR 10 field 5 (GB): zero length",)),
        ("CBAR,10,1,1,2,0.,0.,1.", "CBAR,10,1,1,2,2.,0.,0.",
         ("m.bdf:7: CBAR 10 field 6 (X1): orientation vector [2.0, 0.0, 0.0] is zero or parallel",)),
        ("CBAR,10,1,1,2,0.,0.,1.", "CBAR,10,1,1,2,1", ("CBAR 10 field 6 (G0): orientation vector [0.0, 0.0, 0.0]",)),
        ("CBAR,10,1,1,2,0.,0.,1.", "CBAR,10,1,1,2,8", ("CBAR 10 field 6 (G0): grid 8 is not defined",)),
        ("CONM2,20,3,,1.", "CONM2,20,3,,-1.", ("m.bdf:9: CONM2 20 field 5 (M): negative mass -1.0",)),
        ("CONM2,20,3,,1.", "CONM2,20,3,,1.\n,1.,2.,1.", ("m.bdf:10: CONM2 20 field 2 (I11): indefinite mass",)),
        ("CONM2,20,3,", "CONM2,20,4,", ("CONM2 20 field 3 (G): grid 4 is not defined",)),
        ("MAT1,1,2.1+11,", "MAT1,1,-2.1+11,", ("m.bdf:4: MAT1 1 field 3 (E): E must be > 0",)),
        ("MAT1,1,2.1+11,,0.3,7850.", "MAT1,1,,8.+10", ("MAT1 1 field 3 (E): E must be > 0, got 0.0",)),
        ("7850.", "-1.", ("MAT1 1 field 6 (RHO): negative density",)),
        ("PBAR,1,1,1.-3,", "PBAR,1,1,0.,", ("m.bdf:5: PBAR 1 field 4 (A): area must be > 0",)),
        ("PBAR,1,1,1.-3,1.-6,", "PBAR,1,1,1.-3,-1.-6,", ("PBAR 1 field 5 (I1): I1 must be >= 0",)),
        ("PBAR,1,1,1.-3,1.-6,1.-6,2.-6", "PBAR,1,1,1.-3,1.-6,1.-6,2.-6\n,\n,,,2.-6",
         ("m.bdf:7: PBAR 1 field 4 (I12): I1·I2 must exceed I12² (got I1 = 1e-06, I2 = 1e-06, I12 = 2e-06)",)),
        ("PROD,2,1,1.-4", "PROD,2,1,0.", ("PROD 2 field 4 (A): area must be > 0",)),
        ("SPC1,1,123456,1", "SPC1,1,123456,1\nSPC,1,2,3,0.1",
         ("m.bdf:11: SPC 1 field 5 (D): enforced displacement 0.1",)),
        ("SPC1,1,123456,1", "SPC1,1,123456,1,5", ("SPC1 1 field 4 (G): grid 5 is not defined",)),
        ("GRID,3,,", "GRID,3,5,", ("m.bdf:3: GRID 3 field 3 (CP): coordinate system 5 is not defined",)),
        ("SPC1", "RBE2,30,2,123456,9\nSPC1", ("m.bdf:10: RBE2 30 field 5 (GM): grid 9 is not defined",)),
        ("SPC1", "RBE2,30,9,123456,3\nSPC1", ("RBE2 30 field 3 (GN): grid 9 is not defined",)),
        ("SPC1", "RBE2,30,2,123,1\nSPC1",
         ("RBE2 30 field 4 (CM): grid 1 component 1 is both RBE2-dependent and constrained by SPC1 at m.bdf:11",)),
        ("SPC1", "RBE2,30,2,123,3\nRBE2,31,1,23,3\nSPC1",
         ("m.bdf:11: RBE2 31 field 4 (CM): grid 3 component 2 is already dependent on RBE2 30 at m.bdf:10",)),
        ("SPC1", "RBE2,30,2,1,3\nRBE2,31,3,1,2\nSPC1", ("RBE2", "depend on each other in a loop")),
        ("SPC1", "RBE2,30,2,1,2\nSPC1", ("RBE2 30 field 5 (GM): grid 2 is both the independent grid GN",)),
        ("SPC1", "CROD,30,2,1,1\nSPC1", ("m.bdf:10: CROD 30 field 5 (G2): zero length",)),
        ("SPC1", "CELAS1,30,1,1,1\nSPC1", ("CELAS1 30 field 3 (PID): property 1 is a PBAR; CELAS1 needs PELAS",)),
        ("SPC1", "CBUSH,30,31,1,2\nPBUSH,31,K,1.\nSPC1",
         ("CBUSH 30 field 6 (X1): an orientation vector X1, X2, X3, a grid G0 or a CID is required",)),
        ("SPC1", "CBUSH,30,31,1,2,,,,4\nPBUSH,31,K,1.\nSPC1", ("CBUSH 30 field 9 (CID): coordinate system 4",)),
        ("SPC1", "PARAM,COUPMASS,1.\nSPC1", ("PARAM COUPMASS field 3 (V1): COUPMASS must be an integer",)),
        ("SPC1", "CORD2R,5,6,0.,0.,0.,0.,0.,1.\n,1.\nCORD2R,6,5,0.,0.,0.,0.,0.,1.\n,1.\nSPC1",
         ("CORD2R", "field 3 (RID): coordinate systems refer to each other in a loop",)),
        ("SPC1", "CORD2R,5,,0.,0.,0.,0.,0.,1.\n,0.,0.,2.\nSPC1",
         ("m.bdf:10: CORD2R 5 field 4 (A1): points A, B, C do not define axes",)),
    ],
)
def test_validation_errors(old, new, parts):
    assert old in BASE
    _fails(BASE.replace(old, new, 1), *parts)


@pytest.mark.parametrize(
    "section, parts",
    [
        ("PBARL,5,1,,TUBE\n,0.02,0.03", ("m.bdf:12: PBARL 5 field 3 (DIM2): inner radius 0.03",)),
        ("PBARL,5,1,,BOX\n,0.1,0.1,0.06,0.01", ("PBARL 5 field 4 (DIM3): walls too thick",)),
        ("PBARL,5,1,,BAR\n,0.1,-0.1", ("m.bdf:12: PBARL 5 field 3 (DIM2): dimensions must be > 0",)),
        ("PBEAM,5,1,1.-3,1.-6,1.-6,1.-5", ("m.bdf:11: PBEAM 5 field 7 (I12): I1·I2 must exceed I12²",)),
    ],
)
def test_section_errors(section, parts):
    _fails(BASE + section + "\n", *parts)


FRAME = (DATA / "frame_free.bdf").read_text()


def test_spc_set_selection():
    two_sets = FRAME.replace("ENDDATA", "SPC1,2,123,3\nENDDATA")
    _fails(two_sets, "m.bdf:61: SPC1 2 field 2 (SID): several SPC sets [1, 2] (SPC1 1 at m.bdf:59, SPC1 2 at "
                     "m.bdf:61); choose one in the case control (SPC = n) or with spc_set (--spc-set)")  # was not located
    _fails(two_sets, "m.bdf: SPC set 3 (spc_set or case control) is not in the bulk data (sets: [1, 2])", spc_set=3)
    labels = {tuple(x) for x in _build(two_sets, spc_set=2).dofs.labels}
    assert (1, 1) in labels and (3, 1) not in labels and (3, 4) in labels and (10, 4) not in labels


def test_unknown_structural_cards_refused_unless_allowed_and_lumped_default():
    text = FRAME.replace("PARAM,COUPMASS,1\n", "").replace("ENDDATA", "CHEXA,1,1,1,2,3\nENDDATA")
    line = text.splitlines().index("CHEXA,1,1,1,2,3") + 1
    _fails(text, f"m.bdf: unsupported bulk-data cards that may define structure: CHEXA x1 (m.bdf:{line}): "
                 "the model would lack them; build_model(..., allow_unsupported=True) builds it without them")
    expected = f"m.bdf: unsupported bulk-data cards ignored: CHEXA x1 (m.bdf:{line})"
    with pytest.warns(UserWarning, match=re.escape(expected)):
        model = _build(text, allow_unsupported=True)
    assert model.lumped is True  # no PARAM COUPMASS: Nastran default is lumped
    assert _build(FRAME.replace("COUPMASS,1", "COUPMASS,-1")).lumped is True


def test_massless_mechanism_is_refused_with_the_dofs_involved():
    """Grids 4 and 5 carry no mass and are joined only to each other by a spring: their
    stiffness block [[k, −k], [−k, k]] is singular, a mechanism named by its DoFs."""
    text = "\n".join([
        "GRID,1,,0.,0.,0.,,23456",
        "GRID,4,,1.,0.,0.,,23456",
        "GRID,5,,2.,0.,0.,,23456",
        "CONM2,9,1,,1.",
        "CELAS2,10,1.e3,1,1",
        "CELAS2,11,1.e3,4,1,5,1",
    ])
    with pytest.raises(ValueError, match=r"a mechanism.*involved \(node, component\): \[\((4|5), 1\), \((4|5), 1\)"):
        build_model(read_bdf_text(text))
