"""Diagnosis: where the model fails and which physical effect is missing.

1. **Baseline**: the model, updated with the engineer's parameters if any (thesis §3.2).
2. **Localisation** at the baseline, by two independent methods: (a) sensitivity — the
   share ρ of the residual that one Gauss–Newton step in a single element's (group's)
   stiffness or mass removes (Friswell & Mottershead 1995, §7), (b) residual forces of
   the measured modes expanded to the model (ibid. §8, :func:`residual_forces`).
3. **Candidates** generated from the model (:mod:`updating._effects`), screened by the
   linearised residual reduction ρ (the same Jacobian as (a)); the best of each kind and
   the best overall, and the structural ones (joints, released supports) nearest the
   localised error, are **fitted** with the baseline parameters (Optimistix
   Levenberg–Marquardt; candidates of one model structure share one compiled solver, their
   masks being traced arguments; the screening Jacobian of all elements is one ``jacfwd``).
4. **Ranking by evidence that generalises**: k-fold cross-validation over the test modes
   (fit on the others, predict the held-out ones — the thesis' active/passive idea made
   systematic, §4.2.4.2) and Akaike's criterion ``AIC = n ln(RSS/n) + 2k`` which charges
   for added parameters. An effect is *warranted* when it removes at least
   ``min_score`` % of the held-out error, lowers AIC by at least ``min_delta_aic`` and is
   plausible; otherwise parameter errors alone explain the data.

Residual rows are weighted by the expected measurement noise (relative frequency σ_f,
relative shape σ_φ per component), so the cost is a χ² and frequencies and shapes weigh
as their accuracies say.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxfem
from identification import ModalData
from jaxfem import Model
from jaxfem import _edit as edit

from ._compiled import Compiled
from ._correlation import comac, pair_modes
from ._effects import (
    Effect,
    Extension,
    at_reference,
    constrained_components,
    effect_parameters,
    elements_at,
    extension,
    joint_reference,
    masters,
    total_mass,
)
from ._eigensolvers import Dense
from ._engine import Settings, run
from ._localisation import group_scores, reduction, residual_forces
from ._parameters import Options, Parameter, Parameterisation, ParameterSet
from ._report import json_number
from ._residuals import Problem, evaluate, residuals, rows
from ._result import Iteration, UpdateResult
from ._solve import build_problem, update


@dataclass(frozen=True)
class DiagnoseOptions:
    """Settings of :func:`diagnose`.

    ``noise_freq``/``noise_shape``: expected relative σ of measured frequencies and of
    shape components (Table 4.7 magnitudes). ``folds``: cross-validation folds over the
    test modes. ``shortlist``: screened candidates fitted in full, plus the ``per_kind``
    best of each kind; ``max_structural``:
    joints and released supports fitted (nearest the localised error); ``max_nodes``:
    grids tried for added masses and springs. ``min_score`` (% of held-out error removed)
    and ``min_delta_aic``: evidence an effect needs to be warranted. Every fit is the
    engine's Levenberg–Marquardt loop (:mod:`updating._engine`), converged when no factor
    changes by more than ``tolerance``, at most ``max_steps`` steps.
    """

    noise_freq: float = 0.002
    noise_shape: float = 0.01
    folds: int = 4
    shortlist: int = 6
    per_kind: int = 2
    max_structural: int = 3
    max_nodes: int = 10
    min_score: float = 20.0
    min_delta_aic: float = 10.0
    max_steps: int = 30
    tolerance: float = 1e-5
    kinds: tuple[str, ...] = ("stiffness", "mass", "joint", "added_mass", "boundary_spring",
                              "frequency_dependent_stiffness")

    @property
    def settings(self) -> Settings:
        return Settings(False, self.tolerance, self.max_steps, self.max_steps)


@dataclass(eq=False)
class Candidate:
    """An effect to try: how it is parameterised for the batched fit and what it found."""

    effect: Effect
    family: str  # "mask" (shared structure), "visco", or "structural"
    ext: Extension
    ref: dict  # values at θ = 0
    model: Model | None = None  # own model for structural candidates
    screen: float = float("nan")
    theta0: np.ndarray = field(default_factory=lambda: np.zeros(1))
    result: dict = field(default_factory=dict)

    def values(self, theta_e: np.ndarray) -> dict:
        """Physical values of the effect at its fitted θ."""
        k = self.effect.kind
        t = np.asarray(theta_e, float)
        if k in ("stiffness", "mass"):
            return {"alpha" if k == "stiffness" else "beta": float(np.expm1(t[0]))}
        if k == "frequency_dependent_stiffness":
            return {"alpha": float(np.expm1(t[0])), "a": float(np.expm1(t[1])), "f_ref_hz": self.ref["f_ref_hz"]}
        return {name: float(v * np.exp(t[0])) for name, v in self.ref.items()}


# ---------------------------------------------------------------------------------------
# batched fits


def _cost_rows(theta, problem: Problem, mask, ev):
    """Residual rows of the test modes in ``mask`` at the evaluation ``ev`` (unpaired ones
    get the worst value)."""
    eps = rows(theta, replace(problem, active=mask), ev)
    cost = sum(jnp.sum(eps[k] ** 2) for k in ("eigenvalue", "eigenvector"))
    unpaired = mask & ~ev.paired
    penalty = jnp.sum(jnp.where(unpaired, (problem.lam_weight * problem.max_freq_dev) ** 2 + 1.0, 0.0))
    return cost + penalty


def _solve_one(theta0, problem: Problem, settings: Settings):
    """One fit by the engine; the fitted and the held-out cost from its last evaluation
    (pairing does not depend on the mask: one eigen solve for both)."""
    state = run(theta0, problem, Dense(), jnp.zeros(0), settings)
    theta, ev = state.theta, state.evaluation
    fit, held = (_cost_rows(theta, problem, mask, ev) for mask in (problem.active, ~problem.active))
    return theta, fit, held, ev.lam_a, ev.paired, ev.mac


def _cost_one(theta, problem: Problem):
    return _cost_rows(theta, problem, problem.active, evaluate(theta, problem))


class _Fits:
    """The compiled fit and cost of one diagnosis (freed with it, see :mod:`._compiled`)."""

    def __init__(self):
        self.solve, self.cost = Compiled(_solve_one), Compiled(_cost_one)

_SCAN = (0.0, -1.5, -3.0, -4.5, -6.0, 1.5)  # log-factors tried before fitting a joint or support
_SCAN_ADDED = (-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0)  # ... an added mass or spring (× its reference)


_SCAN_LAW = tuple((np.log1p(alpha), np.log1p(a)) for alpha in (-0.2, 0.0, 0.2)
                  for a in (-0.4, -0.2, 0.0, 0.2, 0.4))  # (E0 factor, a) of a frequency law


def _scan_start(fits: _Fits, problem: Problem, ext: Extension, theta_b: np.ndarray, grid=_SCAN) -> np.ndarray:
    """Best starting θ of an effect on a coarse grid: a fit from the reference alone can
    stall where modes swap partners on the way (a much softer joint, a heavy added mass,
    a strong frequency law)."""
    p = eqx.tree_at(lambda q: q.extension, problem, ext, is_leaf=lambda x: x is None)
    costs = [float(fits.cost(jnp.asarray(np.append(theta_b, t)), p)) for t in grid]
    return np.atleast_1d(np.asarray(grid[int(np.argmin(costs))], float))


def _fold_masks(n: int, folds: int) -> list[np.ndarray]:
    """All modes, then one mask per fold (mode i held out in fold i mod k)."""
    ids = np.arange(n)
    return [np.ones(n, bool)] + [ids % folds != k for k in range(min(folds, n))]


def _run(fits: _Fits, problem: Problem, exts: list, theta0s: list, masks, settings: Settings,
         keep=None) -> list[dict]:
    """Fit every extension on all modes, then on every fold (held-out mask) if
    ``keep(cost)`` (default: always); the folds start at the all-modes fit.

    All fits of one model structure share one compiled solver (the extension and the mask
    are traced arguments). They run in a host loop: ``vmap`` of the Optimistix loop stalled
    on XLA-CPU here (jax 0.10.2), and on CPU a batched eigensolve is no faster than a loop.
    """
    def fit(ext, th, m):
        p = eqx.tree_at(lambda q: (q.extension, q.active), problem, (ext, jnp.asarray(m)),
                        is_leaf=lambda x: x is None)
        return fits.solve(jnp.asarray(th), p, settings)

    lam_e = np.asarray(problem.lam_e)

    def deviation(out):
        return np.where(out[4], np.sqrt(np.maximum(np.asarray(out[3]), 0) / lam_e) - 1, np.nan)

    results = []
    for ext, th in zip(exts, theta0s):
        try:
            full = [np.asarray(o) for o in fit(ext, th, masks[0])]
        except RuntimeError as err:  # a trial step made the model non-finite: report, do not rank
            results.append({"theta": np.asarray(th), "cost": float("inf"), "cv_cost": float("nan"),
                            "freq_dev": np.full(len(lam_e), np.nan), "mac": np.full(len(lam_e), np.nan),
                            "heldout_freq_dev": np.full(len(lam_e), np.nan), "error": str(err).splitlines()[0]})
            continue
        res = {"theta": full[0], "cost": float(full[1]), "cv_cost": float("nan"), "freq_dev": deviation(full),
               "mac": np.where(full[4], full[5], np.nan), "heldout_freq_dev": np.full(len(lam_e), np.nan)}
        if keep is None or keep(res["cost"]):
            held = 0.0
            for m in masks[1:]:
                out = fit(ext, full[0], m)
                held += float(out[2])
                res["heldout_freq_dev"][~m] = deviation(out)[~m]
            res["cv_cost"] = held
        results.append(res)
    return results


# ---------------------------------------------------------------------------------------
# candidates


def _halves(model: Model, pid: int) -> list[tuple[np.ndarray, str]]:
    """A group split in two at the median of its longest extent (left/right, in/outboard)."""
    rows, ids = [], []
    for name in ("beams", "rods"):
        b = getattr(model, name)
        hit = b.pids == pid
        rows.append(model.xyz[b.nodes[hit]].mean(axis=1))
        ids.append(b.ids[hit])
    centre, ids = np.concatenate(rows), np.concatenate(ids)
    if len(ids) < 4:
        return []
    axis = int(np.argmax(np.ptp(centre, axis=0)))
    cut = float(np.median(centre[:, axis]))
    low = centre[:, axis] <= cut
    if low.all() or not low.any():
        return []
    name = "xyz"[axis]
    return [(ids[low], f"pid {pid}, {name} ≤ {cut:.3g} m"), (ids[~low], f"pid {pid}, {name} > {cut:.3g} m")]


def _structural_pids(model: Model) -> list[int]:
    return sorted({int(p) for b in (model.beams, model.rods) for p in b.pids})


def _stiffness_pids(model: Model) -> list[int]:
    return sorted({int(p) for b in (model.beams, model.rods, model.bushes, model.springs) for p in b.pids if p > 0})


def _joints(model: Model) -> list[Effect]:
    """RBE2 groups holding structural elements, and grids shared by two beam/rod groups."""
    out = []
    by_master: dict[int, list[int]] = {}
    for node, master in masters(model).items():
        if elements_at(model, node):
            by_master.setdefault(master, []).append(node)
    for master, nodes in sorted(by_master.items()):
        pids = sorted({*elements_at(model, master).values()}) + sorted(
            {p for n in nodes for p in elements_at(model, n).values()})
        out.append(Effect("joint", pids=tuple(dict.fromkeys(pids)), nodes=tuple(sorted(nodes)),
                          label=f"RBE2 at grid {master} → {', '.join(map(str, sorted(nodes)))}"))
    beam_pids = set(_structural_pids(model))
    for node in model.node_ids:
        at = {p for p in elements_at(model, int(node)).values() if p in beam_pids}
        if len(at) == 2 and int(node) not in masters(model):
            out.append(Effect("joint", pids=tuple(sorted(at)), nodes=(int(node),),
                              label=f"grid {int(node)} between pids {' and '.join(map(str, sorted(at)))}"))
    return out


def _node_candidates(model: Model, node_scores: dict[int, float], n: int) -> list[int]:
    """Grids with the highest localisation score that carry structural elements."""
    ranked = sorted(node_scores, key=lambda k: -node_scores[k])
    return [k for k in ranked if elements_at(model, k) and not constrained_components(model, k)][:n]


def _augment(model: Model, nodes: list[int], m_ref: float, k_ref: float):
    """The model plus dormant (scale 0) point masses and ground springs at ``nodes``."""
    mass_ids, spring_ids = {}, {}
    for node in nodes:
        model, eid = edit.add_mass(model, node, m_ref)
        mass_ids[node] = eid
        model, eids = edit.add_ground_springs(model, node, k_ref, (1, 2, 3))
        spring_ids[node] = eids
    c, s = model.masses, model.springs
    model = eqx.tree_at(lambda m: (m.masses.m_scale, m.springs.k_scale), model, (
        jnp.where(jnp.asarray(np.isin(c.ids, list(mass_ids.values()))), 0.0, c.m_scale),
        jnp.where(jnp.asarray(np.isin(s.ids, [e for ids in spring_ids.values() for e in ids])), 0.0, s.k_scale)))
    return model, mass_ids, spring_ids


# ---------------------------------------------------------------------------------------
# the diagnosis


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`: ``report`` is the JSON-ready dict (see the README);
    ``best`` the winning effect (fitted values) or None; ``candidates`` all tried."""

    report: dict
    best: Effect | None
    candidates: list[Candidate]
    model: Model
    baseline_params: tuple[Parameter, ...]
    element_scores: dict[int, float]
    node_scores: dict[int, float]
    sensor_modes: tuple  # baseline model frequencies (Hz) and shapes at the sensors

    def to_json(self) -> dict:
        """The JSON-ready ``report`` (NaN and inf as null)."""
        from ._report import json_safe

        return json_safe(self.report)


