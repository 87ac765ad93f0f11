"""Candidate physical effects: small parameterised extensions of a model, one type per kind.

Every effect is a final ``eqx.Module``: where it sits (property ids, element ids, grids,
in the bulk data's own ids; static) and its physical values (SI; None until set). Each
knows how to ``apply`` itself to a model (also ``model.with_effect(effect)``), its
location in words (``where``), its starting values (``at_reference``), its free
parameters for the updating engine (``parameters``) and, for fits sharing one compiled solver, as traced masks
(``extension``), its values at fitted log-factors θ (``updated``), whether they are
plausible (``plausibility``) and, as a classmethod, the candidates of its kind that a
model offers (``candidates``). The kinds, by their JSON/CLI names:

- ``stiffness`` / ``mass`` (:class:`GroupStiffness`, :class:`GroupMass`): factor on a
  property group or part of one (eq. 3.1);
- ``joint`` (:class:`Joint`): a rigid connection made flexible;
- ``added_mass`` (:class:`AddedMass`): a point mass at a grid;
- ``payload`` (:class:`Payload`): a point mass on an RBE3 over a footprint of grids, its CG at
  a height above them;
- ``boundary_spring`` (:class:`BoundarySpring`): springs to ground at a grid;
- ``frequency_dependent_stiffness`` (:class:`FrequencyDependentStiffness`):
  ``E(f) = E0 (1 + α)(1 + a ln(f/f_ref))`` on a group (:class:`jaxfem.Viscoelastic`).

:func:`Effect` is the convenient constructor from a kind name and a values dict.
"""

from __future__ import annotations

import abc
from dataclasses import fields, replace
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfem
from jaxfem import Model
from jaxfem import _edit as edit

from ._abstract_effect import AbstractEffect, ids_field, label_field, spread, value_field
from ._extension import K_BLOCKS, PARTS, Extension, extension
from ._parameters import Parameter
from ._topology import (
    constrained_components,
    elements_at,
    joint_reference,
    masters,
    patch_elements,
    property_groups,
    stiffness_pids,
    shell_area,
    structural_pids,
    total_mass,
)

SCAN = (0.0, -1.5, -3.0, -4.5, -6.0, 1.5)  # log-factors tried before fitting a joint, support or mass
SCAN_SEAM = (0.0, -2.0, -4.0, -6.0, -8.0, -10.0, -12.0)  # a seam's: from rigid (reference 100 EA/L) to a detached frame
SCAN_LAW = tuple((0.0, np.log1p(a)) for a in (-0.3, 0.0, 0.15, 0.3, 0.8, 1.5))  # (E0 factor, a − a₀) of a frequency law


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
        """Every stiffness property group, whole."""
        return [cls(pids=(p,), label=lab) for p, _, lab in property_groups(model, stiffness_pids(model), split=False)]

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


# ---------------------------------------------------------------------------------------
# patches of shells: a delamination, a local loss of stiffness, distributed mass


ETA_SD = 0.3  # prior σ of a local loss factor: friction 0.01–0.1, visco-elastic layers 0.1–1
RADII = (0.75, 1.7, 2.6, 3.6)  # patch radius ladder, in shell element sizes: about a grid 4, 12, 24 and 44 square shells


class AbstractPatch(AbstractEffect):
    """An effect on the shells of a patch: those whose centres lie within ``radius`` (m) of
    grid ``nodes[0]`` (and at least those attached to it), or the shells ``eids`` if given.
    Its one free parameter θ is a log-factor on the patch's value."""

    @property
    def centre(self) -> int:
        return self.nodes[0]

    def elements(self, model: Model) -> np.ndarray:
        """The patch's shell element ids."""
        if self.eids:
            return np.asarray(self.eids, np.int64)
        return np.asarray(patch_elements(model, self.centre, self.radius), np.int64)

    def located(self, model: Model) -> AbstractPatch:
        """This patch with its elements listed (``eids``) and its location in words."""
        eids = tuple(int(e) for e in self.elements(model))
        label = self.label or f"{len(eids)} shells within {1000 * self.radius:.0f} mm of grid {self.centre}"
        return replace(self, eids=eids, label=label)

    def __check_init__(self):
        if len(self.nodes) != 1 and not self.eids:
            raise ValueError(f"effect {self.kind}: give its centre grid (nodes) and radius, or its eids")
        if not self.eids and not self.radius > 0:
            raise ValueError(f"effect {self.kind}: radius must be > 0 m")

    def where(self) -> str:
        return self.label or (f"shells within {1000 * self.radius:.0f} mm of grid {self.centre}" if self.nodes
                              else super().where())

    def to_json(self) -> dict:
        return {**super().to_json(), "radius_m": self.radius}

    @classmethod
    def candidates(cls, model: Model) -> list[AbstractPatch]:
        """Patches are placed where the diagnosis localised the error (:meth:`at`), not listed."""
        return []

    @classmethod
    def at(cls, model: Model, node: int, radius: float, **kwargs) -> AbstractPatch:
        """The patch of radius ``radius`` (m) about grid ``node``, its elements listed."""
        return cls(nodes=(node,), radius=radius, **kwargs).located(model)

    def updated(self, theta) -> AbstractPatch:
        name = self.value_names[0]
        return replace(self, **{name: float(getattr(self, name) * np.exp(np.asarray(theta, float)[0]))})


