"""``jaxfem frf``: FRFs and coherence from measured time histories (thesis §2.1)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import DofMapOpt, PlotsOut, check_plots, echoed_warnings, fail, read_dataset, write_json


def frf(
    time_path: Annotated[Path, typer.Argument(metavar="TIME.uff", exists=True, dir_okay=False,
                                              help="time histories (UFF 58, function type 1): forces and responses")],
    force: Annotated[list[str], typer.Option(
        "--force", metavar="LABEL|NODE:DIR",
        help="force channel: its name, DoF (101+Z) or NODE:DIR (101:+3; 101:3 either sign); repeat for several")],
    out: Annotated[Path, typer.Option("--out", metavar="FRF.uff", dir_okay=False,
                                      help="write the FRFs and coherence as UFF 58")],
    h2: Annotated[bool, typer.Option("--h2/--h1", help="estimator: H1 (noise on the responses; default) or H2 "
                                                        "(one input; noise on the force)")] = False,
    window: Annotated[str, typer.Option("--window", metavar="hann|rect",
                                        help="hann: random excitation, blocks overlap by half; rect: periodic "
                                             "excitation of one block's period, or transients")] = "hann",
    blocks: Annotated[int, typer.Option("--blocks", metavar="N",
                                        help="cut the record into N blocks (resolution fs·N/n_samples); "
                                             "hann averages 2N−1 overlapping blocks")] = 8,
    plots: PlotsOut = None,
    json_out: Annotated[Path | None, typer.Option("--json", dir_okay=False, help="write the summary as JSON")] = None,
    dof_map: DofMapOpt = None,
) -> None:
    """FRFs (H1 or H2) and coherence from force and response time histories (Welch
    averaging; thesis §2.1): the --force channels are the inputs, every other channel a
    response."""
    from identification import frf_from_histories, plot_coherence, write_uff

    check_plots(plots)
    if window not in ("hann", "rect"):
        fail(f"--window {window!r}: hann | rect")
    histories = read_dataset(time_path, "time", "time histories", 58, dof_map=dof_map)
    with echoed_warnings():
        try:
            est = frf_from_histories(histories, force, estimator="H2" if h2 else "H1", window=window, blocks=blocks)
        except ValueError as err:
            fail(f"{time_path}: {err}")
    frfs = est.frfs
    typer.echo(f"channels: {histories.n_channels}; inputs {', '.join(est.input_channels)}")
    typer.echo(f"          responses ({frfs.kind}) {', '.join(est.output_channels)}")
    typer.echo(f"fs {est.fs:.6g} Hz, {est.n_samples} samples ({est.n_samples / est.fs:.6g} s); block "
               f"{est.block_length} samples ({est.block_length / est.fs:.6g} s), resolution {est.resolution_hz:.6g} "
               f"Hz, {est.n_averages} averages ({est.window}, {100 * est.overlap:.0f} % overlap), {est.estimator}")
    rows = est.coherence_table()
    width = max(len(f"{r['output']} / {r['input']}") for r in rows)
    typer.echo(f"{'FRF':<{width}} {'min γ²':>7} {'mean γ²':>8}")
    for r in rows:
        pair = f"{r['output']} / {r['input']}"
        if r["min"] is None:
            typer.echo(f"{pair:<{width}} {'–':>7} {'–':>8}")
        else:
            typer.echo(f"{pair:<{width}} {r['min']:>7.3f} {r['mean']:>8.3f}")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        write_uff(out, frfs=frfs)
    except (OSError, ValueError) as err:
        fail(f"cannot write {out}: {err}")
    typer.echo(f"wrote {out}")
    if plots is not None:
        title = f"{est.estimator} from {time_path.name}"
        typer.echo(f"wrote {plot_coherence(frfs, plots / 'coherence.png', title=title)}")
    if json_out is not None:
        write_json(json_out, est.to_json())
