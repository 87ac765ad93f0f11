"""The verdict of a diagnosis: its state, derived from the numbers, and one sentence per state.

States (``Diagnosis.outcome``):

- ``effect`` — explained: effects declared and what remains is at the stated noise
  (χ² per row ≤ :data:`AT_NOISE`) or spread over the modes like noise (then the noise
  scale the remainder implies is named: the stated noise looks understated);
- ``partial`` — effects declared, but some modes remain off beyond noise and no further
  candidate passes the tests (those modes are named);
- ``none_needed`` — no effect declared, and the baseline is at noise or its misfit is
  spread like noise;
- ``unconfirmed`` — no effect declared, but a candidate fits to the stated noise where
  the baseline does not: it failed the held-out tests (which ones are named);
- ``cannot_localise`` — a candidate passes every test, as well at two or more other
  places of its kind (:mod:`._evidence`); nothing is added;
- ``unexplained`` — outside the library: the baseline misfit is structured, no candidate
  reaches the noise and none improves the held-out prediction.

An effect withdrawn by its confirming update (a passive mode worse beyond noise, or a
model the update cannot solve) is named with its reason in every state.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .. import json_safe
from ._confirm import Confirmation
from ._evidence import AT_NOISE, TIE, CandidateResult, Remainder



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


@dataclass(frozen=True)
class Declared:
    """One declared effect: the round it was found in, its ranking row there (values,
    uncertainty, evidence, held-out error before → after that round) and its confirming
    update (passive modes held out; :func:`updating.diagnosis.add_effect`), None when
    the diagnosis ran without confirming."""

    round: int
    result: CandidateResult
    confirmation: Confirmation | None

    @property
    def effect(self):
        """At its confirmed values (the ranking's where it was not confirmed)."""
        return self.confirmation.effect if self.confirmation is not None else self.result.effect

    def to_json(self) -> dict:
        r = self.result
        c = self.confirmation
        return json_safe({
            **self.effect.to_json(), "round": self.round, "theta_sd": list(r.theta_sd), "advice": r.advice,
            "posterior": r.posterior, "log_evidence": r.log_evidence, "chi2_per_row": r.chi2_per_row,
            "heldout_rms_freq_dev_pct_before": r.heldout_rms_freq_dev_pct_before,
            "heldout_rms_freq_dev_pct_after": r.heldout_rms_freq_dev_pct_after,
            "rms_freq_dev_pct_passive_before": c.rms_passive_before if c else None,
            "rms_freq_dev_pct_passive_after": c.rms_passive_after if c else None})


@dataclass(frozen=True)
class Withdrawn:
    """A winner its confirming update withdrew: the row and the reason in words."""

    result: CandidateResult
    reason: str

    def to_json(self) -> dict:
        return json_safe({**self.result.effect.to_json(), "reason": self.reason})


_FAILED = {"decisive_over_baseline": "its evidence is not decisive over the baseline",
           "chi2_lowered": "it does not lower χ² beyond noise",
           "heldout_freq_lowered": "it does not lower the held-out frequency error beyond noise",
           "heldout_shape_lowered": "it does not lower the held-out shape error beyond noise",
           "heldout_rms_not_higher": "it raises the held-out RMS Δf",
           "heldout_no_mode_worse": "it makes held-out modes worse beyond noise"}


def failed(r: CandidateResult) -> str:
    """The checks a candidate failed, in words."""
    words = [_FAILED[k] + (f" (mode {', '.join(map(str, r.heldout_worse_modes))})"
                           if k == "heldout_no_mode_worse" and r.heldout_worse_modes else "")
             for k, ok in asdict(r.checks).items() if not ok]
    return "; ".join(words) or "none"


def state(ranked: str, results: tuple[CandidateResult, ...], declared: tuple[Declared, ...],
          base: Remainder, final: Remainder) -> str:
    """The state (module docstring) from the last round's ranking outcome ``ranked``, its
    candidates, the declared effects, the first baseline's and the final remainder."""
    if declared:
        return "effect" if final.noise_like else "partial"
    if ranked == "cannot_localise":
        return "cannot_localise"
    if base.noise_like:
        return "none_needed"
    if results and results[0].chi2_per_row <= AT_NOISE:
        return "unconfirmed"
    return "unexplained"


def _sd_text(r: Remainder) -> str:
    return f"frequencies ×{r.freq_scale:.1f}, shapes ×{r.shape_scale:.1f}"


def _off_text(r: Remainder, most: int = 5) -> str:
    """The modes off beyond noise, worst first (at most ``most`` named)."""
    text = ", ".join(f"{j} ({'unpaired' if d is None else f'{d:+.2f} %'})" for j, d in r.off[:most])
    return text + (f" and {len(r.off) - most} more" if len(r.off) > most else "")


def _declared_text(declared: tuple[Declared, ...]) -> str:
    out = []
    for k, d in enumerate(declared):
        e = d.result
        lead = "" if len(declared) == 1 else ("First: " if k == 0 else "Then: ")
        out.append(f"{lead}{e.advice[0].upper()}{e.advice[1:]}: held-out frequency error "
                   f"{e.heldout_rms_freq_dev_pct_before:.2f} % → {e.heldout_rms_freq_dev_pct_after:.2f} % "
                   f"(posterior probability {e.posterior:.2f}).")
    return " ".join(out)


def _listed(results: tuple[CandidateResult, ...]) -> str:
    partial = [e for e in results if e.log_evidence > 0][:3]
    return "; ".join(f"{e.effect.kind} at {e.effect.where()} (χ²/row {e.chi2_per_row:.1f})" for e in partial)


def verdict(outcome: str, effects: tuple[CandidateResult, ...], ties: tuple[CandidateResult, ...],
            baseline: Baseline, declared: tuple[Declared, ...] = (), final: Remainder | None = None,
            base: Remainder | None = None, withdrawn: Withdrawn | None = None) -> str:
    """One sentence per state (module docstring) an engineer can act on."""
    b = baseline
    base = base or Remainder(b.chi2_per_row, np.sqrt(b.chi2_per_row_freq), np.sqrt(b.chi2_per_row_shape), (), 0)
    final = final or base
    note = (f" {withdrawn.result.effect.kind} at {withdrawn.result.effect.where()} was withdrawn: {withdrawn.reason}."
            if withdrawn is not None else "")
    if outcome in ("effect", "partial"):
        text = _declared_text(declared)
        if ties:
            text += (" The sensors cannot tell the last from " + ", ".join(t.effect.where() for t in ties)
                     + " (Bayes factor below 20): check those places too.")
        if outcome == "partial":
            return (text + f" Partially explained: modes {_off_text(final)} remain off beyond noise (χ² per row "
                    f"{final.chi2_per_row:.1f}) and no further candidate passes the tests." + note)
        if final.at_noise:
            return text + f" With it the model explains the data to the stated noise (χ² per row {final.chi2_per_row:.2f})." + note
        return (text + f" What remains (χ² per row {final.chi2_per_row:.1f}) is spread over all modes like noise: "
                f"the stated noise looks understated ({_sd_text(final)}), not another effect." + note)
    listed = _listed(effects)
    if outcome == "cannot_localise":
        top = effects[0]
        places = dict.fromkeys([top.effect.where()] + [t.effect.where() for t in ties
                                                       if top.log_evidence - t.log_evidence < TIE])
        return (f"A {top.effect.kind} explains the data, but equally well at {', '.join(places)} (Bayes factors below "
                "e): the sensors cannot localise it. Add sensors about those places, or check them one by one." + note)
    if outcome == "unconfirmed":
        top = effects[0]
        return (f"{top.effect.kind} at {top.effect.where()} fits the data to the stated noise (χ² per row "
                f"{top.chi2_per_row:.2f}, the baseline {b.chi2_per_row:.1f}) but is not confirmed: {failed(top)}. "
                "More test modes, or a test aimed at that place, are needed before adding it." + note)
    if outcome == "unexplained":
        return (f"No effect in the library explains the data: the baseline leaves χ² per row "
                f"{b.chi2_per_row:.1f} at the stated noise (held-out RMS Δf {b.heldout_rms_freq_dev_pct:.2f} %, modes "
                f"{_off_text(base)} off), no candidate reaches the noise and none passes the held-out tests"
                + (f"; best partial candidates: {listed}" if listed else "")
                + ". The model does not represent this structure (model form, e.g. plates modelled as beams) or "
                  "the missing physics lies outside the candidate library." + note)
    if base.at_noise:
        text = (f"No extra effect is warranted: the baseline explains the data to the stated noise "
                f"(χ² per row {b.chi2_per_row:.2f}, held-out RMS Δf {b.heldout_rms_freq_dev_pct:.2f} %)")
    else:
        text = (f"No extra effect is warranted: the baseline's misfit (χ² per row {b.chi2_per_row:.1f}) is spread "
                f"over all modes like noise — the stated noise looks understated ({_sd_text(base)})")
    top = effects[0] if effects else None
    if top is not None and top.checks.decisive_over_baseline:
        return (text + f"; the most probable candidate, {top.effect.kind} at {top.effect.where()} (χ²/row "
                f"{top.chi2_per_row:.2f}), is not confirmed: {failed(top)}." + note)
    return text + (f"; candidates that did not pass: {listed}" if listed else "") + "." + note
