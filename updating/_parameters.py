"""Updating parameters: correction factors (eq. 3.1) and physical values, from TOML.

Every parameter is a relative factor α on its target (``value = value₀ (1 + α)``; for
``stiffness``/``mass`` it is the correction factor α_i/β_j of eq. 3.1). The solver works
on ``θ = log(1 + α)``, so ``α = e^θ − 1 > −1`` holds by construction: stiffness and mass
can never vanish or turn negative, with no clipping (thesis §3.2.1). Two kinds add α
instead: ``a`` and the ply angle ``theta`` (radians, so bounded below by −1 rad).
"""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

import jaxfem
from jaxfem import Model
from jaxfem._model import MAT1, MAT2, MAT8

from . import _schema as schema
from ._schema import FieldError as FieldError

KINDS = ("stiffness", "mass", "E", "G", "rho", "A", "I1", "I2", "J", "k", "m", "a",
         "membrane", "bending", "transverse_shear", "E1", "E2", "G12", "G1Z", "G2Z", "NU12", "t", "nsm", "theta")
# Material kinds: the Materials column scaled and the material types (MAT1/2/8) it acts on.
_MATERIAL = {
    "E": ("E", (MAT1,)), "G": ("G", (MAT1,)), "rho": ("rho", (MAT1, MAT2, MAT8)),
    "E1": ("E", (MAT8,)), "E2": ("E2", (MAT8,)), "G12": ("G", (MAT8,)),
    "G1Z": ("G1z", (MAT8,)), "G2Z": ("G2z", (MAT8,)), "NU12": ("nu", (MAT8,)),
}
_SECTION = {"A", "I1", "I2", "J"}
# Shell section kinds: the ShellSections factor each scales (A, D, S of the laminate).
_SHELL_FACTOR = {"membrane": "membrane", "bending": "bending", "transverse_shear": "shear"}
_SHELL = set(_SHELL_FACTOR) | {"t", "theta"}
_PIDS_ONLY = set(_MATERIAL) | _SECTION | _SHELL | {"nsm", "a"}
# Kinds that also take shell element ids: the element's own factor (Shells.parts) or NSM (Shells.nsm).
_SHELL_ELEMENT = {"membrane": 0, "bending": 1, "transverse_shear": 2, "nsm": None}
# Where sections name their material rows: (section table, column).
_MATERIAL_COLUMNS = (("beam_sections", "material"), ("rod_sections", "material"),
                     ("shell_sections", "materials"), ("shell_sections", "ply_material"))


def _weight(v):
    if isinstance(v, str) and v == "auto":
        return v
    try:
        return schema.number(0.0, strict=True)(v)
    except schema.Expected:
        raise schema.Expected("\"auto\" or a finite number > 0") from None


def _file_bounds(v):
    """In a parameter file, lower > −1 strictly (a bound at α = −1, a value of 0, is a slip)."""
    return schema.bounds(v, ">")


_PARAMETER_SCHEMA = {
    "name": schema.name, "kind": schema.choice(*KINDS), "pids": schema.integers("property ids", nonempty=False),
    "eids": schema.integers("element ids", nonempty=False), "nodes": schema.integers("grid ids", nonempty=False),
    "bounds": schema.bounds,
}


