"""Element matrices: symmetry, rigid-body modes, closed forms, invariance, gradients, vmap."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxfem.elements import (
    beam_axes,
    beam_mass,
    beam_stiffness,
    bush_stiffness,
    conm2_mass,
    rigid_offset,
    rod_mass,
    rod_stiffness,
)

# A short, thick steel bar on a skew axis so that Φ is not negligible.
XA = np.array([0.1, -0.2, 0.3])
XB = np.array([0.4, 0.15, 0.05])
V = np.array([0.2, 0.9, 0.4])
L = float(np.linalg.norm(XB - XA))
MAT = dict(E=2.1e11, G=8.0e10)
SEC = dict(A=4.0e-3, I1=2.0e-6, I2=5.0e-6, J=6.0e-6)
RHO, NSM = 7850.0, 1.5
K1, K2 = 0.85, 0.7
WA = np.array([0.02, -0.01, 0.03])
WB = np.array([-0.015, 0.025, 0.01])


def stiffness(k1=K1, k2=K2, xa=XA, xb=XB, v=V):
    E, G = MAT["E"], MAT["G"]
    return beam_stiffness(xa, xb, v, E, G, SEC["A"], SEC["I1"], SEC["I2"], SEC["J"], k1, k2)


def mass(k1=K1, k2=K2, lumped=False, xa=XA, xb=XB, v=V):
    return beam_mass(
        xa, xb, v, RHO, SEC["A"], NSM, SEC["I1"], SEC["I2"], k1, k2, MAT["E"], MAT["G"], lumped
    )


def local(matrix, xa=XA, xb=XB, v=V):
    """Rotate a basic-axes 12×12 matrix back to element axes."""
    lam = np.kron(np.eye(4), np.asarray(beam_axes(xa, xb, v)))
    return lam @ np.asarray(matrix) @ lam.T


def rigid_modes(points):
    """(6 n, 6) rigid-body motions of grids at ``points`` (3 translations, 3 rotations)."""
    blocks = []
    for x in points:
        rot = np.array([np.cross(e, x) for e in np.eye(3)]).T  # column j: e_j × x
        blocks.append(np.block([[np.eye(3), rot], [np.zeros((3, 3)), np.eye(3)]]))
    return np.vstack(blocks)


def phi(i, k):
    return 12 * MAT["E"] * SEC[i] / (k * MAT["G"] * SEC["A"] * L**2)


def eb_bending(ei):
    """Euler–Bernoulli planar block on [v_A, θ_A, v_B, θ_B], θ = dv/dx (textbook)."""
    return 2 * ei / L**3 * np.array(
        [
            [6, 3 * L, -6, 3 * L],
            [3 * L, 2 * L**2, -3 * L, L**2],
            [-6, -3 * L, 6, -3 * L],
            [3 * L, L**2, -3 * L, 2 * L**2],
        ]
    )


P1 = np.array([1, 5, 7, 11])
P2 = np.array([2, 4, 8, 10])
FLIP = np.diag([1.0, -1.0, 1.0, -1.0])
ALL_MATRICES = {
    "beam_k_timo": lambda: stiffness(),
    "beam_k_eb": lambda: stiffness(0.0, 0.0),
    "beam_m_timo": lambda: mass(),
    "beam_m_eb": lambda: mass(0.0, 0.0),
    "beam_m_lumped": lambda: mass(lumped=True),
    "rod_k": lambda: rod_stiffness(XA, XB, MAT["E"], MAT["G"], SEC["A"], SEC["J"]),
    "rod_m": lambda: rod_mass(XA, XB, RHO, SEC["A"], NSM, False),
    "rod_m_lumped": lambda: rod_mass(XA, XB, RHO, SEC["A"], NSM, True),
    "bush": lambda: bush_stiffness(XA, XB, beam_axes(XA, XB, V), np.arange(1.0, 7.0) * 1e5, 0.3),
    "conm2": lambda: conm2_mass(2.0, WA, np.diag([0.1, 0.2, 0.3])),
    "offset": lambda: rigid_offset(WA, WB),
}


@pytest.mark.parametrize("name", sorted(ALL_MATRICES))
def test_float64(name):
    assert ALL_MATRICES[name]().dtype == jnp.float64


@pytest.mark.parametrize("name", sorted(set(ALL_MATRICES) - {"offset"}))
def test_symmetric(name):
    m = np.asarray(ALL_MATRICES[name]())
    np.testing.assert_allclose(m, m.T, rtol=0, atol=1e-12 * np.abs(m).max())


def test_beam_axes_convention():
    ax = np.asarray(beam_axes([1.0, 2.0, 3.0], [3.0, 2.0, 3.0], [0.0, 0.0, 1.0]))
    np.testing.assert_allclose(ax, [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-15)
    ax = np.asarray(beam_axes(XA, XB, V))
    np.testing.assert_allclose(ax @ ax.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(ax) == pytest.approx(1.0)
    assert abs(ax[2] @ V) < 1e-14 and ax[1] @ V > 0  # v lies in the x–y plane, on the +y side


def test_rigid_offset_kinematics():
    theta = np.array([0.3, -0.7, 0.2])
    u_grid = np.concatenate([np.zeros(3), theta, np.zeros(3), theta])
    u_end = np.asarray(rigid_offset(WA, WB)) @ u_grid
    np.testing.assert_allclose(u_end[:3], np.cross(theta, WA), atol=1e-15)
    np.testing.assert_allclose(u_end[6:9], np.cross(theta, WB), atol=1e-15)


@pytest.mark.parametrize("k1,k2", [(K1, K2), (0.0, 0.0), (K1, 0.0)])
def test_beam_stiffness_rigid_modes(k1, k2):
    k = np.asarray(stiffness(k1, k2, xa=XA + WA, xb=XB + WB))
    t = np.asarray(rigid_offset(WA, WB))
    k_grid = t.T @ k @ t
    for mat in (k, k_grid):
        lam = np.linalg.eigvalsh(mat)
        scale = np.abs(lam).max()
        assert np.sum(np.abs(lam) < 1e-9 * scale) == 6
        assert lam.min() > -1e-9 * scale
    r = rigid_modes([XA, XB])
    residual = np.linalg.norm(k_grid @ r, axis=0)
    assert np.all(residual < 1e-9 * np.linalg.norm(k_grid, 2) * np.linalg.norm(r, axis=0))


def test_beam_stiffness_euler_bernoulli_closed_form():
    E, G, A, I1, I2, J = MAT["E"], MAT["G"], SEC["A"], SEC["I1"], SEC["I2"], SEC["J"]
    k = np.zeros((12, 12))
    k[np.ix_([0, 6], [0, 6])] = E * A / L * np.array([[1, -1], [-1, 1]])
    k[np.ix_([3, 9], [3, 9])] = G * J / L * np.array([[1, -1], [-1, 1]])
    k[np.ix_(P1, P1)] = eb_bending(E * I1)
    # Plane 2 written out (θy = -dw/dx flips the coupling signs).
    a, b, c, d = 12 * E * I2 / L**3, 6 * E * I2 / L**2, 4 * E * I2 / L, 2 * E * I2 / L
    k[np.ix_(P2, P2)] = [[a, -b, -a, -b], [-b, c, b, d], [-a, b, a, b], [-b, d, b, c]]
    np.testing.assert_allclose(local(stiffness(0.0, 0.0)), k, rtol=0, atol=1e-12 * np.abs(k).max())


def test_timoshenko_tends_to_euler_bernoulli():
    k_eb = np.asarray(stiffness(0.0, 0.0))
    k_stiff = np.asarray(stiffness(1e10, 1e10))
    np.testing.assert_allclose(k_stiff, k_eb, rtol=0, atol=1e-8 * np.abs(k_eb).max())
    assert np.abs(np.asarray(stiffness()) - k_eb).max() > 1e-3 * np.abs(k_eb).max()


@pytest.mark.parametrize("plane", [1, 2])
def test_timoshenko_cantilever_tip_deflection(plane):
    """One element, end A clamped, tip load P along element y (plane 1) or z (plane 2)."""
    load = 1234.0
    ax = np.asarray(beam_axes(XA, XB, V))
    k = np.asarray(stiffness())
    f = np.concatenate([load * ax[plane], np.zeros(3)])
    u = np.linalg.solve(k[6:, 6:], f)
    inertia, kfac = (SEC["I1"], K1) if plane == 1 else (SEC["I2"], K2)
    exact = load * L**3 / (3 * MAT["E"] * inertia) + load * L / (kfac * MAT["G"] * SEC["A"])
    assert ax[plane] @ u[:3] == pytest.approx(exact, rel=1e-10)


def test_beam_mass_euler_bernoulli_closed_form():
    m_len = RHO * SEC["A"] + NSM
    hermite = m_len * L / 420 * np.array(
        [
            [156, 22 * L, 54, -13 * L],
            [22 * L, 4 * L**2, 13 * L, -3 * L**2],
            [54, 13 * L, 156, -22 * L],
            [-13 * L, -3 * L**2, -22 * L, 4 * L**2],
        ]
    )
    m = np.zeros((12, 12))
    bar = np.array([[2, 1], [1, 2]]) / 6
    m[np.ix_([0, 6], [0, 6])] = m_len * L * bar
    m[np.ix_([3, 9], [3, 9])] = RHO * (SEC["I1"] + SEC["I2"]) * L * bar
    m[np.ix_(P1, P1)] = hermite
    m[np.ix_(P2, P2)] = FLIP @ hermite @ FLIP
    np.testing.assert_allclose(local(mass(0.0, 0.0)), m, rtol=0, atol=1e-13 * np.abs(m).max())


def _timoshenko_bending_mass(inertia, p):
    """∫ (m' NvᵀNv + ρI NθᵀNθ) dx, Friedman–Kosmatka (1993) shape functions, Gauss quadrature."""
    xi, w = np.polynomial.legendre.leggauss(6)
    xi, w = (xi + 1) / 2, w / 2
    nv = np.stack([
        2 * xi**3 - 3 * xi**2 - p * xi + 1 + p,
        L * (xi**3 - (2 + p / 2) * xi**2 + (1 + p / 2) * xi),
        -2 * xi**3 + 3 * xi**2 + p * xi,
        L * (xi**3 - (1 - p / 2) * xi**2 - p / 2 * xi),
    ]) / (1 + p)
    nt = np.stack([
        6 / L * (xi**2 - xi),
        3 * xi**2 - (4 + p) * xi + 1 + p,
        -6 / L * (xi**2 - xi),
        3 * xi**2 - (2 - p) * xi,
    ]) / (1 + p)
    m_len = RHO * SEC["A"] + NSM
    return L * ((m_len * nv * w) @ nv.T + (RHO * inertia * nt * w) @ nt.T)


def test_beam_mass_timoshenko_matches_shape_function_integral():
    m = local(mass())
    ref1 = _timoshenko_bending_mass(SEC["I1"], phi("I1", K1))
    ref2 = FLIP @ _timoshenko_bending_mass(SEC["I2"], phi("I2", K2)) @ FLIP
    np.testing.assert_allclose(m[np.ix_(P1, P1)], ref1, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(m[np.ix_(P2, P2)], ref2, rtol=1e-12, atol=1e-14)
    assert np.count_nonzero(np.abs(m) > 1e-14) == 4 + 4 + 16 + 16


@pytest.mark.parametrize(
    "name", ["beam_m_timo", "beam_m_eb", "beam_m_lumped", "rod_m", "rod_m_lumped"]
)
def test_rigid_translation_mass(name):
    d = np.array([0.3, -0.5, 0.81])
    d /= np.linalg.norm(d)
    r = np.concatenate([d, np.zeros(3), d, np.zeros(3)])
    m = np.asarray(ALL_MATRICES[name]())
    assert r @ m @ r == pytest.approx((RHO * SEC["A"] + NSM) * L, rel=1e-12)


@pytest.mark.parametrize("k1,k2", [(K1, K2), (0.0, 0.0)])
def test_beam_mass_rigid_rotations(k1, k2):
    ax = np.asarray(beam_axes(XA, XB, V))
    m = np.asarray(mass(k1, k2))
    m_len = RHO * SEC["A"] + NSM
    # Rotation about the element axis: polar inertia only.
    r = np.concatenate([np.zeros(3), ax[0], np.zeros(3), ax[0]])
    assert r @ m @ r == pytest.approx(RHO * (SEC["I1"] + SEC["I2"]) * L, rel=1e-12)
    # Rotation about element z through A: m'L³/3, plus ρI1 L only for Timoshenko.
    r = np.concatenate([np.zeros(3), ax[2], L * ax[1], ax[2]])
    rotary = RHO * SEC["I1"] * L if k1 > 0 else 0.0
    assert r @ m @ r == pytest.approx(m_len * L**3 / 3 + rotary, rel=1e-12)
    assert np.linalg.eigvalsh(m).min() > 0


def test_beam_mass_lumped_pattern():
    m = np.asarray(mass(lumped=True))
    expected = np.diag(np.tile(np.r_[np.ones(3), np.zeros(3)], 2)) * (RHO * SEC["A"] + NSM) * L / 2
    np.testing.assert_allclose(m, expected, rtol=1e-14, atol=0)


def test_rotation_invariance():
    q, _ = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    for fn in (stiffness, mass):
        before = np.linalg.eigvalsh(np.asarray(fn()))
        after = np.linalg.eigvalsh(np.asarray(fn(xa=q @ XA, xb=q @ XB, v=q @ V)))
        np.testing.assert_allclose(after, before, rtol=0, atol=1e-10 * before.max())


def test_rod_stiffness_energies():
    k = np.asarray(ALL_MATRICES["rod_k"]())
    e = (XB - XA) / L
    stretch = np.concatenate([np.zeros(6), e, np.zeros(3)])
    twist = np.concatenate([np.zeros(9), e])
    assert stretch @ k @ stretch == pytest.approx(MAT["E"] * SEC["A"] / L, rel=1e-12)
    assert twist @ k @ twist == pytest.approx(MAT["G"] * SEC["J"] / L, rel=1e-12)
    assert np.linalg.matrix_rank(k) == 2
    assert np.abs(k @ rigid_modes([XA, XB])).max() < 1e-9 * np.abs(k).max()


def test_bush_coincident_grids():
    ax = np.asarray(beam_axes(XA, XB, V))
    k = np.arange(1.0, 7.0) * 1e5
    zero = np.zeros((3, 3))
    kb = np.block([[ax.T @ np.diag(k[:3]) @ ax, zero], [zero, ax.T @ np.diag(k[3:]) @ ax]])
    expected = np.block([[kb, -kb], [-kb, kb]])
    actual = bush_stiffness(XA, XA, ax, k, 0.5)
    np.testing.assert_allclose(actual, expected, rtol=0, atol=1e-9 * k.max())


def test_bush_offsets():
    ax = np.asarray(beam_axes(XA, XB, V))
    k = np.arange(1.0, 7.0) * 1e5
    s = 0.3
    kg = np.asarray(bush_stiffness(XA, XB, ax, k, s))
    r = rigid_modes([XA, XB])
    assert np.abs(kg @ r).max() < 1e-9 * np.abs(kg).max() * np.abs(r).max()
    # Translate grid B only: the spring sees the same relative translation.
    d = np.array([1e-3, -2e-3, 0.5e-3])
    u = np.concatenate([np.zeros(6), d, np.zeros(3)])
    assert u @ kg @ u == pytest.approx(np.sum(k[:3] * (ax @ d) ** 2), rel=1e-12)
    # Rotate grid B only: relative rotation θ plus relative translation θ × (p - xB).
    theta = np.array([0.01, 0.02, -0.015])
    p = XA + s * (XB - XA)
    u = np.concatenate([np.zeros(9), theta])
    rel = np.cross(theta, p - XB)
    energy = np.sum(k[:3] * (ax @ rel) ** 2) + np.sum(k[3:] * (ax @ theta) ** 2)
    assert u @ kg @ u == pytest.approx(energy, rel=1e-12)


def test_conm2_kinetic_energy():
    m = 3.2
    x = np.array([0.3, -0.2, 0.5])
    i11, i22, i33, i21, i31, i32 = 0.4, 0.5, 0.6, 0.05, -0.03, 0.02
    inertia = np.array([[i11, -i21, -i31], [-i21, i22, -i32], [-i31, -i32, i33]])
    mm = np.asarray(conm2_mass(m, x, inertia))
    theta = np.array([0.7, -0.4, 1.1])
    t = np.array([0.2, 0.1, -0.3])
    spin = theta @ inertia @ theta
    u = np.concatenate([np.zeros(3), theta])
    assert u @ mm @ u == pytest.approx(m * np.sum(np.cross(theta, x) ** 2) + spin, rel=1e-13)
    u = np.concatenate([t, theta])
    assert u @ mm @ u == pytest.approx(m * np.sum((t + np.cross(theta, x)) ** 2) + spin, rel=1e-13)


def _objective(fn, weights):
    def f(E, A, I1, K1_):
        return jnp.sum(weights * fn(E, A, I1, K1_))

    return f


@pytest.mark.parametrize("k1", [K1, 0.0])
@pytest.mark.parametrize("kind", ["stiffness", "mass"])
def test_gradients_match_finite_differences(kind, k1):
    weights = np.random.default_rng(1).normal(size=(12, 12))
    if kind == "stiffness":
        def fn(E, A, I1, K1_):
            return beam_stiffness(XA, XB, V, E, MAT["G"], A, I1, SEC["I2"], SEC["J"], K1_, K2)
    else:
        def fn(E, A, I1, K1_):
            return beam_mass(XA, XB, V, RHO, A, NSM, I1, SEC["I2"], K1_, K2, E, MAT["G"], False)
    f = _objective(fn, weights)
    x0 = np.array([MAT["E"], SEC["A"], 2e-5, k1])  # thick section: Φ1 ≈ 0.7 for K1 > 0
    grads = np.asarray(jax.grad(f, argnums=(0, 1, 2, 3))(*x0))
    assert np.all(np.isfinite(grads))
    for i in range(3 if k1 == 0.0 else 4):
        h = 1e-5 * x0[i]
        up, dn = x0.copy(), x0.copy()
        up[i] += h
        dn[i] -= h
        fd = (f(*up) - f(*dn)) / (2 * h)
        assert grads[i] == pytest.approx(float(fd), rel=1e-6)


def _random_batch(n=5):
    rng = np.random.default_rng(2)
    xa = rng.normal(size=(n, 3))
    xb = xa + rng.normal(size=(n, 3))
    v = rng.normal(size=(n, 3))
    k1 = np.array([0.0, 0.8, 0.0, 0.6, 0.9])  # mixed Euler–Bernoulli / Timoshenko batch

    def pos(lo, hi):
        return rng.uniform(lo, hi, size=n)

    return dict(
        xa=xa, xb=xb, v=v, E=pos(1e11, 2e11), G=pos(5e10, 8e10), A=pos(1e-3, 5e-3),
        I1=pos(1e-6, 1e-5), I2=pos(1e-6, 1e-5), J=pos(1e-6, 1e-5), K1=k1, K2=k1[::-1],
        rho=pos(2e3, 8e3), nsm=pos(0, 2), k=rng.uniform(1e4, 1e6, size=(n, 6)), s=pos(0, 1),
        axes=np.stack([np.asarray(beam_axes(a, b, c)) for a, b, c in zip(xa, xb, v)]),
        m=pos(1, 5), inertia=np.eye(3) * pos(0.1, 1)[:, None, None],
    )


VMAP_CASES = {
    "beam_stiffness": (
        beam_stiffness,
        ["xa", "xb", "v", "E", "G", "A", "I1", "I2", "J", "K1", "K2"],
    ),
    "beam_mass": (
        functools.partial(beam_mass, lumped=False),
        ["xa", "xb", "v", "rho", "A", "nsm", "I1", "I2", "K1", "K2", "E", "G"],
    ),
    "beam_mass_lumped": (
        functools.partial(beam_mass, lumped=True),
        ["xa", "xb", "v", "rho", "A", "nsm", "I1", "I2", "K1", "K2", "E", "G"],
    ),
    "rod_stiffness": (rod_stiffness, ["xa", "xb", "E", "G", "A", "J"]),
    "rod_mass": (functools.partial(rod_mass, lumped=False), ["xa", "xb", "rho", "A", "nsm"]),
    "bush_stiffness": (bush_stiffness, ["xa", "xb", "axes", "k", "s"]),
    "conm2_mass": (conm2_mass, ["m", "xa", "inertia"]),
}


@pytest.mark.parametrize("name", sorted(VMAP_CASES))
def test_vmap_equals_loop(name):
    fn, keys = VMAP_CASES[name]
    batch = _random_batch()
    args = [batch[key] for key in keys]
    batched = np.asarray(jax.jit(jax.vmap(fn))(*args))
    looped = np.stack([np.asarray(fn(*[a[i] for a in args])) for i in range(5)])
    assert np.all(np.isfinite(batched))
    np.testing.assert_allclose(batched, looped, rtol=1e-12, atol=1e-12 * np.abs(looped).max())
