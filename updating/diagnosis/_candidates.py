"""Candidate effects of a diagnosis: generated from the model by each kind
(:mod:`updating.diagnosis._effects`), screened by the linearised residual reduction ρ at the
baseline (Friswell & Mottershead 1995, §7; :func:`~updating.diagnosis._localisation.reduction`),
shortlisted for a full fit.

All candidates share one model, so that their fits share one compiled solver: the
nominal one plus dormant elements (scale 0) at every grid of the localised region (added
masses, springs to ground), and its rigid connections (a seam along its whole line, so
that the runs of the line are masks on one model) and supports in that region
released and held by springs :data:`STIFF` times stiffer than their reference — as
rigid as the original to well below measurement noise (GARTEUR, all ten joints:
frequencies within 1e-4) — which the fit then softens.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import jaxfem
from jaxfem import STRUCTURAL_BLOCKS, Model

from .. import Extension, Parameter, extension
from ._effects import (
    RADII,
    AbstractEffect,
    AbstractPatch,
    AddedMass,
    BoundarySpring,
    Delamination,
    DistributedMass,
    FrequencyDependentStiffness,
    GroupMass,
    GroupStiffness,
    Joint,
    PatchStiffness,
    Payload,
    Seam,
    _seam_lines,
)
from ._fit import Fit, HeldOut
from ._screen import Screen, param_eids
from ._topology import (
    constrained_components,
    element_grids,
    elements_at,
    masters,
    shell_size,
    stiffness_pids,
    structural_pids,
    total_mass,
)


@dataclass(eq=False)
class Candidate:
    """An effect to try: its ``reference`` (θ = 0), its free parameters as masks for the
    shared-structure fit (``ext``, on its own ``model`` if it changes the structure), the θ grid
    ``scan`` tried before fitting, its screening ρ and start ``theta0``; then its fit on all
    test modes (:class:`~._fit.Fit`) and, for the most probable, its cross-validation
    (:class:`~._fit.HeldOut`)."""

    reference: AbstractEffect
    ext: Extension | None  # None until shortlisted (a patch: :func:`patch_candidates`)
    scan: tuple | None = None
    screen: float = float("nan")
    theta0: np.ndarray | None = None
    prior_mean: float | np.ndarray = 0.0
    nested: float = float("inf")  # a law: linearised ln B of its coefficient over its group's factor alone
    released: Released | None = None  # a released joint, seam or support: its springs in the shared model
    fit: Fit | None = None
    heldout: HeldOut | None = None

    def __post_init__(self):
        if self.theta0 is None:
            self.theta0 = np.zeros(len(self.reference.prior_sd))

    @property
    def family(self) -> str:
        """``visco`` (a law) or ``mask``: the candidates of one family share a compiled fit."""
        return "visco" if self.ext is not None and self.ext.visco else "mask"

    def prior(self) -> tuple[np.ndarray, np.ndarray]:
        """Mean and σ of the normal prior on each free θ (the kind's ``prior_sd`` about
        its reference; a stiffened joint's reference lies ``prior_mean`` below its θ = 0)."""
        sd = np.asarray(self.reference.prior_sd, float)
        return np.zeros(len(sd)) + self.prior_mean, sd


# ---------------------------------------------------------------------------------------
# candidates by kind


NEXT_GRID = 0.9  # a structure's score from a grid one element away, as a share of that grid's: its own grids first
STIFF = 100.0  # a released rigid connection or support is held this many times stiffer than its reference


def localised_grids(model: Model, screen: Screen, node_scores: dict[int, float], n: int,
                    fraction: float) -> list[int]:
    """The localised region: the best-scoring grids of the property groups (or halves)
    whose stiffness or mass screens at least ``fraction`` of the best (at most three),
    ``n``/2 of them, then the grids scoring at least ``fraction`` of the best, then the
    groups' other grids; those that carry structural elements and no SPC, at most ``n``.
    (Grid scores alone favour grids that move much, such as tips; a large group alone
    would crowd out a high-scoring grid elsewhere: a missing mass on a floor when the
    skin's stiffness screens best.)"""
    groups = []
    for kind in (GroupStiffness, GroupMass):
        for effect in kind.candidates(model):
            ids = effect.elements(model)
            groups.append((float(screen.rho(screen.column(effect.scales, ids), joint=True)), ids))
    top_group = max((g[0] for g in groups), default=0.0)
    in_groups = sorted({g for rho, ids in sorted(groups, key=lambda g: -g[0])[:3] if rho >= fraction * top_group
                        for g in element_grids(model, ids)}, key=lambda k: (-node_scores.get(k, 0.0), k))
    top = max(node_scores.values(), default=0.0)
    high = sorted((k for k in node_scores if node_scores[k] >= fraction * top), key=lambda k: -node_scores[k])
    grids = in_groups[: n // 2] + high + in_groups[n // 2:]
    region = []
    for k in dict.fromkeys(grids):
        if len(region) == n:
            break
        if elements_at(model, k) and not constrained_components(model, k):
            region.append(k)
    return region


def region_structures(model: Model, region: list[int], node_score: dict, kinds, n: int) -> list[AbstractEffect]:
    """Joints (RBE2 groups, grids shared by two groups), seams and supports at or next to
    the localised ``region`` (one element away: the expanded shapes of sparse sensors put
    a connection's error on the grids about it; such a grid's score counts
    :data:`NEXT_GRID` of its own), or scoring high there, at most ``n``:
    the best of each kind and group (a seam's beams, a joint's released group) first, then
    the rest, best first (a frame's seam and a stringer's crossing it score alike; on the
    33k barrel the stringers' seams through a hot grid took every place). :func:`augment`
    releases them all at once, so a joint or seam that releases a group at a grid where
    a better one does (a seam: along its whole line; :func:`_moved`) is left out, and so
    is a joint between a shell and a beam group at a grid of their seam, which a seam
    walks to (on the 33k barrel such joints took the places of the loose frame's seam)."""
    effects = [e for kind in (Joint, Seam, BoundarySpring) if kind.kind in kinds for e in kind.candidates(model)]
    on_seams = {(g, frozenset(s.pids)) for s in effects if isinstance(s, Seam) for g in s.nodes}
    effects = [e for e in effects if not (isinstance(e, Joint) and len(e.nodes) == 1
                                          and (e.nodes[0], frozenset(e.pids)) in on_seams)]  # a seam of one grid
    dep, lines = masters(model), _seam_lines(model)
    near = _dilated(model, node_score, NEXT_GRID)
    inside = _dilated(model, dict.fromkeys(region, 1.0), NEXT_GRID)  # 1 at a region grid, 0.9 one element away
    at = lambda k: dep.get(k, k)  # noqa: E731  an RBE2-dependent grid scores as its master
    best = lambda values, e: max(max(values.get(k, 0.0), values.get(at(k), 0.0)) for k in e.nodes)  # noqa: E731
    score = {e: (best(inside, e) > 0, best(near, e), best(inside, e)) for e in effects}
    ranked = sorted((e for e in effects if score[e][0] or score[e][1] > 0),
                    key=lambda e: (not score[e][0], -score[e][1], -score[e][2]))
    groups, firsts = set(), []
    for e in ranked:
        key = e.kind, tuple(getattr(e, "pids", ()))[1:]
        if key not in groups:
            groups.add(key)
            firsts.append(e)
    first = set(firsts)
    chosen, released = [], {}
    for e in firsts + [e for e in ranked if e not in first]:
        if len(chosen) == n:
            break
        if e.kind != BoundarySpring.kind:  # a group released twice at a grid would be held by the second release only
            span = _moved(e, model, dep, lines)
            if any(None in (p, q) or p == q for g, p in span for q in released.get(g, ())):
                continue
            for g, p in span:
                released.setdefault(g, set()).add(p)
        chosen.append(e)
    return chosen


def _dilated(model: Model, score: dict, weight: float) -> dict[int, float]:
    """Each grid's ``score`` (grid id → value), or ``weight`` × the best on a grid one
    structural element away if that is higher."""
    rows = {int(g): i for i, g in enumerate(np.asarray(model.node_ids))}
    value = np.zeros(len(rows))
    for g, v in score.items():
        if int(g) in rows:
            value[rows[int(g)]] = v
    out = value.copy()
    for name in STRUCTURAL_BLOCKS:
        nodes = np.asarray(getattr(model, name).nodes)
        if not nodes.size:
            continue
        valid = nodes >= 0
        best = weight * np.where(valid, value[np.maximum(nodes, 0)], -np.inf).max(axis=1)
        np.maximum.at(out, nodes[valid], np.broadcast_to(best[:, None], nodes.shape)[valid])
    return {int(g): float(v) for g, v in zip(np.asarray(model.node_ids), out) if v > 0}


def _moved(e: AbstractEffect, model: Model, dep: dict, lines: dict) -> set[tuple[int, int | None]]:
    """(grid, group) pairs a joint or seam releases: a seam the beam group along its whole
    line, a joint the groups it moves off a shared grid; None: the grid itself (an
    RBE2-dependent grid freed from its master). A frame's and a stringer's seams cross at
    grids but move different groups."""
    if isinstance(e, Seam):
        return {(g, e.pids[1]) for g in e.line(model, lines)}
    return {(g, p) for g in e.nodes for p in (e.pids[1:] if g not in dep else (None,))}


@dataclass(frozen=True, eq=False)
class Released:
    """A joint, seam or support released in the shared model (:func:`augment`): the effect
    held :data:`STIFF` times stiffer than its reference, the springs on its translations
    and on its rotations (``trans``, ``rot``; one set if it has one factor); a seam's
    whole ``line`` is released, ``springs`` at each of its grids, so that seams along it
    are masks on the same model (:meth:`seam`)."""

    effect: AbstractEffect
    trans: tuple[int, ...]
    rot: tuple[int, ...]
    line: tuple[int, ...] = ()
    springs: dict = field(default_factory=dict)

    def ids(self) -> list[int]:
        """Every spring released with it."""
        return [e for pair in [(self.trans, self.rot), *self.springs.values()] for ids in pair for e in ids]

    def seam(self, seam: Seam) -> Released:
        """A seam on this one's line, held as stiff (its grids' springs)."""
        grids = [self.springs[g] for g in seam.nodes]
        return Released(seam, tuple(e for t, _ in grids for e in t), tuple(e for _, r in grids for e in r),
                        self.line, self.springs)


def region_shells(model: Model, nodes: list[int]) -> list[tuple[int, tuple[int, ...]]]:
    """(shell id, its grids) of every shell at a grid of ``nodes``, in id order."""
    out, rows = {}, model.node_index(nodes)
    for name in ("quads", "trias"):
        sh = getattr(model, name)
        for eid, row in zip(sh.ids, sh.nodes):
            if np.isin(row, rows).any():
                out[int(eid)] = tuple(int(model.node_ids[r]) for r in row if r >= 0)
    return sorted(out.items())


def augment(model: Model, nodes: list[int], structures: list[AbstractEffect], f_e, beyond: list[int] = ()):
    """The model plus a dormant (scale 0) point mass and ground springs at each grid of
    ``nodes`` and of ``beyond`` (:func:`margin`), at the reference values of :class:`AddedMass` and :class:`BoundarySpring`,
    a dormant :class:`Payload` on each shell at those grids, and each joint, seam (its
    whole line) or support of ``structures`` released and held :data:`STIFF` times
    stiffer than its reference.
    Returns the model, (reference effect, dormant element ids) per grid or shell and kind,
    and the :class:`Released` structures."""
    nominal = model
    stiffened = []
    for effect in structures:
        ref = effect.at_reference(nominal, f_e)
        stiff = ref.updated(np.full(len(ref.prior_sd), np.log(STIFF)))
        if isinstance(stiff, Seam):  # its whole line, at the seam's values per unit length
            line = replace(stiff, nodes=stiff.line(nominal))
            before, model = model, line.add_to(model)
            stiffened.append(Released(stiff, (), (), line.nodes, line.springs(before, model)).seam(stiff))
            continue
        before, model = model, stiff.add_to(model)
        stiffened.append(Released(stiff, *(stiff._halves(before, model) if stiff.split else (stiff._new(before, model), ()))))
    model = jaxfem.refresh(model)  # once for all structures
    dormant = []
    for node in list(nodes) + list(beyond):
        mass = AddedMass(nodes=(node,)).at_reference(nominal, f_e)
        spring = BoundarySpring(nodes=(node,)).at_reference(nominal, f_e)
        model, eid = jaxfem.add_mass(model, node, mass.m)
        model, eids = jaxfem.add_ground_springs(model, node, spring.k, (1, 2, 3))
        dormant += [(mass, [eid]), (spring, eids)]
    for shell, grids in region_shells(nominal, nodes):
        payload = Payload(nodes=grids, label=f"RBE3 over the grids of shell {shell}").at_reference(nominal, f_e)
        before, model = model, payload.add_to(model)
        dormant.append((payload, list(payload._new(before, model))))
    asleep = {s: [e for ref, ids in dormant if ref.scales == s for e in ids] for s in ("k", "m")}
    c, s = model.masses, model.springs
    model = eqx.tree_at(lambda m: (m.masses.m_scale, m.springs.k_scale), model, (
        jnp.where(jnp.asarray(np.isin(c.ids, asleep["m"])), 0.0, c.m_scale),
        jnp.where(jnp.asarray(np.isin(s.ids, asleep["k"])), 0.0, s.k_scale)))
    return model, dormant, stiffened


def group_candidates(model: Model, aug: Model, params: tuple[Parameter, ...], screen: Screen,
                     sigma2: float) -> list[Candidate]:
    """Stiffness, mass and frequency law of the property groups (and halves) each kind
    offers, the stiffness and mass of the whole structure and of the best-screening groups
    together (:func:`_wider`), but not the engineer's parameters; screened by their joint
    residual reduction (a law also by its linearised evidence over its group's factor, at
    the rows' noise σ²)."""
    taken = {(p.kind, tuple(sorted(param_eids(model, p).tolist()))) for p in params}
    out = []
    for kind in (GroupStiffness, GroupMass, FrequencyDependentStiffness):
        for effect in kind.candidates(model):
            ids = effect.elements(model)
            if (effect.kind, tuple(sorted(ids.tolist()))) in taken:
                continue  # already a baseline parameter
            taken.add((effect.kind, tuple(sorted(ids.tolist()))))
            out.append(_group_candidate(effect, model, aug, screen, sigma2))
    for effect in _wider(model, out):
        ids = tuple(sorted(effect.elements(model).tolist()))
        if (effect.kind, ids) not in taken:
            taken.add((effect.kind, ids))
            out.append(_group_candidate(effect, model, aug, screen, sigma2))
    return out


WIDER = (2, 3)  # the best-screening whole groups of a kind offered together, two and three of them


def _wider(model: Model, groups: list[Candidate]) -> list[AbstractEffect]:
    """A global error is the commonest of all: a stiffness and a mass factor of the whole
    structure, and of the :data:`WIDER` best-screening whole groups of each kind together."""
    out = [GroupStiffness(pids=tuple(stiffness_pids(model)), label="the whole structure"),
           GroupMass(pids=tuple(p for p in stiffness_pids(model) if p in structural_pids(model)),
                     label="the whole structure")]
    for cls in (GroupStiffness, GroupMass):
        whole = sorted((c for c in groups if type(c.reference) is cls and not c.reference.eids),
                       key=lambda c: -c.screen)
        for n in WIDER:
            if len(whole) >= n:
                pids = tuple(sorted(p for c in whole[:n] for p in c.reference.pids))
                out.append(cls(pids=pids, label=f"pids {', '.join(map(str, pids))} together"))
    return [e for e in out if e.pids]


def _group_candidate(effect: AbstractEffect, model: Model, aug: Model, screen: Screen, sigma2: float) -> Candidate:
    """A group effect at its reference, screened by its joint residual reduction; a law
    also by the linearised evidence of its coefficient over its group's factor (``nested``)."""
    ref = effect.at_reference(model, screen.f_e)
    c = Candidate(ref, ref.extension(model, aug))
    g = screen.column(ref.scales, effect.elements(model))
    cols = screen.law_columns(g) if c.ext.visco else g
    c.screen = float(screen.rho(cols, joint=True))
    if c.ext.visco:  # start at the linearised step (E0 factor 1 + u, law coefficient a) or on a grid
        c.nested = screen.added_log_evidence(g, cols[:, 1:], ref.prior_sd[1], sigma2)
        u, a = screen.step(cols)
        c.scan = (tuple(np.log1p([np.clip(u, -0.5, 1.0), np.clip(a, -0.7, 1.7)])),) + ref.scan
    return c


def node_candidates(aug: Model, dormant, screen: Screen) -> list[Candidate]:
    """Added mass and ground spring at each localised grid (the dormant elements of ``aug``),
    to start at the best of the linearised step's amplitude (× the reference, within e^±3)
    and the kind's scan grid (a heavy mass is far from linear: its own mode enters the band)."""
    out = []
    for ref, ids in dormant:
        g = screen.column(ref.scales, ids)
        step = float(np.log(np.clip(screen.step(g)[0], np.exp(-3.0), np.exp(3.0))))
        first = step if len(ref.prior_sd) == 1 else (step,) + (0.0,) * (len(ref.prior_sd) - 1)  # a payload: flat
        c = Candidate(ref, ref.dormant_extension(aug, ids), scan=(first,) + tuple(ref.scan))
        c.screen = float(screen.rho(g)[0])
        out.append(c)
    return out


PATCHES = ((Delamination, {}), (PatchStiffness, {"part": "membrane"}), (PatchStiffness, {"part": "bending"}),
           (DistributedMass, {}))  # the patch effects offered at each grid, each radius of RADII


def shell_grids(model: Model, region: list[int]) -> list[int]:
    """The grids of ``region`` that carry shells."""
    shells = set(np.concatenate([model.quads.ids, model.trias.ids]).tolist())
    return [g for g in region if shells & set(elements_at(model, g))]


def patch_candidates(model: Model, region: list[int], screen: Screen, kinds) -> list[Candidate]:
    """Patches of every kind in ``kinds`` (:data:`PATCHES`) about each grid of ``region``
    that carries shells, for each radius of the ladder :data:`~updating.diagnosis._patch_effects.RADII`
    (× the shell size): screened by ρ of their column, to start at the linearised step."""
    h, mass = shell_size(model), total_mass(model)
    out = []
    for node in shell_grids(model, region):
        for radius in RADII:
            for cls, options in PATCHES:
                if cls.kind in kinds:
                    patch = cls.at(model, node, radius * h, **options)
                    out.append(patch_candidate(patch, model, screen, screen.f_e, mass))
    return out


def patch_candidate(patch: AbstractPatch, model: Model, screen: Screen | None, f_e, mass: float) -> Candidate:
    """One patch at its reference (a distributed mass: 1 % of ``mass``, the total),
    screened (``screen`` None: a neighbour tried after screening, to start where
    ``theta0`` is set); its masks are made when it is shortlisted (:func:`with_masks`)."""
    ref = patch.carrying(model, 0.01 * mass) if isinstance(patch, DistributedMass) else patch.at_reference(model, f_e)
    if screen is None:
        return Candidate(ref, None, scan=tuple(ref.scan))
    g = screen.column(ref.scales, ref.elements(model))
    u = float(screen.step(g)[0])
    start = np.log(np.clip(u / ref.nsm, np.exp(-3.0), np.exp(3.0))) if ref.scales == "nsm" else \
        np.log(np.clip(1.0 + u, np.exp(-4.0), np.exp(1.0)))
    return Candidate(ref, None, scan=(float(start),) + tuple(ref.scan),
                     screen=float(screen.rho(g)[0]))


def with_masks(cands: list[Candidate], aug: Model) -> None:
    """Give the candidates without masks theirs, on the shared model ``aug``."""
    for c in cands:
        if c.ext is None:
            c.ext = c.reference.extension(aug, aug)


def patch_neighbours(model: Model, c: Candidate, f_e) -> list[AbstractPatch]:
    """The patches next to a fitted one: the same radius about each neighbouring shell grid,
    and the next radius up and down the ladder about the same grid."""
    ref = c.reference
    h = shell_size(model)
    step = int(np.argmin(np.abs(np.asarray(RADII) * h - ref.radius)))
    options = {"part": ref.part} if isinstance(ref, PatchStiffness) else {}
    out = [type(ref).at(model, g, ref.radius, **options) for g in shell_grids(model, neighbours(model, ref.centre))]
    out += [type(ref).at(model, ref.centre, RADII[i] * h, **options) for i in (step - 1, step + 1) if 0 <= i < len(RADII)]
    return out


def pool(model: Model, cands: list[Candidate], dormant, stiffened) -> tuple[int, ...]:
    """The elements the reduced fits assemble at each step (:attr:`updating.diagnosis._reduced.Bases.pool`):
    the dormant ones, the released joints' springs, and the shells of the patches among
    ``cands`` with one ring of shells about them (a patch moved to a neighbouring grid
    by the hill-climb stays inside)."""
    patches = [c.reference.elements(model) for c in cands if isinstance(c.reference, AbstractPatch)]
    shells = np.unique(np.concatenate(patches)) if patches else np.zeros(0, np.int64)
    ring = list(elements_at(model, element_grids(model, shells))) if len(shells) else []
    added = [e for _, ids in dormant for e in ids] + [e for r in stiffened for e in r.ids()]
    return tuple(sorted({int(e) for e in np.concatenate([shells, ring, added])}))


def structural_candidates(aug: Model, stiffened: list[Released]) -> list[Candidate]:
    """The released joints, seams and supports of ``aug`` (:func:`structural_candidate`),
    and the longer runs about each seam on its line (:meth:`~updating.diagnosis._seam.Seam.longer`)."""
    runs = [[r] + ([r.seam(s) for s in r.effect.longer(r.line)] if isinstance(r.effect, Seam) else [])
            for r in stiffened]
    return [structural_candidate(aug, r) for rs in runs for r in rs]


def structural_candidate(aug: Model, released: Released, theta0=None) -> Candidate:
    """A released joint, seam or support of ``aug``: one log-factor on its springs (two: on
    translations and on rotations), from :data:`STIFF` × its reference (θ = 0) down;
    prior and scan about the reference (``theta0`` given: that start, no scan)."""
    stiff, shift = released.effect, -np.log(STIFF)
    scan = tuple(tuple(shift + np.atleast_1d(t)) for t in stiff.scan) if theta0 is None else None
    return Candidate(stiff, extension(aug, k_log=released.trans, k_log_2=released.rot), scan=scan,
                     theta0=theta0, prior_mean=np.full(len(stiff.prior_sd), shift), released=released)


def seam_neighbours(aug: Model, c: Candidate, coarse: bool = False) -> list[Candidate]:
    """The seams next to a fitted one on its released line (:meth:`~updating.diagnosis._seam.Seam.neighbours`),
    to start at its fitted values."""
    r, theta = c.released, c.fit.theta
    return [structural_candidate(aug, r.seam(s), theta[len(theta) - len(c.theta0):])
            for s in c.reference.neighbours(r.line, coarse)]


def seam_onward(aug: Model, a: Candidate, b: Candidate) -> Candidate | None:
    """The seam move a → b on their released line (:func:`seam_neighbours`) made once more
    from b, to start at b's fitted values; None where it leaves the line."""
    line, theta = b.released.line, b.fit.theta
    start, n = line.index(b.reference.nodes[0]), len(b.reference.nodes)
    start, n = 2 * start - line.index(a.reference.nodes[0]), 2 * n - len(a.reference.nodes)
    if start < 0 or n < 2 or start + n > len(line):
        return None
    return structural_candidate(aug, b.released.seam(b.reference.run(line, start, n)), theta[len(theta) - len(b.theta0):])


LAW_REMAINDER = 2.0  # a law is fitted where its linearised remainder is within this factor of the best other's


def shortlist(cands: list[Candidate], best: int, per_kind: int, kinds, within: float) -> list[Candidate]:
    """The ``best`` screened candidates overall, and of each kind those screening at least
    ``within`` of the kind's best, at most ``per_kind``; frequency laws only where their
    linearised remainder 1 − ρ is within :data:`LAW_REMAINDER` times the best other
    candidate's and whose coefficient's linearised evidence over its group's factor alone
    (``nested``) is positive (a law has its group's factor and one more parameter: screening
    well below a simpler candidate, or no better than its own factor, it cannot win by
    evidence, and its fits solve a frequency-dependent eigenproblem, a compiled fit of
    their own: 22–29 s of a GARTEUR diagnosis)."""
    screened = sorted(cands, key=lambda c: -np.nan_to_num(c.screen, nan=-np.inf))
    law = FrequencyDependentStiffness.kind
    other = max((c.screen for c in screened if c.reference.kind != law and np.isfinite(c.screen)), default=0.0)
    screened = [c for c in screened if c.reference.kind != law
                or (1 - c.screen <= LAW_REMAINDER * (1 - other) and c.nested > 0)]
    short = screened[:best]
    for kind in kinds:
        of_kind = [c for c in screened if c.reference.kind == kind]
        if of_kind:
            top = of_kind[0].screen
            short += [c for c in of_kind if c.screen >= within * top][:per_kind]
    return list(dict.fromkeys(short))


POINT_KINDS = ("added_mass", "boundary_spring", "payload")  # the candidates held at a grid or on its shells


def at_best_grid(cands: list[Candidate], region: list[int], node_scores: dict[int, float]) -> list[Candidate]:
    """The added mass and spring at the region's best-localised grid and the payloads on
    its shells, whatever they screen: a heavy mass brings its own mode into the band,
    beyond the screen's linear step (a 20 kg payload on the 2,500-DoF barrel's floor
    screened below candidates on the skin while the residual forces put it first)."""
    best = max(region, key=lambda g: node_scores.get(g, 0.0), default=None)
    return [c for c in cands if c.reference.kind in POINT_KINDS and best in c.reference.nodes]


def group_screens(cands: list[Candidate]) -> dict[int, float]:
    """Best screening ρ of a whole property group's stiffness or mass, by pid."""
    out: dict[int, float] = {}
    for c in cands:
        e = c.reference
        if isinstance(e, (GroupStiffness, GroupMass)) and not e.eids and e.pids:
            out[e.pids[0]] = max(out.get(e.pids[0], 0.0), c.screen)
    return out


def node_max(model: Model, elem: dict[int, float]) -> dict[int, float]:
    """Grid score: the highest score of the elements at the grid."""
    out = {}
    for node in model.node_ids:
        at = elements_at(model, int(node))
        if at:
            out[int(node)] = max(elem.get(e, 0.0) for e in at)
    return out


def margin(model: Model, region: list[int], n: int, node_scores: dict[int, float]) -> list[int]:
    """At most ``n`` grids about the localised ``region``, ring by ring (each ring's best
    scoring first), that carry structural elements and no SPC: :func:`augment` puts
    dormant point masses and springs there too, so that the place walk can step past the
    region's edge; they are not screened onto the shortlist. (GARTEUR, 50 kN/m to ground
    at fuselage grid 1020: the region reached 1018, where the walk stopped with χ² per
    row 8.7.)"""
    seen, ring, out = set(region), list(region), []
    while ring and len(out) < n:
        ring = sorted({g for r in ring for g in neighbours(model, r)} - seen, key=lambda g: (-node_scores.get(g, 0.0), g))
        seen.update(ring)
        out += [g for g in ring if elements_at(model, g) and not constrained_components(model, g)][: n - len(out)]
    return out


def neighbours(model: Model, node: int) -> list[int]:
    """Grids joined to ``node`` by one structural element."""
    return [g for g in element_grids(model, elements_at(model, node)) if g != node]
