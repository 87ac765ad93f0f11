"""Monte-Carlo study of thesis §4.3: exact recovery, chunks and resume, sharding, the
findings of §4.3.4."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from updating.studies._montecarlo import TABLE_4_6, Runner, Study, default_study, montecarlo

EXACT = 1.0 / (1.0 + TABLE_4_6[1][1]) - 1.0  # the correction that undoes K̃_1 (−17 %)


@pytest.fixture(scope="module")
def zero_error():
    """Tree model 1 (Table 4.6), 3 modes at the 49 measured DoFs, shape and frequency errors
    of zero magnitude and one 5 % relative error; one sample per chunk, one device."""
    study = default_study(1, n_modes=(3,), samples=1, chunk_size=1,
                          errors=(("absolute", (0.0,)), ("frequency", (0.0,)), ("relative", (0.05,))))
    return study, Runner(study, devices=jax.devices()[:1])


def test_zero_measurement_error_recovers_the_modelling_error(zero_error, tmp_path):
    study, runner = zero_error
    seen = []
    result = montecarlo(study, runner=runner, out=tmp_path, progress=seen.append)
    d = result.samples[3]
    assert d["alpha"].dtype == np.float64
    assert np.all(d["status"] == 0) and not d["fallback"].any()
    np.testing.assert_allclose(d["alpha"][:2, 0], EXACT, atol=1e-6)  # blades 2 & 4
    np.testing.assert_allclose(d["alpha"][:2, 1:], 0.0, atol=1e-6)  # untouched substructures
    assert np.abs(d["alpha"][2] - d["alpha"][0]).max() > 1e-4  # the 5 % relative error moves them
    np.testing.assert_allclose(result.reference[3]["alpha"][0], [EXACT, 0.0, 0.0], atol=1e-6)
    assert [p.done for p in seen] == [1, 2, 3] and [p.detail["done"] for p in seen] == [1, 2, 3]
    # Interrupted run: one finished chunk lost; the rerun computes only that one.
    (tmp_path / "chunks" / "n03_0000001.npz").unlink()
    seen.clear()
    again = montecarlo(study, runner=runner, out=tmp_path, progress=seen.append)
    assert len(seen) == 1
    np.testing.assert_array_equal(again.samples[3]["alpha"], d["alpha"])
    stats = again.statistics()
    assert len(stats) == 3 and all(s["succeeded"] == 1 for s in stats)


def test_samples_sharded_over_four_devices_equal_one_device(zero_error):
    """The sample axis sharded over the 4 forced host devices (3 samples padded to 4),
    and with 2 samples per device updated together under vmap (padded to 8)."""
    study, one = zero_error
    assert len(jax.devices()) == 4
    single = one.chunk(3, 0, 3)
    for runner in (Runner(study), Runner(dataclasses.replace(study, lockstep=2))):
        sharded = runner.chunk(3, 0, 3)
        np.testing.assert_allclose(sharded["alpha"], single["alpha"], rtol=0, atol=1e-9)
        np.testing.assert_allclose(sharded["f_a"], single["f_a"], rtol=1e-12)
        np.testing.assert_array_equal(sharded["status"], single["status"])


def test_a_directory_of_another_study_is_refused(zero_error, tmp_path):
    study, _ = zero_error
    (tmp_path / "chunks").mkdir()
    (tmp_path / "study.json").write_text('{"digest": "0000"}')
    with pytest.raises(ValueError, match="different study"):
        montecarlo(study, out=tmp_path, runner=object())


def test_study_from_toml(tmp_path):
    (tmp_path / "s.toml").write_text('[study]\nmodelling_error = 3\nn_modes = [2, 10]\nsamples = 7\n'
                                     '[errors]\nrelative = [0.01, 0.05]\n')
    s = Study.from_toml(tmp_path / "s.toml")
    assert s.error_pids == (12,) and s.error_alpha == pytest.approx(0.10)
    assert s.cells == [("relative", 0.01), ("relative", 0.05)] and s.n_modes == (2, 10)
    assert len(s.chunks()) == 2 and s.chunks()[0] == (2, 0, 14)
    (tmp_path / "bad.toml").write_text('[errors]\nthermal = [0.1]\n')
    with pytest.raises(ValueError, match="errors.thermal: unknown error category"):
        Study.from_toml(tmp_path / "bad.toml")
    (tmp_path / "both.toml").write_text('[study]\nmodelling_error = 1\nerror_pids = [3]\n')
    with pytest.raises(ValueError, match="not both"):
        Study.from_toml(tmp_path / "both.toml")
    assert jnp.asarray(0.0).dtype == jnp.float64


@pytest.fixture(scope="module")
def trends():
    """Tree model 1, 3 and 10 modes, relative shape errors 1/2/4 % and 1 % frequency
    errors, 6 draws per cell (shared across magnitudes: common random numbers)."""
    study = default_study(1, n_modes=(3, 10), samples=6, chunk_size=6,
                          errors=(("relative", (0.01, 0.02, 0.04)), ("frequency", (0.01,))))
    result = montecarlo(study, runner=Runner(study, devices=jax.devices()[:1]))
    stats = {(s["n_modes"], s["category"], s["magnitude"]): s for s in result.statistics()}
    # Failures are counted per cell and left out: fits to noisy frequencies may run away
    # (3 parameters, few modes: cf. Δα ≈ 660 % in §4.3.4.1; measured 1 of 6 at n = 3 and
    # at n = 10); there the fixed preconditioner is refreshed rather than the sample
    # redone with full solves.
    failed = {k: sum(s["failed"].values()) for k, s in stats.items()}
    assert sum(failed.values()) == sum(result.failures.values())
    assert all(v == 0 for k, v in failed.items() if k[1] == "relative"), str(failed)
    assert all(v <= 2 for v in failed.values()), str(failed)
    assert result.fallbacks == 0
    return stats


def test_factor_uncertainty_grows_about_linearly_with_small_errors(trends):
    """§4.3.4.1: Δα grows with the error magnitude, nearly linearly below 5 %."""
    std = [trends[3, "relative", m]["delta_alpha"]["blades_2_4"]["std"] for m in (0.01, 0.02, 0.04)]
    assert std[0] > 1e-3
    np.testing.assert_allclose([std[1] / std[0], std[2] / std[0]], [2.0, 4.0], rtol=0.1)


def test_relative_error_uncertainty_falls_with_more_modes(trends):
    """§4.3.4.1: more modes average the relative shape errors out."""
    for m in (0.01, 0.02, 0.04):
        rms = {n: trends[n, "relative", m]["delta_alpha"]["blades_2_4"]["rms"] for n in (3, 10)}
        assert rms[10] < 0.2 * rms[3]


def test_frequency_errors_pass_into_the_frequencies_at_their_own_size(trends):
    """§4.3.5: Δf from 1 % frequency errors is of the order of 1 %; Δf from shape errors
    is much smaller."""
    rms = np.sqrt(np.mean(np.square(trends[3, "frequency", 0.01]["delta_f"]["rms"])))
    assert 0.3e-2 < rms < 3e-2
    shape = np.sqrt(np.mean(np.square(trends[3, "relative", 0.01]["delta_f"]["rms"])))
    assert shape < 0.2 * rms


def test_subspace_samples_equal_full_solves():
    """Issue 6: warm-started subspace solves give every sample's factors of the update
    with full dense eigensolves (from the initial model) within 1e-8."""
    from updating import Options
    from updating.studies._montecarlo import tree_parameters

    study = default_study(1, n_modes=(3,), samples=2, chunk_size=2, errors=(("relative", (0.05,)),),
                          parameters=tree_parameters(Options(tolerance=1e-9, max_iterations=30,
                                                             solver="gauss-newton")))
    sub = Runner(study, devices=jax.devices()[:1]).chunk(3, 0, 2)
    full = Runner(study, devices=jax.devices()[:1])
    g = full.group(3)
    f, phi = g.data(study, 0, 2)
    ref = g.update(f, phi, "dense", g.origin)
    assert np.all(sub["status"] == 0) and np.all(np.asarray(ref.converged))
    assert np.all(sub["iterations"] < np.asarray(ref.iterations))  # started from the error-free update
    np.testing.assert_allclose(sub["alpha"], np.expm1(np.asarray(ref.theta)), rtol=0, atol=1e-8)


def test_sparse_samples_sharded_over_four_devices_equal_subspace_samples():
    """Issue 16: every evaluation by the sparse solver (jaxfem.eigsh through host
    callbacks, on the 4 host devices at once) gives the factors of the dense subspace
    solves within 1e-7. (A step tolerance of 1e-9 is not reached reliably: on the tree,
    λ_max/λ_1 ≈ 8e8, the sparse modes carry relative errors of ~1e-9, so the last steps
    jitter at that level.)"""
    from updating import Options
    from updating.studies._montecarlo import tree_parameters

    study = default_study(1, n_modes=(3,), samples=2, chunk_size=2, errors=(("relative", (0.05,)),),
                          parameters=tree_parameters(Options(tolerance=1e-7, max_iterations=30,
                                                             solver="gauss-newton")))
    sub = Runner(study, devices=jax.devices()[:1]).chunk(3, 0, 2)
    sparse = Runner(dataclasses.replace(study, eigensolver="sparse")).chunk(3, 0, 2)
    assert np.all(sparse["status"] == 0)
    np.testing.assert_allclose(sparse["alpha"], sub["alpha"], rtol=0, atol=1e-7)
