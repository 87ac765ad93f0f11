"""A Monte-Carlo study (:mod:`updating._montecarlo`) and a diagnosis' candidate fits
(:func:`updating.diagnose`, ``DiagnoseOptions.ray``) run on a Ray cluster.

Each chunk ``(n, start, stop)`` is a call on a Ray actor: one worker process that pins
its CPUs, runs float64 on one JAX device and keeps one :class:`Runner` (its compiled
n-mode groups) for all the chunks it is given. Chunks come back as they finish and go
through the same collection as :func:`updating._montecarlo.montecarlo` (incremental
files, resume, progress); the sample keys do not depend on where a chunk ran, so the
result equals that of one process with as many cores as a worker (XLA-CPU splits some
reductions by its thread count). A chunk whose worker process or node is lost is run
again on a new worker (``max_retries`` times at most), and the retries are counted.

A diagnosis' shortlisted candidates are fitted the same way (:func:`fit_candidates_ray`):
each worker holds one compiled fit of the diagnosis' problem and takes a candidate at a
time (its masks, start, scan grid and reduced basis travel with it); a candidate whose
worker is lost is fitted again elsewhere. For many hosts the same call takes the
cluster's address: the driver keeps the problem, the bases and the ranking, the workers
only fit, so the traffic is one problem per worker and one basis per candidate.
"""

from __future__ import annotations

import collections
import contextlib
import os
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path

import jax
import numpy as np

from ._evidence import Fits, candidate_fit
from ._montecarlo import Progress, Runner, _collect, _Store
from ._study import MonteCarloResult, Study


