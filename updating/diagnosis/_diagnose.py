"""Diagnosis: where the model fails and which physical effect is missing.

1. **Baseline**: the model, updated with the engineer's parameters if any (thesis §3.2).
2. **Localisation** by two independent methods: (a) residual forces of the measured
   modes expanded to the model (Friswell & Mottershead 1995, §8,
   :func:`residual_forces`), standardised by what the shape noise alone leaves there,
   (b) sensitivity — the share ρ of the residual that one Gauss–Newton step in a single
   element's (group's) stiffness or mass removes (ibid. §7). Together they define the
   localised region; the residual forces only where the shapes differ beyond noise (χ²
   per row ≥ ``SHAPE_SIGNAL``), since they are expanded from the shapes alone.
3. **Candidates** of every kind (:mod:`._effects`): group factors and laws, an
   added mass and springs to ground at *every* grid of the region, and every joint or
   support in it — all on one model (:func:`~._candidates.augment`), so that all
   fits share one compiled solver. They are screened by the linearised residual
   reduction ρ (joints and supports by a coarse scan of their stiffness); per kind those
   within ``within`` of the kind's best are fitted (Optimistix Levenberg–Marquardt), and
   the added mass, spring and payloads at the best-localised grid whatever they screen;
   the best added mass or spring walks to neighbouring grids, also past the region's
   edge (:func:`~._candidates.margin`). On
   shells, patches about the region's shell grids (a delamination, a local membrane or
   bending stiffness, distributed mass; radii from a ladder), their centre and radius
   then refined by hill-climbing; a seam likewise walks along its line and in length,
   from the best of the runs of 5, 13 and 34 grids screened there.
4. **Ranking by evidence** (:mod:`._evidence`): the Laplace approximation of each
   candidate's marginal likelihood under its kind's prior, posterior probabilities over
   the candidates and the baseline; the most probable ones are cross-validated over the
   test modes (the thesis' active/passive idea made systematic, §4.2.4.2). An effect is
   declared only when, at the stated noise, it is decisively more probable than the
   baseline, lowers χ² and the held-out error in frequencies and shapes beyond noise and
   makes no held-out mode worse (:func:`~._evidence.evidence`); places of one kind the
   data cannot tell apart are reported as ties.
5. **Damping**, where the test has damping ratios of at least four modes: which region's
   loss factor they ask for beyond uniform damping (:func:`updating.diagnose_damping`,
   the ``damping`` effect), on the model with the declared effects.
6. **Confirmation and rounds**: the winner is added and updated with passive modes held
   out (:func:`_confirm`, withdrawn where a passive mode grows worse or the update
   fails); while what it leaves is not noise, the search runs again on that model, every
   declared effect re-fitted with the engineer's parameters; the set is checked against
   the first baseline (:func:`_final_check`) and the verdict's state derived from the
   numbers (:mod:`._verdict`).

Residual rows are weighted by the expected measurement noise (relative frequency σ_f,
relative shape σ_φ per component), so the cost is a χ² and frequencies and shapes weigh
as their accuracies say.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import jax.numpy as jnp
import numpy as np

from identification import ModalData, comac, rms_pct
from jaxfem import Model

from .. import (
    AbstractEigensolver,
    Direct,
    Options,
    ParameterSet,
    ProgressFn,
    build_problem,
    eigensolver_name,
    evaluate,
    evaluation_pairing,
    extension,
    progress_lines,
    sensor_modes,
)
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
    node_candidates,
    node_max,
    patch_candidates,
    pool,
    region_structures,
    shell_grids,
    shortlist,
    structural_candidates,
    with_masks,
)
from ._damping import MIN_MODES, diagnose_damping
from ._diagnosis import Diagnosis, Localisation
from ._effects import LocalDamping
from ._evidence import combine, evidence, remainder, worse_modes
from ._fit import (Fit, Fits, candidate_fit, cross_validate, failure_reason, fit, fold_masks, scan_costs, soft_fits,
                   threaded, with_extension)
from ._localisation import group_scores, residual_forces
from ._options import DiagnoseOptions
from ._ray_fits import fit_candidates_ray
from ._reduced import Bases
from ._refine import POINT_WALK, refine_directions, refine_patches, refine_places, refine_seams
from ._topology import total_mass
from ._confirm import confirm_on_fit, free_parameters
from ._verdict import Baseline, Declared, Withdrawn, state, verdict

SHAPE_SIGNAL = 2.0  # shape χ² per row at the nominal model below which residual forces do not define the region
FLAT_CHI2 = 0.01  # a fit has converged where its Gauss–Newton step would lower χ² by less (a flat valley)
FULL_MODEL_TOL = 1.0  # χ² by which a candidate's reduced fit may miss its cost on the full model before it is fitted there,
FULL_MODEL_REL = 0.01  # or this share of its χ², if more (the 33k seam's reduced fit missed by 16 of 12,000: 0.13 %)


@dataclass
class _Run:
    """The working state of one diagnosis (not a result): the stated noise, the shared
    model and problem, the compiled fit, each candidate's eigensolver, progress."""

    options: DiagnoseOptions
    params: tuple
    start: float
    sigma2: float
    fits: Fits
    problem: object = None
    none: object = None  # the extension without a candidate
    bases: Bases | None = None
    solvers: dict | None = None
    mass: float = 0.0  # of the nominal model (the effects' plausibility)
    progress: ProgressFn | None = None

    @property
    def say(self) -> Callable[[str], None]:
        """A line of progress (:class:`updating.Progress`)."""
        return progress_lines(self.progress)

    def elapsed(self) -> str:
        return f"{time.perf_counter() - self.start:.0f} s"

    def solver(self, c: Candidate | None) -> AbstractEigensolver:
        """The eigensolver of a candidate's fits (None: the baseline's), made once."""
        if self.bases is None or (c is not None and c.family == "visco"):
            return Direct()
        if c is None:
            return self.bases.reduced(self.problem, self.none, np.zeros(1))
        if c not in self.solvers:
            self.solvers[c] = self.bases.reduced(self.problem, c.ext, np.zeros(c.ext.n_params),
                                                 held=c.released is not None)
        return self.solvers[c]


