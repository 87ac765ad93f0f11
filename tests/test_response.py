"""Frequency response and damping: closed forms, direct vs modal, Rayleigh, gradients, errors."""

import re

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from jaxfem import frf_direct, frf_modal, rayleigh, rayleigh_coefficients, rayleigh_ratio

# SDOF: m (kg), k (N/m), c (N·s/m).
M1, K1, C1 = 2.0, 8.0e3, 3.0
WN1 = np.sqrt(K1 / M1)


def chain(grounded: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """6-DoF spring-mass chain; grounded at both ends, or free-free (one rigid-body mode)."""
    k = np.array([1.0e4, 2.0e4, 1.5e4, 3.0e4, 2.5e4, 1.2e4, 0.8e4])
    m = np.array([1.0, 2.0, 1.5, 0.5, 1.2, 0.9])
    n = len(m)
    K = np.zeros((n, n))
    for i, ki in enumerate(k):
        a, b = i - 1, i  # spring i joins mass i-1 and mass i (index -1 / n: ground)
        if not grounded and (a < 0 or b >= n):
            continue
        for p, q, s in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
            if 0 <= p < n and 0 <= q < n:
                K[p, q] += s * ki
    return K, np.diag(m)


def rel(a, b) -> float:
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(np.asarray(b))))


def test_sdof_closed_form():
    w = np.linspace(0.0, 3.0 * WN1, 301)
    exact = 1.0 / (K1 - M1 * w**2 + 1j * C1 * w)
    K, M = np.array([[K1]]), np.array([[M1]])
    direct = frf_direct(K, M, w, [0], [0], D=np.array([[C1]]))
    zeta = C1 / (2.0 * np.sqrt(K1 * M1))
    lam, phi = np.array([K1 / M1]), np.array([[1.0 / np.sqrt(M1)]])
    modal = frf_modal(lam, phi, w, [0], [0], zeta=np.array([zeta]))
    mu = 0.5  # c = μm + κk
    rayl = frf_modal(lam, phi, w, [0], [0], mu=mu, kappa=(C1 - mu * M1) / K1)
    for h in (direct, modal, rayl):
        assert h.shape == (301, 1, 1) and h.dtype == jnp.complex128
        np.testing.assert_allclose(h[:, 0, 0], exact, rtol=1e-12, atol=0)


@pytest.mark.parametrize("grounded", [True, False])
def test_chain_rayleigh_direct_equals_modal(grounded):
    K, M = chain(grounded)
    mu, kappa = 1.5, 2.0e-4
    lam, phi = jaxfem.eigh(K, M)
    assert grounded or abs(float(lam[0])) < 1e-8 * float(lam[-1])  # rigid-body mode
    w = np.linspace(1.0, 1.2 * np.sqrt(float(lam[-1])), 97)
    dofs = np.arange(6)
    direct = frf_direct(K, M, w, dofs, dofs, D=rayleigh(K, M, mu, kappa))
    modal = frf_modal(lam, phi, w, dofs, dofs, mu=mu, kappa=kappa)
    assert direct.dtype == modal.dtype == jnp.complex128
    np.testing.assert_allclose(modal, direct, rtol=1e-10, atol=0)
    np.testing.assert_allclose(direct, jnp.swapaxes(direct, 1, 2), rtol=1e-12, atol=0)  # reciprocity
    # Rectangular selection, matrix operators as input.
    sub = frf_direct(jaxfem.DenseMatrix(jnp.asarray(K)), M, w, [4, 1], [0, 5, 2], D=rayleigh(K, M, mu, kappa))
    np.testing.assert_allclose(sub, direct[:, [4, 1]][:, :, [0, 5, 2]], rtol=1e-14, atol=0)


def test_direct_factors_once_per_frequency():
    K, M = chain()
    jaxpr = jax.make_jaxpr(lambda k: frf_direct(k, M, np.array([10.0, 20.0]), [0], [0, 1, 2], eta=0.01))(K)
    assert len(re.findall(r"\blu\b", str(jaxpr))) == 1


