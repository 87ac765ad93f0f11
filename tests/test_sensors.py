"""Sensors given by coordinates (jaxfem.locate_sensors): nearest grid and interpolation on shells."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.shell_models import plate
from identification import Sensors, observation_matrix
from jaxfem.io import read_bdf_text

PROPS = "PSHELL,1,1,0.01,1,,1\nMAT1,1,70.E9,,0.3,2700."
A, B = 1.0, 0.8


def _model(text: str) -> jaxfem.Model:
    return jaxfem.build_model(read_bdf_text(text))


@pytest.fixture(scope="module")
def free_quads():
    return _model(plate(A, B, 4, 4, PROPS, bc="free"))


@pytest.fixture(scope="module")
def distorted_trias():
    return _model(plate(A, B, 4, 4, PROPS, bc="free", triangles=True, distort=0.3, seed=1))


@pytest.fixture(scope="module")
def distorted_quads():
    return _model(plate(A, B, 4, 4, PROPS, bc="free", distort=0.3, seed=2))


def _field(model, f) -> np.ndarray:
    """A shape over the solved DoFs: component c of grid g takes f(x, y, z)[c − 1]."""
    rows = model.node_index(model.dofs.labels[:, 0])
    values = np.array([f(*model.xyz[r]) for r in rows])  # (n_dof, 6)
    return values[np.arange(model.n_dof), model.dofs.labels[:, 1] - 1]


def _unit(model, grid, component) -> np.ndarray:
    hit = (model.dofs.labels[:, 0] == grid) & (model.dofs.labels[:, 1] == component)
    return hit.astype(np.float64)


@pytest.mark.parametrize("method", ["nearest", "interpolate"])
def test_sensor_at_a_grid_reads_that_grid(free_quads, method):
    m = free_quads
    grid = 13  # interior, at (0.5, 0.4): corner of four quads
    xyz = np.repeat(m.xyz[m.node_index([grid])], 7, axis=0)
    dirs = [1, 2, 3, 4, 5, 6, [0.6, 0.0, -0.8]]
    sm = jaxfem.locate_sensors(m, xyz, dirs, method)
    C = sm.matrix
    for c in range(6):
        np.testing.assert_allclose(C[c], _unit(m, grid, c + 1), atol=1e-14)
    np.testing.assert_allclose(C[6], 0.6 * _unit(m, grid, 1) - 0.8 * _unit(m, grid, 3), atol=1e-14)
    np.testing.assert_array_equal(sm.grids[:, 0], grid)
    np.testing.assert_allclose(sm.distance, 0.0, atol=1e-15)
    if method == "interpolate":
        assert sm.elements.tolist() == [6] * 7  # lowest id of the four quads at the grid
        assert sm.element_types[0] == "CQUAD4"


def test_nearest_agrees_with_the_observation_matrix_of_grid_sensors():
    """Constrained and RBE2-dependent grids: the same rows as identification's C by grid id."""
    text = plate(A, B, 4, 4, PROPS, bc="ss") + "GRID,100,,0.5,0.4,0.1\nRBE2,200,13,123456,100\n"
    m = _model(text)
    grids = [100, 100, 100, 13, 7, 2]
    codes = [1, 2, 3, 3, 5, 3]
    keep = [0, 1, 2, 3, 4]  # grid 2 is on the support: observation_matrix refuses its zero row
    C_id, _ = observation_matrix(m, Sensors.from_components([grids[i] for i in keep], [codes[i] for i in keep]))
    sm = jaxfem.locate_sensors(m, m.xyz[m.node_index(grids)], codes, "nearest")
    np.testing.assert_allclose(sm.matrix[keep], C_id, atol=1e-15)
    assert not sm.matrix[5].any()  # w held on the support: the sensor reads zero
    assert sm.matrix[0].any()  # u of grid 100 = 0.1·θy of grid 13 (u of grid 13 is held)


