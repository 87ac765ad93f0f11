"""The typed result of a diagnosis (:func:`updating.diagnose`); JSON only through ``to_json``."""

from __future__ import annotations

from dataclasses import dataclass

from identification import Pairing
from jaxfem import Model

from .. import Noise, Parameter, json_safe
from ._abstract_effect import AbstractEffect
from ._candidates import Candidate
from ._damping import DampingDiagnosis
from ._evidence import CandidateResult
from ._confirm import Confirmation
from ._evidence import Remainder
from ._verdict import Baseline, Declared, Withdrawn


@dataclass(frozen=True)
class Localisation:
    """Where the error sits: property groups and grids by score (sensitivity and residual
    force, each scaled to 1 at its best, and their mean), and the region the node-based
    candidates were offered in."""

    groups: tuple[tuple[int, float, float, float], ...]  # (pid, score, sensitivity, residual force)
    nodes: tuple[tuple[int, float, float, float], ...]  # (grid, score, sensitivity, residual force), best 30
    region: tuple[int, ...]

    def to_json(self) -> dict:
        return {"groups": [{"pid": p, "score": s, "sensitivity": a, "residual_force": b} for p, s, a, b in self.groups],
                "nodes": [{"node": n, "score": s, "sensitivity": a, "residual_force": b} for n, s, a, b in self.nodes],
                "region": list(self.region)}


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`. ``outcome``: the state (:mod:`._verdict`: "effect",
    "partial", "none_needed", "unconfirmed", "cannot_localise" or "unexplained");
    ``verdict``: that in one sentence (and the damping part's); ``effects``: the last
    round's ranked candidates, best first; ``best``: the first declared effect (None when
    none is); ``ties``: places the sensors cannot tell from the last declared one (or, when
    it cannot localise, from the winner); ``baseline``; the
    ``pairing`` at the baseline and each sensor's COMAC; ``localisation``; the stated
    ``noise``; ``damping`` (the damping
    part, where the test has damping ratios); ``declared``: the declared effects in order
    (:class:`Declared`), ``withdrawn`` a winner its confirming update withdrew,
    ``remainder`` what the final model leaves, ``rounds`` searched, ``confirmation`` the
    last declared effect's confirming update (the model with every declared effect).
    """

    outcome: str
    verdict: str
    effects: tuple[CandidateResult, ...]
    ties: tuple[CandidateResult, ...]
    best: AbstractEffect | None
    baseline: Baseline
    pairing: Pairing
    comac: tuple[tuple[str, float], ...]  # (sensor label, COMAC)
    localisation: Localisation
    noise: Noise
    noise_scale: float
    baseline_posterior: float
    candidates_evaluated: int
    candidates_fitted: int
    seconds: float
    candidates: tuple[Candidate, ...]
    model: Model
    baseline_params: tuple[Parameter, ...]
    element_scores: dict[int, float]
    node_scores: dict[int, float]
    sensor_modes: tuple  # baseline model frequencies (Hz) and shapes at the sensors
    damping: DampingDiagnosis | None = None
    declared: tuple[Declared, ...] = ()
    withdrawn: Withdrawn | None = None
    remainder: Remainder | None = None
    rounds: int = 1
    confirmation: Confirmation | None = None

    @property
    def no_effect_warranted(self) -> bool:
        return self.best is None

    def to_json(self) -> dict:
        """The ``diagnosis.json`` content (docs/json.md), NaN and inf as null."""
        compared = self.pairing.summary()
        out = {
            "paired_modes": compared["paired_modes"], "unpaired_test": compared["unpaired_test"],
            "unpaired_model": compared["unpaired_model"][:10],
            "baseline": self.baseline.to_json(),
            "sensors": [{"label": lab, "comac": v} for lab, v in self.comac],
            "localisation": self.localisation.to_json(),
            "declared": [d.to_json() for d in self.declared],
            "withdrawn": self.withdrawn.to_json() if self.withdrawn is not None else None,
            "remainder": self.remainder.to_json() if self.remainder is not None else None,
            "rounds": self.rounds,
            "effects": [e.to_json() for e in self.effects],
            "outcome": self.outcome, "noise_scale": self.noise_scale, "baseline_posterior": self.baseline_posterior,
            "ties": [{k: e.to_json()[k] for k in ("kind", "where", "nodes", "pids", "posterior", "log_evidence")}
                     for e in self.ties],
            "no_effect_warranted": self.no_effect_warranted,
            "candidates_evaluated": self.candidates_evaluated, "candidates_fitted": self.candidates_fitted,
            "noise": {"freq_pct": 100 * self.noise.frequency, "shape_pct": 100 * self.noise.relative},
            "verdict": self.verdict,
        }
        if self.damping is not None:
            out["damping"] = self.damping.to_json()
        out["seconds"] = self.seconds
        return json_safe(out)
