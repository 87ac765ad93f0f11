"""``jaxfem diagnose``: where the model fails and which physical effect is missing."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ._common import (
    DEFAULT_GEOMETRY,
    AllowUnsupportedOpt,
    Geometry,
    ModelArg,
    MpcSetOpt,
    SolverOpt,
    SpcSetOpt,
    SubcaseOpt,
    TestArg,
    check_plots,
    check_solver,
    fail,
    frf_prediction,
    geometry_options,
    load_inputs,
    load_test,
    mode_labels,
    write_json,
)


def _fmt(x, spec: str) -> str:
    return format(x, spec) if x is not None and np.isfinite(x) else format("–", spec.split(".")[0])


def _print_diagnosis(rep: dict) -> None:
    b = rep["baseline"]
    typer.echo(f"baseline: RMS Δf {b['rms_freq_dev_pct']:.2f} %, mean MAC {b['mean_mac']:.3f}, "
               f"held-out RMS Δf {b['heldout_rms_freq_dev_pct']:.2f} %, χ²/row {b['chi2_per_row']:.2f}")
    typer.echo("where it fails (combined indicator, property groups): " + ", ".join(
        f"pid {g['pid']} {g['score']:.2f}" for g in rep["localisation"]["groups"][:5]))
    typer.echo("                                              (grids): " + ", ".join(
        f"{n['node']} {n['score']:.2f}" for n in rep["localisation"]["nodes"][:5]))
    typer.echo(f"{'rank':>4} {'effect':<34} {'posterior':>9} {'ln B':>9} {'χ²/row':>8} {'held-out Δf [%]':>16} "
               f"{'MAC':>6}  declared")
    for e in rep["effects"][:10]:
        where = f"{e['kind']} {e['where']}"[:34]
        notes = "  (prior: " + "; ".join(e["plausibility"]) + ")" if e["plausibility"] else ""
        typer.echo(f"{e['rank']:>4} {where:<34} {e['posterior']:>9.3f} {e['log_evidence']:>9.1f} "
                   f"{e['chi2_per_row']:>8.2f} {_fmt(e['heldout_rms_freq_dev_pct_before'], '>7.2f')} → "
                   f"{_fmt(e['heldout_rms_freq_dev_pct_after'], '<6.2f')} {_fmt(e['heldout_mean_mac_after'], '>6.3f')}"
                   f"  {'yes' if e['warranted'] else 'no'}{notes}")
    typer.echo(f"(posterior over the candidates and the baseline, {rep['baseline_posterior']:.3f}; ln B: log Bayes "
               f"factor against the baseline at the stated noise; the misfit's noise scale {rep['noise_scale']:.3g})")
    for d in rep["declared"]:
        typer.echo(f"declared in round {d['round']}: {d['kind']} at {d['where']} (held-out RMS Δf "
                   f"{_fmt(d['heldout_rms_freq_dev_pct_before'], '.2f')} % → {_fmt(d['heldout_rms_freq_dev_pct_after'], '.2f')} %)")
    if rep["withdrawn"]:
        typer.echo(f"withdrawn: {rep['withdrawn']['kind']} at {rep['withdrawn']['where']}: {rep['withdrawn']['reason']}")
    if "damping" in rep:
        _print_damping(rep["damping"])
    typer.echo(rep["verdict"])


def _print_damping(d: dict) -> None:
    b = d["baseline"]
    typer.echo(f"damping (loss factor of a region beyond uniform damping, {len(d['modes'])} modes, {d['regions_fitted']} "
               f"regions): uniform damping (Rayleigh + η0) χ²/row {b['chi2_per_row']:.2f}, held-out ζ error "
               f"{b['heldout_rms_zeta_dev_pct']:.1f} %")
    typer.echo(f"{'rank':>4} {'region':<44} {'η':>14} {'posterior':>9} {'ln B':>8} {'χ²/row':>8} "
               f"{'held-out ζ err [%]':>19}  declared")
    for e in d["effects"][:5]:
        typer.echo(f"{e['rank']:>4} {e['where'][:44]:<44} {e['eta']:>7.3g} ±{e['eta_sd']:<5.2g} {e['posterior']:>9.3f} "
                   f"{e['log_evidence']:>8.1f} {e['chi2_per_row']:>8.2f} {e['heldout_rms_zeta_dev_pct_before']:>8.1f} → "
                   f"{e['heldout_rms_zeta_dev_pct_after']:<8.1f}  {'yes' if e['warranted'] else 'no'}")


def _print_confirmation(after: dict) -> None:
    typer.echo(f"{'test':>5} {'role':>7} {'f_test [Hz]':>12} {'Δf before [%]':>14} {'Δf after [%]':>13} "
               f"{'MAC before':>11} {'MAC after':>10}")
    for row in after["paired_modes"]:
        cells = [f"{row[k]:>+14.2f}" if row[k] is not None else f"{'–':>14}" for k in ("freq_dev_pct_before", "freq_dev_pct_after")]
        macs = [f"{row[k]:>10.3f}" if row[k] is not None else f"{'–':>10}" for k in ("mac_before", "mac_after")]
        typer.echo(f"{row['test']:>5} {row['role']:>7} {row['f_test_hz']:>12.3f} {cells[0]} {cells[1][1:]} "
                   f"{macs[0]:>11} {macs[1]}")
    typer.echo(f"passive (held-out) modes: RMS Δf {after['rms_freq_dev_pct_passive_before']:.2f} % → "
               f"{after['rms_freq_dev_pct_passive_after']:.2f} %; active: {after['rms_freq_dev_pct_active_before']:.2f} % → "
               f"{after['rms_freq_dev_pct_active_after']:.2f} %")
    for w in after["worse"]:
        typer.echo(f"warning: test mode {w['test']} is worse after adding the effect: Δf {w['freq_dev_pct_before']:+.2f} % "
                   f"→ {w['freq_dev_pct_after']:+.2f} % (beyond 2σ of the stated noise)")


def _surface_figure(rep: dict, diag, model, test):
    """The element indicator as a colour map on the shells, with the test's sensor grids
    and the patch of the first-ranked effect when it names elements; None for a model
    without shells."""
    from ..report import plot_surface

    if len(model.quads.ids) + len(model.trias.ids) == 0:
        return None
    effects = rep.get("effects") or []
    patch = effects[0] if effects and effects[0].get("eids") else None
    return plot_surface(model, diag.element_scores, sensors=np.asarray(test.sensors.nodes).tolist(), patch=patch,
                        label="element indicator",
                        title="where it fails: shell elements (sensitivity + residual force)")


def _figures(rep: dict, diag, confirmation, model, test, report: Path) -> dict:
    """The report's plots: comparison, localisation, ranking and, with an effect added, after."""
    import identification as corr

    from ..report import (
        plot_convergence,
        plot_damping,
        plot_effect_ranking,
        plot_freq_dev,
        plot_mac,
        plot_structure,
    )

    f_e, phi_e = np.asarray(test.frequencies_hz), np.asarray(test.shapes)
    f_a, phi_a = diag.sensor_modes
    dev = np.full(len(f_e), np.nan)
    for row in rep["paired_modes"]:
        dev[row["test"] - 1] = row["freq_dev_pct"]
    figures = {
        "mac": plot_mac(np.asarray(corr.mac(phi_a, phi_e)).T, mode_labels(f_e), mode_labels(f_a), report / "mac.png",
                        "MAC: test vs baseline model"),
        "freq_dev": plot_freq_dev(dev, None, mode_labels(f_e), report / "freq_dev.png"),
        "localisation_groups": plot_structure(model, diag.element_scores, None, label="element indicator",
                                              title="where it fails: elements (sensitivity + residual force)"),
        "localisation_nodes": plot_structure(model, None, diag.node_scores, label="grid indicator",
                                             title="where it fails: grids"),
        "effects": plot_effect_ranking(rep["effects"]),
    }
    surface = _surface_figure(rep, diag, model, test)
    if surface is not None:
        figures["localisation_surface"] = surface
    if confirmation is not None:
        res = confirmation.after
        active = ~confirmation.passive
        rows = rep["after"]["paired_modes"]
        figures["freq_dev_after"] = plot_freq_dev(
            np.array([r["freq_dev_pct_before"] if r["freq_dev_pct_before"] is not None else np.nan for r in rows]),
            np.array([r["freq_dev_pct_after"] if r["freq_dev_pct_after"] is not None else np.nan for r in rows]),
            mode_labels(f_e), report / "freq_dev_after.png", active=active)
        f_u, phi_u = res.sensor_modes["after"]
        figures["mac_after"] = plot_mac(np.asarray(corr.mac(phi_u, phi_e)).T, mode_labels(f_e), mode_labels(f_u),
                                        report / "mac_after.png", "MAC after adding the effect")
        figures["convergence"] = plot_convergence(res.history, res.names, report / "convergence.png", active=active)
    if "damping" in rep:
        figures["damping"] = plot_damping(rep["damping"], report / "damping.png")
    if "frf" in rep and (report / "frf.png").exists():
        figures["frf"] = report / "frf.png"
    return figures