def test_nearest_picks_the_closest_grid_and_reports_the_distance(free_quads):
    # grids every 0.25 in x, 0.2 in y; ids row by row (5 per row)
    xyz = [[0.30, 0.21, 0.0], [0.125, 0.1, 0.0], [0.74, 0.79, 0.0]]
    sm = jaxfem.locate_sensors(free_quads, xyz, [3, 3, 3], "nearest", labels=["a", "b", "c"])
    assert sm.grids[:, 0].tolist() == [7, 1, 24]  # tie at (0.125, 0.1): four grids, lowest id
    np.testing.assert_allclose(sm.distance, [np.hypot(0.05, 0.01), np.hypot(0.125, 0.1), np.hypot(0.01, 0.01)])
    assert sm.worst_distance == pytest.approx(np.hypot(0.125, 0.1))
    assert (sm.elements == -1).all()


@pytest.mark.parametrize("model_name", ["free_quads", "distorted_quads", "distorted_trias"])
def test_interpolate_reproduces_a_linear_field(model_name, request):
    m = request.getfixturevalue(model_name)

    def f(x, y, z):
        return (0.1 + 2 * x - y, -0.3 + x + 3 * y, 1.0 - 0.5 * x + 0.7 * y, 0.2 * x, -y, 0.0)

    phi = _field(m, f)
    xyz = np.array([[0.33, 0.27, 0.0], [0.61, 0.43, 0.0], [0.87, 0.09, 0.0], [0.5, 0.4, 0.0]])
    d = np.array([0.36, 0.48, 0.8])
    sm = jaxfem.locate_sensors(m, xyz, [3, 1, d, 5], "interpolate")
    truth = [f(*p) for p in xyz]
    expect = [truth[0][2], truth[1][0], d @ np.array(truth[2][:3]), truth[3][4]]
    np.testing.assert_allclose(sm.observe(jnp.asarray(phi)), expect, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(sm.distance, 0.0, atol=1e-14)
    np.testing.assert_allclose(sm.shape_functions.sum(axis=1), 1.0, rtol=1e-14)


def test_interpolate_reproduces_a_bilinear_field_on_a_quad(free_quads):
    m = free_quads

    def f(x, y, z):
        return (0.0, 0.0, 0.3 + x - 2 * y + 5 * x * y, 0.0, 0.0, 0.0)

    xyz = np.array([[0.33, 0.27, 0.0], [0.61, 0.43, 0.0], [0.1, 0.7, 0.0]])
    sm = jaxfem.locate_sensors(m, xyz, [3, 3, 3], "interpolate")
    np.testing.assert_allclose(sm.observe(jnp.asarray(_field(m, f))), [f(*p)[2] for p in xyz], rtol=1e-12)
    nearest = jaxfem.locate_sensors(m, xyz, [3, 3, 3], "nearest").observe(jnp.asarray(_field(m, f)))
    assert not np.allclose(nearest, [f(*p)[2] for p in xyz], rtol=1e-3)


def test_interpolate_reports_the_normal_distance(free_quads, distorted_trias):
    for m in (free_quads, distorted_trias):
        xyz = [[0.33, 0.27, 0.002], [0.61, 0.43, -0.015]]
        sm = jaxfem.locate_sensors(m, xyz, [3, 3], "interpolate")
        np.testing.assert_allclose(sm.distance, [0.002, 0.015], rtol=1e-10)
        assert sm.worst_distance == pytest.approx(0.015)
    # beside the plate, in its plane: the distance to the nearest edge
    sm = jaxfem.locate_sensors(free_quads, [[1.03, 0.5, 0.0], [0.5, -0.04, 0.003]], [3, 3], "interpolate")
    np.testing.assert_allclose(sm.distance, [0.03, np.hypot(0.04, 0.003)], rtol=1e-10)
    assert sm.elements.tolist() == [12, 2]  # (0.5, 0) is the corner of quads 2 and 3: lowest id
    assert sm.grids[1, 0] == 3 and (sm.grids[1, 1:] == -1).all() and sm.shape_functions[1, 0] == 1.0  # grid 3 alone


def test_report_table(free_quads):
    sm = jaxfem.locate_sensors(free_quads, [[0.33, 0.27, 0.002], [0.5, 0.4, 0.0]], [3, [0.0, 1.0, 0.0]],
                               "interpolate", labels=["tip", "mid"])
    text = sm.report()
    lines = text.splitlines()
    assert lines[0].split() == ["sensor", "direction", "x", "[m]", "y", "[m]", "z", "[m]", "grid/element",
                                "distance", "[m]"]
    assert lines[2].startswith("tip") and "CQUAD4 6 (7 8 13 12)" in lines[2] and "2.000e-03" in lines[2]
    assert lines[3].startswith("mid") and "+Y" in lines[3]
    assert lines[-1] == "worst distance: 2.000e-03 m (sensor tip)"
    near = jaxfem.locate_sensors(free_quads, [[0.33, 0.27, 0.0]], [3], "nearest").report()
    assert "grid 7" in near


def test_interpolated_mode_is_closer_to_the_analytic_shape():
    """First mode of a simply supported plate, sin(πx/a)·sin(πy/b), at off-grid points."""
    m = _model(plate(A, B, 8, 6, PROPS, bc="ss"))
    _, phi = jaxfem.modes(m, 1)
    rng = np.random.default_rng(0)
    xyz = np.column_stack([rng.uniform(0.05, 0.95, 30) * A, rng.uniform(0.05, 0.95, 30) * B, np.zeros(30)])
    exact = np.sin(np.pi * xyz[:, 0] / A) * np.sin(np.pi * xyz[:, 1] / B)

    def error(method):
        y = np.asarray(jaxfem.locate_sensors(m, xyz, [3] * 30, method).observe(phi))[:, 0]
        y = y * (y @ exact) / (y @ y)  # best scale onto the analytic shape
        return np.linalg.norm(y - exact) / np.linalg.norm(exact)

    e_near, e_interp = error("nearest"), error("interpolate")
    assert e_interp < 0.1 * e_near, (e_interp, e_near)  # measured 0.016 against 0.21
    assert e_interp < 0.03


def test_observe_is_jittable_and_differentiable(free_quads):
    m = free_quads
    sm = jaxfem.locate_sensors(m, [[0.33, 0.27, 0.0], [0.61, 0.43, 0.01]], [3, [0.6, 0.8, 0.0]], "interpolate")
    phi = jnp.asarray(np.random.default_rng(3).standard_normal((m.n_dof, 2)))
    y = sm.observe(phi)
    assert y.shape == (2, 2) and y.dtype == jnp.float64
    np.testing.assert_allclose(y, sm.matrix @ np.asarray(phi), rtol=1e-13)
    np.testing.assert_allclose(jax.jit(lambda p: sm.observe(p))(phi), y, rtol=1e-14)
    np.testing.assert_allclose(eqx.filter_jit(sm.observe)(phi), y, rtol=1e-14)
    np.testing.assert_allclose(eqx.filter_jit(lambda s, p: s.observe(p))(sm, phi), y, rtol=1e-14)
    jac = jax.jacfwd(lambda s: sm.observe(s * phi))(jnp.asarray(1.5))
    np.testing.assert_allclose(jac, y, rtol=1e-14)
    grad = jax.grad(lambda p: jnp.sum(sm.observe(p) ** 2))(phi)
    np.testing.assert_allclose(grad, 2 * sm.matrix.T @ np.asarray(y), rtol=1e-12)
    c = jnp.asarray(1 + 2j, dtype=jnp.complex128)
    z = sm.observe(phi[:, 0].astype(jnp.complex128) * c)  # complex shapes and a single vector
    assert z.dtype == jnp.complex128
    np.testing.assert_allclose(z, np.asarray(y[:, 0]) * (1 + 2j), rtol=1e-13)


def test_interpolate_falls_back_to_nearest_with_a_warning(free_quads):
    with pytest.warns(UserWarning, match=r"sensor\(s\) far \(5 m from CQUAD4"):
        sm = jaxfem.locate_sensors(free_quads, [[0.33, 0.27, 0.0], [0.5, 0.4, 5.0]], [3, 3], "interpolate",
                                   labels=["ok", "far"])
    assert sm.elements.tolist()[1] == -1 and sm.grids[1, 0] == 13 and sm.distance[1] == pytest.approx(5.0)
    assert sm.elements[0] > 0
    with pytest.warns(UserWarning, match="far"):
        jaxfem.locate_sensors(free_quads, [[0.5, 0.4, 0.05]], [3], "interpolate", labels=["far"],
                              max_distance=0.01)

    beams = _model(
        "PARAM,COUPMASS,1\nMAT1,1,70.E9,,0.3,2700.\nPBAR,1,1,1.E-4,1.E-9,1.E-9,2.E-9\n"
        "GRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\nGRID,3,,2.,0.,0.\n"
        "CBAR,1,1,1,2,0.,0.,1.\nCBAR,2,1,2,3,0.,0.,1.\n"
    )
    with pytest.warns(UserWarning, match=r"sensor\(s\) s1, s2 read the nearest grid .*no shell"):
        sm = jaxfem.locate_sensors(beams, [[0.9, 0.0, 0.0], [1.6, 0.1, 0.0]], [2, 3], "interpolate",
                                   labels=["s1", "s2"])
    ref = jaxfem.locate_sensors(beams, [[0.9, 0.0, 0.0], [1.6, 0.1, 0.0]], [2, 3], "nearest")
    np.testing.assert_array_equal(sm.matrix, ref.matrix)
    assert ref.grids[:, 0].tolist() == [2, 3]
    np.testing.assert_allclose(ref.distance, [0.1, np.hypot(0.4, 0.1)])


@pytest.mark.parametrize(
    "xyz, directions, method, match",
    [
        ([0.1, 0.2, 0.0], [3], "nearest", r"shape \(3,\)"),
        ([[0.1, 0.2]], [3], "nearest", r"shape \(1, 2\)"),
        ([[0.1, 0.2, 0.0]], [3, 3], "nearest", "1 sensor points but 2 directions"),
        ([[0.1, 0.2, 0.0]], [[0.0, 0.0, 0.0]], "nearest", "is zero"),
        ([[0.1, 0.2, 0.0]], [[1.0, 1.0, 0.0]], "nearest", "not 1"),
        ([[0.1, 0.2, 0.0]], [7], "nearest", "component 7 is not 1..6"),
        ([[0.1, 0.2, 0.0]], [0], "nearest", "component 0"),
        ([[0.1, 0.2, 0.0]], [[1.0, 0.0]], "nearest", "neither a component"),
        ([[0.1, np.nan, 0.0]], [3], "nearest", "not finite"),
        ([[0.1, 0.2, 0.0]], [3], "linear", "unknown method 'linear'"),
    ],
)
def test_errors(free_quads, xyz, directions, method, match):
    with pytest.raises(ValueError, match=match):
        jaxfem.locate_sensors(free_quads, xyz, directions, method)


def test_observe_refuses_a_wrong_shape(free_quads):
    sm = jaxfem.locate_sensors(free_quads, [[0.1, 0.2, 0.0]], [3])
    with pytest.raises(ValueError, match=r"phi has shape \(3, 2\)"):
        sm.observe(jnp.zeros((3, 2)))


def test_sensors_at_grids_equal_nearest_at_the_grid_points(free_quads):
    grids = [int(g) for g in free_quads.node_ids[[3, 7, 11]]]
    skew = np.array([0.6, 0.0, 0.8])
    by_id = jaxfem.sensors_at_grids(free_quads, grids, [3, skew, skew], rotational=[False, False, True])
    xyz = np.asarray(free_quads.xyz)[free_quads.node_index(grids)]
    by_xyz = jaxfem.locate_sensors(free_quads, xyz, [3, skew, skew], "nearest", rotational=[False, False, True])
    np.testing.assert_array_equal(by_id.matrix, by_xyz.matrix)
    assert by_id.rotational.tolist() == [False, False, True] and np.all(by_id.distance == 0.0)
    row = free_quads.dofs.index[free_quads.node_index([grids[2]])[0]]
    assert set(np.flatnonzero(by_id.matrix[2])) <= set(row.tolist())  # a rotation reads that grid's rotations
