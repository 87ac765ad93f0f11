"""Diagnosis: where the model fails and which physical effect is missing.

1. **Baseline**: the model, updated with the engineer's parameters if any (thesis §3.2).
2. **Localisation** by two independent methods: (a) residual forces of the measured
   modes expanded to the model (Friswell & Mottershead 1995, §8,
   :func:`residual_forces`), standardised by what the shape noise alone leaves there,
   (b) sensitivity — the share ρ of the residual that one Gauss–Newton step in a single
   element's (group's) stiffness or mass removes (ibid. §7). Together they define the
   localised region; the residual forces only where the shapes differ beyond noise (χ²
   per row ≥ ``SHAPE_SIGNAL``), since they are expanded from the shapes alone.
3. **Candidates** of every kind (:mod:`updating._effects`): group factors and laws, an
   added mass and springs to ground at *every* grid of the region, and every joint or
   support in it — all on one model (:func:`~updating._candidates.augment`), so that all
   fits share one compiled solver. They are screened by the linearised residual
   reduction ρ (joints and supports by a coarse scan of their stiffness); per kind those
   within ``within`` of the kind's best are fitted (Optimistix Levenberg–Marquardt), and
   the added mass, spring and payloads at the best-localised grid whatever they screen;
   the best added mass or spring walks to neighbouring grids, also past the region's
   edge (:func:`~updating._candidates.margin`). On
   shells, patches about the region's shell grids (a delamination, a local membrane or
   bending stiffness, distributed mass; radii from a ladder), their centre and radius
   then refined by hill-climbing; a seam likewise walks along its line and in length,
   from the best of the runs of 5, 13 and 34 grids screened there.
4. **Ranking by evidence** (:mod:`updating._evidence`): the Laplace approximation of each
   candidate's marginal likelihood under its kind's prior, posterior probabilities over
   the candidates and the baseline; the most probable ones are cross-validated over the
   test modes (the thesis' active/passive idea made systematic, §4.2.4.2). An effect is
   declared only when it is decisively more probable than the baseline, lowers χ² beyond
   noise and lowers the held-out error in frequencies and in shapes; places of one kind
   the data cannot tell apart are reported as ties.
5. **Damping**, where the test has damping ratios of at least four modes: which region's
   loss factor they ask for beyond Rayleigh damping (:func:`updating.diagnose_damping`,
   the ``damping`` effect), on the modes of the baseline with the declared effect.

Residual rows are weighted by the expected measurement noise (relative frequency σ_f,
relative shape σ_φ per component), so the cost is a χ² and frequencies and shapes weigh
as their accuracies say.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import jax.numpy as jnp
import numpy as np

import jaxfem
from identification import ModalData
from jaxfem import Model

from ._candidates import (
    PATCHES,
    Candidate,
    Screen,
    at_best_grid,
    augment,
    group_candidates,
    group_screens,
    localised_grids,
    margin,
    neighbours,
    node_candidates,
    node_max,
    patch_candidate,
    patch_candidates,
    patch_neighbours,
    pool,
    region_structures,
    seam_neighbours,
    seam_onward,
    shell_grids,
    shortlist,
    structural_candidates,
    with_masks,
)
from ._correlation import comac, pair_modes
from ._damping import MIN_MODES, diagnose_damping
from ._effects import KINDS, AbstractEffect, AbstractPatch, LocalDamping, Seam
from ._eigensolvers import AbstractEigensolver, Direct
from ._engine import Settings
from ._evidence import (
    Fits,
    candidate_fit,
    combine,
    cross_validate,
    evidence,
    fit,
    fold_masks,
    scan_costs,
    scan_start,
    verdict,
    with_extension,
)
from ._extension import extension
from ._localisation import group_scores, residual_forces
from ._parameters import Options, Parameter, ParameterSet
from ._ray import fit_candidates_ray
from ._reduced import Bases
from ._report import json_number, rms_pct
from ._residuals import evaluate
from ._result import Iteration, UpdateResult
from ._solve import build_problem, update
from ._topology import total_mass


SHAPE_SIGNAL = 2.0  # shape χ² per row at the nominal model below which residual forces do not define the region
FULL_MODEL_TOL = 1.0  # χ² by which a candidate's reduced fit may miss its cost on the full model before it is fitted there,
FULL_MODEL_REL = 0.01  # or this share of its χ², if more (the 33k seam's reduced fit missed by 16 of 12,000: 0.13 %)
POINT_WALK = ("added_mass", "boundary_spring")  # the kinds the place walk moves from grid to grid
CLIMB_SHARE = 0.5  # a patch kind or a seam is refined when it takes this share of the best candidate's cost reduction


@dataclass(frozen=True)
class DiagnoseOptions:
    """Settings of :func:`diagnose`.

    ``noise_freq``/``noise_shape``: expected relative σ of measured frequencies and of
    shape components (Table 4.7 magnitudes); ``noise_damping``: of measured damping
    ratios (identified damping scatters by 5–20 %). ``region``: the localised region holds the
    grids of the groups screening at least this share of the best and the grids scoring at
    least this share of the best (at most ``max_nodes`` grids, and as many about it where
    the place walk may move a mass or spring, and ``max_structural`` joints or supports). Fitted: the ``shortlist`` best
    screened candidates, and of each kind those screening at least ``within`` of the
    kind's best (at most ``per_kind``). ``cross_validate``: the most probable candidates
    cross-validated with ``folds`` folds over the test modes. Every fit is the engine's
    Levenberg–Marquardt loop (:mod:`updating._engine`), converged when no factor changes
    by more than ``tolerance`` relative (|Δ ln factor|), at most ``max_steps`` steps.
    ``eigensolver``: as the updating option (``auto``: the parameters' own).
    ``reduce_above``: on a model of at least this many DoFs, the candidates are screened,
    fitted and cross-validated on reduced models (:mod:`updating._reduced`); the most
    probable ones are evaluated on the full model at their fitted θ, and fitted again
    there where the costs differ (:func:`_on_full_model`); the full model's values are
    the ones reported.
    ``ray``: the shortlisted candidates fitted on Ray workers (``"local"``, ``"auto"`` or
    a cluster address, :func:`updating._ray.fit_candidates_ray`; ``ray_workers`` of them,
    default one per CPU); the hill-climb and the cross-validation stay on the driver.
    ``threads``: without Ray, the shortlisted candidates, and the neighbours of each step of
    the hill-climbs, are fitted on this many threads of this process, sharing its compiled
    fit (None: one per CPU, at most ``OMP_NUM_THREADS``; 1: one after another).
    """

    noise_freq: float = 0.002
    noise_shape: float = 0.01
    noise_damping: float = 0.1
    eigensolver: str = "auto"
    folds: int = 4
    region: float = 0.3
    max_nodes: int = 30
    max_structural: int = 4
    shortlist: int = 4
    per_kind: int = 3
    within: float = 0.5
    cross_validate: int = 2
    max_steps: int = 20
    tolerance: float = 1e-3
    kinds: tuple[str, ...] = KINDS
    reduce_above: int = 2000
    ray: str | None = None
    ray_workers: int | None = None
    threads: int | None = None

    @property
    def settings(self) -> Settings:
        return Settings(False, self.tolerance, self.max_steps, self.max_steps, relative=True)


@dataclass
class Diagnosis:
    """Result of :func:`diagnose`: ``report`` is the JSON-ready dict (see the README);
    ``best`` the winning effect (fitted values) or None; ``candidates`` all tried."""

    report: dict
    best: AbstractEffect | None
    candidates: list[Candidate]
    model: Model
    baseline_params: tuple[Parameter, ...]
    element_scores: dict[int, float]
    node_scores: dict[int, float]
    sensor_modes: tuple  # baseline model frequencies (Hz) and shapes at the sensors
    damping: LocalDamping | None = None  # the loss factor the measured damping asks for (diagnose_damping)

    def to_json(self) -> dict:
        """The JSON-ready ``report`` (NaN and inf as null)."""
        from ._report import json_safe

        return json_safe(self.report)


def diagnose(model: Model, test: ModalData, parameters: ParameterSet | None = None, *,
             options: DiagnoseOptions = DiagnoseOptions(),
             progress: Callable[[str], None] | None = None) -> Diagnosis:
    """Compare, localise, rank candidate effects by their posterior probability and declare
    one only when it also predicts held-out modes better (module docstring).

    **Arguments:** the nominal model; measured modes; the engineer's updating parameters
    (the baseline; None = the nominal model as it is); options; ``progress`` receives a
    line per stage. **Returns:** a :class:`Diagnosis`.
    """
    say = progress or (lambda s: None)
    start = time.perf_counter()
    elapsed = lambda: f"{time.perf_counter() - start:.0f} s"  # noqa: E731
    params = tuple(parameters.parameters) if parameters else ()
    n_b = len(params)
    ne, ns = len(test.frequencies_hz), len(test.sensors)
    w_lam = options.noise_shape / (np.sqrt(ns) * 2 * options.noise_freq)  # σ_φ-per-component / σ_λ
    sigma2 = (options.noise_shape / np.sqrt(ns)) ** 2
    # a weak prior (one noise unit at a factor e³ ≈ 20) keeps unidentifiable factors finite
    solver = options.eigensolver if options.eigensolver != "auto" or not parameters else parameters.options.eigensolver
    pset = ParameterSet(params, Options(eigenvalue_weight=w_lam, regularisation=sigma2 / 9, eigensolver=solver,
                                        n_model_modes=parameters.options.n_model_modes if parameters else None))
    masks = fold_masks(ne, options.folds)
    fits = Fits(options.settings)
    f_e = np.asarray(test.frequencies_hz)

    # -- localisation at the nominal model: the region where node-based candidates go
    say("localising the error (residual forces)")
    nominal_problem = build_problem(model, test, pset)
    C = np.asarray(nominal_problem.C)
    elem_b, node_b = residual_forces(model, np.asarray(nominal_problem.lam_e), np.asarray(nominal_problem.phi_e), C)
    say(f"localising the error (sensitivity of every element at the nominal model, {elapsed()})")
    nominal_screen = Screen.at(nominal_problem, np.zeros(n_b), model, params, f_e, kinds=("k", "m"))
    chi2_shape = float(np.sum(nominal_screen.r[ne:] ** 2)) / sigma2 / (ne * ns)  # the rows: eigenvalues, then shapes
    if chi2_shape < SHAPE_SIGNAL:  # the expanded shapes are noise: their residual forces point nowhere
        say(f"residual forces left out of the region: the shapes fit within noise (χ² per row {chi2_shape:.2f})")
    k, m = nominal_screen.element_reduction("k"), nominal_screen.element_reduction("m")
    node_nominal = combine(node_max(model, {e: max(k.get(e, 0.0), m.get(e, 0.0)) for e in k | m}),
                           node_b if chi2_shape >= SHAPE_SIGNAL else {})
    nodes = localised_grids(model, nominal_screen, node_nominal, options.max_nodes, options.region)
    structures = region_structures(model, nodes, node_nominal, options.kinds, options.max_structural)
    mass = total_mass(model)
    beyond = margin(model, nodes, options.max_nodes, node_nominal)
    aug, dormant, stiffened = augment(model, nodes, structures, f_e, beyond)
    beyond = set(beyond)
    problem = build_problem(aug, test, pset)
    say(f"region: {len(nodes)} grids ({len(beyond)} more about it for the place walk), {len(structures)} joints, "
        f"seams or supports{''.join(f'; {e.kind} at {e.where()}' for e in structures)}; one model of {aug.n_dof} DoFs")

    # -- baseline: the engineer's parameters fitted on all modes and on each fold
    say(f"baseline fit ({n_b} parameters, {len(masks) - 1}-fold cross-validation over {ne} modes)")
    none = extension(aug)
    base = fit(fits, problem, none, np.zeros(n_b + 1), skip=n_b == 0)  # nothing to fit without parameters
    bases = Bases(with_extension(problem, none), base["theta"]) if aug.n_dof >= options.reduce_above else None
    if bases is not None:
        say(f"reduced models for the candidates: {bases.common.shape[1]} baseline columns "
            f"(modes and static corrections), {elapsed()}")

    def solver(c: Candidate | None) -> AbstractEigensolver:
        """The eigensolver of a candidate's fits (None: the baseline's)."""
        if bases is None or (c is not None and c.family == "visco"):
            return Direct()
        if c is None:
            return bases.reduced(problem, none, np.zeros(1))
        if c.solver is None:
            c.solver = bases.reduced(problem, c.ext, np.zeros(c.ext.n_params), held=c.released is not None)
        return c.solver

    cross_validate(fits, problem, none, base, masks, solver(None))
    theta_b = base["theta"][:n_b]

    # -- screening at the baseline: every element's stiffness and mass (the Jacobian), the
    # joints and supports by a scan of their stiffness
    say(f"screening (sensitivity of every element) ({elapsed()})")
    patches = [cls.kind for cls, _ in PATCHES if cls.kind in options.kinds] if shell_grids(model, nodes) else []
    screen = Screen.at(problem, base["theta"], model, params, f_e,
                       kinds=("k", "m") + (("membrane", "bending", "shear", "nsm") if patches else ()),
                       modes=bases.modes if bases is not None else None)
    elem_a = screen.element_reduction("k")
    node_a = node_max(aug, elem_a)
    points = node_candidates(aug, dormant, screen)
    walk = [c.reference.kind in POINT_WALK and c.reference.nodes[0] in beyond for c in points]
    walk_only = [c for c, w in zip(points, walk) if w and c.effect.kind in options.kinds]
    cands = group_candidates(model, aug, params, screen) + [c for c, w in zip(points, walk) if not w]
    kinds = options.kinds
    if jaxfem.use_sparse(aug, problem.solver) and "frequency_dependent_stiffness" in kinds:
        say("frequency laws are not offered: they need the dense eigensolver")
        kinds = tuple(k for k in kinds if k != "frequency_dependent_stiffness")
    cands = [c for c in cands if c.effect.kind in kinds] + patch_candidates(model, nodes, screen, patches)
    structural = structural_candidates(aug, stiffened)
    if bases is not None:  # the joints can only push other candidates off the shortlist
        bases.pool = pool(aug, shortlist(cands, options.shortlist, options.per_kind, kinds, options.within),
                          dormant, stiffened)
        say(f"reduced fits assemble {len(bases.pool)} elements at each step")
    scans = {c: (list(c.scan), list(scan_costs(fits, problem, c.ext, theta_b, c.scan, solver(c)))) for c in structural}
    for c in sorted(structural, key=lambda c: min(scans[c][1]))[:2]:  # the best two: each factor alone too
        grid, costs = scans[c]
        if c.ext.split and min(costs) < base["cost"]:
            t, r = grid[int(np.argmin(costs))]
            more = [(t + d, r) for d in (-3.0, -1.5, 1.5)] + [(t, r + d) for d in (-3.0, -1.5, 1.5)]
            scans[c] = grid + more, costs + list(scan_costs(fits, problem, c.ext, theta_b, more, solver(c)))
    for c in structural:
        grid, costs = scans[c]
        c.screen, c.theta0 = 1 - float(np.min(costs)) / base["cost"], np.atleast_1d(grid[int(np.argmin(costs))])
        cands.append(c)
    node_score = combine(node_a, node_b)
    short = list(dict.fromkeys(shortlist(cands, options.shortlist, options.per_kind, kinds, options.within)
                               + at_best_grid(cands, nodes, node_nominal)))
    with_masks(short, aug)
    say(f"{len(cands)} candidates screened; fitting {len(short)} ({elapsed()})")

    def fitted(more: list[Candidate]) -> None:
        """Each candidate fitted from its ``theta0`` (``result``): the reduced bases made one
        after another, the fits on threads (:func:`_threaded`) sharing the compiled fit."""
        def one(job: tuple[int, Candidate]) -> dict:
            i, c = job
            say(f"  fitting {i}/{len(more)}: {c.reference.kind} {c.reference.where()} ({elapsed()})")
            return fit(fits, problem, c.ext, np.concatenate([theta_b, c.theta0]), solver(c))

        for c in more:
            solver(c)
        for c, result in zip(more, _threaded(one, list(enumerate(more, 1)), options.threads)):
            c.result = result

    # each from the better of the linearised step and none (the joints' scans are done)
    order = sorted(short, key=lambda c: c.family)
    jobs = [(i, c.ext, theta_b, c.scan if c not in structural else None, c.theta0, solver(c))
            for i, c in enumerate(order)]
    if options.ray:
        say(f"  on Ray ({options.ray}): {len(jobs)} candidates")
        done = fit_candidates_ray(problem, options.settings, jobs, address=options.ray, workers=options.ray_workers)
    else:
        done = _threaded(lambda job: (job, candidate_fit(fits, problem, *job[1:])), jobs, options.threads)
    for k, (job, (theta0, result)) in enumerate(done, 1):
        c = order[job[0]]
        c.theta0, c.result = theta0, result
        say(f"  fitted {k}/{len(order)}: {c.reference.kind} {c.reference.where()} ({elapsed()})")

    # -- the place refined: an added mass or spring moves to a neighbouring grid while that fits better
    for c0, c1 in _refine_places(fitted, solver, fits, problem, aug, cands + walk_only, short, base, theta_b):
        say(f"  {c1.reference.kind} moved from grid {c0.reference.nodes[0]} to {c1.reference.nodes[0]} ({elapsed()})")
    for c0, c1 in _refine_patches(fitted, model, aug, short, base, f_e) + _refine_seams(fitted, aug, short, base):
        say(f"  {c1.reference.kind} moved from {c0.reference.where()} to {c1.reference.where()} ({elapsed()})")

    # -- evidence; the most probable candidates checked on the full model and cross-validated
    n_rows = (ne, ne * ns)
    _, ranked, _ = evidence(short, base, n_b, n_rows, sigma2, mass)
    top = [c for c in ranked if np.isfinite(c.result["cost"])][:options.cross_validate]
    for c in cands + short:  # the others' reduced bases freed (n × r each, 50 MB at 33,000 DoFs; 24 GB filled)
        if c not in top:
            c.solver = None
    if bases is not None:
        say(f"checking the {len(top)} most probable on the full model ({elapsed()})")
        for c in top:
            c.result = _on_full_model(fits, problem, c, sigma2, say)
    say(f"cross-validating the {len(top)} most probable ({len(masks) - 1} folds, {elapsed()})")
    for c in top:
        cross_validate(fits, problem, c.ext, c.result, masks, solver(c))
    effects, ranked, summary = evidence(short, base, n_b, n_rows, sigma2, mass)
    best = ranked[0].effect if summary["outcome"] == "effect" else None

    # -- comparison at the baseline
    ev = evaluate(jnp.asarray(base["theta"]), problem)
    pairing = pair_modes(np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model), f_e,
                         np.asarray(problem.phi_e), min_mac=problem.min_mac, max_freq_dev=problem.max_freq_dev)
    compared = pairing.summary()
    co = np.asarray(comac(np.asarray(ev.phi_model)[:, pairing.model], np.asarray(problem.phi_e)[:, pairing.test]))
    group_b = group_scores(elem_b, model)
    group_a = group_screens(cands)
    groups = combine(group_a, group_b)
    chi2 = lambda cost: float(cost / sigma2 / sum(n_rows))  # noqa: E731
    report = {
        "paired_modes": compared["paired_modes"],
        "unpaired_test": compared["unpaired_test"],
        "unpaired_model": compared["unpaired_model"][:10],
        "baseline": {"parameters": [{"name": p.name, "alpha": float(np.expm1(t))} for p, t in zip(params, theta_b)],
                     "rms_freq_dev_pct": rms_pct(base["freq_dev"]), "mean_mac": float(np.nanmean(base["mac"])),
                     "heldout_rms_freq_dev_pct": rms_pct(base["heldout_freq_dev"]),
                     "heldout_mean_mac": float(np.nanmean(base["heldout_mac"])),
                     "chi2_per_row": chi2(base["cost"]), "chi2_per_row_freq": chi2(base["cost_freq"]) * sum(n_rows) / ne,
                     "chi2_per_row_shape": chi2(base["cost_shape"]) * sum(n_rows) / (ne * ns)},
        "sensors": [{"label": lab, "comac": float(v)} for lab, v in zip(test.sensors.labels, co)],
        "localisation": {
            "groups": [{"pid": p, "score": s, "sensitivity": group_a.get(p, 0.0), "residual_force": group_b.get(p, 0.0)}
                       for p, s in groups.items()],
            "nodes": [{"node": n, "score": s, "sensitivity": node_a.get(n, 0.0), "residual_force": node_b.get(n, 0.0)}
                      for n, s in list(node_score.items())[:30]],
            "region": nodes,
        },
        "effects": effects,
        **summary,
        "no_effect_warranted": best is None,
        "candidates_evaluated": len(cands),
        "candidates_fitted": len(short),
        "noise": {"freq_pct": 100 * options.noise_freq, "shape_pct": 100 * options.noise_shape},
    }
    report["verdict"] = verdict(report)
    damping = None
    if LocalDamping.kind in options.kinds and np.sum(np.asarray(test.damping_ratios) > 0) >= MIN_MODES:
        at = nominal_problem.model(jnp.asarray(theta_b))  # the baseline, with the structural effect if one was found
        damped = diagnose_damping(at if best is None else best.apply(at), test, noise=options.noise_damping,
                                  folds=options.folds, min_mac=problem.min_mac,
                                  max_freq_dev=problem.max_freq_dev, progress=say)
        damping, report["damping"] = damped.effect, damped.report
        report["verdict"] += " Damping: " + damped.report["verdict"]
    report["seconds"] = time.perf_counter() - start
    say(f"diagnosis done in {report['seconds']:.1f} s")
    return Diagnosis(report, best, ranked, model, params, combine(
        {e: v for e, v in elem_a.items() if e in set(model.element_ids().tolist())}, elem_b), node_score,
        (np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model)), damping)


def _on_full_model(fits: Fits, problem, c: Candidate, sigma2: float, say) -> dict:
    """A candidate's reduced fit evaluated on the full model at its θ (costs, Jacobian);
    fitted again there only where the two costs differ by more than :data:`FULL_MODEL_TOL`
    in χ² or, if more, :data:`FULL_MODEL_REL` of the candidate's χ² (a reduced basis
    that misses the effect: a heavy mass's own mode; a gap far below the misfit the
    candidate leaves itself moves neither its place nor the verdict). At 33,000 DoFs a
    refit takes 140–340 s a seam."""
    check = fit(fits, problem, c.ext, c.result["theta"], skip=True)
    gap = abs(check["cost"] - c.result["cost"]) / sigma2
    if gap <= max(FULL_MODEL_TOL, FULL_MODEL_REL * check["cost"] / sigma2):
        return check
    say(f"  {c.reference.kind} {c.reference.where()}: the reduced fit is off by χ² {gap:.3g}; fitted again")
    return fit(fits, problem, c.ext, c.result["theta"])


def _threaded(fn, jobs: list, threads: int | None):
    """``fn(job)`` of each job, in order, on ``threads`` threads (None: one per CPU this
    process may use, at most ``OMP_NUM_THREADS`` where that is set: a process given one
    thread, as a test worker beside others is, fits one candidate at a time). The fits
    share one compiled solver."""
    if threads is None:
        threads = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        budget = os.environ.get("OMP_NUM_THREADS", "")
        threads = min(threads, int(budget)) if budget.isdigit() and int(budget) > 0 else threads
    if threads <= 1 or len(jobs) <= 1:
        yield from map(fn, jobs)
        return
    with ThreadPoolExecutor(threads) as pool:
        yield from pool.map(fn, jobs)


def _climb(best: Candidate, fitted_neighbours, onward=None) -> list[tuple[Candidate, Candidate]]:
    """Move from ``best`` to its best-fitting neighbour while that fits better;
    ``fitted_neighbours(c)``: the neighbours of ``c`` to compare, fitted; ``onward(a, b)``:
    the move a → b made once more, fitted (None where it cannot be), tried first after
    each move (a seam growing grid by grid takes one fit a step, not six). The moves made."""
    moves = []
    while True:
        ahead = onward(*moves[-1]) if moves and onward is not None else None
        if ahead is not None and ahead.result["cost"] < best.result["cost"]:
            moves.append((best, ahead))
            best = ahead
            continue
        step = min(fitted_neighbours(best), key=lambda c: c.result["cost"], default=best)
        if step.result["cost"] >= best.result["cost"]:
            return moves
        moves.append((best, step))
        best = step


def _refine_places(fitted, solver, fits: Fits, problem, aug: Model, cands: list[Candidate], short: list[Candidate],
                   base: dict, theta_b: np.ndarray) -> list[tuple[Candidate, Candidate]]:
    """Hill-climb over the grids: the best fitted added mass (spring to ground) is fitted
    (``fitted(candidates)``, each from its θ₀) at the neighbouring grids of the region, and moves
    while one fits better (the linearised screen hardly separates neighbours). Fitted
    candidates join ``short``; returns the moves made."""
    at_grid = {(c.reference.kind, c.reference.nodes): c for c in cands if c.family == "mask"
               and c.reference.kind in POINT_WALK and not c.ext.split}

    def fitted_neighbours(best: Candidate) -> list[Candidate]:
        kind = best.reference.kind
        new = [at_grid[kind, (g,)] for g in neighbours(aug, best.reference.nodes[0])
               if (kind, (g,)) in at_grid and at_grid[kind, (g,)] not in short]
        for c in new:
            c.theta0 = scan_start(fits, problem, c.ext, theta_b, c.scan, solver(c))
        fitted(new)
        short.extend(new)
        return new

    moves = []
    for kind in POINT_WALK:
        tried = [c for c in short if c.reference.kind == kind and (kind, c.reference.nodes) in at_grid]
        best = min(tried, key=lambda c: c.result["cost"], default=None)
        if best is not None and best.result["cost"] < base["cost"]:
            moves += _climb(best, fitted_neighbours)
    return moves


def _refine_patches(fitted, model: Model, aug: Model, short: list[Candidate], base: dict,
                    f_e) -> list[tuple[Candidate, Candidate]]:
    """Hill-climb of the two best patch kinds (kind and part) that fit better than the
    baseline and take at least half the cost reduction of the best candidate of any kind
    (a patch far behind a mass or a joint is not refined: on the 33k barrel each climb
    costs tens of fits): the best fitted patch is fitted about each neighbouring shell grid
    and with the next radius up and down the ladder, and moves while one fits better
    (centre refined between neighbours, radius chosen by the data). Fits join ``short``."""
    def key(e):
        return e.kind, getattr(e, "part", ""), e.nodes, round(e.radius, 9)

    mass = total_mass(model)
    done = {key(c.reference): c for c in short if isinstance(c.reference, AbstractPatch)}

    def fitted_neighbours(best: Candidate) -> list[Candidate]:
        near = patch_neighbours(model, best, f_e)
        new = {key(p): patch_candidate(p, model, None, f_e, mass) for p in near if key(p) not in done}
        with_masks(list(new.values()), aug)
        theta = best.result["theta"]
        for c in new.values():
            c.theta0 = theta[len(theta) - len(c.theta0):]
        fitted(list(new.values()))
        done.update(new)
        short.extend(new.values())
        return [done[key(p)] for p in near]

    bar = _climb_bar(short, base)
    best_of: dict = {}
    for c in done.values():
        k = key(c.reference)[:2]
        if c.result["cost"] < bar and (k not in best_of or c.result["cost"] < best_of[k].result["cost"]):
            best_of[k] = c
    return [m for best in sorted(best_of.values(), key=lambda c: c.result["cost"])[:2]
            for m in _climb(best, fitted_neighbours)]


def _refine_seams(fitted, aug: Model, short: list[Candidate], base: dict) -> list[tuple[Candidate, Candidate]]:
    """Hill-climb of the best fitted seam that takes at least half the cost reduction of
    the best candidate (as a patch, :func:`_refine_patches`) on its released line
    (:meth:`~updating._effects.Seam.neighbours`): first in coarse moves (half its length
    along, each end or both a quarter of it out or in, the length ladder), then in fine ones (one
    grid along, each end out or in), the last move made once more first, the neighbours
    fitted, moving while one fits better. Fits join ``short``."""
    def key(c: Candidate):
        return c.reference.pids, c.reference.nodes

    done = {key(c): c for c in short if c.reference.kind == Seam.kind and c.released is not None}

    def known(near: list[Candidate]) -> list[Candidate]:
        new = {key(c): c for c in near if key(c) not in done}
        fitted(list(new.values()))
        done.update(new)
        short.extend(new.values())
        return [done[key(c)] for c in near]

    def fitted_neighbours(best: Candidate, coarse: bool) -> list[Candidate]:
        return known(seam_neighbours(aug, best, coarse))

    def onward(a: Candidate, b: Candidate) -> Candidate | None:
        ahead = seam_onward(aug, a, b)
        return None if ahead is None else known([ahead])[0]

    bar = _climb_bar(short, base)
    best = min((c for c in done.values() if c.result["cost"] < bar), key=lambda c: c.result["cost"], default=None)
    if best is None:
        return []
    moves = _climb(best, lambda c: fitted_neighbours(c, coarse=True), onward)
    return moves + _climb(moves[-1][1] if moves else best, lambda c: fitted_neighbours(c, coarse=False), onward)


def _climb_bar(short: list[Candidate], base: dict) -> float:
    """The cost a candidate must fit below to be refined: :data:`CLIMB_SHARE` of the best
    candidate's cost reduction."""
    best = min((c.result["cost"] for c in short if np.isfinite(c.result["cost"])), default=base["cost"])
    return base["cost"] - CLIMB_SHARE * (base["cost"] - best)


