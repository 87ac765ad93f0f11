"""Add an effect to the model and update it with the engineer's parameters, holding passive
modes out: the error falling, on modes not used in the fit (thesis §4.2.4.2)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import jax.numpy as jnp
import numpy as np

from identification import ModalData, Pairing, rms_pct
from jaxfem import Model

from .. import (
    Extension,
    Iteration,
    Noise,
    Options,
    Parameter,
    ParameterSet,
    Problem,
    ProgressFn,
    UpdateResult,
    build_problem,
    evaluate,
    evaluation_pairing,
    json_number,
    json_safe,
    parameterise,
    sensor_modes,
    update,
)
from ._abstract_effect import AbstractEffect
from ._evidence import worse_modes
from ._fit import Fits, scan_start, with_extension
from ._options import NOISE, DiagnoseOptions


@dataclass(frozen=True)
class ModeChange:
    """One test mode before and after the update with the effect: Δf [%] and MAC (None
    where unpaired), its role in the fit ("active" or "passive")."""

    test: int
    role: str
    f_test_hz: float
    freq_dev_pct_before: float | None
    freq_dev_pct_after: float | None
    mac_before: float | None
    mac_after: float | None


@dataclass(frozen=True)
class Confirmation:
    """The update without and with an effect, on the same active/passive split: the effect
    at its updated values, the baseline's pairing, the update, per-mode changes, RMS Δf [%]
    over active and passive modes, mean passive MAC, and the modes grown ``worse`` beyond
    2σ of the frequency noise."""

    effect: AbstractEffect
    before: Pairing
    after: UpdateResult
    passive: np.ndarray  # bool per test mode
    modes: tuple[ModeChange, ...]
    rms_active_before: float | None
    rms_active_after: float | None
    rms_passive_before: float | None
    rms_passive_after: float | None
    mean_mac_passive_before: float | None
    mean_mac_passive_after: float | None
    worse: tuple[ModeChange, ...]

    @property
    def passive_worse(self) -> tuple[ModeChange, ...]:
        """The passive modes grown worse beyond noise: what withdraws a declaration."""
        return tuple(m for m in self.worse if m.role == "passive")

    def to_json(self) -> dict:
        """JSON-ready (NaN and inf as null)."""
        a = self.after
        return json_safe({
            "effect": self.effect.to_json(),
            "parameters": [{"name": n, "alpha": float(x)} for n, x in zip(a.names, a.alpha)],
            "converged": bool(a.converged), "iterations": int(a.iterations), "seconds": float(a.seconds),
            "passive_modes": [int(j) + 1 for j in np.flatnonzero(self.passive)],
            "paired_modes": [vars(m) for m in self.modes],
            "rms_freq_dev_pct_active_before": self.rms_active_before, "rms_freq_dev_pct_active_after": self.rms_active_after,
            "rms_freq_dev_pct_passive_before": self.rms_passive_before,
            "rms_freq_dev_pct_passive_after": self.rms_passive_after,
            "mean_mac_passive_before": self.mean_mac_passive_before,
            "mean_mac_passive_after": self.mean_mac_passive_after,
            "history": [h.to_json(a.names, self.passive) for h in a.history],
            "worse": [vars(m) for m in self.worse],
        })


def add_effect(model: Model, test: ModalData, effect: AbstractEffect, parameters: ParameterSet | None = None, *,
               passive_modes: tuple[int, ...] | None = None,
               progress: ProgressFn | None = None, noise: Noise = NOISE) -> Confirmation:
    """Add ``effect`` and update it with the engineer's parameters, holding
    ``passive_modes`` out of the fit (default: every fourth test mode from the third);
    compare with the update without it. The effect starts from its ``values`` (e.g. as
    fitted by :func:`diagnose`) or, without values, from :func:`start_values`. Its
    parameters (``effect.parameters``) are updated with the engineer's and the fitted
    log-factors give its final values (``effect.updated``); one that scales what an
    engineer's parameter already scales (a law's E0 on such a group) stays at its value.
    ``worse``: the modes whose
    |Δf| grew by more than 2σ of the stated frequency noise (``noise.frequency``)."""
    ne = len(test.frequencies_hz)
    passive = tuple(passive_modes) if passive_modes is not None else default_passive(ne)
    base = tuple(parameters.parameters) if parameters else ()
    opts = replace(parameters.options if parameters else Options(), active_modes=None, passive_modes=passive)
    if base:
        before = update(model, test, ParameterSet(base, opts)).after
    else:
        problem = build_problem(model, test, ParameterSet((), opts))
        before = evaluation_pairing(evaluate(jnp.zeros(0), problem), test, problem)
    start = effect if effect.values else start_values(model, test, effect, opts)
    extended = start.apply(model)
    eparams = start.parameters(model, extended)
    free = free_parameters(eparams, base)
    after = update(extended, test, ParameterSet(base + free, opts), progress=progress)
    final = start.updated(np.array([after.theta[after.names.index(q.name)] if q in free else 0.0 for q in eparams]))
    return _confirmation(final, before, after, test, passive, noise)


def confirm_on_fit(fits: Fits, problem: Problem, none: Extension, ext: Extension, reference: AbstractEffect,
                   theta_e, params: tuple[Parameter, ...], at_params: Callable[[np.ndarray], Model],
                   test: ModalData, noise: Noise = NOISE) -> Confirmation:
    """:func:`add_effect` on a diagnosis' compiled fit (``fits`` on ``problem``, the model
    holding every candidate): the baseline (extension ``none``) and the effect (``ext``,
    θ = 0 its ``reference``, from its fitted ``theta_e``), each with the engineer's
    ``params`` from nominal, fitted on the same active modes at the diagnosis' stated-noise
    weights; no compilation of its own (two updates compiled apart took 25–30 s of a
    GARTEUR diagnosis). The effect's α are relative to its fitted values;
    ``at_params(θ)``: the model at the engineer's log-factors θ."""
    t0 = time.perf_counter()
    ne, n_b = len(test.frequencies_hz), len(params)
    passive = default_passive(ne)
    mask = ~np.isin(np.arange(1, ne + 1), passive)
    theta_e = np.asarray(theta_e, float)
    b = fits.loop(np.zeros(n_b + 1), with_extension(problem, none, mask), skip=n_b == 0)
    a = fits.loop(np.concatenate([np.zeros(n_b), theta_e]), with_extension(problem, ext, mask))
    final, start, nominal = reference.updated(a.theta[n_b:]), reference.updated(theta_e), at_params(np.zeros(n_b))
    eparams = start.parameters(nominal, start.apply(nominal))
    model = final.apply(at_params(a.theta[:n_b]))
    alpha = np.concatenate([a.alpha[:, :n_b], np.expm1(np.log1p(a.alpha[:, n_b:]) - theta_e)], axis=1)
    history = [Iteration(k, alpha[k], a.freq_dev[k], a.mac[k], float(a.cost[k])) for k in range(len(alpha))]
    modes = {"before": sensor_modes(a.start), "after": sensor_modes(a.end)}
    after = UpdateResult(model, [q.name for q in params + eparams], alpha[-1], np.log1p(alpha[-1]), a.converged,
                         len(history) - 1, history, mask, evaluation_pairing(a.start, test, problem), evaluation_pairing(a.end, test, problem),
                         time.perf_counter() - t0, modes, parameterise(model, params + eparams)[1])
    return _confirmation(final, evaluation_pairing(b.end, test, problem), after, test, passive, noise)


