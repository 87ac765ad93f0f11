"""The result of the damping diagnosis (:func:`updating.diagnose_damping`): typed and
immutable, JSON only through ``to_json()`` (the ``damping`` part of ``diagnosis.json``)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from ._effects import LocalDamping


@dataclass(frozen=True)
class DampingMode:
    """One paired mode (numbers from 1): the measured ratio ζ, Rayleigh's fit
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
class DampingBaseline:
    """Rayleigh damping alone (with the model's own loss factors): χ² per row at the stated
    noise, the held-out RMS deviation of ζ in % of the measured ratio, its posterior."""

    chi2_per_row: float
    heldout_rms_zeta_dev_pct: float
    posterior: float

    def to_json(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class DampingChecks:
    """What declaring a region needs; ``passed``: all of them."""

    decisive_over_baseline: bool
    chi2_lowered: bool
    heldout_lowered: bool

    @property
    def passed(self) -> bool:
        return all(asdict(self).values())


@dataclass(frozen=True)
class DampingRegion:
    """One ranked region: the loss factor at its fitted η and what the data say of it.
    ``log_evidence`` relative to Rayleigh alone's, ``eta_sd`` the posterior σ of η, the
    held-out RMS ζ deviation [%] with Rayleigh alone (``before``) and with the region."""

    effect: LocalDamping
    rank: int
    eta_sd: float
    posterior: float
    log_evidence: float
    chi2_per_row: float
    advice: str
    heldout_rms_zeta_dev_pct_before: float
    heldout_rms_zeta_dev_pct_after: float
    plausibility: tuple[str, ...]
    checks: DampingChecks
    warranted: bool

    @property
    def eta(self) -> float:
        return self.effect.eta

    def to_json(self) -> dict:
        return {**self.effect.to_json(), "rank": self.rank, "eta": self.eta, "eta_sd": self.eta_sd,
                "posterior": self.posterior, "log_evidence": self.log_evidence, "chi2_per_row": self.chi2_per_row,
                "advice": self.advice, "heldout_rms_zeta_dev_pct_before": self.heldout_rms_zeta_dev_pct_before,
                "heldout_rms_zeta_dev_pct_after": self.heldout_rms_zeta_dev_pct_after,
                "plausibility": list(self.plausibility), "checks": asdict(self.checks), "warranted": self.warranted}


@dataclass(frozen=True)
class DampingDiagnosis:
    """``outcome`` "effect" or "none_needed"; the paired ``modes``; Rayleigh alone
    (``baseline``); the ``regions`` best first (at most ``n_report``); the noise on the
    ratios in %, σ²'s scale (``noise_scale``), how many regions were fitted; the declared
    ``effect`` (the first region where it is warranted, else None) and the ``verdict``.
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
                    noise_pct: float) -> str:
    """One sentence: the loss factor to add and where, with what it does to the held-out
    damping error; or that Rayleigh damping explains the measured damping."""
    b = baseline
    if outcome == "effect":
        e = regions[0]
        return (f"{e.advice[0].upper()}{e.advice[1:]}: held-out damping error "
                f"{e.heldout_rms_zeta_dev_pct_before:.1f} % → {e.heldout_rms_zeta_dev_pct_after:.1f} % "
                f"(posterior probability {e.posterior:.2f}).")
    return (f"No local loss factor is warranted: Rayleigh damping leaves χ² per row {b.chi2_per_row:.2f} at "
            f"{noise_pct:.0f} % noise on the ratios (held-out error {b.heldout_rms_zeta_dev_pct:.1f} %).")
