"""A candidate's fits: the engine's Levenberg–Marquardt loop (:mod:`updating._engine`) on
all test modes and on each fold of a k-fold cross-validation (the thesis' active/passive
idea made systematic, §4.2.4.2). The candidates of one diagnosis share one compiled
solver: their masks (:class:`updating.Extension`) and the fold's mask are traced arguments,
and they are fitted on threads of one process sharing it (:func:`threaded`).
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from threadpoolctl import threadpool_limits

from jaxfem import FAST_COMPILE

from .. import (
    AbstractEigensolver,
    Compiled,
    Direct,
    Extension,
    Problem,
    Settings,
    paired_freq_dev,
    rows,
    run,
)
from ._effects import SCAN

EXTENSION_PARAMS = 2  # the most parameters of one extension (a log-factor and a second one)
REFINE = (-1.0, -0.5, 0.5, 1.0)  # log-factor steps about the best point of a one-factor scan


@dataclass(frozen=True)
class Fit:
    """One fit on all test modes: θ, cost Σ row² (frequency + shape parts), Δf (fraction)
    and MAC per test mode (NaN where unpaired), the Jacobian of the residual rows (None
    and ``error`` set where a trial step made the model non-finite; cost inf)."""

    theta: np.ndarray
    cost: float
    cost_freq: float
    cost_shape: float
    freq_dev: np.ndarray
    mac: np.ndarray
    jac: np.ndarray | None
    error: str | None = None


@dataclass(frozen=True)
class Loop:
    """One fit's loop: θ, each accepted iterate's factors α = e^θ − 1, cost ½‖ε‖², Δf
    (fraction) and MAC per test mode (row 0 the start), whether it converged, and the
    evaluations (:class:`updating.Evaluation`) at the start and at θ."""

    theta: np.ndarray
    alpha: np.ndarray
    cost: np.ndarray
    freq_dev: np.ndarray
    mac: np.ndarray
    converged: bool
    start: object
    end: object


@dataclass(frozen=True)
class HeldOut:
    """k-fold cross-validation of a fit: summed held-out costs (frequency, shape) and each
    test mode's Δf (fraction) and MAC when it was held out (NaN where unpaired)."""

    freq: float
    shape: float
    freq_dev: np.ndarray
    mac: np.ndarray


def _cost_parts(theta, problem: Problem, mask, ev):
    """Frequency and shape cost (Σ row²) of the test modes in ``mask`` at ``ev``; an
    unpaired mode costs the largest frequency deviation allowed and a whole shape."""
    eps = rows(theta, replace(problem, active=mask), ev)
    unpaired = mask & ~ev.paired
    freq = jnp.sum(eps["eigenvalue"] ** 2) + jnp.sum(jnp.where(unpaired, (problem.lam_weight * problem.max_freq_dev) ** 2, 0.0))
    return freq, jnp.sum(eps["eigenvector"] ** 2) + jnp.sum(jnp.where(unpaired, 1.0, 0.0))


def _solve_one(theta0, problem: Problem, settings: Settings, skip, solver: AbstractEigensolver):
    """One fit by the engine (``skip``: none, evaluate at θ₀) with ``solver``; at its θ the
    fitted and held-out costs (frequency, shape), the paired eigenvalues and MAC, and the
    Jacobian of the residual rows."""
    state = run(theta0, problem, solver, jnp.zeros(0), settings, skip, evaluate_skipped=True)
    ev, jac = state.evaluation, state.jacobian
    fit, held = (_cost_parts(state.theta, problem, mask, ev) for mask in (problem.active, ~problem.active))
    loop = (state.history, state.accepted, state.converged, state.start, ev)
    return state.theta, fit, held, ev.lam_a, ev.paired, ev.mac, jac[:-state.theta.shape[0]], loop


def _cost_one(theta, problem: Problem, solver: AbstractEigensolver):
    """The cost of :func:`_solve_one` at θ without its step and Jacobian (a scan point)."""
    ev = solver(theta, problem, jnp.zeros(0))[0]
    return sum(_cost_parts(theta, problem, problem.active, ev))