def diagnose(model: Model, test: ModalData, parameters: ParameterSet | None = None, *,
             options: DiagnoseOptions = DiagnoseOptions(),
             progress: ProgressFn | None = None) -> Diagnosis:
    """Compare, localise, rank candidate effects by their posterior probability, declare one
    only when it also predicts held-out modes better and its confirming update worsens no
    passive mode; then search again on the model with it, all declared effects re-fitted
    with the engineer's parameters, until the remainder is noise or no candidate passes
    (module docstring, step 6).

    **Arguments:** the nominal model; measured modes; the engineer's updating parameters
    (the baseline; None = the nominal model as it is); options; ``progress`` (:class:`updating.Progress`) a line per
    stage. **Returns:** a :class:`Diagnosis`.
    """
    params = tuple(parameters.parameters) if parameters else ()
    opts = parameters.options if parameters else Options()
    start = time.perf_counter()
    rows_ = (len(test.frequencies_hz), len(test.frequencies_hz) * len(test.sensors))
    declared: list[Declared] = []
    withdrawn, rounds, at, p, final = None, [], model, params, None
    for k in range(1, options.rounds + 1):
        rounds.append(_round(at, test, p, opts, options, progress, start, k))
        r = rounds[-1]
        final = r.base, r.base_held
        if r.ranking.outcome != "effect":
            break
        top, c = r.ranking.results[0], r.ranking.candidates[0]
        left = remainder(c.fit, r.run.sigma2, options.noise.frequency, rows_)
        confirmation, reason = _confirm(r, c, test, top, judged=left.noise_like)
        if reason is not None:
            withdrawn = Withdrawn(top, reason)
            r.run.say(f"{top.effect.kind} at {top.effect.where()} withdrawn: {reason}")
            break
        declared.append(Declared(k, top, confirmation))
        final = c.fit, c.heldout
        if left.noise_like or k == options.rounds:
            break
        at, p = _with_effect(at, p, declared[-1], k)
        r.run.say(f"round {k + 1}: searching again on the model with {len(declared)} effect(s), re-fitted together")
    reason = _final_check(rounds[0], final[1], declared, options.noise.frequency)
    if reason is not None:  # the set worsens a mode: the last effect goes, the state is the one before it
        withdrawn = Withdrawn(declared.pop().result, reason)
        final = rounds[len(declared)].base, rounds[len(declared)].base_held  # the round fitting those left
    return _result(rounds, tuple(declared), withdrawn, model, test, start, final[0])


