"""What the commands share: arguments, input files with exit-2 errors, tables and JSON."""

from __future__ import annotations

import json
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, NoReturn

import numpy as np
import typer

from .._report import json_safe

ModelArg = Annotated[Path, typer.Argument(metavar="MODEL.bdf", exists=True, dir_okay=False,
                                          help="Nastran bulk data (SI units)")]
TestArg = Annotated[Path, typer.Argument(metavar="TEST.uff", exists=True, dir_okay=False,
                                         help="universal file with the measured modes (dataset 55)")]
JsonOut = Annotated[Path, typer.Option("--json", dir_okay=False, help="write results as JSON")]
PlotsOut = Annotated[Path | None, typer.Option("--plots", help="directory for PNG plots")]
SolverOpt = Annotated[str | None, typer.Option(
    "--solver", metavar="dense|sparse",
    help="eigensolver: dense (all modes) or sparse (lowest modes, shift-invert Lanczos); "
         "default: the parameter file's, else sparse above 5,000 DoFs")]


def fail(message: str) -> NoReturn:
    """One-line error on stderr, exit code 2 (usage / input error), no traceback."""
    typer.echo("error: " + " ".join(str(message).split()), err=True)
    raise typer.Exit(2)


@contextmanager
def echoed_warnings() -> Iterator[None]:
    """Warnings raised inside go to stderr as one line each (``warning: ...``) at the end."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    for w in caught:
        typer.echo("warning: " + " ".join(str(w.message).split()), err=True)


def write_json(path: Path, data: dict) -> None:
    """``data`` as indented JSON (NaN and inf as null), its directory made if missing, and say so."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(json_safe(data), indent=2, allow_nan=False))
    except OSError as err:
        fail(f"cannot write {path}: {err}")
    typer.echo(f"wrote {path}")


def check_plots(plots: Path | None) -> None:
    if plots is not None and plots.exists() and not plots.is_dir():
        fail(f"--plots {plots} exists and is not a directory")


def load_model(path: Path):
    import jaxfem
    from jaxfem.io import read_bdf

    with echoed_warnings():
        try:
            bulk = read_bdf(path)
            model = jaxfem.build_model(bulk)
        except (ValueError, OSError) as err:
            fail(f"cannot read model {path}: {err}")
    if bulk.unknown:
        typer.echo(f"warning: unsupported cards ignored: {', '.join(sorted(bulk.unknown))}", err=True)
    return model


def read_dataset(path: Path, key: str, what: str, dataset: int):
    """``read_uff(path)[key]``; exit 2 naming the file when it cannot be read or holds no
    such dataset."""
    from identification import read_uff

    with echoed_warnings():
        try:
            data = read_uff(path)[key]
        except (ValueError, OSError) as err:
            fail(f"cannot read {what} {path}: {err}")
    if data is None:
        fail(f"{path}: no {what} (UFF dataset {dataset}) in the file")
    return data


def load_test(path: Path):
    """The measured modes of a universal file, as real normal modes."""
    return read_dataset(path, "modes", "mode shapes", 55).real()


def check_solver(solver: str | None) -> str:
    """``--solver``: ``dense`` or ``sparse`` (None: ``auto``); exit 2 otherwise."""
    if solver not in (None, "dense", "sparse", "auto"):
        fail(f"--solver {solver!r}: dense | sparse")
    return solver or "auto"


def load_inputs(model_path: Path, test_path: Path, params_path: Path | None = None, solver: str | None = None):
    """Model, real test modes, observation matrix and the parameter set (None without a
    file; ``solver``, from ``--solver``, overrides its eigensolver), checked against each
    other; on bad input exit 2 naming the file."""
    from dataclasses import replace

    from identification import observation_matrix

    from .._parameters import ParameterSet, parameterise

    params = None
    check_solver(solver)
    if params_path is not None:
        try:
            params = ParameterSet.from_toml(params_path)
        except (ValueError, OSError) as err:
            fail(f"bad parameter file: {err}")
        if solver is not None:
            params = replace(params, options=replace(params.options, eigensolver=solver))
    model = load_model(model_path)
    test = load_test(test_path)
    try:
        C = observation_matrix(model, test.sensors)[0]
    except ValueError as err:  # unknown sensor grids
        fail(f"test data {test_path}: {err}")
    if params is not None:
        try:
            parameterise(model, params)
        except ValueError as err:
            fail(f"{params_path}: {err}")
    return model, test, C, params


def mode_labels(freqs) -> list[str]:
    """``"1 (12.3)"``: mode number and frequency in Hz, for plot axes."""
    return [f"{i} ({f:.1f})" for i, f in enumerate(np.asarray(freqs).tolist(), 1)]


def print_pairing(p) -> None:
    """The pairing table (f_test, f_model, Δf, MAC per test mode); warnings on stderr."""
    typer.echo(f"{'test':>5} {'model':>6} {'f_test [Hz]':>12} {'f_model [Hz]':>13} {'Δf [%]':>8} {'MAC':>6}")
    for t, m, ft, fm, d, c in p.table():
        if m is None:
            typer.echo(f"{t:>5} {'–':>6} {ft:>12.4f} {'–':>13} {'–':>8} {'–':>6}")
        else:
            typer.echo(f"{t:>5} {m:>6} {ft:>12.4f} {fm:>13.4f} {d:>+8.2f} {c:>6.3f}")
    for line in p.warnings:
        typer.echo(f"warning: {line}", err=True)


def frf_prediction(path: Path, test, initial, updated, plots: Path | None) -> dict:
    """Measured FRFs against the initial and updated model's predictions (FRAC, dB;
    thesis §4.2.5.3), printed per pair; ``plots``: also ``frf.png`` of the first pair."""
    from .._prediction import frf_correlation, predict_frf

    frf = read_dataset(path, "frfs", "FRFs", 58)
    ratios = np.asarray(test.damping_ratios)
    zeta = float(np.mean(ratios[ratios > 0])) if np.any(ratios > 0) else 0.01
    try:
        predicted = {key: predict_frf(m, frf, zeta=zeta) for key, m in (("before", initial), ("after", updated))}
    except ValueError as err:
        fail(f"{path}: {err}")
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
        from .._plots import plot_frf_overlay

        unit = {"receptance": "m/N", "mobility": "m/(s·N)", "accelerance": "m/(s²·N)"}[frf.kind]
        plot_frf_overlay(frf.frequencies_hz, frf.values[:, 0, 0],
                         {"initial model": predicted["before"][:, 0, 0], "updated model": predicted["after"][:, 0, 0]},
                         f"{frf.outputs.labels[0]} / {frf.inputs.labels[0]}", plots / "frf.png", unit)
    return {"zeta": zeta, "kind": frf.kind, "pairs": pairs}