class Fits:
    """The compiled fit of one diagnosis (freed with it, see :mod:`._compiled`) and its
    compiled cost, the fit's evaluation without step or Jacobian (a scan point: 75 ms
    against 250 ms through the fit at 628 DoFs). ``solver``: the problem's own eigensolver
    (:class:`Direct`) or a candidate's reduced one. Both are compiled with
    :data:`jaxfem.FAST_COMPILE`: a diagnosis compiles them a few times and runs each some
    hundred steps, and compiling dominated (a GARTEUR fit 12.5 s to compile)."""

    def __init__(self, settings: Settings):
        self._solve, self._cost, self.settings = Compiled(_solve_one, FAST_COMPILE), Compiled(_cost_one, FAST_COMPILE), settings

    def solve(self, theta0, problem: Problem, solver: AbstractEigensolver = Direct(), skip: bool = False):
        """θ₀ padded with inert zeros to the engineer's parameters and :data:`EXTENSION_PARAMS`:
        one compiled fit for extensions of one parameter and of two (each compiled fit took
        14–24 s at 33,000 DoFs). An inert entry changes no model; its Jacobian column is
        its regularisation row alone, so its step is zero and θ, costs and Jacobian are
        those of the unpadded fit (they are returned so)."""
        return self._run(theta0, problem, solver, skip)[:-1]

    def loop(self, theta0, problem: Problem, solver: AbstractEigensolver = Direct(), skip: bool = False) -> Loop:
        """A fit (:meth:`solve`) with its loop kept, for an update's report."""
        theta, *_, (history, accepted, converged, start, end) = self._run(theta0, problem, solver, skip)
        n, rows_ = theta.shape[0], int(accepted) + 1
        return Loop(np.asarray(theta), np.asarray(history.alpha)[:rows_, :n], np.asarray(history.cost)[:rows_],
                    np.asarray(history.freq_dev)[:rows_], np.asarray(history.mac)[:rows_], bool(converged), start, end)

    def _run(self, theta0, problem: Problem, solver: AbstractEigensolver, skip: bool):
        n = jnp.asarray(theta0).shape[0]
        out = self._solve(self._padded(theta0, problem), problem, self.settings, jnp.asarray(skip), solver)
        return (out[0][:n], *out[1:-2], out[-2][:, :n], out[-1])

    @staticmethod
    def _padded(theta, problem: Problem):
        theta = jnp.asarray(theta)
        width = max(theta.shape[0], len(problem.parameterisation.parameters) + EXTENSION_PARAMS)
        return jnp.pad(theta, (0, width - theta.shape[0]))

    def cost(self, theta, problem: Problem, solver: AbstractEigensolver = Direct()) -> float:
        """The cost at θ; inf where the model there is not solvable (a point of a scan that
        makes K + σM indefinite is no candidate's start: :func:`fit` reports it likewise)."""
        try:
            return float(self._cost(self._padded(theta, problem), problem, solver))
        except (RuntimeError, ValueError) as err:
            if not unsolvable(err):
                raise
            return float("inf")


def with_extension(problem: Problem, ext: Extension, mask=None) -> Problem:
    """``problem`` with a candidate's masks (and a fold's mask of fitted modes)."""
    if mask is None:
        return eqx.tree_at(lambda q: q.extension, problem, ext, is_leaf=lambda x: x is None)
    return eqx.tree_at(lambda q: (q.extension, q.active), problem, (ext, jnp.asarray(mask)),
                       is_leaf=lambda x: x is None)


def scan_costs(fits: Fits, problem: Problem, ext: Extension, theta_b: np.ndarray, grid=SCAN,
               solver: AbstractEigensolver = Direct()) -> np.ndarray:
    """Cost at each point of a coarse grid of the effect's log-factors."""
    p = with_extension(problem, ext, np.ones(problem.lam_e.shape[0], bool))
    return np.array([fits.cost(np.append(theta_b, t), p, solver) for t in grid])


def scan_start(fits: Fits, problem: Problem, ext: Extension, theta_b: np.ndarray, grid=SCAN,
               solver: AbstractEigensolver = Direct()) -> np.ndarray:
    """Best starting θ of an effect on a coarse grid: a fit from the reference alone can
    stall where modes swap partners on the way (a much softer joint, a heavy added mass,
    a strong frequency law). The grid's first factor is then refined about its best point
    (:data:`REFINE`): a heavy mass brings its own mode into the band, and the valley where
    every mode pairs can be narrower than the grid's steps."""
    costs = list(scan_costs(fits, problem, ext, theta_b, grid, solver))
    best = np.asarray(grid[int(np.argmin(costs))], float)
    step = np.eye(best.size)[0].reshape(best.shape)
    grid = list(grid) + [best + d * step for d in REFINE]
    costs += list(scan_costs(fits, problem, ext, theta_b, grid[len(costs):], solver))
    return np.atleast_1d(np.asarray(grid[int(np.argmin(costs))], float))


def candidate_fit(fits: Fits, problem: Problem, ext: Extension, theta_b: np.ndarray, scan, theta0,
                  solver: AbstractEigensolver = Direct()) -> tuple[np.ndarray, Fit]:
    """A shortlisted candidate's start (the best point of its ``scan`` grid, or ``theta0``
    without one) and its fit on all modes: ``(θ₀, fit)``."""
    if scan is not None:
        theta0 = scan_start(fits, problem, ext, theta_b, scan, solver)
    return theta0, fit(fits, problem, ext, np.concatenate([theta_b, theta0]), solver)


