"""What the commands share: arguments, input files with exit-2 errors, tables and JSON."""

from __future__ import annotations

import functools
import inspect
import json
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Annotated, NoReturn, get_type_hints

import numpy as np
import typer

from .. import json_safe

ModelArg = Annotated[Path, typer.Argument(metavar="MODEL.bdf", exists=True, dir_okay=False,
                                          help="Nastran deck (any consistent units: see --units)")]
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


def load_model(path: Path, content: dict | None = None, allow_unsupported: bool = False,
               sets: tuple[int | None, ...] = (None, None, None)):
    """The model of a bulk-data file; exit 2 naming the file, line, card and field when it
    cannot be read or built, naming ``--allow-unsupported`` when it holds unsupported
    structural cards; the reader's and builder's warnings on stderr. ``content``: a dict
    to receive the parsed bulk data (``bulk``); ``allow_unsupported``: build without those
    cards; ``sets``: the SPC and MPC set ids to apply and the subcase whose choices hold
    otherwise (``--spc-set``, ``--mpc-set``, ``--subcase``; None: the case control's, else the
    only set in the file) (:func:`jaxfem.build_model`)."""
    import jaxfem
    from jaxfem.io import UnsupportedCardsError, read_bdf

    with echoed_warnings():
        try:
            bulk = read_bdf(path)
            spc, mpc, subcase = (tuple(sets) + (None, None, None))[:3]
            model = jaxfem.build_model(bulk, spc, mpc, subcase=subcase, allow_unsupported=allow_unsupported)
        except UnsupportedCardsError as err:
            fail(f"cannot read model {path}: {err.problem}; --allow-unsupported builds it without them")
        except (ValueError, OSError) as err:
            fail(f"cannot read model {path}: {err}")
    if content is not None:
        content["bulk"] = bulk
    return model


def read_dataset(path: Path, key: str, what: str, dataset: int, length_units: str | None = None,
                 content: dict | None = None, dof_map: Path | None = None):
    """``read_uff(path)[key]``; exit 2 naming the file (once) when it cannot be read or holds
    no such dataset, and saying so when FRFs are asked of time histories or the reverse.
    ``content``: a dict to receive everything the file holds. ``dof_map``: CSV
    channel,node,direction for channel-only records (``--dof-map``)."""
    from identification import dataset58_function_types, read_dof_map, read_uff

    def once(message) -> str:  # read_uff's messages begin with the path
        return str(message) if str(path) in str(message) else f"{path}: {message}"

    def time_not_frfs() -> None:
        fail(f"{path} holds time histories (UFF 58, function type 1), not FRFs: make FRFs with "
             f"`jaxfem frf {path} --force ...`")

    mapping = None
    if dof_map is not None:
        try:
            mapping = read_dof_map(dof_map)
        except (ValueError, OSError) as err:
            fail(f"--dof-map: {err}")
    with echoed_warnings():
        try:
            everything = read_uff(path, length_units=length_units, dof_map=mapping)
        except (ValueError, OSError) as err:
            if key == "frfs" and isinstance(err, ValueError):
                types = dataset58_function_types(path)
                if 1 in types and 4 not in types:
                    time_not_frfs()
            fail(f"cannot read {what}: {once(err)}")
    data = everything[key]
    if content is not None:
        content.update(everything)
    if data is None:
        if key == "frfs" and everything.get("time") is not None:
            time_not_frfs()
        if key == "time" and everything.get("frfs") is not None:
            fail(f"{path} holds FRFs (UFF 58, function type 4), not time histories: give it to the commands "
                 "that read FRFs (jaxfem identify)")
        fail(f"{path}: no {what} (UFF dataset {dataset}) in the file")
    return data


def load_test(path: Path, length_units: str | None = None, content: dict | None = None):
    """The measured modes of a universal file, as real normal modes (``content``: as
    :func:`read_dataset`)."""
    return read_dataset(path, "modes", "mode shapes", 55, length_units, content).real()


TestUnitsOpt = Annotated[str | None, typer.Option(
    "--test-units", metavar="m|mm|cm|in",
    help="length unit of the test file's coordinates and shapes when it has no units dataset (164); overrides one")]
MapOpt = Annotated[str, typer.Option(
    "--map", metavar="auto|id|nearest|interpolate",
    help="how test nodes read the model: by grid id, at the nearest grid, or interpolated in the nearest shell "
         "element; auto: by id when every test node is a model grid at the same place, else nearest")]