def _final_check(first: _Round, heldout, declared: list[Declared], freq_sd: float) -> str | None:
    """The declared effects as a set against the first baseline: the reason to withdraw
    the last when a held-out mode (cross-validated with all of them) or a passive mode of
    the confirming updates is worse by more than 2σ of the frequency noise; None when none is."""
    if not declared:
        return None
    held = worse_modes(first.base_held.freq_dev, heldout.freq_dev, freq_sd) if heldout is not None else ()
    c0, c1 = declared[0].confirmation, declared[-1].confirmation
    passive = ()
    if c0 is not None and c1 is not None:
        d0, d1 = c0.before.per_test()[0], c1.after.after.per_test()[0]
        passive = tuple(j for j in worse_modes(d0 / 100, d1 / 100, freq_sd) if c1.passive[j - 1])
    if not held and not passive:
        return None
    what = [f"held-out mode {', '.join(map(str, held))}"] if held else []
    what += [f"passive mode {', '.join(map(str, passive))} of the confirming update"] if passive else []
    return (f"with the {len(declared)} declared effect(s) together, {' and '.join(what)} grew worse than the "
            "baseline by more than 2σ of the frequency noise")


def _round(model: Model, test: ModalData, params: tuple, opts: Options, options: DiagnoseOptions,
           progress: ProgressFn | None, start: float, k: int) -> _Round:
    """One round: localise, fit the baseline, screen, fit and rank the candidates (steps 1–4)."""
    ne, ns = len(test.frequencies_hz), len(test.sensors)
    w_lam = options.noise.relative / (np.sqrt(ns) * options.noise.eigenvalue)  # σ_φ-per-component / σ_λ
    sigma2 = (options.noise.relative / np.sqrt(ns)) ** 2
    # a weak prior (one noise unit at a factor e³ ≈ 20) keeps unidentifiable factors finite
    solver = eigensolver_name(options.eigensolver, ParameterSet(params, opts) if params else None)
    pset = ParameterSet(params, Options(eigenvalue_weight=w_lam, regularisation=sigma2 / 9, eigensolver=solver,
                                        n_model_modes=opts.n_model_modes))
    settings = replace(options.settings, cost_tolerance=float(FLAT_CHI2 / 2 * sigma2))  # engine cost ½Σr², χ² = Σr²/σ²
    run = _Run(options, params, start, sigma2, Fits(settings), solvers={},
               mass=total_mass(model), progress=progress)
    if k > 1:
        run.say(f"round {k}")
    f_e = np.asarray(test.frequencies_hz)
    where = _localise(run, model, test, pset, f_e)
    base, base_held, masks = _baseline(run, where.aug, ne)
    cands, walk_only, structural, screen_k = _candidates(run, model, where, base, f_e, soft=k > 1)
    short = list(dict.fromkeys(shortlist(cands, options.shortlist, options.per_kind, where.kinds, options.within)
                               + at_best_grid(cands, where.nodes, where.node_nominal)))
    with_masks(short, where.aug)
    run.say(f"{len(cands)} candidates screened; fitting {len(short)} ({run.elapsed()})")
    _fit_shortlist(run, short, structural, base, model, where, cands + walk_only, f_e)
    ranking = _rank(run, short, cands, base, base_held, masks, (ne, ne * ns))
    return _Round(run, model, where, base, base_held, ranking, cands, short, screen_k)