def soft_fits(fits: Fits, problem: Problem, cands: list, theta_b: np.ndarray, solver, threads: int | None) -> list[Fit]:
    """Each candidate fitted from its scan's softest point, the engineer's factors free: a
    scan holds them at the baseline's, which may compensate the very softness scanned
    (GARTEUR joint and mass, round 2: the true joint's scan rose 0.30 → 0.56 against a
    baseline cost of 0.27, its fit from the scan's end fell to 0.002). ``solver(c)``: its eigensolver."""
    def one(c) -> Fit:
        return fit(fits, problem, c.ext, np.concatenate([theta_b, min(c.scan, key=np.sum)]), solver(c))

    return list(threaded(one, cands, threads))


def unsolvable(err: Exception) -> bool:
    """Whether ``err`` is a check of the compiled solve failing at runtime (K + σM
    indefinite, a non-finite model): a RuntimeError, or, from a host callback, a ValueError
    (a fit on a thread at 33k) — not a programming error."""
    return isinstance(err, RuntimeError) or "CpuCallback error" in str(err)


def failure_reason(err: Exception) -> str:
    """The check's own message from a failed compiled solve (a host callback wraps it in
    a traceback whose first line says only "CpuCallback error")."""
    lines = str(err).splitlines()
    for line in lines:
        if "RuntimeError: " in line:
            return line.split("RuntimeError: ", 1)[1].strip()
    return lines[0] if lines else type(err).__name__


def fold_masks(n: int, folds: int) -> list[np.ndarray]:
    """All modes, then one mask per fold (mode i held out in fold i mod k)."""
    ids = np.arange(n)
    return [np.ones(n, bool)] + [ids % folds != k for k in range(min(folds, n))]


def fit(fits: Fits, problem: Problem, ext: Extension, theta0, solver: AbstractEigensolver = Direct(),
        skip: bool = False) -> Fit:
    """Fit one extension on all modes (``skip``: evaluate at θ₀)."""
    lam_e = np.asarray(problem.lam_e)
    try:
        out = jax.tree.map(np.asarray, fits.solve(theta0, with_extension(problem, ext, np.ones(len(lam_e), bool)),
                                                  solver, skip))
    except (RuntimeError, ValueError) as err:  # a trial step made the model non-finite: report, do not rank
        if not unsolvable(err):
            raise
        return Fit(np.asarray(theta0), float("inf"), float("nan"), float("nan"), np.full(len(lam_e), np.nan),
                   np.full(len(lam_e), np.nan), None, failure_reason(err))
    theta, (cf, cs), _, lam_a, paired, macs, jac = out
    return Fit(theta, float(cf + cs), float(cf), float(cs), _deviation(lam_a, paired, lam_e),
               np.where(paired, macs, np.nan), jac)


def cross_validate(fits: Fits, problem: Problem, ext: Extension, result: Fit, masks,
                   solver: AbstractEigensolver = Direct(), threads: int | None = 1) -> HeldOut:
    """Held-out costs and Δf, MAC per test mode, each fold fitted from the all-modes fit
    (on ``threads``, :func:`threaded`)."""
    lam_e = np.asarray(problem.lam_e)
    dev, macs_out, cf, cs = np.full(len(lam_e), np.nan), np.full(len(lam_e), np.nan), 0.0, 0.0
    solved = threaded(lambda m: fits.solve(result.theta, with_extension(problem, ext, m), solver), masks[1:], threads)
    for m, (_, _, (hf, hs), lam_a, paired, macs, _) in zip(masks[1:], solved):
        cf += float(hf)
        cs += float(hs)
        dev[~m] = _deviation(np.asarray(lam_a), np.asarray(paired), lam_e)[~m]
        macs_out[~m] = np.where(np.asarray(paired), np.asarray(macs), np.nan)[~m]
    return HeldOut(cf, cs, dev, macs_out)


def _deviation(lam_a, paired, lam_e) -> np.ndarray:
    return np.asarray(paired_freq_dev(jnp.asarray(lam_a), jnp.asarray(paired), jnp.asarray(lam_e)))


def threaded(fn, jobs: list, threads: int | None):
    """``fn(job)`` of each job, in order, on ``threads`` threads (None: one per CPU this
    process may use, at most ``OMP_NUM_THREADS`` where that is set: a process given one
    thread, as a test worker beside others is, fits one candidate at a time). The fits
    share one compiled solver; on threads, BLAS and LAPACK run on one thread each (two
    two-thread OpenBLAS calls oversubscribed two cores: a diagnosis 77–85 s, 56–67 s so)."""
    if threads is None:
        threads = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        budget = os.environ.get("OMP_NUM_THREADS", "")
        threads = min(threads, int(budget)) if budget.isdigit() and int(budget) > 0 else threads
    if threads <= 1 or len(jobs) <= 1:
        yield from map(fn, jobs)
        return
    with threadpool_limits(1, user_api="blas"), ThreadPoolExecutor(threads) as pool:
        yield from pool.map(fn, jobs)
