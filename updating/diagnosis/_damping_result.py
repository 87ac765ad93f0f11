"""The result of the damping diagnosis (:func:`updating.diagnose_damping`): typed and
immutable, JSON only through ``to_json()`` (the ``damping`` part of ``diagnosis.json``)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from ._effects import LocalDamping


@dataclass(frozen=True)
class DampingMode:
    """One paired mode (numbers from 1): the measured ratio ζ, uniform damping's fit
    ``zeta_baseline`` and the first-ranked region's ``zeta_best`` (NaN without one)."""

    test_mode: int
    f_test_hz: float
    zeta_test: float
    model_mode: int
    zeta_baseline: float
    zeta_best: float

    def to_json(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class UniformDamping:
    """Uniform damping: Rayleigh's ``mu`` [1/s] and ``kappa`` [s] (eq. 3.40) and a loss
    factor ``eta0`` on every element with stiffness (the MAP, ≥ 0), with the σ ``eta0_sd``
    of its Gaussian posterior."""

    mu: float
    kappa: float
    eta0: float
    eta0_sd: float

    def to_json(self) -> dict:
        return asdict(self)

    def describe(self) -> str:
        return (f"Rayleigh μ = {self.mu:.3g} 1/s, κ = {self.kappa:.3g} s, loss factor η0 = {self.eta0:.3g} "
                f"(±{self.eta0_sd:.2g})")


@dataclass(frozen=True)
class DampingBaseline:
    """The null model, uniform damping (with the model's own loss factors): χ² per row and
    held-out χ² per row at the stated noise, the held-out RMS deviation of ζ in % of the
    measured ratio, its posterior, its fit (``uniform``) and whether its χ² is at the noise
    level (``at_noise``: χ² ≤ n + 2√(2n) for n ratios)."""

    chi2_per_row: float
    heldout_chi2_per_row: float
    heldout_rms_zeta_dev_pct: float
    posterior: float
    uniform: UniformDamping
    at_noise: bool

    def to_json(self) -> dict:
        return {"chi2_per_row": self.chi2_per_row, "heldout_chi2_per_row": self.heldout_chi2_per_row,
                "heldout_rms_zeta_dev_pct": self.heldout_rms_zeta_dev_pct, "posterior": self.posterior,
                **self.uniform.to_json(), "at_noise": self.at_noise}


@dataclass(frozen=True)
class DampingChecks:
    """What declaring a region needs, all at the stated noise (``passed``: all of them):
    posterior ≥ 0.5, ln Bayes factor over the null model ≥ ln 20, χ² and held-out χ²
    lowered beyond noise (2√(2n)), held-out χ² ≤ n + 2√(2n)."""

    most_probable: bool
    decisive_over_baseline: bool
    chi2_lowered: bool
    heldout_lowered: bool
    heldout_at_noise: bool

    @property
    def passed(self) -> bool:
        return all(asdict(self).values())


@dataclass(frozen=True)
class DampingRegion:
    """One ranked region: the loss factor at its fitted η and what the data say of it.
    ``log_evidence`` relative to the null model's, ``eta_sd`` the posterior σ of η, χ²
    and held-out χ² per row at the stated noise, the held-out RMS ζ deviation [%] with the
    null model (``before``) and with the region; ``uniform``: the uniform damping fitted with it."""

    effect: LocalDamping
    rank: int
    eta_sd: float
    posterior: float
    log_evidence: float
    chi2_per_row: float
    heldout_chi2_per_row: float
    advice: str
    heldout_rms_zeta_dev_pct_before: float
    heldout_rms_zeta_dev_pct_after: float
    uniform: UniformDamping
    plausibility: tuple[str, ...]
    checks: DampingChecks
    warranted: bool

    @property
    def eta(self) -> float:
        return self.effect.eta

    def to_json(self) -> dict:
        return {**self.effect.to_json(), "rank": self.rank, "eta": self.eta, "eta_sd": self.eta_sd,
                "posterior": self.posterior, "log_evidence": self.log_evidence, "chi2_per_row": self.chi2_per_row,
                "heldout_chi2_per_row": self.heldout_chi2_per_row, "advice": self.advice, "heldout_rms_zeta_dev_pct_before": self.heldout_rms_zeta_dev_pct_before,
                "heldout_rms_zeta_dev_pct_after": self.heldout_rms_zeta_dev_pct_after,
                **self.uniform.to_json(), "plausibility": list(self.plausibility), "checks": asdict(self.checks), "warranted": self.warranted}


@dataclass(frozen=True)
class DampingDiagnosis:
    """``outcome`` "effect", "none_needed" (uniform damping explains the ratios) or
    "unexplained"; the paired ``modes``; the null model (``baseline``); the ``regions`` best
    first (at most ``n_report``); the stated noise on the ratios in %; ``noise_scale``, the
    χ²/row of the retained model (the declared region's fit, else the null model's): an
    estimate of (actual/stated noise)², reported only, never used in a decision; how many
    regions were fitted; the declared ``effect`` (the first region where it is warranted,
    else None) and the ``verdict``.
    ``to_json()``: the ``damping`` part of ``diagnosis.json`` (``regions`` as ``effects``)."""

    outcome: str
    modes: tuple[DampingMode, ...]
    baseline: DampingBaseline
    noise_pct: float
    noise_scale: float
    regions_fitted: int
    regions: tuple[DampingRegion, ...]
    effect: LocalDamping | None
    verdict: str

    def to_json(self) -> dict:
        return {"outcome": self.outcome, "modes": [m.to_json() for m in self.modes],
                "baseline": self.baseline.to_json(), "noise_pct": self.noise_pct, "noise_scale": self.noise_scale,
                "regions_fitted": self.regions_fitted, "effects": [r.to_json() for r in self.regions],
                "verdict": self.verdict}


def damping_verdict(outcome: str, regions: tuple[DampingRegion, ...], baseline: DampingBaseline,
                    noise_pct: float, noise_scale: float) -> str:
    """One sentence per outcome: the loss factor to add and where on top of uniform damping,
    with what it does to the held-out damping error ("effect"); that uniform damping explains
    the ratios ("none_needed"); or that nothing among the candidates does ("unexplained")."""
    b = baseline
    if outcome == "effect":
        e = regions[0]
        return (f"{e.advice[0].upper()}{e.advice[1:]} on top of uniform damping ({e.uniform.describe()}): "
                f"held-out damping error {e.heldout_rms_zeta_dev_pct_before:.1f} % → "
                f"{e.heldout_rms_zeta_dev_pct_after:.1f} % (posterior probability {e.posterior:.2f}).")
    if outcome == "none_needed":
        return (f"No local damping effect: uniform damping ({b.uniform.describe()}) explains the measured ratios to "
                f"the stated noise (χ²/row {b.chi2_per_row:.2f} at {noise_pct:.3g} % on each ratio).")
    return (f"No local damping effect is declared, but uniform damping ({b.uniform.describe()}) leaves χ²/row "
            f"{b.chi2_per_row:.2f} at the stated {noise_pct:.3g} % on each ratio and no region passes the checks for a "
            f"local loss factor ({_best(regions)}): the ratios scatter about uniform damping by about "
            f"{noise_pct * noise_scale ** 0.5:.0f} % or need physics outside the candidates.")


_CHECKS = {"most_probable": "posterior ≥ 0.5", "decisive_over_baseline": "decisive over uniform damping",
           "chi2_lowered": "χ² lowered beyond noise", "heldout_lowered": "held-out χ² lowered beyond noise",
           "heldout_at_noise": "held-out χ² at the noise level"}


def _best(regions: tuple[DampingRegion, ...]) -> str:
    """The most probable region and the checks it fails, for the verdict."""
    if not regions:
        return "none asks for a loss factor above 0"
    e = regions[0]
    failed = ", ".join(_CHECKS[k] for k, ok in asdict(e.checks).items() if not ok)
    return (f"the most probable, {e.effect.where()} with η = {e.eta:.3g}, posterior {e.posterior:.2f}, held-out "
            f"χ²/row {e.heldout_chi2_per_row:.2f}, fails: {failed}")