def _confirm(r: _Round, c: Candidate, test: ModalData, top, judged: bool = True):
    """The winner added and updated with the engineer's parameters, passive modes held out,
    on the round's compiled fit (:func:`confirm_on_fit`): ``(confirmation, None)``, or
    the reason it is withdrawn — an update that fails (a law or value making K + σM
    indefinite) or, where the winner's remainder is noise (``judged``; else the final set
    is judged, :func:`_final_check`), a passive mode worse beyond 2σ of the frequency noise."""
    run = r.run
    if not run.options.confirm:
        return None, None
    e, n_b = top.effect, len(run.params)
    run.say(f"confirming {e.kind} at {e.where()}: updated with it, passive modes held out ({run.elapsed()})")
    try:
        conf = confirm_on_fit(run.fits, run.problem, run.none, c.ext, c.reference, c.fit.theta[n_b:], run.params,
                              lambda t: r.where.nominal_problem.model(jnp.asarray(t)), test, run.options.noise)
    except (ValueError, RuntimeError, FloatingPointError) as err:
        return None, f"its confirming update failed ({failure_reason(err)[:200]})"
    if conf.passive_worse and judged:
        return conf, ("its confirming update made passive mode " + ", ".join(
            f"{m.test} ({m.freq_dev_pct_before:+.2f} % → {m.freq_dev_pct_after:+.2f} %)" for m in conf.passive_worse)
            + " worse beyond 2σ of the frequency noise")
    return conf, None


def _with_effect(model: Model, params: tuple, declared: Declared, k: int) -> tuple[Model, tuple]:
    """The model with a declared effect — as its confirming update left it (the engineer's
    factors and the effect's values updated), else at the ranking's values — and the
    engineer's parameters with the effect's own (named for its round), to be re-fitted
    together in the next round from there."""
    extended = declared.effect.apply(model)
    own = free_parameters(declared.effect.parameters(model, extended), params)
    params = params + tuple(replace(q, name=f"{q.name}_{k}") for q in own)
    return (declared.confirmation.after.model if declared.confirmation is not None else extended), params


@dataclass
class _Round:
    """One round's working results (not a result): its run, model, localisation, baseline
    fit and cross-validation, ranking, candidates, shortlist, each element's screen."""

    run: _Run
    model: Model
    where: object
    base: Fit
    base_held: object
    ranking: object
    cands: list
    short: list
    screen_k: dict


@dataclass
class _Where:
    """The localisation at the nominal model and the shared model of all candidates."""

    nominal_problem: object
    elem_b: dict
    node_b: dict
    node_nominal: dict
    nodes: list
    aug: Model
    dormant: object
    stiffened: list
    beyond: set
    kinds: tuple