def _pin(num_cpus: int):
    """Restrict this process to a block of ``num_cpus`` of its node's cores that no other
    worker holds. XLA-CPU sizes its thread pool by the process's CPU affinity (measured:
    ``XLA_FLAGS`` thread options and ``OMP_NUM_THREADS`` left it at all cores). A block is
    claimed by a lock on a file in the node's temporary directory, which the system
    releases when the process dies. Returns the lock's descriptor, or None where every
    block is held (more workers than cores: left to the scheduler) or off Linux."""
    if not hasattr(os, "sched_setaffinity"):
        return None
    import fcntl

    cpus = sorted(os.sched_getaffinity(0))
    for k in range(len(cpus) // num_cpus):
        block = cpus[k * num_cpus:(k + 1) * num_cpus]
        lock = os.open(Path(tempfile.gettempdir()) / f"jaxfem-ray-cpu{block[0]}.lock", os.O_CREAT | os.O_RDWR)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(lock)
            continue
        os.sched_setaffinity(0, block)
        return lock
    return None


class _Worker:
    """The Ray actor of a Monte-Carlo study: CPUs pinned and float64 before JAX starts its
    backend, one device, one runner for all its chunks."""

    def __init__(self, study: Study, runner_factory, num_cpus: int):
        self._lock = _pin(num_cpus)
        jax.config.update("jax_enable_x64", True)
        self.runner = runner_factory(study, devices=jax.devices()[:1])

    def run(self, chunk: tuple) -> dict:
        return self.runner.chunk(*chunk)


class _Pool:
    """Jobs dispatched to actors (``worker(*args)``, ``.run(job)``), one at a time each: an
    idle actor takes the next job of the group (``job[0]``: a chunk's n-mode group) it has
    compiled, else of the group with most jobs waiting; an actor with nothing left is
    released at once (its CPUs free a replacement's place)."""

    def __init__(self, ray, worker, args: tuple, num_cpus: int, workers: int, max_retries: int):
        self.ray = ray
        self.actor = ray.remote(worker).options(num_cpus=num_cpus, max_restarts=0, max_task_retries=0)
        self.args = args
        self.workers, self.max_retries = workers, max_retries
        self.queue: list = []
        self.idle: list = []  # (actor, n of its last chunk)
        self.running: dict = {}  # ObjectRef -> (chunk, actor)
        self.failures: collections.Counter = collections.Counter()
        self.retries = 0

    def start(self, todo: list) -> None:
        self.queue = list(todo)
        self.idle = [(self.actor.remote(*self.args), None) for _ in range(min(self.workers, len(todo)))]
        self._dispatch()

    def _dispatch(self) -> None:
        while self.idle and self.queue:
            actor, n = self.idle.pop()
            waiting = collections.Counter(c[0] for c in self.queue)
            group = n if n in waiting else max(waiting, key=waiting.get)
            chunk = next(c for c in self.queue if c[0] == group)
            self.queue.remove(chunk)
            self.running[actor.run.remote(chunk)] = (chunk, actor)
        if not self.queue:
            for actor, _ in self.idle:
                self.ray.kill(actor)
            self.idle.clear()

    def results(self):
        """Yield ``(job, data)`` as jobs finish; a job whose worker was lost is queued
        again and a new worker started in its place."""
        while self.running:
            [ref], _ = self.ray.wait(list(self.running), num_returns=1)
            chunk, actor = self.running.pop(ref)
            try:
                data = self.ray.get(ref)
            except self.ray.exceptions.RayActorError as err:  # the process or its node died
                self.failures[id(chunk)] += 1
                if self.failures[id(chunk)] > self.max_retries:
                    label = f"chunk {chunk}" if all(isinstance(x, int) for x in chunk) else f"candidate {chunk[0]}"
                    raise RuntimeError(f"{label}: worker lost {self.failures[id(chunk)]} times "
                                       f"(max_retries={self.max_retries}): {err}") from err
                self.retries += 1
                self.ray.kill(actor)
                self.queue.insert(0, chunk)
                self.idle.append((self.actor.remote(*self.args), None))
                self._dispatch()
                continue
            self.idle.append((actor, chunk[0]))
            self._dispatch()
            yield chunk, data

    def close(self) -> None:
        for actor in [a for a, _ in self.idle] + [a for _, a in self.running.values()]:
            self.ray.kill(actor)
        self.idle.clear()
        self.running.clear()


def montecarlo_ray(study: Study, *, address: str | None = None, out: str | Path | None = None,
                   progress: Progress | None = None, workers: int | None = None, num_cpus: int = 1,
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
    with _cluster(address, "montecarlo_ray") as ray:
        workers = workers or max(1, int(ray.cluster_resources().get("CPU", 0)) // num_cpus)
        pool = _Pool(ray, _Worker, (study, runner_factory, num_cpus), num_cpus, workers, max_retries)
        store = _Store(out, study) if out is not None else None
        # Started before the driver computes the reference; _collect's own list of chunks
        # to do is read from the same store and is the same.
        pool.start([c for c in study.chunks() if store is None or not store.path(c).exists()])
        try:
            report = progress and (lambda p: progress({**p, "retries": pool.retries}))
            return _collect(study, runner or runner_factory(study), store, report, lambda todo: pool.results())
        finally:
            pool.close()


@contextlib.contextmanager
def _cluster(address: str | None, caller: str):
    """Ray, connected to ``address`` (``"local"`` or None: a local cluster, or the one
    ``RAY_ADDRESS`` names; ``"auto"``; ``"ray://head:10001"``) unless already initialised;
    disconnected at the end if connected here."""
    try:
        import ray
    except ImportError:
        raise ImportError(f"{caller} needs Ray: pip install 'jaxfem[ray]'") from None
    connected = not ray.is_initialized()
    if connected:
        with warnings.catch_warnings():
            # Ray starts its processes by fork + exec: no JAX thread is shared with them.
            warnings.filterwarnings("ignore", r"os\.fork\(\) was called", RuntimeWarning)
            ray.init(address=None if address == "local" else address)
    try:
        yield ray
    finally:
        if connected:
            ray.shutdown()


class _FitWorker:
    """The Ray actor of a diagnosis: CPUs pinned, float64, one compiled fit of the problem
    for all its candidates."""

    def __init__(self, problem, settings, num_cpus: int):
        self._lock = _pin(num_cpus)
        jax.config.update("jax_enable_x64", True)
        self.problem, self.fits = _device(problem), Fits(_device(settings))

    def run(self, job: tuple):
        return candidate_fit(self.fits, self.problem, *_device(job[1:]))


def _host(tree):
    """JAX arrays as NumPy: they travel as float64 (a worker reads its arguments before it
    can enable float64)."""
    return jax.tree.map(lambda x: np.asarray(x) if isinstance(x, jax.Array) else x, tree)


def _device(tree):
    """NumPy arrays back as JAX arrays."""
    return jax.tree.map(lambda x: jax.numpy.asarray(x) if isinstance(x, np.ndarray) else x, tree)


def fit_candidates_ray(problem, settings, jobs: list[tuple], *, address: str | None = None,
                       workers: int | None = None, num_cpus: int = 1, max_retries: int = 3):
    """Yield ``(job, (θ₀, fit))`` of a diagnosis' candidate fits as they finish, fitted on
    Ray workers (:func:`updating._evidence.candidate_fit`; ``job = (index, ext, θ_b, scan,
    θ₀, eigensolver)``); ``address``, ``workers``, ``num_cpus``, ``max_retries`` as for
    :func:`montecarlo_ray`."""
    with _cluster(address, "diagnose --ray") as ray:
        workers = workers or max(1, int(ray.cluster_resources().get("CPU", 0)) // num_cpus)
        pool = _Pool(ray, _FitWorker, (_host(problem), _host(settings), num_cpus), num_cpus,
                     min(workers, len(jobs)), max_retries)
        pool.start([(job[0], *_host(job[1:])) for job in jobs])
        try:
            yield from pool.results()
        finally:
            pool.close()
