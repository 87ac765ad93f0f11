"""The abstract physical effect: what every kind of :mod:`updating.diagnosis._effects` owns."""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import numpy as np

from jaxfem import Model

from .. import Extension, Parameter


def _ids(ids) -> tuple[int, ...]:
    return tuple(int(i) for i in ids)


def _value(v) -> float | None:
    return None if v is None else float(v)


def ids_field():
    """A location field: bulk-data ids as a static tuple (default empty)."""
    return eqx.field(static=True, default=(), converter=_ids)


def value_field():
    """A physical value: a float leaf, None until set."""
    return eqx.field(default=None, converter=_value)


def label_field():
    """The location in words, if not generated from the ids."""
    return eqx.field(static=True, default="")


class AbstractEffect(eqx.Module):
    """A physical effect at a place in the model, with its physical values (SI).

    A final subclass per kind holds its location (``pids``/``eids``/``nodes``, static
    tuples of bulk-data ids; ``label``: the location in words, if given) and its values
    (``value_names``: float leaves, None until set), and offers its candidates in a model
    (classmethod ``candidates``). ``kind``: the JSON/CLI name. ``scales``: ``"k"`` or
    ``"m"``, the element scale its first free factor multiplies. ``scan``: log-factors θ
    tried from the reference before updating it (None: start at the reference).
    ``prior_sd``: standard deviation of the weakly-informative normal prior on each free
    log-factor θ, centred on the reference (θ = 0); the diagnosis' evidence uses it.
    """

    label: eqx.AbstractVar[str]
    kind: ClassVar[str]
    value_names: ClassVar[tuple[str, ...]]
    scales: ClassVar[str]
    scan: ClassVar[tuple | None]
    prior_sd: ClassVar[tuple[float, ...]]

    @abc.abstractmethod
    def apply(self, model: Model) -> Model:
        """The model with this effect at its values."""

    @abc.abstractmethod
    def at_reference(self, model: Model, f_test_hz) -> AbstractEffect:
        """This effect at its starting values for a fit (test frequencies in Hz)."""

    @abc.abstractmethod
    def parameters(self, before: Model, after: Model) -> tuple[Parameter, ...]:
        """Updating parameters of this effect added to ``before`` (giving ``after``); the
        engine's θ of each is the log-factor that :meth:`updated` takes."""

    @abc.abstractmethod
    def extension(self, model: Model, extended: Model) -> Extension:
        """The same free parameters as traced masks on ``extended`` (this effect applied
        to ``model``)."""

    @abc.abstractmethod
    def updated(self, theta) -> AbstractEffect:
        """The effect at fitted log-factors θ of its :meth:`parameters` (θ = 0: unchanged)."""

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        """Notes on implausible values (none: plausible); ``total_mass`` in kg,
        ``reference`` the effect at its starting values."""
        return []

    @abc.abstractmethod
    def advice(self, sd) -> str:
        """What to add to the model, in words, at these values; ``sd``: the standard
        deviation of each free log-factor θ (from the evidence's Laplace approximation)."""

    @property
    def values(self) -> dict[str, float]:
        """The physical values that are set, by name."""
        return {n: getattr(self, n) for n in self.value_names if getattr(self, n) is not None}

    def location(self) -> dict[str, tuple[int, ...]]:
        """``pids``, ``eids``, ``nodes`` (empty where the kind has none)."""
        return {name: getattr(self, name, ()) for name in ("pids", "eids", "nodes")}

    def where(self) -> str:
        """The location in words."""
        if self.label:
            return self.label
        names = {"pids": "pid", "eids": "eid", "nodes": "node"}
        return "; ".join(f"{names[k]} {', '.join(map(str, ids))}" for k, ids in self.location().items() if ids)

    def to_json(self) -> dict:
        """``kind``, ``pids``, ``eids``, ``nodes``, ``where`` and ``parameters`` (values)."""
        return {"kind": self.kind, **{k: list(v) for k, v in self.location().items()},
                "where": self.where(), "parameters": self.values}

    def _need(self, name: str) -> float:
        v = getattr(self, name)
        if v is None:
            raise ValueError(f"{self.kind} at {self.where()}: value {name!r} is not set "
                             "(at_reference gives starting values)")
        return v


def spread(value: float, sd: float, unit: str) -> str:
    """``value unit (±…)`` for a quantity known to a log-factor standard deviation ``sd``:
    ± in the unit up to sd = 0.3, else "within a factor" e^sd (``unit`` "": a pure number)."""
    u = f" {unit}" if unit else ""
    if not np.isfinite(sd):
        return f"{value:.3g}{u} (not determined by the data)"
    if sd <= 0.3:
        return f"{value:.3g}{u} (±{abs(value) * sd:.2g}{u})"
    return f"{value:.3g}{u} (within a factor {np.exp(sd):.2g})"