def _localise(run: _Run, model: Model, test: ModalData, pset: ParameterSet, f_e) -> _Where:
    """Residual forces and every element's sensitivity at the nominal model: the region where
    node-based candidates go; the one model holding every candidate (step 2)."""
    options, say = run.options, run.say
    ne, ns = len(f_e), len(test.sensors)
    say("localising the error (residual forces)")
    nominal_problem = build_problem(model, test, pset)
    C = np.asarray(nominal_problem.C)
    elem_b, node_b = residual_forces(model, np.asarray(nominal_problem.lam_e), np.asarray(nominal_problem.phi_e), C)
    say(f"localising the error (sensitivity of every element at the nominal model, {run.elapsed()})")
    nominal_screen = Screen.at(nominal_problem, np.zeros(len(run.params)), model, run.params, f_e, kinds=("k", "m"))
    chi2_shape = float(np.sum(nominal_screen.r[ne:] ** 2)) / run.sigma2 / (ne * ns)  # rows: eigenvalues, then shapes
    if chi2_shape < SHAPE_SIGNAL:  # the expanded shapes are noise: their residual forces point nowhere
        say(f"residual forces left out of the region: the shapes fit within noise (χ² per row {chi2_shape:.2f})")
    k, m = nominal_screen.element_reduction("k"), nominal_screen.element_reduction("m")
    node_nominal = combine(node_max(model, {e: max(k.get(e, 0.0), m.get(e, 0.0)) for e in k | m}),
                           node_b if chi2_shape >= SHAPE_SIGNAL else {})
    nodes = localised_grids(model, nominal_screen, node_nominal, options.max_nodes, options.region)
    structures = region_structures(model, nodes, node_nominal, options.kinds, options.max_structural)
    beyond = margin(model, nodes, options.max_nodes, node_nominal)
    aug, dormant, stiffened = augment(model, nodes, structures, f_e, beyond)
    run.problem = build_problem(aug, test, pset)
    say(f"region: {len(nodes)} grids ({len(beyond)} more about it for the place walk), {len(structures)} joints, "
        f"seams or supports{''.join(f'; {e.kind} at {e.where()}' for e in structures)}; one model of {aug.n_dof} DoFs")
    kinds = options.kinds
    if run.problem.sparse and "frequency_dependent_stiffness" in kinds:
        say("frequency laws are not offered: they need the dense eigensolver")
        kinds = tuple(k for k in kinds if k != "frequency_dependent_stiffness")
    return _Where(nominal_problem, elem_b, node_b, node_nominal, nodes, aug, dormant, stiffened, set(beyond), kinds)


def _baseline(run: _Run, aug: Model, ne: int) -> tuple[Fit, object, list]:
    """The engineer's parameters fitted on all modes and on each fold; the reduced bases of
    a large model (step 1)."""
    n_b, problem = len(run.params), run.problem
    masks = fold_masks(ne, run.options.folds)
    run.say(f"baseline fit ({n_b} parameters, {len(masks) - 1}-fold cross-validation over {ne} modes)")
    run.none = extension(aug)
    base = fit(run.fits, problem, run.none, np.zeros(n_b + 1), skip=n_b == 0)  # nothing to fit without parameters
    if aug.n_dof >= run.options.reduce_above:
        run.bases = Bases(with_extension(problem, run.none), base.theta)
        run.say(f"reduced models for the candidates: {run.bases.common.shape[1]} baseline columns "
                f"(modes and static corrections), {run.elapsed()}")
    return base, cross_validate(run.fits, problem, run.none, base, masks, run.solver(None), run.options.threads), masks