def _shape_views(diag, confirmation, test, gmap, params, options, report: Path,
                 test_content: dict | None = None) -> dict[str, str]:
    """The 3-D views of test and model mode shapes next to the report: the initial model
    (``shapes.html``) and, with an effect added, the updated model (``shapes_after.html``),
    each paired anew with the parameter file's thresholds; {link text: file name}. A view
    that cannot be made is a warning, not the loss of the report."""
    import jaxfem
    from identification import observation_matrix, pair_modes

    from .. import eigensolver_name, n_model_modes
    from ..report import correlation_view, measured_geometry

    limits = {} if params is None else {"min_mac": params.options.min_mac,
                                        "max_freq_dev": params.options.max_freq_dev}
    models = [("the initial model", "shapes.html", diag.model)]
    if confirmation is not None:
        models.append(("the model with the effect, updated", "shapes_after.html", confirmation.after.model))
    solver = eigensolver_name(options.eigensolver, params)  # as diagnose: else the parameter file's
    f_e, phi_e = np.asarray(test.frequencies_hz), np.asarray(test.shapes)
    views = {}
    try:
        nodes, lines, names = measured_geometry(test_content, gmap)
        for label, name, m in models:
            lam, phi = jaxfem.modes(m, n_model_modes(m, len(f_e)), solver=solver)
            at = observation_matrix(m, test.sensors)[0] @ np.asarray(phi)
            pairing = pair_modes(np.asarray(jaxfem.frequencies_hz(lam)), at, f_e, phi_e, **limits)
            path = correlation_view(report / name, model=m, phi=np.asarray(phi), test=test, at_sensors=at,
                                    pairing=pairing, test_nodes=nodes, test_lines=lines, names=names,
                                    title=f"mode shapes: test vs {label}")
            views[f"test vs {label} ({len(pairing.test)} pairs)"] = name
            typer.echo(f"wrote {path}")
    except ValueError as err:
        typer.echo(f"warning: 3-D mode-shape view not written: {err}", err=True)
    return views


