"""Results of an update: the accepted iterates and the updated model (thesis §3.2)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from jaxfem import Model

from ._parameters import Parameterisation


@dataclass
class Iteration:
    """One accepted iterate: parameters, per-test-mode Δf and MAC (NaN if unpaired), cost."""

    iteration: int
    alpha: np.ndarray
    freq_dev: np.ndarray
    mac: np.ndarray
    cost: float


@dataclass
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

    def table(self) -> list[dict]:
        """Parameters with their factors α (value = value₀·(1 + α))."""
        return [{"name": n, "kind": p.kind, "alpha": float(a)} for n, p, a in
                zip(self.names, self.parameterisation.parameters, self.alpha)]
