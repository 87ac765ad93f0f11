"""Effects that add elements: flexible joints, springs to ground, point masses and payloads
(the seams: :mod:`updating.diagnosis._seam`); the kinds by name: :mod:`updating.diagnosis._effects`."""

from __future__ import annotations

import abc
from dataclasses import replace

import equinox as eqx
import numpy as np

import jaxfem
from jaxfem import Model

from .. import Extension, Parameter, extension
from ._abstract_effect import (
    AbstractEffect,
    ids_field,
    label_field,
    spread,
    value_field,
)
from ._scans import SCAN
from ._topology import (
    constrained_components,
    elements_at,
    joint_reference,
    masters,
    structural_pids,
    total_mass,
)

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
        (several effects added at once refresh once: :func:`jaxfem.refresh`)."""

    def apply(self, model: Model) -> Model:
        return jaxfem.refresh(self.add_to(model))

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
            model, new = jaxfem.add_grid(model, model.xyz[model.node_index([node])[0]])
            side = model.element_ids(pids=pids[1:])
            model = jaxfem.reconnect(model, side.tolist(), node, new)
            a, b = node, new
        else:  # an RBE2-dependent grid becomes independent, held by springs
            model = jaxfem.release(model, node)
            a, b = master, node
        # translations and rotations: two bushes, two factors; the springs at the released grid
        model = jaxfem.add_bush(model, a, b, [k_trans * share] * 3 + [0.0] * 3, s=1.0)[0]
        model = jaxfem.add_bush(model, a, b, [0.0] * 3 + [k_rot * share] * 3, s=1.0)[0]
    return model


def _check_shared(model: Model, node: int, pids, dep: dict) -> None:
    """A grid released as shared by groups must have an element of ``pids[1:]`` at it:
    else the springs would hold a new grid nothing is attached to, a silent no-op
    (``joint:node=1013`` at the RBE2 master 1013 instead of its dependent grids)."""
    at = set(elements_at(model, node).values())
    if at & set(pids[1:]):
        return
    dependents = sorted(g for g, m in dep.items() if m == node)
    hint = (f"grid {node} is the master of an RBE2: give its dependent grids "
            f"({', '.join(map(str, dependents))}) as the joint's nodes" if dependents
            else f"give two pids meeting there (e.g. joint:node={node};pids=first,second: the second is released), of "
                 f"{', '.join(map(str, sorted(at))) or 'none'}")
    raise ValueError(f"a joint at grid {node} releases nothing: it is not an RBE2-dependent grid and no element "
                     f"of pids {list(pids[1:]) or '(none given)'} is attached to it; {hint}")


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

    def _released_grids_checked(self, model: Model) -> dict:
        """The model's RBE2 dependents → masters, each grid of the joint checked to release
        something (:func:`_check_shared`)."""
        dep = masters(model)
        for node in self.nodes:
            if node not in dep:
                _check_shared(model, node, self.pids, dep)
        return dep

    def add_to(self, model: Model) -> Model:
        self._released_grids_checked(model)
        return _release(model, self.nodes, self.pids, self._need("k_trans"), self._need("k_rot"))

    def at_reference(self, model: Model, f_test_hz) -> Joint:
        """Slightly flexible (:func:`~updating.diagnosis._topology.joint_reference` of the released side)."""
        dep = self._released_grids_checked(model)
        side = [e for n in self.nodes for e, p in elements_at(model, n).items() if n in dep or p in self.pids[1:]]
        return replace(self, **joint_reference(model, self.nodes, side))

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        return _rigid_note(self, reference)

    def advice(self, sd) -> str:
        s = np.broadcast_to(np.asarray(sd, float), (2,))
        return (f"make the {self.where()} a flexible joint: k_rot = {spread(self.k_rot, s[1], 'N·m/rad')}, "
                f"k_trans = {spread(self.k_trans, s[0], 'N/m')}")



class BoundarySpring(AbstractAddedElements):
    """Springs to ground at a grid: ``k`` (N/m) on the translations ``components`` (1–3,
    in the grid's displacement axes; default all three) of an unconstrained grid, or
    ``k_trans`` (N/m) / ``k_rot`` (N·m/rad) on the released components of an SPC."""

    nodes: tuple[int, ...] = ids_field()
    label: str = label_field()
    components: tuple[int, ...] = eqx.field(static=True, default=(1, 2, 3), converter=lambda c: tuple(int(i) for i in c))
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
        if not self.components or not set(self.components) <= {1, 2, 3}:
            raise ValueError(f"effect {self.kind}: components {self.components} must be translations among 1, 2, 3")

    @classmethod
    def candidates(cls, model: Model) -> list[BoundarySpring]:
        """Flexible supports: every SPC'd grid that carries structural elements."""
        return [cls(nodes=(int(n),), label=f"support at grid {int(n)}") for n in model.node_ids
                if constrained_components(model, int(n)) and elements_at(model, int(n))]

    def add_to(self, model: Model) -> Model:
        for node in self.nodes:
            fixed = constrained_components(model, node)
            if fixed:
                model = jaxfem.release(model, node)
                model = jaxfem.add_ground_springs(model, node, [
                    self._need("k_trans") if c <= 3 else self._need("k_rot") for c in fixed], fixed)[0]
            else:
                model = jaxfem.add_ground_springs(model, node, self._need("k"), self.components)[0]
        return model

    def at_reference(self, model: Model, f_test_hz) -> BoundarySpring:
        """On free grids a spring that alone would carry the structure at f₁/10; a released
        support slightly flexible (:func:`~updating.diagnosis._topology.joint_reference`)."""
        if not any(constrained_components(model, n) for n in self.nodes):
            k = total_mass(model) * (2 * np.pi * float(np.min(np.asarray(f_test_hz, float))) / 10) ** 2
            return replace(self, k=k, k_trans=None, k_rot=None)
        side = [e for n in self.nodes for e in elements_at(model, n)]
        return replace(self, k=None, **joint_reference(model, self.nodes, side))

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        return _rigid_note(self, reference)

    def to_json(self) -> dict:
        return {**super().to_json(), "components": list(self.components)}

    def advice(self, sd) -> str:
        s = np.broadcast_to(np.asarray(sd, float), (2,)) if self.split else np.full(2, np.atleast_1d(sd)[0])
        grids = ", ".join(map(str, self.nodes))
        if not self.split and self.components != (1, 2, 3):
            return (f"add a spring to ground of {spread(self.k, s[0], 'N/m')} on translation "
                    f"{', '.join('xyz'[c - 1] for c in self.components)} of grid {grids} only")
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
            model = jaxfem.add_mass(model, node, self._need("m"))[0]
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
        model, ref = jaxfem.add_rbe3(model, self.nodes)
        return jaxfem.add_mass(model, ref, m, inertia=m * (plate + h * h / 3 * inplane), offset=h * n)[0]

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
