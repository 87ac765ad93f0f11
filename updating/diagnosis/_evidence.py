"""Evidence for a candidate effect: its Bayesian evidence, its held-out error, and the
checks a declaration must pass (the verdict in words: :mod:`._verdict`).

**Evidence** (MacKay 1992; Sivia & Skilling 2006, §3.3): the residual rows are weighted
so that each carries the stated noise σ² (:func:`updating.diagnose`), the likelihood is
Gaussian, and each free log-factor θ has a normal prior (the kind's ``prior_sd`` about
its reference; the engineer's parameters σ = 3). The Laplace approximation at the fitted
θ* gives

    ln Z = −½ χ²(θ*) − ½ Σ z_i² − Σ ln s_i − ½ ln det H,   H = JᵀJ/σ² + diag(1/s²),

with z_i = (θ*_i − μ_i)/s_i; everything after −½ χ² is the log Occam factor, the price of
the parameters' freedom. Every decision is taken at the **stated** noise: where even the
best candidate leaves χ² per row above 1 (model-form error, or noise understated), that
χ² per row (the Birge ratio) is reported as an estimate of the noise scale beside the
ranking, never used to weaken a check. The posterior over the candidates and the
baseline (equal prior odds) is softmax(ln Z).

**Held-out error**: k-fold cross-validation over the test modes (:mod:`._fit`), in
frequencies and in shapes separately.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from .. import json_safe, rms_pct
from ._abstract_effect import AbstractEffect
from ._candidates import Candidate
from ._fit import Fit, HeldOut

BASELINE_SD = 3.0  # prior σ of the engineer's log-factors (the fits' ridge, see diagnose)
DECISIVE = np.log(20.0)  # ln Bayes factor an effect needs over the baseline ("strong", Kass & Raftery 1995)
TIE = 1.0  # ln Bayes factor below which two places of one kind explain the data equally
NEAR = DECISIVE  # ln Bayes factor below which the data do not tell a place of one kind from the winner's
AT_NOISE = 4.0  # χ² per row up to which a fit explains the data at the stated noise (residuals within 2× the noise)
OFF = 3.0  # |Δf| in σ of the remainder's own robust noise scale beyond which a mode is off, not noise
MEDIAN_CHI2_1 = 0.4549  # median of a χ² of one degree of freedom: the robust scale of the frequency residuals
UNDERSTATED = 6.0  # the most by which a stated noise σ is taken to be understated; a larger misfit is not noise


@dataclass(frozen=True)
class Remainder:
    """What a fit leaves at the stated noise: χ² per row (all rows), the noise scales it
    implies (√ of the frequency and shape χ² per row), the test modes ``off`` beyond 2σ of
    the stated frequency noise or unpaired — (mode, Δf [%] or None), worst first — and
    ``outliers``: how many of them lie beyond :data:`OFF` times the frequency residuals'
    robust scale (their median) too, the modes even a scaled noise does not explain."""

    chi2_per_row: float
    freq_scale: float
    shape_scale: float
    off: tuple[tuple[int, float | None], ...]
    outliers: int

    @property
    def at_noise(self) -> bool:
        return self.chi2_per_row <= AT_NOISE

    @property
    def noise_like(self) -> bool:
        """At noise, or beyond it with no outlier and scales within :data:`UNDERSTATED`:
        the stated noise understated."""
        return self.at_noise or not self.outliers and max(self.freq_scale, self.shape_scale) <= UNDERSTATED

    def to_json(self) -> dict:
        return json_safe({"chi2_per_row": self.chi2_per_row, "noise_scale_freq": self.freq_scale,
                          "noise_scale_shape": self.shape_scale, "at_noise": self.at_noise,
                          "noise_like": self.noise_like, "outliers": self.outliers,
                          "modes_off": [{"mode": j, "freq_dev_pct": d} for j, d in self.off]})


def remainder(fit: Fit, sigma2: float, freq_sd: float, rows_: tuple[int, int]) -> Remainder:
    """The :class:`Remainder` of a fit (``rows_``: its frequency and shape rows; ``freq_sd``:
    the stated relative σ of a frequency)."""
    n_f, n_s = rows_
    d = np.asarray(fit.freq_dev, float)
    z = np.where(np.isfinite(d), np.abs(d) / freq_sd, np.inf)
    finite = z[np.isfinite(z)]
    robust = np.sqrt(max(1.0, float(np.median(finite ** 2)) / MEDIAN_CHI2_1)) if finite.size else 1.0
    order = [int(j) for j in np.argsort(-z, kind="stable") if z[j] > 2.0]
    off = tuple((j + 1, None if not np.isfinite(d[j]) else float(100 * d[j])) for j in order)
    return Remainder(float(fit.cost / sigma2 / (n_f + n_s)), float(np.sqrt(fit.cost_freq / sigma2 / n_f)),
                     float(np.sqrt(fit.cost_shape / sigma2 / max(n_s, 1))), off, int(np.sum(z > OFF * robust)))


def log_evidence(theta, cost: float, jac, mean: np.ndarray, sd: np.ndarray,
                 sigma2: float) -> tuple[float, float, np.ndarray]:
    """ln Z, ln Occam factor and the posterior σ of each θ, by the Laplace approximation
    at the fitted θ* (module docstring); ``mean``, ``sd``: the prior of every θ."""
    if not np.isfinite(cost):
        return -np.inf, np.nan, np.full(len(mean), np.nan)
    J = np.asarray(jac)
    H = J.T @ J / sigma2 + np.diag(1.0 / sd ** 2)
    sign, logdet = np.linalg.slogdet(H)
    z = (np.asarray(theta) - mean) / sd
    occam = -0.5 * np.sum(z ** 2) - np.sum(np.log(sd)) - 0.5 * logdet
    cov_sd = np.sqrt(np.maximum(np.diag(np.linalg.pinv(H)), 0.0))
    return -0.5 * cost / sigma2 + occam, occam, cov_sd


def lowered(before: float, after: float, n: int, *, or_kept: bool = False) -> bool:
    """A held-out χ² of ``n`` rows lowered beyond its noise (by 2σ of a χ², 2√(2n)); with
    ``or_kept``, also kept at the noise level where the baseline already was there."""
    band = 2 * np.sqrt(2 * n)
    return after < before - band or (or_kept and before <= n + band and after <= n + band)


@dataclass(frozen=True)
class Checks:
    """What a declaration needs (:func:`evidence`); ``passed``: all of them."""

    decisive_over_baseline: bool
    chi2_lowered: bool
    heldout_freq_lowered: bool
    heldout_shape_lowered: bool
    heldout_rms_not_higher: bool
    heldout_no_mode_worse: bool

    @property
    def passed(self) -> bool:
        return all(asdict(self).values())


@dataclass(frozen=True)
class CandidateResult:
    """One ranked candidate: the effect at its fitted values and what the data say of it.
    Frequencies in %, ``log_evidence`` relative to the baseline's, ``theta_sd`` the
    posterior σ of its log-factors, ``score`` the held-out cost reduction in %."""

    effect: AbstractEffect
    rank: int
    posterior: float
    log_evidence: float
    log_occam: float
    theta_sd: tuple[float, ...]
    advice: str
    delta_aic: float
    score: float | None
    screen: float | None
    chi2_per_row: float
    heldout_rms_freq_dev_pct_before: float | None
    heldout_rms_freq_dev_pct_after: float | None
    heldout_modes_compared: int | None
    heldout_worse_modes: tuple[int, ...]
    heldout_mean_mac_before: float | None
    heldout_mean_mac_after: float | None
    rms_freq_dev_pct_after: float | None
    plausibility: tuple[str, ...]
    cross_validated: bool
    checks: Checks
    warranted: bool

    @property
    def plausible(self) -> bool:
        return not self.plausibility

    def to_json(self) -> dict:
        return {**self.effect.to_json(), "rank": self.rank, "posterior": self.posterior,
                "log_evidence": self.log_evidence, "log_occam": self.log_occam, "theta_sd": list(self.theta_sd),
                "advice": self.advice, "delta_aic": self.delta_aic, "score": self.score, "screen": self.screen,
                "chi2_per_row": self.chi2_per_row,
                "heldout_rms_freq_dev_pct_before": self.heldout_rms_freq_dev_pct_before,
                "heldout_rms_freq_dev_pct_after": self.heldout_rms_freq_dev_pct_after,
                "heldout_modes_compared": self.heldout_modes_compared,
                "heldout_worse_modes": list(self.heldout_worse_modes),
                "heldout_mean_mac_before": self.heldout_mean_mac_before,
                "heldout_mean_mac_after": self.heldout_mean_mac_after,
                "rms_freq_dev_pct_after": self.rms_freq_dev_pct_after,
                "plausible": self.plausible, "plausibility": list(self.plausibility),
                "cross_validated": self.cross_validated, "checks": asdict(self.checks), "warranted": self.warranted}


@dataclass(frozen=True)
class Ranking:
    """The candidates best first (:class:`CandidateResult`, and the :class:`Candidate` each
    came from), the ``outcome`` ("effect": the first passed every check; "cannot_localise":
    it did, but as well (ln B < :data:`TIE`) at two or more other places of its kind — grids,
    elements or groups, not directions at one grid; "none_needed": none
    passed), the noise-scale estimate (Birge ratio, reported only), the baseline's posterior
    and the places of the winner's kind the data do not tell from it (ln B < :data:`NEAR`)."""

    results: tuple[CandidateResult, ...]
    candidates: tuple[Candidate, ...]
    outcome: str
    noise_scale: float
    baseline_posterior: float
    ties: tuple[CandidateResult, ...]


