"""The iterative updating loop: regularised least squares with Optimistix (thesis §3.2).

``update`` minimises ½‖ε(θ)‖² (eq. 3.4 with the weights inside ε) by Levenberg–Marquardt
or Gauss–Newton (the step of eq. 3.11), stepping the Optimistix solver one iteration at
a time so that each iteration's parameters, frequency deviations, MACs and cost are
recorded. The Jacobian comes from the implicit-differentiation rule of ``jaxfem.eigh``
(forward mode). Convergence: max |α_κ − α_κ₋₁| ≤ tolerance over an accepted step
(thesis §4.2.5.1, footnote 8: 1e-3).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

import jaxfem
from identification import ModalData, observation_matrix
from jaxfem import Model
from jaxfem._model import Opaque

from ._compiled import Compiled
from ._correlation import pair_modes
from ._parameters import Parameterisation, ParameterSet, parameterise
from ._residuals import Problem, auto_eigenvalue_weights, residuals
from ._result import Iteration, UpdateResult


def _active_mask(test: ModalData, options) -> np.ndarray:
    ids = np.arange(1, len(test.frequencies_hz) + 1)
    active = np.ones(len(ids), bool) if options.active_modes is None else np.isin(ids, options.active_modes)
    active &= ~np.isin(ids, options.passive_modes)
    unknown = sorted((set(options.active_modes or ()) | set(options.passive_modes)) - set(ids.tolist()))
    if unknown:
        raise ValueError(f"active/passive modes {unknown} are not test mode numbers 1..{len(ids)}")
    if not active.any():
        raise ValueError("no active test modes")
    return active


def build_problem(model: Model, test: ModalData, parameters: ParameterSet,
                  *, sensors_C: np.ndarray | None = None) -> Problem:
    """Assemble the :class:`Problem` (observation matrix, weights, pairing thresholds)."""
    opts = parameters.options
    model, param = parameterise(model, parameters)
    C = observation_matrix(model, test.sensors)[0] if sensors_C is None else sensors_C
    shapes = np.real(test.real().shapes) if np.iscomplexobj(test.shapes) else np.asarray(test.shapes)
    n_free = model.n_dof - len(model.dofs.massless)
    ne = len(test.frequencies_hz)
    n_model = opts.n_model_modes or min(n_free, 2 * ne + 6)
    values, structure = jaxfem.partition(model)
    problem = Problem(
        values=values,
        structure=Opaque(structure),
        parameterisation=param,
        lam_e=jnp.asarray((2 * np.pi * np.asarray(test.frequencies_hz)) ** 2),
        phi_e=jnp.asarray(shapes),
        C=jnp.asarray(C),
        active=jnp.asarray(_active_mask(test, opts)),
        lam_weight=jnp.ones(ne),
        mu=jnp.asarray(float(opts.regularisation)),
        n_model=int(n_model),
        use_lam=opts.residual in ("eigenvalue", "combined"),
        use_phi=opts.residual in ("eigenvector", "combined"),
        min_mac=float(opts.min_mac),
        max_freq_dev=float(opts.max_freq_dev),
    )
    theta0 = jnp.zeros(len(param.parameters))
    if opts.residual == "combined":
        w = auto_eigenvalue_weights(theta0, problem) if opts.eigenvalue_weight == "auto" \
            else jnp.full(ne, float(opts.eigenvalue_weight))
        problem = eqx.tree_at(lambda p: p.lam_weight, problem, w)
    return problem


def _pairing(ev, test: ModalData, problem: Problem):
    """Exact (Hungarian) pairing of all computed model modes, for reports."""
    return pair_modes(np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model),
                      np.asarray(test.frequencies_hz), np.asarray(problem.phi_e),
                      min_mac=problem.min_mac, max_freq_dev=problem.max_freq_dev)


def update(model: Model, test: ModalData, parameters: ParameterSet, *,
           progress: Callable[[Iteration], None] | None = None) -> UpdateResult:
    """Update ``model`` against measured modes ``test`` (thesis §3.2, Fig. 3.1).

    **Arguments:** the nominal model, the measured modes (sensors labelled by grid and
    direction), the parameters and options; ``progress`` is called after every
    accepted iteration. **Returns:** an :class:`UpdateResult`.
    """
    start = time.perf_counter()
    opts = parameters.options
    problem = build_problem(model, test, parameters)
    n_p = len(problem.parameterisation.parameters)
    solver_cls = optx.LevenbergMarquardt if opts.solver == "levenberg-marquardt" else optx.GaussNewton
    solver = solver_cls(rtol=1e-12, atol=1e-12)
    fn = lambda theta, prob: residuals(theta, prob)
    theta = jnp.zeros(n_p)
    out_struct, aux_struct = jax.eval_shape(fn, theta, problem)
    options = {"jac": "fwd"}
    state = Compiled(solver.init)(fn, theta, problem, options, out_struct, aux_struct, frozenset())
    step = Compiled(lambda t, s, p: solver.step(fn, t, p, options, s, frozenset()))
    summary = Compiled(fn)

    evaluations = []

    def record(k, theta):
        eps, ev = summary(theta, problem)
        evaluations.append(ev)
        cost = 0.5 * sum(float(jnp.sum(v**2)) for v in jax.tree.leaves(eps))
        ratio = np.maximum(np.asarray(ev.lam_a) / np.asarray(problem.lam_e), 0.0)  # unpaired rows hold mode 0
        dev = np.where(np.asarray(ev.paired), np.sqrt(ratio) - 1, np.nan)
        it = Iteration(k, np.asarray(jnp.expm1(theta)), dev, np.where(np.asarray(ev.paired), np.asarray(ev.mac), np.nan), cost)
        if progress:
            progress(it)
        return it

    history = [record(0, theta)]
    converged = False
    for _ in range(opts.max_iterations * 4):  # rejected LM steps do not count as iterations
        new_theta, state, _ = step(theta, state, problem)
        if bool(jnp.all(new_theta == theta)):
            if bool(state.terminate) if hasattr(state, "terminate") else False:
                break
            continue
        change = float(jnp.max(jnp.abs(jnp.expm1(new_theta) - jnp.expm1(theta))))
        theta = new_theta
        history.append(record(len(history), theta))
        if change <= opts.tolerance:
            converged = True
            break
        if len(history) > opts.max_iterations:
            break
    final_model = problem.model(theta)
    return UpdateResult(
        model=final_model,
        names=[p.name for p in problem.parameterisation.parameters],
        alpha=np.asarray(jnp.expm1(theta)),
        theta=np.asarray(theta),
        converged=converged,
        iterations=len(history) - 1,
        history=history,
        active=np.asarray(problem.active),
        before=_pairing(evaluations[0], test, problem),
        after=_pairing(evaluations[-1], test, problem),
        seconds=time.perf_counter() - start,
        sensor_modes={key: (np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model))
                      for key, ev in (("before", evaluations[0]), ("after", evaluations[-1]))},
        parameterisation=problem.parameterisation,
    )