def _candidates(run: _Run, model: Model, where: _Where, base: Fit, f_e, soft: bool):
    """Every candidate screened at the baseline: each element's stiffness and mass (the
    Jacobian), patches on shells, the joints and supports by a scan of their stiffness
    (step 3); with ``soft`` (rounds after the first) each joint also by a fit from its
    scan's softest point (:func:`soft_fits`: 6–10 s a round at 628 DoFs; in the first round
    the scans found every true joint of the truth suite), its fit where it beats the scan. Returns the candidates, those
    only the place walk reaches, the structural ones and every element's screened
    stiffness share."""
    options, problem, aug, n_b = run.options, run.problem, where.aug, len(run.params)
    theta_b = base.theta[:n_b]
    run.say(f"screening (sensitivity of every element) ({run.elapsed()})")
    patches = ([cls.kind for cls, _ in PATCHES if cls.kind in options.kinds]
               if shell_grids(model, where.nodes) else [])
    screen = Screen.at(problem, base.theta, model, run.params, f_e,
                       kinds=("k", "m") + (("membrane", "bending", "shear", "nsm") if patches else ()),
                       modes=run.bases.modes if run.bases is not None else None)
    elem_a = screen.element_reduction("k")
    points = node_candidates(aug, where.dormant, screen)
    walk = [c.reference.kind in POINT_WALK and c.reference.nodes[0] in where.beyond for c in points]
    walk_only = [c for c, w in zip(points, walk) if w and c.reference.kind in options.kinds]
    cands = group_candidates(model, aug, run.params, screen, run.sigma2) + [c for c, w in zip(points, walk) if not w]
    cands = [c for c in cands if c.reference.kind in where.kinds] + patch_candidates(model, where.nodes, screen, patches)
    structural = structural_candidates(aug, where.stiffened)
    if run.bases is not None:  # the joints can only push other candidates off the shortlist
        run.bases.pool = pool(aug, shortlist(cands, options.shortlist, options.per_kind, where.kinds, options.within),
                              where.dormant, where.stiffened)
        run.say(f"reduced fits assemble {len(run.bases.pool)} elements at each step")
    scans = {c: (list(c.scan), list(scan_costs(run.fits, problem, c.ext, theta_b, c.scan, run.solver(c))))
             for c in structural}
    for c in sorted(structural, key=lambda c: min(scans[c][1]))[:2]:  # the best two: each factor alone too
        grid, costs = scans[c]
        if c.ext.split and min(costs) < base.cost:
            t, r = grid[int(np.argmin(costs))]
            more = [(t + d, r) for d in (-3.0, -1.5, 1.5)] + [(t, r + d) for d in (-3.0, -1.5, 1.5)]
            scans[c] = grid + more, costs + list(scan_costs(run.fits, problem, c.ext, theta_b, more, run.solver(c)))
    joints = [c for c in structural if c.reference.kind == "joint"] if soft else []
    softened = dict(zip(joints, soft_fits(run.fits, problem, joints, theta_b, run.solver, options.threads)))
    for c in structural:
        grid, costs = scans[c]
        c.screen, c.theta0 = 1 - float(np.min(costs)) / base.cost, np.atleast_1d(grid[int(np.argmin(costs))])
        if c in softened and softened[c].cost < min(costs):  # its fit from the soft end is the fit
            c.fit = softened[c]
            c.screen, c.theta0 = 1 - c.fit.cost / base.cost, c.fit.theta[n_b:]
        cands.append(c)
    return cands, walk_only, structural, elem_a


def _fit_shortlist(run: _Run, short: list[Candidate], structural, base: Fit, model: Model, where: _Where,
                   walkable: list[Candidate], f_e) -> None:
    """The shortlist fitted (on threads or Ray), then each place refined by hill-climbing."""
    options, problem, say = run.options, run.problem, run.say
    theta_b = base.theta[:len(run.params)]

    def fitted(more: list[Candidate]) -> None:
        """Each candidate fitted from its ``theta0``: the reduced bases made one after
        another, the fits on threads (:func:`threaded`) sharing the compiled fit."""
        def one(job: tuple[int, Candidate]) -> Fit:
            i, c = job
            say(f"  fitting {i}/{len(more)}: {c.reference.kind} {c.reference.where()} ({run.elapsed()})")
            return fit(run.fits, problem, c.ext, np.concatenate([theta_b, c.theta0]), run.solver(c))

        for c in more:
            run.solver(c)
        for c, result in zip(more, threaded(one, list(enumerate(more, 1)), options.threads)):
            c.fit = result

    # each from the better of the linearised step and none (the joints' scans are done); a law's
    # own compiled fit first, compiling on one thread while the others fit (last, alone: 10 s)
    order = sorted(short, key=lambda c: c.family)
    own = [next(c for c in order if c.family == f) for f in dict.fromkeys(c.family for c in order) if f != "mask"]
    order = own + [c for c in order if c not in own]
    jobs = [(i, c.ext, theta_b, c.scan if c not in structural else None, c.theta0, run.solver(c))
            for i, c in enumerate(order) if c.fit is None]
    if options.ray:
        say(f"  on Ray ({options.ray}): {len(jobs)} candidates")
        done = fit_candidates_ray(problem, run.fits.settings, jobs, address=options.ray, workers=options.ray_workers)
    else:
        done = threaded(lambda job: (job, candidate_fit(run.fits, problem, *job[1:])), jobs, options.threads)
    for k, (job, (theta0, result)) in enumerate(done, 1):
        c = order[job[0]]
        c.theta0, c.fit = theta0, result
        say(f"  fitted {k}/{len(jobs)}: {c.reference.kind} {c.reference.where()} ({run.elapsed()})")
    for c0, c1 in refine_places(fitted, run.solver, run.fits, problem, where.aug, walkable, short, base, theta_b):
        say(f"  {c1.reference.kind} moved from grid {c0.reference.nodes[0]} to {c1.reference.nodes[0]} "
            f"({run.elapsed()})")
    for c in refine_directions(fitted, where.aug, short, base):
        say(f"  {c.reference.kind} {c.reference.where()} fitted ({run.elapsed()})")
    for c0, c1 in (refine_patches(fitted, model, where.aug, short, base, f_e)
                   + refine_seams(fitted, where.aug, short, base)):
        say(f"  {c1.reference.kind} moved from {c0.reference.where()} to {c1.reference.where()} ({run.elapsed()})")


