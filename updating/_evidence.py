"""Evidence for a candidate effect: its fits, its Bayesian evidence, its held-out error,
and the verdict that cannot contradict itself.

Every fit is the engine's Levenberg–Marquardt loop (:mod:`updating._engine`); the
candidates of one diagnosis share one compiled solver (their masks
(:class:`~updating._extension.Extension`) and the fold's mask are traced arguments).

**Evidence** (MacKay 1992; Sivia & Skilling 2006, §3.3): the residual rows are weighted
so that each carries the stated noise σ² (:func:`updating.diagnose`), the likelihood is
Gaussian, and each free log-factor θ has a normal prior (the kind's ``prior_sd`` about
its reference; the engineer's parameters σ = 3). The Laplace approximation at the fitted
θ* gives

    ln Z = −½ χ²(θ*) − ½ Σ z_i² − Σ ln s_i − ½ ln det H,   H = JᵀJ/σ² + diag(1/s²),

with z_i = (θ*_i − μ_i)/s_i; everything after −½ χ² is the log Occam factor, the price of
the parameters' freedom. When even the best candidate leaves χ² per row above 1 (model
form error), σ² is scaled by that χ² per row (the Birge ratio) so that one misfit does not
turn small differences into certainties; the scale is reported. The posterior over the
candidates and the baseline (equal prior odds) is softmax(ln Z).

**Held-out error**: k-fold cross-validation over the test modes (fit on the others,
predict the held-out ones — the thesis' active/passive idea made systematic, §4.2.4.2),
in frequencies and in shapes separately.
"""

from __future__ import annotations

from dataclasses import replace

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._candidates import Candidate
from ._compiled import Compiled
from ._effects import SCAN
from ._eigensolvers import AbstractEigensolver, Direct
from ._engine import Settings, run
from ._extension import Extension
from ._report import rms_pct
from ._residuals import Problem, rows

BASELINE_SD = 3.0  # prior σ of the engineer's log-factors (the fits' ridge, see diagnose)
DECISIVE = np.log(20.0)  # ln Bayes factor an effect needs over the baseline ("strong", Kass & Raftery 1995)
TIE = 1.0  # ln Bayes factor below which two places of one kind explain the data equally
REFINE = (-1.0, -0.5, 0.5, 1.0)  # log-factor steps about the best point of a one-factor scan
EXTENSION_PARAMS = 2  # the most parameters of one extension (a log-factor and a second one)
UNEXPLAINED_CHI2 = 4.0  # χ² per row above which the baseline does not explain the data (residuals 2× noise)


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
    return state.theta, fit, held, ev.lam_a, ev.paired, ev.mac, jac[:-state.theta.shape[0]]


class Fits:
    """The compiled fit of one diagnosis (freed with it, see :mod:`._compiled`); a cost
    is the fit without a step (one compiled function, not two). ``solver``: the problem's
    own eigensolver (:class:`Direct`) or a candidate's reduced one."""

    def __init__(self, settings: Settings):
        self._solve, self.settings = Compiled(_solve_one), settings

    def solve(self, theta0, problem: Problem, solver: AbstractEigensolver = Direct(), skip: bool = False):
        """θ₀ padded with inert zeros to the engineer's parameters and :data:`EXTENSION_PARAMS`:
        one compiled fit for extensions of one parameter and of two (each compiled fit took
        14–24 s at 33,000 DoFs). An inert entry changes no model; its Jacobian column is
        its regularisation row alone, so its step is zero and θ, costs and Jacobian are
        those of the unpadded fit (they are returned so)."""
        theta0 = jnp.asarray(theta0)
        n = theta0.shape[0]
        width = max(n, len(problem.parameterisation.parameters) + EXTENSION_PARAMS)
        out = self._solve(jnp.pad(theta0, (0, width - n)), problem, self.settings, jnp.asarray(skip), solver)
        return (out[0][:n], *out[1:-1], out[-1][:, :n])

    def cost(self, theta, problem: Problem, solver: AbstractEigensolver = Direct()) -> float:
        return float(sum(self.solve(theta, problem, solver, skip=True)[1]))


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
                  solver: AbstractEigensolver = Direct()) -> tuple[np.ndarray, dict]:
    """A shortlisted candidate's start (the best point of its ``scan`` grid, or ``theta0``
    without one) and its fit on all modes: ``(θ₀, fit)``."""
    if scan is not None:
        theta0 = scan_start(fits, problem, ext, theta_b, scan, solver)
    return theta0, fit(fits, problem, ext, np.concatenate([theta_b, theta0]), solver)


