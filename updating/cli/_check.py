"""``jaxfem check``: what jaxfem read from a bulk-data deck, to compare with Nastran at a glance."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from ._common import (
    AllowUnsupportedOpt,
    MpcSetOpt,
    SpcSetOpt,
    SubcaseOpt,
    UnitsOpt,
    fail,
    load_model,
    unit_system,
    write_json,
)
# card name → group shown; by prefix, so that cards the reader learns later are grouped too
_GROUPS = (("coordinate systems", ("CORD",)), ("elements", ("C",)), ("properties", ("P",)),
           ("materials", ("MAT",)), ("rigid elements", ("RB",)), ("constraints", ("SPC", "MPC")))
_BLOCKS = {"beams": "CBAR/CBEAM", "rods": "CROD", "quads": "CQUAD4", "trias": "CTRIA3", "masses": "CONM2",
           "conm1": "CONM1", "scalar_masses": "CMASS", "direct": "DMIG"}


def _group(name: str) -> str:
    if name in ("GRID", "PARAM"):
        return name
    return next((group for group, prefixes in _GROUPS if name.startswith(prefixes)), "other cards")


def _cards(bulk) -> dict[str, dict[str, int]]:
    """Counts of the cards read, by group (elements, properties, materials, ...) and name."""
    out: dict[str, dict[str, int]] = {}
    for name, cards in sorted(bulk.cards.items()):
        if cards and _group(name) not in ("GRID", "PARAM"):
            out.setdefault(_group(name), {})[name] = len(cards)
    return out


def _files(bulk, path: Path) -> list[str]:
    """The files read: the reader's list when it keeps one (INCLUDE), else those the cards came from."""
    files = getattr(bulk, "files", None)
    if files:
        return [str(f) for f in files]
    seen = {str(path): None} | {c.file: None for cards in bulk.cards.values() for c in cards}
    return list(seen | {f: None for places in bulk.unknown.values() for f, _ in places})


def _case_control(bulk) -> dict | None:
    """The deck's case control (SOL, subcases and their choices) as plain data; None without one."""
    return None if bulk.case_control is None else bulk.case_control.to_json()


def _subcase(case: dict | None, chosen: int | None) -> dict:
    """The subcase whose choices apply (``--subcase``, else the first), empty without case control."""
    subcases = (case or {}).get("subcases") or [{}]
    return next((s for s in subcases if s.get("id") == chosen), subcases[0]) if chosen is not None else subcases[0]


def _case_line(case: dict) -> str:
    """``SOL 103; subcase 1: SPC = 1, METHOD = 10; not read: ...``: the choices made, briefly."""
    if "subcases" not in case:
        return ", ".join(f"{k} = {v}" for k, v in case.items())
    parts = [f"SOL {case['sol']}"] if case.get("sol") is not None else []
    for sub in case["subcases"]:
        chosen = [f"{k.upper()} = {v}" for k, v in sub.items()
                  if k not in ("id", "where", "places") and v not in (None, "", [], {})]
        parts.append(f"subcase {sub.get('id')}: {', '.join(chosen) or 'no SPC/MPC/METHOD chosen'}")
    ignored = sorted({str(c[0]) for c in case.get("ignored") or ()})
    return "; ".join(parts + ([f"not read: {', '.join(ignored)}"] if ignored else []))


def _sets(bulk, names: tuple[str, ...], chosen: int | None, case_choice: int | None = None) -> dict:
    """The set ids of SPC (or MPC) cards in the deck and the one applied: ``chosen``
    (the option), else the case control's, else the only one."""
    sets = sorted({c["SID"] for name in names + (names[0] + "ADD",) for c in bulk[name]})
    applied = next((s for s in (chosen, case_choice) if s is not None), sets[0] if len(sets) == 1 else None)
    return {"sets": sets, "applied": applied}


def _constraints(model, bulk, sets: tuple[int | None, ...], subcase: dict) -> dict:
    """Constrained (SPC, SPC1, GRID PS) and dependent (rigid elements, MPC) grid DoFs, auto-SPC,
    as the DoF map has them, grid by grid in any axes: the grid moves in rank(coef) ways, its
    own solved DoFs among them; the others are dependent, the remaining components
    constrained (a dependent DoF whose independent DoFs are all constrained counts there)."""
    dofs, ids = model.dofs, np.asarray(model.node_ids)
    coef = np.asarray(dofs.coef)
    moving = np.linalg.matrix_rank(coef) if coef.shape[-1] else np.zeros(len(ids), dtype=np.int64)
    own = np.searchsorted(ids, np.asarray(dofs.labels)[:, 0]) if len(dofs.labels) else np.zeros(0, np.int64)
    solved = np.bincount(own, minlength=len(ids))
    n_auto = len(dofs.auto_spc)
    mpc = _sets(bulk, ("MPC",), sets[1], subcase.get("mpc"))
    applied_mpc = {mpc["applied"]} | {s for c in bulk["MPCADD"] if c["SID"] == mpc["applied"] for s in c["S"]}
    return {
        "spc": _sets(bulk, ("SPC", "SPC1"), sets[0], subcase.get("spc")),
        "mpc": mpc,
        "constrained_dofs": int(6 * len(ids) - moving.sum() - n_auto),
        "dependent_dofs": int((moving - solved).sum()),
        "rigid_elements": {name: len(cards) for name, cards in sorted(bulk.cards.items())
                           if cards and _group(name) == "rigid elements"},
        "mpc_equations": sum(1 for c in bulk["MPC"] if c["SID"] in applied_mpc),
        "auto_spc": [[int(g), int(c)] for g, c in np.asarray(dofs.auto_spc).tolist()],
    }