def test_structural_damping():
    K, M = chain()
    eta = 0.02
    lam, phi = jaxfem.eigh(K, M)
    w = np.linspace(0.0, 1.2 * np.sqrt(float(lam[-1])), 97)
    direct = frf_direct(K, M, w, [0, 3], [1, 5], eta=eta)
    modal = frf_modal(lam, phi, w, [0, 3], [1, 5], eta=eta)
    np.testing.assert_allclose(modal, direct, rtol=1e-10, atol=0)
    # SDOF: H(ω) = 1/(k(1+iη) − mω²), peak 1/(ηk) exactly at ω_n.
    K1a, M1a = np.array([[K1]]), np.array([[M1]])
    grid = np.concatenate([np.linspace(0.5 * WN1, 1.5 * WN1, 2001), [WN1]])
    h = np.abs(frf_direct(K1a, M1a, grid, [0], [0], eta=eta)[:, 0, 0])
    np.testing.assert_allclose(h[-1], 1.0 / (eta * K1), rtol=1e-12)
    assert h.max() <= h[-1] * (1 + 1e-14)
    hm = frf_modal(np.array([K1 / M1]), np.array([[M1**-0.5]]), np.array([WN1]), [0], [0], eta=eta)
    np.testing.assert_allclose(abs(hm[0, 0, 0]), 1.0 / (eta * K1), rtol=1e-12)


def test_rayleigh_coefficients_and_ratio():
    w1, w2, z1, z2 = 10.0, 200.0, 0.02, 0.05
    mu, kappa = rayleigh_coefficients(w1, w2, z1, z2)
    np.testing.assert_allclose(rayleigh_ratio(jnp.array([w1, w2]), mu, kappa), [z1, z2], rtol=1e-14)
    # ζ(ω) is smallest, √(μκ), at ω = √(μ/κ).
    w = np.linspace(1.0, 400.0, 40001)
    z = np.asarray(rayleigh_ratio(w, mu, kappa))
    np.testing.assert_allclose(w[np.argmin(z)], np.sqrt(mu / kappa), rtol=1e-3)
    np.testing.assert_allclose(rayleigh_ratio(np.sqrt(mu / kappa), mu, kappa), np.sqrt(mu * kappa), rtol=1e-14)
    # The undamped modes diagonalise D with ΦᵀDΦ = diag(2 ζ(ω_r) ω_r).
    K, M = chain()
    lam, phi = jaxfem.eigh(K, M)
    wr = jnp.sqrt(lam)
    modal_d = phi.T @ rayleigh(K, M, mu, kappa) @ phi
    expected = jnp.diag(2.0 * rayleigh_ratio(wr, mu, kappa) * wr)
    np.testing.assert_allclose(modal_d, expected, rtol=0, atol=1e-12 * float(jnp.max(expected)))
    with pytest.raises(ValueError, match="differ"):
        rayleigh_coefficients(w1, w1, z1, z2)
    with pytest.raises(ValueError, match="omega1 must be positive"):
        rayleigh_coefficients(-1.0, w2, z1, z2)


def test_half_power_bandwidth():
    K, M = chain()
    lam, phi = jaxfem.eigh(K, M)
    zeta = np.array([0.01, 0.02, 0.015, 0.01, 0.03, 0.02])
    wr = np.sqrt(np.asarray(lam))
    for r in (0, 5):  # ω_r ≈ 43 and 364 rad/s lie far from the other modes (95–203 rad/s)
        dof = int(np.argmax(np.abs(phi[:, r])))
        w = np.linspace(wr[r] * (1 - 6 * zeta[r]), wr[r] * (1 + 6 * zeta[r]), 20001)
        h = np.abs(frf_modal(lam, phi, w, [dof], [dof], zeta=zeta)[:, 0, 0])
        above = np.nonzero(h >= h.max() / np.sqrt(2.0))[0]
        lo, hi = above[0], above[-1]
        assert 0 < lo and hi < len(w) - 1 and np.all(np.diff(above) == 1)
        half = h.max() / np.sqrt(2.0)
        w_lo = np.interp(half, [h[lo - 1], h[lo]], [w[lo - 1], w[lo]])
        w_hi = np.interp(half, [h[hi + 1], h[hi]], [w[hi + 1], w[hi]])
        np.testing.assert_allclose(w_hi - w_lo, 2.0 * zeta[r] * wr[r], rtol=1e-2)