# ---------------------------------------------------------------------------------------
# add the effect and update again


@dataclass
class Confirmation:
    """The update without and with an effect, on the same active/passive split."""

    effect: AbstractEffect  # at its updated values
    before: object  # Pairing of the baseline (updated with the engineer's parameters, if any)
    after: UpdateResult
    passive: np.ndarray  # bool per test mode
    report: dict

    def to_json(self) -> dict:
        """The JSON-ready ``report`` (NaN and inf as null)."""
        from ._report import json_safe

        return json_safe(self.report)


def add_effect(model: Model, test: ModalData, effect: AbstractEffect, parameters: ParameterSet | None = None, *,
               passive_modes: tuple[int, ...] | None = None,
               progress: Callable[[Iteration], None] | None = None, noise_freq: float = 0.002) -> Confirmation:
    """Add ``effect`` and update it with the engineer's parameters, holding
    ``passive_modes`` out of the fit (default: every fourth test mode from the third);
    compare with the update without it. The effect starts from its ``values`` (e.g. as
    fitted by :func:`diagnose`) or, without values, from :func:`start_values`. Its
    parameters (``effect.parameters``) are updated with the engineer's and the fitted
    log-factors give its final values (``effect.updated``).

    **Returns:** a :class:`Confirmation`; ``report`` is JSON-ready (per-mode Δf and MAC
    before/after with roles, RMS Δf over active and passive modes, iteration history, and
    ``worse``: the modes whose |Δf| grew by more than 2σ of the frequency noise
    ``noise_freq``, relative).
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
    eparams = start.parameters(model, extended)
    after = update(extended, test, ParameterSet(base + eparams, opts), progress=progress)
    final = start.updated(np.array([after.theta[after.names.index(p.name)] for p in eparams]))
    is_passive = np.isin(np.arange(1, ne + 1), passive)
    (d0, m0), (d1, m1) = before.per_test(), after.after.per_test()
    f_e = np.asarray(test.frequencies_hz)

    def rms(d, sel):
        return rms_pct(d[sel] / 100)

    report = {
        "effect": final.to_json(),
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
    grew = np.abs(d1) - np.abs(d0) > 2 * 100 * noise_freq  # NaN (unpaired before or after): not compared
    report["worse"] = [r for r, g in zip(report["paired_modes"], grew) if g]
    return Confirmation(final, before, after, is_passive, report)


def start_values(model: Model, test: ModalData, effect: AbstractEffect, opts: Options | None = None) -> AbstractEffect:
    """Starting values for updating an effect: ``effect.at_reference``, moved to the best
    point of the coarse grid of log-factors ``effect.scan`` (a joint, support or added
    mass scaled, a frequency law's factor and coefficient changed; None: no scan)."""
    start = effect.at_reference(model, test.frequencies_hz)
    if start.scan is None:
        return start
    extended = start.apply(model)
    problem = build_problem(extended, test, ParameterSet((), replace(opts or Options(), passive_modes=())))
    return start.updated(scan_start(Fits(DiagnoseOptions().settings), problem, start.extension(model, extended), np.zeros(0), start.scan))
