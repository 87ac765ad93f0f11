"""Candidate effects of a diagnosis: generated from the model by each kind
(:mod:`updating._effects`), screened by the linearised residual reduction ρ at the
baseline (Friswell & Mottershead 1995, §7; :func:`~updating._localisation.reduction`),
shortlisted for a full fit.

Group factors and node effects (added masses, springs to ground) share one model: the
nominal one plus dormant elements (scale 0) at the localised grids, so that their fits
share one compiled solver. Joints and released supports change the model's structure:
each gets its own model at its reference values.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxfem
from jaxfem import Model
from jaxfem import _edit as edit

from ._compiled import Compiled
from ._effects import (
    SCAN_ADDED,
    AbstractEffect,
    AddedMass,
    BoundarySpring,
    FrequencyDependentStiffness,
    GroupMass,
    GroupStiffness,
    Joint,
)
from ._extension import Extension, extension
from ._localisation import reduction
from ._parameters import Parameter, Parameterisation
from ._residuals import Problem, residuals
from ._topology import constrained_components, elements_at


@dataclass(eq=False)
class Candidate:
    """An effect to try: its ``reference`` (θ = 0), its free parameters as masks for the
    shared-structure fit (``ext``, on its own ``model`` if it changes the structure), the θ grid
    ``scan`` tried before fitting, its screening ρ, what the fit found (``result``) and the
    effect at the fitted values (``effect``; the reference until then)."""

    reference: AbstractEffect
    ext: Extension
    model: Model | None = None
    scan: tuple | None = None
    screen: float = float("nan")
    theta0: np.ndarray | None = None
    result: dict = field(default_factory=dict)
    effect: AbstractEffect | None = None

    def __post_init__(self):
        if self.effect is None:
            self.effect = self.reference
        if self.theta0 is None:
            self.theta0 = np.zeros(self.ext.n_params)

    @property
    def family(self) -> str:
        """``structural`` (own model), ``visco`` (a law) or ``mask``: the candidates of one
        family share a compiled fit."""
        return "structural" if self.model is not None else "visco" if self.ext.visco else "mask"


# ---------------------------------------------------------------------------------------
# the screening Jacobian


@dataclass
class Screen:
    """Weighted residual ``r`` at the baseline and its linearisation: ``J_k``/``J_m`` per
    element stiffness/mass scale (ids ``k_ids``/``m_ids``), ``J_b`` the baseline
    parameters; ``row_mode``: test mode of each row; ``f_e``, ``f_ref`` (Hz)."""

    r: np.ndarray
    J_k: np.ndarray
    J_m: np.ndarray
    k_ids: np.ndarray
    m_ids: np.ndarray
    J_b: np.ndarray
    row_mode: np.ndarray
    f_e: np.ndarray
    f_ref: float

    @classmethod
    def at(cls, problem: Problem, theta, n_b: int, f_e: np.ndarray) -> Screen:
        r, J_k, J_m, k_ids, m_ids = _element_jacobian(problem, np.asarray(theta))
        return cls(r, J_k, J_m, k_ids, m_ids, _baseline_columns(problem, theta, n_b), _row_modes(problem),
                   f_e, float(np.exp(np.mean(np.log(f_e)))))

    def column(self, scales: str, eids) -> np.ndarray:
        """One column: the stiffness (``scales`` "k") or mass ("m") of ``eids`` scaled together."""
        J, ids = (self.J_k, self.k_ids) if scales == "k" else (self.J_m, self.m_ids)
        return J[:, np.isin(ids, np.asarray(list(eids), np.int64))].sum(axis=1, keepdims=True)

    def law_columns(self, g: np.ndarray) -> np.ndarray:
        """A stiffness column and its frequency law: ``g`` and ``g·ln(f/f_ref)``."""
        return np.concatenate([g, g * np.log(self.f_e[self.row_mode] / self.f_ref)[:, None]], axis=1)


def _row_modes(problem: Problem) -> np.ndarray:
    """Test mode of each residual row (eigenvalue rows, then eigenvector rows)."""
    ne, ns = problem.phi_e.shape[1], problem.phi_e.shape[0]
    return np.concatenate([np.arange(ne), np.tile(np.arange(ne), ns)])


def _flat(theta, problem: Problem):
    eps, _ = residuals(theta, problem)
    return jnp.concatenate([jnp.ravel(eps[k]) for k in ("eigenvalue", "eigenvector")])


def _baseline_columns(problem: Problem, theta, n_b: int) -> np.ndarray:
    if n_b == 0:
        return np.zeros((len(_row_modes(problem)), 0))
    J = Compiled(jax.jacfwd(_flat))(jnp.asarray(theta), problem)
    return np.asarray(J)[:, :n_b]


def _element_jacobian_fn(theta, problem: Problem):
    model0 = problem.model(theta)

    def fn(uk, um):
        m = model0
        for name, u in zip(("beams", "rods", "springs", "bushes"), uk):
            k = getattr(m, name).k_scale
            m = eqx.tree_at(lambda x, name=name: getattr(x, name).k_scale, m, jnp.where(k == 0, u, k * (1 + u)))
        for name, u in zip(("beams", "rods", "masses"), um):
            ms = getattr(m, name).m_scale
            m = eqx.tree_at(lambda x, name=name: getattr(x, name).m_scale, m, jnp.where(ms == 0, u, ms * (1 + u)))
        p = eqx.tree_at(lambda q: (q.values, q.parameterisation, q.extension), problem,
                        (jaxfem.partition(m)[0], Parameterisation((), (), (), (), ()), None),
                        is_leaf=lambda x: x is None)
        return _flat(jnp.zeros(0), p)

    structure = problem.structure.value
    uk = tuple(jnp.zeros(len(getattr(structure, n).ids)) for n in ("beams", "rods", "springs", "bushes"))
    um = tuple(jnp.zeros(len(getattr(structure, n).ids)) for n in ("beams", "rods", "masses"))
    r = fn(uk, um)
    jk, jm = jax.jacfwd(fn, argnums=(0, 1))(uk, um)
    return r, jnp.concatenate(jk, axis=1), jnp.concatenate(jm, axis=1)


def _element_jacobian(problem: Problem, theta):
    """Weighted residual r at θ and its derivative w.r.t. each element's stiffness and mass
    scale (a dormant element: w.r.t. waking it at its reference value)."""
    r, jk, jm = Compiled(_element_jacobian_fn)(jnp.asarray(theta), problem)
    s = problem.structure.value
    k_ids = np.concatenate([getattr(s, n).ids for n in ("beams", "rods", "springs", "bushes")])
    m_ids = np.concatenate([getattr(s, n).ids for n in ("beams", "rods", "masses")])
    return np.asarray(r), np.asarray(jk), np.asarray(jm), k_ids, m_ids


# ---------------------------------------------------------------------------------------
# candidates by kind


def localised_grids(model: Model, node_scores: dict[int, float], n: int) -> list[int]:
    """Grids with the highest localisation score that carry structural elements (and no SPC)."""
    ranked = sorted(node_scores, key=lambda k: -node_scores[k])
    return [k for k in ranked if elements_at(model, k) and not constrained_components(model, k)][:n]


def augment(model: Model, nodes: list[int], f_e) -> tuple[Model, list[tuple[AbstractEffect, list[int]]]]:
    """The model plus a dormant (scale 0) point mass and ground springs at each grid, at the
    reference values of :class:`AddedMass` and :class:`BoundarySpring`; returns the model
    and (reference effect, its dormant element ids) per grid and kind."""
    dormant, nominal = [], model
    for node in nodes:
        mass = AddedMass(nodes=(node,)).at_reference(nominal, f_e)
        spring = BoundarySpring(nodes=(node,)).at_reference(nominal, f_e)
        model, eid = edit.add_mass(model, node, mass.m)
        model, eids = edit.add_ground_springs(model, node, spring.k, (1, 2, 3))
        dormant += [(mass, [eid]), (spring, eids)]
    asleep = {s: [e for ref, ids in dormant if ref.scales == s for e in ids] for s in ("k", "m")}
    c, s = model.masses, model.springs
    model = eqx.tree_at(lambda m: (m.masses.m_scale, m.springs.k_scale), model, (
        jnp.where(jnp.asarray(np.isin(c.ids, asleep["m"])), 0.0, c.m_scale),
        jnp.where(jnp.asarray(np.isin(s.ids, asleep["k"])), 0.0, s.k_scale)))
    return model, dormant


def group_candidates(model: Model, aug: Model, params: tuple[Parameter, ...], screen: Screen) -> list[Candidate]:
    """Stiffness, mass and frequency law of the property groups (and halves) each kind
    offers, but not the engineer's parameters; screened by their joint residual reduction."""
    taken = {(p.kind, tuple(sorted(_param_eids(model, p).tolist()))) for p in params}
    out = []
    for kind in (GroupStiffness, GroupMass, FrequencyDependentStiffness):
        for effect in kind.candidates(model):
            ids = effect.elements(model)
            if (effect.kind, tuple(sorted(ids.tolist()))) in taken:
                continue  # already a baseline parameter
            ref = effect.at_reference(model, screen.f_e)
            c = Candidate(ref, ref.extension(model, aug), scan=ref.scan)
            g = screen.column(ref.scales, ids)
            c.screen = float(reduction(screen.r, screen.law_columns(g) if c.ext.visco else g, screen.J_b, joint=True))
            out.append(c)
    return out


