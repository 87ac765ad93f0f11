"""``jaxfem montecarlo``: Monte-Carlo study of experimental errors (thesis §4.3)."""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ._common import PlotsOut, check_plots, echoed_warnings, fail, write_json


def _load_study(path: Path):
    from ..studies import Study

    try:
        return Study.from_toml(path)
    except (ValueError, OSError) as err:
        message = str(err)
        fail(message if str(path) in message else f"{path}: {message}")


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
        typer.echo("* α(δ = 0) = 0: Δα = α(δ) − α(0), not the ratio of eq. 4.4")
    failures = ", ".join(f"{k} {v}" for k, v in result.failures.items() if v) or "none"
    typer.echo(f"{sum(len(d['status']) for d in result.samples.values())} samples; failed (left out of the "
               f"statistics): {failures}; redone with full eigensolves: {result.fallbacks}")


def _progress(p) -> None:
    typer.echo(f"[montecarlo] {p.message}", err=True)


def _chunk_directory(out: Path, study) -> Path:
    """``out``, checked as the study's chunk directory; says what a rerun resumes from it."""
    from ..studies import ChunkStore

    try:
        store = ChunkStore(out, study)
    except (ValueError, OSError) as err:
        fail(f"--out: {err}")
    chunks = study.chunks()
    found = [c for c in chunks if store.path(c).exists()]
    if found:
        rest = f"{len(chunks) - len(found)} to compute" if len(found) < len(chunks) else "nothing to compute"
        typer.echo(f"resuming from {out}: {len(found)} of {len(chunks)} chunks found "
                   f"({sum(b - a for _, a, b in found)} samples); {rest}")
    else:
        typer.echo(f"finished chunks are written to {out} (a rerun resumes from there)")
    return out


def montecarlo(
    config: Annotated[Path, typer.Argument(metavar="CONFIG.toml", exists=True, dir_okay=False,
                                           help="the study: [study], [errors], [[parameter]], [options] (docs/montecarlo.md)")],
    json_out: Annotated[Path, typer.Option("--json", dir_okay=False, help="write the statistics per cell as JSON")],
    plots: PlotsOut = None,
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
    correction-factor, frequency and MAC deviations (eq. 4.4, eq. 4.5, eq. 4.6, Figs. 4.24–4.32)."""
    import jax

    from ..studies import Runner, duration
    from ..studies import montecarlo as run_study

    check_plots(plots)
    study = _load_study(config)

    # Where the samples are computed: this process, sharded over the first N devices, or
    # Ray workers (this process then only runs the error-free reference updates).
    available = jax.devices()
    if devices is not None and devices > len(available):
        fail(f"--devices {devices}: only {len(available)} JAX devices ({available[0].platform})")
    chosen = available[:devices]
    with echoed_warnings():
        try:
            runner = Runner(study, devices=chosen)
        except (ValueError, OSError, KeyError) as err:
            fail(f"{config}: cannot set up the study: {err}")
    _study_header(config, study, runner, f"{len(chosen)} of {len(available)} ({chosen[0].platform})")
    out = _chunk_directory(out if out is not None else json_out.with_suffix(".chunks"), study)
    typer.echo("error-free reference updates (compiled once per number of modes) ...", err=True)

    try:
        if ray is None:
            result = run_study(study, out=out, progress=_progress, runner=runner)
        else:
            from ..studies import montecarlo_ray

            try:
                result = montecarlo_ray(study, address=None if ray == "local" else ray, out=out,
                                        progress=_progress, runner=runner)
            except (ImportError, ConnectionError, RuntimeError) as err:
                fail(f"--ray {ray}: {err}")
    except (OSError, zipfile.BadZipFile) as err:  # a chunk that cannot be written, or a truncated one
        fail(f"chunks in {out}: {err} (delete a damaged chunk file to compute it again)")
    except ValueError as err:
        fail(f"{config}: {err}")
    write_json(json_out, dict(result.to_json(), config=str(config), devices=len(chosen)))
    if plots is not None:
        from ..report import plot_montecarlo

        try:
            written = plot_montecarlo(result, plots, name=config.name)
        except OSError as err:
            fail(f"cannot write plots to {plots}: {err}")
        typer.echo("wrote " + ", ".join(str(w) for w in written))
    _study_summary(result)
    typer.echo(f"done in {duration(result.seconds)}")
