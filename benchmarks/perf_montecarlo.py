"""Monte-Carlo updating throughput (thesis §4.3 study, issue 6), one run.

Batched: :class:`updating.studies._montecarlo.Runner` — the complete update (pairing + Gauss–Newton
loop) per sample, subspace eigensolves warm-started and preconditioned with the
error-free update's (K − σM)⁻¹ (:func:`jaxfem.subspace`), samples sharded over 1, 2 and 4
forced host devices (and 4 samples per ``vmap`` batch on one device), starting from the
error-free update. Reference, in the same run: a
Python loop over the samples, each one call of the same update compiled for one sample,
with a full dense eigensolve (:func:`jaxfem.dense_modes`, all modes, one Cholesky
factorisation) at every residual evaluation — from the initial model (the plain update),
and from the error-free update (the batched samples' start: the full-solve result every
sample is compared with). All timed after compilation; the batched setup (compilation,
the error-free update and its preconditioner, once per n-mode group) is reported apart.
Reported: updated samples per second and the ratios, iterations, the largest factor
difference to the full-solve results on the samples both converged, failures,
fallbacks to full solves and the peak resident memory of the process.

Then the pipeline a user would otherwise build (issue 13, :mod:`benchmarks.scipy_pipeline`):
the same residual, pairing, Gauss–Newton iteration, start (the batched samples' θ) and
tolerance in NumPy/SciPy — ``scipy.linalg.eigh`` (subset, stiffness-standardised), one
refinement sweep with element-level K products, and the analytic Jacobian (φᵀK_iφ and the
modal expansion over the computed modes plus the static term of the omitted ones,
eq. 3.18, eq. 3.23, eq. 3.28, eq. 3.29) — on the same samples, split over two spawned
single-threaded processes (one per core of the 2-core machine; ``--processes``); also
from the initial model, and bare (the expansion truncated to the computed modes, no
refinement) from the batched samples' start. Its matrices come from jaxfem and are
checked against it first (K(θ) at a random θ; λ and Cφ at θ = 0 against ``model_modes``
and the full dense solve). Reported as the other rows, with the largest factor
difference to the batched results (1 device) or the plain loop, and the ratio "batched
1 device / scipy pipeline" (samples per second, the same start; the issue's target is ≥ 2).

Usage: ``python -m benchmarks.perf_montecarlo [--samples 16] [--modes 10] [--processes 2] [--json OUT]``.
"""

from __future__ import annotations

import os

os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=4")

import argparse
import dataclasses
import json
import platform
import resource
import time

import jax

jax.config.update("jax_enable_x64", True)

import numpy as np

from benchmarks.scipy_pipeline import ReferenceProblem, ScipyPipeline, verify
from updating import Options
from updating.studies._montecarlo import Runner, _record, default_study, tree_parameters


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def _difference(a: dict, b: dict) -> tuple[float, int]:
    """Largest |α difference| on the samples both converged, and their number."""
    both = (a["status"] == 0) & (b["status"] == 0)
    return (float(np.max(np.abs(a["alpha"][both] - b["alpha"][both]))) if both.any() else float("nan")), int(both.sum())