class AbstractPatchPart(AbstractPatch):
    """A factor on one part of the patch's shell stiffness (:class:`jaxfem.Shells`
    ``parts``: membrane, bending or transverse shear), 1 = intact. Value ``factor``."""

    part: ClassVar[str]

    def apply(self, model: Model) -> Model:
        eids, col, factor = self.elements(model), PARTS.index(self.part), self._need("factor")
        for name in ("quads", "trias"):
            sh = getattr(model, name)
            at = jnp.asarray(np.isin(sh.ids, eids))
            model = eqx.tree_at(lambda m, name=name: getattr(m, name).parts, model,
                                sh.parts.at[:, col].multiply(jnp.where(at, factor, 1.0)))
        return model

    def _kind_of_part(self) -> str:
        return "transverse_shear" if self.part == "shear" else self.part

    def at_reference(self, model: Model, f_test_hz) -> AbstractPatchPart:
        """Intact (factor 1)."""
        return replace(self.located(model), factor=1.0)

    def parameters(self, before: Model, after: Model) -> tuple[Parameter, ...]:
        return (Parameter(self.kind, self._kind_of_part(), eids=tuple(self.elements(before)), bounds=(-0.99, 0.5)),)

    def extension(self, model: Model, extended: Model) -> Extension:
        return extension(extended, part_log=self.elements(model), part=self.part)

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        if self.factor > 1.5:
            return [f"{self.part} stiffness × {self.factor:.2f}: a damage that stiffens"]
        return []

    def advice(self, sd) -> str:
        s = float(np.atleast_1d(sd)[0])
        return (f"{self.verb} in the {self.where()}: {self.part} stiffness × {spread(self.factor, s, '')}, "
                f"{100 * (self.factor - 1):+.0f} %")


class Delamination(AbstractPatchPart):
    """A delamination: the transverse-shear stiffness of a patch reduced (the thesis models
    it as a 90 % reduction of G1Z and G2Z, §5.3.2.1). Value ``factor`` (1 = intact)."""

    nodes: tuple[int, ...] = ids_field()
    eids: tuple[int, ...] = ids_field()
    label: str = label_field()
    radius: float = eqx.field(static=True, default=0.0)
    factor: float | None = value_field()

    kind = "delamination"
    value_names = ("factor",)
    part = "shear"
    verb = "a delamination"
    scales = "shear"
    scan = (0.0, -1.2, -2.3, -3.5)
    prior_sd = (2.0,)  # a 90 % loss (θ = −2.3) lies within 1.2σ


class PatchStiffness(AbstractPatchPart):
    """Local loss (or gain) of membrane or bending stiffness in a patch: impact damage, a
    softer repair. ``part``: "membrane" or "bending". Value ``factor`` (1 = intact)."""

    nodes: tuple[int, ...] = ids_field()
    eids: tuple[int, ...] = ids_field()
    label: str = label_field()
    radius: float = eqx.field(static=True, default=0.0)
    part: str = eqx.field(static=True, default="bending")
    factor: float | None = value_field()

    kind = "patch_stiffness"
    value_names = ("factor",)
    verb = "a local stiffness change"
    scan = (0.0, -0.7, -1.6, 0.4)
    prior_sd = (1.0,)

    def __check_init__(self):
        super().__check_init__()
        if self.part not in ("membrane", "bending"):
            raise ValueError(f"effect patch_stiffness: part must be membrane or bending, got {self.part!r}")

    @property
    def scales(self) -> str:
        return self.part

    def where(self) -> str:
        return f"{self.part} of the " + super().where()

    def to_json(self) -> dict:
        return {**super().to_json(), "part": self.part}


class DistributedMass(AbstractPatch):
    """Non-structural mass spread over a patch (insulation, sealant, payload). Value
    ``nsm`` (kg/m², :class:`jaxfem.Shells` ``nsm``)."""

    nodes: tuple[int, ...] = ids_field()
    eids: tuple[int, ...] = ids_field()
    label: str = label_field()
    radius: float = eqx.field(static=True, default=0.0)
    nsm: float | None = value_field()

    kind = "distributed_mass"
    value_names = ("nsm",)
    scales = "nsm"
    scan = SCAN
    prior_sd = (1.5,)  # as an added mass

    def apply(self, model: Model) -> Model:
        eids = self.elements(model)
        for name in ("quads", "trias"):
            sh = getattr(model, name)
            at = jnp.asarray(np.isin(sh.ids, eids), dtype=jnp.float64)
            model = eqx.tree_at(lambda m, name=name: getattr(m, name).nsm, model, sh.nsm + at * self._need("nsm"))
        return model

    def at_reference(self, model: Model, f_test_hz) -> DistributedMass:
        """1 % of the total mass, spread over the patch."""
        return self.carrying(model, 0.01 * total_mass(model))

    def carrying(self, model: Model, mass: float) -> DistributedMass:
        """This patch carrying ``mass`` (kg) spread evenly over its area."""
        patch = self.located(model)
        return replace(patch, nsm=mass / shell_area(model, patch.elements(model)))

    def parameters(self, before: Model, after: Model) -> tuple[Parameter, ...]:
        return (Parameter(self.kind, "nsm", eids=tuple(self.elements(before)), bounds=(-1.0, 10.0)),)

    def extension(self, model: Model, extended: Model) -> Extension:
        return extension(extended, nsm_add=self.elements(model), nsm=self._need("nsm"))

    def mass(self, model: Model) -> float:
        """The mass added (kg)."""
        return self._need("nsm") * shell_area(model, self.elements(model))

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        if reference is not None and self.nsm > 20.0 * reference.nsm:
            return [f"{self.nsm:.3g} kg/m² over the patch is {self.nsm / reference.nsm:.0f} % of the total mass"]
        return []

    def advice(self, sd) -> str:
        return (f"add non-structural mass of {spread(self.nsm, float(np.atleast_1d(sd)[0]), 'kg/m²')} "
                f"over the {self.where()}")


