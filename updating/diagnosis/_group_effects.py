"""Factors on a property group: :class:`GroupStiffness`, :class:`GroupMass` (eq. 3.1) and the
frequency law :class:`FrequencyDependentStiffness`; the kinds by name: :mod:`updating.diagnosis._effects`."""

from __future__ import annotations

from dataclasses import replace
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfem
from jaxfem import Model

from .. import K_BLOCKS, Extension, Parameter, extension
from ._abstract_effect import AbstractEffect, ids_field, label_field, value_field
from ._scans import SCAN_LAW
from ._topology import property_groups, stiffness_pids, structural_pids

LAW_SHARE = 0.5  # the largest share of the stiffness elements a frequency law's group may hold

# ---------------------------------------------------------------------------------------
# factors on a property group


def _combined(a0: float, theta) -> float:
    """(1 + a₀)(1 + α) − 1 with α = e^θ − 1: factors multiply (eq. 3.1); exact for a₀ = 0."""
    alpha = float(np.expm1(theta))
    return a0 + alpha + a0 * alpha


class AbstractGroupEffect(AbstractEffect):
    """A factor (value ``factor_name``) on the stiffness (``scales`` "k") or mass ("m")
    of a property group (``pids``) or part of one (``eids``): the element matrices scaled
    by 1 + factor (eq. 3.1). Free parameter θ = ln(1 + α'), factors multiplying."""

    factor_name: ClassVar[str]

    def __check_init__(self):
        if not (self.pids or self.eids):
            raise ValueError(f"effect {self.kind}: give pids or eids")

    def elements(self, model: Model) -> np.ndarray:
        """Element ids of the group (``eids`` if given, else the ``pids``)."""
        return np.asarray(self.eids, np.int64) if self.eids else model.element_ids(pids=self.pids)

    def _factor(self) -> float:
        return getattr(self, self.factor_name) or 0.0

    def _parameter(self, name: str) -> Parameter:
        kind = {"k": "stiffness", "m": "mass"}[self.scales]
        return Parameter(name, kind, **({"eids": self.eids} if self.eids else {"pids": self.pids}))

    def apply(self, model: Model) -> Model:
        group, factor = [self.elements(model).tolist()], jnp.array([self._factor()])
        return jaxfem.correct(model, group, factor) if self.scales == "k" else jaxfem.correct(model, (), None, group, factor)

    def at_reference(self, model: Model, f_test_hz) -> AbstractGroupEffect:
        """No change."""
        return replace(self, **{self.factor_name: 0.0})

    def parameters(self, before: Model, after: Model) -> tuple[Parameter, ...]:
        return (self._parameter(self.kind),)

    def extension(self, model: Model, extended: Model) -> Extension:
        return extension(extended, **{f"{self.scales}_log": self.elements(model)})

    def updated(self, theta) -> AbstractGroupEffect:
        return replace(self, **{self.factor_name: _combined(self._factor(), np.asarray(theta, float)[0])})

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        f = self._factor()
        return [] if -0.5 <= f <= 1.0 else [f"factor {f:+.2f} outside [-0.5, 1.0]"]

    def advice(self, sd) -> str:
        what = {"k": "stiffness", "m": "mass"}[self.scales]
        f, s = self._factor(), float(np.atleast_1d(sd)[0])
        unc = f"±{100 * (1 + f) * s:.1f} %" if np.isfinite(s) else "not determined by the data"
        return f"change the {what} of {self.where()} by {100 * f:+.1f} % ({unc})"


class GroupStiffness(AbstractGroupEffect):
    """Stiffness factor α of a group, ``K = K₀ + α K_g`` (eq. 3.1). Values: ``alpha`` (1)."""

    pids: tuple[int, ...] = ids_field()
    eids: tuple[int, ...] = ids_field()
    label: str = label_field()
    alpha: float | None = value_field()

    kind = "stiffness"
    value_names = ("alpha",)
    factor_name = "alpha"
    scales = "k"
    scan = None
    prior_sd = (0.3,)

    @classmethod
    def candidates(cls, model: Model) -> list[GroupStiffness]:
        """Every stiffness property group, and both halves of each beam/rod group."""
        return [cls(pids=(p,), eids=e, label=lab) for p, e, lab in property_groups(model, stiffness_pids(model), split=True)]


