"""Correlation: MAC, COMAC, MSF, cross-orthogonality, Guyan/SEREP reductions, mode pairing."""

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sl

from updating import (
    automac,
    comac,
    cross_orthogonality,
    frequency_deviation,
    guyan,
    mac,
    modal_scale_factor,
    pair_modes,
    pair_modes_masked,
    serep,
)

F_MODEL = np.array([5.0, 8.0, 9.0, 17.0, 23.0, 30.0])


def _chain(n, seed=0, massless=()):
    """Fixed-free spring-mass chain with random stiffnesses and masses."""
    rng = np.random.default_rng(seed)
    k = rng.uniform(1.0, 2.0, n) * 1e4
    m = rng.uniform(0.5, 1.5, n)
    m[list(massless)] = 0.0
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    return K, np.diag(m)


def _shapes(n_dof=20, n=8, seed=1):
    """Orthonormal shapes: the MAC between different columns is exactly 0."""
    q, _ = np.linalg.qr(np.random.default_rng(seed).standard_normal((n_dof, n)))
    return q


def _noisy(phi, level, seed):
    return phi + level * np.random.default_rng(seed).standard_normal(phi.shape)


# --- MAC and friends ------------------------------------------------------------------


def test_mac_identities():
    rng = np.random.default_rng(0)
    v = rng.standard_normal((12, 1))
    w = rng.standard_normal((12, 1))
    w = w - v * (v.T @ w) / (v.T @ v)  # orthogonal to v
    rotated = -3.0 * np.exp(0.7j) * v
    assert mac(v, v)[0, 0] == pytest.approx(1.0, abs=1e-14)
    assert mac(v, rotated)[0, 0] == pytest.approx(1.0, abs=1e-14)
    assert mac(rotated, v)[0, 0] == pytest.approx(1.0, abs=1e-14)
    assert mac(v, w)[0, 0] == pytest.approx(0.0, abs=1e-14)
    assert mac(v, rotated).dtype == jnp.float64


def test_mac_symmetry_and_range():
    rng = np.random.default_rng(1)
    a = rng.standard_normal((15, 4)) + 1j * rng.standard_normal((15, 4))
    e = rng.standard_normal((15, 6))
    m = mac(a, e)
    assert m.shape == (4, 6)
    np.testing.assert_allclose(mac(e, a), m.T, atol=1e-15)
    assert np.all((m >= 0) & (m <= 1))
    auto = automac(a)
    np.testing.assert_allclose(auto, auto.T, atol=1e-15)
    np.testing.assert_allclose(np.diag(auto), 1.0, atol=1e-14)


def test_mac_jit_vmap():
    a = _shapes(n=3)
    batch = np.stack([_noisy(a, 0.01, s) for s in range(4)])
    out = jax.jit(jax.vmap(mac, in_axes=(None, 0)))(a, batch)
    assert out.shape == (4, 3, 3)
    np.testing.assert_allclose(out[2], mac(a, batch[2]), atol=1e-15)


def test_mac_gradient_matches_finite_differences():
    a, e = _shapes(n=3, seed=2), _noisy(_shapes(n=3, seed=2), 0.3, 3)
    w = np.random.default_rng(4).standard_normal((3, 3))

    def f(x):
        return jnp.sum(w * mac(x, e))

    g = jax.grad(f)(jnp.asarray(a))
    d = np.random.default_rng(5).standard_normal(a.shape)
    h = 1e-6
    fd = (f(a + h * d) - f(a - h * d)) / (2 * h)
    assert np.all(np.isfinite(g))
    assert float(jnp.sum(g * d)) == pytest.approx(float(fd), rel=1e-7, abs=1e-10)


def test_mac_zero_vector_has_finite_gradient():
    e = _shapes(n=2)
    for a in (np.zeros((20, 2)), np.zeros((20, 2), np.complex128)):
        assert np.all(mac(a, e) == 0.0)
    g = jax.grad(lambda x: jnp.sum(mac(x, e)))(jnp.zeros((20, 2)))
    assert np.all(np.isfinite(g))


