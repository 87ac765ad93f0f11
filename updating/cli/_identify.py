"""``jaxfem identify``: modal parameters from FRFs (thesis §2.3.1)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import check_plots, echoed_warnings, fail, read_dataset, write_json


def identify(
    frf_path: Annotated[Path, typer.Argument(metavar="FRF.uff", exists=True, dir_okay=False,
                                             help="measured FRFs (UFF 58), with coherence if available")],
    json_out: Annotated[Path, typer.Option("--json", dir_okay=False, help="write the identified modes and the diagram as JSON")],
    plots: Annotated[Path | None, typer.Option("--plots", help="directory for the stabilisation diagram (PNG)")] = None,
    modes_out: Annotated[Path | None, typer.Option("--uff", help="write the identified modes as UFF 55")] = None,
    fmin: Annotated[float | None, typer.Option("--fmin", help="lower end of the band, Hz")] = None,
    fmax: Annotated[float | None, typer.Option("--fmax", help="upper end of the band, Hz")] = None,
    min_coherence: Annotated[float, typer.Option("--min-coherence", help="lines below are left out")] = 0.5,
) -> None:
    """Modal parameters from FRFs: pLSCF stabilisation diagram, automatic selection of the
    stable poles, LSFD mode shapes, real normal modes (thesis §2.3.1)."""
    from identification import identify as run_identify
    from identification import write_uff

    check_plots(plots)
    frfs = read_dataset(frf_path, "frfs", "FRFs", 58)
    with echoed_warnings():
        try:
            modes, report = run_identify(frfs, fmin=fmin, fmax=fmax, min_coherence=min_coherence)
        except ValueError as err:
            fail(f"{frf_path}: {err}")
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
    write_json(json_out, report)