def _rank(run: _Run, short: list[Candidate], cands: list[Candidate], base: Fit, base_held, masks,
          n_rows: tuple[int, int]):
    """Evidence; the most probable candidates checked on the full model and cross-validated;
    the ranking again with their held-out errors (step 4)."""
    n_b, say = len(run.params), run.say
    mass = run.mass
    f_sd = run.options.noise.frequency
    ranked = evidence(short, base, base_held, n_b, n_rows, run.sigma2, mass, f_sd).candidates
    top = [c for c in ranked if np.isfinite(c.fit.cost)][:run.options.cross_validate]
    for c in cands + short:  # the others' reduced bases freed (n × r each, 50 MB at 33,000 DoFs; 24 GB filled)
        if c not in top:
            run.solvers.pop(c, None)
    if run.bases is not None:
        say(f"checking the {len(top)} most probable on the full model ({run.elapsed()})")
        for c in top:
            c.fit = _on_full_model(run, c)
    say(f"cross-validating the {len(top)} most probable ({len(masks) - 1} folds, {run.elapsed()})")
    for c in top:
        c.heldout = cross_validate(run.fits, run.problem, c.ext, c.fit, masks, run.solver(c), run.options.threads)
    return evidence(short, base, base_held, n_b, n_rows, run.sigma2, mass, f_sd)


def _on_full_model(run: _Run, c: Candidate) -> Fit:
    """A candidate's reduced fit evaluated on the full model at its θ (costs, Jacobian);
    fitted again there only where the two costs differ by more than :data:`FULL_MODEL_TOL`
    in χ² or, if more, :data:`FULL_MODEL_REL` of the candidate's χ² (a reduced basis
    that misses the effect: a heavy mass's own mode; a gap far below the misfit the
    candidate leaves itself moves neither its place nor the verdict). At 33,000 DoFs a
    refit takes 140–340 s a seam."""
    check = fit(run.fits, run.problem, c.ext, c.fit.theta, skip=True)
    gap = abs(check.cost - c.fit.cost) / run.sigma2
    if gap <= max(FULL_MODEL_TOL, FULL_MODEL_REL * check.cost / run.sigma2):
        return check
    run.say(f"  {c.reference.kind} {c.reference.where()}: the reduced fit is off by χ² {gap:.3g}; fitted again")
    return fit(run.fits, run.problem, c.ext, c.fit.theta)