MaxDistanceOpt = Annotated[float | None, typer.Option(
    "--max-distance", metavar="M", help="largest accepted test-node-to-model distance, m (default 5 % of the "
                                        "model's size)")]
DofMapOpt = Annotated[Path | None, typer.Option(
    "--dof-map", metavar="CSV", exists=True, dir_okay=False,
    help="channel → DoF table (columns channel,node,direction) for records without DoFs (node 0, direction 0)")]
SpcSetOpt = Annotated[int | None, typer.Option(
    "--spc-set", metavar="SID", help="the SPC/SPC1/SPCADD set to apply, over the case control's SPC = SID "
                                     "(default: the case control's, else the only one)")]
MpcSetOpt = Annotated[int | None, typer.Option(
    "--mpc-set", metavar="SID", help="the MPC/MPCADD set to apply, over the case control's MPC = SID "
                                     "(default: the case control's, else the only one)")]
SubcaseOpt = Annotated[int | None, typer.Option(
    "--subcase", metavar="ID", help="the case control's subcase whose SPC, MPC, METHOD and K2GG/M2GG/B2GG choices "
                                    "apply (default: the first)")]
AllowUnsupportedOpt = Annotated[bool, typer.Option(
    "--allow-unsupported", help="build the model without the structural cards jaxfem does not support (elements, "
                                "properties, materials it cannot read): the structure then lacks them")]
UnitsOpt = Annotated[str, typer.Option(
    "--units", metavar="SYSTEM", help="the deck's consistent unit system, for the units shown and the test geometry "
                                      "(converted to its length): SI, mm-t-s, cm-g-s, in-lbf-s, ft-lbf-s")]
AlignOpt = Annotated[bool, typer.Option(
    "--align", help="move the test geometry onto the model first (rigid least-squares fit on matched points)")]


@dataclass(frozen=True)
class Geometry:
    """The test-geometry options of a command (``--map``, ``--max-distance``,
    ``--test-units``, ``--align``, and ``--units``, the model's), declared once: each field's annotation is its typer
    option (name, help, checks) and its default the option's (:func:`geometry_options`)."""

    map: MapOpt = "auto"
    max_distance: MaxDistanceOpt = None
    test_units: TestUnitsOpt = None
    align: AlignOpt = False
    units: UnitsOpt = "SI"


DEFAULT_GEOMETRY = Geometry()  # a command's placeholder default; :func:`geometry_options` replaces it


def geometry_options(command: Callable) -> Callable:
    """``command`` with its parameter ``geometry: Geometry`` shown to typer as the fields
    of :class:`Geometry`, in its place (same options, help texts and defaults in every
    command), and passed on to it as one :class:`Geometry`."""
    hints, declared = get_type_hints(command, include_extras=True), get_type_hints(Geometry, include_extras=True)
    signature = inspect.signature(command)
    if "geometry" not in signature.parameters:
        raise TypeError(f"{command.__name__} has no parameter 'geometry'")
    params = []
    for p in signature.parameters.values():
        params += ([inspect.Parameter(f.name, p.kind, default=f.default, annotation=declared[f.name])
                    for f in fields(Geometry)] if p.name == "geometry" else [p.replace(annotation=hints[p.name])])

    @functools.wraps(command)
    def wrapped(*args, **kwargs):
        geometry = Geometry(**{f.name: kwargs.pop(f.name) for f in fields(Geometry) if f.name in kwargs})
        return command(*args, geometry=geometry, **kwargs)

    wrapped.__signature__ = inspect.Signature(params, return_annotation=hints.get("return", inspect.Signature.empty))
    wrapped.__annotations__ = {p.name: p.annotation for p in params} | {"return": hints.get("return")}
    return wrapped


