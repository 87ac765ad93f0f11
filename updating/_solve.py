"""An engineer's update (thesis §3.2): the problem from model, test and parameter file,
the engine's loop (:mod:`updating._engine`), the result with its before/after pairings.

The residual, stopping rule and solver are the engine's: ½‖ε(θ)‖² (eq. 3.4) minimised by
Levenberg–Marquardt or Gauss–Newton (eq. 3.11), converged when max |α_κ − α_κ₋₁| ≤
tolerance over an accepted step (thesis §4.2.5.1, footnote 8: 1e-3).
"""

from __future__ import annotations

import time
import warnings

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfem
from identification import ModalData, observation_matrix, pair_modes
from jaxfem import Model, Opaque

from ._compiled import Compiled
from ._eigensolvers import Direct, resolve_eigensolver
from ._engine import Settings, run
from ._parameters import ParameterSet, identical_columns, parameterise
from ._progress import Progress, ProgressFn
from ._residuals import Problem, auto_eigenvalue_weights
from ._result import Iteration, UpdateResult


def active_mask(test: ModalData, options) -> np.ndarray:
    ids = np.arange(1, len(test.frequencies_hz) + 1)
    active = np.ones(len(ids), bool) if options.active_modes is None else np.isin(ids, options.active_modes)
    active &= ~np.isin(ids, options.passive_modes)
    for key in ("active_modes", "passive_modes"):
        unknown = sorted(set(getattr(options, key) or ()) - set(ids.tolist()))
        if unknown:
            raise ValueError(f"options.{key}: {unknown} are not test mode numbers 1..{len(ids)}")
    if not active.any():
        raise ValueError("no active test modes: options.passive_modes holds every test mode")
    return active


def underdetermined(problem: Problem, options) -> str | None:
    """Why the fit is under-determined, or None: more parameters than data rows (active
    test modes × (1 eigenvalue row + one eigenvector row per sensor), as ``residual``
    chooses). Then JᵀJ is singular: Gauss–Newton has no step without regularisation;
    Levenberg–Marquardt (or μ > 0) picks one of the many minima, and "converged" says
    nothing about the parameters."""
    n_p = len(problem.parameterisation.parameters)
    active, n_s = int(np.sum(np.asarray(problem.active))), int(problem.C.shape[0])
    per_mode = int(problem.use_lam) + n_s * int(problem.use_phi)
    n_rows = active * per_mode
    if n_p <= n_rows:
        return None
    many = lambda n, what: f"{n} {what}" + ("" if n == 1 else "s")  # noqa: E731
    return (f"{many(n_p, 'parameter')} but {many(n_rows, 'residual row')} ({many(active, 'active test mode')} × "
            f"{many(per_mode, 'row')}, residual = {options.residual!r}): the fit is under-determined")


def build_problem(model: Model, test: ModalData, parameters: ParameterSet,
                  *, sensors_C: np.ndarray | None = None) -> Problem:
    """Assemble the :class:`Problem` (observation matrix, weights, pairing thresholds)."""
    opts = parameters.options
    model, param = parameterise(model, parameters)
    C = observation_matrix(model, test.sensors)[0] if sensors_C is None else sensors_C
    shapes = np.real(test.real().shapes) if np.iscomplexobj(test.shapes) else np.asarray(test.shapes)
    ne = len(test.frequencies_hz)
    n_model = n_model_modes(model, ne, opts.n_model_modes)
    values, structure = jaxfem.partition(model)
    problem = Problem(
        values=values,
        structure=Opaque(structure),
        parameterisation=param,
        lam_e=jnp.asarray((2 * np.pi * np.asarray(test.frequencies_hz)) ** 2),
        phi_e=jnp.asarray(shapes),
        C=jnp.asarray(C),
        active=jnp.asarray(active_mask(test, opts)),
        lam_weight=jnp.ones(ne),
        mu=jnp.asarray(float(opts.regularisation)),
        n_model=int(n_model),
        use_lam=opts.residual in ("eigenvalue", "combined"),
        use_phi=opts.residual in ("eigenvector", "combined"),
        min_mac=float(opts.min_mac),
        max_freq_dev=float(opts.max_freq_dev),
        sparse=resolve_eigensolver(opts.eigensolver, model),
    )
    theta0 = jnp.zeros(len(param.parameters))
    if opts.residual == "combined":
        w = auto_eigenvalue_weights(theta0, problem) if opts.eigenvalue_weight == "auto" \
            else jnp.full(ne, float(opts.eigenvalue_weight))
        problem = eqx.tree_at(lambda p: p.lam_weight, problem, w)
    return problem