class GroupMass(AbstractGroupEffect):
    """Mass factor β of a group, ``M = M₀ + β M_g`` (eq. 3.1). Values: ``beta`` (1)."""

    pids: tuple[int, ...] = ids_field()
    eids: tuple[int, ...] = ids_field()
    label: str = label_field()
    beta: float | None = value_field()

    kind = "mass"
    value_names = ("beta",)
    factor_name = "beta"
    scales = "m"
    scan = None
    prior_sd = (0.2,)

    @classmethod
    def candidates(cls, model: Model) -> list[GroupMass]:
        """Every beam/rod property group and both halves of each."""
        pids = [p for p in stiffness_pids(model) if p in structural_pids(model)]
        return [cls(pids=(p,), eids=e, label=lab) for p, e, lab in property_groups(model, pids, split=True)]


class FrequencyDependentStiffness(AbstractGroupEffect):
    """A frequency law on a group's stiffness, ``E(f) = E0 (1 + α)(1 + a ln(f/f_ref))``
    (:class:`jaxfem.Viscoelastic`). Values: ``alpha`` (1), ``a`` (1), ``f_ref_hz`` (Hz).

    Free parameters θ = (ln(1 + α'), ln(1 + a')): a stiffness factor on E0 and the
    additive change of the coefficient, ``a = a₀ + (e^θ₁ − 1)``, in the shared-structure fits
    (:class:`~updating._extension.Extension`) and in an update (parameter kind ``a``).
    """

    pids: tuple[int, ...] = ids_field()
    eids: tuple[int, ...] = ids_field()
    label: str = label_field()
    alpha: float | None = value_field()
    a: float | None = value_field()
    f_ref_hz: float | None = value_field()

    kind = "frequency_dependent_stiffness"
    value_names = ("alpha", "a", "f_ref_hz")
    factor_name = "alpha"
    scales = "k"
    scan = SCAN_LAW
    prior_sd = (0.3, 0.7)  # a = e^θ₁ − 1 within (−0.75, 3) at 2σ: visco-elastic moduli may rise steeply

    def __check_init__(self):
        if not self.pids:
            raise ValueError(f"effect {self.kind}: give the pids of the layer")

    @classmethod
    def candidates(cls, model: Model) -> list[FrequencyDependentStiffness]:
        """Every stiffness property group, whole, of at most :data:`LAW_SHARE` of the
        structure's stiffness elements: a material law of (nearly) the whole structure is
        model form, not a missing local physics."""
        n = len(model.element_ids(pids=stiffness_pids(model)))
        return [cls(pids=(p,), label=lab) for p, _, lab in property_groups(model, stiffness_pids(model), split=False)
                if len(model.element_ids(pids=(p,))) <= LAW_SHARE * n]

    def apply(self, model: Model) -> Model:
        model, group = super().apply(model), self.elements(model).tolist()
        masks = [jnp.asarray(np.isin(getattr(model, b).ids, group), dtype=jnp.float64) for b in K_BLOCKS]
        law = jaxfem.Viscoelastic(tuple(masks), jnp.asarray(self.a or 0.0), jnp.asarray(self._need("f_ref_hz")))
        return eqx.tree_at(lambda m: m.viscoelastic, model, law, is_leaf=lambda x: x is None)

    def at_reference(self, model: Model, f_test_hz) -> FrequencyDependentStiffness:
        """No change, at the geometric mean of the test frequencies."""
        return replace(self, alpha=0.0, a=0.0, f_ref_hz=float(np.exp(np.mean(np.log(np.asarray(f_test_hz, float))))))

    def parameters(self, before: Model, after: Model) -> tuple[Parameter, ...]:
        return (self._parameter(self.kind + "_E0"), Parameter(self.kind + "_a", "a", pids=self.pids, bounds=(-0.5, 0.5)))

    def extension(self, model: Model, extended: Model) -> Extension:
        return extension(extended, k_log=self.elements(model), f_ref=self._need("f_ref_hz"), a0=self.a or 0.0)

    def updated(self, theta) -> FrequencyDependentStiffness:
        t = np.asarray(theta, float)
        return replace(super().updated(t[:1]), a=(self.a or 0.0) + float(np.expm1(t[1])))

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        return super().plausibility(total_mass) + ([f"a = {self.a:.2f} beyond ±0.5"] if abs(self.a) > 0.5 else [])

    def advice(self, sd) -> str:
        s = np.broadcast_to(np.asarray(sd, float), (2,))
        a_sd = f"±{(1 + self.a) * s[1]:.2g}" if np.isfinite(s[1]) else "not determined by the data"
        return (f"give {self.where()} a frequency-dependent stiffness E(f) = E0·(1 {self.alpha:+.3f})·"
                f"(1 + a·ln(f / {self.f_ref_hz:.3g} Hz)) with a = {self.a:.3f} ({a_sd})")