def _params(model, bulk) -> list[dict]:
    """The PARAMs read and what each does to the model."""
    effects = {"COUPMASS": "lumped mass" if model.lumped else "consistent mass",
               "K6ROT": f"shell drilling stiffness K6ROT = {model.k6rot:g}",
               "WTMASS": "masses scaled by it (not M2GG), in the mass table too (Nastran's GRDPNT prints "
                         "input units: the note below converts)",
               "GRDPNT": "reference point of the mass table"}
    return [{"name": c.id, "values": [c["V1"], c["V2"]],
             "effect": effects.get(c.id, "none on stiffness or mass")} for c in bulk["PARAM"]]


def _reference(model, bulk, reference: int | None) -> tuple[int, str | None]:
    """The mass table's reference grid: ``--reference``, else PARAM GRDPNT (0, or an undefined
    grid: the basic origin, as Nastran), with a note when GRDPNT names no grid."""
    if reference is not None:
        if reference != 0 and reference not in set(np.asarray(model.node_ids).tolist()):
            fail(f"--reference {reference}: no such grid in the model")
        return reference, None
    grdpnt = next((c for c in bulk["PARAM"] if c.id == "GRDPNT"), None)
    value = grdpnt["V1"] if grdpnt is not None else None
    if isinstance(value, int) and value > 0:
        if value in set(np.asarray(model.node_ids).tolist()):
            return value, None
        return 0, f"PARAM GRDPNT {value} is not a grid: the basic origin is the reference point, as in Nastran"
    return 0, None


def _input_units_note(props, bulk) -> str | None:
    """With PARAM WTMASS ≠ 1: the total mass in the deck's input units, as Nastran's GRDPNT
    prints it (mass ÷ WTMASS; the weight generator is not scaled by WTMASS)."""
    card = next((c for c in bulk["PARAM"] if c.id == "WTMASS"), None)
    if card is None or card["V1"] == 1.0:
        return None
    return (f"PARAM WTMASS {card['V1']:g}: the table is in mass units (input × WTMASS); Nastran's GRDPNT prints "
            f"input units: total {props.mass / card['V1']:.6E}")


def check_summary(path: Path, model, bulk, reference: int | None = None,
                  sets: tuple[int | None, ...] = (None, None, None), units: str = "SI") -> tuple[dict, object]:
    """Everything ``jaxfem check`` prints as plain data (the ``--json`` content), and the
    :class:`jaxfem.MassProperties` of its mass table."""
    import jaxfem

    grid, note = _reference(model, bulk, reference)
    props = jaxfem.mass_properties(model, grid)
    note = "; ".join(n for n in (note, _input_units_note(props, bulk)) if n) or None
    n_scalar = 0 if model.scalar_rows is None else len(model.scalar_rows)
    xyz = np.delete(np.asarray(model.xyz), [] if model.scalar_rows is None else model.scalar_rows, axis=0)
    structural = set(bulk.structural_unknown())
    case = _case_control(bulk)
    return {
        "model": str(path),
        "files": _files(bulk, path),
        "case_control": case,
        "grids": {"count": len(model.node_ids) - n_scalar, "scalar_points": n_scalar,
                  "in_local_cd": sum(1 for c in bulk["GRID"] if c["CD"]),
                  "min": xyz.min(axis=0).tolist() if len(xyz) else None,
                  "max": xyz.max(axis=0).tolist() if len(xyz) else None},
        "cards": _cards(bulk),
        "mass": props.to_json() | ({"note": note} if note else {}),
        "constraints": _constraints(model, bulk, sets, _subcase(case, (tuple(sets) + (None,) * 3)[2])),
        "dofs": {"grid": 6 * len(model.node_ids), "solved": int(model.n_dof),
                 "massless": len(model.dofs.massless)},
        "params": _params(model, bulk),
        "ignored_cards": {n: [f"{f}:{line}" for f, line in p] for n, p in sorted(bulk.unknown.items())
                          if n not in structural},
        "unsupported_cards": {n: [f"{f}:{line}" for f, line in bulk.unknown[n]] for n in sorted(structural)},
        "units": unit_system(units).describe() + " (inertia mass·length²; the deck carries no units: --units "
                                                  "names them)",
    }, props