def default_passive(ne: int) -> tuple[int, ...]:
    """Every fourth of ``ne`` test modes from the third (numbered from 1): held out of an update."""
    return tuple(i for i in range(1, ne + 1) if i % 4 == 3)


def _confirmation(final: AbstractEffect, before: Pairing, after: UpdateResult, test: ModalData,
                  passive: tuple[int, ...], noise: Noise) -> Confirmation:
    """Per-mode changes, RMS Δf over active and passive modes, passive MAC, the modes
    grown worse beyond 2σ of the frequency noise."""
    ne = len(test.frequencies_hz)
    is_passive = np.isin(np.arange(1, ne + 1), passive)
    (d0, m0), (d1, m1) = before.per_test(), after.after.per_test()
    f_e = np.asarray(test.frequencies_hz)
    modes = tuple(ModeChange(j + 1, "passive" if is_passive[j] else "active", float(f_e[j]), json_number(d0[j]),
                             json_number(d1[j]), json_number(m0[j]), json_number(m1[j])) for j in range(ne))
    grew = set(worse_modes(d0 / 100, d1 / 100, noise.frequency))
    rms = lambda d, sel: rms_pct(d[sel] / 100)  # noqa: E731
    mean = lambda m: json_number(np.nanmean(m[is_passive])) if is_passive.any() else None  # noqa: E731
    return Confirmation(final, before, after, is_passive, modes, rms(d0, ~is_passive), rms(d1, ~is_passive),
                        rms(d0, is_passive), rms(d1, is_passive), mean(m0), mean(m1),
                        tuple(m for m in modes if m.test in grew))


def free_parameters(effect_params: tuple[Parameter, ...], base: tuple[Parameter, ...]) -> tuple[Parameter, ...]:
    """An effect's parameters less those scaling what one of ``base`` already scales (a
    law's E0 on a group the engineer scales): identical Jacobian columns, kept fixed."""
    taken = {(q.kind, q.pids, q.eids, q.nodes) for q in base}
    return tuple(q for q in effect_params if (q.kind, q.pids, q.eids, q.nodes) not in taken)


def start_values(model: Model, test: ModalData, effect: AbstractEffect, opts: Options | None = None) -> AbstractEffect:
    """Starting values for updating an effect: ``effect.at_reference``, moved to the best
    point of the coarse grid of log-factors ``effect.scan`` (a joint, support or added
    mass scaled, a frequency law's factor and coefficient changed; None: no scan)."""
    start = effect.at_reference(model, test.frequencies_hz)
    if start.scan is None:
        return start
    extended = start.apply(model)
    problem = build_problem(extended, test, ParameterSet((), replace(opts or Options(), passive_modes=())))
    return start.updated(scan_start(Fits(DiagnoseOptions().settings), problem, start.extension(model, extended),
                                    np.zeros(0), start.scan))