def node_candidates(aug: Model, dormant, screen: Screen) -> list[Candidate]:
    """Added mass and ground spring at each localised grid (the dormant elements of ``aug``)."""
    out = []
    for ref, ids in dormant:
        c = Candidate(ref, extension(aug, **{f"{ref.scales}_add": ids}), scan=SCAN_ADDED)
        c.screen = float(reduction(screen.r, screen.column(ref.scales, ids), screen.J_b)[0])
        out.append(c)
    return out


def structural_candidates(model: Model, node_score: dict, kinds, n: int, f_e) -> list[Candidate]:
    """Joints and flexible supports, the ``n`` nearest the localised error, each on its own
    model at its reference values."""
    effects = [e for kind in (Joint, BoundarySpring) if kind.kind in kinds for e in kind.candidates(model)]
    effects.sort(key=lambda e: -max(node_score.get(k, 0.0) for k in e.nodes))
    out = []
    for effect in effects[:n]:
        ref = effect.at_reference(model, f_e)
        extended = ref.apply(model)
        out.append(Candidate(ref, ref.extension(model, extended), model=extended, scan=ref.scan))
    return out


def shortlist(cands: list[Candidate], shortlist: int, per_kind: int, kinds) -> list[Candidate]:
    """The best screened candidates overall and per kind, and every structural one."""
    screened = sorted((c for c in cands if c.family != "structural"), key=lambda c: -c.screen)
    short = screened[:shortlist]
    for kind in kinds:
        short += [c for c in screened if c.effect.kind == kind][:per_kind]
    return list(dict.fromkeys(short)) + [c for c in cands if c.family == "structural"]


def group_screens(cands: list[Candidate]) -> dict[int, float]:
    """Best screening ρ of a whole property group's stiffness or mass, by pid."""
    out: dict[int, float] = {}
    for c in cands:
        e = c.effect
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


def _param_eids(model: Model, p: Parameter) -> np.ndarray:
    return np.union1d(model.element_ids(pids=p.pids) if p.pids else np.zeros(0, np.int64), np.asarray(p.eids, np.int64))
