"""The sparse path on the stiffened fuselage barrel (benchmarks/fuselage.py), against SciPy's eigsh, in one run.

For each size (default 33k, 100k and 300k DoFs), in a child process of its own (so that
its peak memory is its own):

- build: bulk-data text → ``read_bdf_text`` → ``build_model``; ``assemble`` (K, M blocks);
- references, on the same CSR matrices, 20 lowest modes at the same shift σ:
  ``scipy.sparse.linalg.eigsh`` with its defaults (SuperLU, COLAMD ordering), and
  ``eigsh`` with ``OPinv`` = the factorisation jaxfem uses (MKL PARDISO where installed,
  else SuperLU with MMD on AᵀA + A) — "eigsh on the same library";
- (a) ``jaxfem.eigsh`` 20 modes alone (host: factorisation + Lanczos + refinement);
- (b) 20 modes + the full Jacobians dλ/dp (20 × 20) and dφ/dp (n × 20 × 20, and at 200
  sensor DoFs) for the 20 parameter groups of ``fuselage.parameter_groups(20)``, by
  forward mode through parameterisation, assembly and ``jaxfem.eigsh`` (jitted; the
  first call's compile time apart), the tangents a few at a time as in the updating
  engine (``TANGENT_DOFS // n`` per batch: all 20 tangents of the element blocks at once
  do not fit in 24 GB at 100k DoFs);
- (c) at the smallest size, 10 parameters (``fuselage.parameter_groups(10)``), 20 test
  modes at the 200 sensor DoFs: one iteration of the engine (residual and its Jacobian,
  ``updating._engine.linearise``, compiled: the second call), and a whole ``update``
  limited to one iteration from a cold start (compilation included);
- (d) the child's peak resident memory (``ru_maxrss``).

Usage: ``python -m benchmarks.perf_sparse [--sizes 33000 100000 300000] [--jacobian-up-to 150000] [--json OUT]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

N_MODES, N_PARAMS, N_SENSORS = 20, 20, 200


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def measure(n_dof: int, update: bool, jacobian_up_to: int = 10**9) -> dict:
    """Everything for one size, in this process."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np
    import scipy.sparse.linalg as spla

    import jaxfem
    from benchmarks import fuselage
    from jaxfem import _sparse
    from jaxfem.io import read_bdf_text
    from updating import ParameterSet, parameterise
    from updating._engine import TANGENT_DOFS

    out = {"requested_n_dof": n_dof}
    text = fuselage.barrel_bdf(n_dof)
    model, out["build_s"] = _timed(lambda: jaxfem.build_model(read_bdf_text(text, name="barrel")))
    out["n_dof"] = int(model.n_dof)
    (K, M), out["assemble_s"] = _timed(lambda: jax.block_until_ready(jaxfem.assemble(model)))
    pat = _sparse.pattern(tuple(K.indices) + tuple(M.indices), K.n)
    nk = len(K.blocks)
    kd = pat.values([np.asarray(b) for b in K.blocks], pat.slots[:nk])
    md = pat.values([np.asarray(b) for b in M.blocks], pat.slots[nk:])
    Kc, Mc = pat.matrix(kd), pat.matrix(md)
    out["nnz_per_row"] = Kc.nnz / K.n
    backend = _sparse.resolve_backend("auto")
    out["backend"] = backend

    # (a) jaxfem.eigsh, modes alone (a fresh factorisation: the cache is cleared)
    _sparse._FACTORS.clear()
    (lam, _), out["a_jaxfem_modes_s"] = _timed(lambda: jax.block_until_ready(jaxfem.eigsh(K, M, N_MODES)))
    sigma = float(jaxfem.sparse_modes(K, M, N_MODES).solver.sigma)
    out["sigma"] = sigma
    out["frequencies_hz"] = np.asarray(jaxfem.frequencies_hz(lam)).round(4).tolist()

    # references on the same matrices and shift
    def scipy_default():
        return spla.eigsh(Kc.tocsc(), N_MODES, Mc.tocsc(), sigma=sigma, which="LM")

    def scipy_same_library():
        f = _sparse._FACTORS.clear() or _sparse.factor(pat, backend, kd, md, sigma)
        op = spla.LinearOperator(Kc.shape, matvec=f.solve, dtype=np.float64)
        return spla.eigsh(Kc, N_MODES, Mc, sigma=sigma, OPinv=op, which="LM")

    (ref, _), out["eigsh_default_s"] = _timed(scipy_default)
    out["eigsh_default_max_rel_dev"] = float(np.max(np.abs(np.sort(ref) / np.asarray(lam) - 1)))
    _, out["eigsh_same_library_s"] = _timed(scipy_same_library)
    out["eigsh_best_s"] = min(out["eigsh_default_s"], out["eigsh_same_library_s"])

    if n_dof > jacobian_up_to:
        out["b_skipped"] = f"above --jacobian-up-to {jacobian_up_to} DoFs"
        out["d_peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
        return out

    # (b) modes + full Jacobians in 20 parameter groups
    base, par = parameterise(model, fuselage.parameter_groups(N_PARAMS))
    free = np.flatnonzero(np.asarray(model.node_ids) < 10**8)
    rows = np.random.default_rng(0).choice(free, N_SENSORS // 2, replace=False)
    nodes = np.repeat(rows, 2)
    comps = np.tile([1, 2], len(rows))  # y and z translations of 100 grids
    coef = jnp.asarray(model.dofs.coef[nodes, comps])
    index = jnp.asarray(model.dofs.index[nodes])

    def f(theta):
        lam, phi = jaxfem.eigsh(*jaxfem.assemble(par.apply(base, theta)), N_MODES)
        phi_pad = jnp.concatenate([phi, jnp.zeros((1, N_MODES))])
        return lam, phi, jnp.einsum("sw,swm->sm", coef, phi_pad[index])

    chunk = max(1, TANGENT_DOFS // n_dof)  # tangents at a time, as the updating engine (memory)

    def jac(theta):
        primal, lin = jax.linearize(f, theta)
        return primal, jax.lax.map(lin, jnp.eye(N_PARAMS), batch_size=chunk)

    jac = jax.jit(jac)
    theta = jnp.zeros(N_PARAMS)
    _sparse._FACTORS.clear()
    _, first = _timed(lambda: jax.block_until_ready(jac(theta)))
    _sparse._FACTORS.clear()
    (_, (jl, jp, js)), out["b_modes_and_jacobians_s"] = _timed(lambda: jax.block_until_ready(jac(theta)))
    out["b_tangents_at_a_time"] = chunk
    out["b_compile_s"] = first - out["b_modes_and_jacobians_s"]
    out["b_over_eigsh_best"] = out["b_modes_and_jacobians_s"] / out["eigsh_best_s"]
    out["a_over_eigsh_best"] = out["a_jaxfem_modes_s"] / out["eigsh_best_s"]
    out["jacobian_shapes"] = [list(jl.shape), list(jp.shape), list(js.shape)]
    out["finite"] = bool(np.all(np.isfinite(np.asarray(jp))))

    if update:
        from identification import Sensors
        from updating import Options, simulate_test
        from updating._eigensolvers import Direct
        from updating._engine import linearise
        from updating._solve import build_problem
        from updating._solve import update as run_update

        params = ParameterSet(tuple(fuselage.parameter_groups(10)),
                              Options(max_iterations=1, tolerance=1e-12, eigensolver="sparse"))
        sensors = Sensors.from_components(np.asarray(model.node_ids)[nodes], comps + 1)
        test = simulate_test(fuselage_truth(fuselage, n_dof), sensors, N_MODES, solver="sparse")
        problem = build_problem(model, test, params)
        lin = jax.jit(lambda t: linearise(t, problem, jnp.zeros(0), Direct())[:2])
        t0 = jnp.zeros(10)
        jax.block_until_ready(lin(t0))
        _sparse._FACTORS.clear()
        _, out["c_iteration_s"] = _timed(lambda: jax.block_until_ready(lin(t0)))
        _sparse._FACTORS.clear()
        _, out["c_update_one_iteration_cold_s"] = _timed(lambda: run_update(model, test, params))
        out["c_n_model_modes"] = problem.n_model
    out["d_peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    return out


def fuselage_truth(fuselage, n_dof):
    import jaxfem
    from jaxfem.io import read_bdf_text

    return jaxfem.build_model(read_bdf_text(fuselage.barrel_bdf(n_dof, damage={"frames E": 0.1, "joint k": -0.5}),
                                            name="truth"))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[33000, 100000, 300000])
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--jacobian-up-to", type=int, default=150_000,
                        help="largest size at which (b) is measured (memory and time)")
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--update", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        print(json.dumps(measure(args.child, args.update, args.jacobian_up_to)))
        return
    rows = []
    for i, n in enumerate(args.sizes):
        cmd = [sys.executable, "-m", "benchmarks.perf_sparse", "--child", str(n),
               "--jacobian-up-to", str(args.jacobian_up_to)] + (["--update"] if i == 0 else [])
        done = subprocess.run(cmd, capture_output=True, text=True, env=os.environ)
        printed = [line for line in done.stdout.splitlines() if line.startswith("{")]
        if done.returncode and not printed:
            print(done.stderr[-3000:], file=sys.stderr)
            lines = done.stderr.strip().splitlines() or [f"exit code {done.returncode} (killed: out of memory?)"]
            rows.append({"requested_n_dof": n, "error": lines[-1]})
            continue
        row = json.loads(printed[-1])
        rows.append(row)
        print(json.dumps(row), flush=True)
    result = {"machine": f"{platform.machine()}, {os.cpu_count()} cores", "rows": rows}
    if args.json:
        args.json.write_text(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
