"""``jaxfem update``: update parameters (and added effects) so that the model modes match the test."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ._common import (
    DEFAULT_GEOMETRY,
    AllowUnsupportedOpt,
    Geometry,
    JsonOut,
    ModelArg,
    MpcSetOpt,
    PlotsOut,
    SolverOpt,
    SpcSetOpt,
    SubcaseOpt,
    TestArg,
    check_plots,
    echoed_warnings,
    fail,
    frf_prediction,
    geometry_options,
    load_inputs,
    mode_labels,
    write_json,
)


def _add_effects(model, test, params, specs: list[str], progress):
    """``--add-effect``: each effect from its starting values (printed), updated with the
    parameters by :func:`updating.add_effect` on the test modes the options make active.
    ``add_effect`` takes one effect: the ones before the last are added to the model and
    their parameters (named ``KIND_<k>``) to the engineer's.

    **Returns:** the model with every effect at its starting values, the
    :class:`~updating.Confirmation`.
    """
    from .. import active_mask
    from ..diagnosis import add_effect, effect_parameters, parse_effect, start_values

    steps = []
    for spec in specs:
        try:
            effect = start_values(model, test, parse_effect(spec), params.options)
            extended = effect.apply(model)
        except (ValueError, KeyError) as err:
            fail(f"--add-effect {spec}: {err}")
        typer.echo(f"added {effect.kind} at {effect.where()}: starting values "
                   + ", ".join(f"{k} = {v:.4g}" for k, v in effect.values.items()))
        steps.append((model, effect, extended))
        model = extended
    extra = []
    for before, effect, extended in steps[:-1]:
        extra += [replace(p, name=f"{p.name}_{len(extra) + 1}") for p in effect_parameters(effect, before, extended)]
    params = replace(params, parameters=tuple(params.parameters) + tuple(extra))
    passive = tuple(int(j) + 1 for j in np.flatnonzero(~active_mask(test, params.options)))
    before, last, _ = steps[-1]
    return model, add_effect(before, test, last, params, passive_modes=passive, progress=progress)


def _print_result(result: dict, res, opts) -> None:
    status = "converged" if res.converged else "NOT converged"
    typer.echo(f"{status} after {res.iterations} iterations ({res.seconds:.1f} s; tolerance on max|Δα| "
               f"{opts.tolerance:g})")
    typer.echo(f"{'parameter':>12} {'kind':>10} {'α':>12} {'bounds':>16}  within")
    for row in result["parameters"]:
        lo, hi = row["bounds"]
        typer.echo(f"{row['name']:>12} {row['kind']:>10} {row['alpha']:>+12.6f} {f'[{lo:g}, {hi:g}]':>16}  "
                   f"{'yes' if row['within_bounds'] else 'NO'}")
        if not row["within_bounds"]:
            typer.echo(f"warning: parameter {row['name']} α = {row['alpha']:+.4f} is outside its bounds "
                       f"[{lo:g}, {hi:g}]", err=True)


def _print_pairings(result: dict, res) -> None:
    active = np.asarray(res.active, dtype=bool)
    typer.echo(f"{'test':>5} {'role':>7} {'f_test [Hz]':>12} | {'before: model':>13} {'f [Hz]':>10} "
               f"{'Δf [%]':>8} {'MAC':>6} | {'after: model':>12} {'f [Hz]':>10} {'Δf [%]':>8} {'MAC':>6}")

    def cells(row, width):
        _, m, _, fm, d, c = row
        if m is None:
            return f"{'–':>{width}} {'–':>10} {'–':>8} {'–':>6}"
        return f"{m:>{width}} {fm:>10.4f} {d:>+8.2f} {c:>6.3f}"

    for j, (b, a) in enumerate(zip(res.before.table(), res.after.table())):
        role = "active" if active[j] else "passive"
        typer.echo(f"{b[0]:>5} {role:>7} {b[2]:>12.4f} | {cells(b, 13)} | {cells(a, 12)}")
    for line in res.after.warnings:
        typer.echo(f"warning (after): {line}", err=True)
    for key in ("before", "after"):
        p = result[key]
        if p["paired_modes"]:
            typer.echo(f"{key}: paired {len(p['paired_modes'])}/{len(active)}, RMS Δf {p['rms_freq_dev_pct']:.3f} %, "
                       f"mean MAC {p['mean_mac']:.4f}")


def _plot(res, test, plots: Path) -> list[Path]:
    import identification as corr

    from ..report import plot_convergence, plot_freq_dev, plot_mac

    f_e, phi_e = np.asarray(test.frequencies_hz), np.asarray(test.shapes)
    active = np.asarray(res.active, dtype=bool)
    written = []
    for key in ("before", "after"):
        f_a, phi_a = res.sensor_modes[key]
        written.append(plot_mac(np.asarray(corr.mac(phi_a, phi_e)).T, mode_labels(f_e), mode_labels(f_a),
                                plots / f"mac_{key}.png", f"MAC {key} updating"))
    written.append(plot_freq_dev(res.before.per_test()[0], res.after.per_test()[0], mode_labels(f_e),
                                 plots / "freq_dev.png", active=active))
    written.append(plot_convergence(res.history, res.names, plots / "convergence.png", active=active))
    return written


@geometry_options
def update(
    model_path: ModelArg,
    test_path: TestArg,
    params_path: Annotated[Path, typer.Option("--params", metavar="PARAMS.toml", exists=True, dir_okay=False,
                                              help="updating parameters and options (TOML, schema in docs/parameters.md)")],
    json_out: JsonOut,
    plots: PlotsOut = None,
    frf_path: Annotated[Path | None, typer.Option("--frf", exists=True, dir_okay=False,
                                                  help="measured FRFs (UFF 58) to predict before/after")] = None,
    add_effect: Annotated[list[str] | None, typer.Option(
        "--add-effect", metavar="KIND:TARGET",
        help="add a physical effect and update its parameters too, e.g. joint:node=6001, "
             "added_mass:node=2015, frequency_dependent_stiffness:pid=41 (repeatable)")] = None,
    solver: SolverOpt = None,
    geometry: Geometry = DEFAULT_GEOMETRY,
    allow_unsupported: AllowUnsupportedOpt = False,
    spc_set: SpcSetOpt = None,
    mpc_set: MpcSetOpt = None,
    subcase: SubcaseOpt = None,
) -> None:
    """Update model parameters so that the model modes match the test modes.

    With ``--add-effect``, each effect is added to the model at its starting values (a
    slightly flexible joint or support, 1 % of the mass, a = 0, ...) and its parameters
    are updated with the others (``updating.add_effect``).

    With ``--frf``, the measured FRFs are predicted by the initial and the updated model
    (modal superposition, viscous ratio = mean measured modal damping, else 1 %) and
    compared by FRAC and mean |Δ| in dB (validation by prediction, thesis §4.2.5.3).
    """
    from .. import update as run_update

    check_plots(plots)
    model, test, _, params, gmap, _ = load_inputs(model_path, test_path, params_path, solver,
                                               geometry,
                                               allow_unsupported, (spc_set, mpc_set, subcase))
    last = {}

    def progress(p) -> None:
        it = p.detail
        alpha = np.asarray(it.alpha)
        step = "–" if "alpha" not in last else f"{np.max(np.abs(alpha - last['alpha'])):.3e}"
        last["alpha"] = alpha
        typer.echo(f"iteration {it.iteration:3d}  cost {it.cost:.6e}  max|Δα| {step}", err=True)

    confirmation = None
    try:
        if add_effect:
            model, confirmation = _add_effects(model, test, params, add_effect, progress)
            res = confirmation.after
        else:
            with echoed_warnings():
                res = run_update(model, test, params, progress=progress)
    except ValueError as err:
        fail(f"{params_path}: {err}")

    result = {"model": str(model_path), "test": str(test_path), "parameters_file": str(params_path),
              **res.to_json(), "test_geometry": gmap.to_json()}
    if confirmation is not None:
        result["add_effect"] = confirmation.to_json()
    _print_result(result, res, params.options)
    if frf_path is not None:
        result["frf"] = frf_prediction(frf_path, test, model, res.model, plots, gmap)
    _print_pairings(result, res)
    write_json(json_out, result)
    if plots is not None:
        try:
            written = _plot(res, test, plots)
        except OSError as err:
            fail(f"cannot write plots to {plots}: {err}")
        typer.echo("wrote " + ", ".join(str(w) for w in written))