class LocalDamping(AbstractPatch):
    """A local structural loss factor: a visco-elastic layer, friction in a joint or
    between delaminated plies. The elements of a patch (shells about a grid) or ``eids``
    (a property group, the beams at a grid) get loss factor ``eta`` (Nastran GE) on their
    whole stiffness, :class:`jaxfem.StructuralDamping`. It changes no stiffness or mass,
    so no modal update can fit it: :func:`updating.diagnose_damping` does, from measured
    modal damping (eq. 3.40 plus the modal strain energy of the elements)."""

    nodes: tuple[int, ...] = ids_field()
    eids: tuple[int, ...] = ids_field()
    label: str = label_field()
    radius: float = eqx.field(static=True, default=0.0)
    eta: float | None = value_field()

    kind = "damping"
    value_names = ("eta",)
    scales = "eta"
    scan = None
    prior_sd = (ETA_SD,)  # on η itself (≥ 0; half-normal), not on a log-factor

    def where(self) -> str:
        return self.label or ("the " + super().where())

    def apply(self, model: Model) -> Model:
        eids, eta = tuple(int(e) for e in self.elements(model)), self._need("eta")
        old = model.damping
        kept = {} if old is None else {e: v for e, v in zip(old.eids, np.asarray(old.eta)) if e not in set(eids)}
        kept.update(dict.fromkeys(eids, eta))
        return replace(model, damping=jaxfem.StructuralDamping(tuple(kept), jnp.asarray(list(kept.values()))))

    def at_reference(self, model: Model, f_test_hz) -> LocalDamping:
        """A loss factor of 0.1 (a structural adhesive or a lightly damped visco-elastic layer)."""
        return replace(self.located(model) if not self.eids else self, eta=0.1)

    def _modal_only(self):
        raise ValueError(f"effect damping at {self.where()}: a loss factor changes no stiffness or mass, so the "
                         "modal update cannot fit it; updating.diagnose_damping fits it from measured damping")

    def parameters(self, before: Model, after: Model) -> tuple[Parameter, ...]:
        self._modal_only()

    def extension(self, model: Model, extended: Model) -> Extension:
        self._modal_only()

    def updated(self, theta) -> LocalDamping:
        """At loss factor θ[0] (linear, not a log-factor: η may be 0)."""
        return replace(self, eta=float(np.asarray(theta, float)[0]))

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        if self.eta > 2.0:
            return [f"loss factor {self.eta:.2g}: beyond the most damping visco-elastic materials (about 2)"]
        return []

    def advice(self, sd) -> str:
        s = float(np.atleast_1d(sd)[0])
        return f"give {self.where()} a structural loss factor η = {self.eta:.3g} (±{s:.2g})"


PATCH_KINDS = (Delamination, PatchStiffness, DistributedMass)


# ---------------------------------------------------------------------------------------
# effects that add elements: springs, bushes, masses


class AbstractAddedElements(AbstractEffect):
    """An effect that adds elements to the model. One free factor scales all of its
    values (the new elements' ``k`` or ``m``); a joint or a released support has two,
    on its translational and on its rotational stiffness (θ₀ on ``k_trans``, θ₁ on ``k_rot``)."""

    @property
    def split(self) -> bool:
        """Two free factors: translations and rotations."""
        return getattr(self, "k_rot", None) is not None

    @abc.abstractmethod
    def add_to(self, model: Model) -> Model:
        """The model with this effect's elements added, its DoF map not yet refreshed
        (several effects added at once refresh once: :func:`jaxfem._edit.refresh`)."""

    def apply(self, model: Model) -> Model:
        return edit.refresh(self.add_to(model))

    def _new(self, before: Model, after: Model) -> tuple[int, ...]:
        return tuple(sorted(set(after.element_ids().tolist()) - set(before.element_ids().tolist())))

    def _halves(self, before: Model, after: Model) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """The new elements acting on translations and those acting on rotations."""
        new = np.asarray(self._new(before, after), np.int64)
        b, s = after.bushes, after.springs
        rot = np.concatenate([b.ids[np.isin(b.ids, new) & np.all(np.asarray(b.k)[:, :3] == 0, axis=1)],
                              s.ids[np.isin(s.ids, new) & (s.components[:, 0] > 3)]])
        return tuple(int(e) for e in new if e not in rot), tuple(int(e) for e in sorted(rot))

    def parameters(self, before: Model, after: Model) -> tuple[Parameter, ...]:
        if self.split:
            trans, rot = self._halves(before, after)
            return (Parameter(self.kind + "_trans", "k", eids=trans, bounds=(-0.999, 1e3)),
                    Parameter(self.kind + "_rot", "k", eids=rot, bounds=(-0.999, 1e3)))
        bounds = (-0.999, 1e3) if self.scales == "k" else (-1.0, 10.0)
        return (Parameter(self.kind, self.scales, eids=self._new(before, after), bounds=bounds),)

    def extension(self, model: Model, extended: Model) -> Extension:
        if self.split:
            trans, rot = self._halves(model, extended)
            return extension(extended, k_log=trans, k_log_2=rot)
        return extension(extended, **{f"{self.scales}_log": self._new(model, extended)})

    def dormant_extension(self, aug: Model, ids) -> Extension:
        """The free parameters of this effect's dormant elements ``ids`` in the diagnosis'
        shared model ``aug`` (scale 0 there; θ₀ = 0 wakes them at the reference values)."""
        return extension(aug, **{f"{self.scales}_add": ids})

    def updated(self, theta) -> AbstractAddedElements:
        t = np.asarray(theta, float)
        if self.split:
            return replace(self, k_trans=float(self.k_trans * np.exp(t[0])), k_rot=float(self.k_rot * np.exp(t[1])))
        return replace(self, **{name: float(v * np.exp(t[0])) for name, v in self.values.items()})

    def _check_nodes(self):
        if not self.nodes:
            raise ValueError(f"effect {self.kind}: give nodes")


def _rigid_note(effect: Joint | BoundarySpring, reference: AbstractEffect | None) -> list[str]:
    k_rot, ref = effect.k_rot, getattr(reference, "k_rot", None)
    if k_rot is not None and ref is not None and k_rot > 1e3 * ref:
        return ["joint stiffer than 1000× its reference: effectively rigid"]
    return []


