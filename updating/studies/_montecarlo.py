"""Running experimental-error Monte-Carlo studies, thesis §4.3 (procedure of Fig. 4.23), batched.

The reference model gives the "measured" modes: its lowest modes at the sensors (surplus
DoFs dropped, no reduction, §4.3.3.2). The initial model is the reference with the
modelling error of Table 4.6 (K̃_0 = K_0 + α K_group). Each sample adds measurement
errors of one category and magnitude (Table 4.7, :mod:`updating._simulation`: relative
and absolute shape errors, frequency errors on λ = ω²) to the first n modes, and is
updated by the engine of :func:`updating.update` (:func:`updating._engine.run`: same
residual, weights, stopping rule), vmapped over ``lockstep`` samples; the sample axis is sharded over the JAX devices
(``shard_map``), the lockstep batches of a device run in sequence. Its eigenproblems are
solved by subspace iteration (:func:`jaxfem.subspace`) warm-started from the Ritz basis
of the error-free update (where every noisy sample starts) and then from the last
iterate, preconditioned with the error-free update's (K − σM)⁻¹ (no factorisation per
evaluation); a solve that does not converge with it (a fit running far away) is redone
with a fresh one (counted, ``refreshes``), a sample whose solve still fails is redone with
full dense solves (:func:`jaxfem.dense_modes`, counted, ``fallback``). The eigenvalue
weights (§5.2.4) are those of the error-free data.

Statistics relative to the same update without measurement error (δ = 0):
Δα = α(δ)/α(0) (eq. 4.4), Δf_n (eq. 4.5) and ΔMAC_n (eq. 4.6), per category, magnitude
and number of modes. Draw j of every cell of the n-mode group has the key
``fold_in(fold_in(key(seed), n), j)``: a result does not depend on how the study is cut
into chunks, and the cells share their random draws (common random numbers: the same
δ pattern at every magnitude of a category, so trends over the magnitude are not
masked by sampling noise; each cell's statistics stay those of independent draws).
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxfem
from identification import Sensors
from jaxfem.io import read_bdf

from .. import (
    LOCKSTEP,
    AbstractEigensolver,
    Compiled,
    Direct,
    Noise,
    Problem,
    Progress,
    ProgressFn,
    Refined,
    Settings,
    Subspace,
    build_problem,
    perturb,
    run,
    simulate_test,
)
from ._study import (
    CATEGORIES,
    TABLE_4_6,
    TABLE_4_7,
    MonteCarloResult,
    Study,
    default_study,
    tree_parameters,
)

__all__ = ["CATEGORIES", "TABLE_4_6", "TABLE_4_7", "MonteCarloResult", "Study", "default_study", "tree_parameters",
           "Runner", "montecarlo"]


# --------------------------------------------------------------------------- the batched update


@dataclasses.dataclass(frozen=True)
class _Kind:
    """How a group's samples are solved: ``subspace`` or ``dense`` (refined) eigensolves, the
    engine's settings, the shift σ and the samples per vmap batch on each device."""

    eigensolver: str
    settings: Settings
    shift: float
    lockstep: int

    def solver(self, start: _Start) -> AbstractEigensolver:
        if self.eigensolver == "dense":
            return Refined(self.shift)
        if self.eigensolver == "sparse":
            return Direct()
        return Subspace(start.inverse, self.shift, self.lockstep)


class _Outcome(eqx.Module):
    theta: jax.Array
    iterations: jax.Array
    converged: jax.Array
    change: jax.Array  # largest factor change of the last accepted step
    solved: jax.Array  # every accepted iterate's eigen solve converged
    refreshes: jax.Array  # evaluations that needed a fresh preconditioner
    paired: jax.Array
    lam_a: jax.Array
    mac: jax.Array


class _Start(eqx.Module):
    """Where updates start: factors θ, the Ritz basis there (the first warm start) and
    the fixed preconditioner (K(θ) − σM)⁻¹ of every subspace solve (:func:`jaxfem.shifted_inverse`)."""

    theta: jax.Array
    basis: jax.Array
    inverse: jax.Array


def _update_one(lam_e, phi_e, valid, problem: Problem, start: _Start, kind: _Kind) -> _Outcome:
    """One sample: the engine (:func:`updating._engine.run`) on the measured data
    (λ_e, φ_e) from ``start``; a padding sample (``valid`` False) takes no step."""
    problem = eqx.tree_at(lambda p: (p.lam_e, p.phi_e), problem, (lam_e, phi_e))
    s = run(start.theta, problem, kind.solver(start), start.basis, kind.settings, ~valid)
    ev = s.evaluation
    return _Outcome(s.theta, s.accepted, s.converged, s.change, s.solved, s.refreshes, ev.paired, ev.lam_a, ev.mac)