def fold_masks(n: int, folds: int) -> list[np.ndarray]:
    """All modes, then one mask per fold (mode i held out in fold i mod k)."""
    ids = np.arange(n)
    return [np.ones(n, bool)] + [ids % folds != k for k in range(min(folds, n))]


def fit(fits: Fits, problem: Problem, ext: Extension, theta0, solver: AbstractEigensolver = Direct(),
        skip: bool = False) -> dict:
    """Fit one extension on all modes (``skip``: evaluate at θ₀): θ, cost (frequency +
    shape), Δf, MAC, Jacobian J."""
    lam_e = np.asarray(problem.lam_e)
    try:
        out = jax.tree.map(np.asarray, fits.solve(theta0, with_extension(problem, ext, np.ones(len(lam_e), bool)),
                                                  solver, skip))
    except (RuntimeError, ValueError) as err:  # a trial step made the model non-finite: report, do not rank
        if isinstance(err, ValueError) and "CpuCallback error" not in str(err):
            raise  # a check in a host callback arrives as either (a fit on a thread at 33k: ValueError)
        return {"theta": np.asarray(theta0), "cost": float("inf"), "freq_dev": np.full(len(lam_e), np.nan),
                "mac": np.full(len(lam_e), np.nan), "error": str(err).splitlines()[0]}
    theta, (cf, cs), _, lam_a, paired, macs, jac = out
    return {"theta": theta, "cost": float(cf + cs), "cost_freq": float(cf), "cost_shape": float(cs),
            "freq_dev": _deviation(lam_a, paired, lam_e), "mac": np.where(paired, macs, np.nan), "jac": jac}


def cross_validate(fits: Fits, problem: Problem, ext: Extension, res: dict, masks,
                   solver: AbstractEigensolver = Direct()) -> None:
    """Held-out costs (frequency, shape) and Δf per test mode, each fold fitted from the
    all-modes fit; stored in ``res``."""
    lam_e = np.asarray(problem.lam_e)
    res["heldout_freq_dev"] = np.full(len(lam_e), np.nan)
    res["heldout_mac"] = np.full(len(lam_e), np.nan)
    res["cv_freq"] = res["cv_shape"] = 0.0
    for m in masks[1:]:
        _, _, (hf, hs), lam_a, paired, macs, _ = fits.solve(res["theta"], with_extension(problem, ext, m), solver)
        res["cv_freq"] += float(hf)
        res["cv_shape"] += float(hs)
        res["heldout_freq_dev"][~m] = _deviation(np.asarray(lam_a), np.asarray(paired), lam_e)[~m]
        res["heldout_mac"][~m] = np.where(np.asarray(paired), np.asarray(macs), np.nan)[~m]


def _deviation(lam_a, paired, lam_e):
    return np.where(paired, np.sqrt(np.maximum(np.asarray(lam_a), 0) / lam_e) - 1, np.nan)


# ---------------------------------------------------------------------------------------
# Laplace evidence


def log_evidence(res: dict, mean: np.ndarray, sd: np.ndarray, sigma2: float) -> tuple[float, float, np.ndarray]:
    """ln Z, ln Occam factor and the posterior σ of each θ, by the Laplace approximation
    at the fitted θ* (module docstring); ``mean``, ``sd``: the prior of every θ."""
    if not np.isfinite(res["cost"]):
        return -np.inf, np.nan, np.full(len(mean), np.nan)
    J = np.asarray(res["jac"])
    H = J.T @ J / sigma2 + np.diag(1.0 / sd ** 2)
    sign, logdet = np.linalg.slogdet(H)
    z = (np.asarray(res["theta"]) - mean) / sd
    occam = -0.5 * np.sum(z ** 2) - np.sum(np.log(sd)) - 0.5 * logdet
    cov_sd = np.sqrt(np.maximum(np.diag(np.linalg.pinv(H)), 0.0))
    return -0.5 * res["cost"] / sigma2 + occam, occam, cov_sd