def diagnose(model: Model, test: ModalData, parameters: ParameterSet | None = None, *,
             options: DiagnoseOptions = DiagnoseOptions(),
             progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Compare, localise, and rank candidate effects by how well they predict held-out modes.

    **Arguments:** the nominal model; measured modes; the engineer's updating parameters
    (the baseline; None = the nominal model as it is); options; ``progress`` receives a
    line per stage. **Returns:** a :class:`Diagnosis`.
    """
    say = progress or (lambda s: None)
    start = time.perf_counter()
    params = tuple(parameters.parameters) if parameters else ()
    n_b = len(params)
    ne, ns = len(test.frequencies_hz), len(test.sensors)
    w_lam = options.noise_shape / (np.sqrt(ns) * 2 * options.noise_freq)  # σ_φ-per-component / σ_λ
    sigma2 = (options.noise_shape / np.sqrt(ns)) ** 2
    # a weak prior (one noise unit at a factor e³ ≈ 20) keeps unidentifiable factors finite
    pset = ParameterSet(params, Options(eigenvalue_weight=w_lam, regularisation=sigma2 / 9,
                                        n_model_modes=parameters.options.n_model_modes if parameters else None))
    masks = _fold_masks(ne, options.folds)
    fits = _Fits()

    # -- localisation at the nominal model: where to put node-based candidates
    say("localising the error (residual forces)")
    nominal_problem = build_problem(model, test, pset)
    C = np.asarray(nominal_problem.C)
    elem_b, node_b = residual_forces(model, np.asarray(nominal_problem.lam_e), np.asarray(nominal_problem.phi_e), C)
    nodes = _node_candidates(model, node_b, options.max_nodes)
    mass = total_mass(model)
    f1 = float(np.min(test.frequencies_hz))
    m_ref = 0.01 * mass
    k_ref = mass * (2 * np.pi * f1 / 10) ** 2  # a support that alone would carry the structure at f₁/10
    aug, mass_ids, spring_ids = _augment(model, nodes, m_ref, k_ref)
    problem = build_problem(aug, test, pset)
    zero = extension(aug)

    # -- baseline: the engineer's parameters fitted on all modes and on each fold
    say(f"baseline fit ({n_b} parameters, {len(masks) - 1}-fold cross-validation over {ne} modes)")
    base = _run(fits, problem, [zero], [np.zeros(n_b + 1)], masks, options.settings)[0]
    theta_b = base["theta"][:n_b]

    # -- screening Jacobian at the baseline: every element's stiffness and mass, dormant ones
    say("screening (sensitivity of every element)")
    screen = _Screen.at(problem, base["theta"], n_b, test)
    elem_a = {int(e): float(v) for e, v in zip(screen.k_ids, reduction(screen.r, screen.J_k, screen.J_b))}
    node_a = _node_max(aug, elem_a)
    cands = _group_candidates(model, aug, params, screen) + _node_candidates_at(
        aug, nodes, screen, mass_ids, spring_ids, m_ref, k_ref)
    cands = [c for c in cands if c.effect.kind in options.kinds]
    node_score = _combine(node_a, node_b)
    cands += [_structural_candidate(model, e) for e in _structural_effects(model, node_score, options)]
    short = _shortlist(cands, options)
    say(f"{len(cands)} candidates screened; fitting {len(short)} with {len(masks) - 1}-fold cross-validation")

    # -- fits: all modes, then the folds for those that could pass the AIC test
    n_rows = ne * (1 + ns)

    def theta_start(c):
        return np.concatenate([theta_b, c.theta0])

    def keep(k_e):
        return lambda cost: n_rows * np.log(max(cost, 1e-300) / base["cost"]) + 2 * k_e <= -options.min_delta_aic

    for c in short:
        if c.effect.kind in ("added_mass", "boundary_spring") and c.family == "mask":
            c.theta0 = _scan_start(fits, problem, c.ext, theta_b, _SCAN_ADDED)
        if c.family == "visco":
            c.theta0 = _scan_start(fits, problem, c.ext, theta_b, _SCAN_LAW)
    for family in ("mask", "visco"):
        group = [c for c in short if c.family == family]
        if group:
            say(f"  {family}: {len(group)} candidates × {len(masks)} fits ({time.perf_counter() - start:.0f} s)")
            for c, res in zip(group, _run(fits, problem, [c.ext for c in group], [theta_start(c) for c in group],
                                          masks, options.settings, keep(group[0].ext.n_params))):
                c.result = res
    for c in short:
        if c.family == "structural":
            say(f"  {c.effect.kind} {c.effect.where()} ({time.perf_counter() - start:.0f} s)")
            p = build_problem(c.model, test, pset)
            c.theta0 = _scan_start(fits, p, c.ext, theta_b)
            c.result = _run(fits, p, [c.ext], [theta_start(c)], masks, options.settings, keep(1))[0]

    effects, ranked = _evidence(short, base, n_b, n_rows, sigma2, mass, options)
    best = ranked[0].effect if effects and effects[0]["warranted"] else None

    # -- comparison at the baseline
    ev = evaluate(jnp.asarray(base["theta"]), problem)
    pairing = pair_modes(np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model), screen.f_e,
                         np.asarray(problem.phi_e), min_mac=problem.min_mac, max_freq_dev=problem.max_freq_dev)
    compared = pairing.summary()
    co = np.asarray(comac(np.asarray(ev.phi_model)[:, pairing.model], np.asarray(problem.phi_e)[:, pairing.test]))
    group_b = group_scores(elem_b, model)
    group_a = _group_from_screen(cands)
    groups = _combine(group_a, group_b)
    report = {
        "paired_modes": compared["paired_modes"],
        "unpaired_test": compared["unpaired_test"],
        "unpaired_model": compared["unpaired_model"][:10],
        "baseline": {"parameters": [{"name": p.name, "alpha": float(np.expm1(t))} for p, t in zip(params, theta_b)],
                     "rms_freq_dev_pct": _rms(base["freq_dev"]), "mean_mac": float(np.nanmean(base["mac"])),
                     "heldout_rms_freq_dev_pct": _rms(base["heldout_freq_dev"]),
                     "chi2_per_row": float(base["cost"] / sigma2 / n_rows)},
        "sensors": [{"label": lab, "comac": float(v)} for lab, v in zip(test.sensors.labels, co)],
        "localisation": {
            "groups": [{"pid": p, "score": s, "sensitivity": group_a.get(p, 0.0), "residual_force": group_b.get(p, 0.0)}
                       for p, s in groups.items()],
            "nodes": [{"node": n, "score": s, "sensitivity": node_a.get(n, 0.0), "residual_force": node_b.get(n, 0.0)}
                      for n, s in list(node_score.items())[:30]],
        },
        "effects": effects,
        "no_effect_warranted": best is None,
        "candidates_evaluated": len(cands),
        "candidates_fitted": len(short),
        "noise": {"freq_pct": 100 * options.noise_freq, "shape_pct": 100 * options.noise_shape},
    }
    report["verdict"] = _verdict(report)
    report["seconds"] = time.perf_counter() - start
    say(f"diagnosis done in {report['seconds']:.1f} s")
    return Diagnosis(report, best, ranked, model, params, _combine(
        {e: v for e, v in elem_a.items() if e in set(model.element_ids().tolist())}, elem_b), node_score,
        (np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model)))


@dataclass
class _Screen:
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
    def at(cls, problem: Problem, theta, n_b: int, test: ModalData) -> _Screen:
        r, J_k, J_m, k_ids, m_ids = _element_jacobian(problem, np.asarray(theta))
        f_e = np.asarray(test.frequencies_hz)
        return cls(r, J_k, J_m, k_ids, m_ids, _baseline_columns(problem, theta, n_b), _row_modes(problem),
                   f_e, float(np.exp(np.mean(np.log(f_e)))))

    def column(self, J: np.ndarray, ids: np.ndarray, eids) -> np.ndarray:
        """One column: the elements ``eids`` scaled together."""
        return J[:, np.isin(ids, np.asarray(list(eids), np.int64))].sum(axis=1, keepdims=True)


def _group_candidates(model: Model, aug: Model, params, screen: _Screen) -> list[Candidate]:
    """Stiffness, mass and frequency law of every property group, stiffness and mass of
    both halves of each structural group; screened by their joint residual reduction."""
    taken = {(p.kind, tuple(sorted(_param_eids(model, p).tolist()))) for p in params}
    structural = _structural_pids(model)
    out = []
    for pid in _stiffness_pids(model):
        groups = [(model.element_ids(pids=[pid]), f"pid {pid}", ())]
        if pid in structural:
            groups += [(ids, label, tuple(int(e) for e in ids)) for ids, label in _halves(model, pid)]
        for ids, label, eids in groups:
            for kind in ("stiffness", "mass", "frequency_dependent_stiffness"):
                if (kind == "mass" and pid not in structural) or (kind == "frequency_dependent_stiffness" and eids):
                    continue
                if (kind, tuple(sorted(ids.tolist()))) in taken:
                    continue  # already a baseline parameter
                eff = Effect(kind, pids=(pid,), eids=eids, label=label)
                if kind == "stiffness":
                    c = Candidate(eff, "mask", extension(aug, k_log=ids), {})
                    cols = screen.column(screen.J_k, screen.k_ids, ids)
                elif kind == "mass":
                    c = Candidate(eff, "mask", extension(aug, m_log=ids), {})
                    cols = screen.column(screen.J_m, screen.m_ids, ids)
                else:
                    c = Candidate(eff, "visco", extension(aug, k_log=ids, f_ref=screen.f_ref),
                                  {"f_ref_hz": screen.f_ref}, theta0=np.zeros(2))
                    g = screen.column(screen.J_k, screen.k_ids, ids)
                    cols = np.concatenate([g, g * np.log(screen.f_e[screen.row_mode] / screen.f_ref)[:, None]], axis=1)
                c.screen = float(reduction(screen.r, cols, screen.J_b, joint=True))
                out.append(c)
    return out


def _node_candidates_at(aug: Model, nodes, screen: _Screen, mass_ids, spring_ids, m_ref, k_ref) -> list[Candidate]:
    """Added mass and ground spring at each localised grid (dormant elements of ``aug``)."""
    out = []
    for node in nodes:
        for kind, ids, J, ref, ident in (
                ("added_mass", [mass_ids[node]], screen.J_m, {"m": m_ref}, screen.m_ids),
                ("boundary_spring", spring_ids[node], screen.J_k, {"k": k_ref}, screen.k_ids)):
            ext = extension(aug, m_add=ids) if kind == "added_mass" else extension(aug, k_add=ids)
            c = Candidate(Effect(kind, nodes=(node,)), "mask", ext, ref)
            c.screen = float(reduction(screen.r, screen.column(J, ident, ids), screen.J_b)[0])
            out.append(c)
    return out


def _structural_effects(model: Model, node_score: dict, options: DiagnoseOptions) -> list[Effect]:
    """Joints and flexible supports, the ``max_structural`` nearest the localised error."""
    out = []
    if "joint" in options.kinds:
        out += _joints(model)
    if "boundary_spring" in options.kinds:
        out += [Effect("boundary_spring", nodes=(int(n),), label=f"support at grid {int(n)}")
                for n in model.node_ids if constrained_components(model, int(n)) and elements_at(model, int(n))]
    out.sort(key=lambda e: -max(node_score.get(n, 0.0) for n in e.nodes))
    return out[: options.max_structural]


def _shortlist(cands: list[Candidate], options: DiagnoseOptions) -> list[Candidate]:
    """The best screened candidates overall and per kind, and every structural one."""
    screened = sorted((c for c in cands if c.family != "structural"), key=lambda c: -c.screen)
    short = screened[: options.shortlist]
    for kind in options.kinds:
        short += [c for c in screened if c.effect.kind == kind][: options.per_kind]
    return list(dict.fromkeys(short)) + [c for c in cands if c.family == "structural"]


def _evidence(short: list[Candidate], base: dict, n_b: int, n_rows: int, sigma2: float, mass: float,
              options: DiagnoseOptions) -> tuple[list[dict], list[Candidate]]:
    """Score (% of the cross-validated error removed), ΔAIC and plausibility of every
    fitted candidate; JSON rows and candidates, best first (warranted ones ahead)."""

    def aic(cost, k):
        return n_rows * np.log(max(cost, 1e-300) / n_rows) + 2 * k

    base_aic = aic(base["cost"], n_b)
    effects = []
    for c in short:
        res = c.result
        values = c.values(res["theta"][n_b:])
        d_aic = aic(res["cost"], n_b + len(c.theta0)) - base_aic
        score = 100 * (1 - res["cv_cost"] / base["cv_cost"]) if base["cv_cost"] > 0 else 0.0  # NaN: not CV'd
        notes = _plausibility(c, values, mass) + ([f"fit failed: {res['error']}"] if "error" in res else [])
        c.effect = eff = replace(c.effect, values=values)
        effects.append({
            "kind": eff.kind, "pids": list(eff.pids), "eids": list(eff.eids), "nodes": list(eff.nodes),
            "where": eff.where(), "parameters": values, "score": float(score), "delta_aic": float(d_aic),
            "screen": float(c.screen) if np.isfinite(c.screen) else None,
            "chi2_per_row": float(res["cost"] / sigma2 / n_rows),
            "heldout_rms_freq_dev_pct_before": _rms(base["heldout_freq_dev"]),
            "heldout_rms_freq_dev_pct_after": _rms(res["heldout_freq_dev"]),
            "rms_freq_dev_pct_after": _rms(res["freq_dev"]),
            "plausible": not notes, "plausibility": notes,
            "warranted": bool(score >= options.min_score and -d_aic >= options.min_delta_aic and not notes),
            "cross_validated": bool(np.isfinite(score)),
        })
    order = sorted(range(len(effects)), key=lambda i: (
        -effects[i]["warranted"], -np.nan_to_num(effects[i]["score"], nan=-np.inf), effects[i]["delta_aic"]))
    for rank, i in enumerate(order, 1):
        effects[i]["rank"] = rank
    return [effects[i] for i in order], [short[i] for i in order]


def _rms(dev) -> float | None:
    dev = np.asarray(dev, float)
    dev = dev[np.isfinite(dev)]
    return float(100 * np.sqrt(np.mean(dev**2))) if dev.size else None


def _verdict(report: dict) -> str:
    b = report["baseline"]
    if report["no_effect_warranted"]:
        return (f"No extra effect is warranted: the baseline predicts held-out modes to "
                f"{b['heldout_rms_freq_dev_pct']:.2f} % RMS and no candidate improves that by enough "
                f"(χ² per row {b['chi2_per_row']:.2f} at the stated noise).")
    e = report["effects"][0]
    vals = ", ".join(f"{k} = {v:.4g}" for k, v in e["parameters"].items())
    return (f"Missing effect: {e['kind']} at {e['where']} ({vals}); held-out RMS frequency error "
            f"{e['heldout_rms_freq_dev_pct_before']:.2f} % → {e['heldout_rms_freq_dev_pct_after']:.2f} %, "
            f"ΔAIC = {e['delta_aic']:.1f}.")


def _plausibility(c: Candidate, values: dict, mass: float) -> list[str]:
    notes = []
    k = c.effect.kind
    if k in ("stiffness", "mass", "frequency_dependent_stiffness"):
        a = values.get("alpha", values.get("beta"))
        if not -0.5 <= a <= 1.0:
            notes.append(f"factor {a:+.2f} outside [-0.5, 1.0]")
    if k == "frequency_dependent_stiffness" and abs(values["a"]) > 0.5:
        notes.append(f"a = {values['a']:.2f} beyond ±0.5")
    if k == "added_mass" and values["m"] > 0.2 * mass:
        notes.append(f"added mass {values['m']:.3g} kg is {100 * values['m'] / mass:.0f} % of the total")
    if k in ("joint", "boundary_spring") and "k_rot" in values and values["k_rot"] > 1e3 * c.ref["k_rot"]:
        notes.append("joint stiffer than 100× its reference: effectively rigid")
    return notes


def _combine(a: dict, b: dict) -> dict:
    """Mean of two indicators, each scaled to a maximum of 1; best first."""
    ta, tb = max(a.values(), default=1.0) or 1.0, max(b.values(), default=1.0) or 1.0
    keys = set(a) | set(b)
    out = {k: 0.5 * (a.get(k, 0.0) / ta + b.get(k, 0.0) / tb) for k in keys}
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def _group_from_screen(cands: list[Candidate]) -> dict[int, float]:
    out: dict[int, float] = {}
    for c in cands:
        if c.effect.kind in ("stiffness", "mass") and not c.effect.eids and c.effect.pids:
            p = c.effect.pids[0]
            out[p] = max(out.get(p, 0.0), c.screen)
    return out


def _node_max(model: Model, elem: dict[int, float]) -> dict[int, float]:
    out = {}
    for node in model.node_ids:
        at = elements_at(model, int(node))
        if at:
            out[int(node)] = max(elem.get(e, 0.0) for e in at)
    return out


def _param_eids(model: Model, p: Parameter) -> np.ndarray:
    return np.union1d(model.element_ids(pids=p.pids) if p.pids else np.zeros(0, np.int64), np.asarray(p.eids, np.int64))


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
        p = eqx.tree_at(lambda q: (q.values, q.parameterisation, q.extension),
                        problem, (jaxfem.partition(m)[0], _identity(problem), None), is_leaf=lambda x: x is None)
        return _flat(jnp.zeros(0), p)

    structure = problem.structure.value
    uk = tuple(jnp.zeros(len(getattr(structure, n).ids)) for n in ("beams", "rods", "springs", "bushes"))
    um = tuple(jnp.zeros(len(getattr(structure, n).ids)) for n in ("beams", "rods", "masses"))
    r = fn(uk, um)
    jk, jm = jax.jacfwd(fn, argnums=(0, 1))(uk, um)
    return r, jnp.concatenate(jk, axis=1), jnp.concatenate(jm, axis=1)


def _identity(problem: Problem) -> Parameterisation:
    return Parameterisation((), (), (), (), ())


def _element_jacobian(problem: Problem, theta):
    """Weighted residual r at θ and its derivative w.r.t. each element's stiffness and mass
    scale (a dormant element: w.r.t. waking it at its reference value)."""
    r, jk, jm = Compiled(_element_jacobian_fn)(jnp.asarray(theta), problem)
    s = problem.structure.value
    k_ids = np.concatenate([getattr(s, n).ids for n in ("beams", "rods", "springs", "bushes")])
    m_ids = np.concatenate([getattr(s, n).ids for n in ("beams", "rods", "masses")])
    return np.asarray(r), np.asarray(jk), np.asarray(jm), k_ids, m_ids


def _structural_candidate(model: Model, eff: Effect) -> Candidate:
    """An effect that changes the model's structure, at its reference values."""
    if eff.kind == "joint":
        side = [e for n in eff.nodes for e in elements_at(model, n)]
        if masters(model).get(eff.nodes[0]) is None:
            side = [e for e, p in elements_at(model, eff.nodes[0]).items() if p in eff.pids[1:]]
        ref = joint_reference(model, eff.nodes, side)
    else:
        side = list(elements_at(model, eff.nodes[0]))
        ref = joint_reference(model, eff.nodes, side)
    before = set(model.element_ids().tolist())
    m = replace(eff, values=ref).apply(model)
    new = sorted(set(m.element_ids().tolist()) - before)
    return Candidate(eff, "structural", extension(m, k_log=new), ref, model=m)


# ---------------------------------------------------------------------------------------
# add the effect and update again


@dataclass
class Confirmation:
    """The update without and with an effect, on the same active/passive split."""

    effect: Effect  # at its updated values
    before: object  # Pairing of the baseline (updated with the engineer's parameters, if any)
    after: UpdateResult
    passive: np.ndarray  # bool per test mode
    report: dict

    def to_json(self) -> dict:
        """The JSON-ready ``report`` (NaN and inf as null)."""
        from ._report import json_safe

        return json_safe(self.report)


def add_effect(model: Model, test: ModalData, effect: Effect, parameters: ParameterSet | None = None, *,
               passive_modes: tuple[int, ...] | None = None,
               progress: Callable[[Iteration], None] | None = None) -> Confirmation:
    """Add ``effect`` and update it with the engineer's parameters, holding
    ``passive_modes`` out of the fit (default: every fourth test mode from the third);
    compare with the update without it. The effect starts from its ``values`` (e.g. as
    fitted by :func:`diagnose`) or, without values, from :func:`at_reference` scaled by
    the best of a coarse scan of log-factors (a joint may be far softer than its reference).

    **Returns:** a :class:`Confirmation`; ``report`` is JSON-ready (per-mode Δf and MAC
    before/after with roles, RMS Δf over active and passive modes, iteration history).
    """
    ne = len(test.frequencies_hz)
    passive = tuple(passive_modes) if passive_modes is not None else tuple(i for i in range(1, ne + 1) if i % 4 == 3)
    base = tuple(parameters.parameters) if parameters else ()
    opts = replace(parameters.options if parameters else Options(), active_modes=None, passive_modes=passive)
    if base:
        before = update(model, test, ParameterSet(base, opts)).after
    else:
        problem = build_problem(model, test, ParameterSet((), opts))
        ev = evaluate(jnp.zeros(0), problem)
        before = pair_modes(np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model),
                            np.asarray(test.frequencies_hz), np.asarray(problem.phi_e),
                            min_mac=problem.min_mac, max_freq_dev=problem.max_freq_dev)
    start = effect if effect.values else start_values(model, test, effect, opts)
    extended = start.apply(model)
    eparams = effect_parameters(start, model, extended)
    after = update(extended, test, ParameterSet(base + eparams, opts), progress=progress)
    alpha = [float(after.alpha[after.names.index(p.name)]) for p in eparams]
    values = dict(start.values)
    if effect.kind in ("stiffness", "mass"):
        key = "alpha" if effect.kind == "stiffness" else "beta"
        values = {key: (1 + values.get(key, 0.0)) * (1 + alpha[0]) - 1}  # factors multiply (eq. 3.1)
    elif effect.kind == "frequency_dependent_stiffness":
        values.update(alpha=(1 + values.get("alpha", 0.0)) * (1 + alpha[0]) - 1, a=values["a"] + alpha[1])
    else:
        values = {k: float(v * (1 + alpha[0])) for k, v in values.items()}
    final = replace(start, values=values)
    is_passive = np.isin(np.arange(1, ne + 1), passive)
    (d0, m0), (d1, m1) = before.per_test(), after.after.per_test()
    f_e = np.asarray(test.frequencies_hz)

    def rms(d, sel):
        return _rms(d[sel] / 100)

    report = {
        "effect": {"kind": final.kind, "pids": list(final.pids), "eids": list(final.eids),
                   "nodes": list(final.nodes), "where": final.where(), "parameters": values},
        "parameters": [{"name": n, "alpha": float(a)} for n, a in zip(after.names, after.alpha)],
        "converged": bool(after.converged), "iterations": int(after.iterations), "seconds": float(after.seconds),
        "passive_modes": list(passive),
        "paired_modes": [{"test": j + 1, "role": "passive" if is_passive[j] else "active", "f_test_hz": float(f_e[j]),
                          "freq_dev_pct_before": json_number(d0[j]), "freq_dev_pct_after": json_number(d1[j]),
                          "mac_before": json_number(m0[j]), "mac_after": json_number(m1[j])} for j in range(ne)],
        "rms_freq_dev_pct_active_before": rms(d0, ~is_passive), "rms_freq_dev_pct_active_after": rms(d1, ~is_passive),
        "rms_freq_dev_pct_passive_before": rms(d0, is_passive), "rms_freq_dev_pct_passive_after": rms(d1, is_passive),
        "mean_mac_passive_before": json_number(np.nanmean(m0[is_passive])) if is_passive.any() else None,
        "mean_mac_passive_after": json_number(np.nanmean(m1[is_passive])) if is_passive.any() else None,
        "history": [h.to_json(after.names, is_passive) for h in after.history],
    }
    return Confirmation(final, before, after, is_passive, report)