def _measure(key, category, magnitude, lam0, phi0):
    """One sample's measured data: the Table 4.7 error of one category (index in
    ``CATEGORIES``) and magnitude on (λ0, φ0) (:func:`updating._simulation.perturb`)."""
    noise = Noise.table_4_7(**{name: jnp.where(category == i, magnitude, 0.0) for i, name in enumerate(CATEGORIES)})
    return perturb(key, noise, lam0, phi0)


class _Group:
    """Everything one n-mode group needs: the problem, the warm start, compiled batches."""

    def __init__(self, study: Study, n: int, reference, initial, sensors: Sensors, devices):
        sparse = study.eigensolver == "sparse"
        solver = "sparse" if sparse else "dense"
        test = simulate_test(reference, sensors, n, solver=solver)
        opts = dataclasses.replace(study.parameters.options, eigensolver=solver)
        n_free = initial.n_dof - len(initial.dofs.massless)
        self.problem = build_problem(initial, test, dataclasses.replace(study.parameters, options=opts))
        n_model = self.problem.n_model
        self.f0, self.phi0 = jnp.asarray(test.frequencies_hz), jnp.asarray(test.shapes)
        q = min(n_free - (2 if sparse else 0), max(2 * n_model, n_model + 8))
        lam0, basis = jaxfem.modes(initial, q, solver=solver)
        rigid = float(lam0[0]) < 1e-6 * float(lam0[n_model - 1])
        shift = -0.01 * float(lam0[n_model - 1]) if rigid else 0.0
        self.kinds = {kind: _Kind(kind, Settings.from_options(opts), shift, study.lockstep)
                      for kind in (("sparse",) if sparse else ("subspace", "dense"))}
        # Where every update starts: the initial model, and for the noisy samples the
        # error-free update (:meth:`sample_start`); the sparse solver needs no preconditioner.
        inverse = jnp.zeros((0, 0)) if sparse else jaxfem.shifted_inverse(*jaxfem.assemble(initial), shift=shift)
        self.origin = _Start(jnp.zeros(len(self.problem.parameterisation.parameters)), basis, inverse)
        self._sample_start = None
        self._reference: dict[str, _Outcome] = {}
        self.devices = devices
        self.n = n
        mesh = jax.sharding.Mesh(np.array(devices), ("samples",))
        # Samples per compiled call: whole lockstep batches per device, about a chunk.
        per_call = len(devices) * study.lockstep
        self.batch = per_call * -(-study.chunk_size // per_call)
        self._batch = {k: Compiled(lambda l, p, v, prob, start, s=s: _sharded(l, p, v, prob, start, s, mesh))
                       for k, s in self.kinds.items()}
        self._measure = Compiled(jax.vmap(_measure, in_axes=(0, 0, 0, None, None)))

    def data(self, study: Study, start: int, stop: int):
        """Measured frequencies (Hz) and shapes of samples ``start:stop``."""
        j = np.arange(start, stop)
        cells = study.cells
        cat = np.array([CATEGORIES.index(cells[i][0]) for i in j // study.samples])
        mag = np.array([cells[i][1] for i in j // study.samples])
        base = jax.random.fold_in(jax.random.key(study.seed), self.n)
        keys = jax.vmap(lambda i: jax.random.fold_in(base, i))(jnp.asarray(j % study.samples))
        lam, phi = self._measure(keys, jnp.asarray(cat), jnp.asarray(mag), (2 * jnp.pi * self.f0) ** 2, self.phi0)
        return jaxfem.frequencies_hz(lam), phi

    def reference(self, kind: str) -> _Outcome:
        """The update of the error-free data from the initial model (one sample)."""
        if kind not in self._reference:
            self._reference[kind] = self.update(self.f0[None], self.phi0[None], kind, self.origin)
        return self._reference[kind]

    def sample_start(self, kind: str):
        """Where the noisy samples start: θ, the Ritz basis and the preconditioner of the
        error-free update (each sample is a small perturbation of it: about half the
        iterations of a start from the initial model, same converged factors), or the
        initial model if that update failed."""
        if self._sample_start is None:
            ref = self.reference(kind)
            self._sample_start = self.origin
            if bool(ref.converged[0]) and bool(np.all(ref.paired[0])) and kind == "sparse":
                self._sample_start = _Start(jnp.asarray(ref.theta[0]), self.origin.basis, self.origin.inverse)
            elif bool(ref.converged[0]) and bool(np.all(ref.paired[0])):
                theta = jnp.asarray(ref.theta[0])
                K, M = jaxfem.assemble(self.problem.model(theta))
                shift = self.kinds["subspace"].shift
                sol = jaxfem.subspace(K, M, self.origin.basis, self.problem.n_model, shift=shift)
                if bool(sol.converged):
                    self._sample_start = _Start(theta, sol.basis, jaxfem.shifted_inverse(K, M, shift=shift))
        return self._sample_start

    def update(self, f, phi, kind: str, start: _Start) -> _Outcome:
        """Update the samples (f, φ) from ``start``, sharded over the
        devices. Batches are padded to whole multiples of ``batch`` samples (padding takes
        no step), so every batch size runs the one compiled program."""
        b = f.shape[0]
        pad = -b % self.batch
        lam = (2 * jnp.pi * f) ** 2
        lam, phi = (jnp.concatenate([x, jnp.repeat(x[-1:], pad, axis=0)]) for x in (lam, phi))
        valid = jnp.arange(b + pad) < b
        out = [self._batch[kind](*(x[i:i + self.batch] for x in (lam, phi, valid)), self.problem, start)
               for i in range(0, b + pad, self.batch)]
        return jax.tree.map(lambda *x: np.concatenate([np.asarray(v) for v in x])[:b], *out)


def _sharded(lam, phi, valid, problem, start, kind: _Kind, mesh) -> _Outcome:
    """:func:`_update_one` over the samples: the sample axis sharded over the mesh's
    devices (``shard_map``); on each device ``vmap`` over ``kind.lockstep`` samples at
    a time (their loops run until the slowest is done), those batches in sequence. One
    sample is not vmapped: a vmap of one was measured 4.6× slower on XLA-CPU (tree, 10
    modes: 0.48 s against 0.10 s per sample)."""
    shared, static = eqx.partition((problem, start), eqx.is_array)
    v = kind.lockstep

    def local(lam, phi, valid, shared):
        problem, start = eqx.combine(shared, static)
        if v == 1:
            return jax.lax.map(lambda x: _update_one(*x, problem, start, kind), (lam, phi, valid))
        update = jax.vmap(lambda *x: _update_one(*x, problem, start, kind), axis_name=LOCKSTEP)
        out = jax.lax.map(lambda x: update(*x), jax.tree.map(lambda a: a.reshape(-1, v, *a.shape[1:]),
                                                            (lam, phi, valid)))
        return jax.tree.map(lambda a: a.reshape(-1, *a.shape[2:]), out)

    P = jax.sharding.PartitionSpec
    # check_vma=False: the loop carries start replicated (θ0) and become per-sample.
    return jax.shard_map(local, mesh=mesh, in_specs=(P("samples"),) * 3 + (P(),), out_specs=P("samples"),
                         check_vma=False)(lam, phi, valid, shared)


class Runner:
    """Runs chunks of a :class:`Study` in this process, compiling once per n-mode group
    (the compiled code is freed with the runner)."""

    def __init__(self, study: Study, devices=None):
        self.study = study
        self.devices = list(devices or jax.devices())
        reference = jaxfem.build_model(read_bdf(study.model))
        self.reference = reference
        self.initial = jaxfem.correct(reference, [reference.element_ids(pids=list(study.error_pids))],
                                      jnp.array([study.error_alpha]))
        self.sensors = Sensors.read_csv(study.sensors)
        self._groups: dict[int, _Group] = {}

    def group(self, n: int) -> _Group:
        if n not in self._groups:
            self._groups[n] = _Group(self.study, n, self.reference, self.initial, self.sensors, self.devices)
        return self._groups[n]

    def reference_update(self, n: int) -> dict:
        """The update with error-free data (δ = 0) of the n-mode group."""
        return _record(self.group(n).reference(self.study.eigensolver), np.asarray(self.group(n).f0)[None],
                       np.zeros(1, bool))

    def chunk(self, n: int, start: int, stop: int) -> dict:
        """Samples ``start:stop`` of the n-mode group: measured data, updated factors and
        modes, iterations, status; with fallback to full eigensolves where needed."""
        g = self.group(n)
        f, phi = g.data(self.study, start, stop)
        start = g.sample_start(self.study.eigensolver)
        out = g.update(f, phi, self.study.eigensolver, start)
        redo = ~out.solved
        if redo.any():
            full = g.update(f[redo], phi[redo], "dense", start)
            out = jax.tree.map(lambda a, b: _put(a, redo, b), out, full)
        return _record(out, np.asarray(f), redo)


def _put(a, mask, b):
    a = a.copy()
    a[mask] = b
    return a


def _record(out: _Outcome, f_e: np.ndarray, fallback: np.ndarray) -> dict:
    theta = np.asarray(out.theta)
    ok_pairs = np.all(np.asarray(out.paired), axis=1)
    status = np.where(~np.all(np.isfinite(theta), axis=1), 3,
                      np.where(~np.asarray(out.converged), 1, np.where(~ok_pairs, 2, 0)))
    f_a = np.where(out.paired, np.sqrt(np.maximum(np.asarray(out.lam_a), 0)) / (2 * np.pi), np.nan)
    return {"alpha": np.expm1(theta), "f_e": f_e, "f_a": f_a, "mac": np.where(out.paired, out.mac, np.nan),
            "iterations": np.asarray(out.iterations), "change": np.asarray(out.change),
            "status": status.astype(np.int64),
            "fallback": np.asarray(fallback, bool), "refreshes": np.asarray(out.refreshes)}


def chunk_progress(record: dict) -> Progress:
    """A study's chunk record (chunk, chunks, n_modes, done, total, rate, seconds_left,
    failed, fallbacks; ``retries`` on Ray) as a :class:`updating.Progress`."""
    r = record
    retries = f", {r['retries']} retried" if "retries" in r else ""
    return Progress(f"chunk {r['chunk']}/{r['chunks']} (n = {r['n_modes']}): {r['done']}/{r['total']} samples, "
                    f"{r['rate']:.3g} samples/s, ETA {duration(r['seconds_left'])}, {r['failed']} failed, "
                    f"{r['fallbacks']} fallbacks{retries}", r["done"], r["total"], record)


def duration(seconds: float) -> str:
    """Seconds as a person reads them ("3 min 05 s"; "–" if not finite)."""
    if not np.isfinite(seconds):
        return "–"
    minutes, s = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min" if hours else f"{minutes} min {s:02d} s" if minutes else f"{s} s"


def montecarlo(study: Study, *, out: str | Path | None = None, progress: ProgressFn | None = None,
               runner: Runner | None = None) -> MonteCarloResult:
    """Run a study in this process (samples sharded over all JAX devices).

    **Arguments:** the :class:`Study`; ``out``: a directory where every finished chunk is
    written at once (``chunks/*.npz``) and from which an interrupted run resumes;
    ``progress``: called after each chunk (:func:`chunk_progress`: samples done of the
    total, its ``detail`` the chunk record: samples per second, seconds left, failures,
    fallbacks).

    **Returns:** :class:`MonteCarloResult`.
    """
    runner = runner or Runner(study)
    store = ChunkStore(out, study) if out is not None else None
    report = progress and (lambda record: progress(chunk_progress(record)))
    return _collect(study, runner, store, report, lambda chunks: ((c, runner.chunk(*c)) for c in chunks))


class ChunkStore:
    """Finished chunks on disk: ``<out>/study.json`` and ``<out>/chunks/n<n>_<start>.npz``."""

    def __init__(self, out, study: Study):
        self.dir = Path(out)
        (self.dir / "chunks").mkdir(parents=True, exist_ok=True)
        meta = self.dir / "study.json"
        if meta.exists():
            held = json.loads(meta.read_text())
            if held.get("digest") != study.digest():
                raise ValueError(f"{self.dir} holds chunks of a different study (digest {held.get('digest')}); "
                                 "use another directory")
        else:
            meta.write_text(json.dumps({"digest": study.digest(), "study": study.to_dict()}, indent=1))

    def path(self, chunk) -> Path:
        n, start, _ = chunk
        return self.dir / "chunks" / f"n{n:02d}_{start:07d}.npz"

    def load(self, chunk) -> dict | None:
        p = self.path(chunk)
        if not p.exists():
            return None
        with np.load(p) as z:
            return {k: z[k] for k in z.files}

    def save(self, chunk, data: dict) -> None:
        tmp = self.path(chunk).with_suffix(".tmp.npz")
        np.savez(tmp, **data)
        tmp.replace(self.path(chunk))  # atomic: a killed run never leaves half a chunk


def _collect(study: Study, runner: Runner, store: ChunkStore | None, progress: Callable[[dict], None] | None,
             execute: Callable) -> MonteCarloResult:
    start_time = time.perf_counter()
    chunks = study.chunks()
    results: dict = {}
    if store is not None:
        for c in chunks:
            held = store.load(c)
            if held is not None:
                results[c] = held
    todo = [c for c in chunks if c not in results]
    total = sum(c[2] - c[1] for c in chunks)
    done = sum(c[2] - c[1] for c in results)
    resumed = done
    reference = {n: runner.reference_update(n) for n in study.n_modes}
    for c, data in execute(todo):
        results[c] = data
        if store is not None:
            store.save(c, data)
        done += c[2] - c[1]
        if progress:
            elapsed = time.perf_counter() - start_time
            rate = (done - resumed) / elapsed
            progress({"chunk": len(results), "chunks": len(chunks), "n_modes": c[0], "done": done, "total": total,
                      "rate": rate, "seconds_left": (total - done) / rate if rate > 0 else float("inf"),
                      "failed": int(sum(np.sum(r["status"] > 0) for r in results.values())),
                      "fallbacks": int(sum(np.sum(r["fallback"]) for r in results.values()))})
    samples = {}
    for n in study.n_modes:
        parts = [results[c] for c in chunks if c[0] == n]
        samples[n] = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    names = study.parameters.names
    return MonteCarloResult(study, names, samples, reference, time.perf_counter() - start_time)