@dataclass(frozen=True)
class Parameter:
    """One updating parameter: a relative factor on the values of a target.

    ``kind``: ``stiffness`` | ``mass`` (element groups, eq. 3.1) or a physical value
    ``E``, ``G`` (MAT1), ``rho`` (any material) of the materials of the target
    properties, ``A``, ``I1``, ``I2``, ``J`` (beam and rod sections), ``k`` (springs and
    bushes), ``m`` (CONM2 masses), ``a`` (the coefficient of the model's frequency law,
    :class:`jaxfem.Viscoelastic`, additive: ``a = a₀ + α``; its pids name the layer).
    Shells (PSHELL/PCOMP pids): ``membrane``, ``bending``, ``transverse_shear`` (the
    laminate's A, D, S), ``E1``, ``E2``, ``G12``, ``G1Z``, ``G2Z``, ``NU12`` (their MAT8
    materials), ``t`` (thickness: PSHELL T, every PCOMP ply and Z0), ``theta`` (every
    PCOMP ply angle, additive in radians: ``θ_ply = θ_ply,0 + α``); ``nsm`` (shell, beam
    and rod sections). Targets: ``pids`` (property ids), ``eids`` (element ids) or, for
    ``k``/``m``, ``nodes`` (grid ids); ``membrane``, ``bending``, ``transverse_shear``
    and ``nsm`` on shell ``eids`` scale those elements' own factor or non-structural mass
    (:class:`jaxfem.Shells` ``parts``, ``nsm``: a patch). ``bounds``: plausible range of α, reported (not
    enforced).

    Checked on construction (:class:`FieldError` naming the key): ``name`` a non-empty
    string, ``kind`` one of :data:`KINDS`, ids integers ≥ 1 (a bool or 1.7 is refused,
    not truncated), ``bounds`` two finite numbers, −1 ≤ lower < upper, and the targets
    the kind takes. Whether the targets hold what the kind scales is checked against a
    model by :func:`parameterise`.
    """

    name: str
    kind: str
    pids: tuple[int, ...] = ()
    eids: tuple[int, ...] = ()
    nodes: tuple[int, ...] = ()
    bounds: tuple[float, float] = (-0.5, 1.0)

    def __post_init__(self):
        owner = f"parameter {self.name!r}"
        for key, check in _PARAMETER_SCHEMA.items():
            try:
                object.__setattr__(self, key, schema.checked(key, check, getattr(self, key)))
            except FieldError as err:
                raise FieldError(err.key, err.text, owner) from None

        def fail(key, text):
            raise FieldError(key, text, owner)

        if not (self.pids or self.eids or self.nodes):
            fail("pids", "no target: give pids, eids or nodes")
        if self.nodes and self.kind not in ("k", "m"):
            fail("nodes", f"nodes = [...] is only for kinds k and m, not kind {self.kind}")
        if self.kind == "m" and self.pids:
            fail("pids", "kind m (CONM2) targets eids or nodes, not pids")
        if self.kind in _SHELL_ELEMENT and self.eids and not self.pids:
            pass
        elif self.kind in _PIDS_ONLY:
            if self.eids:
                fail("eids", f"kind {self.kind} needs pids = [...], not eids")
            if not self.pids:
                fail("pids", f"kind {self.kind} needs pids = [...]")


MAX_ITERATIONS = 100_000  # the loop keeps one history row per accepted iteration

_OPTIONS_SCHEMA = {
    "active_modes": schema.integers("test mode numbers", nonempty=True),
    "passive_modes": schema.integers("test mode numbers", nonempty=False),
    "residual": schema.choice("eigenvalue", "eigenvector", "combined"),
    "eigenvalue_weight": _weight,
    "regularisation": schema.number(0.0, strict=False),
    "solver": schema.choice("levenberg-marquardt", "gauss-newton"),
    "max_iterations": schema.integer(1, MAX_ITERATIONS),
    "tolerance": schema.number(0.0, strict=True),
    "min_mac": schema.number(0.0, strict=False, high=1.0),
    "max_freq_dev": schema.number(0.0, strict=True),
    "n_model_modes": schema.integer(1),
    "eigensolver": schema.choice("auto", "dense", "sparse"),
}
_OPTIONAL = {"active_modes", "n_model_modes"}  # None: the default rule


