"""Updating parameters: correction factors (eq. 3.1) and physical values, from TOML.

Every parameter is a relative factor α on its target (``value = value₀ (1 + α)``; for
``stiffness``/``mass`` it is the correction factor α_i/β_j of eq. 3.1). The solver works
on ``θ = log(1 + α)``, so ``α = e^θ − 1 > −1`` holds by construction: stiffness and mass
can never vanish or turn negative, with no clipping (thesis §3.2.1). Two kinds add α
instead: ``a`` and the ply angle ``theta`` (radians, so bounded below by −1 rad).
What each kind scales, and the checks of its targets against a model: :mod:`updating._targets`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import tomllib
from jaxtyping import Array, Float

import jaxfem
from identification import MAX_FREQ_DEV, MIN_MAC
from jaxfem import EIGENSOLVERS, Model

from . import schema
from ._targets import (
    _MATERIAL,
    _PIDS_ONLY,
    _SHELL_ELEMENT,
    _column,
    _element_group,
    _private_materials,
    _scale_physical,
    _target_problem,
)
from ._targets import KINDS as KINDS
from .schema import FieldError as FieldError


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


def _dim_index(v):
    """The DIM index of kind ``dim``: an integer ≥ 1, or None (the other kinds)."""
    return None if v is None else schema.integer(1)(v)


_PARAMETER_SCHEMA = {
    "name": schema.name, "kind": schema.choice(*KINDS), "pids": schema.integers("property ids", nonempty=False),
    "eids": schema.integers("element ids", nonempty=False), "nodes": schema.integers("grid ids", nonempty=False),
    "bounds": schema.bounds, "dim": _dim_index,
}


@dataclass(frozen=True)
class Parameter:
    """One updating parameter: a relative factor on the values of a target.

    ``kind``: ``stiffness`` | ``mass`` (element groups, eq. 3.1) or a physical value
    ``E``, ``G`` (MAT1), ``rho`` (any material) of the materials of the target
    properties, ``A``, ``I1``, ``I2``, ``J`` (beam and rod sections), ``k`` (springs and
    bushes), ``m`` (CONM2 masses), ``dim`` (the dimension DIMn, ``n`` = ``dim``, of the
    PBARL/PBEAML sections of ``pids``: A, I1, I2, J, K1, K2 recomputed through Nastran's
    section library), ``a`` (the coefficient of the model's frequency law,
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
    not truncated), ``bounds`` two finite numbers, −1 ≤ lower < upper, ``dim`` an integer
    ≥ 1 given with kind ``dim`` only, and the targets the kind takes. Whether the targets
    hold what the kind scales is checked against a model by :func:`parameterise`.
    """

    name: str
    kind: str
    pids: tuple[int, ...] = ()
    eids: tuple[int, ...] = ()
    nodes: tuple[int, ...] = ()
    bounds: tuple[float, float] = (-0.5, 1.0)
    dim: int | None = None

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
        if (self.kind == "dim") != (self.dim is not None):
            fail("dim", "kind dim needs dim = n, the index of the section dimension DIMn" if self.kind == "dim"
                 else f"dim = {self.dim} is only for kind dim, not kind {self.kind}")
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
    "eigensolver": schema.choice(*EIGENSOLVERS),
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
    min_mac: float = MIN_MAC
    max_freq_dev: float = MAX_FREQ_DEV
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

