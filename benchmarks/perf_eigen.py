"""Eigenpairs + full eigenvalue and eigenvector Jacobian, against references in one run.

For 3-D frames of about 500, 2000 and 5000 DoFs (benchmarks/frames.py), 20 modes and
20 stiffness correction factors (one per property group, thesis eq. 3.1):

- jaxfem: ``jacfwd`` through ``jaxfem.eigh`` on the element-stacked K(α), M (one
  compiled call returning modes and Jacobians), and the forward solve alone;
- scipy ``eigh(K, M)`` all modes (default driver) and with ``subset_by_index`` (20 modes);
- a central finite-difference Jacobian from 2×20 scipy subset solves;
- ``jax.jacfwd`` through plain ``jnp.linalg.eigh`` after a Cholesky reduction of the
  dense K(α) = K0 + Σ α_i K_i.

Compile time and run time are reported apart (best of ``--repeat`` runs after a warm-up).
Usage: ``python benchmarks/perf_eigen.py [--sizes 500 2000 5000] [--json OUT]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import jax

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import jax.scipy.linalg as jsl  # noqa: E402
import numpy as np  # noqa: E402
import scipy.linalg as sl  # noqa: E402

import jaxfem  # noqa: E402
from benchmarks.frames import SIZES, frame_bdf  # noqa: E402
from jaxfem.io import read_bdf_text  # noqa: E402

N_MODES, N_PARAMS = 20, 20


def best_time(fn, repeat):
    jax.block_until_ready(fn())  # warm-up (compilation, caches)
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - t)
    return min(times)


def compiled(fn, *args):
    """Compile time of a jitted function (lowering + XLA compilation, no execution)."""
    t = time.perf_counter()
    fn.lower(*args).compile()
    return time.perf_counter() - t


def setup(size, n_params=N_PARAMS):
    nx, ny, nz = SIZES[size]
    model = jaxfem.build_model(read_bdf_text(frame_bdf(nx, ny, nz, n_groups=n_params), name=f"frame_{size}"))
    groups = [model.element_ids(pids=[g + 1]) for g in range(n_params)]
    return model, groups


def jaxfem_functions(model, groups, n_modes):
    """Jitted (values, α) → modes, and → (modes, Jacobians); the structure stays concrete."""
    values, structure = jaxfem.partition(model)

    def modes(values, alpha):
        K, M = jaxfem.assemble(jaxfem.correct(eqx.combine(values, structure), groups, alpha))
        return jaxfem.eigh(K, M, n_modes)

    def with_jacobian(values, alpha):
        jac, value = jax.jacfwd(lambda a: (modes(values, a),) * 2, has_aux=True)(alpha)
        return value, jac

    return values, jax.jit(modes), jax.jit(with_jacobian)


def dense_parts(model, groups):
    """K0, M and the group matrices K_i as dense NumPy arrays (K(α) = K0 + Σ α_i K_i)."""
    K0, M = (np.asarray(a.todense()) for a in jaxfem.assemble(model))
    parts = []
    for g in groups:
        K1, _ = jaxfem.assemble(jaxfem.correct(model, [g], jnp.ones(1)))
        parts.append(np.asarray(K1.todense()) - K0)
    return K0, M, np.stack(parts)


def run_size(size, repeat, skip_slow, jnp_max_dof):
    model, groups = setup(size)
    alpha = jnp.zeros(N_PARAMS)
    n = model.n_dof
    row = {"size": size, "n_dof": n, "n_massless": len(model.dofs.massless)}
    values, modes, with_jac = jaxfem_functions(model, groups, N_MODES)
    row["jaxfem_compile_s"] = compiled(with_jac, values, alpha)
    compiled(modes, values, alpha)
    row["jaxfem_forward_s"] = best_time(lambda: modes(values, alpha), repeat)
    row["jaxfem_eig_jac_s"] = best_time(lambda: with_jac(values, alpha), repeat)

    K0, M, Ki = dense_parts(model, groups)
    row["scipy_all_s"] = best_time(lambda: sl.eigh(K0, M), repeat)
    sub = lambda K: sl.eigh(K, M, subset_by_index=[0, N_MODES - 1])
    row["scipy_subset_s"] = best_time(lambda: sub(K0), repeat)

    (lam, phi), (jl, jp) = with_jac(values, alpha)
    if not skip_slow:
        h = 1e-6
        t = time.perf_counter()
        fd_l = []
        for i in range(N_PARAMS):
            lp, pp = sub(K0 + h * Ki[i])
            lm, pm = sub(K0 - h * Ki[i])
            fd_l.append((lp - lm) / (2 * h))
        row["fd_jacobian_s"] = time.perf_counter() - t
        fd_l = np.stack(fd_l, axis=1)
        row["fd_vs_jaxfem_dlam_rel"] = float(np.max(np.abs(fd_l - jl)) / np.max(np.abs(jl)))

    if not skip_slow and n <= jnp_max_dof:

        @jax.jit
        def plain(K0, M, Ki, a):
            K = K0 + jnp.einsum("i,ijk->jk", a, Ki)
            lm = jnp.linalg.cholesky(M)
            y = jsl.solve_triangular(lm, K, lower=True)
            w, v = jnp.linalg.eigh(jsl.solve_triangular(lm, y.T, lower=True))
            return w[:N_MODES], jsl.solve_triangular(lm.T, v[:, :N_MODES], lower=False)

        plain_jac = jax.jit(jax.jacfwd(plain, argnums=3))
        args = (jnp.asarray(K0), jnp.asarray(M), jnp.asarray(Ki), alpha)
        compiled(plain, *args)
        row["jnp_eigh_forward_s"] = best_time(lambda: plain(*args), repeat)
        compiled(plain_jac, *args)
        row["jnp_jacfwd_s"] = best_time(lambda: plain_jac(*args), 1)
        row["jnp_vs_jaxfem_dlam_rel"] = float(
            np.max(np.abs(plain_jac(*args)[0] - jl)) / np.max(np.abs(jl)))
    return row


def run_scaling(repeat):
    """Cost of eigen + Jacobian at n≈2000 with the number of modes and of parameters."""
    rows = []
    for n_params in (5, 20, 80):
        model, groups = setup("2000", n_params)
        for n_modes in (10, 20, 50):
            if n_params != 20 and n_modes != 20:
                continue
            values, modes, with_jac = jaxfem_functions(model, groups, n_modes)
            alpha = jnp.zeros(n_params)
            compiled(with_jac, values, alpha)
            compiled(modes, values, alpha)
            fwd = best_time(lambda: modes(values, alpha), repeat)
            tot = best_time(lambda: with_jac(values, alpha), repeat)
            rows.append({"n_params": n_params, "n_modes": n_modes, "forward_s": fwd,
                         "eig_jac_s": tot, "jacobian_share": (tot - fwd) / tot})
    return rows


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", default=list(SIZES))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--skip-slow", action="store_true", help="skip the FD and jnp-jacfwd references")
    parser.add_argument("--no-scaling", action="store_true")
    parser.add_argument("--jnp-max-dof", type=int, default=2500,
                        help="skip the dense jnp-jacfwd reference above this size (memory: 20 dense n×n tangents)")
    parser.add_argument("--json")
    args = parser.parse_args()
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, jax {jax.__version__}"
    print(f"machine: {machine}")
    rows = []
    for size in args.sizes:
        row = run_size(size, args.repeat, args.skip_slow, args.jnp_max_dof)
        rows.append(row)
        ref = row["scipy_all_s"]
        print(f"\nn = {row['n_dof']} DoFs, {N_MODES} modes, {N_PARAMS} parameters (best of {args.repeat})")
        print(f"  {'method':<44}{'time [s]':>10}{'/ scipy all':>13}")
        for label, key in [
            ("jaxfem eigen + full Jacobian (λ and φ)", "jaxfem_eig_jac_s"),
            ("jaxfem eigen only", "jaxfem_forward_s"),
            ("scipy eigh(K, M) all modes", "scipy_all_s"),
            ("scipy eigh subset_by_index (20 modes)", "scipy_subset_s"),
            ("central FD Jacobian (2×20 scipy subset)", "fd_jacobian_s"),
            ("jnp Cholesky + eigh (forward)", "jnp_eigh_forward_s"),
            ("jax.jacfwd through jnp Cholesky + eigh", "jnp_jacfwd_s"),
        ]:
            if key in row:
                print(f"  {label:<44}{row[key]:>10.3f}{row[key] / ref:>13.2f}")
        print(f"  compile time jaxfem eigen + Jacobian: {row['jaxfem_compile_s']:.1f} s")
        jac_share = (row["jaxfem_eig_jac_s"] - row["jaxfem_forward_s"]) / row["jaxfem_eig_jac_s"]
        print(f"  Jacobian share of jaxfem time: {100 * jac_share:.0f} %")
        if "fd_jacobian_s" in row:
            print(f"  speed-up over FD (2×20 subset solves + one for the modes): "
                  f"{(row['fd_jacobian_s'] + row['scipy_subset_s']) / row['jaxfem_eig_jac_s']:.1f}×; "
                  f"dλ/dα agreement {row['fd_vs_jaxfem_dlam_rel']:.1e} (max rel.)")
        if "jnp_jacfwd_s" in row:
            print(f"  speed-up over jnp jacfwd: {row['jnp_jacfwd_s'] / row['jaxfem_eig_jac_s']:.1f}×; "
                  f"dλ/dα agreement {row['jnp_vs_jaxfem_dlam_rel']:.1e} (max rel.)")
    scaling = [] if args.no_scaling else run_scaling(args.repeat)
    if scaling:
        print("\nscaling at n≈2000 (jaxfem): parameters × modes")
        print(f"  {'params':>6} {'modes':>6} {'eigen [s]':>10} {'eigen+jac [s]':>14} {'jac share':>10}")
        for r in scaling:
            print(f"  {r['n_params']:>6} {r['n_modes']:>6} {r['forward_s']:>10.3f} "
                  f"{r['eig_jac_s']:>14.3f} {100 * r['jacobian_share']:>9.0f}%")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"machine": machine, "sizes": rows, "scaling": scaling}, f, indent=2)


if __name__ == "__main__":
    main()