def _counts(group: dict[str, int]) -> str:
    return ", ".join(f"{name} {n}" for name, n in group.items()) or "none"


def _places(cards: dict[str, list[str]]) -> str:
    return "; ".join(f"{n} x{len(p)} ({', '.join(p[:3])}{', ...' if len(p) > 3 else ''})"
                     for n, p in cards.items()) or "none"


def _print_summary(result: dict, table: str) -> None:
    echo = typer.echo
    echo(f"files read: {', '.join(result['files'])}")
    if result["case_control"]:
        echo(f"case control: {_case_line(result['case_control'])}")
    g = result["grids"]
    box = "" if g["min"] is None else "; bounding box " + ", ".join(
        f"{axis} {lo:.6g} … {hi:.6g}" for axis, lo, hi in zip("xyz", g["min"], g["max"]))
    scalar = f" (and {g['scalar_points']} scalar points)" if g["scalar_points"] else ""
    echo(f"grids: {g['count']}{scalar}{box}")
    if g["in_local_cd"]:
        echo(f"displacement systems: {g['in_local_cd']} grids with CD ≠ 0: their constraints, springs, scalar "
             "masses and DoF labels are in the CD axes; mode shapes and sensors in basic axes")
    for group in ("elements", "properties", "materials", "coordinate systems", "other cards"):
        if group in result["cards"] or group in ("elements", "properties", "materials"):
            echo(f"{group}: {_counts(result['cards'].get(group, {}))}")
    mass = result["mass"]
    echo("mass by element block: " + _counts({f"{b} ({_BLOCKS.get(b, b)})": f"{m:.6g}"
                                             for b, m in mass["by_block"].items()}))
    if "note" in mass:
        echo(f"note: {mass['note']}")
    echo(table)
    c = result["constraints"]
    spc, mpc = c["spc"], c["mpc"]
    echo(f"constraints: SPC set {spc['applied'] or 'none'} (in the deck: {spc['sets'] or 'none'}), "
         f"{c['constrained_dofs']} grid DoFs constrained (SPC, SPC1, GRID PS); MPC set {mpc['applied'] or 'none'} "
         f"({c['mpc_equations']} equations); rigid elements: {_counts(c['rigid_elements'])}; "
         f"{c['dependent_dofs']} dependent DoFs; auto-SPC removed {len(c['auto_spc'])} DoFs")
    if c["auto_spc"]:
        shown = ", ".join(f"({g}, {k})" for g, k in c["auto_spc"][:10])
        echo(f"auto-SPC (neither stiffness nor mass), (grid, component): {shown}"
             + (f" and {len(c['auto_spc']) - 10} more (all in --json)" if len(c["auto_spc"]) > 10 else ""))
    d = result["dofs"]
    echo(f"DoFs solved: {d['solved']} of {d['grid']} grid DoFs ({d['massless']} massless, condensed)")
    params = ", ".join(f"{p['name']} {' '.join(str(v) for v in p['values'] if v is not None)} ({p['effect']})"
                       for p in result["params"])
    echo(f"PARAMs: {params or 'none (lumped mass, K6ROT 100)'}")
    echo(f"ignored cards (no effect on stiffness or mass): {_places(result['ignored_cards'])}")
    echo(f"unsupported structural cards, left out (--allow-unsupported): {_places(result['unsupported_cards'])}")
    echo(f"units: {result['units']}")


def check(
    model: Annotated[Path, typer.Argument(metavar="DECK", exists=True, dir_okay=False, help="Nastran bulk data")],
    json_out: Annotated[Path | None, typer.Option("--json", dir_okay=False, help="write the summary as JSON")] = None,
    reference: Annotated[int | None, typer.Option(
        "--reference", metavar="GRID", help="reference grid of the mass table (default: PARAM GRDPNT, "
                                            "else the basic origin)")] = None,
    allow_unsupported: AllowUnsupportedOpt = False,
    spc_set: SpcSetOpt = None,
    mpc_set: MpcSetOpt = None,
    subcase: SubcaseOpt = None,
    units: UnitsOpt = "SI",
) -> None:
    """What jaxfem read from a deck: files, grids, cards by type, mass, CG and inertia (as
    Nastran's GRDPNT table), constraints, DoFs, PARAMs, ignored and unsupported cards."""
    content: dict = {}
    built = load_model(model, content, allow_unsupported, (spc_set, mpc_set, subcase))
    result, props = check_summary(model, built, content["bulk"], reference, (spc_set, mpc_set, subcase), units)
    _print_summary(result, props.table())
    if json_out:
        write_json(json_out, result)
