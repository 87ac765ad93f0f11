"""Updating parameters: correction factors (eq. 3.1) and physical values, from TOML.

Every parameter is a relative factor α on its target (``value = value₀ (1 + α)``; for
``stiffness``/``mass`` it is the correction factor α_i/β_j of eq. 3.1). The solver works
on ``θ = log(1 + α)``, so ``α = e^θ − 1 > −1`` holds by construction: stiffness and mass
can never vanish or turn negative, with no clipping (thesis §3.2.1).
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

KINDS = ("stiffness", "mass", "E", "G", "rho", "A", "I1", "I2", "J", "k", "m", "a")
_MATERIAL = {"E": "E", "G": "G", "rho": "rho"}
_SECTION = {"A", "I1", "I2", "J"}


@dataclass(frozen=True)
class Parameter:
    """One updating parameter: a relative factor on the values of a target.

    ``kind``: ``stiffness`` | ``mass`` (element groups, eq. 3.1) or a physical value
    ``E``, ``G``, ``rho`` (materials of the target properties), ``A``, ``I1``, ``I2``,
    ``J`` (sections), ``k`` (springs and bushes), ``m`` (CONM2 masses), ``a`` (the
    coefficient of the model's frequency law, :class:`jaxfem.Viscoelastic`, additive:
    ``a = a₀ + α``; its pids name the layer). Targets: ``pids``
    (property ids), ``eids`` (element ids) or, for ``k``/``m``, ``nodes`` (grid ids).
    ``bounds``: plausible range of α, reported (not enforced).
    """

    name: str
    kind: str
    pids: tuple[int, ...] = ()
    eids: tuple[int, ...] = ()
    nodes: tuple[int, ...] = ()
    bounds: tuple[float, float] = (-0.5, 1.0)

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"parameter {self.name!r}: kind {self.kind!r} is not one of {KINDS}")
        if not (self.pids or self.eids or self.nodes):
            raise ValueError(f"parameter {self.name!r}: give pids, eids or nodes")
        if self.nodes and self.kind not in ("k", "m"):
            raise ValueError(f"parameter {self.name!r}: nodes = [...] is only for kinds k and m")
        if self.kind == "m" and self.pids:
            raise ValueError(f"parameter {self.name!r}: kind m (CONM2) targets eids or nodes, not pids")
        if self.kind in _MATERIAL or self.kind in _SECTION or self.kind == "a":
            if self.eids or not self.pids:
                raise ValueError(f"parameter {self.name!r}: kind {self.kind} needs pids = [...]")


@dataclass(frozen=True)
class Options:
    """Updating options (TOML table ``[options]``); thresholds of §4.3.3.3 and §5.2.4.

    ``active_modes``/``passive_modes``: test mode numbers (1-based, file order) used in the
    fit / held out for prediction (default: all active). ``residual``: ``eigenvalue``,
    ``eigenvector`` or ``combined`` (§3.2.2). ``eigenvalue_weight``: ``"auto"`` (§5.2.4)
    or a number. ``regularisation``: μ of W_p = μ I (eq. 3.4) on θ. ``tolerance``:
    convergence when max |Δα| ≤ tolerance between iterations (§4.2.5.1, footnote 8).
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

    def __post_init__(self):
        if self.residual not in ("eigenvalue", "eigenvector", "combined"):
            raise ValueError(f"options.residual {self.residual!r}: eigenvalue | eigenvector | combined")
        if self.solver not in ("levenberg-marquardt", "gauss-newton"):
            raise ValueError(f"options.solver {self.solver!r}: levenberg-marquardt | gauss-newton")
        if self.eigenvalue_weight != "auto" and not float(self.eigenvalue_weight) > 0:
            raise ValueError("options.eigenvalue_weight must be 'auto' or a positive number")
        if self.regularisation < 0 or self.tolerance <= 0 or self.max_iterations < 1:
            raise ValueError("options: regularisation ≥ 0, tolerance > 0, max_iterations ≥ 1")


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
        """Read ``[[parameter]]`` entries and an optional ``[options]`` table."""
        path = Path(path)
        try:
            data = tomllib.loads(path.read_text())
        except tomllib.TOMLDecodeError as err:
            raise ValueError(f"{path}: {err}") from None
        unknown = set(data) - {"parameter", "options"}
        if unknown:
            raise ValueError(f"{path}: unknown top-level keys {sorted(unknown)}")
        return cls.from_dict(data, str(path))

    @classmethod
    def from_dict(cls, data: dict, where: str) -> ParameterSet:
        """From the ``parameter`` list and ``options`` table of parsed TOML; errors name ``where``."""
        params = []
        for i, entry in enumerate(data.get("parameter", []), 1):
            allowed = {"name", "kind", "pids", "eids", "nodes", "bounds"}
            extra = set(entry) - allowed
            if extra or "name" not in entry or "kind" not in entry:
                raise ValueError(
                    f"{where}: parameter #{i}: needs name and kind; allowed keys {sorted(allowed)}"
                    + (f", unknown {sorted(extra)}" if extra else "")
                )
            try:
                params.append(Parameter(
                    name=str(entry["name"]), kind=str(entry["kind"]),
                    pids=tuple(int(x) for x in entry.get("pids", ())),
                    eids=tuple(int(x) for x in entry.get("eids", ())),
                    nodes=tuple(int(x) for x in entry.get("nodes", ())),
                    bounds=tuple(float(x) for x in entry.get("bounds", (-0.5, 1.0))),
                ))
            except ValueError as err:
                raise ValueError(f"{where}: parameter #{i}: {err}") from None
        if not params:
            raise ValueError(f"{where}: no [[parameter]] declared")
        opts = dict(data.get("options", {}))
        known = set(Options.__dataclass_fields__)
        if set(opts) - known:
            raise ValueError(f"{where}: unknown options {sorted(set(opts) - known)}; allowed {sorted(known)}")
        for key in ("active_modes", "passive_modes"):
            if key in opts:
                opts[key] = tuple(int(x) for x in opts[key])
        try:
            return cls(tuple(params), Options(**opts))
        except (ValueError, TypeError) as err:
            raise ValueError(f"{where}: {err}") from None


