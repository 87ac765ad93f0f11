"""Diagnosis: where the model fails and which physical effect is missing.

1. **Baseline**: the model, updated with the engineer's parameters if any (thesis §3.2).
2. **Localisation** at the baseline, by two independent methods: (a) sensitivity — the
   share ρ of the residual that one Gauss–Newton step in a single element's (group's)
   stiffness or mass removes (Friswell & Mottershead 1995, §7), (b) residual forces of
   the measured modes expanded to the model (ibid. §8, :func:`residual_forces`).
3. **Candidates** generated from the model by each kind (:mod:`updating._effects`),
   screened by the linearised residual reduction ρ (the same Jacobian as (a),
   :mod:`updating._candidates`); the best of each kind and
   the best overall, and the structural ones (joints, released supports) nearest the
   localised error, are **fitted** with the baseline parameters (Optimistix
   Levenberg–Marquardt; candidates of one model structure share one compiled solver, their
   masks being traced arguments; the screening Jacobian of all elements is one ``jacfwd``).
4. **Ranking by evidence that generalises** (:mod:`updating._evidence`): k-fold cross-validation over the test modes
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
from dataclasses import dataclass, replace

import jax.numpy as jnp
import numpy as np

import jaxfem
from identification import ModalData
from jaxfem import Model

from ._candidates import (
    Candidate,
    Screen,
    augment,
    group_candidates,
    group_screens,
    localised_grids,
    node_candidates,
    node_max,
    shortlist,
    structural_candidates,
)
from ._correlation import comac, pair_modes
from ._effects import KINDS, AbstractEffect
from ._engine import Settings
from ._evidence import Fits, combine, evidence, fold_masks, run_fits, scan_start, verdict
from ._extension import extension
from ._localisation import group_scores, reduction, residual_forces
from ._parameters import Options, Parameter, ParameterSet
from ._report import json_number, rms_pct
from ._residuals import evaluate
from ._result import Iteration, UpdateResult
from ._solve import build_problem, update
from ._topology import total_mass


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
    kinds: tuple[str, ...] = KINDS

    @property
    def settings(self) -> Settings:
        return Settings(False, self.tolerance, self.max_steps, self.max_steps)


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
    masks = fold_masks(ne, options.folds)
    fits = Fits()
    f_e = np.asarray(test.frequencies_hz)

    # -- localisation at the nominal model: where to put node-based candidates
    say("localising the error (residual forces)")
    nominal_problem = build_problem(model, test, pset)
    C = np.asarray(nominal_problem.C)
    elem_b, node_b = residual_forces(model, np.asarray(nominal_problem.lam_e), np.asarray(nominal_problem.phi_e), C)
    nodes = localised_grids(model, node_b, options.max_nodes)
    mass = total_mass(model)
    aug, dormant = augment(model, nodes, f_e)
    problem = build_problem(aug, test, pset)

    # -- baseline: the engineer's parameters fitted on all modes and on each fold
    say(f"baseline fit ({n_b} parameters, {len(masks) - 1}-fold cross-validation over {ne} modes)")
    base = run_fits(fits, problem, [extension(aug)], [np.zeros(n_b + 1)], masks, options.settings)[0]
    theta_b = base["theta"][:n_b]

    # -- screening Jacobian at the baseline: every element's stiffness and mass, dormant ones
    say("screening (sensitivity of every element)")
    screen = Screen.at(problem, base["theta"], n_b, f_e)
    elem_a = {int(e): float(v) for e, v in zip(screen.k_ids, reduction(screen.r, screen.J_k, screen.J_b))}
    node_a = node_max(aug, elem_a)
    cands = group_candidates(model, aug, params, screen) + node_candidates(aug, dormant, screen)
    cands = [c for c in cands if c.effect.kind in options.kinds]
    node_score = combine(node_a, node_b)
    cands += structural_candidates(model, node_score, options.kinds, options.max_structural, f_e)
    short = shortlist(cands, options.shortlist, options.per_kind, options.kinds)
    say(f"{len(cands)} candidates screened; fitting {len(short)} with {len(masks) - 1}-fold cross-validation")

    # -- fits: all modes, then the folds for those that could pass the AIC test
    n_rows = ne * (1 + ns)

    def theta_start(c):
        return np.concatenate([theta_b, c.theta0])

    def keep(k_e):
        return lambda cost: n_rows * np.log(max(cost, 1e-300) / base["cost"]) + 2 * k_e <= -options.min_delta_aic

    for c in short:
        if c.scan is not None and c.family != "structural":
            c.theta0 = scan_start(fits, problem, c.ext, theta_b, c.scan)
    for family in ("mask", "visco"):
        group = [c for c in short if c.family == family]
        if group:
            say(f"  {family}: {len(group)} candidates × {len(masks)} fits ({time.perf_counter() - start:.0f} s)")
            for c, res in zip(group, run_fits(fits, problem, [c.ext for c in group], [theta_start(c) for c in group],
                                              masks, options.settings, keep(group[0].ext.n_params))):
                c.result = res
    for c in short:
        if c.family == "structural":
            say(f"  {c.effect.kind} {c.effect.where()} ({time.perf_counter() - start:.0f} s)")
            p = build_problem(c.model, test, pset)
            c.theta0 = scan_start(fits, p, c.ext, theta_b, c.scan)
            c.result = run_fits(fits, p, [c.ext], [theta_start(c)], masks, options.settings, keep(1))[0]

    effects, ranked = evidence(short, base, n_b, n_rows, sigma2, mass, options.min_score, options.min_delta_aic)
    best = ranked[0].effect if effects and effects[0]["warranted"] else None

    # -- comparison at the baseline
    ev = evaluate(jnp.asarray(base["theta"]), problem)
    pairing = pair_modes(np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model), f_e,
                         np.asarray(problem.phi_e), min_mac=problem.min_mac, max_freq_dev=problem.max_freq_dev)
    compared = pairing.summary()
    co = np.asarray(comac(np.asarray(ev.phi_model)[:, pairing.model], np.asarray(problem.phi_e)[:, pairing.test]))
    group_b = group_scores(elem_b, model)
    group_a = group_screens(cands)
    groups = combine(group_a, group_b)
    report = {
        "paired_modes": compared["paired_modes"],
        "unpaired_test": compared["unpaired_test"],
        "unpaired_model": compared["unpaired_model"][:10],
        "baseline": {"parameters": [{"name": p.name, "alpha": float(np.expm1(t))} for p, t in zip(params, theta_b)],
                     "rms_freq_dev_pct": rms_pct(base["freq_dev"]), "mean_mac": float(np.nanmean(base["mac"])),
                     "heldout_rms_freq_dev_pct": rms_pct(base["heldout_freq_dev"]),
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
    report["verdict"] = verdict(report)
    report["seconds"] = time.perf_counter() - start
    say(f"diagnosis done in {report['seconds']:.1f} s")
    return Diagnosis(report, best, ranked, model, params, combine(
        {e: v for e, v in elem_a.items() if e in set(model.element_ids().tolist())}, elem_b), node_score,
        (np.asarray(jaxfem.frequencies_hz(ev.lam_model)), np.asarray(ev.phi_model)))


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
               progress: Callable[[Iteration], None] | None = None) -> Confirmation:
    """Add ``effect`` and update it with the engineer's parameters, holding
    ``passive_modes`` out of the fit (default: every fourth test mode from the third);
    compare with the update without it. The effect starts from its ``values`` (e.g. as
    fitted by :func:`diagnose`) or, without values, from :func:`start_values`. Its
    parameters (``effect.parameters``) are updated with the engineer's and the fitted
    log-factors give its final values (``effect.updated``).

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
    return start.updated(scan_start(Fits(), problem, start.extension(model, extended), np.zeros(0), start.scan))