@dataclass(frozen=True)
class Options:
    """Updating options (TOML table ``[options]``); thresholds of §4.3.3.3 and §5.2.4.

    ``active_modes``/``passive_modes``: test mode numbers (1-based, file order) used in the
    fit / held out for prediction (default: all active). ``residual``: ``eigenvalue``,
    ``eigenvector`` or ``combined`` (§3.2.2). ``eigenvalue_weight``: ``"auto"`` (§5.2.4)
    or a number. ``regularisation``: μ of W_p = μ I (eq. 3.4) on θ. ``tolerance``:
    convergence when max |Δα| ≤ tolerance between iterations (§4.2.5.1, footnote 8).
    ``eigensolver``: ``auto``, ``dense`` or ``sparse`` (:func:`jaxfem.modes`).

    Every value is checked on construction against the schema of docs/parameters.md (type
    and range; a :class:`FieldError` naming the key): the one check of the TOML table and
    of Python callers alike.
    """

    active_modes: tuple[int, ...] | None = None
    passive_modes: tuple[int, ...] = ()
    residual: str = "combined"
    eigenvalue_weight: float | str = "auto"
    regularisation: float = 0.0
    solver: str = "levenberg-marquardt"
    max_iterations: int = 50
    tolerance: float = 1e-3
    min_mac: float = 0.65
    max_freq_dev: float = 0.30
    n_model_modes: int | None = None
    eigensolver: str = "auto"

    def __post_init__(self):
        for key, check in _OPTIONS_SCHEMA.items():
            value = getattr(self, key)
            if not (value is None and key in _OPTIONAL):
                try:
                    object.__setattr__(self, key, schema.checked(key, check, value))
                except FieldError as err:
                    raise FieldError(err.key, err.text, "options") from None
        both = sorted(set(self.active_modes or ()) & set(self.passive_modes))
        if both:
            raise FieldError("passive_modes", f"test modes {both} are also in active_modes: "
                             "a mode is fitted or held out, not both", "options")

    @classmethod
    def from_dict(cls, table, where: str) -> Options:
        """From the parsed ``[options]`` table; errors name ``where`` and ``options.KEY``."""
        if not isinstance(table, dict):
            raise ValueError(f"{where}: options: expected a table [options], got {schema.show(table)}")
        schema.refuse_unknown(table, cls.__dataclass_fields__, where, "options.")
        try:
            return cls(**table)
        except FieldError as err:
            raise ValueError(f"{where}: options.{err.key}: {err.text}") from None


@dataclass(frozen=True)
class ParameterSet:
    """Parameters and options, as declared in a TOML file (schema in docs/parameters.md)."""

    parameters: tuple[Parameter, ...]
    options: Options = field(default_factory=Options)

    def __post_init__(self):
        names = [p.name for p in self.parameters]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"duplicate parameter names: {dup}")

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.parameters]

    @classmethod
    def from_toml(cls, path: str | Path) -> ParameterSet:
        """Read ``[[parameter]]`` entries and an optional ``[options]`` table; every key is
        checked before any computation (:meth:`from_dict`). Errors: ``ValueError`` naming
        the file and the key."""
        path = Path(path)
        try:
            data = tomllib.loads(path.read_bytes().decode("utf-8"))
        except UnicodeDecodeError as err:
            raise ValueError(f"{path}: not UTF-8 text: {err}") from None
        except tomllib.TOMLDecodeError as err:
            raise ValueError(f"{path}: {err}") from None
        schema.refuse_unknown(data, ("parameter", "options"), str(path), "")
        return cls.from_dict(data, str(path))

    @classmethod
    def from_dict(cls, data: dict, where: str) -> ParameterSet:
        """From the ``parameter`` array and ``options`` table of parsed TOML.

        The schema of docs/parameters.md, checked key by key before anything is computed;
        a ``ValueError`` names ``where``, the key (``parameter[2].pids``, counted from 1
        in file order, ``options.max_iterations``) and what was expected. Unknown keys are
        errors. Bounds in a file need −1 < lower < upper.
        """
        entries = data.get("parameter", [])
        if not isinstance(entries, list):
            raise ValueError(f"{where}: parameter: expected [[parameter]] tables (an array of tables), "
                             f"got {schema.show(entries)}")
        if not entries:
            raise ValueError(f"{where}: no [[parameter]] declared")
        params, first = [], {}
        for i, entry in enumerate(entries, 1):
            key = f"parameter[{i}]"
            if not isinstance(entry, dict):
                raise ValueError(f"{where}: {key}: expected a table ([[parameter]]), got {schema.show(entry)}")
            schema.refuse_unknown(entry, _PARAMETER_SCHEMA, where, key + ".")
            for required in ("name", "kind"):
                if required not in entry:
                    raise ValueError(f"{where}: {key}.{required}: required (keys: name, kind, and pids, eids or nodes)")
            label = f" (parameter {entry['name']!r})" if isinstance(entry["name"], str) else ""
            try:
                if "bounds" in entry:
                    schema.checked("bounds", _file_bounds, entry["bounds"])
                params.append(Parameter(**entry))
            except FieldError as err:
                raise ValueError(f"{where}: {key}.{err.key}: {err.text}{label}") from None
            name = params[-1].name
            if name in first:
                raise ValueError(f"{where}: {key}.name: {name!r} is also the name of {first[name]}; names are unique")
            first[name] = key
        return cls(tuple(params), Options.from_dict(data.get("options", {}), where))


