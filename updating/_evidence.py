"""Evidence for a candidate effect: fits with k-fold cross-validation over the test
modes, and the scores that rank them.

Every fit is the engine's Levenberg–Marquardt loop (:mod:`updating._engine`); candidates
of one model structure share one compiled solver, their masks
(:class:`~updating._extension.Extension`) and the fold's mask being traced arguments.
An effect is ranked by the share of the cross-validated (held-out) error it removes —
the thesis' active/passive idea made systematic, §4.2.4.2 — and by Akaike's criterion
``AIC = n ln(RSS/n) + 2k``, which charges for added parameters.
"""

from __future__ import annotations

from dataclasses import replace

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._candidates import Candidate
from ._compiled import Compiled
from ._effects import SCAN
from ._eigensolvers import Dense
from ._engine import Settings, run
from ._extension import Extension
from ._report import rms_pct
from ._residuals import Problem, evaluate, rows


def _cost_rows(theta, problem: Problem, mask, ev):
    """Residual rows of the test modes in ``mask`` at the evaluation ``ev`` (unpaired ones
    get the worst value)."""
    eps = rows(theta, replace(problem, active=mask), ev)
    cost = sum(jnp.sum(eps[k] ** 2) for k in ("eigenvalue", "eigenvector"))
    unpaired = mask & ~ev.paired
    penalty = jnp.sum(jnp.where(unpaired, (problem.lam_weight * problem.max_freq_dev) ** 2 + 1.0, 0.0))
    return cost + penalty


def _solve_one(theta0, problem: Problem, settings: Settings):
    """One fit by the engine; the fitted and the held-out cost from its last evaluation
    (pairing does not depend on the mask: one eigen solve for both)."""
    state = run(theta0, problem, Dense(), jnp.zeros(0), settings)
    theta, ev = state.theta, state.evaluation
    fit, held = (_cost_rows(theta, problem, mask, ev) for mask in (problem.active, ~problem.active))
    return theta, fit, held, ev.lam_a, ev.paired, ev.mac


def _cost_one(theta, problem: Problem):
    return _cost_rows(theta, problem, problem.active, evaluate(theta, problem))


class Fits:
    """The compiled fit and cost of one diagnosis (freed with it, see :mod:`._compiled`)."""

    def __init__(self):
        self.solve, self.cost = Compiled(_solve_one), Compiled(_cost_one)


def scan_start(fits: Fits, problem: Problem, ext: Extension, theta_b: np.ndarray, grid=SCAN) -> np.ndarray:
    """Best starting θ of an effect on a coarse grid: a fit from the reference alone can
    stall where modes swap partners on the way (a much softer joint, a heavy added mass,
    a strong frequency law)."""
    p = eqx.tree_at(lambda q: q.extension, problem, ext, is_leaf=lambda x: x is None)
    costs = [float(fits.cost(jnp.asarray(np.append(theta_b, t)), p)) for t in grid]
    return np.atleast_1d(np.asarray(grid[int(np.argmin(costs))], float))


def fold_masks(n: int, folds: int) -> list[np.ndarray]:
    """All modes, then one mask per fold (mode i held out in fold i mod k)."""
    ids = np.arange(n)
    return [np.ones(n, bool)] + [ids % folds != k for k in range(min(folds, n))]


def run_fits(fits: Fits, problem: Problem, exts: list, theta0s: list, masks, settings: Settings,
             keep=None) -> list[dict]:
    """Fit every extension on all modes, then on every fold (held-out mask) if
    ``keep(cost)`` (default: always); the folds start at the all-modes fit.

    All fits of one model structure share one compiled solver (the extension and the mask
    are traced arguments). They run in a host loop: ``vmap`` of the Optimistix loop stalled
    on XLA-CPU here (jax 0.10.2), and on CPU a batched eigensolve is no faster than a loop.
    """
    def fit(ext, th, m):
        p = eqx.tree_at(lambda q: (q.extension, q.active), problem, (ext, jnp.asarray(m)),
                        is_leaf=lambda x: x is None)
        return fits.solve(jnp.asarray(th), p, settings)

    lam_e = np.asarray(problem.lam_e)

    def deviation(out):
        return np.where(out[4], np.sqrt(np.maximum(np.asarray(out[3]), 0) / lam_e) - 1, np.nan)

    results = []
    for ext, th in zip(exts, theta0s):
        try:
            full = [np.asarray(o) for o in fit(ext, th, masks[0])]
        except RuntimeError as err:  # a trial step made the model non-finite: report, do not rank
            results.append({"theta": np.asarray(th), "cost": float("inf"), "cv_cost": float("nan"),
                            "freq_dev": np.full(len(lam_e), np.nan), "mac": np.full(len(lam_e), np.nan),
                            "heldout_freq_dev": np.full(len(lam_e), np.nan), "error": str(err).splitlines()[0]})
            continue
        res = {"theta": full[0], "cost": float(full[1]), "cv_cost": float("nan"), "freq_dev": deviation(full),
               "mac": np.where(full[4], full[5], np.nan), "heldout_freq_dev": np.full(len(lam_e), np.nan)}
        if keep is None or keep(res["cost"]):
            held = 0.0
            for m in masks[1:]:
                out = fit(ext, full[0], m)
                held += float(out[2])
                res["heldout_freq_dev"][~m] = deviation(out)[~m]
            res["cv_cost"] = held
        results.append(res)
    return results


