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

The kinds live in :mod:`._group_effects`, :mod:`._patch_effects`, :mod:`._element_effects`
and :mod:`._seam`; this module names them (and re-exports them, with the scan ladders).
"""

from __future__ import annotations

from dataclasses import fields

from jaxfem import Model

from .. import Parameter
from ._abstract_effect import AbstractEffect
from ._element_effects import AbstractAddedElements as AbstractAddedElements
from ._element_effects import AbstractMass as AbstractMass
from ._element_effects import AddedMass, BoundarySpring, Joint, Payload
from ._group_effects import AbstractGroupEffect as AbstractGroupEffect
from ._group_effects import FrequencyDependentStiffness, GroupMass, GroupStiffness
from ._patch_effects import ETA_SD as ETA_SD
from ._patch_effects import PATCH_KINDS, LocalDamping
from ._patch_effects import RADII as RADII
from ._patch_effects import AbstractPatch as AbstractPatch
from ._patch_effects import AbstractPatchPart as AbstractPatchPart
from ._patch_effects import Delamination as Delamination
from ._patch_effects import DistributedMass as DistributedMass
from ._patch_effects import PatchStiffness as PatchStiffness
from ._scans import SCAN as SCAN
from ._scans import SCAN_LAW as SCAN_LAW
from ._scans import SCAN_SEAM as SCAN_SEAM
from ._seam import SEAM_GRIDS as SEAM_GRIDS
from ._seam import SEAM_LENGTHS as SEAM_LENGTHS
from ._seam import SEAM_SCREEN as SEAM_SCREEN
from ._seam import Seam
from ._seam import _chains as _chains
from ._seam import _seam_lines as _seam_lines

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
                         f"{sorted(names & {'pids', 'eids', 'nodes', 'radius', 'part', 'height', 'components'})}, {list(cls.value_names)}")
    return cls(**where, **(values or {}), label=label)


def parse_effect(spec: str) -> AbstractEffect:
    """``KIND:TARGET`` as on the command line, e.g. ``joint:node=6001``,
    ``joint:node=3007;pids=21,22``, ``stiffness:pid=41``, ``mass:eids=201-205``,
    ``added_mass:node=2015``, ``payload:nodes=2015,2016,2026,2025;height=0.05`` (its CG, m),
    ``boundary_spring:node=1``, ``boundary_spring:node=1001;components=3`` (z only),
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
        if key == "components" and value:
            try:
                location["components"] = tuple(int(c) for c in value.split(","))
            except ValueError:
                raise ValueError(f"effect {spec!r}: components {value!r} are not integers 1–3") from None
            continue
        if key in ("radius", "height") and value:
            try:
                location[key] = float(value)
            except ValueError:
                raise ValueError(f"effect {spec!r}: {key} {value!r} is not a number of metres") from None
            continue
        if key not in where or not value:
            raise ValueError(f"effect {spec!r}: unknown target {part!r} "
                             "(pid(s)=, eid(s)=, node(s)=, radius=, part=, height=, components=)")
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