def test_comac_flags_corrupted_dof():
    K, M = _chain(15)
    _, phi = sl.eigh(K, M)
    phi_a = phi[:, :5]
    phi_e = _noisy(phi_a, 1e-3, 0) * np.array([1.0, -2.0, 5.0, 0.1, 3.0])  # any scale, any sign
    phi_e[6] *= np.array([3.0, 0.05, 2.5, 0.1, 4.0])  # e.g. a wrong sensor sensitivity per run
    c = comac(phi_a, phi_e)
    assert c.shape == (15,)
    assert int(np.argmin(c)) == 6
    assert c[6] < 0.5 and np.all(np.delete(np.asarray(c), 6) > 0.98)


def test_modal_scale_factor_recovers_scale():
    phi_a = _shapes(n=3) + 0j
    scale = np.array([2.5, -0.3, 1.2 * np.exp(0.4j)])
    np.testing.assert_allclose(modal_scale_factor(phi_a, phi_a * scale), scale, atol=1e-14)
    noisy = _noisy(phi_a.real * scale.real, 1e-3, 2)
    np.testing.assert_allclose(modal_scale_factor(phi_a.real, noisy), scale.real, atol=1e-2)


def test_frequency_deviation():
    np.testing.assert_allclose(frequency_deviation(jnp.array([9.0, 12.0]), jnp.array([10.0, 10.0])), [-0.1, 0.2])


def test_cross_orthogonality_of_exact_modes_is_identity():
    K, M = _chain(10)
    _, phi = sl.eigh(K, M)
    co = cross_orthogonality(phi[:, :6], 4.0 * phi[:, :4], M)  # scale removed by the normalisation
    assert co.shape == (6, 4)
    np.testing.assert_allclose(co, np.eye(6, 4), atol=1e-12)


# --- Reductions -----------------------------------------------------------------------


def test_guyan_frequencies_are_upper_bounds():
    K, M = _chain(12, seed=3)
    master = np.array([11, 2, 5, 8])  # order kept
    k_red, m_red = guyan(K, M, master)
    lam_full = sl.eigh(K, M, eigvals_only=True)
    lam_red = sl.eigh(np.asarray(k_red), np.asarray(m_red), eigvals_only=True)
    assert np.all(lam_red >= lam_full[:4] * (1 - 1e-12))
    assert lam_red[0] > lam_full[0] * (1 + 1e-6)
    mask = np.zeros(12, bool)
    mask[master] = True
    k_mask, _ = guyan(K, M, mask)
    perm = np.argsort(master)
    np.testing.assert_allclose(k_mask, np.asarray(k_red)[np.ix_(perm, perm)], rtol=1e-12)


def test_guyan_is_exact_for_massless_slaves():
    slaves = np.array([0, 3, 4, 7, 9])
    K, M = _chain(10, seed=4, massless=slaves)
    master = np.setdiff1d(np.arange(10), slaves)
    lam_full = sl.eigvals(K, M)  # infinite eigenvalues for the massless DoFs
    lam_full = np.sort(lam_full[np.isfinite(lam_full)].real)
    k_red, m_red = guyan(K, M, master)
    lam_red = sl.eigh(np.asarray(k_red), np.asarray(m_red), eigvals_only=True)
    np.testing.assert_allclose(lam_red, lam_full, rtol=1e-10)


def test_guyan_is_differentiable():
    K, M = _chain(8, seed=5)
    master = [1, 4, 7]
    dk = jax.jacfwd(lambda t: guyan(t * K, M, master)[0])(1.0)
    np.testing.assert_allclose(dk, guyan(K, M, master)[0], rtol=1e-10)  # K_red(tK) = t K_red(K)


def test_serep_reproduces_retained_modes():
    K, M = _chain(12, seed=6)
    lam, phi = sl.eigh(K, M)
    master = np.array([2, 5, 8, 11])
    phi_r = phi[:, :4]
    m_red = serep(phi_r, M, master)
    T = phi_r @ np.linalg.pinv(phi_r[master])
    lam_red = sl.eigh(T.T @ K @ T, np.asarray(m_red), eigvals_only=True)
    np.testing.assert_allclose(lam_red, lam[:4], rtol=1e-10)
    # Fewer modes than masters: the retained modes stay orthonormal on M_red.
    m_red3 = serep(phi[:, :3], M, master)
    np.testing.assert_allclose(cross_orthogonality(phi[master, :3], phi[master, :3], m_red3), np.eye(3), atol=1e-10)
    with pytest.raises(ValueError, match="at most 4 retained modes"):
        serep(phi[:, :5], M, master)


