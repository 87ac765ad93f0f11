"""``jaxfem modes``: natural frequencies of a bulk-data model."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from ._common import AllowUnsupportedOpt, MpcSetOpt, SolverOpt, SpcSetOpt, check_solver, fail, load_model, write_json

LARGE = 5000  # DoFs above which the dense solve's time and memory are announced


def _modes_table(path: Path, n_modes: int, solver: str = "auto", allow_unsupported: bool = False,
                 sets: tuple[int | None, int | None] = (None, None)) -> dict:
    """The lowest ``n_modes`` (at least 1) of the model; exit 2 with one line for a file
    that cannot be read or built, a model without mass, or a failed eigensolve."""
    import time

    import jaxfem

    if n_modes < 1:
        fail(f"-n/--n-modes must be at least 1, got {n_modes}")
    content: dict = {}
    model = load_model(path, content, allow_unsupported, sets)
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
    return {
        "model": str(path),
        "n_dof": int(model.n_dof),
        "eigensolver": "sparse" if sparse else "dense",
        "solve_seconds": time.perf_counter() - start,
        "n_massless": len(model.dofs.massless),
        "auto_spc": [[int(a), int(b)] for a, b in model.dofs.auto_spc],
        "unknown_cards": sorted(content["bulk"].unknown),
        "eigenvalues": [float(x) for x in lam],
        "frequencies_hz": freqs,
    }


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
    typer.echo(f"{'mode':>5}  {'f [Hz]':>12}  {'λ = ω² [rad²/s²]':>18}")
    for i, (f, lam) in enumerate(zip(result["frequencies_hz"], result["eigenvalues"]), 1):
        typer.echo(f"{i:>5}  {f:>12.4f}  {lam:>18.6e}")


def modes(
    model: Annotated[Path, typer.Argument(exists=True, dir_okay=False, help="Nastran bulk data (SI units)")],
    n: Annotated[int, typer.Option("-n", "--n-modes", help="number of modes")] = 10,
    json_out: Annotated[Path | None, typer.Option("--json", dir_okay=False, help="write results as JSON")] = None,
    solver: SolverOpt = None,
    allow_unsupported: AllowUnsupportedOpt = False,
    spc_set: SpcSetOpt = None,
    mpc_set: MpcSetOpt = None,
) -> None:
    """Natural frequencies of a bulk-data model."""
    result = _modes_table(model, n, check_solver(solver), allow_unsupported, (spc_set, mpc_set))
    _print_table(result)
    if json_out:
        write_json(json_out, result)
