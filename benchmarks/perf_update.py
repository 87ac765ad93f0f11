"""One updating iteration (eigen + Jacobian + LM step), jaxfem against scipy + FD, one run.

jaxfem: one Levenberg–Marquardt step of the updating engine (residuals with in-loop
pairing, forward-mode Jacobian through the implicit eigen rule), compiled, timed
after a warm-up. Reference: the same iteration built from scipy — dense K(α) = K0 + Σ α_i K_i,
``scipy.linalg.eigh(K, M, subset_by_index)`` for the model modes, MAC pairing (Hungarian),
residuals, a central finite-difference Jacobian (2p more solves) and the LM step by
``numpy.linalg.lstsq`` on the damped normal equations.

Cases: the GARTEUR SM-AG19 model (updating/data/garteur.bdf, 24 sensors, 14 modes,
stiffness factors on its property groups) and a ≈5000-DoF frame (20 groups, 14 modes).
Usage: ``python -m benchmarks.perf_update [--cases garteur frame5000] [--json OUT]``.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import time
from pathlib import Path

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import scipy.linalg as sl  # noqa: E402
from scipy.optimize import linear_sum_assignment  # noqa: E402

import jaxfem  # noqa: E402
from benchmarks.frames import SIZES, frame_bdf  # noqa: E402
from benchmarks.models import MODELS  # noqa: E402
from benchmarks.perf_eigen import best_time  # noqa: E402
from identification import Sensors, observation_matrix  # noqa: E402
from jaxfem.io import read_bdf, read_bdf_text  # noqa: E402
from updating import Options, Parameter, ParameterSet, build_problem, parameterise, simulate_test  # noqa: E402
from updating import _engine  # noqa: E402
from updating._compiled import Compiled  # noqa: E402
from updating._eigensolvers import Direct  # noqa: E402
from updating._engine import Settings  # noqa: E402


def garteur_case():
    model = jaxfem.build_model(read_bdf(MODELS / "garteur.bdf"))
    with open(MODELS / "garteur_sensors.csv") as f:
        rows = list(csv.DictReader(f))
    sensors = Sensors.from_components([int(r["node"]) for r in rows], [int(r["component"]) for r in rows])
    pids = sorted(set(model.beam_sections.ids.tolist()))
    return model, sensors, pids, 14


def frame_case():
    model = jaxfem.build_model(read_bdf_text(frame_bdf(*SIZES["5000"], n_groups=20)))
    nodes = model.node_ids[(model.node_ids > 25) & (model.node_ids < 900000)][::9]
    sensors = Sensors.from_components(np.repeat(nodes, 2), np.tile([1, 2], len(nodes)))
    return model, sensors, list(range(1, 21)), 14


def simulated(model, sensors, params, n_modes):
    base, par = parameterise(model, params)
    alpha = 0.1 * np.sin(np.arange(1, len(params) + 1))
    truth = par.apply(base, jnp.log1p(jnp.asarray(alpha)))
    f = np.asarray(jaxfem.frequencies_hz(jaxfem.modes(truth, n_modes + 6)[0]))
    skip = int(np.sum(f <= 3.0))  # elastic modes only (GARTEUR: 6 free/suspension)
    C, _ = observation_matrix(model, sensors)
    return simulate_test(truth, sensors, n_modes, skip=skip), C


def jaxfem_step(problem, n_p):
    """One step of the updating engine (``updating._engine.run`` limited to one step: the
    residual and Jacobian at α = 0 and the Levenberg–Marquardt step), compiled."""
    settings = Settings(False, 1e-3, 1, 1)
    run = Compiled(_engine.run)
    theta = jnp.zeros(n_p)
    return lambda: run(theta, problem, Direct(), jnp.zeros(0), settings).solver


def scipy_iteration(K0, Ki, M, C, test, weights, n_model, damping=1e-3):
    """Eigen + pairing + residual + FD Jacobian (2p solves) + LM step, scipy/numpy."""
    lam_e = (2 * np.pi * test.frequencies_hz) ** 2
    phi_e = test.shapes

    def resid(alpha):
        K = K0 + np.tensordot(alpha, Ki, 1)
        lam, phi = sl.eigh(K, M, subset_by_index=[0, n_model - 1])
        ps = C @ phi
        mac = (ps.T @ phi_e) ** 2 / np.outer(np.sum(ps**2, 0), np.sum(phi_e**2, 0))
        rows, cols = linear_sum_assignment(-mac)
        order = rows[np.argsort(cols)]
        pa = ps[:, order]
        msf = np.sum(pa * phi_e, 0) / np.sum(pa * pa, 0)
        r_l = weights * (lam_e - lam[order]) / lam_e
        r_p = (phi_e - msf * pa) / np.linalg.norm(phi_e, axis=0)
        return np.concatenate([r_l, r_p.ravel()])

    alpha = np.zeros(Ki.shape[0])
    r = resid(alpha)
    h = 1e-6
    J = np.column_stack([(resid(alpha + h * e) - resid(alpha - h * e)) / (2 * h) for e in np.eye(len(alpha))])
    A = np.vstack([J, np.sqrt(damping) * np.eye(len(alpha))])
    return np.linalg.lstsq(A, -np.concatenate([r, np.zeros(len(alpha))]), rcond=None)[0]


def run(name, case, repeat):
    model, sensors, pids, n_modes = case()
    params = tuple(Parameter(f"pid{p}", "stiffness", pids=(p,)) for p in pids)
    test, C = simulated(model, sensors, params, n_modes)
    pset = ParameterSet(params, Options())
    problem = build_problem(model, test, pset)
    n_p = len(params)
    t = time.perf_counter()
    step = jaxfem_step(problem, n_p)
    jax.block_until_ready(step())
    compile_s = time.perf_counter() - t
    t_jax = best_time(step, repeat)
    K0, M = (np.asarray(a.todense()) for a in jaxfem.assemble(model))
    if len(model.dofs.massless):
        raise SystemExit(f"{name}: the scipy reference needs a model without massless DoFs")
    groups = problem.parameterisation.stiffness_groups
    Ki = np.stack([np.asarray(jaxfem.assemble(jaxfem.correct(model, [g], jnp.ones(1)))[0].todense()) - K0
                   for g in groups])
    weights = np.asarray(problem.lam_weight)
    t = time.perf_counter()  # one reference iteration: it is (2p + 1) solves long
    scipy_iteration(K0, Ki, M, C, test, weights, problem.n_model)
    t_ref = time.perf_counter() - t
    return {"case": name, "n_dof": model.n_dof, "n_params": n_p, "n_test_modes": n_modes,
            "n_model_modes": problem.n_model, "n_sensors": len(sensors), "jaxfem_step_s": t_jax,
            "jaxfem_first_call_s": compile_s, "scipy_fd_iteration_s": t_ref, "speedup": t_ref / t_jax}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", nargs="+", default=["garteur", "frame5000"])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json")
    args = parser.parse_args()
    cases = {"garteur": garteur_case, "frame5000": frame_case}
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, jax {jax.__version__}"
    print(f"machine: {machine}")
    rows = []
    for name in args.cases:
        row = run(name, cases[name], args.repeat)
        rows.append(row)
        print(f"\n{name}: n = {row['n_dof']} DoFs, {row['n_params']} parameters, {row['n_test_modes']} test modes "
              f"({row['n_model_modes']} model modes), {row['n_sensors']} sensors")
        print(f"  jaxfem LM iteration (eigen + Jacobian + step): {row['jaxfem_step_s']:.3f} s "
              f"(first call with compilation {row['jaxfem_first_call_s']:.1f} s)")
        print(f"  scipy eigh + FD Jacobian + LM step:           {row['scipy_fd_iteration_s']:.3f} s")
        print(f"  ratio scipy+FD / jaxfem: {row['speedup']:.1f}×")
    if args.json:
        Path(args.json).write_text(json.dumps({"machine": machine, "cases": rows}, indent=2))


if __name__ == "__main__":
    main()