class Parameterisation(eqx.Module):
    """A :class:`ParameterSet` resolved against one model: ``apply(model, θ)`` is pure JAX.

    Built by :func:`parameterise`, which may give target properties private material
    rows (so that ``E`` of some properties does not change others sharing the MAT1).
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
    if p.kind in _MATERIAL:
        mats = np.unique(np.concatenate([
            model.beam_sections.material[_rows(model.beam_sections.ids, p.pids)],
            model.rod_sections.material[_rows(model.rod_sections.ids, p.pids)],
        ]))
        field_name = _MATERIAL[p.kind]
        values = getattr(model.materials, field_name)
        return eqx.tree_at(lambda m: getattr(m.materials, field_name), model,
                           _scale_rows(values, mats, factor))
    if p.kind in _SECTION:
        rows = _rows(model.beam_sections.ids, p.pids)
        model = eqx.tree_at(lambda m: getattr(m.beam_sections, p.kind), model,
                            _scale_rows(getattr(model.beam_sections, p.kind), rows, factor))
        if p.kind in ("A", "J"):
            rows = _rows(model.rod_sections.ids, p.pids)
            model = eqx.tree_at(lambda m: getattr(m.rod_sections, p.kind), model,
                                _scale_rows(getattr(model.rod_sections, p.kind), rows, factor))
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


def _private_materials(model: Model, pids: Sequence[int]) -> Model:
    """Give the sections of ``pids`` their own material rows (copies) if they share one."""
    mats = model.materials
    changed = False
    sections = {}
    for name in ("beam_sections", "rod_sections"):
        sec = getattr(model, name)
        material = sec.material.copy()
        for row in _rows(sec.ids, pids):
            users = sum(int(np.sum(getattr(model, n).material == material[row]))
                        for n in ("beam_sections", "rod_sections"))
            targets = sum(int(np.sum(getattr(model, n).material[_rows(getattr(model, n).ids, pids)]
                                     == material[row])) for n in ("beam_sections", "rod_sections"))
            if users > targets:  # shared with a property outside the target: copy it
                material[row], mats = len(mats.ids), _copy_material(mats, material[row])
                changed = True
        sections[name] = material
    if not changed:
        return model
    model = eqx.tree_at(lambda m: m.materials, model, mats)
    for name, material in sections.items():
        model = eqx.tree_at(lambda m: getattr(m, name).material, model, material)
    return model


def parameterise(model: Model, parameters: ParameterSet | Sequence[Parameter]) -> tuple[Model, Parameterisation]:
    """Resolve parameters against a model; check every target exists.

    **Returns:** ``(model, parameterisation)``: the model possibly with private material
    rows for material parameters, and the pure ``apply(model, θ)`` map.
    """
    params = tuple(parameters.parameters if isinstance(parameters, ParameterSet) else parameters)
    all_pids = set(np.concatenate([model.beam_sections.ids, model.rod_sections.ids,
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
            model = _private_materials(model, p.pids)
    for i, p in enumerate(params):
        empty = (p.kind in ("stiffness", "mass") and not len(_element_group(model, p)))
        if p.kind == "k":
            empty = not (len(_target_rows(model, model.springs, p)) or len(_target_rows(model, model.bushes, p)))
        if empty:
            raise ValueError(f"parameter {p.name!r}: its target contains no element of kind {p.kind}")
    return model, Parameterisation(params, tuple(k_groups), tuple(m_groups), tuple(k_index), tuple(m_index))
