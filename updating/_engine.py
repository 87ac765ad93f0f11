"""The updating engine: one regularised least-squares loop for every use (thesis §3.2).

:func:`run` minimises ½‖ε(θ)‖² (eq. 3.4, the weights inside ε, residual rows of
``updating._residuals``) by Optimistix Gauss–Newton or Levenberg–Marquardt (the step of
eq. 3.11), stepped in a ``lax.while_loop``: jittable and vmappable, one sample
of a Monte-Carlo study or one fit of a diagnosis as much as an engineer's update.

One stopping rule: converged when an accepted step changes no factor α = e^θ − 1 by more
than ``tolerance`` (thesis §4.2.5.1), or when Optimistix' own Cauchy test
(rtol = atol = 1e-12) ends the loop without a step; at most ``max_iterations`` accepted
steps and ``max_steps`` steps in all (rejected Levenberg–Marquardt steps included).

The state is a typed :class:`State`; the iterates are kept in fixed-size arrays
(:class:`History`, one row per accepted iterate, row 0 the start). The Jacobian is
forward mode through the eigensolver's derivative rule (:mod:`updating._eigensolvers`),
computed in the same pass as the residual; the step's least-squares problem is solved by
:class:`updating._qr.HouseholderQR`.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Bool, Float, Int

import jaxfem

from ._eigensolvers import AbstractEigensolver
from ._parameters import Options
from ._qr import HouseholderQR
from ._residuals import Evaluation, Problem, paired_freq_dev, rows

SOLVER_TOL = 1e-12  # Optimistix' Cauchy test (rtol = atol), the solver's own stopping rule


class Settings(eqx.Module):
    """The loop's settings (static): solver, the α-change ``tolerance`` (§4.2.5.1),
    ``max_iterations`` accepted steps, ``max_steps`` steps in all. With ``relative`` the
    tolerance is on the relative change of each factor, |Δθ| = |Δ ln(1 + α)|: for
    factors far from 1 (a softened joint, a woken added mass) a small Δα is no convergence.
    ``cost_tolerance`` (> 0): also converged when the undamped Gauss–Newton step from the
    accepted iterate predicts a cost decrease ½(‖ε‖² − ‖ε + J δ‖²) below it — a flat
    valley (a released joint's stiffness, which any value past the release fits alike)
    where θ moves by more than ``tolerance`` at every step and the cost by nothing."""

    gauss_newton: bool = eqx.field(static=True)
    tolerance: float = eqx.field(static=True)
    max_iterations: int = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    relative: bool = eqx.field(static=True, default=False)
    cost_tolerance: float = eqx.field(static=True, default=0.0)

    @classmethod
    def from_options(cls, options: Options, *, max_steps: int | None = None) -> Settings:
        """From the ``[options]`` of a parameter file; ``max_steps`` defaults to 4 × max_iterations."""
        return cls(options.solver == "gauss-newton", float(options.tolerance), int(options.max_iterations),
                   int(max_steps or 4 * options.max_iterations))


class History(eqx.Module):
    """The accepted iterates, row 0 the start; rows past ``State.accepted`` are NaN.
    ``alpha`` (h, p) factors; ``cost`` (h,) ½‖ε‖²; ``freq_dev`` (h, n_e) relative
    deviation f_a/f_e − 1 per test mode and ``mac`` (h, n_e), NaN where unpaired."""

    alpha: Float[Array, "h p"]
    cost: Float[Array, " h"]
    freq_dev: Float[Array, "h ne"]
    mac: Float[Array, "h ne"]


class State(eqx.Module):
    """The loop state after :func:`run`: ``theta`` (the last accepted iterate), the
    Optimistix state's arrays, the warm start, counts, flags, the history, the
    evaluations at the start and at ``theta``, and the Jacobian there."""

    theta: Float[Array, " p"]
    solver: object
    warm: Array
    accepted: Int[Array, ""]
    steps: Int[Array, ""]
    converged: Bool[Array, ""]
    change: Float[Array, ""]  # largest factor change of the last accepted step
    solved: Bool[Array, ""]  # every evaluated eigen solve converged
    refreshes: Int[Array, ""]  # evaluations that needed a fresh preconditioner
    done: Bool[Array, ""]
    history: History
    start: Evaluation
    evaluation: Evaluation
    jacobian: Float[Array, "m p"]  # of ε at ``theta``: the one the loop made there


class _Aux(eqx.Module):
    ev: Evaluation
    warm: Array
    solved: Bool[Array, ""]
    refreshed: Bool[Array, ""]


@jax.custom_jvp
def _attach(theta, eps, jac):
    """``eps`` whose derivative in θ is ``jac``: the linearisation Optimistix keeps in its
    loop state is then the small Jacobian, not every intermediate of the eigen solve,
    which a ``while_loop`` would copy at every step."""
    return eps


@_attach.defjvp
def _attach_jvp(primals, tangents):
    _, eps, jac = primals
    return eps, jac @ tangents[0]


TANGENT_DOFS = 200_000  # above SPARSE_ABOVE DoFs, the Jacobian takes TANGENT_DOFS // n_dof tangents at a time


def linearise(theta, problem: Problem, warm: Array, eigensolver: AbstractEigensolver):
    """ε(θ) as one vector (eigenvalue, eigenvector, regularisation rows), its forward-mode
    Jacobian computed in the same pass, and the eigensolver's auxiliary output."""

    def flat(t):
        ev, new_warm, solved, refreshed = eigensolver(t, problem, warm)
        eps = rows(t, problem, ev)
        return jnp.concatenate([jnp.ravel(v) for v in jax.tree.leaves(eps)]), _Aux(ev, new_warm, solved, refreshed)

    t = jax.lax.stop_gradient(theta)
    eps, lin, aux = jax.linearize(flat, t, has_aux=True)
    eye = jnp.eye(t.shape[0], dtype=t.dtype)
    n_dof = problem.C.shape[1]
    if n_dof <= jaxfem.SPARSE_ABOVE:
        return eps, jax.vmap(lin, out_axes=1)(eye), aux
    # large models: the element-block tangents of all parameters at once would not fit
    # (20 at 100,000 DoFs: more than 24 GB); a few at a time, the factorisations cached
    return eps, jax.lax.map(lin, eye, batch_size=max(1, TANGENT_DOFS // n_dof)).T, aux


def _residual(theta, args, eigensolver: AbstractEigensolver):
    """ε(θ) whose derivative is the Jacobian of :func:`linearise`."""
    eps, jac, aux = linearise(theta, *args, eigensolver)
    return _attach(theta, eps, jac), aux


def _solver(settings: Settings):
    cls = optx.GaussNewton if settings.gauss_newton else optx.LevenbergMarquardt
    return cls(rtol=SOLVER_TOL, atol=SOLVER_TOL, linear_solver=HouseholderQR())


def _row(theta, cost, ev: Evaluation, problem: Problem):
    dev = paired_freq_dev(ev.lam_a, ev.paired, problem.lam_e)
    return jnp.expm1(theta), cost, dev, jnp.where(ev.paired, ev.mac, jnp.nan)


Progress = Callable[[int, np.ndarray, float, np.ndarray, np.ndarray], None]


def _converged(opt, new, moved, change, settings: Settings):
    """The step taken and the undamped Gauss–Newton step from its end both within the
    tolerance (a Levenberg–Marquardt step is damped, λ = 1 at first, and where JᵀJ ≪ 1 — a
    softened seam's stiffness — it is short however far the minimum lies), or the
    Gauss–Newton step predicting less than ``cost_tolerance`` (:class:`Settings`).
    Minimum-norm lstsq, not the step's QR: a padded inert column is zero where μ = 0
    (updating.diagnosis._fit.Fits)."""
    r, J = opt.f_info.residual, opt.f_info.jac.as_matrix()
    gn = jnp.linalg.lstsq(J, -r)[0]
    remaining = jnp.max(jnp.abs(gn) if settings.relative else jnp.abs(jnp.expm1(new + gn) - jnp.expm1(new)))
    converged = (moved & (change <= settings.tolerance) & (remaining <= settings.tolerance)) | (opt.terminate & ~moved)
    if settings.cost_tolerance > 0:
        flat = 0.5 * (jnp.sum(r ** 2) - jnp.sum((r + J @ gn) ** 2)) <= settings.cost_tolerance
        converged = converged | (moved & flat)
    return converged


def run(theta0: Float[Array, " p"], problem: Problem, eigensolver: AbstractEigensolver, warm: Array,
        settings: Settings, skip: Bool[Array, ""] | bool = False, progress: Progress | None = None,
        evaluate_skipped: bool = False) -> State:
    """Update from ``theta0``: the loop of :func:`updating.update`, one jittable function.

    **Arguments:** the start θ₀ = log(1 + α₀); the :class:`Problem`; the eigensolver and
    its first warm start; the :class:`Settings`; ``skip``: take no step (padding samples
    of a batch; with ``evaluate_skipped``, θ₀ is still evaluated: a cost and its
    Jacobian); ``progress(iteration, α, cost, Δf, MAC)``: called on the host after every
    accepted iterate (``jax.debug.callback``; not under ``vmap``).

    **Returns:** the final :class:`State`.
    """
    solver = _solver(settings)
    fn = lambda t, a: _residual(t, a, eigensolver)
    # Plain shapes: inside shard_map eval_shape attaches the manual mesh.
    f_struct, aux_struct = jax.tree.map(lambda s: jax.ShapeDtypeStruct(s.shape, s.dtype),
                                        jax.eval_shape(fn, theta0, (problem, warm)))
    options = {"jac": "fwd"}
    state0 = solver.init(fn, theta0, (problem, warm), options, f_struct, aux_struct, frozenset())
    arrays, static = eqx.partition(state0, eqx.is_array)  # the state holds a jaxpr: carry only arrays
    h = settings.max_iterations + 1
    n_p, n_e = theta0.shape[0], problem.lam_e.shape[0]
    nan = jnp.asarray(jnp.nan, theta0.dtype)
    history = History(jnp.full((h, n_p), nan), jnp.full(h, nan), jnp.full((h, n_e), nan), jnp.full((h, n_e), nan))

    def emit(k, row):
        jax.debug.callback(lambda k, a, c, d, m: progress(int(k), np.asarray(a), float(c), np.asarray(d),
                                                          np.asarray(m)), k, *row, ordered=True)

    def body(s: State) -> State:
        new, opt, _ = solver.step(fn, s.theta, (problem, s.warm), options, eqx.combine(s.solver, static),
                                  frozenset())
        aux: _Aux = opt.aux
        cost = 0.5 * jnp.sum(opt.f_info.residual ** 2)
        first = s.steps == 0  # the first step evaluates the start and accepts it
        moved = jnp.any(new != s.theta)
        change = jnp.max(jnp.abs(new - s.theta) if settings.relative else jnp.abs(jnp.expm1(new) - jnp.expm1(s.theta)))
        accepted = s.accepted + moved.astype(jnp.int32)
        row = _row(new, cost, aux.ev, problem)
        slot = jnp.where(first, 0, accepted)
        write = first | moved
        history = jax.tree.map(lambda hist, r: hist.at[slot].set(jnp.where(write, r, hist[slot])), s.history,
                               History(*row))
        if progress is not None:
            jax.lax.cond(write, lambda: emit(slot, row), lambda: None)
        converged = _converged(opt, new, moved, change, settings)
        steps = s.steps + 1
        done = converged | (accepted >= settings.max_iterations) | (steps >= settings.max_steps) \
            | ~jnp.all(jnp.isfinite(new)) | skip
        start = jax.tree.map(lambda a, b: jnp.where(first, a, b), aux.ev, s.start)
        return State(new, eqx.filter(opt, eqx.is_array), aux.warm, accepted, steps, converged,
                     jnp.where(moved, change, s.change), s.solved & aux.solved,
                     s.refreshes + aux.refreshed.astype(jnp.int32), done, history, start, aux.ev,
                     s.jacobian)

    ev0 = jax.tree.map(jnp.zeros_like, arrays.aux.ev)
    s0 = State(theta0, arrays, warm, jnp.asarray(0), jnp.asarray(0), jnp.asarray(False),
               jnp.asarray(jnp.inf, theta0.dtype), jnp.asarray(True), jnp.asarray(0),
               jnp.asarray(False) if evaluate_skipped else jnp.asarray(skip), history,
               ev0, ev0, jnp.zeros(f_struct.shape + (n_p,), theta0.dtype))
    final = jax.lax.while_loop(lambda s: ~s.done, body, s0)
    # the last accepted linearisation, at ``theta`` (the Jacobian a second solve would make)
    jac = eqx.combine(final.solver, static).f_info.jac.as_matrix()
    return eqx.tree_at(lambda s: s.jacobian, final, jac)