def evidence(short: list[Candidate], base: dict, n_b: int, n_rows: int, sigma2: float, mass: float,
             min_score: float, min_delta_aic: float) -> tuple[list[dict], list[Candidate]]:
    """Score (% of the cross-validated error removed), ΔAIC and plausibility of every
    fitted candidate, which gets its fitted ``effect``; JSON rows and candidates, best
    first (warranted ones ahead)."""

    def aic(cost, k):
        return n_rows * np.log(max(cost, 1e-300) / n_rows) + 2 * k

    base_aic = aic(base["cost"], n_b)
    effects = []
    for c in short:
        res = c.result
        c.effect = fitted = c.reference.updated(res["theta"][n_b:])
        d_aic = aic(res["cost"], n_b + len(c.theta0)) - base_aic
        score = 100 * (1 - res["cv_cost"] / base["cv_cost"]) if base["cv_cost"] > 0 else 0.0  # NaN: not CV'd
        notes = fitted.plausibility(mass, c.reference) + ([f"fit failed: {res['error']}"] if "error" in res else [])
        effects.append({
            **fitted.to_json(), "score": float(score), "delta_aic": float(d_aic),
            "screen": float(c.screen) if np.isfinite(c.screen) else None,
            "chi2_per_row": float(res["cost"] / sigma2 / n_rows),
            "heldout_rms_freq_dev_pct_before": rms_pct(base["heldout_freq_dev"]),
            "heldout_rms_freq_dev_pct_after": rms_pct(res["heldout_freq_dev"]),
            "rms_freq_dev_pct_after": rms_pct(res["freq_dev"]),
            "plausible": not notes, "plausibility": notes,
            "warranted": bool(score >= min_score and -d_aic >= min_delta_aic and not notes),
            "cross_validated": bool(np.isfinite(score)),
        })
    order = sorted(range(len(effects)), key=lambda i: (
        -effects[i]["warranted"], -np.nan_to_num(effects[i]["score"], nan=-np.inf), effects[i]["delta_aic"]))
    for rank, i in enumerate(order, 1):
        effects[i]["rank"] = rank
    return [effects[i] for i in order], [short[i] for i in order]


def verdict(report: dict) -> str:
    """One sentence: the missing effect and what it does to the held-out error, or none."""
    b = report["baseline"]
    if report["no_effect_warranted"]:
        return (f"No extra effect is warranted: the baseline predicts held-out modes to "
                f"{b['heldout_rms_freq_dev_pct']:.2f} % RMS and no candidate improves that by enough "
                f"(χ² per row {b['chi2_per_row']:.2f} at the stated noise).")
    e = report["effects"][0]
    vals = ", ".join(f"{k} = {v:.4g}" for k, v in e["parameters"].items())
    return (f"Missing effect: {e['kind']} at {e['where']} ({vals}); held-out RMS frequency error "
            f"{e['heldout_rms_freq_dev_pct_before']:.2f} % → {e['heldout_rms_freq_dev_pct_after']:.2f} %, "
            f"ΔAIC = {e['delta_aic']:.1f}.")


def combine(a: dict, b: dict) -> dict:
    """Mean of two indicators, each scaled to a maximum of 1; best first."""
    ta, tb = max(a.values(), default=1.0) or 1.0, max(b.values(), default=1.0) or 1.0
    keys = set(a) | set(b)
    out = {k: 0.5 * (a.get(k, 0.0) / ta + b.get(k, 0.0) / tb) for k in keys}
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))
