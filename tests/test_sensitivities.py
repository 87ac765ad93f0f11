"""Eigen-sensitivities of a 3-D frame (> 200 DoFs) checked three ways.

Parameters: a stiffness and a mass correction factor on element groups (eq. 3.1), and
physical values (Young's modulus, density, a section inertia, a spring rate, a lumped
mass). Methods: the custom JVP through ``jax.jvp``, ``jax.jacfwd`` and ``jax.grad``
(element-stacked tangents); the same rule on dense matrices; Nelson's method; central
finite differences.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.frames import frame_bdf
from jaxfem.io import read_bdf_text

N_MODES = 8
P0 = jnp.zeros(7)


def parameterised(coupmass):
    model = jaxfem.build_model(read_bdf_text(frame_bdf(3, 3, 4, coupmass=coupmass), name="frame"))
    k_group = [model.element_ids(pids=list(range(1, 6)))]
    m_group = [model.element_ids(pids=list(range(6, 11)))]

    def with_params(p):
        m = jaxfem.correct(model, k_group, p[0:1], m_group, p[1:2])
        m = eqx.tree_at(lambda t: t.materials.E, m, m.materials.E * (1 + p[2] * jnp.array([1.0, 0.0])))
        m = eqx.tree_at(lambda t: t.materials.rho, m, m.materials.rho * (1 + p[3] * jnp.array([0.0, 1.0])))
        m = eqx.tree_at(lambda t: t.beam_sections.I1, m, m.beam_sections.I1.at[2].multiply(1 + p[4]))
        m = eqx.tree_at(lambda t: t.springs.k, m, m.springs.k * (1 + p[5]))
        m = eqx.tree_at(lambda t: t.masses.m, m, m.masses.m.at[1].multiply(1 + p[6]))
        return m

    def modes(p):
        return jaxfem.eigh(*jaxfem.assemble(with_params(p)), N_MODES)

    def dense_matrices(p):
        K, M = jaxfem.assemble(with_params(p))
        return K.todense(), M.todense()

    return model, jax.jit(modes), jax.jit(dense_matrices)


@pytest.fixture(scope="module", params=[1, -1], ids=["consistent", "lumped"])
def frame(request):
    model, modes, dense = parameterised(request.param)
    jl, jp = jax.jit(jax.jacfwd(modes))(P0)
    lam, phi = modes(P0)
    return model, modes, dense, lam, phi, jl, jp


def test_frame_is_large_enough_and_float64(frame):
    model, _, _, lam, phi, jl, jp = frame
    assert model.n_dof >= 200
    assert {lam.dtype, phi.dtype, jl.dtype, jp.dtype} == {jnp.dtype(jnp.float64)}
    assert np.all(np.diff(np.asarray(lam)) > 1e-6 * float(lam[-1]))  # no repeated modes here


def test_jvp_and_grad_match_jacfwd(frame):
    _, modes, _, _, _, jl, jp = frame
    for i in (0, 3, 6):
        _, (dl, dp) = jax.jvp(modes, (P0,), (jnp.eye(7)[i],))
        np.testing.assert_allclose(dl, jl[:, i], rtol=1e-10, atol=1e-12 * float(jnp.max(jnp.abs(jl))))
        np.testing.assert_allclose(dp, jp[:, :, i], rtol=1e-8, atol=1e-10 * float(jnp.max(jnp.abs(dp))))
    w = jnp.linspace(1.0, 2.0, N_MODES)

    def scalar(p):
        lam, phi = modes(p)
        return jnp.sum(w * lam) + jnp.sum(phi[:10] ** 2)

    lam, phi = modes(P0)
    expected = jl.T @ w + jnp.einsum("ij,ijk->k", 2 * phi[:10], jp[:10])
    np.testing.assert_allclose(jax.grad(scalar)(P0), expected, rtol=1e-8)


def test_dense_tangents_and_nelson_agree(frame):
    model, _, dense, lam, phi, jl, jp = frame
    K, M = dense(P0)
    dK, dM = jax.jacfwd(dense)(P0)

    def dense_modes(p):
        Kd, Md = dense(p)
        return jaxfem.eigh(Kd, jaxfem.DenseMatrix(Md, massless=model.dofs.massless), N_MODES)

    jl_dense, jp_dense = jax.jacfwd(dense_modes)(P0)
    lscale, pscale = float(jnp.max(jnp.abs(jl))), float(jnp.max(jnp.abs(jp)))
    np.testing.assert_allclose(jl_dense, jl, rtol=1e-8, atol=1e-8 * lscale)
    np.testing.assert_allclose(jp_dense, jp, atol=1e-8 * pscale)
    for i in range(7):
        for r in range(N_MODES):
            dl, dp = jaxfem.nelson(K, M, lam[r], phi[:, r], dK[:, :, i], dM[:, :, i])
            np.testing.assert_allclose(dl, jl[r, i], rtol=1e-8, atol=1e-8 * lscale)
            np.testing.assert_allclose(dp, jp[:, r, i], atol=1e-8 * pscale)


def test_finite_differences(frame):
    """Fourth-order central differences, (−f(2h) + 8f(h) − 8f(−h) + f(−2h)) / 12h."""
    _, modes, _, lam, phi, jl, jp = frame
    h = 1e-4
    for i in range(7):
        (l2, p2), (l1, p1), (m1, q1), (m2, q2) = (modes(P0.at[i].set(s * h)) for s in (2, 1, -1, -2))
        fd_l = (-l2 + 8 * l1 - 8 * m1 + m2) / (12 * h)
        fd_p = (-p2 + 8 * p1 - 8 * q1 + q2) / (12 * h)
        np.testing.assert_allclose(fd_l, jl[:, i], rtol=1e-5, atol=1e-5 * float(jnp.max(jnp.abs(jl))))
        np.testing.assert_allclose(fd_p, jp[:, :, i], atol=1e-5 * float(jnp.max(jnp.abs(jp))))


def test_stiffness_scaling_identity(frame):
    """λ is homogeneous of degree 1 in a common stiffness factor: Σ_i ∂λ/∂α_i = λ (eq. 3.19)."""
    model = frame[0]
    everything = [model.element_ids()]
    dl = jax.jacfwd(lambda a: jaxfem.eigh(*jaxfem.assemble(jaxfem.correct(model, everything, a)),
                                          N_MODES)[0])(jnp.zeros(1))
    np.testing.assert_allclose(dl[:, 0], frame[3], rtol=1e-9)


def test_repeated_modes_of_a_symmetric_column():
    """A square-section cantilever column has exactly repeated bending pairs: finite
    derivatives, cluster mean exact, and the pair's invariant subspace derivative exact."""
    lines = ["PARAM,COUPMASS,1", "MAT1,1,2.1+11,,0.3,7850.", "PBAR,1,1,1.e-3,2.e-7,2.e-7,3.e-7"]
    lines += [f"GRID,{i + 1},,0.,0.,{0.1 * i}" for i in range(11)]
    lines += [f"CBAR,{i + 1},1,{i + 1},{i + 2},1.,0.,0." for i in range(10)]
    lines += ["SPC1,1,123456,1"]
    model = jaxfem.build_model(read_bdf_text("\n".join(lines)))

    def modes(p):
        m = eqx.tree_at(lambda t: t.beam_sections.A, model, model.beam_sections.A * (1 + p[0]))
        m = eqx.tree_at(lambda t: t.materials.E, m, m.materials.E * (1 + p[1]))
        return jaxfem.eigh(*jaxfem.assemble(m), 4)

    modes = jax.jit(modes)
    lam, phi = modes(jnp.zeros(2))
    assert abs(float(lam[1] / lam[0]) - 1) < 1e-8  # the pair is repeated (to round-off)
    jl, jp = jax.jacfwd(modes)(jnp.zeros(2))
    assert jnp.all(jnp.isfinite(jl)) and jnp.all(jnp.isfinite(jp))
    h = 3e-3  # eigenvalues carry ~1e-9 relative round-off (∝ λ_max): fourth-order stencil
    stencil = (2, 1, -1, -2), jnp.array([-1.0, 8.0, -8.0, 1.0]) / (12 * h)
    proj = lambda p: p[:, :2] @ p[:, :2].T
    for i in range(2):
        runs = [modes(jnp.zeros(2).at[i].set(s * h)) for s in stencil[0]]
        fd_mean = sum(c * r[0][:2].mean() for c, r in zip(stencil[1], runs))
        fd_proj = sum(c * proj(r[1]) for c, r in zip(stencil[1], runs))
        np.testing.assert_allclose(jl[0, i], fd_mean, rtol=1e-5)
        np.testing.assert_allclose(jl[1, i], fd_mean, rtol=1e-5)
        dproj = jp[:, :2, i] @ phi[:, :2].T + phi[:, :2] @ jp[:, :2, i].T
        np.testing.assert_allclose(dproj, fd_proj, atol=1e-5 * float(jnp.max(jnp.abs(proj(phi)))))