class Parameterisation(eqx.Module):
    """A :class:`ParameterSet` resolved against one model: ``apply(model, θ)`` is pure JAX.

    Built by :func:`parameterise`, which may give target properties private material
    rows (so that ``E`` of some properties does not change others sharing the material).
    """

    parameters: tuple[Parameter, ...] = eqx.field(static=True)
    stiffness_groups: tuple[tuple[int, ...], ...] = eqx.field(static=True)  # element ids
    mass_groups: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    stiffness_index: tuple[int, ...] = eqx.field(static=True)
    mass_index: tuple[int, ...] = eqx.field(static=True)

    def apply(self, model: Model, theta: Float[Array, " p"]) -> Model:
        """The model with every parameter's factor applied; differentiable in θ."""
        scale = jnp.exp(theta)  # 1 + α
        alpha = scale - 1.0
        model = jaxfem.correct(
            model,
            self.stiffness_groups,
            alpha[jnp.asarray(self.stiffness_index, dtype=int)],
            self.mass_groups,
            alpha[jnp.asarray(self.mass_index, dtype=int)],
        )
        for i, p in enumerate(self.parameters):
            if p.kind in ("stiffness", "mass"):
                continue
            model = _scale_physical(model, p, scale[i])
        return model


def _rows(ids: np.ndarray, wanted: Sequence[int]) -> np.ndarray:
    return np.flatnonzero(np.isin(ids, np.asarray(wanted, dtype=np.int64)))


def _scale_rows(values: Array, rows: np.ndarray, factor) -> Array:
    mask = np.zeros(values.shape[0])
    mask[rows] = 1.0
    shape = (-1,) + (1,) * (values.ndim - 1)
    return values * (1.0 + (factor - 1.0) * jnp.asarray(mask).reshape(shape))


def _scale_physical(model: Model, p: Parameter, factor) -> Model:
    if p.kind in _SHELL_ELEMENT and p.eids:
        for name in ("quads", "trias"):
            sh, rows = getattr(model, name), _rows(getattr(model, name).ids, p.eids)
            col = _SHELL_ELEMENT[p.kind]
            if col is None:
                model = eqx.tree_at(lambda m: getattr(m, name).nsm, model, _scale_rows(sh.nsm, rows, factor))
            else:
                parts = sh.parts.at[:, col].set(_scale_rows(sh.parts[:, col], rows, factor))
                model = eqx.tree_at(lambda m: getattr(m, name).parts, model, parts)
        return model
    if p.kind in _MATERIAL:
        field_name, types = _MATERIAL[p.kind]
        rows = _material_rows(model, p.pids, types)
        values = getattr(model.materials, field_name)
        return eqx.tree_at(lambda m: getattr(m.materials, field_name), model,
                           _scale_rows(values, rows, factor))
    if p.kind in _SECTION:
        rows = _rows(model.beam_sections.ids, p.pids)
        model = eqx.tree_at(lambda m: getattr(m.beam_sections, p.kind), model,
                            _scale_rows(getattr(model.beam_sections, p.kind), rows, factor))
        if p.kind in ("A", "J"):
            rows = _rows(model.rod_sections.ids, p.pids)
            model = eqx.tree_at(lambda m: getattr(m.rod_sections, p.kind), model,
                                _scale_rows(getattr(model.rod_sections, p.kind), rows, factor))
        return model
    if p.kind in _SHELL:
        sec = model.shell_sections
        rows = _rows(sec.ids, p.pids)
        if p.kind in _SHELL_FACTOR:
            name = _SHELL_FACTOR[p.kind]
            return eqx.tree_at(lambda m: getattr(m.shell_sections, name), model,
                               _scale_rows(getattr(sec, name), rows, factor))
        if p.kind == "t":  # PSHELL T; PCOMP plies and Z0 together (same centre); t = Σ plies
            return eqx.tree_at(lambda m: (m.shell_sections.t, m.shell_sections.z0, m.shell_sections.ply_t), model,
                               tuple(_scale_rows(v, rows, factor) for v in (sec.t, sec.z0, sec.ply_t)))
        plies = np.zeros(sec.ply_theta.shape)  # kind theta: every ply of the target PCOMPs
        plies[rows] = np.asarray(sec.ply_material)[rows] >= 0
        return eqx.tree_at(lambda m: m.shell_sections.ply_theta, model,
                           sec.ply_theta + (factor - 1.0) * jnp.asarray(plies))
    if p.kind == "nsm":
        for name in ("beam_sections", "rod_sections", "shell_sections"):
            sec = getattr(model, name)
            model = eqx.tree_at(lambda m: getattr(m, name).nsm, model,
                                _scale_rows(sec.nsm, _rows(sec.ids, p.pids), factor))
        return model
    if p.kind == "a":
        if model.viscoelastic is None:
            raise ValueError(f"parameter {p.name!r}: kind a needs a model with a frequency law")
        return eqx.tree_at(lambda m: m.viscoelastic.a, model, model.viscoelastic.a + (factor - 1.0))
    if p.kind == "k":
        s, b = model.springs, model.bushes
        srows = _target_rows(model, s, p)
        brows = _target_rows(model, b, p)
        model = eqx.tree_at(lambda m: m.springs.k, model, _scale_rows(s.k, srows, factor))
        return eqx.tree_at(lambda m: m.bushes.k, model, _scale_rows(b.k, brows, factor))
    c = model.masses  # kind "m"
    rows = np.union1d(_rows(c.ids, p.eids), np.flatnonzero(np.isin(model.node_ids[c.nodes], p.nodes)))
    return eqx.tree_at(lambda m: m.masses.m, model, _scale_rows(c.m, rows, factor))


