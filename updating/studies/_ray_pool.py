"""Ray plumbing shared by the Monte-Carlo studies and a diagnosis' candidate fits: a worker's
CPUs pinned, jobs dispatched to actors with retries, the cluster connected, arrays that travel."""

from __future__ import annotations

import collections
import contextlib
import os
import tempfile
import warnings
from pathlib import Path

import jax
import numpy as np


def pin_cpus(num_cpus: int):
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


class RayPool:
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


@contextlib.contextmanager
def ray_cluster(address: str | None, caller: str):
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


def to_host(tree):
    """JAX arrays as NumPy: they travel as float64 (a worker reads its arguments before it
    can enable float64)."""
    return jax.tree.map(lambda x: np.asarray(x) if isinstance(x, jax.Array) else x, tree)


def to_device(tree):
    """NumPy arrays back as JAX arrays."""
    return jax.tree.map(lambda x: jax.numpy.asarray(x) if isinstance(x, np.ndarray) else x, tree)