def n_model_modes(model: Model, n_test: int, requested: int | None = None) -> int:
    """Model modes computed for pairing with ``n_test`` test modes: ``requested``, else
    n_test + max(6, n_test): twice the test modes, at least six spare (room for rigid-body,
    crossing and spurious modes); at most the free DoFs."""
    n_free = model.n_dof - len(model.dofs.massless)
    return int(min(n_free, requested or n_test + max(6, n_test)))


def sensor_modes(ev) -> tuple[np.ndarray, np.ndarray]:
    """All computed model modes of one evaluation: frequencies (Hz) and shapes at the sensors."""
    return np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model)


def evaluation_pairing(ev, test: ModalData, problem: Problem):
    """Exact (Hungarian) pairing of all computed model modes of one evaluation
    (:class:`Evaluation`) with the test modes, at the problem's thresholds, for reports."""
    return pair_modes(*sensor_modes(ev), np.asarray(test.frequencies_hz), np.asarray(problem.phi_e),
                      min_mac=problem.min_mac, max_freq_dev=problem.max_freq_dev)


def update(model: Model, test: ModalData, parameters: ParameterSet, *,
           progress: ProgressFn | None = None) -> UpdateResult:
    """Update ``model`` against measured modes ``test`` (thesis §3.2, Fig. 3.1): the engine
    (:func:`updating._engine.run`) with the dense eigensolver, from α = 0.

    **Arguments:** the nominal model, the measured modes (sensors labelled by grid and
    direction), the parameters and options; ``progress`` (:class:`updating.Progress`) after every
    accepted iteration, its ``detail`` the :class:`Iteration`. **Returns:** an :class:`UpdateResult`.

    Two parameters on the same targets (:func:`identical_columns`) or more parameters
    than residual rows (:func:`underdetermined`), where JᵀJ is singular: a ``ValueError``
    before the loop with Gauss–Newton and no regularisation (it has no step), else
    a ``UserWarning``, kept in the result's ``warnings``.
    """
    start = time.perf_counter()
    problem = build_problem(model, test, parameters)
    settings = Settings.from_options(parameters.options)
    notes = []
    plain_gauss_newton = settings.gauss_newton and parameters.options.regularisation == 0
    for why, remedy in ((identical_columns(model, problem.parameterisation.parameters), "keep one of each pair"),
                        (underdetermined(problem, parameters.options), "use fewer parameters or more test modes")):
        if why is None:
            continue
        if plain_gauss_newton:  # JᵀJ singular: no step (a NaN model and a traceback, before)
            raise ValueError(f"{why}: Gauss–Newton has no unique step; {remedy}, or set options.regularisation "
                             "> 0 or solver = \"levenberg-marquardt\"")
        why += (f": α is one of many minimisers (the regularisation or the damping picks it) and 'converged' "
                f"does not mean identified; {remedy}")
        warnings.warn(why, UserWarning, stacklevel=2)
        notes.append(why)
    theta0 = jnp.zeros(len(problem.parameterisation.parameters))

    def report(k, alpha, cost, dev, mac):
        it = Iteration(k, alpha, dev, mac, cost)
        progress(Progress(f"iteration {int(k)}: cost {float(cost):.6e}", int(k), settings.max_iterations, it))

    state = Compiled(run)(theta0, problem, Direct(), jnp.zeros(0), settings, False, report if progress else None)
    h = state.history
    n = int(state.accepted)
    history = [Iteration(k, np.asarray(h.alpha[k]), np.asarray(h.freq_dev[k]), np.asarray(h.mac[k]),
                         float(h.cost[k])) for k in range(n + 1)]
    theta = state.theta
    return UpdateResult(
        model=problem.model(theta),
        names=[p.name for p in problem.parameterisation.parameters],
        alpha=np.asarray(jnp.expm1(theta)),
        theta=np.asarray(theta),
        converged=bool(state.converged),
        iterations=n,
        history=history,
        active=np.asarray(problem.active),
        before=evaluation_pairing(state.start, test, problem),
        after=evaluation_pairing(state.evaluation, test, problem),
        seconds=time.perf_counter() - start,
        sensor_modes={"before": sensor_modes(state.start), "after": sensor_modes(state.evaluation)},
        parameterisation=problem.parameterisation,
        warnings=tuple(notes),
    )