def diagnosis(model, test, params, *, model_name: str, test_name: str, json_out: Path | None,
              report: Path | None, frf_path: Path | None = None, options=None, reference: dict | None = None,
              gmap=None, test_content: dict | None = None) -> dict:
    """Diagnose, add the winning effect, update, print, write JSON and the HTML report
    (``reference``: the reference state's file and per-mode change, when the test is a change;
    ``gmap``: the test geometry's map onto the model; ``test_content``: what was read
    from the test file (:func:`identification.read_uff`), for the 3-D view's test nodes and lines)."""
    from .. import json_safe
    from ..diagnosis import DiagnoseOptions, diagnose
    from ..report import write_report

    def say(line: str) -> None:
        typer.echo(f"[diagnose] {line}", err=True)

    options = options or DiagnoseOptions()
    try:
        diag = diagnose(model, test, params, options=options, progress=say)
    except (ImportError, ConnectionError) as err:
        if not options.ray:
            raise
        fail(f"--ray {options.ray}: {err}")
    except ValueError as err:
        fail(f"cannot diagnose {model_name} against {test_name}: {err}")
    rep = dict(diag.to_json(), model=model_name, test=test_name)
    if reference is not None:
        rep["reference"] = reference
    if gmap is not None:
        rep["test_geometry"] = gmap.to_json()
    _print_diagnosis(rep)
    confirmation = diag.confirmation
    if confirmation is not None:
        rep["after"] = confirmation.to_json()
        _print_confirmation(rep["after"])
    if frf_path is not None and confirmation is not None:
        rep["frf"] = frf_prediction(frf_path, test, model, confirmation.after.model, report, gmap)
    if json_out is not None:
        write_json(json_out, rep)
    if report is not None:
        try:
            report.mkdir(parents=True, exist_ok=True)
            figures = _figures(rep, diag, confirmation, model, test, report)
            views = _shape_views(diag, confirmation, test, gmap, params, options, report, test_content)
            written = write_report(json_safe(rep), figures, report / "report.html", links=views)
        except OSError as err:
            fail(f"cannot write the report to {report}: {err}")
        typer.echo(f"wrote {written}")
    return rep