def _section_materials(model: Model, pids: Sequence[int]) -> dict[int, np.ndarray]:
    """pid → the material rows its section names (beam, rod, PSHELL roles, PCOMP plies)."""
    out: dict[int, list] = {}
    for name, column in _MATERIAL_COLUMNS:
        sec = getattr(model, name)
        rows = np.asarray(getattr(sec, column))
        for r in _rows(sec.ids, pids):
            out.setdefault(int(sec.ids[r]), []).extend(int(m) for m in np.ravel(rows[r]) if m >= 0)
    return {pid: np.unique(np.asarray(rows, np.int64)) for pid, rows in out.items()}


def _material_rows(model: Model, pids: Sequence[int], types=(MAT1, MAT2, MAT8)) -> np.ndarray:
    """Material rows of the types ``types`` (MAT1, MAT2, MAT8) named by the sections of ``pids``."""
    rows = np.concatenate([np.zeros(0, np.int64), *_section_materials(model, pids).values()])
    rows = np.unique(rows)
    return rows[np.isin(model.materials.kind[rows], types)]


_TYPE_NAMES = {MAT1: "MAT1", MAT2: "MAT2", MAT8: "MAT8"}


class _Ids(list):
    """Ids in a message: the first ten, then how many in all."""

    def __repr__(self) -> str:
        return list.__repr__(self) if len(self) <= 10 else list.__repr__(self[:10])[:-1] + f", … {len(self)} in all]"


def _missing(wanted: Sequence[int], present) -> _Ids:
    present = set(np.asarray(present).tolist())
    return _Ids(int(i) for i in wanted if i not in present)


