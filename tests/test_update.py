"""Updating on a small 3-D frame: recovery, pairing inside the loop, noise, prediction."""

import gc
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.frames import frame_bdf
from identification import FRFData, ModalData, Sensors, observation_matrix
from jaxfem.io import read_bdf_text
from updating._parameters import Options, Parameter, ParameterSet, parameterise
from updating._prediction import frf_correlation, predict_frf
from updating import Noise, parameter_std, simulate_test
from updating._solve import build_problem, update

TRUE_ALPHA = np.array([0.15, -0.10, 0.08, -0.05])


@pytest.fixture(scope="module")
def setup():
    model = jaxfem.build_model(read_bdf_text(frame_bdf(3, 3, 3, n_groups=6), name="frame"))
    params = (Parameter("cols_a", "stiffness", pids=(1, 2)), Parameter("beams_b", "stiffness", pids=(3, 4)),
              Parameter("box_E", "E", pids=(6,)), Parameter("floor_mass", "m", nodes=(14, 23)))
    base, par = parameterise(model, params)
    truth = par.apply(base, jnp.log1p(jnp.asarray(TRUE_ALPHA)))
    free = model.node_ids[(model.node_ids > 9) & (model.node_ids < 900000)]
    sensors = Sensors.from_components(np.repeat(free[::2], 2), np.tile([1, 2], len(free[::2])))
    measured = simulate_test(truth, sensors, 12)
    return model, params, truth, measured.frequencies_hz, measured.shapes, sensors


def _update(model, params, test, **options):
    return update(model, test, ParameterSet(params, Options(**{"tolerance": 1e-9, **options})))


def test_recovers_factors_with_shuffled_missing_and_spurious_modes(setup):
    model, params, _, f, shapes, sensors = setup
    order = [3, 0, 2, 1, 5, 4, 7, 6, 9, 8]  # out of order; mode 11 (index 10) missing
    f_test = np.append(f[order], 1.5 * f[-1])  # plus a spurious mode far above the model's
    rng = np.random.default_rng(0)
    spurious = rng.standard_normal(shapes.shape[0])
    test = ModalData(f_test, np.column_stack([shapes[:, order], spurious]), sensors)
    res = _update(model, params, test)
    assert res.converged
    np.testing.assert_allclose(res.alpha, TRUE_ALPHA, rtol=1e-6)
    pairs = dict(zip(res.after.test.tolist(), res.after.model.tolist()))
    assert all(pairs[j] == order[j] for j in range(10))  # pairing follows the shapes
    assert 10 in res.after.unpaired_test.tolist()  # the spurious mode is reported, not fitted
    assert any("test mode 11" in w for w in res.after.warnings)
    dev = res.history[-1].freq_dev[:10]
    assert np.max(np.abs(dev)) < 1e-8
    assert np.isnan(res.history[-1].freq_dev[10])


def test_pairing_survives_mode_crossing():
    """Two separate cantilever columns; the true errors swap the order of their modes."""
    lines = ["PARAM,COUPMASS,1", "MAT1,1,7.e10,,0.33,2700.",
             "PBAR,1,1,4.e-4,1.0e-8,2.0e-8,1.e-8", "PBAR,2,1,4.e-4,1.03e-8,2.06e-8,1.e-8"]
    for c, x in ((0, 0.0), (1, 1.0)):
        lines += [f"GRID,{100 * c + i + 1},,{x},0.,{0.1 * i}" for i in range(11)]
        lines += [f"CBAR,{100 * c + i + 1},{c + 1},{100 * c + i + 1},{100 * c + i + 2},1.,0.,0."
                  for i in range(10)]
        lines.append(f"SPC1,1,123456,{100 * c + 1}")
    model = jaxfem.build_model(read_bdf_text("\n".join(lines)))
    params = (Parameter("col1", "stiffness", pids=(1,)), Parameter("col2", "stiffness", pids=(2,)))
    base, par = parameterise(model, params)
    alpha = np.array([0.12, -0.08])
    truth = par.apply(base, jnp.log1p(jnp.asarray(alpha)))
    sensors = Sensors.from_components(np.repeat([5, 8, 11, 105, 108, 111], 2), np.tile([1, 2], 6))
    C, _ = observation_matrix(model, sensors)
    lam_t, phi_t = jaxfem.eigh(*jaxfem.assemble(truth), 6)
    test = ModalData(np.asarray(jaxfem.frequencies_hz(lam_t)), np.asarray(C @ phi_t), sensors)
    res = _update(model, params, test)
    np.testing.assert_allclose(res.alpha, alpha, rtol=1e-6)
    # Nominal: column 1's first mode comes first; in the test it comes second.
    assert res.before.model.tolist() != res.before.test.tolist()
    assert res.after.model.tolist() == list(range(6))
    assert np.max(np.abs(res.after.freq_dev)) < 1e-8


