"""``jaxfem identify``: modal parameters from FRFs (thesis §2.3.1)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated

import typer

from ._common import (
    DofMapOpt,
    check_plots,
    echoed_warnings,
    fail,
    read_dataset,
    write_json,
)


def identify(
    frf_path: Annotated[Path, typer.Argument(metavar="FRF.uff", exists=True, dir_okay=False,
                                             help="measured FRFs (UFF 58), with coherence if available")],
    json_out: Annotated[Path, typer.Option("--json", dir_okay=False, help="write the identified modes and the diagram as JSON")],
    plots: Annotated[Path | None, typer.Option("--plots", help="directory for the stabilisation diagram (PNG)")] = None,
    modes_out: Annotated[Path | None, typer.Option("--uff", help="write the identified modes as UFF 55")] = None,
    fmin: Annotated[float | None, typer.Option("--fmin", help="lower end of the band, Hz")] = None,
    fmax: Annotated[float | None, typer.Option("--fmax", help="upper end of the band, Hz")] = None,
    min_coherence: Annotated[float, typer.Option("--min-coherence", help="lines below are left out")] = 0.5,
    orders: Annotated[str | None, typer.Option(
        "--orders", metavar="A:B[:STEP]",
        help="pLSCF model orders A to B (every STEP-th); default 2:40/n_ref, n_ref the smaller of outputs and "
             "inputs")] = None,
    stab_freq: Annotated[float, typer.Option(
        "--stab-freq", help="a pole is stable in frequency when |Δf|/f to the previous order is at most this")] = 0.01,
    stab_damp: Annotated[float, typer.Option(
        "--stab-damp", help="a pole is stable in damping when |Δζ|/ζ to the previous order is at most this")] = 0.05,
    stab_mac: Annotated[float, typer.Option(
        "--stab-mac", help="a pole is stable in shape when its MAC with the previous order's is at least this")] = 0.98,
    dof_map: DofMapOpt = None,
) -> None:
    """Modal parameters from FRFs: pLSCF stabilisation diagram, automatic selection of the
    stable poles, LSFD mode shapes, real normal modes (thesis §2.3.1). More inputs than
    outputs (roving hammer) are read by reciprocity H_ij = H_ji: the shapes come at every
    hammer point. When no mode is found the diagram (PNG) and the JSON are written all the
    same, for a look at which options to change."""
    from identification import IdentificationError
    from identification import identify as run_identify

    check_plots(plots)
    order_list = _orders(orders)
    for flag, value, ok, what in (
        ("--stab-freq", stab_freq, stab_freq > 0, "positive"),
        ("--stab-damp", stab_damp, stab_damp > 0, "positive"),
        ("--stab-mac", stab_mac, 0 < stab_mac < 1, "between 0 and 1"),
        ("--min-coherence", min_coherence, 0 <= min_coherence <= 1, "in [0, 1]"),
    ):
        if not ok:
            fail(f"{flag} {value:g}: must be {what}")
    frfs = read_dataset(frf_path, "frfs", "FRFs", 58, dof_map=dof_map)
    error = None
    with echoed_warnings():
        try:
            modes, report = run_identify(frfs, fmin=fmin, fmax=fmax, min_coherence=min_coherence, orders=order_list,
                                         tol_f=stab_freq, tol_zeta=stab_damp, min_mac=stab_mac)
        except ValueError as err:
            error = err
    if error is not None and not isinstance(error, IdentificationError):
        fail(_once(frf_path, str(error)))
    if error is not None:
        report = error.report
    _print_options(report)
    if error is not None:
        png = (plots / "stabilisation.png") if plots is not None else json_out.with_name(
            f"{json_out.stem}_stabilisation.png")
        _plot(report, png)
        write_json(json_out, report)
        o, band = report["options"], report["band_hz"]
        fail(f"{_once(frf_path, report['error'])}. Options that may help: --orders (now "
             f"{_format_orders(report['orders'])}; more or higher orders, e.g. 2:60), --stab-freq (now "
             f"{o['tol_f']:g}), --stab-damp (now {o['tol_zeta']:g}), --stab-mac (now {o['min_mac']:g}), "
             f"--fmin/--fmax (band now {band[0]:.6g}–{band[1]:.6g} Hz), --min-coherence (now "
             f"{o['min_coherence']:g}). The diagram is in {png}, the poles found in {json_out}")
    typer.echo(f"{'mode':>4} {'f [Hz]':>10} {'ζ [%]':>7} {'stable orders':>14} {'complexity':>11}")
    for i, m in enumerate(report["modes"], 1):
        typer.echo(f"{i:>4} {m['frequency_hz']:>10.4f} {100 * m['damping_ratio']:>7.3f} {m['n_orders_stable']:>14d} "
                   f"{m['complexity']:>11.3f}")
    recip = report["reciprocity"]
    if recip["dofs_from_inputs"]:
        typer.echo(f"shapes at the inputs {', '.join(recip['dofs_from_inputs'])} by reciprocity (H_ij = H_ji)")
    if modes_out is not None:
        _write_modes(modes_out, modes)
    if plots is not None:
        _plot(report, plots / "stabilisation.png")
    write_json(json_out, report)


def _write_modes(path: Path, modes) -> None:
    """``--uff``: the modes as UFF 55; exit 2 naming the file when it cannot be written
    (pyuff's own error on a bad path is a bare ``Exception``, so the file is opened here
    first)."""
    from identification import write_uff

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w"):
            pass
        write_uff(path, modes=modes)
    except (OSError, ValueError) as err:
        fail(f"cannot write {path}: {err}")
    typer.echo(f"wrote {path}")


def _once(path: Path, message: str) -> str:
    """``path: message``, unless the message names the path already (read_uff's messages begin with it)."""
    return message if str(path) in message else f"{path}: {message}"


def _orders(text: str | None) -> list[int] | None:
    """``--orders A:B`` or ``A:B:STEP`` as the list of model orders; exit 2 on anything else."""
    if text is None:
        return None
    parts = text.split(":")
    if len(parts) not in (2, 3) or not all(re.fullmatch(r"[0-9]+", p.strip()) for p in parts):
        fail(f"--orders {text!r}: give A:B or A:B:STEP, whole numbers (e.g. 2:40 or 2:60:2)")
    a, b, step = (int(p) for p in parts) if len(parts) == 3 else (int(parts[0]), int(parts[1]), 1)
    if a < 1 or step < 1:
        fail(f"--orders {text}: the lowest order and the step must be at least 1")
    if a > b:
        fail(f"--orders {text}: the lowest order {a} is above the highest {b}")
    orders = list(range(a, b + 1, step))
    if len(orders) < 3:
        fail(f"--orders {text} gives {len(orders)} model order(s): a stabilisation diagram needs at least 3, "
             "a mode 4 (it must be stable over 3, and the lowest order is never stable)")
    return orders


def _format_orders(orders: list[int]) -> str:
    """``A:B`` or ``A:B:STEP`` when evenly spaced, else the list."""
    steps = {b - a for a, b in zip(orders, orders[1:])}
    if len(steps) != 1:
        return ",".join(map(str, orders))
    step = steps.pop()
    return f"{orders[0]}:{orders[-1]}" + (f":{step}" if step != 1 else "")


def _print_options(report: dict) -> None:
    """One line naming the choices of the run and the options that set them."""
    o, band = report["options"], report["band_hz"]
    refs = report["reciprocity"]["references"]
    typer.echo(f"pLSCF orders {_format_orders(report['orders'])} (--orders), references: the {refs}"
               f"{' (reciprocity H_ij = H_ji)' if refs == 'outputs' else ''}; stable when |Δf|/f ≤ {o['tol_f']:g} "
               f"(--stab-freq), |Δζ|/ζ ≤ {o['tol_zeta']:g} (--stab-damp), MAC ≥ {o['min_mac']:g} (--stab-mac) "
               f"over ≥ {report['min_orders']} orders; band {band[0]:.6g}–{band[1]:.6g} Hz (--fmin/--fmax), "
               f"coherence ≥ {o['min_coherence']:g} (--min-coherence)")


def _plot(report: dict, path: Path) -> None:
    from identification import plot_stabilisation

    try:
        typer.echo(f"wrote {plot_stabilisation(report, path)}")
    except OSError as err:
        fail(f"cannot write {path}: {err}")
