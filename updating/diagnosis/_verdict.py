"""The verdict of a diagnosis in one sentence, derived from the ranking's numbers."""

from __future__ import annotations

from dataclasses import dataclass

from ._evidence import UNEXPLAINED_CHI2, CandidateResult


@dataclass(frozen=True)
class Baseline:
    """The baseline (the model updated with the engineer's parameters, if any): its
    factors α by name, RMS Δf [%] and mean MAC over the paired test modes, the same held
    out (k-fold), and χ² per row at the stated noise (all rows, frequency and shape rows)."""

    parameters: tuple[tuple[str, float], ...]
    rms_freq_dev_pct: float | None
    mean_mac: float
    heldout_rms_freq_dev_pct: float | None
    heldout_mean_mac: float
    chi2_per_row: float
    chi2_per_row_freq: float
    chi2_per_row_shape: float

    def to_json(self) -> dict:
        return {"parameters": [{"name": n, "alpha": a} for n, a in self.parameters],
                "rms_freq_dev_pct": self.rms_freq_dev_pct, "mean_mac": self.mean_mac,
                "heldout_rms_freq_dev_pct": self.heldout_rms_freq_dev_pct, "heldout_mean_mac": self.heldout_mean_mac,
                "chi2_per_row": self.chi2_per_row, "chi2_per_row_freq": self.chi2_per_row_freq,
                "chi2_per_row_shape": self.chi2_per_row_shape}


def verdict(outcome: str, effects: tuple[CandidateResult, ...], ties: tuple[CandidateResult, ...],
            baseline: Baseline) -> str:
    """One sentence an engineer can act on: the effect to add, with its uncertainty and
    what it does to the held-out error; or that none is needed; or that no single effect
    of the library explains the data."""
    if outcome == "effect":
        e = effects[0]
        text = (f"{e.advice[0].upper()}{e.advice[1:]}: held-out frequency error "
                f"{e.heldout_rms_freq_dev_pct_before:.2f} % → {e.heldout_rms_freq_dev_pct_after:.2f} % "
                f"(posterior probability {e.posterior:.2f}).")
        if ties:
            text += (" The sensors cannot tell it apart from " + ", ".join(t.effect.where() for t in ties)
                     + " (Bayes factor below e): check those places too.")
        if e.chi2_per_row > UNEXPLAINED_CHI2:
            text += (f" χ² per row stays {e.chi2_per_row:.1f} at the stated noise: more than this one effect "
                     "is missing.")
        return text
    partial = [e for e in effects if e.log_evidence > 0][:3]
    listed = "; ".join(f"{e.effect.kind} at {e.effect.where()} (χ²/row {e.chi2_per_row:.1f})" for e in partial)
    b = baseline
    if outcome == "unexplained":
        return (f"No single effect explains the data: the baseline leaves χ² per row "
                f"{b.chi2_per_row:.1f} at the stated noise (held-out RMS Δf {b.heldout_rms_freq_dev_pct:.2f} %) "
                f"and no candidate passes the held-out tests"
                + (f"; best partial candidates: {listed}" if listed else "")
                + ". The missing physics lies outside the candidate library (model form, e.g. plates "
                  "modelled as beams; joints or supports not offered as candidates) or the stated noise "
                  "is too optimistic.")
    return (f"No extra effect is warranted: the baseline explains the data to the stated noise "
            f"(χ² per row {b.chi2_per_row:.2f}, held-out RMS Δf {b.heldout_rms_freq_dev_pct:.2f} %)"
            + (f"; candidates that did not pass: {listed}" if listed else "") + ".")