def _lowered(before: float, after: float, n: int, *, or_kept: bool = False) -> bool:
    """A held-out χ² of ``n`` rows lowered beyond its noise (by 2σ of a χ², 2√(2n)); with
    ``or_kept``, also kept at the noise level where the baseline already was there."""
    band = 2 * np.sqrt(2 * n)
    return after < before - band or (or_kept and before <= n + band and after <= n + band)


def evidence(short: list[Candidate], base: dict, n_b: int, rows_: tuple[int, int], sigma2: float,
             mass: float) -> tuple[list[dict], list[Candidate], dict]:
    """Rank the fitted candidates by posterior probability and test the best against the
    baseline; returns JSON rows (best first), the candidates in that order and a summary
    (``outcome``: "effect", "none_needed" or "unexplained"; ``noise_scale``; ``ties``).

    ``rows_``: (frequency rows, shape rows) of all test modes. The declared effect is the
    most probable candidate when it (a) is decisively more probable than the baseline,
    (b) lowers χ² beyond noise, (c) lowers the held-out error in frequencies beyond noise
    **and** in shapes beyond noise — or keeps shapes at the noise level where the baseline
    already predicts them that well (:func:`_lowered`), and (d) does not raise the held-out
    RMS Δf over the modes paired with and without it (the number shown: a winner whose
    error rises would contradict itself). Plausibility is the prior, not a cut.
    """
    n_f, n_s = rows_
    n_rows = n_f + n_s
    chi2_row = lambda r: r["cost"] / sigma2 / n_rows  # noqa: E731
    scale = max(1.0, min([chi2_row(base)] + [chi2_row(c.result) for c in short]))
    s2 = sigma2 * scale
    prior_b = (np.zeros(n_b + 1), np.full(n_b + 1, BASELINE_SD))
    base["log_evidence"], base["log_occam"], _ = log_evidence(base, *prior_b, s2)
    for c in short:
        mean, sd = c.prior()
        res = c.result
        res["log_evidence"], res["log_occam"], res["theta_sd"] = log_evidence(
            res, np.concatenate([np.zeros(n_b), mean]), np.concatenate([np.full(n_b, BASELINE_SD), sd]), s2)
        c.effect = c.reference.updated(res["theta"][n_b:])
    lz = np.array([base["log_evidence"]] + [c.result["log_evidence"] for c in short])
    post = np.exp(lz - lz.max())
    post /= post.sum()
    order = sorted(range(len(short)), key=lambda i: -lz[i + 1])
    effects = []
    for i in order:
        c, res = short[i], short[i].result
        cv = "cv_freq" in res
        notes = c.effect.plausibility(mass, c.reference) + ([f"fit failed: {res['error']}"] if "error" in res else [])
        checks = {
            "decisive_over_baseline": bool(lz[i + 1] - lz[0] >= DECISIVE),
            "chi2_lowered": bool(res["cost"] < base["cost"] - 2 * np.sqrt(2 * n_rows) * sigma2 * scale),
            "heldout_freq_lowered": bool(cv and _lowered(base["cv_freq"] / s2, res["cv_freq"] / s2, n_f)),
            "heldout_shape_lowered": bool(cv and _lowered(base["cv_shape"] / s2, res["cv_shape"] / s2, n_s,
                                                          or_kept=True)),
        }
        cv_base = base["cv_freq"] + base["cv_shape"]
        rms_before, rms_after, both = rms_pct(base["heldout_freq_dev"]), None, None
        if cv:  # over the modes paired with and without the effect: the numbers shown
            both = np.isfinite(base["heldout_freq_dev"]) & np.isfinite(res["heldout_freq_dev"])
            rms_before, rms_after = rms_pct(base["heldout_freq_dev"][both]), rms_pct(res["heldout_freq_dev"][both])
        checks["heldout_rms_not_higher"] = bool(cv and rms_after <= rms_before)
        effects.append({
            **c.effect.to_json(), "rank": len(effects) + 1,
            "posterior": float(post[i + 1]), "log_evidence": float(lz[i + 1] - lz[0]),
            "log_occam": float(res["log_occam"]),
            "theta_sd": [float(v) for v in res["theta_sd"][n_b:]],
            "advice": c.effect.advice(res["theta_sd"][n_b:]),
            "delta_aic": float(_aic(res["cost"], n_b + len(c.theta0), n_rows) - _aic(base["cost"], n_b, n_rows)),
            "score": float(100 * (1 - (res["cv_freq"] + res["cv_shape"]) / cv_base)) if cv else None,
            "screen": float(c.screen) if np.isfinite(c.screen) else None,
            "chi2_per_row": float(chi2_row(res)),
            "heldout_rms_freq_dev_pct_before": rms_before,
            "heldout_rms_freq_dev_pct_after": rms_after,
            "heldout_modes_compared": int(both.sum()) if cv else None,
            "heldout_mean_mac_before": _mean(base["heldout_mac"]),
            "heldout_mean_mac_after": _mean(res["heldout_mac"]) if cv else None,
            "rms_freq_dev_pct_after": rms_pct(res["freq_dev"]),
            "plausible": not notes, "plausibility": notes,
            "cross_validated": cv, "checks": checks, "warranted": False,
        })
    outcome, ties = "none_needed", []
    if effects:
        top = effects[0]
        top["warranted"] = all(top["checks"].values())
        if top["warranted"]:
            outcome = "effect"
            ties = [e for e in effects[1:] if e["kind"] == top["kind"]
                    and effects[0]["log_evidence"] - e["log_evidence"] < TIE]
    if outcome != "effect" and chi2_row(base) > UNEXPLAINED_CHI2:
        outcome = "unexplained"
    summary = {"outcome": outcome, "noise_scale": float(scale), "baseline_posterior": float(post[0]),
               "ties": [{k: e[k] for k in ("kind", "where", "nodes", "pids", "posterior", "log_evidence")}
                        for e in ties]}
    return effects, [short[i] for i in order], summary