def evidence(short: list[Candidate], base: Fit, base_heldout: HeldOut | None, n_b: int, rows_: tuple[int, int],
             sigma2: float, mass: float, freq_sd: float) -> Ranking:
    """Rank the fitted candidates by posterior probability and test the best against the
    baseline (its fit, its cross-validation ``base_heldout``).

    ``rows_``: (frequency rows, shape rows) of all test modes; ``freq_sd``: the stated
    relative σ of a frequency. The declared effect is the most probable candidate when it
    (a) is decisively more probable than the baseline, (b) lowers χ² beyond noise,
    (c) lowers the held-out error in frequencies beyond noise **and** in shapes beyond noise
    — or keeps shapes at the noise level where the baseline already predicts them that well
    (:func:`lowered`), (d) does not raise the held-out RMS Δf over the modes paired with
    and without it (the number shown: a winner whose error rises would contradict itself)
    and (e) makes no held-out mode's |Δf| worse by more than 2σ of the frequency noise —
    all at the stated noise. Where the candidate itself leaves modes off beyond noise (its
    :class:`Remainder` is not noise-like: another effect is still missing and moves modes
    about), (e) is judged on the final set of declared effects instead
    (:func:`updating.diagnose`). Plausibility is the prior, not a cut.
    """
    n_f, n_s = rows_
    n_rows = n_f + n_s
    chi2_row = lambda f: f.cost / sigma2 / n_rows  # noqa: E731
    scale = max(1.0, min([chi2_row(base)] + [chi2_row(c.fit) for c in short]))
    lz_b = log_evidence(base.theta, base.cost, base.jac, np.zeros(n_b + 1), np.full(n_b + 1, BASELINE_SD), sigma2)[0]
    scored = []
    for c in short:
        mean, sd = c.prior()
        lz, occam, theta_sd = log_evidence(c.fit.theta, c.fit.cost, c.fit.jac, np.concatenate([np.zeros(n_b), mean]),
                                           np.concatenate([np.full(n_b, BASELINE_SD), sd]), sigma2)
        scored.append((lz, occam, theta_sd))
    lz = np.array([lz_b] + [s[0] for s in scored])
    post = np.exp(lz - lz.max())
    post /= post.sum()
    order = sorted(range(len(short)), key=lambda i: -lz[i + 1])
    results = []
    for i in order:
        c, (_, occam, theta_sd) = short[i], scored[i]
        results.append(_result(c, len(results) + 1, post[i + 1], lz[i + 1] - lz_b, occam, theta_sd, base,
                               base_heldout, n_b, (n_f, n_s), sigma2, freq_sd, mass))
    outcome, ties = "none_needed", ()
    if results and results[0].checks.passed:
        top = results[0] = _warranted(results[0])
        ties = tuple(r for r in results[1:] if r.effect.kind == top.effect.kind
                     and top.log_evidence - r.log_evidence < NEAR)
        place = lambda r: tuple(r.effect.location().values())  # noqa: E731  (one grid's directions: one place)
        equal = {place(r) for r in ties if top.log_evidence - r.log_evidence < TIE} - {place(top)}
        outcome = "cannot_localise" if len(equal) >= 2 else "effect"
    return Ranking(tuple(results), tuple(short[i] for i in order), outcome, float(scale), float(post[0]), ties)