def _release(model: Model, nodes, pids, k_trans: float, k_rot: float, shares=None) -> Model:
    """Each grid of ``nodes`` released into two bushes (translations ``k_trans``, rotations
    ``k_rot``, each × the grid's share, 1 by default): an RBE2-dependent grid is released
    and held to its master; a grid shared by groups gets a coincident new grid for the
    elements of ``pids[1:]``."""
    dep = masters(model)
    for node, share in zip(nodes, np.ones(len(nodes)) if shares is None else shares):
        master = dep.get(node)
        if master is None:  # a grid shared by two groups: the second group gets its own grid
            model, new = edit.add_grid(model, model.xyz[model.node_index([node])[0]])
            side = model.element_ids(pids=pids[1:])
            model = edit.reconnect(model, side.tolist(), node, new)
            a, b = node, new
        else:  # an RBE2-dependent grid becomes independent, held by springs
            model = edit.release(model, node)
            a, b = master, node
        # translations and rotations: two bushes, two factors; the springs at the released grid
        model = edit.add_bush(model, a, b, [k_trans * share] * 3 + [0.0] * 3, s=1.0)[0]
        model = edit.add_bush(model, a, b, [0.0] * 3 + [k_rot * share] * 3, s=1.0)[0]
    return model


class Joint(AbstractAddedElements):
    """A rigid connection made flexible: 6-DoF springs (two CBUSHes, translations and
    rotations) located at the released grid. At an RBE2-dependent grid the grid is
    released and held to its master; at a grid shared by two property groups
    (``pids``: the first keeps the grid, the others are moved to a new coincident one).
    Values: ``k_trans`` (N/m) on translations, ``k_rot`` (N·m/rad) on rotations."""

    nodes: tuple[int, ...] = ids_field()
    pids: tuple[int, ...] = ids_field()
    label: str = label_field()
    k_trans: float | None = value_field()
    k_rot: float | None = value_field()

    kind = "joint"
    value_names = ("k_trans", "k_rot")
    scales = "k"
    scan = tuple((t, t) for t in SCAN)
    prior_sd = (3.0, 3.0)  # stiffness spans decades: e^±6 ≈ ×/÷ 400 at 2σ

    def __check_init__(self):
        self._check_nodes()

    @classmethod
    def candidates(cls, model: Model) -> list[Joint]:
        """RBE2 groups holding structural elements, and grids shared by two beam/rod groups."""
        out = []
        dep = masters(model)
        by_master: dict[int, list[int]] = {}
        for node, master in dep.items():
            if elements_at(model, node):
                by_master.setdefault(master, []).append(node)
        for master, nodes in sorted(by_master.items()):
            pids = sorted({*elements_at(model, master).values()}) + sorted(
                {p for n in nodes for p in elements_at(model, n).values()})
            out.append(cls(pids=tuple(dict.fromkeys(pids)), nodes=tuple(sorted(nodes)),
                           label=f"RBE2 at grid {master} → {', '.join(map(str, sorted(nodes)))}"))
        beam_pids = set(structural_pids(model))
        for node in model.node_ids:
            at = {p for p in elements_at(model, int(node)).values() if p in beam_pids}
            if len(at) == 2 and int(node) not in dep:
                out.append(cls(pids=tuple(sorted(at)), nodes=(int(node),),
                               label=f"grid {int(node)} between pids {' and '.join(map(str, sorted(at)))}"))
        return out

    def add_to(self, model: Model) -> Model:
        return _release(model, self.nodes, self.pids, self._need("k_trans"), self._need("k_rot"))

    def at_reference(self, model: Model, f_test_hz) -> Joint:
        """Slightly flexible (:func:`~updating._topology.joint_reference` of the released side)."""
        dep = masters(model)
        if not all(n in dep for n in self.nodes) and len(self.pids) < 2:
            raise ValueError(f"joint at grid(s) {list(self.nodes)}: not RBE2-dependent; name the two "
                             "groups, e.g. joint:node=3007;pids=21,22 (the second group is released)")
        side = [e for n in self.nodes for e, p in elements_at(model, n).items() if n in dep or p in self.pids[1:]]
        return replace(self, **joint_reference(model, self.nodes, side))

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        return _rigid_note(self, reference)

    def advice(self, sd) -> str:
        s = np.broadcast_to(np.asarray(sd, float), (2,))
        return (f"make the {self.where()} a flexible joint: k_rot = {spread(self.k_rot, s[1], 'N·m/rad')}, "
                f"k_trans = {spread(self.k_trans, s[0], 'N/m')}")


SEAM_GRIDS = 5  # grids per seam candidate: a seam line is offered in runs of this many
SEAM_LENGTHS = (3, 5, 8, 13, 21, 34)  # seam ladder, in grids: a fitted seam is refined along its line and in length
SEAM_SCREEN = (13, 34)  # longer runs screened beside each run of SEAM_GRIDS (Seam.longer): a loose stretch
# whose short pieces do not fit on their own (the 33k barrel's 31 grids: its first 5 fit at a local minimum)