def start_values(model: Model, test: ModalData, effect: Effect, opts: Options | None = None) -> Effect:
    """Starting values for updating an effect: :func:`at_reference`, moved to the best point
    of a coarse scan (a joint, support or added mass scaled by a factor of :data:`_SCAN`,
    a frequency law from :data:`_SCAN_LAW`)."""
    start = at_reference(model, effect, test.frequencies_hz)
    opts = opts or Options()
    if start.kind == "frequency_dependent_stiffness":
        extended = start.apply(model)
        ext = extension(extended, k_log=start.elements(model), f_ref=start.values["f_ref_hz"])
        problem = build_problem(extended, test, ParameterSet((), replace(opts, passive_modes=())))
        t = _scan_start(_Fits(), problem, ext, np.zeros(0), _SCAN_LAW)
        return replace(start, values=dict(start.values, alpha=float(np.expm1(t[0])), a=float(np.expm1(t[1]))))
    if start.kind not in ("joint", "boundary_spring", "added_mass"):
        return start
    extended = start.apply(model)
    new = sorted(set(extended.element_ids().tolist()) - set(model.element_ids().tolist()))
    ext = extension(extended, m_log=new) if start.kind == "added_mass" else extension(extended, k_log=new)
    problem = build_problem(extended, test, ParameterSet((), replace(opts, passive_modes=())))
    t = float(_scan_start(_Fits(), problem, ext, np.zeros(0))[0])
    return replace(start, values={k: v * float(np.exp(t)) for k, v in start.values.items()})
