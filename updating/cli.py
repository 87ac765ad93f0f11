"""The ``jaxfem`` command line."""

from __future__ import annotations

import json
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Annotated, NoReturn

import numpy as np
import typer

from ._report import json_number, json_safe

# plain click errors: a rich error panel cuts long paths short ("File ... does not exist")
app = typer.Typer(add_completion=False, no_args_is_help=True, help=__doc__, rich_markup_mode=None)
ModelArg = Annotated[Path, typer.Argument(metavar="MODEL.bdf", exists=True, dir_okay=False,
                                          help="Nastran bulk data (SI units)")]
TestArg = Annotated[Path, typer.Argument(metavar="TEST.uff", exists=True, dir_okay=False,
                                         help="universal file with the measured modes (dataset 55)")]


@app.callback()
def _main() -> None:
    """Differentiable structural dynamics: FE models, modes and model updating (SI units)."""
    import jax

    jax.config.update("jax_enable_x64", True)


def _modes_table(path: Path, n_modes: int) -> dict:
    import jaxfem
    from jaxfem.io import read_bdf

    bulk = read_bdf(path)
    model = jaxfem.build_model(bulk)
    n_modes = min(n_modes, model.n_dof - len(model.dofs.massless))
    K, M = jaxfem.assemble(model)
    lam, _ = jaxfem.eigh(K, M, n_modes)
    freqs = [float(f) for f in jaxfem.frequencies_hz(lam)]
    return {
        "model": str(path),
        "n_dof": int(model.n_dof),
        "n_massless": len(model.dofs.massless),
        "auto_spc": [[int(a), int(b)] for a, b in model.dofs.auto_spc],
        "unknown_cards": sorted(bulk.unknown),
        "eigenvalues": [float(x) for x in lam],
        "frequencies_hz": freqs,
    }


def _print_table(result: dict) -> None:
    typer.echo(f"model {result['model']}: {result['n_dof']} DoFs after constraints "
               f"({result['n_massless']} massless, condensed; {len(result['auto_spc'])} auto-SPC)")
    if result["unknown_cards"]:
        typer.echo(f"warning: unsupported cards ignored: {', '.join(result['unknown_cards'])}", err=True)
    typer.echo(f"{'mode':>5}  {'f [Hz]':>12}  {'λ = ω² [rad²/s²]':>18}")
    for i, (f, lam) in enumerate(zip(result["frequencies_hz"], result["eigenvalues"]), 1):
        typer.echo(f"{i:>5}  {f:>12.4f}  {lam:>18.6e}")


@app.command()
def modes(
    model: Annotated[Path, typer.Argument(exists=True, dir_okay=False, help="Nastran bulk data (SI units)")],
    n: Annotated[int, typer.Option("-n", "--n-modes", help="number of modes")] = 10,
    json_out: Annotated[Path | None, typer.Option("--json", help="write results as JSON")] = None,
) -> None:
    """Natural frequencies of a bulk-data model."""
    result = _modes_table(model, n)
    _print_table(result)
    if json_out:
        json_out.write_text(json.dumps(result, indent=2))
        typer.echo(f"wrote {json_out}")


@app.command()
def demo(
    out: Annotated[Path, typer.Option("--out", help="directory for the case, diagnosis.json and the report")] = Path("jaxfem-demo"),
) -> None:
    """The main job on an embedded case: the GARTEUR SM-AG19 model and modes "measured" on
    a truth with a hidden effect and noise. Diagnose, rank the candidate effects, add the
    winner, update again and write the report (a few minutes on 2 cores)."""
    import time

    from ._demo import HIDDEN, PARAMETERS, demo_case

    start = time.perf_counter()
    typer.echo(f"simulating the measurement (hidden from the diagnosis: {HIDDEN}; fuselage stiffness +6 %; "
               "noise 0.2 % on frequencies, 1 % on shapes) ...", err=True)
    model_path, test_path = demo_case(out)
    typer.echo(f"case: {model_path} (nominal model), {test_path} (14 modes at 24 sensors); engineer's parameters: "
               + ", ".join(f"{p.name} ({p.kind} of pids {list(p.pids)})" for p in PARAMETERS.parameters))
    model = _load_model(model_path)
    test = _load_test(test_path)
    _diagnosis(model, test, PARAMETERS, model_name=model_path.name, test_name=test_path.name,
               json_out=out / "diagnosis.json", report=out / "report")
    typer.echo(f"demo done in {time.perf_counter() - start:.0f} s")


# --- correlation and updating -------------------------------------------------------------


def _fail(message: str) -> NoReturn:
    """One-line error on stderr, exit code 2 (usage / input error), no traceback."""
    typer.echo("error: " + " ".join(str(message).split()), err=True)
    raise typer.Exit(2)


def _echo_warnings(caught: list[warnings.WarningMessage]) -> None:
    for w in caught:
        typer.echo("warning: " + " ".join(str(w.message).split()), err=True)


def _load_model(path: Path):
    import jaxfem
    from jaxfem.io import read_bdf

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            bulk = read_bdf(path)
            model = jaxfem.build_model(bulk)
        except (ValueError, OSError) as err:
            _fail(f"cannot read model {path}: {err}")
    _echo_warnings(caught)
    if bulk.unknown:
        typer.echo(f"warning: unsupported cards ignored: {', '.join(sorted(bulk.unknown))}", err=True)
    return model


