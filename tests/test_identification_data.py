"""Measured-data containers and the sensor observation matrix."""

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from identification import FRFData, ModalData, Sensors, observation_matrix

# -- Sensors ---------------------------------------------------------------------------


def test_sensors_from_components():
    s = Sensors.from_components([101, 101, 102, 103], [3, -1, 6, -5])
    assert s.labels == ["101+Z", "101-X", "102+RZ", "103-RY"]
    np.testing.assert_array_equal(s.directions, [[0, 0, 1], [-1, 0, 0], [0, 0, 1], [0, -1, 0]])
    np.testing.assert_array_equal(s.rotational, [False, False, True, True])
    np.testing.assert_array_equal(s.codes, [3, -1, 6, -5])
    assert len(s) == 4


def test_sensors_from_vectors_normalises_and_labels_skew():
    s = Sensors.from_vectors([7, 8], [[0.0, 2.0, 2.0], [0.0, 0.0, -3.0]], rotational=[False, True])
    np.testing.assert_allclose(s.directions, [[0, 2**-0.5, 2**-0.5], [0, 0, -1]], rtol=1e-15)
    assert s.labels == ["7:(0.00,0.71,0.71)", "8-RZ"]
    np.testing.assert_array_equal(s.codes, [0, -6])


@pytest.mark.parametrize(
    "make, message",
    [
        (
            lambda: Sensors.from_vectors([7, 8], [[1, 0, 0], [0, 0, 0]]),
            "sensor 1 at grid 8: direction [0.0, 0.0, 0.0] has no length",
        ),
        (lambda: Sensors.from_components([5, 6], [3, 7]), "sensor 1 at grid 6: direction code 7 is not ±1..6"),
        (lambda: Sensors.from_components([5], [0]), "sensor 0 at grid 5: direction code 0"),
        (lambda: Sensors([5], [[0.0, 0.0, 2.0]]), "sensor 0 at grid 5: direction [0.0, 0.0, 2.0] is not a unit vector"),
        (
            lambda: Sensors.from_components([101, 102, 101], [3, 3, -3]),
            "sensors 0 (101+Z) and 2 (101-Z) measure the same DoF",
        ),
        (
            lambda: Sensors.from_vectors([4, 4], [[0, 1, 1], [0, -2, -2]]),
            "sensors 0 (4:(0.00,0.71,0.71)) and 1 (4:(0.00,-0.71,-0.71)) measure the same DoF",
        ),
    ],
)
def test_sensor_errors_name_the_sensor(make, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        make()


def test_translation_and_rotation_about_one_axis_are_different_dofs():
    s = Sensors.from_components([1, 1], [3, 6])
    assert s.labels == ["1+Z", "1+RZ"]


# -- ModalData -------------------------------------------------------------------------


@pytest.fixture
def sensors():
    return Sensors.from_components([101, 101, 102], [1, 3, 3])


def test_modal_data_defaults_and_select(sensors):
    shapes = np.arange(1.0, 10.0).reshape(3, 3)
    data = ModalData([10.0, 20.0, 30.0], shapes, sensors, mode_ids=[4, 5, 6])
    np.testing.assert_array_equal(data.damping_ratios, 0.0)  # unknown damping is 0
    assert data.generalised_masses is None and data.n_modes == 3
    sub = data.select([2, 0])
    np.testing.assert_array_equal(sub.mode_ids, [6, 4])
    np.testing.assert_array_equal(sub.frequencies_hz, [30.0, 10.0])
    np.testing.assert_array_equal(sub.shapes, shapes[:, [2, 0]])
    with pytest.raises(ValueError, match=r"mode indices \[3\] out of range for 3 modes"):
        data.select([3])


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(shapes=np.ones((2, 2))), "shapes has shape (2, 2), expected (3, 2)"),
        (dict(frequencies_hz=[10.0, -1.0]), "mode 8: frequency -1.0 Hz is not finite and positive"),
        (dict(frequencies_hz=[np.inf, 1.0]), "mode 7: frequency inf Hz"),
        (dict(damping_ratios=[0.01, 1.5]), "mode 8: damping ratio 1.5 is not in [0, 1)"),
        (dict(generalised_masses=[1.0, 0.0]), "mode 8: generalised mass 0.0 kg"),
        (dict(shapes=np.array([[1.0, 1.0], [np.nan, 1.0], [1.0, 1.0]])), "mode 7: shape value nan at sensor 101+Z"),
        (dict(shapes=np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0]])), "mode 8: the shape is zero at every sensor"),
        (dict(mode_ids=[3, 3]), "mode ids [3] appear more than once"),
    ],
)
def test_modal_data_validation_names_the_mode(sensors, change, message):
    args = dict(frequencies_hz=[10.0, 20.0], shapes=np.ones((3, 2)), mode_ids=[7, 8]) | change
    with pytest.raises(ValueError, match=re.escape(message)):
        ModalData(args.pop("frequencies_hz"), args.pop("shapes"), sensors, **args)


