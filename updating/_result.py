"""Results of an update: the accepted iterates and the updated model (thesis §3.2)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from identification import rms_pct
from jaxfem import Model

from ._json import json_number
from ._parameters import Parameterisation


@dataclass(frozen=True)
class Iteration:
    """One accepted iterate: parameters, per-test-mode Δf and MAC (NaN if unpaired), cost."""

    iteration: int
    alpha: np.ndarray
    freq_dev: np.ndarray
    mac: np.ndarray
    cost: float

    def to_json(self, names: list[str], passive=None) -> dict:
        """JSON-ready: ``alpha`` by parameter name, ``freq_dev_pct`` and ``mac`` per test
        mode (null where unpaired), ``cost``, and the RMS Δf (%) over the active and over
        the passive (held-out; ``passive``: bool per test mode, default none) test modes,
        null where no such mode is paired. The one schema of every iteration history."""
        dev = 100.0 * np.asarray(self.freq_dev, dtype=np.float64)
        passive = np.zeros(dev.shape, bool) if passive is None else np.asarray(passive, bool)
        return {
            "iteration": int(self.iteration),
            "alpha": {name: float(a) for name, a in zip(names, np.asarray(self.alpha))},
            "freq_dev_pct": [json_number(d) for d in dev],
            "mac": [json_number(m) for m in np.asarray(self.mac)],
            "cost": float(self.cost),
            "rms_freq_dev_pct_active": rms_pct(dev[~passive] / 100),
            "rms_freq_dev_pct_passive": rms_pct(dev[passive] / 100),
        }


@dataclass(frozen=True)
class UpdateResult:
    """Outcome of :func:`update`: updated model, factors, history, before/after pairings."""

    model: Model
    names: list[str]
    alpha: np.ndarray
    theta: np.ndarray
    converged: bool
    iterations: int
    history: list[Iteration]
    active: np.ndarray  # bool per test mode
    before: object  # Pairing (Hungarian) of the initial model
    after: object  # Pairing of the updated model
    seconds: float
    sensor_modes: dict  # "before"/"after": (model frequencies in Hz, shapes at the sensors)
    parameterisation: Parameterisation = field(repr=False)
    warnings: tuple[str, ...] = ()  # e.g. an under-determined fit (updating._solve)

    def table(self) -> list[dict]:
        """Parameters with their factors α (value = value₀·(1 + α))."""
        return [{"name": n, "kind": p.kind, "alpha": float(a)} for n, p, a in
                zip(self.names, self.parameterisation.parameters, self.alpha)]

    def to_json(self) -> dict:
        """JSON-ready: parameters (name, kind, α, bounds, within bounds), convergence,
        the iteration history (:meth:`Iteration.to_json`, passive = not active), the
        pairings before and after (:meth:`Pairing.to_json`), active and passive modes,
        ``warnings`` (why ``converged`` may say little, e.g. an under-determined fit)."""
        active = np.asarray(self.active, dtype=bool)
        parameters = [dict(row, bounds=list(p.bounds), within_bounds=bool(p.bounds[0] <= row["alpha"] <= p.bounds[1]))
                      for row, p in zip(self.table(), self.parameterisation.parameters)]
        return {
            "parameters": parameters,
            "converged": bool(self.converged),
            "warnings": list(self.warnings),
            "iterations": int(self.iterations),
            "seconds": float(self.seconds),
            "history": [h.to_json(self.names, ~active) for h in self.history],
            "before": self.before.to_json(),
            "after": self.after.to_json(),
            "active_modes": [int(j) + 1 for j in np.flatnonzero(active)],
            "passive_modes": [int(j) + 1 for j in np.flatnonzero(~active)],
        }