@geometry_options
def diagnose(
    model_path: ModelArg,
    test_path: TestArg,
    json_out: Annotated[Path, typer.Option("--json", dir_okay=False, help="write diagnosis.json")],
    report: Annotated[Path | None, typer.Option("--report", help="directory for report.html and its PNG plots")] = None,
    params_path: Annotated[Path | None, typer.Option("--params", metavar="PARAMS.toml", exists=True, dir_okay=False,
                                                     help="the engineer's updating parameters (the baseline)")] = None,
    frf_path: Annotated[Path | None, typer.Option("--frf", exists=True, dir_okay=False,
                                                  help="measured FRFs (UFF 58) predicted before/after")] = None,
    noise_freq: Annotated[float, typer.Option("--noise-freq", help="expected frequency error, % (1σ)")] = 0.2,
    noise_shape: Annotated[float, typer.Option("--noise-shape", help="expected shape error per component, % (1σ)")] = 1.0,
    noise_damping: Annotated[float, typer.Option(
        "--noise-damping", help="expected error of measured damping ratios, % of each ratio (1σ); used when TEST "
                                "has damping ratios of at least four modes")] = 10.0,
    solver: SolverOpt = None,
    geometry: Geometry = DEFAULT_GEOMETRY,
    allow_unsupported: AllowUnsupportedOpt = False,
    spc_set: SpcSetOpt = None,
    mpc_set: MpcSetOpt = None,
    subcase: SubcaseOpt = None,
    reference_path: Annotated[Path | None, typer.Option(
        "--reference", metavar="HEALTHY.uff", exists=True, dir_okay=False,
        help="modes of a reference state (e.g. before the damage) at the same sensors: diagnose the change "
             "between it and TEST, carried onto the model's modes (its own error cancels); state the noise "
             "of a difference")] = None,
    ray: Annotated[str | None, typer.Option(
        "--ray", metavar="ADDRESS", help="fit the candidates on a Ray cluster: 'local' (start one here), 'auto' "
                                         "(the cluster of this node) or ray://HEAD:10001 (needs jaxfem[ray])")] = None,
) -> None:
    """Where does the model fail, and which physical effect is missing? Localise the error,
    rank candidate effects by Bayesian evidence, test the most probable on held-out modes,
    add it and update again."""
    from .. import Noise
    from ..diagnosis import DiagnoseOptions

    check_plots(report)
    if not (noise_freq > 0 and noise_shape > 0 and noise_damping > 0):
        fail("--noise-freq, --noise-shape and --noise-damping must be positive (percent)")
    model, test, _, params, gmap, content = load_inputs(model_path, test_path, params_path, solver,
                                               geometry,
                                               allow_unsupported, (spc_set, mpc_set, subcase))
    change = None
    if reference_path is not None:
        test, change = _relative(model, test, reference_path, check_solver(solver) or "auto", gmap)
    noise = Noise(frequency=noise_freq / 100, relative=noise_shape / 100, damping=noise_damping / 100)
    options = DiagnoseOptions(noise=noise, eigensolver=check_solver(solver), ray=ray)
    diagnosis(model, test, params, model_name=model_path.name, test_name=test_path.name, json_out=json_out,
              report=report, frf_path=frf_path, options=options,
              reference=None if change is None else {"file": reference_path.name, "modes": change}, gmap=gmap,
              test_content=content)


def _relative(model, test, reference_path: Path, solver: str, gmap):
    """The change from the reference test to the test, on the model's modes
    (:func:`updating.relative_to`); the per-mode change printed. The reference is read
    at the test's nodes (``gmap``)."""
    from identification import observation_matrix

    from ..diagnosis import relative_to

    reference = gmap.apply(load_test(reference_path))
    try:
        observation_matrix(model, reference.sensors)
        data, rows = relative_to(model, test, reference, solver=solver)
    except ValueError as err:
        fail(f"reference {reference_path}: {err}")
    typer.echo(f"change from {reference_path.name}: {len(data.frequencies_hz)} of {len(rows)} reference modes "
               "paired with the test and the model")
    typer.echo(f"{'ref':>4} {'f_ref [Hz]':>11} {'f_test [Hz]':>12} {'change [%]':>11}")
    for r in rows:
        typer.echo(f"{r['reference_mode']:>4} {r['f_reference_hz']:>11.3f} {_fmt(r['f_test_hz'], '>12.3f')} "
                   f"{_fmt(r['change_pct'], '>+11.3f')}")
    return data, rows

