"""Monte-Carlo study of thesis §4.3 (work in progress: core procedure, chunks, resume)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from updating._montecarlo import TABLE_4_6, Runner, Study, default_study, montecarlo

EXACT = 1.0 / (1.0 + TABLE_4_6[1][1]) - 1.0  # the correction that undoes K̃_1 (−17 %)


@pytest.fixture(scope="module")
def zero_error():
    """Tree model 1 (Table 4.6), 3 modes at the 49 measured DoFs, shape and frequency errors
    of zero magnitude; one sample per chunk, one device (each device compiles its own copy)."""
    study = default_study(1, n_modes=(3,), samples=1, chunk_size=1,
                          errors=(("absolute", (0.0,)), ("frequency", (0.0,))))
    return study, Runner(study, devices=jax.devices()[:1])


def test_zero_measurement_error_recovers_the_modelling_error(zero_error, tmp_path):
    study, runner = zero_error
    seen = []
    result = montecarlo(study, runner=runner, out=tmp_path, progress=seen.append)
    d = result.samples[3]
    assert d["alpha"].dtype == np.float64
    assert np.all(d["status"] == 0) and not d["fallback"].any()
    np.testing.assert_allclose(d["alpha"][:, 0], EXACT, atol=1e-6)  # blades 2 & 4
    np.testing.assert_allclose(d["alpha"][:, 1:], 0.0, atol=1e-6)  # untouched substructures
    np.testing.assert_allclose(result.reference[3]["alpha"][0], [EXACT, 0.0, 0.0], atol=1e-6)
    assert [p["done"] for p in seen] == [1, 2]
    # Interrupted run: one finished chunk lost; the rerun computes only that one.
    (tmp_path / "chunks" / "n03_0000001.npz").unlink()
    seen.clear()
    again = montecarlo(study, runner=runner, out=tmp_path, progress=seen.append)
    assert len(seen) == 1
    np.testing.assert_array_equal(again.samples[3]["alpha"], d["alpha"])
    stats = again.statistics()
    assert len(stats) == 2 and all(s["succeeded"] == 1 for s in stats)


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
    with pytest.raises(ValueError, match="unknown error categories"):
        Study.from_toml(tmp_path / "bad.toml")
    (tmp_path / "both.toml").write_text('[study]\nmodelling_error = 1\nerror_pids = [3]\n')
    with pytest.raises(ValueError, match="not both"):
        Study.from_toml(tmp_path / "both.toml")
    assert jnp.asarray(0.0).dtype == jnp.float64