def _frf_prediction(path: Path, test, initial, updated, plots: Path | None) -> dict:
    """Measured FRFs against the initial and updated model's predictions (FRAC, dB)."""
    from identification import read_uff

    from ._prediction import frf_correlation, predict_frf

    try:
        frf = read_uff(path)["frfs"]
    except (ValueError, OSError, ImportError) as err:
        _fail(f"cannot read FRFs {path}: {err}")
    if frf is None:
        _fail(f"{path}: no FRFs (UFF dataset 58) in the file")
    ratios = np.asarray(test.damping_ratios)
    zeta = float(np.mean(ratios[ratios > 0])) if np.any(ratios > 0) else 0.01
    try:
        predicted = {key: predict_frf(m, frf, zeta=zeta) for key, m in (("before", initial), ("after", updated))}
    except ValueError as err:
        _fail(f"{path}: {err}")
    corr = {key: frf_correlation(frf.values, h) for key, h in predicted.items()}
    pairs = []
    for o, out in enumerate(frf.outputs.labels):
        for i, inp in enumerate(frf.inputs.labels):
            pairs.append({"output": out, "input": inp,
                          **{f"frac_{k}": float(corr[k]["frac"][o, i]) for k in corr},
                          **{f"mean_abs_db_{k}": float(corr[k]["mean_abs_db"][o, i]) for k in corr}})
            typer.echo(f"FRF {out} / {inp}: FRAC {pairs[-1]['frac_before']:.3f} → {pairs[-1]['frac_after']:.3f}, "
                       f"mean |Δ| {pairs[-1]['mean_abs_db_before']:.2f} → {pairs[-1]['mean_abs_db_after']:.2f} dB")
    if plots is not None:
        from ._plots import plot_frf_overlay

        unit = {"receptance": "m/N", "mobility": "m/(s·N)", "accelerance": "m/(s²·N)"}[frf.kind]
        plot_frf_overlay(frf.frequencies_hz, frf.values[:, 0, 0],
                         {"initial model": predicted["before"][:, 0, 0], "updated model": predicted["after"][:, 0, 0]},
                         f"{frf.outputs.labels[0]} / {frf.inputs.labels[0]}", plots / "frf.png", unit)
    return {"zeta": zeta, "kind": frf.kind, "pairs": pairs}


def _load_test(path: Path):
    """The measured modes of a universal file, as real normal modes."""
    from identification import read_uff

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            modes = read_uff(path)["modes"]
        except (ValueError, OSError, ImportError) as err:
            _fail(f"cannot read test data {path}: {err}")
    _echo_warnings(caught)
    if modes is None:
        _fail(f"test data {path}: no mode shapes (UFF dataset 55) in the file")
    return modes.real()


def _observation(model, test, path: Path) -> np.ndarray:
    from identification import observation_matrix

    try:
        return observation_matrix(model, test.sensors)[0]
    except ValueError as err:
        _fail(f"test data {path}: {err}")


def _load_inputs(model_path: Path, test_path: Path, params_path: Path | None = None):
    """Model, real test modes, observation matrix and the parameter set (None without a
    file), checked against each other; on bad input exit 2 naming the file."""
    from ._parameters import ParameterSet, parameterise

    params = None
    if params_path is not None:
        try:
            params = ParameterSet.from_toml(params_path)
        except (ValueError, OSError) as err:
            _fail(f"bad parameter file: {err}")
    model = _load_model(model_path)
    test = _load_test(test_path)
    C = _observation(model, test, test_path)  # unknown sensor grids: exit 2 naming them
    if params is not None:
        try:
            parameterise(model, params)
        except ValueError as err:
            _fail(f"{params_path}: {err}")
    return model, test, C, params


def _n_model_modes(model, n_test: int, requested: int | None) -> int:
    n_free = model.n_dof - len(model.dofs.massless)
    return int(min(n_free, max(2 * n_test + 6, requested or 0)))


