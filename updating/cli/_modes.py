"""``jaxfem modes``: natural frequencies of a bulk-data model."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import (
    AllowUnsupportedOpt,
    MpcSetOpt,
    SolverOpt,
    SpcSetOpt,
    SubcaseOpt,
    check_solver,
    fail,
    load_model,
    write_json,
)

LARGE = 5000  # DoFs above which the dense solve's time and memory are announced


DECK_HELP = "Nastran deck (bulk data, with or without case control; any consistent units)"
RANGE_MODES = 30  # modes computed when the case control's METHOD gives a range without a number


def method(bulk, subcase: int | None) -> dict | None:
    """The case control's METHOD as ``{"card", "n", "range"}``: EIGRL ND, V1..V2 or EIGR
    ND (else NE), F1..F2 [Hz] (MSC QRG, EIGRL, EIGR); None without one."""
    case = bulk.case_control.subcase(subcase) if bulk.case_control is not None else None
    if case is None or case.method is None:
        return None
    card = next((c for c in bulk["EIGRL"] + bulk["EIGR"] if c["SID"] == case.method), None)
    if card is None:
        fail(f"{case.places.get('METHOD', case.where)}: METHOD = {case.method}: no EIGRL or EIGR {case.method} "
             "in the bulk data")
    n, lo, hi = ((card["ND"], card["V1"], card["V2"]) if card.name == "EIGRL"
                 else (card["ND"] or card["NE"], card["F1"], card["F2"]))
    return {"card": f"{card.name} {card.id} ({card.file}:{card.line})", "n": n, "range": (lo, hi)}


def _suport(bulk, subcase: int | None) -> int:
    """Number of reference DoFs the deck's SUPORT (and the subcase's SUPORT1 set) names."""
    case = bulk.case_control.subcase(subcase) if bulk.case_control is not None else None
    sid = None if case is None else case.suport1
    cards = bulk["SUPORT"] + [c for c in bulk["SUPORT1"] if c["SID"] == sid]
    return sum(len(str(c["C"])) if c["C"] else 1 for c in cards)


def _modes_table(path: Path, n_modes: int | None, solver: str = "auto", allow_unsupported: bool = False,
                 sets: tuple[int | None, ...] = (None, None, None)) -> dict:
    """The lowest ``n_modes`` (at least 1; None: the case control's METHOD, else 10) of the
    model, within METHOD's frequency range when ``n_modes`` is None; exit 2 with one line
    for a file that cannot be read or built, a model without mass, or a failed eigensolve."""
    import time

    import jaxfem

    if n_modes is not None and n_modes < 1:
        fail(f"-n/--n-modes must be at least 1, got {n_modes}")
    content: dict = {}
    model = load_model(path, content, allow_unsupported, sets)
    chosen = method(content["bulk"], (tuple(sets) + (None,) * 3)[2]) if n_modes is None else None
    if n_modes is None:
        n_modes = (chosen or {}).get("n") or (RANGE_MODES if chosen and chosen["range"][1] else 10)
    sparse = jaxfem.use_sparse(model, solver)
    n_mass = model.n_dof - len(model.dofs.massless)
    if n_mass < 1:
        fail(f"model {path}: no DoF carries mass (give RHO on the materials, NSM or CONM2): it has no modes")
    n_modes = min(n_modes, n_mass - (2 if sparse else 0))
    if n_modes < 1:
        fail(f"model {path}: {n_mass} DoF(s) with mass: too few for the sparse eigensolver; use --solver dense")
    if model.n_dof > LARGE and not sparse:
        minutes = 100.0 / 60.0 * (model.n_dof / 6500) ** 3  # n³ from 6,500 DoFs ≈ 100 s measured on 2 cores
        typer.echo(f"note: {model.n_dof} DoFs: the dense eigensolver computes every mode, about "
                   f"{minutes:.0f} min on 2 cores and {8 * 8 * model.n_dof**2 / 2**30:.0f} GiB", err=True)
    start = time.perf_counter()
    try:
        lam, _ = jaxfem.modes(model, n_modes, solver="sparse" if sparse else "dense")
    except ValueError as err:
        fail(f"model {path}: {err}")
    freqs = [float(f) for f in jaxfem.frequencies_hz(lam)]
    lam, freqs = _in_range(lam, freqs, chosen)
    return {
        "model": str(path),
        "n_dof": int(model.n_dof),
        "eigensolver": "sparse" if sparse else "dense",
        "solve_seconds": time.perf_counter() - start,
        "n_massless": len(model.dofs.massless),
        "auto_spc": [[int(a), int(b)] for a, b in model.dofs.auto_spc],
        "unknown_cards": sorted(content["bulk"].unknown),
        "method": chosen,
        "suport_dofs": _suport(content["bulk"], (tuple(sets) + (None,) * 3)[2]),
        "eigenvalues": [float(x) for x in lam],
        "frequencies_hz": freqs,
    }


def _in_range(lam, freqs: list[float], chosen: dict | None) -> tuple[list[float], list[float]]:
    """The modes within METHOD's range [V1, V2] Hz (all without one)."""
    lo, hi = (chosen or {}).get("range") or (None, None)
    keep = [i for i, f in enumerate(freqs) if (lo is None or f >= lo) and (hi is None or f <= hi)]
    return [float(lam[i]) for i in keep], [freqs[i] for i in keep]


def _print_table(result: dict) -> None:
    typer.echo(f"model {result['model']}: {result['n_dof']} DoFs after constraints "
               f"({result['n_massless']} massless, condensed; {len(result['auto_spc'])} auto-SPC); "
               f"{result['eigensolver']} eigensolver, {result['solve_seconds']:.1f} s")
    if result["auto_spc"]:
        by_grid: dict[int, str] = {}
        for grid, component in result["auto_spc"]:
            by_grid[grid] = by_grid.get(grid, "") + str(component)
        shown = ", ".join(f"{grid} ({c})" for grid, c in list(by_grid.items())[:10])
        typer.echo(f"auto-SPC, neither stiffness nor mass, grid (components): {shown}"
                   + (f" and {len(by_grid) - 10} more grids (all in --json)" if len(by_grid) > 10 else ""))
    m = result["method"]
    if m:
        lo, hi = m["range"]
        span = "" if lo is None and hi is None else f", {lo or 0:g} to {hi if hi is not None else '∞'} Hz"
        typer.echo(f"METHOD: {m['card']}: {m['n'] or 'all'} modes{span}")
    k = result["suport_dofs"]
    if k:
        typer.echo(f"SUPORT: {k} reference DoFs: the lowest {k} modes are the rigid-body modes")
    typer.echo(f"{'mode':>5}  {'f [Hz]':>12}  {'λ = ω² [rad²/s²]':>18}")
    for i, (f, lam) in enumerate(zip(result["frequencies_hz"], result["eigenvalues"]), 1):
        rigid = "  rigid body (SUPORT)" if i <= k else ""
        typer.echo(f"{i:>5}  {f:>12.4f}  {lam:>18.6e}{rigid}")


def modes(
    model: Annotated[Path, typer.Argument(exists=True, dir_okay=False, help=DECK_HELP)],
    n: Annotated[int | None, typer.Option("-n", "--n-modes", help="number of modes (default: the case "
                                                               "control's METHOD, else 10)")] = None,
    json_out: Annotated[Path | None, typer.Option("--json", dir_okay=False, help="write results as JSON")] = None,
    solver: SolverOpt = None,
    allow_unsupported: AllowUnsupportedOpt = False,
    spc_set: SpcSetOpt = None,
    mpc_set: MpcSetOpt = None,
    subcase: SubcaseOpt = None,
) -> None:
    """Natural frequencies of a bulk-data model."""
    result = _modes_table(model, n, check_solver(solver), allow_unsupported, (spc_set, mpc_set, subcase))
    _print_table(result)
    if json_out:
        write_json(json_out, result)
