"""A diagnosis' shortlisted candidates fitted on Ray workers (``DiagnoseOptions.ray``):
each worker holds one compiled fit of the diagnosis' problem and takes a candidate at a
time (its masks, start, scan grid and reduced basis travel with it); a candidate whose
worker is lost is fitted again elsewhere. For many hosts the same call takes the
cluster's address: the driver keeps the problem, the bases and the ranking, the workers
only fit, so the traffic is one problem per worker and one basis per candidate."""

from __future__ import annotations

import jax

from ..studies import RayPool, pin_cpus, ray_cluster, to_device, to_host
from ._fit import Fits, candidate_fit


class _FitWorker:
    """The Ray actor of a diagnosis: CPUs pinned, float64, one compiled fit of the problem
    for all its candidates."""

    def __init__(self, problem, settings, num_cpus: int):
        self._lock = pin_cpus(num_cpus)
        jax.config.update("jax_enable_x64", True)
        self.problem, self.fits = to_device(problem), Fits(to_device(settings))

    def run(self, job: tuple):
        return candidate_fit(self.fits, self.problem, *to_device(job[1:]))


def fit_candidates_ray(problem, settings, jobs: list[tuple], *, address: str | None = None,
                       workers: int | None = None, num_cpus: int = 1, max_retries: int = 3):
    """Yield ``(job, (θ₀, fit))`` of a diagnosis' candidate fits as they finish, fitted on
    Ray workers (:func:`updating.diagnosis._fit.candidate_fit`; ``job = (index, ext, θ_b, scan,
    θ₀, eigensolver)``); ``address``, ``workers``, ``num_cpus``, ``max_retries`` as for
    :func:`montecarlo_ray`."""
    with ray_cluster(address, "diagnose --ray") as ray:
        workers = workers or max(1, int(ray.cluster_resources().get("CPU", 0)) // num_cpus)
        pool = RayPool(ray, _FitWorker, (to_host(problem), to_host(settings), num_cpus), num_cpus,
                     min(workers, len(jobs)), max_retries)
        pool.start([(job[0], *to_host(job[1:])) for job in jobs])
        try:
            yield from pool.results()
        finally:
            pool.close()