class Seam(AbstractAddedElements):
    """A seam or fastener line made flexible: the grids that a beam group (a frame, a
    stringer; ``pids[1]``) shares with a shell group (the skin; ``pids[0]``, which keeps
    them) along a line, each released into springs of a stiffness per unit length × the
    grid's share of the line (half the distance to each neighbour on it). Values:
    ``k_trans`` (N/m per m of seam) on translations, ``k_rot`` (N·m/rad per m) on rotations."""

    nodes: tuple[int, ...] = ids_field()
    pids: tuple[int, ...] = ids_field()
    label: str = label_field()
    k_trans: float | None = value_field()
    k_rot: float | None = value_field()

    kind = "seam"
    value_names = ("k_trans", "k_rot")
    scales = "k"
    scan = tuple((t, t) for t in SCAN_SEAM)
    prior_sd = (3.0, 3.0)

    def __check_init__(self):
        self._check_nodes()
        if len(self.pids) != 2:
            raise ValueError(f"seam at grids {list(self.nodes)}: name the shell group and the beam group, "
                             "e.g. seam:node=1001-1005;pids=101,201 (the beams are released)")

    @classmethod
    def candidates(cls, model: Model) -> list[Seam]:
        """Every line of grids a beam group shares with a shell group, in runs of
        :data:`SEAM_GRIDS` along the beams."""
        return [cls(pids=pids, nodes=line[:1]).run(line, k, SEAM_GRIDS)
                for pids, lines in _seam_lines(model).items() for line in lines
                for k in range(0, len(line), SEAM_GRIDS)]

    def line(self, model: Model, lines: dict | None = None) -> tuple[int, ...]:
        """The whole line this seam lies on (grids in order along it); ``lines``: the
        model's seam lines (:func:`_seam_lines`), if at hand."""
        for line in (_seam_lines(model) if lines is None else lines).get(tuple(self.pids), []):
            if self.nodes[0] in line:
                return line
        raise ValueError(f"seam at grids {list(self.nodes)}: no line of pid {self.pids[1]} on pid {self.pids[0]} "
                         "runs through them")

    def run(self, line: tuple[int, ...], start: int, n: int) -> Seam:
        """This seam (its values) on ``n`` grids of ``line`` from index ``start``."""
        nodes = tuple(line[start:start + n])
        return replace(self, nodes=nodes,
                       label=f"grids {nodes[0]}–{nodes[-1]} of pid {self.pids[1]} on pid {self.pids[0]}")

    def longer(self, line: tuple[int, ...]) -> list[Seam]:
        """Runs of each length of :data:`SEAM_SCREEN` shorter than ``line`` that overlap
        this one or lie next to it, half a length apart (clipped to the line): the
        stretches about it that screening offers."""
        start, n = line.index(self.nodes[0]), len(self.nodes)
        runs = [(int(np.clip(s, 0, len(line) - m)), m) for m in SEAM_SCREEN if m < len(line)
                for s in range(start - m, start + n + 1, max(1, m // 2))]
        return [self.run(line, s, m) for s, m in dict.fromkeys(runs)]

    def neighbours(self, line: tuple[int, ...], coarse: bool = False) -> list[Seam]:
        """The seams next to this one on its ``line``: one grid along it either way and
        each end one grid out or in; ``coarse``: half its length along either way, each
        end a quarter of its length out or in, both ends so (about the same centre), and
        the next length of :data:`SEAM_LENGTHS` up and down about the same centre. (On the
        33k barrel a run of 21 grids centred on the 31 loose ones fitted better than
        every run one grid longer or shorter at either end, and worse than the 31.)"""
        start, n = line.index(self.nodes[0]), len(self.nodes)
        along, d = (max(1, n // 2), max(1, n // 4)) if coarse else (1, 1)
        runs = [(start - along, n), (start + along, n),  # along the line
                (start - d, n + d), (start, n + d), (start + d, n - d), (start, n - d)]  # an end out or in
        if coarse:  # both ends out or in; the ladder, about the same centre
            runs += [(start - d, n + 2 * d), (start + d, n - 2 * d)]
            step = int(np.argmin(np.abs(np.asarray(SEAM_LENGTHS) - n)))
            runs += [(start + n // 2 - SEAM_LENGTHS[i] // 2, SEAM_LENGTHS[i]) for i in (step - 1, step + 1)
                     if 0 <= i < len(SEAM_LENGTHS)]
        runs = [(int(np.clip(s, 0, len(line) - m)), m) for s, m in runs if 2 <= m <= len(line)]
        return [self.run(line, s, m) for s, m in dict.fromkeys(runs) if (s, m) != (start, n)]

    def springs(self, before: Model, after: Model) -> dict[int, tuple[tuple[int, ...], tuple[int, ...]]]:
        """The springs :meth:`add_to` added (``before`` → ``after``) at each grid:
        (on translations, on rotations)."""
        trans, rot = self._halves(before, after)
        b = after.bushes
        at = {int(e): {int(after.node_ids[r]) for r in row} for e, row in zip(b.ids, np.asarray(b.nodes))}
        return {g: (tuple(e for e in trans if g in at[e]), tuple(e for e in rot if g in at[e])) for g in self.nodes}

    def shares(self, model: Model) -> np.ndarray:
        """Each grid's length of seam (m): half the distance to each neighbour on the line."""
        b, xyz = model.beams, np.asarray(model.xyz)
        rows = set(model.node_index(list(self.nodes)).tolist())
        shell = {int(r) for blk in (model.quads, model.trias) for p, row in zip(blk.pids, blk.nodes)
                 if int(p) == self.pids[0] for r in row if r >= 0}
        ends = np.asarray(b.nodes)[np.asarray(b.pids) == self.pids[1]][:, :2]
        out = []
        for r in model.node_index(list(self.nodes)):
            near = [j if i == r else i for i, j in ends if r in (i, j) and {i, j} <= shell | rows]
            out.append(0.5 * sum(np.linalg.norm(xyz[n] - xyz[r]) for n in near))
        return np.asarray(out)

    def add_to(self, model: Model) -> Model:
        return _release(model, self.nodes, self.pids, self._need("k_trans"), self._need("k_rot"), self.shares(model))

    def at_reference(self, model: Model, f_test_hz) -> Seam:
        """A joint's reference (:func:`~updating._topology.joint_reference` of the beams)
        per unit of the mean share: slightly softer than rigid."""
        side = [e for n in self.nodes for e, p in elements_at(model, n).items() if p == self.pids[1]]
        share = float(np.mean(self.shares(model)))
        if share <= 0:
            raise ValueError(f"seam at grids {list(self.nodes)}: no beam of pid {self.pids[1]} runs along "
                             f"them on the shells of pid {self.pids[0]}")
        return replace(self, **{k: v / share for k, v in joint_reference(model, self.nodes, side).items()})

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        return _rigid_note(self, reference)

    def advice(self, sd) -> str:
        s = np.broadcast_to(np.asarray(sd, float), (2,))
        return (f"make the seam at {self.where()} flexible: k_rot = {spread(self.k_rot, s[1], 'N·m/rad per m')}, "
                f"k_trans = {spread(self.k_trans, s[0], 'N/m per m')}")


def _seam_lines(model: Model) -> dict[tuple[int, int], list[tuple[int, ...]]]:
    """The lines of grids each beam group shares with each shell group, by (shell pid,
    beam pid): each line's grids in order along it (:func:`_chains`)."""
    shells = [(model.quads.pids, model.quads.nodes), (model.trias.pids, model.trias.nodes)]
    shell_rows = {int(p): set() for pids, _ in shells for p in pids}
    for pids, nodes in shells:
        for p, row in zip(pids, nodes):
            shell_rows[int(p)].update(int(r) for r in row if r >= 0)
    b, out = model.beams, {}
    for bp in sorted({int(p) for p in b.pids}):
        ends = np.asarray(b.nodes)[np.asarray(b.pids) == bp][:, :2]
        for sp, rows in sorted(shell_rows.items()):
            edges = [(int(i), int(j)) for i, j in ends if int(i) in rows and int(j) in rows]
            lines = [tuple(int(model.node_ids[r]) for r in line) for line in _chains(edges)]
            if lines:
                out[sp, bp] = lines
    return out


def _chains(edges: list[tuple[int, int]]) -> list[list[int]]:
    """The connected lines of ``edges`` (grid rows), each in order along the line (a ring
    from its lowest row)."""
    nbr: dict[int, list[int]] = {}
    for i, j in edges:
        nbr.setdefault(i, []).append(j)
        nbr.setdefault(j, []).append(i)
    seen, out = set(), []
    for start in sorted(nbr, key=lambda r: (len(nbr[r]) != 1, r)):  # line ends first
        if start in seen:
            continue
        line, prev, cur = [], None, start
        while cur is not None and cur not in seen:
            seen.add(cur)
            line.append(cur)
            nxt = [n for n in nbr[cur] if n != prev and n not in seen]
            prev, cur = cur, (nxt[0] if nxt else None)
        out.append(line)
    return out


class BoundarySpring(AbstractAddedElements):
    """Springs to ground at a grid: ``k`` (N/m) on the translations of an unconstrained
    grid, or ``k_trans`` (N/m) / ``k_rot`` (N·m/rad) on the released components of an SPC."""

    nodes: tuple[int, ...] = ids_field()
    label: str = label_field()
    k: float | None = value_field()
    k_trans: float | None = value_field()
    k_rot: float | None = value_field()

    kind = "boundary_spring"
    value_names = ("k", "k_trans", "k_rot")
    scales = "k"

    @property
    def scan(self) -> tuple:
        """On a free grid one factor; a released support's two factors scanned together."""
        return tuple((t, t) for t in SCAN) if self.split else SCAN

    @property
    def prior_sd(self) -> tuple[float, ...]:
        return (3.0, 3.0) if self.split else (3.0,)

    def __check_init__(self):
        self._check_nodes()

    @classmethod
    def candidates(cls, model: Model) -> list[BoundarySpring]:
        """Flexible supports: every SPC'd grid that carries structural elements."""
        return [cls(nodes=(int(n),), label=f"support at grid {int(n)}") for n in model.node_ids
                if constrained_components(model, int(n)) and elements_at(model, int(n))]

    def add_to(self, model: Model) -> Model:
        for node in self.nodes:
            fixed = constrained_components(model, node)
            if fixed:
                model = edit.release(model, node)
                model = edit.add_ground_springs(model, node, [
                    self._need("k_trans") if c <= 3 else self._need("k_rot") for c in fixed], fixed)[0]
            else:
                model = edit.add_ground_springs(model, node, self._need("k"), (1, 2, 3))[0]
        return model

    def at_reference(self, model: Model, f_test_hz) -> BoundarySpring:
        """On free grids a spring that alone would carry the structure at f₁/10; a released
        support slightly flexible (:func:`~updating._topology.joint_reference`)."""
        if not any(constrained_components(model, n) for n in self.nodes):
            k = total_mass(model) * (2 * np.pi * float(np.min(np.asarray(f_test_hz, float))) / 10) ** 2
            return replace(self, k=k, k_trans=None, k_rot=None)
        side = [e for n in self.nodes for e in elements_at(model, n)]
        return replace(self, k=None, **joint_reference(model, self.nodes, side))

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        return _rigid_note(self, reference)

    def advice(self, sd) -> str:
        s = np.broadcast_to(np.asarray(sd, float), (2,)) if self.split else np.full(2, np.atleast_1d(sd)[0])
        grids = ", ".join(map(str, self.nodes))
        if not self.split:
            return f"add springs to ground of {spread(self.k, s[0], 'N/m')} on the translations of grid {grids}"
        return (f"make the support at grid {grids} flexible: k_trans = {spread(self.k_trans, s[0], 'N/m')}, "
                f"k_rot = {spread(self.k_rot, s[1], 'N·m/rad')}")


class AbstractMass(AbstractAddedElements):
    """Added mass: one value ``m`` (kg), from 1 % of the total mass."""

    value_names = ("m",)
    scales = "m"
    scan = SCAN
    prior_sd = (1.5,)  # about the reference 1 % of the total mass: 0.05 % to 20 % at 2σ

    def __check_init__(self):
        self._check_nodes()

    def at_reference(self, model: Model, f_test_hz) -> AbstractMass:
        """1 % of the total mass."""
        return replace(self, m=0.01 * total_mass(model))

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        if self.m > 0.2 * total_mass:
            return [f"added mass {self.m:.3g} kg is {100 * self.m / total_mass:.0f} % of the total"]
        return []


class AddedMass(AbstractMass):
    """A point mass at a grid (CONM2). Values: ``m`` (kg)."""

    nodes: tuple[int, ...] = ids_field()
    label: str = label_field()
    m: float | None = value_field()

    kind = "added_mass"

    def add_to(self, model: Model) -> Model:
        for node in self.nodes:
            model = edit.add_mass(model, node, self._need("m"))[0]
        return model

    def advice(self, sd) -> str:
        return f"add {spread(self.m, float(np.atleast_1d(sd)[0]), 'kg')} at grid {', '.join(map(str, self.nodes))}"


class Payload(AbstractMass):
    """A payload hung on an interpolation element, as seats, boxes and equipment are
    modelled: a point mass (CONM2) carried by an RBE3 on the translations of grids
    ``nodes`` (equal weights), its CG ``height`` (m) from their centroid along the
    footprint's normal n (the unit normal whose largest component is positive), with the
    inertia of a uniform box standing on the footprint: a plate filling it (the grids'
    second moment about the centroid ÷ 3, exact for a rectangle) plus m (2h)²/12 about the
    in-plane axes. It moves with their mean motion — not with one grid (:class:`AddedMass`)
    nor with the shells' bending between them (:class:`DistributedMass`). Offered on each
    shell of the localised region, its grids the footprint. Values: ``m`` (kg), ``height``
    (m); free parameters: θ₀ a log-factor on m, θ₁ a shift of the height in units of the
    footprint's size ``size`` (√ of twice the grids' second moment, the side of a square
    footprint), from 0 (a flat payload); :meth:`parameters` (an update with the effect
    added) has θ₀ alone, the height held where the diagnosis put it. (Without the plate's
    inertia, 20 kg on a 0.3 m floor shell of the 2,500-DoF barrel left modes 4.8 % off a
    payload that has it; with its CG on the floor, a 0.1 m box there was fitted as 6.6 kg,
    held-out 1.4 %.)"""

    nodes: tuple[int, ...] = ids_field()
    label: str = label_field()
    m: float | None = value_field()
    height: float | None = value_field()
    size: float = eqx.field(static=True, default=0.0)

    kind = "payload"
    value_names = ("m", "height")
    # mass × CG height: the valley is narrow (20 kg, 5 cm up on the 2,500-DoF barrel: from 0.6 to 0.005 within
    # e^0.2 in m) and far from a flat payload's (θ₁ = 0 leads a fit to the wrong mass)
    scan = tuple((t, h) for h in (0.0, 0.3, -0.3, 0.7, -0.7) for t in (-3.0, -1.5, 0.0, 1.0, 2.0, 3.0))
    prior_sd = (1.5, 1.0)  # m as an added mass; the CG within two footprint sizes at 2σ

    def __check_init__(self):
        self._check_nodes()
        if len(self.nodes) < 3:
            raise ValueError(f"effect payload: give at least 3 grids not on one line (the RBE3's footprint), "
                             f"got {list(self.nodes)}")

    def footprint(self, model: Model) -> tuple[np.ndarray, np.ndarray, float]:
        """The grids' centroid (m), the footprint's normal n and its size (m)."""
        r = np.asarray(model.xyz)[model.node_index(self.nodes)]
        centre = r.mean(axis=0)
        n = np.linalg.svd(r - centre)[2][-1]
        n = n if n[np.argmax(np.abs(n))] > 0 else -n
        return centre, n, float(np.sqrt(2 * np.sum((r - centre) ** 2) / len(r)))

    def _box(self, model: Model):
        """(plate inertia per kg, in-plane projector (I − nnᵀ), n)."""
        centre, n, _ = self.footprint(model)
        r = np.asarray(model.xyz)[model.node_index(self.nodes)] - centre
        return (np.sum(r * r) * np.eye(3) - r.T @ r) / (3 * len(r)), np.eye(3) - np.outer(n, n), n

    def add_to(self, model: Model) -> Model:
        plate, inplane, n = self._box(model)
        m, h = self._need("m"), float(self.height or 0.0)
        model, ref = edit.add_rbe3(model, self.nodes)
        return edit.add_mass(model, ref, m, inertia=m * (plate + h * h / 3 * inplane), offset=h * n)[0]

    def at_reference(self, model: Model, f_test_hz) -> Payload:
        """1 % of the total mass, at its height (default 0: on the footprint)."""
        return replace(self, m=0.01 * total_mass(model), height=float(self.height or 0.0),
                       size=self.footprint(model)[2])

    def moves(self, model: Model, eid: int) -> dict:
        """``height`` masks of :func:`~updating._extension.extension` for this payload's
        CONM2 ``eid``: θ₁ shifts its CG by θ₁·size along n, its box inertia follows."""
        _, inplane, n = self._box(model)
        m, h, u = self._need("m"), float(self.height or 0.0), self.footprint(model)[2]
        return {eid: (u * n, m * 2 * h * u / 3 * inplane, m * u * u / 3 * inplane)}

    def extension(self, model: Model, extended: Model) -> Extension:
        (eid,) = [e for e in self._new(model, extended) if e in np.asarray(extended.masses.ids)]
        return extension(extended, m_log=self._new(model, extended), height=self.moves(extended, eid))

    def dormant_extension(self, aug: Model, ids) -> Extension:
        (eid,) = [e for e in ids if e in np.asarray(aug.masses.ids)]
        return extension(aug, m_add=ids, height=self.moves(aug, eid))

    def updated(self, theta) -> Payload:
        """θ₀ on m; θ₁ (when given: the diagnosis' fit) shifts the height by θ₁·size."""
        t = np.atleast_1d(np.asarray(theta, float))
        if len(t) > 1 and not self.size > 0:
            raise ValueError(f"payload at {self.where()}: its footprint's size is not set (at_reference sets it)")
        h = float(self.height or 0.0) + (float(t[1]) * self.size if len(t) > 1 else 0.0)
        return replace(self, m=float(self._need("m") * np.exp(t[0])), height=h)

    def where(self) -> str:
        return self.label or f"RBE3 over grids {', '.join(map(str, self.nodes))}"

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        notes = super().plausibility(total_mass, reference)
        if self.size and abs(self.height or 0.0) > 2 * self.size:
            notes.append(f"payload CG {self.height:.3g} m from its footprint, more than twice its size "
                         f"({self.size:.3g} m)")
        return notes

    def advice(self, sd) -> str:
        sd = np.atleast_1d(np.asarray(sd, float))
        h = float(self.height or 0.0)
        cg = "its CG on the footprint: a flat plate"
        if h:
            pm = f" (±{sd[1] * self.size:.2g} m)" if len(sd) > 1 else ""
            cg = f"its CG {h:.3g} m{pm} along the footprint's normal: a box {2 * abs(h):.2g} m high"
        return (f"add a payload of {spread(self.m, float(sd[0]), 'kg')} on an RBE3 over grids "
                f"{', '.join(map(str, self.nodes))} (a CONM2 on a grid at their centroid, {cg})")


# ---------------------------------------------------------------------------------------
# by kind name: the JSON, the command line


_TYPES: dict[str, type[AbstractEffect]] = {t.kind: t for t in (
    GroupStiffness, GroupMass, Joint, Seam, AddedMass, Payload, BoundarySpring, FrequencyDependentStiffness, *PATCH_KINDS,
    LocalDamping)}
KINDS = tuple(_TYPES)


def Effect(kind: str, pids=(), eids=(), nodes=(), values: dict | None = None, label: str = "",
           **location) -> AbstractEffect:
    """The effect of a kind by its JSON/CLI name, e.g. ``Effect("joint", nodes=(6001,),
    values={"k_trans": 1e8, "k_rot": 4e4})``: the convenient constructor of the typed
    classes (:class:`Joint` here). ``values``: SI, by the class' value names;
    ``location``: a patch's ``radius`` (m) and ``part``, a payload's ``height`` (m)."""
    if kind not in _TYPES:
        raise ValueError(f"effect kind {kind!r} is not one of {KINDS}")
    cls = _TYPES[kind]
    names = {f.name for f in fields(cls)}
    where = {k: v for k, v in (("pids", pids), ("eids", eids), ("nodes", nodes)) if len(v)} | location
    wrong = sorted(set(where) - names) + sorted(set(values or {}) - set(cls.value_names))
    if wrong:
        raise ValueError(f"effect {kind}: {wrong} not among its locations and values "
                         f"{sorted(names & {'pids', 'eids', 'nodes', 'radius', 'part'})}, {list(cls.value_names)}")
    return cls(**where, **(values or {}), label=label)


def parse_effect(spec: str) -> AbstractEffect:
    """``KIND:TARGET`` as on the command line, e.g. ``joint:node=6001``,
    ``joint:node=3007;pids=21,22``, ``stiffness:pid=41``, ``mass:eids=201-205``,
    ``added_mass:node=2015``, ``payload:nodes=2015,2016,2026,2025;height=0.05`` (its CG, m),
    ``boundary_spring:node=1``,
    ``frequency_dependent_stiffness:pid=41``, ``delamination:node=1234;radius=0.03``,
    ``patch_stiffness:node=1234;radius=0.05;part=bending`` (radius in m),
    ``seam:node=1001-1005;pids=101,201``, ``damping:eids=6-8`` (a loss factor, fitted by
    :func:`updating.diagnose_damping`)."""
    kind, _, target = spec.partition(":")
    if kind not in KINDS or not target:
        raise ValueError(f"effect {spec!r}: write KIND:TARGET with KIND one of {KINDS}, "
                         "TARGET like pid=41, node=1029, eids=201-205 (';' between several)")
    where: dict[str, tuple[int, ...]] = {"pids": (), "eids": (), "nodes": ()}
    location: dict = {}
    for part in target.split(";"):
        key, _, value = part.partition("=")
        key = {"pid": "pids", "eid": "eids", "node": "nodes"}.get(key.strip(), key.strip())
        if key == "part" and value:
            location["part"] = value.strip()
            continue
        if key in ("radius", "height") and value:
            try:
                location[key] = float(value)
            except ValueError:
                raise ValueError(f"effect {spec!r}: {key} {value!r} is not a number of metres") from None
            continue
        if key not in where or not value:
            raise ValueError(f"effect {spec!r}: unknown target {part!r} "
                             "(pid(s)=, eid(s)=, node(s)=, radius=, part=, height=)")
        ids: list[int] = []
        try:
            for item in value.split(","):
                lo, _, hi = item.partition("-")
                ids += list(range(int(lo), int(hi or lo) + 1))
        except ValueError:
            raise ValueError(f"effect {spec!r}: {part!r} is not a list of integers") from None
        where[key] = tuple(ids)
    return Effect(kind, **where, **location)


def at_reference(model: Model, effect: AbstractEffect, f_test_hz) -> AbstractEffect:
    """``effect.at_reference(model, f_test_hz)``: the effect at its starting values."""
    return effect.at_reference(model, f_test_hz)


def effect_parameters(effect: AbstractEffect, before: Model, after: Model) -> tuple[Parameter, ...]:
    """``effect.parameters(before, after)``: its updating parameters."""
    return effect.parameters(before, after)