def _result(rounds: list[_Round], declared: tuple[Declared, ...], withdrawn: Withdrawn | None, model: Model,
            test: ModalData, start: float, final_fit: Fit) -> Diagnosis:
    """The comparison at the first baseline, the last round's localisation and ranking, the
    declared effects, the state and its verdict; the damping part (step 5)."""
    first, last = rounds[0], rounds[-1]
    run, options, n_b = first.run, first.run.options, len(first.run.params)
    problem = first.run.problem
    ne, ns = len(test.frequencies_hz), len(test.sensors)
    base = first.base
    theta_b = base.theta[:n_b]
    ev = evaluate(jnp.asarray(base.theta), problem)
    pairing = evaluation_pairing(ev, test, problem)
    co = np.asarray(comac(np.asarray(ev.phi_model)[:, pairing.model], np.asarray(problem.phi_e)[:, pairing.test]))
    where = last.where
    group_b, group_a = group_scores(where.elem_b, last.model), group_screens(last.cands)
    node_a = node_max(where.aug, last.screen_k)
    node_score = combine(node_a, where.node_b)
    chi2 = lambda cost: float(cost / run.sigma2 / (ne + ne * ns))  # noqa: E731
    baseline = Baseline(
        tuple((p.name, float(np.expm1(t))) for p, t in zip(run.params, theta_b)), rms_pct(base.freq_dev),
        float(np.nanmean(base.mac)), rms_pct(first.base_held.freq_dev), float(np.nanmean(first.base_held.mac)),
        chi2(base.cost), chi2(base.cost_freq) * (ne + ne * ns) / ne, chi2(base.cost_shape) * (ne + ne * ns) / (ne * ns))
    localisation = Localisation(
        tuple((p, s, group_a.get(p, 0.0), group_b.get(p, 0.0)) for p, s in combine(group_a, group_b).items()),
        tuple((n, s, node_a.get(n, 0.0), where.node_b.get(n, 0.0)) for n, s in list(node_score.items())[:30]),
        tuple(where.nodes))
    ranking = last.ranking
    rows_ = (ne, ne * ns)
    left = lambda f: remainder(f, run.sigma2, options.noise.frequency, rows_)  # noqa: E731
    final = left(final_fit)
    outcome = state(ranking.outcome, ranking.results, declared, left(base), final)
    ties = ranking.ties if outcome == "cannot_localise" or declared and declared[-1].round == len(rounds) else ()
    text = verdict(outcome, ranking.results, ties, baseline, declared, final, left(base), withdrawn)
    confirmation = declared[-1].confirmation if declared else None
    damping = _damping(run, test, first, declared, confirmation)
    if damping is not None:
        text += " Damping: " + damping.verdict
    seconds = time.perf_counter() - start
    run.say(f"diagnosis done in {seconds:.1f} s")
    return Diagnosis(
        outcome, text, ranking.results, ties, declared[0].effect if declared else None, baseline, pairing,
        tuple((lab, float(v)) for lab, v in zip(test.sensors.labels, co)), localisation, options.noise,
        ranking.noise_scale, ranking.baseline_posterior, sum(len(r.cands) for r in rounds),
        sum(len(r.short) for r in rounds), seconds, ranking.candidates, model, run.params,
        combine({e: v for e, v in first.screen_k.items() if e in set(model.element_ids().tolist())}, first.where.elem_b),
        node_score, sensor_modes(ev), damping,
        declared, withdrawn, final, len(rounds), confirmation)


def _damping(run: _Run, test: ModalData, first: _Round, declared, confirmation):
    """The damping part, on the model with the declared effects (updated, where confirmed)."""
    options = run.options
    if LocalDamping.kind not in options.kinds or np.sum(np.asarray(test.damping_ratios) > 0) < MIN_MODES:
        return None
    at = first.where.nominal_problem.model(jnp.asarray(first.base.theta[:len(run.params)]))
    if confirmation is not None:
        at = confirmation.after.model
    elif declared:
        for d in declared:
            at = d.effect.apply(at)
    problem = run.problem
    return diagnose_damping(at, test, noise=options.noise, folds=options.folds, min_mac=problem.min_mac,
                            max_freq_dev=problem.max_freq_dev, progress=run.progress)
