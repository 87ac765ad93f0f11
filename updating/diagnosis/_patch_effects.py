"""Effects on a patch of shells: a delamination, a local loss of stiffness, distributed mass,
a local loss factor; the kinds by name: :mod:`updating.diagnosis._effects`."""

from __future__ import annotations

from dataclasses import replace
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfem
from jaxfem import Model

from .. import PARTS, Extension, Parameter, extension
from ._abstract_effect import (
    AbstractEffect,
    ids_field,
    label_field,
    spread,
    value_field,
)
from ._scans import SCAN
from ._topology import patch_elements, shell_area, total_mass

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