def _block_problem(model: Model, p: Parameter) -> str | None:
    """Why targets of the element kinds (``stiffness``, ``mass``, ``k``, ``m``) or the beam
    section kinds have nothing ``p`` scales: each named id must hold it (None: fine). A
    target without it would leave its column zero: α stays 0 and the update "converges"."""
    blocks = lambda names: [getattr(model, n) for n in names]  # noqa: E731
    cat = lambda arrays: np.concatenate([np.zeros(0, np.int64)] + [np.asarray(a) for a in arrays])  # noqa: E731
    if p.kind in ("stiffness", "mass"):
        names = jaxfem.STIFFNESS_BLOCKS if p.kind == "stiffness" else jaxfem.MASS_BLOCKS
        eids = _missing(p.eids, cat(b.ids for b in blocks(names)))
        if eids:
            what = "CONM2 masses (no stiffness)" if p.kind == "stiffness" else "springs or bushes (no mass)"
            return f"eids {eids} are {what}: nothing for kind {p.kind} to scale"
        pids = _missing(p.pids, cat(b.pids for b in blocks(n for n in names if n != "masses")))
        if pids:
            other = "" if p.kind == "stiffness" else " (PELAS and PBUSH elements have no mass)"
            return (f"pids {pids} are used by no element with a {p.kind} matrix{other}: "
                    f"nothing for kind {p.kind} to scale")
        return None
    if p.kind == "k":
        sb = blocks(("springs", "bushes"))
        eids = _missing(p.eids, cat(b.ids for b in sb))
        pids = _missing(p.pids, cat(b.pids for b in sb))
        attached = cat(model.node_ids[b.nodes[b.nodes >= 0]] for b in sb)
        nodes = _missing(p.nodes, attached)
        for key, bad, what in (("eids", eids, "are not springs or bushes (CELAS, CBUSH)"),
                               ("pids", pids, "are not PELAS or PBUSH properties"),
                               ("nodes", nodes, "have no spring or bush attached")):
            if bad:
                return f"{key} {bad} {what}: nothing for kind k (spring and bush stiffness) to scale"
        return None
    if p.kind == "m":
        c = model.masses
        for key, bad, what in (("eids", _missing(p.eids, c.ids), "are not CONM2 masses"),
                               ("nodes", _missing(p.nodes, model.node_ids[c.nodes]), "carry no CONM2 mass")):
            if bad:
                return f"{key} {bad} {what}: nothing for kind m (CONM2 mass) to scale"
        return None
    if p.kind in _SECTION:
        rods = p.kind in ("A", "J")
        pids = _missing(p.pids, cat([model.beam_sections.ids] + ([model.rod_sections.ids] if rods else [])))
        if pids:
            held = "PBAR/PBARL/PBEAM" + ("/PROD" if rods else "")
            return f"pids {pids} are not {held} properties: nothing for kind {p.kind} to scale" \
                + ("" if rods else " (a PROD has A and J only)")
    return None


def _target_problem(model: Model, p: Parameter) -> str | None:
    """Why the targets of ``p`` have nothing that it scales (None: fine)."""
    problem = _block_problem(model, p)
    if problem or p.kind in ("stiffness", "mass", "k", "m") or p.kind in _SECTION:
        return problem
    if p.kind in _SHELL_ELEMENT and p.eids:
        shells = np.concatenate([model.quads.ids, model.trias.ids])
        other = sorted(set(p.eids) - set(shells.tolist()))
        if other:
            return f"eids {other[:10]} are not shells (kind {p.kind} on eids acts on CQUAD4/CTRIA3 elements)"
        if p.kind == "nsm" and not any(np.any(np.asarray(getattr(model, n).nsm)[_rows(getattr(model, n).ids, p.eids)])
                                       for n in ("quads", "trias")):
            return "the elements' own NSM is 0: a relative factor cannot change it (an effect sets it first)"
        return None
    if p.kind in _MATERIAL:
        _, types = _MATERIAL[p.kind]
        used = _section_materials(model, p.pids)
        kinds = model.materials.kind
        none = [pid for pid in p.pids if not np.isin(kinds[used.get(pid, np.zeros(0, np.int64))], types).any()]
        if none:
            wanted = "/".join(_TYPE_NAMES[t] for t in types)
            return f"pids {none} use no {wanted} material (kind {p.kind} scales {wanted} materials)"
        if p.kind in ("G1Z", "G2Z"):
            sec = model.shell_sections
            rows = _rows(sec.ids, p.pids)
            shear = [np.asarray(sec.ply_material)[r] if sec.composite[r] else np.asarray(sec.materials)[r, 2:3]
                     for r in rows]
            values = np.asarray(getattr(model.materials, _MATERIAL[p.kind][0]))
            bad = [int(sec.ids[r]) for r, m in zip(rows, shear)
                   if sec.shear_rigid[r] or not ((kinds[m[m >= 0]] == MAT8) & (values[m[m >= 0]] > 0)).any()]
            if bad:
                return (f"pids {sorted(bad)} have no MAT8 transverse-shear material with {p.kind} > 0 "
                        "(MID3 of a PSHELL, or the plies of a PCOMP not shear rigid)")
        return None
    if p.kind in _SHELL:
        sec = model.shell_sections
        shells = set(sec.ids.tolist())
        other = [pid for pid in p.pids if pid not in shells]
        if other:
            return f"pids {other} are not PSHELL or PCOMP properties (kind {p.kind} acts on shell sections)"
        rows = _rows(sec.ids, p.pids)
        if p.kind == "theta":
            pshell = [int(sec.ids[r]) for r in rows if not sec.composite[r]]
            if pshell:
                return f"pids {pshell} are PSHELL; kind theta rotates the plies of PCOMP properties"
        if p.kind == "transverse_shear":
            rigid = [int(sec.ids[r]) for r in rows if sec.shear_rigid[r]]
            if rigid:
                return f"pids {rigid} are shear rigid (blank MID3, or MAT8 plies without G1Z/G2Z): no S to scale"
        return None
    if p.kind == "nsm":
        values, known = [], set()
        for name in ("beam_sections", "rod_sections", "shell_sections"):
            sec = getattr(model, name)
            rows = _rows(sec.ids, p.pids)
            values.append(np.asarray(sec.nsm)[rows])
            known |= set(sec.ids[rows].tolist())
        other = [pid for pid in p.pids if pid not in known]
        if other:
            return f"pids {other} are not beam, rod or shell properties (kind nsm)"
        if not np.any(np.concatenate(values)):
            return "NSM is 0 on every target property: a relative factor cannot change it"
    return None