def _warranted(r: CandidateResult) -> CandidateResult:
    return replace(r, warranted=True)


def _result(c: Candidate, rank: int, posterior: float, log_z: float, occam: float, theta_sd, base: Fit,
            base_heldout: HeldOut | None, n_b: int, rows_: tuple[int, int], sigma2: float, freq_sd: float,
            mass: float) -> CandidateResult:
    """A candidate's row of the ranking (:func:`evidence`), its checks at the stated noise."""
    n_f, n_s = rows_
    n_rows, s2 = n_f + n_s, sigma2
    res, held = c.fit, c.heldout
    effect = c.reference.updated(res.theta[n_b:])
    cv = held is not None
    notes = effect.plausibility(mass, c.reference) + ([f"fit failed: {res.error}"] if res.error else [])
    base_dev = base_heldout.freq_dev
    rms_before, rms_after, both, worse = rms_pct(base_dev), None, None, ()
    if cv:  # over the modes paired with and without the effect: the numbers shown
        both = np.isfinite(base_dev) & np.isfinite(held.freq_dev)
        rms_before, rms_after = rms_pct(base_dev[both]), rms_pct(held.freq_dev[both])
        worse = worse_modes(base_dev, held.freq_dev, freq_sd)
    structured = not remainder(res, sigma2, freq_sd, rows_).noise_like if np.isfinite(res.cost) else False
    checks = Checks(
        decisive_over_baseline=bool(log_z >= DECISIVE),
        chi2_lowered=bool(res.cost < base.cost - 2 * np.sqrt(2 * n_rows) * sigma2),
        heldout_freq_lowered=bool(cv and lowered(base_heldout.freq / s2, held.freq / s2, n_f)),
        heldout_shape_lowered=bool(cv and lowered(base_heldout.shape / s2, held.shape / s2, n_s, or_kept=True)),
        heldout_rms_not_higher=bool(cv and rms_after <= rms_before),
        heldout_no_mode_worse=bool(cv and (not worse or structured)))
    cv_base = base_heldout.freq + base_heldout.shape
    return CandidateResult(
        effect=effect, rank=rank, posterior=float(posterior), log_evidence=float(log_z), log_occam=float(occam),
        theta_sd=tuple(float(v) for v in theta_sd[n_b:]), advice=effect.advice(theta_sd[n_b:]),
        delta_aic=float(_aic(res.cost, n_b + len(c.theta0), n_rows) - _aic(base.cost, n_b, n_rows)),
        score=float(100 * (1 - (held.freq + held.shape) / cv_base)) if cv else None,
        screen=float(c.screen) if np.isfinite(c.screen) else None,
        chi2_per_row=float(res.cost / sigma2 / n_rows),
        heldout_rms_freq_dev_pct_before=rms_before, heldout_rms_freq_dev_pct_after=rms_after,
        heldout_modes_compared=int(both.sum()) if cv else None, heldout_worse_modes=worse,
        heldout_mean_mac_before=_mean(base_heldout.mac), heldout_mean_mac_after=_mean(held.mac) if cv else None,
        rms_freq_dev_pct_after=rms_pct(res.freq_dev), plausibility=tuple(notes), cross_validated=cv,
        checks=checks, warranted=False)


def worse_modes(before, after, freq_sd: float) -> tuple[int, ...]:
    """Test modes (1-based) whose |Δf| grew by more than 2σ of the frequency noise
    ``freq_sd`` (fractions; modes unpaired before or after are not compared)."""
    grew = np.abs(np.asarray(after, float)) - np.abs(np.asarray(before, float)) > 2 * freq_sd
    return tuple(int(j) + 1 for j in np.flatnonzero(grew))


def _aic(cost: float, k: int, n: int) -> float:
    return n * np.log(max(cost, 1e-300) / n) + 2 * k


def _mean(x) -> float | None:
    x = np.asarray(x, float)
    return float(np.nanmean(x)) if np.isfinite(x).any() else None


def combine(a: dict, b: dict) -> dict:
    """Mean of two indicators, each scaled to a maximum of 1; best first."""
    ta, tb = max(a.values(), default=1.0) or 1.0, max(b.values(), default=1.0) or 1.0
    keys = set(a) | set(b)
    out = {k: 0.5 * (a.get(k, 0.0) / ta + b.get(k, 0.0) / tb) for k in keys}
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))