# --- Pairing --------------------------------------------------------------------------


def _model_and_test():
    phi = _shapes()
    return F_MODEL, phi[:, :6], phi


def test_pairing_follows_swapped_shapes():
    f_a, phi_a, _ = _model_and_test()
    order = np.array([0, 2, 1, 3, 4, 5])  # test modes 2 and 3 carry model shapes 3 and 2
    f_e = np.array([5.1, 8.4, 8.6, 17.2, 23.5, 29.0])
    phi_e = _noisy(phi_a[:, order], 0.02, 0)
    p = pair_modes(f_a, phi_a, f_e, phi_e)
    np.testing.assert_array_equal(p.test, np.arange(6))
    np.testing.assert_array_equal(p.model, order)
    assert np.all(p.mac > 0.95) and p.warnings == ()
    np.testing.assert_allclose(p.freq_dev, (f_a[order] - f_e) / f_e)
    np.testing.assert_array_equal(pair_modes(f_a, phi_a, f_e, phi_e * np.exp(0.3j)).model, order)  # complex
    row = p.table()[1]
    assert row[:4] == (2, 3, 8.4, 9.0)
    assert row[4] == pytest.approx(100 * (9.0 - 8.4) / 8.4) and row[5] == pytest.approx(p.mac[1])


def test_spurious_test_mode_is_reported():
    f_a, phi_a, phi = _model_and_test()
    f_e = np.array([5.1, 8.1, 9.1, 16.8, 20.0, 23.3])  # test mode 5 is spurious
    spurious = np.sqrt(0.4) * phi[:, 3] + np.sqrt(0.6) * phi[:, 7]  # MAC 0.40 with model mode 4
    phi_e = np.column_stack([phi_a[:, :4], spurious, phi_a[:, 4]])
    p = pair_modes(f_a, phi_a, f_e, phi_e)
    np.testing.assert_array_equal(p.test, [0, 1, 2, 3, 5])
    np.testing.assert_array_equal(p.model, [0, 1, 2, 3, 4])
    np.testing.assert_array_equal(p.unpaired_test, [4])
    np.testing.assert_array_equal(p.unpaired_model, [5])
    assert len(p.warnings) == 1
    assert re.fullmatch(r"test mode 5 \(20\.0 Hz\): best model candidate 4 MAC 0\.40 < 0\.65", p.warnings[0])
    assert p.table()[4] == (5, None, 20.0, None, None, None)


def test_test_mode_losing_its_candidate_is_reported():
    f_a, phi_a, phi = _model_and_test()
    rival = np.sqrt(0.8) * phi[:, 1] + np.sqrt(0.2) * phi[:, 7]  # MAC 0.80 with model mode 2
    f_e = np.array([5.0, 8.0, 8.2])
    p = pair_modes(f_a[:2], phi_a[:, :2], f_e, np.column_stack([phi_a[:, :2], rival]))
    np.testing.assert_array_equal(p.model, [0, 1])
    assert p.warnings == (
        "test mode 3 (8.2 Hz): admissible model candidate 2 (MAC 0.80) is paired with test mode 2 (MAC 1.00)",
    )


def test_missing_test_mode():
    f_a, phi_a, _ = _model_and_test()
    keep = [0, 1, 3, 4, 5]
    p = pair_modes(f_a, phi_a, f_a[keep] * 1.02, _noisy(phi_a[:, keep], 0.02, 1))
    np.testing.assert_array_equal(p.model, keep)
    np.testing.assert_array_equal(p.unpaired_model, [2])
    assert p.unpaired_test.size == 0 and p.warnings == ()


def _crossing_model(theta):
    """K = Q diag(k) Qᵀ, M = I: modes are Q's columns; the first two swap as θ passes 1."""
    q = _shapes(n_dof=6, n=6, seed=7)
    k = (2 * np.pi) ** 2 * np.array([10.0 * theta, 10.5, 14.0, 18.0, 25.0, 31.0]) ** 2
    lam, phi = sl.eigh(q @ np.diag(k) @ q.T)
    return np.sqrt(lam) / (2 * np.pi), phi, q