def map_geometry(model, test, nodes: dict, units: dict, test_path: Path, geometry: Geometry):
    """The model with the test nodes on it and the test data renamed onto them
    (:func:`identification.map_test_geometry`); the mapping printed; exit 2 on implausible
    geometry naming the option to use."""
    from identification import map_test_geometry

    metre = unit_system(geometry.units).metre  # test coordinates are read in m: to the model's length unit
    nodes = {k: np.asarray(v) / metre for k, v in nodes.items()}
    with echoed_warnings():
        try:
            model, gmap = map_test_geometry(
                model, nodes, set(test.sensors.nodes.tolist()), method=geometry.map,
                max_distance=None if geometry.max_distance is None else geometry.max_distance / metre,
                align_frames=geometry.align,
                length_units_given=geometry.test_units is not None,
                length_factor=units["length"])
        except ValueError as err:
            fail(f"test data {test_path}: {err}")
    if metre != 1.0:  # reported in m, as the test file's coordinates
        moved = None if gmap.alignment is None else gmap.alignment | {
            "translation": np.asarray(gmap.alignment["translation"]) * metre}
        gmap = replace(gmap, xyz=gmap.xyz * metre, distance=gmap.distance * metre, alignment=moved)
    for line in gmap.lines():
        typer.echo(line)
    return model, gmap.apply(test), gmap


def unit_system(name: str):
    """The :class:`jaxfem.UnitSystem` named by ``--units``; exit 2 naming the choices."""
    import jaxfem

    if name not in jaxfem.UNIT_SYSTEMS:
        fail(f"--units {name!r}: use one of {', '.join(jaxfem.UNIT_SYSTEMS)}")
    return jaxfem.UNIT_SYSTEMS[name]


def check_solver(solver: str | None) -> str:
    """``--solver``: a name of :data:`updating.EIGENSOLVERS` (None: ``auto``); exit 2 otherwise."""
    from .. import EIGENSOLVERS

    if solver not in (None, *EIGENSOLVERS):
        fail(f"--solver {solver!r}: {' | '.join(EIGENSOLVERS)}")
    return solver or "auto"


def load_inputs(model_path: Path, test_path: Path, params_path: Path | None = None, solver: str | None = None,
                geometry: Geometry = Geometry(), allow_unsupported: bool = False,
                sets: tuple[int | None, ...] = (None, None, None)):
    """Model (with the test nodes mapped onto it, :func:`map_geometry`), real test modes,
    observation matrix, the parameter set (None without a file; ``solver``, from
    ``--solver``, overrides its eigensolver), the :class:`identification.GeometryMap` and
    everything read from the test file (:func:`identification.read_uff`), checked
    against each other; on bad input exit 2 naming the file."""
    from identification import observation_matrix

    from .. import ParameterSet, parameterise

    params = None
    check_solver(solver)
    if params_path is not None:
        try:
            params = ParameterSet.from_toml(params_path)
        except (ValueError, OSError) as err:
            fail(f"bad parameter file: {err}")
        if solver is not None:
            params = replace(params, options=replace(params.options, eigensolver=solver))
    model = load_model(model_path, allow_unsupported=allow_unsupported, sets=sets)
    content: dict = {}
    test = load_test(test_path, geometry.test_units, content)
    model, test, gmap = map_geometry(model, test, content["nodes"], content["units"], test_path, geometry)
    try:
        C = observation_matrix(model, test.sensors)[0]
    except ValueError as err:  # unknown sensor grids
        fail(f"test data {test_path}: {err}")
    if params is not None:
        try:
            parameterise(model, params)
        except ValueError as err:
            fail(f"{params_path}: {err}")
    return model, test, C, params, gmap, content


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


def frf_prediction(path: Path, test, initial, updated, plots: Path | None, gmap=None) -> dict:
    """Measured FRFs against the initial and updated model's predictions (FRAC, dB;
    thesis §4.2.5.3), printed per pair; ``plots``: also ``frf.png`` of the first pair;
    ``gmap``: the test geometry's map (:func:`map_geometry`) applied to the FRFs' DoFs."""
    from .. import frf_correlation, predict_frf

    frf = read_dataset(path, "frfs", "FRFs", 58)
    if gmap is not None:
        frf = gmap.apply(frf)
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
        from ..report import plot_frf_overlay

        unit = {"receptance": "m/N", "mobility": "m/(s·N)", "accelerance": "m/(s²·N)"}[frf.kind]
        plot_frf_overlay(frf.frequencies_hz, frf.values[:, 0, 0],
                         {"initial model": predicted["before"][:, 0, 0], "updated model": predicted["after"][:, 0, 0]},
                         f"{frf.outputs.labels[0]} / {frf.inputs.labels[0]}", plots / "frf.png", unit)
    return {"zeta": zeta, "kind": frf.kind, "pairs": pairs}