def test_noise_within_derived_tolerance(setup):
    """1 % relative shape noise and 0.2 % frequency noise.

    Tolerance from first-order propagation (``updating.parameter_std``): with the weighted
    residual Jacobian J at the truth and the residual noise covariance Σ (frequency noise
    σ_f gives σ_λ/λ = 2σ_f on the eigenvalue rows times their weights; a relative shape
    error σ_φ on component i gives σ_φ|φ_e,i|/‖φ_e‖ on the eigenvector rows),
    Cov θ = J⁺ Σ J⁺ᵀ and σ_α = e^θ σ_θ; each factor must lie within 5σ of the truth.
    """
    model, params, truth, f, shapes, sensors = setup
    noise = Noise(frequency=0.002, relative=0.01)  # σ 0.2 % on the frequencies: 0.4 % on λ
    test = simulate_test(truth, sensors, 10, noise, jax.random.key(1))
    pset = ParameterSet(params, Options(tolerance=1e-8))
    res = update(model, test, pset)
    problem = build_problem(model, ModalData(f[:10], shapes[:, :10], sensors), pset)
    theta = jnp.log1p(jnp.asarray(TRUE_ALPHA))
    sigma = parameter_std(problem, theta, noise)
    err = np.abs(res.alpha - TRUE_ALPHA)
    assert np.all(err <= 5 * sigma), (err, sigma)
    assert np.all(sigma < 0.05)  # the tolerance is meaningful, not vacuous


def test_passive_modes_and_frf_prediction_improve(setup):
    model, params, truth, f, shapes, sensors = setup
    test = ModalData(f[:10], shapes[:, :10], sensors)
    opts = dict(active_modes=tuple(range(1, 7)), passive_modes=tuple(range(7, 11)))
    res = _update(model, params, test, **opts)
    np.testing.assert_allclose(res.alpha, TRUE_ALPHA, rtol=1e-5)
    before = {t: d for t, d in zip(res.before.test, res.before.freq_dev)}
    after = {t: d for t, d in zip(res.after.test, res.after.freq_dev)}
    for passive in range(6, 10):
        assert abs(after[passive]) < 1e-6 < abs(before[passive])
    out = Sensors.from_components([14, 27], [1, 2])
    inp = Sensors.from_components([27], [2])
    freqs = np.linspace(5.0, 60.0, 120)
    measured = FRFData(freqs, np.zeros((120, 2, 1)), out, inp, "receptance")
    measured = FRFData(freqs, predict_frf(truth, measured, zeta=0.02), out, inp, "receptance")
    frac_before = frf_correlation(measured.values, predict_frf(model, measured, zeta=0.02))["frac"]
    frac_after = frf_correlation(measured.values, predict_frf(res.model, measured, zeta=0.02))["frac"]
    assert np.all(frac_after > 1 - 1e-8) and np.all(frac_before < 0.99)


def test_predict_frf_equals_direct_solve(setup):
    model = setup[0]
    out = Sensors.from_components([14], [1])
    inp = Sensors.from_components([27], [2])
    freqs = np.array([3.0, 17.0, 41.0])
    probe = FRFData(freqs, np.zeros((3, 1, 1)), out, inp, "accelerance")
    K, M = jaxfem.assemble(model)
    C_out, _ = observation_matrix(model, out)
    C_in, _ = observation_matrix(model, inp)
    i, j = int(np.argmax(C_out[0])), int(np.argmax(C_in[0]))
    direct = np.asarray(jaxfem.frf_direct(K.todense(), M.todense(), 2 * np.pi * freqs, [i], [j]))
    np.testing.assert_allclose(predict_frf(model, probe, zeta=0.0), -((2 * np.pi * freqs) ** 2)[:, None, None] * direct,
                               rtol=1e-8)


def _memory_maps() -> int:
    with open("/proc/self/maps") as f:
        return sum(1 for _ in f)


@pytest.mark.skipif(not os.path.exists("/proc/self/maps"), reason="counts Linux memory maps")
def test_updates_release_their_compiled_code(setup):
    """Every update compiles for its own problem; XLA-CPU maps each kernel separately, and
    code kept for the whole process crashes it past vm.max_map_count (65530 maps)."""
    model, params, _, f, shapes, sensors = setup
    test = ModalData(f[:6], shapes[:, :6], sensors)
    _update(model, params[:1], test, max_iterations=2)
    gc.collect()
    before = _memory_maps()
    for _ in range(2):
        _update(model, params[:1], test, max_iterations=2)
    gc.collect()
    assert _memory_maps() - before < 60  # measured: +12 over three updates; +1100 per update when the code was kept


def test_sparse_eigensolver_gives_the_dense_update(setup):
    """Issue 16: the same update with options.eigensolver = "sparse" (shift-invert Lanczos,
    derivatives of the paired modes only) and "dense": equal factors and histories."""
    model, params, _, f, shapes, sensors = setup
    test = ModalData(f, shapes, sensors)
    dense = _update(model, params, test, eigensolver="dense")
    sparse = _update(model, params, test, eigensolver="sparse")
    assert dense.converged and sparse.converged and sparse.iterations == dense.iterations
    np.testing.assert_allclose(sparse.alpha, dense.alpha, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sparse.alpha, TRUE_ALPHA, rtol=1e-6)
    np.testing.assert_allclose([h.cost for h in sparse.history], [h.cost for h in dense.history], rtol=1e-6, atol=1e-20)
