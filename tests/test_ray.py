"""A Monte-Carlo study's chunks and a diagnosis' candidate fits on a local Ray cluster
(updating.studies._ray, updating.diagnosis._ray_fits)."""

import functools
import os
import sys

import jax
import numpy as np
import pytest
import ray

from test_reduced import case, joint  # noqa: F401 (fixtures)
from updating._eigensolvers import Direct
from updating.diagnosis._fit import candidate_fit
from updating.studies._montecarlo import Runner, default_study, montecarlo
from updating.diagnosis._ray_fits import fit_candidates_ray
from updating.studies._ray import montecarlo_ray

# Ray starts its processes with fork + exec (subprocess); JAX warns at every fork once its
# backend runs (other tests of this xdist worker may have started it). Exec'd children
# share no threads with this process.
pytestmark = pytest.mark.filterwarnings(r"ignore:os\.fork\(\) was called:RuntimeWarning")


class DiesOnce(Runner):
    """A worker's runner whose process dies on its first chunk while ``marker`` exists
    (removing it first, so exactly one worker dies and its retry succeeds)."""

    def __init__(self, study, devices=None, *, marker):
        super().__init__(study, devices)
        self.marker = marker

    def chunk(self, n, start, stop):
        try:
            self.marker.unlink()
        except FileNotFoundError:
            return super().chunk(n, start, stop)
        os._exit(1)


@pytest.fixture(scope="module")
def cores():
    """A local cluster of this process's cores; workers import this module by value (it
    is not on their path)."""
    cores = len(os.sched_getaffinity(0))
    ray.init(num_cpus=cores, include_dashboard=False, log_to_driver=False)
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
    yield cores
    ray.shutdown()


# One test compiles: pytest-xdist (-n 2) may send this module's tests to both its
# processes, each then starting a local cluster (they coexist; the other tests are cheap).
def test_chunks_on_ray_equal_one_process_and_survive_a_lost_worker(cores, tmp_path):
    """Tree model 1, 2 modes, two chunks of one sample (5 % shape, 2 % frequency error):
    the driver's runner compiles the Ray run's reference while the worker compiles, then
    runs the one-process study. The worker dies on its first chunk; its replacement runs
    both. Equal to the last bit: same code, XLA flags, inputs and one device, and a worker
    with this process's number of cores: XLA-CPU splits some reductions by its thread
    count, and these samples end at or near the 16-iteration limit, not converged, where
    rounding shows (a worker pinned to 1 of 2 cores differed by 2e-6 relative in α)."""
    study = default_study(1, n_modes=(2,), samples=1, chunk_size=1,
                          errors=(("relative", (0.05,)), ("frequency", (0.02,))))
    driver = Runner(study, devices=jax.devices()[:1])
    (tmp_path / "marker").touch()
    seen = []
    result = montecarlo_ray(study, out=tmp_path / "out", progress=seen.append, workers=1, num_cpus=cores,
                            runner=driver,
                            runner_factory=functools.partial(DiesOnce, marker=tmp_path / "marker"))
    single = montecarlo(study, runner=driver)
    assert not (tmp_path / "marker").exists()
    assert [p.done for p in seen] == [1, 2] and seen[-1].detail["retries"] == 1 and "1 retried" in seen[-1].message
    for key, value in single.samples[2].items():
        np.testing.assert_array_equal(result.samples[2][key], value, err_msg=key)
    # Resumed from the chunk files: nothing left to run, no worker started.
    seen.clear()
    again = montecarlo_ray(study, out=tmp_path / "out", progress=seen.append, runner=driver)
    assert seen == []
    np.testing.assert_array_equal(again.samples[2]["alpha"], single.samples[2]["alpha"])


class NoReference:
    """A driver runner for a run that fails before its reference is needed."""

    def reference_update(self, n):
        return {}


def dies(study, devices):
    """A worker's runner factory whose process dies at once."""
    os._exit(1)


def test_a_chunk_whose_workers_keep_dying_fails_after_max_retries(cores):
    study = default_study(1, n_modes=(2,), samples=1, chunk_size=1, errors=(("relative", (0.05,)),))
    with pytest.raises(RuntimeError, match=r"worker lost 2 times \(max_retries=1\)"):
        montecarlo_ray(study, max_retries=1, runner=NoReference(), runner_factory=dies)


def test_without_ray_the_message_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "ray", None)
    with pytest.raises(ImportError, match=r"jaxfem\[ray\]"):
        montecarlo_ray(default_study(1))


def test_candidate_fits_on_ray_equal_one_process(cores, joint):  # noqa: F811
    """The frame's released joint fitted on the full and on the reduced model, with a scan
    and without: the same θ₀, θ and cost as fitted here (float64 on one core each)."""
    problem, fits, c, red, _ = joint
    jobs = [(0, c.ext, np.zeros(0), None, np.array([0.0, -4.6]), Direct()),
            (1, c.ext, np.zeros(0), c.scan, np.zeros(2), red)]
    remote = dict((job[0], out) for job, out in fit_candidates_ray(problem, fits.settings, jobs, workers=2))
    assert sorted(remote) == [0, 1]
    for job in jobs:
        theta0, here = candidate_fit(fits, problem, *job[1:])
        there = remote[job[0]]
        assert there[1].theta.dtype == np.float64
        np.testing.assert_allclose(there[0], theta0)
        np.testing.assert_allclose(there[1].theta, here.theta, rtol=1e-7, atol=1e-9)
        np.testing.assert_allclose(there[1].cost, here.cost, rtol=1e-7)