def test_pairing_survives_mode_crossing():
    _, _, q = _crossing_model(1.0)
    f_e, phi_e = np.array([10.0, 10.5, 14.0, 18.0]), q[:, :4]
    for theta, expected in ((0.95, [0, 1, 2, 3]), (1.1, [1, 0, 2, 3])):
        f_a, phi_a, _ = _crossing_model(theta)
        assert np.all(np.diff(f_a) > 0)
        p = pair_modes(f_a, phi_a, f_e, phi_e)
        np.testing.assert_array_equal(p.model, expected)
        index, paired = pair_modes_masked(f_a, phi_a, f_e, phi_e)
        np.testing.assert_array_equal(index, expected)
        assert np.all(paired)


def test_thresholds_are_respected():
    phi = _shapes()
    phi_a = phi[:, :1]
    phi_e = np.sqrt(0.6) * phi[:, :1] + np.sqrt(0.4) * phi[:, 1:2]  # MAC 0.6
    f_a, f_e = np.array([10.0]), np.array([10.0])
    assert mac(phi_a, phi_e)[0, 0] == pytest.approx(0.6)
    assert pair_modes(f_a, phi_a, f_e, phi_e).test.size == 0
    assert pair_modes(f_a, phi_a, f_e, phi_e, min_mac=0.55).test.size == 1
    assert not pair_modes_masked(f_a, phi_a, f_e, phi_e)[1][0]
    assert pair_modes_masked(f_a, phi_a, f_e, phi_e, min_mac=0.55)[1][0]
    for f_model, ok in ((12.9, True), (13.1, False), (7.1, True), (6.9, False)):
        p = pair_modes(np.array([f_model]), phi_a, f_e, phi_a)
        assert (p.test.size == 1) is ok
        assert bool(pair_modes_masked(np.array([f_model]), phi_a, f_e, phi_a)[1][0]) is ok
    assert "Δf +31.0 % outside ±30 %" in pair_modes(np.array([13.1]), phi_a, f_e, phi_a).warnings[0]
    with pytest.raises(ValueError, match="min_mac"):
        pair_modes(f_a, phi_a, f_e, phi_e, min_mac=1.5)


@pytest.mark.parametrize("seed", range(5))
def test_greedy_masked_agrees_with_hungarian(seed):
    rng = np.random.default_rng(seed)
    f_a, phi_a, phi = _model_and_test()
    src = rng.permutation(np.r_[rng.choice(6, 4, replace=False), 7])  # 4 true modes and 1 spurious
    f_e = np.where(src < 6, F_MODEL[np.minimum(src, 5)], 15.0) * rng.uniform(0.9, 1.1, 5)
    phi_e = _noisy(phi[:, src], 0.03, seed)
    p = pair_modes(f_a, phi_a, f_e, phi_e)
    index, paired = jax.jit(pair_modes_masked)(f_a, phi_a, f_e, phi_e)
    expected = np.full(5, -1)
    expected[p.test] = p.model
    np.testing.assert_array_equal(index, expected)
    np.testing.assert_array_equal(paired, expected >= 0)
    np.testing.assert_array_equal(p.unpaired_test, np.flatnonzero(src == 7))


def test_masked_pairing_jit_vmap_batch(key):
    f_a, phi_a, _ = _model_and_test()
    order = np.array([0, 2, 1, 3, 4])
    k1, k2 = jax.random.split(key)
    phi_e = phi_a[:, order] + 0.02 * jax.random.normal(k1, (8, 20, 5))
    f_e = F_MODEL[order] * (1 + 0.02 * jax.random.normal(k2, (8, 5)))
    batch = lambda x: jnp.broadcast_to(x, (8,) + x.shape)  # noqa: E731
    index, paired = jax.jit(jax.vmap(pair_modes_masked))(batch(f_a), batch(phi_a), f_e, phi_e)
    assert index.shape == (8, 5) and index.dtype == jnp.int32
    np.testing.assert_array_equal(index, np.broadcast_to(order, (8, 5)))
    assert np.all(paired)


