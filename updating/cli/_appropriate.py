"""``jaxfem appropriate``: phase-resonance planning (thesis §3.4, Table 5.11)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ._common import AllowUnsupportedOpt, ModelArg, MpcSetOpt, SpcSetOpt, SubcaseOpt, fail, load_model, write_json


def _dof_indices(model, spec: str, option: str) -> tuple[list[int], list[str]]:
    """Solved-DoF indices of "GRID:COMPONENT,..." (components 1–6); each must be a DoF of
    its own (not constrained, not an RBE2-dependent combination)."""
    from identification import Sensors, observation_matrix

    pairs = [item.split(":") for item in spec.split(",") if item.strip()]
    if not pairs or any(len(p) != 2 for p in pairs):
        fail(f"{option} {spec!r}: expected GRID:COMPONENT,..., components 1–6 (e.g. 101:3,205:3)")
    try:
        nodes, comps = [int(p[0]) for p in pairs], [int(p[1]) for p in pairs]
        C, _ = observation_matrix(model, Sensors.from_components(nodes, comps))
    except ValueError as err:
        fail(f"{option} {spec}: {err} (expected GRID:COMPONENT,..., components 1–6)")
    labels = [f"{n}:{c}" for n, c in zip(nodes, comps)]
    out = []
    for label, row in zip(labels, C):
        hit = np.flatnonzero(row)
        if len(hit) != 1 or row[hit[0]] != 1.0:
            fail(f"{option}: {label} is not an independent DoF of the model (RBE2-dependent grid)")
        out.append(int(hit[0]))
    return out, labels


def appropriate(
    model_path: ModelArg,
    candidates: Annotated[str, typer.Option("--candidates", metavar="GRID:C,...",
                                            help="candidate exciter positions, e.g. 101:3,205:3")],
    n_exciters: Annotated[int, typer.Option("--exciters", help="number of exciters used together")],
    json_out: Annotated[Path, typer.Option("--json", dir_okay=False, help="write the ranking as JSON")],
    n_modes: Annotated[int, typer.Option("--modes", help="modes to appropriate (the lowest)")] = 6,
    method: Annotated[str, typer.Option("--method", help="thesis, lewis_wrisley, asher or hunt")] = "thesis",
    sensors: Annotated[str | None, typer.Option("--sensors", metavar="GRID:C,...",
                                                help="response DoFs of the MIF (default: all DoFs)")] = None,
    kappa: Annotated[float, typer.Option("--kappa", help="stiffness-proportional damping D = μM + κK, κ in s")] = 1e-3,
    mu: Annotated[float, typer.Option("--mu", help="mass-proportional damping, 1/s")] = 0.0,
    top: Annotated[int, typer.Option("--top", help="exciter sets listed per mode")] = 5,
    allow_unsupported: AllowUnsupportedOpt = False,
    spc_set: SpcSetOpt = None,
    mpc_set: MpcSetOpt = None,
    subcase: SubcaseOpt = None,
) -> None:
    """Phase-resonance planning: the predicted MIF (eq. 3.54) of every set of ``--exciters``
    positions among the candidates, with the appropriated forces (thesis §3.4, Table 5.11)."""
    import jaxfem
    from identification import appropriation_report

    for flag, value, ok, what in (
        ("--exciters", n_exciters, n_exciters >= 1, "at least 1"),
        ("--modes", n_modes, n_modes >= 1, "at least 1"),
        ("--top", top, top >= 1, "at least 1"),
        ("--kappa", kappa, kappa >= 0 and np.isfinite(kappa), "finite and non-negative (s)"),
        ("--mu", mu, mu >= 0 and np.isfinite(mu), "finite and non-negative (1/s)"),
    ):
        if not ok:
            fail(f"{flag} {value:g}: must be {what}")
    model = load_model(model_path, allow_unsupported=allow_unsupported, sets=(spc_set, mpc_set, subcase))
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
        fail(f"{model_path.name}: {err}")
    typer.echo(f"{'mode':>4} {'f [Hz]':>9} {'best exciters':<28} {'MIF':>7}")
    for m in rep["modes"]:
        best = m["best"]
        where = ", ".join(best["labels"]) if best else "none found"
        mif = f"{best['mif']:>7.1f}" if best else f"{'–':>7}"
        typer.echo(f"{m['mode']:>4} {m['natural_frequency_hz']:>9.3f} {where:<28} {mif}")
    write_json(json_out, dict(rep, model=model_path.name))