def scipy_rows(out: dict, args, g, f, phi, start, batched: dict, plain: dict) -> None:
    """The SciPy pipeline on the same samples: from the batched samples' start (compared
    with the batched results), from the initial model (compared with the plain loop), and
    its bare variant (truncated expansion, no refinement) from the batched samples' start."""
    S = f.shape[0]
    reference = ReferenceProblem.from_problem(g.problem, shift=g.kinds["subspace"].shift,
                                              tolerance=args.tolerance, max_iterations=16)
    checks = verify(reference, g.problem)
    out["scipy_checks"] = checks
    print("scipy pipeline checks: K(θ) {K_rel:.1e} (assembled), {K_elements_rel:.1e} (elements), M(θ) {M_rel:.1e} "
          "relative; at θ = 0 λ {lam_rel_dense_modes:.1e}, Cφ {phi_rel_dense_modes:.1e} from the full dense solve, "
          "λ {lam_rel_model_modes:.1e}, Cφ {phi_rel_model_modes:.1e} from model_modes (jaxfem.eigh)".format(**checks))
    f, phi = np.asarray(f), np.asarray(phi)
    pool, setup = _timed(lambda: ScipyPipeline(reference, args.processes))  # spawn, imports, warm-up
    bare = {"refine": False, "expansion": "subset"}
    with pool:
        for key, theta0, variant, other, what, against in (
                ("scipy_pipeline", start, {}, batched, "error-free update", "batched (1 device)"),
                ("scipy_pipeline_from_initial", np.zeros_like(np.asarray(start)), {}, plain, "initial model",
                 "plain loop"),
                ("scipy_pipeline_bare", start, bare, batched, "error-free update", "batched (1 device)")):
            got, t = _timed(lambda th=theta0, v=variant: pool.update(th, f, phi, **v))
            diff, compared = _difference(got, other)
            out[key] = {"seconds": t, "samples_per_s": S / t, "setup_s": setup, "processes": args.processes,
                        "variant": {"standardise": reference.standardise, "refine": reference.refine,
                                    "expansion": reference.expansion, **variant},
                        "failed": int(np.sum(got["status"] > 0)), "iterations": float(got["iterations"].mean()),
                        "max_alpha_difference": diff, "compared_with": against, "compared_samples": compared}
            label = "scipy pipeline" + (", bare (subset expansion, no refinement)" if variant else "")
            print(f"{label}, {args.processes} processes, from the {what}: {S / t:7.3f} samples/s  (setup "
                  f"{setup:.1f} s, {out[key]['failed']} failed, {got['iterations'].mean():.1f} iterations; max |Δα| to "
                  f"the {against} {diff:.2e} on {compared})")
    ratio = out["batched_1_devices"]["samples_per_s"] / out["scipy_pipeline"]["samples_per_s"]
    out["ratio_batched_1_device_to_scipy_pipeline"] = ratio
    print(f"batched 1 device / scipy pipeline: ×{ratio:.2f} (samples per second, the same start)")


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--modes", type=int, default=10)
    ap.add_argument("--error", type=float, default=0.01, help="relative shape error (fraction)")
    ap.add_argument("--tolerance", type=float, default=1e-9, help="largest factor change of the last step")
    ap.add_argument("--processes", type=int, default=2, help="worker processes of the SciPy pipeline")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    n, S = args.modes, args.samples
    options = Options(tolerance=args.tolerance, max_iterations=16, solver="gauss-newton")
    study = default_study(1, n_modes=(n,), samples=S, chunk_size=S, errors=(("relative", (args.error,)),),
                          parameters=tree_parameters(options))

    # Reference: a Python loop over the one-sample update with full eigensolves (each call
    # one compiled sample), from the initial model (the plain update) and, as the
    # equality reference of every sample, from the batched samples' start.
    loop = Runner(dataclasses.replace(study, eigensolver="dense", chunk_size=1), devices=jax.devices()[:1])
    _, compile_loop = _timed(lambda: loop.reference_update(n))
    g = loop.group(n)
    f, phi = g.data(study, 0, S)

    def loop_from(start):
        outs, t = _timed(lambda: [g.update(f[j:j + 1], phi[j:j + 1], "dense", start) for j in range(S)])
        got = {k: np.concatenate([_record(o, np.asarray(f[j:j + 1]), np.zeros(1, bool))[k] for j, o in enumerate(outs)])
               for k in ("alpha", "status", "iterations")}
        return got, t

    ref, t_loop = loop_from(g.origin)
    same, t_same = loop_from(g.sample_start("dense"))
    out = {"study": f"tree model 1, {n} modes, relative shape error {100 * args.error:g} %, {S} samples",
           "machine": f"{platform.machine()}, {os.cpu_count()} cores", "jax": jax.__version__}
    print(f"{out['study']}; {out['machine']}")
    for key, got, t, what in (("loop_full", ref, t_loop, "initial model"),
                              ("loop_full_same_start", same, t_same, "error-free update")):
        out[key] = {"seconds": t, "samples_per_s": S / t, "compile_s": compile_loop,
                    "failed": int(np.sum(got["status"] > 0)), "iterations": float(got["iterations"].mean())}
        print(f"loop, full solves from the {what:17s}: {S / t:7.3f} samples/s  (compile {compile_loop:.1f} s, "
              f"{out[key]['failed']} failed, {got['iterations'].mean():.1f} iterations per sample)")
    for d, v in ((1, 1), (2, 1), (4, 1), (1, 4)):
        runner = Runner(dataclasses.replace(study, lockstep=v), devices=jax.devices()[:d])
        key = f"batched_{d}_devices" + (f"_lockstep_{v}" if v > 1 else "")
        # Once per group: compile, the error-free update and its preconditioner.
        _, compile_s = _timed(lambda r=runner: (r.reference_update(n), r.group(n).sample_start("subspace"),
                                                r.group(n).data(study, 0, S)))
        got, t = _timed(lambda r=runner: r.chunk(n, 0, S))
        if (d, v) == (1, 1):
            batched, start = got, runner.group(n).sample_start("subspace").theta
        both = (got["status"] == 0) & (same["status"] == 0)
        diff = float(np.max(np.abs(got["alpha"][both] - same["alpha"][both]))) if both.any() else float("nan")
        plain = (got["status"] == 0) & (ref["status"] == 0)
        diff_plain = float(np.max(np.abs(got["alpha"][plain] - ref["alpha"][plain]))) if plain.any() else float("nan")
        out[key] = {
            "seconds": t, "samples_per_s": S / t, "ratio_to_loop": t_loop / t, "ratio_to_loop_same_start": t_same / t,
            "setup_s": compile_s, "failed": int(np.sum(got["status"] > 0)), "fallbacks": int(got["fallback"].sum()),
            "refreshes": int(got["refreshes"].sum()), "iterations": float(got["iterations"].mean()),
            "max_alpha_difference_to_full": diff, "compared_samples": int(both.sum()),
            "max_alpha_difference_to_plain_loop": diff_plain, "compared_plain": int(plain.sum())}
        print(f"batched, {d} device(s), vmap {v}: {S / t:7.3f} samples/s  ×{t_loop / t:5.2f} the loop, ×{t_same / t:5.2f} the "
              f"same-start loop (setup {compile_s:.1f} s, {out[key]['failed']} failed, "
              f"{int(got['fallback'].sum())} fallbacks, {int(got['refreshes'].sum())} refreshes, {got['iterations'].mean():.1f} iterations; max |Δα| to full "
              f"{diff:.2e} on {int(both.sum())}, to the plain loop {diff_plain:.2e} on {int(plain.sum())})")
    scipy_rows(out, args, g, f, phi, start, batched, ref)
    out["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak resident memory: {out['peak_rss_mib']:.0f} MiB")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return out


if __name__ == "__main__":
    main()