def _model_modes(model, C: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Model frequencies (Hz) and shapes at the sensors ``C φ``."""
    import jaxfem

    lam, phi = jaxfem.modes(model, n)
    return np.asarray(jaxfem.frequencies_hz(lam)), C @ np.asarray(phi)


def _labels(freqs) -> list[str]:
    return [f"{i} ({f:.1f})" for i, f in enumerate(np.asarray(freqs).tolist(), 1)]


def _print_pairing(p) -> None:
    typer.echo(f"{'test':>5} {'model':>6} {'f_test [Hz]':>12} {'f_model [Hz]':>13} {'Δf [%]':>8} {'MAC':>6}")
    for t, m, ft, fm, d, c in p.table():
        if m is None:
            typer.echo(f"{t:>5} {'–':>6} {ft:>12.4f} {'–':>13} {'–':>8} {'–':>6}")
        else:
            typer.echo(f"{t:>5} {m:>6} {ft:>12.4f} {fm:>13.4f} {d:>+8.2f} {c:>6.3f}")
    for line in p.warnings:
        typer.echo(f"warning: {line}", err=True)


def _check_plots(plots: Path | None) -> None:
    if plots is None:
        return
    from ._plots import require_matplotlib

    try:
        require_matplotlib()
    except ImportError as err:
        _fail(str(err))
    if plots.exists() and not plots.is_dir():
        _fail(f"--plots {plots} exists and is not a directory")


def _write_json(path: Path, data: dict) -> None:
    path.write_text(json.dumps(data, indent=2, allow_nan=False))
    typer.echo(f"wrote {path}")


@app.command()
def correlate(
    model_path: ModelArg,
    test_path: TestArg,
    json_out: Annotated[Path, typer.Option("--json", help="write results as JSON")],
    plots: Annotated[Path | None, typer.Option("--plots", help="directory for PNG plots (needs matplotlib, the plot extra)")] = None,
    n: Annotated[int | None, typer.Option("-n", "--n-modes",
                                          help="model modes to compute (at least 2 × test modes + 6)")] = None,
    min_mac: Annotated[float, typer.Option("--min-mac", help="pairing threshold on MAC")] = 0.65,
    max_freq_dev: Annotated[float, typer.Option("--max-freq-dev", help="pairing threshold on |Δf| (fraction)")] = 0.30,
) -> None:
    """Correlate model and test modes: pairing by MAC and Δf, AutoMAC, COMAC."""
    from . import _correlation as corr

    _check_plots(plots)
    model, test, C, _ = _load_inputs(model_path, test_path)
    ne = test.n_modes
    n_model = _n_model_modes(model, ne, n)
    f_a, phi_a = _model_modes(model, C, n_model)
    f_e, phi_e = np.asarray(test.frequencies_hz), np.asarray(test.shapes)
    try:
        pairing = corr.pair_modes(f_a, phi_a, f_e, phi_e, min_mac=min_mac, max_freq_dev=max_freq_dev)
    except ValueError as err:
        _fail(str(err))
    auto = np.asarray(corr.automac(phi_e))
    labels = test.sensors.labels
    if pairing.test.size:
        co = np.asarray(corr.comac(phi_a[:, pairing.model], phi_e[:, pairing.test]))
        order = np.argsort(co, kind="stable")
        comac_rows = [{"sensor": labels[i], "value": float(co[i])} for i in order]
    else:
        comac_rows = []
    result = {"model": str(model_path), "test": str(test_path), "n_model_modes": n_model,
              "min_mac": pairing.min_mac, "max_freq_dev": pairing.max_freq_dev,
              **pairing.summary(),
              "automac": auto.tolist(), "comac": comac_rows}

    typer.echo(f"model {model_path}: {model.n_dof} DoFs, {n_model} modes; test {test_path}: "
               f"{ne} modes at {len(labels)} sensors")
    typer.echo(f"pairing: MAC ≥ {pairing.min_mac:.2f}, |Δf| ≤ {100 * pairing.max_freq_dev:.0f} %")
    _print_pairing(pairing)
    if result["paired_modes"]:
        typer.echo(f"paired {len(result['paired_modes'])}/{ne}: RMS Δf {result['rms_freq_dev_pct']:.2f} %, "
                   f"mean MAC {result['mean_mac']:.3f}")
    typer.echo("AutoMAC of the test shapes:")
    typer.echo("      " + "".join(f"{j:>6}" for j in range(1, ne + 1)))
    for i, row in enumerate(auto, 1):
        typer.echo(f"{i:>6}" + "".join(f"{v:>6.2f}" for v in row))
    typer.echo("COMAC per sensor (lowest first):")
    for row in comac_rows:
        typer.echo(f"  {row['sensor']:>12} {row['value']:.3f}")
    _write_json(json_out, result)
    if plots is not None:
        from ._plots import plot_freq_dev, plot_mac

        written = [
            plot_mac(np.asarray(corr.mac(phi_a, phi_e)).T, _labels(f_e), _labels(f_a), plots / "mac.png",
                     f"MAC: {test_path.name} vs {model_path.name}"),
            plot_freq_dev(pairing.per_test()[0], None, _labels(f_e), plots / "freq_dev.png"),
        ]
        typer.echo("wrote " + ", ".join(str(w) for w in written))


@app.command()
def update(
    model_path: ModelArg,
    test_path: TestArg,
    params_path: Annotated[Path, typer.Option("--params", metavar="PARAMS.toml", exists=True, dir_okay=False,
                                              help="updating parameters and options (TOML, schema in README)")],
    json_out: Annotated[Path, typer.Option("--json", help="write results as JSON")],
    plots: Annotated[Path | None, typer.Option("--plots", help="directory for PNG plots (needs matplotlib, the plot extra)")] = None,
    frf_path: Annotated[Path | None, typer.Option("--frf", exists=True, dir_okay=False,
                                                  help="measured FRFs (UFF 58) to predict before/after")] = None,
    add_effect: Annotated[list[str] | None, typer.Option(
        "--add-effect", metavar="KIND:TARGET",
        help="add a physical effect and update its parameters too, e.g. joint:node=6001, "
             "added_mass:node=2015, frequency_dependent_stiffness:pid=41 (repeatable)")] = None,
) -> None:
    """Update model parameters so that the model modes match the test modes.

    With ``--add-effect``, each effect is added to the model at its starting values (a
    slightly flexible joint or support, 1 % of the mass, a = 0, ...) and its parameters
    are updated with the others (``updating.at_reference``, ``effect_parameters``).

    With ``--frf``, the measured FRFs are predicted by the initial and the updated model
    (modal superposition, viscous ratio = mean measured modal damping, else 1 %) and
    compared by FRAC and mean |Δ| in dB (validation by prediction, thesis §4.2.5.3).
    """
    from . import _correlation as corr
    from ._solve import update as run_update

    _check_plots(plots)
    model, test, _, params = _load_inputs(model_path, test_path, params_path)
    if add_effect:
        from ._diagnose import start_values
        from ._effects import effect_parameters, parse_effect

        extra = []
        for spec in add_effect:
            try:
                effect = start_values(model, test, parse_effect(spec), params.options)
                extended = effect.apply(model)
            except (ValueError, KeyError) as err:
                _fail(f"--add-effect {spec}: {err}")
            extra += [replace(p, name=f"{p.name}_{len(extra) + 1}") for p in effect_parameters(effect, model, extended)]
            typer.echo(f"added {effect.kind} at {effect.where()}: starting values "
                       + ", ".join(f"{k} = {v:.4g}" for k, v in effect.values.items()))
            model = extended
        params = replace(params, parameters=tuple(params.parameters) + tuple(extra))
    opts = params.options
    ne = test.n_modes
    names = params.names
    last = {}

    def progress(it) -> None:
        alpha = np.asarray(it.alpha)
        step = "–" if "alpha" not in last else f"{np.max(np.abs(alpha - last['alpha'])):.3e}"
        last["alpha"] = alpha
        typer.echo(f"iteration {it.iteration:3d}  cost {it.cost:.6e}  max|Δα| {step}", err=True)

    try:
        res = run_update(model, test, params, progress=progress)
    except ValueError as err:
        _fail(f"{params_path}: {err}")

    active = np.asarray(res.active, dtype=bool)
    param_rows = []
    for p, a in zip(params.parameters, res.alpha):
        lo, hi = p.bounds
        param_rows.append({"name": p.name, "kind": p.kind, "alpha": float(a), "bounds": [lo, hi],
                           "within_bounds": bool(lo <= a <= hi)})
    result = {
        "model": str(model_path), "test": str(test_path), "parameters_file": str(params_path),
        "parameters": param_rows,
        "converged": bool(res.converged),
        "iterations": int(res.iterations),
        "seconds": float(res.seconds),
        "history": [
            {"iteration": int(h.iteration),
             "alpha": {name: float(a) for name, a in zip(names, np.asarray(h.alpha))},
             "freq_dev_pct": [json_number(100.0 * d) for d in np.asarray(h.freq_dev)],
             "mac": [json_number(m) for m in np.asarray(h.mac)],
             "cost": float(h.cost)}
            for h in res.history
        ],
        "before": res.before.summary(),
        "after": res.after.summary(),
        "active_modes": [int(j) + 1 for j in np.flatnonzero(active)],
        "passive_modes": [int(j) + 1 for j in np.flatnonzero(~active)],
    }

    status = "converged" if res.converged else "NOT converged"
    typer.echo(f"{status} after {res.iterations} iterations ({res.seconds:.1f} s; tolerance on max|Δα| "
               f"{opts.tolerance:g})")
    typer.echo(f"{'parameter':>12} {'kind':>10} {'α':>12} {'bounds':>16}  within")
    for row in param_rows:
        lo, hi = row["bounds"]
        typer.echo(f"{row['name']:>12} {row['kind']:>10} {row['alpha']:>+12.6f} {f'[{lo:g}, {hi:g}]':>16}  "
                   f"{'yes' if row['within_bounds'] else 'NO'}")
        if not row["within_bounds"]:
            typer.echo(f"warning: parameter {row['name']} α = {row['alpha']:+.4f} is outside its bounds "
                       f"[{lo:g}, {hi:g}]", err=True)
    if frf_path is not None:
        result["frf"] = _frf_prediction(frf_path, test, model, res.model, plots)
    before, after = res.before.table(), res.after.table()
    typer.echo(f"{'test':>5} {'role':>7} {'f_test [Hz]':>12} | {'before: model':>13} {'f [Hz]':>10} "
               f"{'Δf [%]':>8} {'MAC':>6} | {'after: model':>12} {'f [Hz]':>10} {'Δf [%]':>8} {'MAC':>6}")

    def cells(row, width):
        _, m, _, fm, d, c = row
        if m is None:
            return f"{'–':>{width}} {'–':>10} {'–':>8} {'–':>6}"
        return f"{m:>{width}} {fm:>10.4f} {d:>+8.2f} {c:>6.3f}"

    for j, (b, a) in enumerate(zip(before, after)):
        role = "active" if active[j] else "passive"
        typer.echo(f"{b[0]:>5} {role:>7} {b[2]:>12.4f} | {cells(b, 13)} | {cells(a, 12)}")
    for line in res.after.warnings:
        typer.echo(f"warning (after): {line}", err=True)
    for key in ("before", "after"):
        p = result[key]
        if p["paired_modes"]:
            typer.echo(f"{key}: paired {len(p['paired_modes'])}/{ne}, RMS Δf {p['rms_freq_dev_pct']:.3f} %, "
                       f"mean MAC {p['mean_mac']:.4f}")
    _write_json(json_out, result)
    if plots is not None:
        from ._plots import plot_convergence, plot_freq_dev, plot_mac

        f_e, phi_e = np.asarray(test.frequencies_hz), np.asarray(test.shapes)
        written = []
        for key in ("before", "after"):
            f_a, phi_a = res.sensor_modes[key]
            written.append(plot_mac(np.asarray(corr.mac(phi_a, phi_e)).T, _labels(f_e), _labels(f_a),
                                    plots / f"mac_{key}.png", f"MAC {key} updating"))
        written.append(plot_freq_dev(res.before.per_test()[0], res.after.per_test()[0], _labels(f_e),
                                     plots / "freq_dev.png", active=active))
        written.append(plot_convergence(res.history, names, plots / "convergence.png", active=active))
        typer.echo("wrote " + ", ".join(str(w) for w in written))


# --- diagnosis ----------------------------------------------------------------------------


def _diagnosis(model, test, params, *, model_name: str, test_name: str, json_out: Path | None,
               report: Path | None, frf_path: Path | None = None, options=None) -> dict:
    """Diagnose, add the winning effect, update, print, write JSON and the HTML report."""
    from . import _correlation as corr
    from ._diagnose import DiagnoseOptions, add_effect, diagnose

    def say(line: str) -> None:
        typer.echo(f"[diagnose] {line}", err=True)

    diag = diagnose(model, test, params, options=options or DiagnoseOptions(), progress=say)
    rep = dict(diag.report, model=model_name, test=test_name)
    b = rep["baseline"]
    typer.echo(f"baseline: RMS Δf {b['rms_freq_dev_pct']:.2f} %, mean MAC {b['mean_mac']:.3f}, "
               f"held-out RMS Δf {b['heldout_rms_freq_dev_pct']:.2f} %, χ²/row {b['chi2_per_row']:.2f}")
    typer.echo("where it fails (combined indicator, property groups): " + ", ".join(
        f"pid {g['pid']} {g['score']:.2f}" for g in rep["localisation"]["groups"][:5]))
    typer.echo("                                              (grids): " + ", ".join(
        f"{n['node']} {n['score']:.2f}" for n in rep["localisation"]["nodes"][:5]))
    typer.echo(f"{'rank':>4} {'effect':<34} {'score':>6} {'ΔAIC':>8} {'held-out Δf [%]':>16}  warranted")
    def fmt(x, spec):
        return format(x, spec) if x is not None and np.isfinite(x) else format("–", spec.split(".")[0])

    for e in rep["effects"][:10]:
        where = f"{e['kind']} {e['where']}"[:34]
        notes = "  (" + "; ".join(e["plausibility"]) + ")" if e["plausibility"] else ""
        typer.echo(f"{e['rank']:>4} {where:<34} {fmt(e['score'], '>6.1f')} {e['delta_aic']:>8.1f} "
                   f"{fmt(e['heldout_rms_freq_dev_pct_before'], '>7.2f')} → "
                   f"{fmt(e['heldout_rms_freq_dev_pct_after'], '<6.2f')}  {'yes' if e['warranted'] else 'no'}{notes}")
    typer.echo(rep["verdict"])
    confirmation = None
    if diag.best is not None:
        typer.echo(f"adding {diag.best.kind} at {diag.best.where()} and updating again "
                   "(passive modes held out of the fit):")

        def progress(it) -> None:
            typer.echo(f"[update] iteration {it.iteration:3d}  cost {it.cost:.4e}", err=True)

        confirmation = add_effect(model, test, diag.best, params, progress=progress)
        after = confirmation.report
        rep["after"] = after
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
    if frf_path is not None and confirmation is not None:
        rep["frf"] = _frf_prediction(frf_path, test, model, confirmation.after.model, report)
    if json_out is not None:
        _write_json(json_out, json_safe(rep))
    if report is not None:
        from ._plots import (
            plot_convergence,
            plot_effect_ranking,
            plot_freq_dev,
            plot_mac,
            plot_structure,
        )
        from ._report import write_report

        report.mkdir(parents=True, exist_ok=True)
        f_e, phi_e = np.asarray(test.frequencies_hz), np.asarray(test.shapes)
        f_a, phi_a = diag.sensor_modes
        dev = np.full(len(f_e), np.nan)
        for row in rep["paired_modes"]:
            dev[row["test"] - 1] = row["freq_dev_pct"]
        figures = {
            "mac": plot_mac(np.asarray(corr.mac(phi_a, phi_e)).T, _labels(f_e), _labels(f_a), report / "mac.png",
                            "MAC: test vs baseline model"),
            "freq_dev": plot_freq_dev(dev, None, _labels(f_e), report / "freq_dev.png"),
            "localisation_groups": plot_structure(model, diag.element_scores, None, label="element indicator",
                                                  title="where it fails: elements (sensitivity + residual force)"),
            "localisation_nodes": plot_structure(model, None, diag.node_scores, label="grid indicator",
                                                 title="where it fails: grids"),
            "effects": plot_effect_ranking(rep["effects"]),
        }
        if confirmation is not None:
            res = confirmation.after
            active = ~confirmation.passive
            figures["freq_dev_after"] = plot_freq_dev(
                np.array([r["freq_dev_pct_before"] if r["freq_dev_pct_before"] is not None else np.nan for r in rep["after"]["paired_modes"]]),
                np.array([r["freq_dev_pct_after"] if r["freq_dev_pct_after"] is not None else np.nan for r in rep["after"]["paired_modes"]]),
                _labels(f_e), report / "freq_dev_after.png", active=active)
            f_u, phi_u = res.sensor_modes["after"]
            figures["mac_after"] = plot_mac(np.asarray(corr.mac(phi_u, phi_e)).T, _labels(f_e), _labels(f_u),
                                            report / "mac_after.png", "MAC after adding the effect")
            figures["convergence"] = plot_convergence(res.history, res.names, report / "convergence.png", active=active)
        if "frf" in rep and (report / "frf.png").exists():
            figures["frf"] = report / "frf.png"
        path = write_report(json_safe(rep), figures, report / "report.html")
        typer.echo(f"wrote {path}")
    return rep


@app.command()
def diagnose(
    model_path: ModelArg,
    test_path: TestArg,
    json_out: Annotated[Path, typer.Option("--json", help="write diagnosis.json")],
    report: Annotated[Path | None, typer.Option("--report", help="directory for report.html and its PNG plots")] = None,
    params_path: Annotated[Path | None, typer.Option("--params", metavar="PARAMS.toml", exists=True, dir_okay=False,
                                                     help="the engineer's updating parameters (the baseline)")] = None,
    frf_path: Annotated[Path | None, typer.Option("--frf", exists=True, dir_okay=False,
                                                  help="measured FRFs (UFF 58) predicted before/after")] = None,
    noise_freq: Annotated[float, typer.Option("--noise-freq", help="expected frequency error, % (1σ)")] = 0.2,
    noise_shape: Annotated[float, typer.Option("--noise-shape", help="expected shape error per component, % (1σ)")] = 1.0,
) -> None:
    """Where does the model fail, and which physical effect is missing? Localise the error,
    rank candidate effects by cross-validated prediction of held-out modes and AIC, add the
    best one and update again."""
    from ._diagnose import DiagnoseOptions

    if report is not None:
        _check_plots(report)
    model, test, _, params = _load_inputs(model_path, test_path, params_path)
    if not (noise_freq > 0 and noise_shape > 0):
        _fail("--noise-freq and --noise-shape must be positive (percent)")
    options = DiagnoseOptions(noise_freq=noise_freq / 100, noise_shape=noise_shape / 100)
    _diagnosis(model, test, params, model_name=model_path.name, test_name=test_path.name, json_out=json_out,
               report=report, frf_path=frf_path, options=options)


# --- identification ------------------------------------------------------------------------


@app.command()
def identify(
    frf_path: Annotated[Path, typer.Argument(metavar="FRF.uff", exists=True, dir_okay=False,
                                             help="measured FRFs (UFF 58), with coherence if available")],
    json_out: Annotated[Path, typer.Option("--json", help="write the identified modes and the diagram as JSON")],
    plots: Annotated[Path | None, typer.Option("--plots", help="directory for the stabilisation diagram (PNG)")] = None,
    modes_out: Annotated[Path | None, typer.Option("--uff", help="write the identified modes as UFF 55")] = None,
    fmin: Annotated[float | None, typer.Option("--fmin", help="lower end of the band, Hz")] = None,
    fmax: Annotated[float | None, typer.Option("--fmax", help="upper end of the band, Hz")] = None,
    min_coherence: Annotated[float, typer.Option("--min-coherence", help="lines below are left out")] = 0.5,
) -> None:
    """Modal parameters from FRFs: pLSCF stabilisation diagram, automatic selection of the
    stable poles, LSFD mode shapes, real normal modes (thesis §2.3.1)."""
    from identification import identify as run_identify
    from identification import read_uff, write_uff

    _check_plots(plots)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            frfs = read_uff(frf_path)["frfs"]
            if frfs is None:
                _fail(f"{frf_path}: no FRFs (UFF dataset 58) in the file")
            modes, report = run_identify(frfs, fmin=fmin, fmax=fmax, min_coherence=min_coherence)
        except (ValueError, OSError) as err:
            _fail(f"{frf_path}: {err}")
    _echo_warnings(caught)
    typer.echo(f"{'mode':>4} {'f [Hz]':>10} {'ζ [%]':>7} {'stable orders':>14} {'complexity':>11}")
    for i, m in enumerate(report["modes"], 1):
        typer.echo(f"{i:>4} {m['frequency_hz']:>10.4f} {100 * m['damping_ratio']:>7.3f} {m['n_orders_stable']:>14d} "
                   f"{m['complexity']:>11.3f}")
    if modes_out is not None:
        write_uff(modes_out, modes=modes)
        typer.echo(f"wrote {modes_out}")
    if plots is not None:
        from identification import plot_stabilisation

        plots.mkdir(parents=True, exist_ok=True)
        typer.echo(f"wrote {plot_stabilisation(report, plots / 'stabilisation.png')}")
    _write_json(json_out, json_safe(report))


def _dof_indices(model, spec: str, option: str) -> tuple[list[int], list[str]]:
    """Solved-DoF indices of "GRID:COMPONENT,..." (components 1–6); each must be a DoF of
    its own (not constrained, not an RBE2-dependent combination)."""
    from identification import Sensors, observation_matrix

    try:
        pairs = [item.split(":") for item in spec.split(",") if item.strip()]
        nodes, comps = [int(p[0]) for p in pairs], [int(p[1]) for p in pairs]
        C, _ = observation_matrix(model, Sensors.from_components(nodes, comps))
    except (ValueError, IndexError) as err:
        _fail(f"{option} {spec}: {err} (expected GRID:COMPONENT,..., components 1–6)")
    labels = [f"{n}:{c}" for n, c in zip(nodes, comps)]
    out = []
    for label, row in zip(labels, C):
        hit = np.flatnonzero(row)
        if len(hit) != 1 or row[hit[0]] != 1.0:
            _fail(f"{option}: {label} is not an independent DoF of the model (RBE2-dependent grid)")
        out.append(int(hit[0]))
    return out, labels


@app.command()
def appropriate(
    model_path: ModelArg,
    candidates: Annotated[str, typer.Option("--candidates", metavar="GRID:C,...",
                                            help="candidate exciter positions, e.g. 101:3,205:3")],
    n_exciters: Annotated[int, typer.Option("--exciters", help="number of exciters used together")],
    json_out: Annotated[Path, typer.Option("--json", help="write the ranking as JSON")],
    n_modes: Annotated[int, typer.Option("--modes", help="modes to appropriate (the lowest)")] = 6,
    method: Annotated[str, typer.Option("--method", help="thesis, lewis_wrisley, asher or hunt")] = "thesis",
    sensors: Annotated[str | None, typer.Option("--sensors", metavar="GRID:C,...",
                                                help="response DoFs of the MIF (default: all DoFs)")] = None,
    kappa: Annotated[float, typer.Option("--kappa", help="stiffness-proportional damping D = μM + κK, κ in s")] = 1e-3,
    mu: Annotated[float, typer.Option("--mu", help="mass-proportional damping, 1/s")] = 0.0,
    top: Annotated[int, typer.Option("--top", help="exciter sets listed per mode")] = 5,
) -> None:
    """Phase-resonance planning: the predicted MIF (eq. 3.54) of every set of ``--exciters``
    positions among the candidates, with the appropriated forces (thesis §3.4, Table 5.11)."""
    import jaxfem
    from identification import appropriation_report

    model = _load_model(model_path)
    cand, labels = _dof_indices(model, candidates, "--candidates")
    sens = _dof_indices(model, sensors, "--sensors")[0] if sensors else None
    K, M = (np.asarray(a.todense()) for a in jaxfem.assemble(model))
    names = [""] * K.shape[0]
    for i, label in zip(cand, labels):
        names[i] = label
    names = [n or f"dof {i + 1}" for i, n in enumerate(names)]
    try:
        rep = appropriation_report(K, M, {"mu": mu, "kappa": kappa}, cand, n_exciters, n_modes, method=method,
                                   sensors=sens, labels=names, top=top)
    except (ValueError, np.linalg.LinAlgError) as err:
        _fail(f"{model_path.name}: {err}")
    typer.echo(f"{'mode':>4} {'f [Hz]':>9} {'best exciters':<28} {'MIF':>7}")
    for m in rep["modes"]:
        best = m["best"]
        where = ", ".join(best["labels"]) if best else "none found"
        mif = f"{best['mif']:>7.1f}" if best else f"{'–':>7}"
        typer.echo(f"{m['mode']:>4} {m['natural_frequency_hz']:>9.3f} {where:<28} {mif}")
    _write_json(json_out, json_safe(dict(rep, model=model_path.name)))


# --- Monte-Carlo studies -------------------------------------------------------------------


def _duration(seconds: float) -> str:
    if not np.isfinite(seconds):
        return "–"
    minutes, s = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min" if hours else f"{minutes} min {s:02d} s" if minutes else f"{s} s"


def _load_study(path: Path):
    from ._montecarlo import Study

    try:
        return Study.from_toml(path)
    except (ValueError, TypeError, OSError) as err:
        message = str(err)
        _fail(message if str(path) in message else f"{path}: {message}")


def _study_header(config: Path, study, runner, devices: str) -> None:
    s = study
    total = len(s.cells) * s.samples * len(s.n_modes)
    typer.echo(f"study {config}: model {s.model.name} ({runner.reference.n_dof} DoFs), "
               f"{len(runner.sensors.labels)} sensors ({s.sensors.name}); modelling error "
               f"{100 * s.error_alpha:+g} % stiffness on pids {', '.join(map(str, s.error_pids))}")
    typer.echo("parameters: " + ", ".join(f"{p.name} ({p.kind})" for p in s.parameters.parameters))
    typer.echo(f"n_modes: {', '.join(map(str, s.n_modes))}; cells: " + "; ".join(
        f"{c} " + ", ".join(f"{100 * m:g}" for m in mags) + " %" for c, mags in s.errors)
        + f" ({len(s.cells)} cells)")
    typer.echo(f"samples: {s.samples} per cell × {len(s.cells)} cells × {len(s.n_modes)} mode sets = {total}, "
               f"in {len(s.chunks())} chunks of ≤ {s.chunk_size}; seed {s.seed}; eigensolver {s.eigensolver}; "
               f"devices: {devices}")


def _study_summary(result) -> None:
    """Per n and category: std Δα [%] at the largest magnitude, failures and fallbacks."""
    stats = result.statistics()
    names = result.names
    width = max(12, *map(len, names))
    typer.echo("std Δα [%] at the largest magnitude (eq. 4.4); failed samples and fallbacks over all "
               "magnitudes of the category")
    typer.echo(f"{'n':>3} {'category':>9} {'δ max [%]':>9} " + " ".join(f"{p:>{width}}" for p in names)
               + f" {'failed':>7} {'fallbacks':>9}")
    difference = False
    for n in result.study.n_modes:
        for category, mags in result.study.errors:
            rows = [s for s in stats if s["n_modes"] == n and s["category"] == category]
            top = max(rows, key=lambda s: s["magnitude"])
            cells = []
            for p in names:
                std = 100 * top["delta_alpha"][p]["std"]
                mark = "" if top["delta_alpha_is_ratio"][p] else "*"
                difference |= bool(mark)
                cells.append(f"{f'{std:.3g}{mark}' if np.isfinite(std) else '–':>{width}}")
            failed = sum(sum(s["failed"].values()) for s in rows)
            fallbacks = sum(s["fallback"] for s in rows)
            typer.echo(f"{n:>3} {category:>9} {100 * max(mags):>9g} " + " ".join(cells)
                       + f" {failed:>7} {fallbacks:>9}")
    if difference:
        typer.echo("* α(δ = 0) = 0: Δα = α(δ) − α(0), not the ratio of eq. (4.4)")
    failures = ", ".join(f"{k} {v}" for k, v in result.failures.items() if v) or "none"
    typer.echo(f"{sum(len(d['status']) for d in result.samples.values())} samples; failed (left out of the "
               f"statistics): {failures}; redone with full eigensolves: {result.fallbacks}")


@app.command()
def montecarlo(
    config: Annotated[Path, typer.Argument(metavar="CONFIG.toml", exists=True, dir_okay=False,
                                           help="the study: [study], [errors], [[parameter]], [options] (README)")],
    json_out: Annotated[Path, typer.Option("--json", help="write the statistics per cell as JSON")],
    plots: Annotated[Path | None, typer.Option("--plots", help="directory for PNG plots (needs matplotlib, the plot extra)")] = None,
    out: Annotated[Path | None, typer.Option(
        "--out", help="directory of the finished chunks, from which a rerun resumes "
                      "(default: next to the JSON, OUT.json → OUT.chunks)")] = None,
    devices: Annotated[int | None, typer.Option("--devices", min=1, help="use the first N JAX devices (default: all)")] = None,
    ray: Annotated[str | None, typer.Option(
        "--ray", metavar="ADDRESS", help="run the chunks on a Ray cluster: 'local' (start one here), 'auto' "
                                         "(the cluster of this node) or ray://HEAD:10001 (needs jaxfem[ray])")] = None,
) -> None:
    """Monte-Carlo study of experimental errors (thesis §4.3): "measured" modes of a
    reference model with random errors of each category and magnitude (Table 4.7),
    updated from a model with a known modelling error (Table 4.6); statistics of the
    correction-factor, frequency and MAC deviations (eqs. 4.4–4.6, Figs. 4.24–4.32)."""
    import jax

    from ._montecarlo import Runner, _Store
    from ._montecarlo import montecarlo as run_study

    _check_plots(plots)
    study = _load_study(config)

    # Where the samples are computed: this process, sharded over the first N devices, or
    # Ray workers (this process then only runs the error-free reference updates).
    available = jax.devices()
    if devices is not None and devices > len(available):
        _fail(f"--devices {devices}: only {len(available)} JAX devices ({available[0].platform})")
    chosen = available[:devices]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            runner = Runner(study, devices=chosen)
        except (ValueError, OSError, KeyError) as err:
            _fail(f"{config}: cannot set up the study: {err}")
    _echo_warnings(caught)
    _study_header(config, study, runner, f"{len(chosen)} of {len(available)} ({chosen[0].platform})")
    out = out if out is not None else json_out.with_suffix(".chunks")
    try:
        store = _Store(out, study)
    except (ValueError, OSError) as err:
        _fail(f"--out: {err}")
    chunks = study.chunks()
    found = [c for c in chunks if store.path(c).exists()]
    if found:
        rest = f"{len(chunks) - len(found)} to compute" if len(found) < len(chunks) else "nothing to compute"
        typer.echo(f"resuming from {out}: {len(found)} of {len(chunks)} chunks found "
                   f"({sum(b - a for _, a, b in found)} samples); {rest}")
    else:
        typer.echo(f"finished chunks are written to {out} (a rerun resumes from there)")
    typer.echo("error-free reference updates (compiled once per number of modes) ...", err=True)

    def progress(p: dict) -> None:
        typer.echo(f"[montecarlo] chunk {p['chunk']}/{p['chunks']} (n = {p['n_modes']}): "
                   f"{p['done']}/{p['total']} samples, {p['rate']:.3g} samples/s, "
                   f"ETA {_duration(p['seconds_left'])}, {p['failed']} failed, {p['fallbacks']} fallbacks", err=True)

    if ray is None:
        result = run_study(study, out=out, progress=progress, runner=runner)
    else:
        from ._ray import montecarlo_ray

        try:
            result = montecarlo_ray(study, address=None if ray == "local" else ray, out=out,
                                    progress=progress, runner=runner)
        except (ImportError, ConnectionError, RuntimeError) as err:
            _fail(f"--ray {ray}: {err}")
    _write_json(json_out, json_safe(dict(result.to_json(), config=str(config), devices=len(chosen))))
    if plots is not None:
        from ._montecarlo_plots import plot_montecarlo

        written = plot_montecarlo(result, plots, name=config.name)
        typer.echo("wrote " + ", ".join(str(w) for w in written))
    _study_summary(result)
    typer.echo(f"done in {_duration(result.seconds)}")