def test_pairing_rejects_bad_shapes():
    f_a, phi_a, _ = _model_and_test()
    with pytest.raises(ValueError, match="f_e must have shape"):
        pair_modes(f_a, phi_a, f_a[:3], phi_a)
    with pytest.raises(ValueError, match="share the DoFs"):
        pair_modes_masked(f_a, phi_a, f_a, phi_a[:10])


# --- The correlation workflow (updating.correlate) ---------------------------------------


def test_correlate_returns_typed_result_and_the_cli_json(tmp_path):
    """``updating.correlate`` on a small frame against its own modes, shifted in frequency
    and with noisy shapes: typed attributes, and ``to_json()`` is what ``jaxfem correlate
    --json`` writes."""
    import dataclasses
    import json

    from typer.testing import CliRunner

    import jaxfem
    import updating
    from benchmarks.frames import frame_bdf
    from identification import (
        ModalData,
        Pairing,
        Sensors,
        map_test_geometry,
        observation_matrix,
        read_uff,
        write_uff,
    )
    from jaxfem.io import read_bdf
    from updating.cli import app

    bdf, uff, out = tmp_path / "frame.bdf", tmp_path / "test.uff", tmp_path / "correlate.json"
    bdf.write_text(frame_bdf(2, 2, 2, n_groups=2))
    model = jaxfem.build_model(read_bdf(bdf))
    free = np.asarray([g for g in np.asarray(model.node_ids).tolist() if g > 4])  # above the clamped base
    sensors = Sensors.from_components(np.repeat(free, 2), np.tile([1, 2], free.size))
    lam, phi = jaxfem.eigh(*jaxfem.assemble(model), 5)
    shapes = observation_matrix(model, sensors)[0] @ np.asarray(phi)
    shapes = shapes + 0.01 * np.abs(shapes).max(axis=0) * np.random.default_rng(3).standard_normal(shapes.shape)
    test = ModalData(np.asarray(jaxfem.frequencies_hz(lam)) * np.array([1.02, 0.97, 1.05, 1.0, 0.99]), shapes, sensors)
    write_uff(uff, nodes={int(g): np.asarray(x) for g, x in zip(model.node_ids, model.xyz)}, modes=test)

    cli = CliRunner().invoke(app, ["correlate", str(bdf), str(uff), "--json", str(out)])
    assert cli.exit_code == 0, cli.output

    # the library on what the CLI reads: the test nodes mapped onto the model, real modes
    content = read_uff(uff)
    mapped, gmap = map_test_geometry(model, content["nodes"], set(free.tolist()), method="auto",
                                     length_factor=content["units"]["length"])
    res = updating.correlate(mapped, gmap.apply(content["modes"].real()), model_name=str(bdf), test_name=str(uff),
                             geometry=gmap)
    assert isinstance(res, updating.CorrelationResult) and isinstance(res.pairing, Pairing)
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.max_automac = 0.5
    n_a, n_s = updating.n_model_modes(model, 5), len(sensors)
    assert res.n_model_modes == n_a and res.model_frequencies_hz.shape == (n_a,)
    assert res.model_at_sensors.shape == (n_s, n_a) and res.model_shapes.shape == (mapped.n_dof, n_a)
    assert res.test_shapes.shape == (n_s, 5) and res.sensors == tuple(sensors.labels)
    assert res.n_paired == 5 and res.warnings == () and res.pairing.min_mac == updating.Options.min_mac
    assert res.rms_freq_dev_pct == pytest.approx(100 * np.sqrt(np.mean(res.pairing.freq_dev ** 2)))
    assert res.mean_mac == pytest.approx(np.mean(res.pairing.mac)) and res.mean_mac > 0.95
    assert res.automac.shape == (5, 5) and np.allclose(np.diag(res.automac), 1.0)
    assert res.comac.shape == (n_s,) and [v for _, v in res.comac_ranking] == sorted(res.comac.tolist())
    assert isinstance(res.aliasing, tuple)
    assert json.loads(json.dumps(updating.json_safe(res.to_json()))) == json.loads(out.read_text())
    with pytest.raises(ValueError, match="max_automac"):
        updating.correlate(mapped, test, max_automac=1.5)