def test_gradients_direct_modal_fd():
    K0, M = chain()
    mu, kappa, eta = 1.5, 2.0e-4, 0.01
    lam0 = np.asarray(jaxfem.eigh(K0, M)[0])
    w0 = np.array([1.03 * np.sqrt(lam0[1])])
    out, inp = [0, 4], [2]

    def via_direct(s):
        K = s * jnp.asarray(K0)
        h = frf_direct(K, M, w0, out, inp, D=rayleigh(K, M, mu, kappa), eta=eta)
        return jnp.sum(jnp.abs(h) ** 2)

    def via_modal(s):
        lam, phi = jaxfem.eigh(s * jnp.asarray(K0), M)
        h = frf_modal(lam, phi, w0, out, inp, mu=mu, kappa=kappa, eta=eta)
        return jnp.sum(jnp.abs(h) ** 2)

    s0, ds = 1.0, 1e-5
    g_direct = jax.grad(via_direct)(s0)
    g_modal = jax.grad(via_modal)(s0)
    fd = (via_direct(s0 + ds) - via_direct(s0 - ds)) / (2 * ds)
    np.testing.assert_allclose(g_modal, g_direct, rtol=1e-9)
    np.testing.assert_allclose(g_direct, fd, rtol=1e-6)
    assert abs(float(fd)) > 1e-3 * float(via_direct(s0)) / s0  # a meaningful derivative

    # Direct solve: gradient w.r.t. scales of K, M and D (independent) against FD.
    D0 = rayleigh(K0, M, mu, kappa)

    def scaled(p):
        h = frf_direct(p[0] * K0, p[1] * M, w0, out, inp, D=p[2] * D0, eta=eta)
        return jnp.sum(jnp.abs(h) ** 2)

    p0 = jnp.array([1.0, 1.0, 1.0])
    g = jax.grad(scaled)(p0)
    fd = jnp.array([(scaled(p0 + ds * e) - scaled(p0 - ds * e)) / (2 * ds) for e in jnp.eye(3)])
    np.testing.assert_allclose(g, fd, rtol=1e-6)


def test_errors():
    K, M = chain()
    lam, phi = jaxfem.eigh(K, M)
    w = np.array([10.0, 20.0])
    with pytest.raises(TypeError, match="float64"):
        frf_direct(K.astype(np.float32), M, w, [0], [0])
    with pytest.raises(TypeError, match="float64"):
        frf_modal(lam.astype(jnp.float32), phi, w, [0], [0])
    with pytest.raises(TypeError, match="omega"):
        frf_direct(K, M, w.astype(np.float32), [0], [0])
    with pytest.raises(ValueError, match="in_dofs: DoF index 7 "):
        frf_direct(K, M, w, [0], [1, 7])
    with pytest.raises(ValueError, match="out_dofs: DoF index -1 "):
        frf_modal(lam, phi, w, [-1], [0])
    with pytest.raises(ValueError, match="non-negative"):
        frf_direct(K, M, np.array([-5.0, 10.0]), [0], [0])
    with pytest.raises(ValueError, match="1-D"):
        frf_modal(lam, phi, 10.0, [0], [0])
    with pytest.raises(ValueError, match=r"one ratio per mode \(6,\)"):
        frf_modal(lam, phi, w, [0], [0], zeta=np.full(5, 0.01))
    with pytest.raises(ValueError, match="not both"):
        frf_modal(lam, phi, w, [0], [0], zeta=0.01, mu=1.0)
    with pytest.raises(ValueError, match="shape"):
        frf_direct(K, M[:5, :5], w, [0], [0])
    with pytest.raises(ValueError, match="D has shape"):
        frf_direct(K, M, w, [0], [0], D=np.eye(3))
    with pytest.raises(ValueError, match="phi"):
        frf_modal(lam[:5], phi, w, [0], [0])
    with pytest.raises(ValueError, match="eta"):
        frf_direct(K, M, w, [0], [0], eta=-0.1)
    # Traced values are checked at run time.
    with pytest.raises(RuntimeError, match="omega must be non-negative"):
        eqx.filter_jit(lambda om: frf_modal(lam, phi, om, [0], [0]))(jnp.array([-1.0, 2.0]))