def _target_rows(model: Model, block, p: Parameter) -> np.ndarray:
    """Springs or bushes named by eid or pid, or attached to one of ``p.nodes``."""
    at_node = np.isin(model.node_ids[np.maximum(block.nodes, 0)], p.nodes) & (block.nodes >= 0)
    rows = np.union1d(_rows(block.ids, p.eids), _rows(block.pids, p.pids))
    return np.union1d(rows, np.flatnonzero(at_node.any(axis=1)))


def _element_group(model: Model, p: Parameter) -> np.ndarray:
    return np.union1d(model.element_ids(pids=p.pids) if p.pids else np.zeros(0, np.int64),
                      np.asarray(p.eids, dtype=np.int64))


def _copy_material(mats, row: int):
    """The material table with row ``row`` appended again, under the id −(its id)."""
    copy = jax.tree.map(lambda a: a[row : row + 1], mats)
    copy = eqx.tree_at(lambda m: m.ids, copy, -copy.ids)
    return jax.tree.map(lambda a, b: (np if isinstance(a, np.ndarray) else jnp).concatenate([a, b]), mats, copy)


def _private_materials(model: Model, pids: Sequence[int], types=(MAT1, MAT2, MAT8)) -> Model:
    """Give the sections of ``pids`` their own material rows (copies) where they share one
    (of the types ``types``) with a property outside ``pids``.

    Every reference is redirected: beam and rod ``material``, the PSHELL roles (MID1..MID4)
    and PCOMP plies of shell sections. One copy per shared material, used by all the
    targets' references to it (a PSHELL with MID1 = MID2 keeps one material).
    """
    tables = {}
    for name, column in _MATERIAL_COLUMNS:
        sec = getattr(model, name)
        rows = np.array(getattr(sec, column), dtype=np.int64, copy=True)
        target = np.isin(sec.ids, np.asarray(pids, np.int64)).reshape((-1,) + (1,) * (rows.ndim - 1))
        tables[name, column] = (rows, np.broadcast_to(target, rows.shape) & (rows >= 0))
    by_target = set().union(*(rows[t].tolist() for rows, t in tables.values()))
    by_others = set().union(*(rows[~t & (rows >= 0)].tolist() for rows, t in tables.values()))
    kinds = model.materials.kind
    shared = sorted(m for m in by_target & by_others if kinds[m] in types)
    if not shared:
        return model
    mats = model.materials
    for m in shared:
        new = len(mats.ids)
        mats = _copy_material(mats, m)
        for rows, target in tables.values():
            rows[target & (rows == m)] = new
    model = eqx.tree_at(lambda md: md.materials, model, mats)
    for (name, column), (rows, _) in tables.items():
        model = eqx.tree_at(lambda md: getattr(getattr(md, name), column), model, rows)
    return model


