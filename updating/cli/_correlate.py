"""``jaxfem correlate``: pairing by MAC and Δf, AutoMAC, COMAC."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from .. import Options
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
    check_solver,
    fail,
    geometry_options,
    load_inputs,
    mode_labels,
    print_pairing,
    write_json,
)


def check_thresholds(n: int | None, min_mac: float, max_freq_dev: float, max_automac: float | None = None) -> None:
    """Exit 2 naming the option when ``-n``, ``--min-mac``, ``--max-freq-dev`` or
    ``--max-automac`` is out of range, before any model is read or solved."""
    checks = [
        ("-n", n, n is None or n >= 1, "a positive number of model modes"),
        ("--min-mac", min_mac, 0 < min_mac <= 1, "in (0, 1]"),
        ("--max-freq-dev", max_freq_dev, max_freq_dev >= 0, "a non-negative fraction (0.3 = 30 %)"),
    ]
    if max_automac is not None:
        checks.append(("--max-automac", max_automac, 0 < max_automac <= 1, "in (0, 1]"))
    for flag, value, ok, what in checks:
        if not ok:
            fail(f"{flag} {value:g}: must be {what}")


@geometry_options
def correlate(
    model_path: ModelArg,
    test_path: TestArg,
    json_out: JsonOut,
    plots: PlotsOut = None,
    report: Annotated[Path | None, typer.Option(
        "--report", help="directory for shapes.html: test and model mode shapes of every pair animated in 3-D "
                         "(one self-contained HTML file)")] = None,
    n: Annotated[int | None, typer.Option("-n", "--n-modes",
                                          help="model modes to compute (default: twice the test modes, at least 6 spare; as n_model_modes)")] = None,
    min_mac: Annotated[float, typer.Option("--min-mac", help="pairing threshold on MAC")] = Options.min_mac,
    max_freq_dev: Annotated[float, typer.Option("--max-freq-dev", help="pairing threshold on |Δf| (fraction)")] = Options.max_freq_dev,
    solver: SolverOpt = None,
    geometry: Geometry = DEFAULT_GEOMETRY,
    allow_unsupported: AllowUnsupportedOpt = False,
    spc_set: SpcSetOpt = None,
    mpc_set: MpcSetOpt = None,
    subcase: SubcaseOpt = None,
    max_automac: Annotated[float, typer.Option(
        "--max-automac", help="warn of spatial aliasing when two test modes have an AutoMAC above this")] = 0.9,
) -> None:
    """Correlate model and test modes: pairing by MAC and Δf, AutoMAC, COMAC; warnings of
    spatial aliasing."""
    import identification as corr

    from .. import correlate as correlate_modes

    check_plots(plots)
    check_thresholds(n, min_mac, max_freq_dev, max_automac)
    model, test, _, _, gmap, content = load_inputs(model_path, test_path, geometry=geometry,
                                                   allow_unsupported=allow_unsupported, sets=(spc_set, mpc_set, subcase))
    try:
        res = correlate_modes(model, test, n_modes=n, min_mac=min_mac, max_freq_dev=max_freq_dev,
                              max_automac=max_automac, solver=check_solver(solver), model_name=str(model_path),
                              test_name=str(test_path), geometry=gmap)
    except ValueError as err:
        fail(f"{model_path}: {err}")
    result = res.to_json()
    pairing, ne, labels = res.pairing, test.n_modes, res.sensors
    f_a, phi_a, f_e, phi_e = res.model_frequencies_hz, res.model_at_sensors, res.test_frequencies_hz, res.test_shapes

    typer.echo(f"model {model_path}: {model.n_dof} DoFs, {res.n_model_modes} modes; test {test_path}: "
               f"{ne} modes at {len(labels)} sensors")
    typer.echo(f"pairing: MAC ≥ {pairing.min_mac:.2f}, |Δf| ≤ {100 * pairing.max_freq_dev:.0f} %")
    print_pairing(pairing)
    if res.n_paired:
        typer.echo(f"paired {res.n_paired}/{ne}: RMS Δf {res.rms_freq_dev_pct:.2f} %, mean MAC {res.mean_mac:.3f}")
    typer.echo("AutoMAC of the test shapes:")
    typer.echo("      " + "".join(f"{j:>6}" for j in range(1, ne + 1)))
    for i, row in enumerate(res.automac, 1):
        typer.echo(f"{i:>6}" + "".join(f"{v:>6.2f}" for v in row))
    typer.echo("COMAC per sensor (lowest first):")
    for sensor, value in res.comac_ranking:
        typer.echo(f"  {sensor:>12} {value:.3f}")
    for line in res.aliasing:
        typer.echo(f"warning: {line}", err=True)
    write_json(json_out, result)
    if plots is not None:
        from ..report import plot_freq_dev, plot_mac

        try:
            written = [
                plot_mac(np.asarray(corr.mac(phi_a, phi_e)).T, mode_labels(f_e), mode_labels(f_a),
                         plots / "mac.png", f"MAC: {test_path.name} vs {model_path.name}"),
                plot_freq_dev(pairing.per_test()[0], None, mode_labels(f_e), plots / "freq_dev.png"),
            ]
        except OSError as err:
            fail(f"cannot write plots to {plots}: {err}")
        typer.echo("wrote " + ", ".join(str(w) for w in written))
    if report is not None:
        from ..report import correlation_view, measured_geometry

        try:
            nodes, lines, names = measured_geometry(content, gmap)
            view = correlation_view(report / "shapes.html", model=model, phi=res.model_shapes, test=test,
                                    at_sensors=phi_a, pairing=pairing, test_nodes=nodes, test_lines=lines,
                                    names=names, title=f"mode shapes: {test_path.name} vs {model_path.name}")
        except (ValueError, OSError) as err:
            fail(f"--report {report}: {err}")
        typer.echo(f"wrote {view}")
