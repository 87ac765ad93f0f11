"""A Monte-Carlo study (:mod:`updating.studies._montecarlo`) run on a Ray cluster.

Each chunk ``(n, start, stop)`` is a call on a Ray actor: one worker process that pins
its CPUs, runs float64 on one JAX device and keeps one :class:`Runner` (its compiled
n-mode groups) for all the chunks it is given. Chunks come back as they finish and go
through the same collection as :func:`updating.studies._montecarlo.montecarlo` (incremental
files, resume, progress); the sample keys do not depend on where a chunk ran, so the
result equals that of one process with as many cores as a worker (XLA-CPU splits some
reductions by its thread count). A chunk whose worker process or node is lost is run
again on a new worker (``max_retries`` times at most), and the retries are counted.

The same plumbing (:mod:`._ray_pool`) fits a diagnosis' candidates (:mod:`updating.diagnosis._ray_fits`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import jax

from .. import ProgressFn
from ._montecarlo import ChunkStore, Runner, _collect, chunk_progress
from ._ray_pool import RayPool, pin_cpus, ray_cluster
from ._study import MonteCarloResult, Study


class _Worker:
    """The Ray actor of a Monte-Carlo study: CPUs pinned and float64 before JAX starts its
    backend, one device, one runner for all its chunks."""

    def __init__(self, study: Study, runner_factory, num_cpus: int):
        self._lock = pin_cpus(num_cpus)
        jax.config.update("jax_enable_x64", True)
        self.runner = runner_factory(study, devices=jax.devices()[:1])

    def run(self, chunk: tuple) -> dict:
        return self.runner.chunk(*chunk)


def montecarlo_ray(study: Study, *, address: str | None = None, out: str | Path | None = None,
                   progress: ProgressFn | None = None, workers: int | None = None, num_cpus: int = 1,
                   max_retries: int = 3, runner: Runner | None = None,
                   runner_factory: Callable[..., Runner] = Runner) -> MonteCarloResult:
    """Run a study's chunks on a Ray cluster; otherwise as :func:`updating.montecarlo`.

    **Arguments:** the :class:`Study`; ``address``: the cluster, for ``ray.init`` when Ray
    is not initialised yet (None: start a local one, or the one ``RAY_ADDRESS`` names;
    ``"auto"``: the cluster this node belongs to; ``"ray://head:10001"``: Ray Client, needs
    ``ray[client]``), disconnected at the end if this call connected; ``out``/``progress``:
    as for :func:`updating.montecarlo`, on the driver (progress also gets ``retries``);
    ``workers``: worker processes (default: the cluster's CPUs // ``num_cpus``, at least 1,
    at most one per chunk); ``num_cpus``: cores of each worker (Ray's resource; the worker
    is pinned to that many cores of its node and Ray sets ``OMP_NUM_THREADS`` to it);
    ``max_retries``: how many times a chunk is run again after its worker process or node
    was lost; ``runner``: the driver's runner for the error-free reference update (default
    ``runner_factory(study)``); ``runner_factory(study, devices=...)``: builds each worker's
    runner (once per worker process; the package must be installed on every node).

    **Returns:** :class:`MonteCarloResult`, equal to the last bit to that of one process
    on one device with ``num_cpus`` cores (e.g. under ``taskset -c 0`` for 1).
    """
    if num_cpus < 1 or max_retries < 0 or (workers is not None and workers < 1):
        raise ValueError("num_cpus and workers must be at least 1, max_retries at least 0")
    with ray_cluster(address, "montecarlo_ray") as ray:
        workers = workers or max(1, int(ray.cluster_resources().get("CPU", 0)) // num_cpus)
        pool = RayPool(ray, _Worker, (study, runner_factory, num_cpus), num_cpus, workers, max_retries)
        store = ChunkStore(out, study) if out is not None else None
        # Started before the driver computes the reference; _collect's own list of chunks
        # to do is read from the same store and is the same.
        pool.start([c for c in study.chunks() if store is None or not store.path(c).exists()])
        try:
            report = progress and (lambda p: progress(chunk_progress({**p, "retries": pool.retries})))
            return _collect(study, runner or runner_factory(study), store, report, lambda todo: pool.results())
        finally:
            pool.close()