def _aic(cost: float, k: int, n: int) -> float:
    return n * np.log(max(cost, 1e-300) / n) + 2 * k


def _mean(x) -> float | None:
    x = np.asarray(x, float)
    return float(np.nanmean(x)) if np.isfinite(x).any() else None


def verdict(report: dict) -> str:
    """One sentence an engineer can act on: the effect to add, with its uncertainty and
    what it does to the held-out error; or that none is needed; or that no single effect
    of the library explains the data."""
    b, outcome = report["baseline"], report["outcome"]
    if outcome == "effect":
        e = report["effects"][0]
        text = (f"{e['advice'][0].upper()}{e['advice'][1:]}: held-out frequency error "
                f"{e['heldout_rms_freq_dev_pct_before']:.2f} % → {e['heldout_rms_freq_dev_pct_after']:.2f} % "
                f"(posterior probability {e['posterior']:.2f}).")
        if report["ties"]:
            text += (" The sensors cannot tell it apart from " + ", ".join(t["where"] for t in report["ties"])
                     + " (Bayes factor below e): check those places too.")
        if e["chi2_per_row"] > UNEXPLAINED_CHI2:
            text += (f" χ² per row stays {e['chi2_per_row']:.1f} at the stated noise: more than this one effect "
                     "is missing.")
        return text
    partial = [e for e in report["effects"] if e["log_evidence"] > 0][:3]
    listed = "; ".join(f"{e['kind']} at {e['where']} (χ²/row {e['chi2_per_row']:.1f})" for e in partial)
    if outcome == "unexplained":
        return (f"No single effect explains the data: the baseline leaves χ² per row "
                f"{b['chi2_per_row']:.1f} at the stated noise (held-out RMS Δf {b['heldout_rms_freq_dev_pct']:.2f} %) "
                f"and no candidate passes the held-out tests"
                + (f"; best partial candidates: {listed}" if listed else "")
                + ". The missing physics lies outside the candidate library (model form, e.g. plates "
                  "modelled as beams; joints or supports not offered as candidates) or the stated noise "
                  "is too optimistic.")
    return (f"No extra effect is warranted: the baseline explains the data to the stated noise "
            f"(χ² per row {b['chi2_per_row']:.2f}, held-out RMS Δf {b['heldout_rms_freq_dev_pct']:.2f} %)"
            + (f"; candidates that did not pass: {listed}" if listed else "") + ".")


def combine(a: dict, b: dict) -> dict:
    """Mean of two indicators, each scaled to a maximum of 1; best first."""
    ta, tb = max(a.values(), default=1.0) or 1.0, max(b.values(), default=1.0) or 1.0
    keys = set(a) | set(b)
    out = {k: 0.5 * (a.get(k, 0.0) / ta + b.get(k, 0.0) / tb) for k in keys}
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))