def test_real_recovers_a_rotated_real_mode(sensors):
    phi = np.array([[0.3, 1.0], [-1.0, 0.2], [0.5, -0.7]])
    psi = phi * np.exp(1j * np.array([0.7, -2.9]))  # complex only through a common phase
    real = ModalData([1.0, 2.0], psi, sensors).real()
    assert real.shapes.dtype == np.float64
    expected = phi * np.sign(phi[np.argmax(np.abs(phi), axis=0), [0, 1]])  # largest component positive
    np.testing.assert_allclose(real.shapes, expected, atol=1e-14)


def test_real_is_the_least_squares_best_real_approximation(sensors):
    rng = np.random.default_rng(1)
    psi = rng.normal(size=(3, 1)) + 1j * rng.normal(size=(3, 1))
    phi = ModalData([1.0], psi, sensors).real().shapes[:, 0]
    theta = np.linspace(0.0, np.pi, 20001)
    best = np.max(np.sum(np.real(psi * np.exp(1j * theta)) ** 2, axis=0))  # ‖Re(e^{iθ}ψ)‖² on a grid
    assert np.sum(phi**2) >= best - 1e-12
    data = ModalData([1.0], phi[:, None], sensors)
    assert data.real() is data


def test_modal_data_accepts_traced_values(sensors):
    def build(f):
        return ModalData(f, jnp.ones((3, 2)), sensors).frequencies_hz * 2.0

    np.testing.assert_array_equal(jax.jit(build)(jnp.array([1.0, 2.0])), [2.0, 4.0])


# -- FRFData ---------------------------------------------------------------------------


def _frf(**change):
    args = dict(
        frequencies_hz=[1.0, 2.0, 3.0],
        values=np.ones((3, 2, 1), dtype=complex),
        outputs=Sensors.from_components([101, 102], [3, -3]),
        inputs=Sensors.from_components([1], [3]),
        kind="accelerance",
    ) | change
    return FRFData(**args)


def test_frf_data_holds_complex_values():
    frf = _frf(values=np.ones((3, 2, 1)), coherence=np.full((3, 2, 1), 0.9))
    assert frf.values.dtype == np.complex128 and frf.coherence.shape == (3, 2, 1)


@pytest.mark.parametrize(
    "change, message",
    [
        (dict(kind="inertance"), "FRF kind 'inertance' is not one of"),
        (dict(values=np.ones((3, 1, 1))), "values has shape (3, 1, 1), expected (3, 2, 1)"),
        (dict(frequencies_hz=[1.0, 3.0, 2.0]), "not strictly increasing: line 2 (2.0 Hz) after 3.0 Hz"),
        (dict(frequencies_hz=[1.0, 1.0, 2.0]), "line 1 (1.0 Hz) after 1.0 Hz"),
        (
            dict(values=np.where(np.arange(6).reshape(3, 2, 1) == 3, np.nan, 1.0)),
            "FRF 102-Z / 1+Z: value (nan+0j) at 2.0 Hz",
        ),
        (dict(coherence=np.full((3, 2, 1), 1.5)), "FRF 101+Z / 1+Z: coherence 1.5 at 1.0 Hz"),
    ],
)
def test_frf_data_validation_names_the_item(change, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        _frf(**change)


# -- observation_matrix ----------------------------------------------------------------

# Grid 1 carries a mass (all 6 DoFs free), grid 2 is an RBE2 slave of grid 1, grid 3 is
# clamped, grid 4 is free but has neither mass nor stiffness (auto-SPC removes it).
BDF = """\
GRID,1,,0.,0.,0.
GRID,2,,1.,2.,0.5
GRID,3,,2.,0.,0.
GRID,4,,3.,0.,0.
CONM2,10,1,,2.
,1.,,1.,,,1.
RBE2,20,1,123456,2
SPC1,1,123456,3
"""
XYZ = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 0.5], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]])


def _skew(r):
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


@pytest.fixture(scope="module")
def model():
    with pytest.warns(UserWarning, match=r"6 DoF\(s\), \(node, component\) \(1, 1\), .* carry mass but no stiffness"):
        return jaxfem.build_model(jaxfem.io.read_bdf_text(BDF))  # no elements: the mass moves freely


def _grid1_rows(model):
    """C rows (6, n_dof) reading the six DoFs of grid 1, the independent grid."""
    return observation_matrix(model, Sensors.from_components([1] * 6, range(1, 7)))[0]


def test_skew_sensor_reads_the_projection_of_the_translations(model):
    d = np.array([0.0, 3.0, 4.0]) / 5.0
    C, report = observation_matrix(model, Sensors.from_vectors([1], [d]))
    np.testing.assert_allclose(C[0], d @ _grid1_rows(model)[:3], atol=1e-15)
    assert report == [{"sensor": "1:(0.00,0.60,0.80)", "grid": 1, "distance": 0.0}]