def _column(model: Model, p: Parameter) -> tuple:
    """What ``p`` scales, resolved (an element group, spring rows, ...): two parameters with
    the same key have identical Jacobian columns."""
    if p.kind in ("stiffness", "mass"):
        return p.kind, frozenset(_element_group(model, p).tolist())
    if p.kind == "k":
        return p.kind, frozenset(_target_rows(model, model.springs, p).tolist()), \
            frozenset(_target_rows(model, model.bushes, p).tolist())
    if p.kind == "m":
        c = model.masses
        return p.kind, frozenset(np.union1d(_rows(c.ids, p.eids),
                                            np.flatnonzero(np.isin(model.node_ids[c.nodes], p.nodes))).tolist())
    if p.kind == "a":  # one coefficient of the frequency law, whatever the pids
        return (p.kind,)
    return p.kind, frozenset(p.pids), frozenset(p.eids)


def identical_columns(model: Model, parameters: ParameterSet | Sequence[Parameter]) -> str | None:
    """Parameters of the same kind on the same targets (however named: pids or their
    eids), whose Jacobian columns are therefore identical, named pair by pair; None if
    there are none. Only their combined effect is identifiable (JᵀJ is singular); the
    parameter selection aids (:func:`updating.identifiability`) report such pairs too."""
    params = tuple(parameters.parameters if isinstance(parameters, ParameterSet) else parameters)
    seen, pairs = {}, []
    for p in params:
        column = _column(model, p)
        if column in seen:
            pairs.append(f"{seen[column].name!r} and {p.name!r} (kind {p.kind})")
        seen.setdefault(column, p)
    if not pairs:
        return None
    return (f"parameters {'; '.join(pairs)} scale the same targets: identical Jacobian columns, "
            "only their combined effect is identifiable")


def parameterise(model: Model, parameters: ParameterSet | Sequence[Parameter]) -> tuple[Model, Parameterisation]:
    """Resolve parameters against a model; check every target exists, holds what its
    parameter's kind scales (an ``m`` on a CBAR, an ``I1`` on a PROD are refused): a
    ``ValueError`` naming the parameter, its kind and those targets. Two parameters on the
    same targets are left to :func:`identical_columns`.

    **Returns:** ``(model, parameterisation)``: the model possibly with private material
    rows for material parameters, and the pure ``apply(model, θ)`` map.
    """
    params = tuple(parameters.parameters if isinstance(parameters, ParameterSet) else parameters)
    all_pids = set(np.concatenate([model.beam_sections.ids, model.rod_sections.ids, model.shell_sections.ids,
                                   model.springs.pids, model.bushes.pids]).tolist())
    all_eids = set(model.element_ids().tolist())
    all_nodes = set(model.node_ids.tolist())
    k_groups, m_groups, k_index, m_index = [], [], [], []
    for i, p in enumerate(params):
        for kind, wanted, known in (("pids", p.pids, all_pids), ("eids", p.eids, all_eids),
                                    ("nodes", p.nodes, all_nodes)):
            missing = sorted(set(wanted) - known)
            if missing:
                raise ValueError(f"parameter {p.name!r}: {kind} {missing} not in the model")
        if p.kind == "stiffness":
            k_groups.append(tuple(int(e) for e in _element_group(model, p)))
            k_index.append(i)
        elif p.kind == "mass":
            m_groups.append(tuple(int(e) for e in _element_group(model, p)))
            m_index.append(i)
        elif p.kind in _MATERIAL:
            model = _private_materials(model, p.pids, _MATERIAL[p.kind][1])
    for i, p in enumerate(params):
        problem = _target_problem(model, p)
        if problem:
            raise ValueError(f"parameter {p.name!r}: {problem}")
    return model, Parameterisation(params, tuple(k_groups), tuple(m_groups), tuple(k_index), tuple(m_index))
