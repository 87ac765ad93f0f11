"""Element sensitivities of the residual (updating.diagnosis._element_sensitivity): every element's
stiffness and mass scale against forward mode through the eigensolver's own derivative
rule, shell parts and non-structural mass against central finite differences, the sparse
path (lowest modes + static correction) against the dense one."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.frames import frame_bdf
from benchmarks.shell_models import plate
from identification import Sensors
from jaxfem import MASS_BLOCKS, STIFFNESS_BLOCKS
from jaxfem.io import read_bdf_text
from updating import Options, ParameterSet
from updating.diagnosis._element_sensitivity import element_jacobian
from updating._residuals import residuals
from updating._simulation import simulate_test
from updating._solve import build_problem

LAMINATE = """MAT8,8,5.4e10,5.4e10,0.05,5.0e9,2.0e9,2.0e9,1460.0
PCOMP,1,,,,,,,,
,8,0.002,0.,,8,0.002,0.,"""


def _flat(theta, problem):
    eps, _ = residuals(theta, problem)
    return jnp.concatenate([jnp.ravel(eps[k]) for k in ("eigenvalue", "eigenvector")])


def _problem(model, truth, sensors, n, solver="auto"):
    test = simulate_test(truth, sensors, n)
    return build_problem(model, test, ParameterSet((), Options(eigenvalue_weight=2.0, eigensolver=solver)))


def _columns(jac, kind, ids):
    at = {int(e): i for i, e in enumerate(jac.ids[kind])}
    return jac.columns[kind][:, [at[int(e)] for e in ids]]


@pytest.fixture(scope="module")
def frame_problem():
    model = jaxfem.build_model(read_bdf_text(frame_bdf(2, 2, 4, n_groups=8)))
    grids = list(range(5, 21))
    sensors = Sensors.from_components(np.repeat(grids, 2), np.tile([1, 2], len(grids)))
    truth = jaxfem.correct(model, [model.element_ids(pids=[3]).tolist()], jnp.array([0.2]))
    return model, _problem(model, truth, sensors, 12)


def test_element_columns_equal_forward_mode(frame_problem):
    """Each element's stiffness and mass column equals jax.jacfwd through jaxfem.eigh's
    own rule (all modes: the modal expansion is exact), at a θ where the residual is not 0."""
    model, problem = frame_problem
    jac = element_jacobian(problem, jnp.zeros(0), kinds=("k", "m"))

    def fn(uk, um):
        m = problem.model(jnp.zeros(0))
        for names, us, scale in ((STIFFNESS_BLOCKS, uk, "k_scale"), (MASS_BLOCKS, um, "m_scale")):
            for name, u in zip(names, us):
                s = getattr(getattr(m, name), scale)
                m = eqx.tree_at(lambda x, name=name: getattr(getattr(x, name), scale), m, s * (1 + u))
        p = eqx.tree_at(lambda q: q.values, problem, jaxfem.partition(m)[0])
        return _flat(jnp.zeros(0), p)

    zeros = lambda names: tuple(jnp.zeros(len(getattr(model, n).ids)) for n in names)  # noqa: E731
    jk, jm = jax.jacfwd(fn, argnums=(0, 1))(zeros(STIFFNESS_BLOCKS), zeros(MASS_BLOCKS))
    k_ids = np.concatenate([getattr(model, n).ids for n in STIFFNESS_BLOCKS])
    m_ids = np.concatenate([getattr(model, n).ids for n in MASS_BLOCKS])
    ref_k, ref_m = np.concatenate(jk, axis=1), np.concatenate(jm, axis=1)
    assert np.abs(ref_k).max() > 1e-3 and np.abs(ref_m).max() > 1e-3
    np.testing.assert_allclose(jac.r, fn(zeros(STIFFNESS_BLOCKS), zeros(MASS_BLOCKS)), atol=1e-14)
    np.testing.assert_allclose(_columns(jac, "k", k_ids), ref_k, atol=1e-9 * np.abs(ref_k).max())
    np.testing.assert_allclose(_columns(jac, "m", m_ids), ref_m, atol=1e-9 * np.abs(ref_m).max())
    assert jac.columns["k"].dtype == np.float64


@pytest.fixture(scope="module")
def laminate_plate():
    """A clamped 0.4 × 0.3 m CFRP plate, 10 × 8 CQUAD4 (transverse-shear flexible),
    its truth with a stiffer membrane; 14 modes at z of every interior grid."""
    model = jaxfem.build_model(read_bdf_text(plate(0.4, 0.3, 10, 8, LAMINATE, bc="cfff")))
    truth = jaxfem.correct(model, [model.element_ids().tolist()], jnp.array([0.05]))
    grids = [int(g) for g, x in zip(model.node_ids, np.asarray(model.xyz)) if x[0] > 0]
    return model, truth, Sensors.from_components(grids, np.full(len(grids), 3))


@pytest.mark.parametrize("kind", ["shear", "bending", "nsm"])
def test_shell_part_columns_equal_forward_mode(laminate_plate, kind):
    """Columns of a shell part (relative) and of NSM (absolute, kg/m²) for three elements
    against forward mode through jaxfem.eigh's rule, one element at a time (finite
    differences cannot resolve them: a shear column's eigenvalue rows are 4e-7 of λ).
    (The membrane column of a flat symmetric laminate's bending modes is 0.)"""
    model, truth, sensors = laminate_plate
    problem = _problem(model, truth, sensors, 10, solver="dense")
    jac = element_jacobian(problem, jnp.zeros(0), kinds=(kind,))
    rows = np.asarray(model.quads.ids).searchsorted(model.quads.ids[[0, 37, 79]])
    col = {"membrane": 0, "bending": 1, "shear": 2}.get(kind)

    def moved(u, row):
        q = model.quads
        if col is None:
            m = eqx.tree_at(lambda x: x.quads.nsm, model, q.nsm.at[row].add(u))
        else:
            m = eqx.tree_at(lambda x: x.quads.parts, model, q.parts.at[row, col].multiply(1 + u))
        return _flat(jnp.zeros(0), eqx.tree_at(lambda p: p.values, problem, jaxfem.partition(m)[0]))

    ref = np.stack([jax.jvp(lambda u: moved(u, r), (0.0,), (1.0,))[1] for r in rows], axis=1)
    got = _columns(jac, kind, model.quads.ids[rows])
    assert np.abs(ref).max() > 1e-6
    np.testing.assert_allclose(got, ref, atol=1e-8 * np.abs(ref).max())


def test_sparse_path_matches_dense(laminate_plate):
    """The sparse path's columns (the lowest modes, the rest by its static correction):
    eigenvalue rows exact, eigenvector rows within 2 % of the column's size."""
    model, truth, sensors = laminate_plate
    dense = element_jacobian(_problem(model, truth, sensors, 10, "dense"), jnp.zeros(0), kinds=("k", "shear"))
    sparse = element_jacobian(_problem(model, truth, sensors, 10, "sparse"), jnp.zeros(0), kinds=("k", "shear"))
    np.testing.assert_allclose(sparse.r, dense.r, atol=1e-8)
    for kind in ("k", "shear"):
        d, s = dense.columns[kind], _columns(sparse, kind, dense.ids[kind])
        np.testing.assert_allclose(s[:10], d[:10], rtol=1e-6, atol=1e-9 * np.abs(d[:10]).max())
        scale = np.linalg.norm(d, axis=0)
        assert np.all(np.linalg.norm(s - d, axis=0) <= 0.02 * scale + 1e-12)


def test_columns_do_not_depend_on_the_signs_of_a_second_solve(laminate_plate, monkeypatch):
    """The screen's full-length modes signed otherwise than the residual's (ARPACK returns
    any of them negated from one call to the next) must not flip their eigenvector rows."""
    from updating.diagnosis import _element_sensitivity

    model, truth, sensors = laminate_plate
    problem = _problem(model, truth, sensors, 10, "sparse")
    ref = element_jacobian(problem, jnp.zeros(0), kinds=("m",))
    modes = _element_sensitivity._modes

    def negated(*args):
        ev, lam, phi, solve, sigma = modes(*args)
        return ev, lam, phi * np.where(np.arange(phi.shape[1]) % 2, -1.0, 1.0), solve, sigma

    monkeypatch.setattr(_element_sensitivity, "_modes", negated)
    got = element_jacobian(problem, jnp.zeros(0), kinds=("m",))
    assert np.abs(ref.columns["m"][10:]).max() > 1e-6
    np.testing.assert_allclose(got.columns["m"], ref.columns["m"], atol=1e-10 * np.abs(ref.columns["m"]).max())
