"""eigh and its derivative rule on dense matrices: Nelson, finite differences, policies."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sl

from jaxfem import DenseMatrix, eigh, nelson


def _pair(n, seed, massless=()):
    rng = np.random.default_rng(seed)
    a = rng.standard_normal((n, n))
    k = a @ a.T + 0.1 * np.eye(n)
    b = rng.standard_normal((n, n))
    m = b @ b.T / n + np.eye(n)
    dk = rng.standard_normal((n, n))
    dm = rng.standard_normal((n, n))
    dk, dm = dk + dk.T, 0.1 * (dm + dm.T)
    idx = np.asarray(massless, dtype=np.int64)
    m[idx, :] = m[:, idx] = 0.0
    dm[idx, :] = dm[:, idx] = 0.0
    return tuple(jnp.asarray(x) for x in (k, m, dk, dm)) + (idx,)


def _path(k, m, dk, dm, idx, n_modes):
    return lambda t: eigh(k + t * dk, DenseMatrix(m + t * dm, massless=idx), n_modes)


@pytest.mark.parametrize("massless", [(), (2, 5, 7)])
def test_forward_matches_scipy(massless):
    k, m, dk, dm, idx = _pair(12, 0, massless)
    lam, phi = _path(k, m, dk, dm, idx, None)(0.0)
    assert lam.dtype == jnp.float64 and phi.dtype == jnp.float64
    a = np.setdiff1d(np.arange(12), idx)
    kn, mn = np.asarray(k), np.asarray(m)
    kaa = kn[np.ix_(a, a)]
    if len(idx):
        kaa = kaa - kn[np.ix_(a, idx)] @ np.linalg.solve(kn[np.ix_(idx, idx)], kn[np.ix_(idx, a)])
    ref = sl.eigh(kaa, mn[np.ix_(a, a)], eigvals_only=True)
    np.testing.assert_allclose(lam, ref, rtol=1e-10)
    np.testing.assert_allclose(phi.T @ m @ phi, np.eye(len(a)), atol=1e-10)
    np.testing.assert_allclose(k @ phi, m @ phi * lam[None, :], atol=1e-9 * float(lam[-1]))
    big = phi[np.argmax(np.abs(phi), axis=0), np.arange(phi.shape[1])]
    assert np.all(big > 0)


@pytest.mark.parametrize("massless", [(), (2, 5, 7)])
def test_jvp_against_nelson_and_finite_differences(massless):
    k, m, dk, dm, idx = _pair(12, 1, massless)
    f = _path(k, m, dk, dm, idx, 5)
    (lam, phi), (dlam, dphi) = jax.jvp(f, (0.0,), (1.0,))
    h = 1e-6
    (l1, p1), (l2, p2) = f(h), f(-h)
    np.testing.assert_allclose(dlam, (l1 - l2) / (2 * h), rtol=1e-5)
    np.testing.assert_allclose(dphi, (p1 - p2) / (2 * h), atol=1e-5 * float(jnp.max(jnp.abs(dphi))))
    for r in range(5):
        dl, dp = nelson(k, m, lam[r], phi[:, r], dk, dm)
        np.testing.assert_allclose(dl, dlam[r], rtol=1e-10)
        np.testing.assert_allclose(dp, dphi[:, r], atol=1e-10 * float(jnp.max(jnp.abs(dp))))


def test_jacfwd_and_grad_agree():
    k, m, dk, dm, idx = _pair(10, 2)
    rng = np.random.default_rng(3)
    dk2 = jnp.asarray(rng.standard_normal((10, 10)))
    dk2 = dk2 + dk2.T

    def f(p):
        return eigh(k + p[0] * dk + p[1] * dk2, m + p[0] * dm, 4)

    p0 = jnp.zeros(2)
    jl, jp = jax.jacfwd(f)(p0)
    weights = jnp.arange(1.0, 5.0)

    def scalar(p):
        lam, phi = f(p)
        return jnp.sum(weights * lam) + jnp.sum(phi[:3] ** 2)

    grad = jax.grad(scalar)(p0)
    lam, phi = f(p0)
    expected = jl.T @ weights + jnp.einsum("ij,ijk->k", 2 * phi[:3], jp[:3])
    np.testing.assert_allclose(grad, expected, rtol=1e-10)
    for i, t in enumerate(jnp.eye(2)):
        _, (dl, dp) = jax.jvp(f, (p0,), (t,))
        np.testing.assert_allclose(jl[:, i], dl, rtol=1e-12)
        np.testing.assert_allclose(jp[:, :, i], dp, rtol=1e-12, atol=1e-14)


def _repeated(seed):
    """K with a triple eigenvalue 4 and a double 9 (M = I); a random symmetric dK."""
    rng = np.random.default_rng(seed)
    q, _ = np.linalg.qr(rng.standard_normal((8, 8)))
    lam = np.array([1.0, 4.0, 4.0, 4.0, 6.0, 9.0, 9.0, 12.0])
    dk = rng.standard_normal((8, 8))
    return jnp.asarray(q @ np.diag(lam) @ q.T), jnp.eye(8), jnp.asarray(dk + dk.T)


def test_repeated_mean_policy_is_finite_and_exact_for_cluster_mean():
    k, m, dk = _repeated(4)
    f = lambda t: eigh(k + t * dk, m, 7)
    (lam, phi), (dlam, dphi) = jax.jvp(f, (0.0,), (1.0,))
    assert jnp.all(jnp.isfinite(dlam)) and jnp.all(jnp.isfinite(dphi))
    h = 1e-6
    l1, l2 = f(h)[0], f(-h)[0]
    fd = (l1 - l2) / (2 * h)
    np.testing.assert_allclose(dlam[1:4], np.full(3, fd[1:4].mean()), rtol=1e-6)
    np.testing.assert_allclose(dlam[5:7], np.full(2, fd[5:7].mean()), rtol=1e-6)
    np.testing.assert_allclose(np.asarray(dlam)[[0, 4]], np.asarray(fd)[[0, 4]], rtol=1e-6)
    # The derivative of the cluster's spectral projector P = Φ_C Φ_Cᵀ is exact.
    proj = lambda t: (lambda p: p[:, 1:4] @ p[:, 1:4].T)(f(t)[1])
    dproj = dphi[:, 1:4] @ phi[:, 1:4].T + phi[:, 1:4] @ dphi[:, 1:4].T
    np.testing.assert_allclose(dproj, (proj(h) - proj(-h)) / (2 * h), atol=1e-6)
    g = jax.grad(lambda t: jnp.sum(f(t)[0]) + jnp.sum(f(t)[1] ** 4))(0.0)
    assert jnp.isfinite(g)


def test_repeated_split_policy_gives_directional_derivatives():
    k, m, dk = _repeated(5)
    f = lambda t: eigh(k + t * dk, m, 7, degenerate="split")
    (lam, _), (dlam, dphi) = jax.jvp(f, (0.0,), (1.0,))
    assert jnp.all(jnp.isfinite(dphi))
    h = 1e-7
    one_sided = (f(h)[0] - lam) / h
    np.testing.assert_allclose(dlam, one_sided, rtol=1e-5, atol=1e-6)
    # Reference: eigenvalues of the degenerate-subspace matrix for the triple cluster.
    w, v = np.linalg.eigh(np.asarray(k))
    c = v[:, 1:4]
    np.testing.assert_allclose(dlam[1:4], np.linalg.eigvalsh(c.T @ np.asarray(dk) @ c), rtol=1e-10)


def test_close_but_distinct_eigenvalues_stay_finite():
    """Gap 1e-9 relative (below DEGENERATE_RTOL): derivatives finite, no inf/NaN."""
    k, m, dk = _repeated(6)
    w, v = np.linalg.eigh(np.asarray(k))
    w[2] += 4e-9
    kc = jnp.asarray(v @ np.diag(w) @ v.T)
    jl, jp = jax.jacfwd(lambda t: eigh(kc + t * dk, m, 7))(0.0)
    assert jnp.all(jnp.isfinite(jl)) and jnp.all(jnp.isfinite(jp))


def test_rigid_body_modes_free_spring_chain():
    """Free–free 4-mass chain: one zero eigenvalue, elastic ones and derivatives exact."""
    kk = 1000.0
    k = kk * jnp.array([[1.0, -1, 0, 0], [-1, 2, -1, 0], [0, -1, 2, -1], [0, 0, -1, 1]])
    m = jnp.eye(4)
    lam, phi = eigh(k, m)
    ref = 2 * kk * (1 - np.cos(np.arange(4) * np.pi / 4))
    np.testing.assert_allclose(lam, ref, atol=1e-9 * kk)
    dl = jax.jacfwd(lambda s: eigh(s * k, m)[0])(1.0)
    np.testing.assert_allclose(dl, ref, atol=1e-9 * kk)  # λ is linear in a stiffness scale


def test_distinct_modes_beside_a_stiff_penalty_are_not_averaged():
    """Modes 0.5 % apart under a penalty stiffness 10¹⁵ times theirs (a joint's stiff
    springs): each keeps its own derivative, dλ₁/dk₁ = 1 and dλ₂/dk₁ = 0 (from the whole
    spectrum's largest eigenvalue the threshold grouped the lowest eight and gave ⅛ each)."""
    rng = np.random.default_rng(3)
    q, _ = np.linalg.qr(rng.standard_normal((11, 11)))
    w = np.array([100.0, 100.5, 300, 700, 1.1e3, 2e3, 3e3, 4e3, 5e3, 6e3, 7e3])
    k = jnp.asarray(sl.block_diag(q @ np.diag(w) @ q.T, 1e17))  # the penalty on a DoF of its own
    dk = jnp.asarray(sl.block_diag(np.outer(q[:, 0], q[:, 0]), 0.0))
    dlam = jax.jacfwd(lambda t: eigh(k + t * dk, jnp.eye(12), 2)[0])(0.0)
    np.testing.assert_allclose(dlam, [1.0, 0.0], atol=1e-6)


def test_float32_is_refused():
    with pytest.raises(TypeError, match="float64"):
        eigh(jnp.eye(3, dtype=jnp.float32), jnp.eye(3, dtype=jnp.float32))


def test_bad_shapes_and_indefinite_mass():
    with pytest.raises(ValueError, match="square"):
        eigh(jnp.ones((2, 3)), jnp.eye(2))
    with pytest.raises(ValueError, match="n_modes"):
        eigh(jnp.eye(3), jnp.eye(3), 4)
    with pytest.raises(Exception, match="not positive definite"):
        eigh(jnp.eye(3), jnp.diag(jnp.array([1.0, -1.0, 1.0])))


def test_a_dense_problem_too_large_for_memory_is_refused_before_allocating():
    from jaxfem._eigen import _check_memory

    _check_memory(2000)  # 256 MB: fine anywhere
    with pytest.raises(MemoryError, match=r"needs about \d+ GiB for 1000000 DoFs"):
        _check_memory(1_000_000)