def test_negative_direction_flips_the_sign(model):
    up, _ = observation_matrix(model, Sensors.from_components([1], [3]))
    down, _ = observation_matrix(model, Sensors.from_components([1], [-3]))
    np.testing.assert_array_equal(down, -up)


def test_rbe2_slave_reads_the_rigid_body_motion(model):
    u1 = _grid1_rows(model)  # grid-1 DoFs as rows over the solved DoFs
    rigid = np.eye(6)
    rigid[:3, 3:] = -_skew(XYZ[1] - XYZ[0])  # u₂ = u₁ + θ₁ × (x₂ − x₁), θ₂ = θ₁
    d = np.array([1.0, -1.0, 2.0]) / np.sqrt(6.0)
    sensors = Sensors.from_vectors([2, 2, 2], [[0, 1, 0], [0, 0, 1], d], rotational=[False, False, True])
    C, _ = observation_matrix(model, sensors)
    np.testing.assert_allclose(C[:2], rigid[1:3] @ u1, atol=1e-14)
    np.testing.assert_allclose(C[2], d @ rigid[3:] @ u1, atol=1e-14)


def test_constrained_sensor_is_refused(model):
    for grid in (3, 4):  # SPC and auto-SPC
        with pytest.raises(ValueError, match=re.escape(f"sensor {grid}+Z reads grid {grid} where every")):
            observation_matrix(model, Sensors.from_components([1, grid], [1, 3]))


def test_unknown_sensor_nodes_are_listed(model):
    with pytest.raises(ValueError, match=re.escape("sensor grid(s) [7, 9] not in the model")):
        observation_matrix(model, Sensors.from_components([9, 1, 7], [3, 3, 3]))


def test_nearest_grid_mapping_reports_distances(model):
    sensors = Sensors.from_components([501, 502], [3, 2])
    xyz = XYZ[[1, 0]] + [[0.0, 0.0, 2e-3], [0.0, 0.0, 0.0]]
    with pytest.warns(UserWarning, match=re.escape("501+Z → grid 2 (0.002 m)")):
        C, report = observation_matrix(model, sensors, nearest=True, sensor_xyz=xyz)
    expected, _ = observation_matrix(model, Sensors.from_components([2, 1], [3, 2]))
    np.testing.assert_array_equal(C, expected)
    assert [r["grid"] for r in report] == [2, 1]
    np.testing.assert_allclose([r["distance"] for r in report], [2e-3, 0.0], atol=1e-15)
    observation_matrix(model, sensors, nearest=True, sensor_xyz=xyz, tol=1e-2)  # within tol: no warning
    with pytest.raises(ValueError, match="nearest=True needs sensor_xyz"):
        observation_matrix(model, sensors, nearest=True)


def test_sensors_read_csv(tmp_path):
    good = tmp_path / "s.csv"
    good.write_text("label,node,component\nA,12,3\nB,14,-2\n")
    s = Sensors.read_csv(good)
    assert list(s.nodes) == [12, 14] and s.directions[1].tolist() == [0.0, -1.0, 0.0]
    bad = tmp_path / "bad.csv"
    bad.write_text("label,node,component\nA,12,3\nB,1x,2\n")
    with pytest.raises(ValueError, match=r"bad\.csv, line 3"):
        Sensors.read_csv(bad)
    (tmp_path / "cols.csv").write_text("label,grid\nA,1\n")
    with pytest.raises(ValueError, match=r"cols\.csv, line 1: missing column\(s\) \['node', 'component'\]"):
        Sensors.read_csv(tmp_path / "cols.csv")
    for text, message in [
        ("label,node,component\nA,\u0661,3\n", "line 2: field 'node': '\u0661' is not a node id (integer)"),
        ("label,node,component\nA,123456789012345678901,3\n", "line 2: field 'node': 123456789012345678901 is "
                                                               "outside 1..2,147,483,647"),  # was an OverflowError
        ("label,node,component\nA,0,3\n", "line 2: field 'node': 0 is outside 1..2,147,483,647"),
        ("label,node,component\nA,1,7\n", "line 2: field 'component': 7 is not a direction code ±1..6"),
        ("label,node,component\nA,1,3\nB,1,-3\n", "line 3: node 1 component 3 repeats line 2"),
        ("label,node,component\nA,1,3,9\n", "line 2: more fields than the header's 3"),  # was ignored
        ("label,node,component\nA,1\n", "line 2: field 'component' is empty"),
    ]:
        bad.write_text(text)
        with pytest.raises(ValueError) as err:
            Sensors.read_csv(bad)
        assert str(err.value) == f"{bad}, {message}"
    bad.write_bytes(b"label,node,component\ncaf\xe9,1,3\n")
    with pytest.raises(ValueError, match=r"bad\.csv, line 2: byte 0xe9 is not UTF-8 \(save the sensor list as UTF-8\)"):
        Sensors.read_csv(bad)
