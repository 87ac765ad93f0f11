"""Candidate physical effects: small parameterised extensions of a model.

An :class:`Effect` names a kind, where it sits (property ids, element ids, grids, in
the bulk data's own ids) and its physical values; ``effect.apply(model)`` (also
``model.with_effect(effect)``) returns the extended model. Kinds:

- ``stiffness`` / ``mass``: factor α on a property group or part of one (eq. 3.1);
- ``joint``: a rigid connection (RBE2, or a grid shared by two property groups) made
  flexible: a 6-DoF spring, translations ``k_trans`` (N/m), rotations ``k_rot`` (N·m/rad);
- ``added_mass``: a point mass ``m`` (kg) at a grid;
- ``boundary_spring``: springs to ground at a grid, ``k`` (N/m) on translations of an
  unconstrained grid, or ``k_trans``/``k_rot`` on the released components of an SPC;
- ``frequency_dependent_stiffness``: ``E(f) = E0 (1 + a ln(f/f_ref))`` on a group with the
  factor ``alpha`` on E0 (:class:`jaxfem.Viscoelastic`).

For fitting, :class:`Extension` expresses an effect's free parameters as traced masks on
a model, so that many candidates of the same model structure share one compiled solver
and are batched with ``vmap``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

import jaxfem
from jaxfem import Model
from jaxfem import _edit as edit

from ._parameters import Parameter

KINDS = ("stiffness", "mass", "joint", "added_mass", "boundary_spring", "frequency_dependent_stiffness")
_K_BLOCKS = ("beams", "rods", "springs", "bushes")
_THETA_MAX = 25.0  # |log-factor| beyond which a trial step is clipped (e^25 ≈ 7e10)
_M_BLOCKS = ("beams", "rods", "masses")


@dataclass(frozen=True)
class Effect:
    """A physical effect at a place in the model, with its values (SI units).

    ``values``: ``alpha``/``beta`` (relative factors), ``k_trans`` N/m, ``k_rot``
    N·m/rad, ``k`` N/m, ``m`` kg, ``a`` (1), ``f_ref_hz`` Hz.
    """

    kind: str
    pids: tuple[int, ...] = ()
    eids: tuple[int, ...] = ()
    nodes: tuple[int, ...] = ()
    values: dict = field(default_factory=dict, hash=False, compare=False)
    label: str = ""

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"effect kind {self.kind!r} is not one of {KINDS}")

    def where(self) -> str:
        if self.label:
            return self.label
        parts = [f"{name} {', '.join(map(str, ids))}" for name, ids in
                 (("pid", self.pids), ("eid", self.eids), ("node", self.nodes)) if ids]
        return "; ".join(parts)

    def elements(self, model: Model) -> np.ndarray:
        """Element ids of the effect's group (``eids`` if given, else the ``pids``)."""
        return np.asarray(self.eids, np.int64) if self.eids else model.element_ids(pids=self.pids)

    def apply(self, model: Model) -> Model:
        """The model with this effect at its ``values``."""
        v = self.values
        if self.kind in ("stiffness", "mass", "frequency_dependent_stiffness"):
            group = [self.elements(model).tolist()]
            if self.kind == "stiffness" or self.kind == "frequency_dependent_stiffness":
                model = jaxfem.correct(model, group, jnp.array([v.get("alpha", 0.0)]))
            elif self.kind == "mass":
                model = jaxfem.correct(model, (), None, group, jnp.array([v.get("beta", 0.0)]))
            if self.kind == "frequency_dependent_stiffness":
                masks = [jnp.asarray(np.isin(getattr(model, b).ids, group[0]), dtype=jnp.float64) for b in _K_BLOCKS]
                model = eqx.tree_at(lambda m: m.viscoelastic, model,
                                    jaxfem.Viscoelastic(*masks, jnp.asarray(float(v.get("a", 0.0))),
                                                        jnp.asarray(float(v["f_ref_hz"]))),
                                    is_leaf=lambda x: x is None)
            return model
        if self.kind == "added_mass":
            for node in self.nodes:
                model = edit.add_mass(model, node, float(v["m"]))[0]
            return edit.refresh(model)
        if self.kind == "boundary_spring":
            for node in self.nodes:
                fixed = constrained_components(model, node)
                if fixed:
                    model = edit.release(model, node)
                    model = edit.add_ground_springs(model, node, [
                        v["k_trans"] if c <= 3 else v["k_rot"] for c in fixed], fixed)[0]
                else:
                    model = edit.add_ground_springs(model, node, v["k"], (1, 2, 3))[0]
            return edit.refresh(model)
        # joint
        k6 = [v["k_trans"]] * 3 + [v["k_rot"]] * 3
        for node, master in joint_pairs(model, self):
            if master is None:  # a grid shared by two groups: the second group gets its own grid
                model, new = edit.add_grid(model, model.xyz[model.node_index([node])[0]])
                side = model.element_ids(pids=self.pids[1:])
                model = edit.reconnect(model, side.tolist(), node, new)
                model = edit.add_bush(model, node, new, k6)[0]
            else:  # an RBE2-dependent grid becomes independent, held by a spring
                model = edit.release(model, node)
                model = edit.add_bush(model, master, node, k6)[0]
        return edit.refresh(model)


# ---------------------------------------------------------------------------------------
# Model topology


def _own(model: Model, row: int) -> set[int]:
    node = model.node_ids[row]
    return {int(c) for n, c in model.dofs.labels if n == node}


def masters(model: Model) -> dict[int, int]:
    """RBE2-dependent grid → the grid whose DoFs carry it (from the DoF map)."""
    owner = np.asarray(model.dofs.labels[:, 0])
    out = {}
    for row, node in enumerate(model.node_ids):
        idx = model.dofs.index[row]
        idx = idx[idx < model.n_dof]
        owners = set(owner[idx].tolist())
        if idx.size and int(node) not in owners and len(owners) == 1:
            out[int(node)] = owners.pop()
    return out


def constrained_components(model: Model, node: int) -> list[int]:
    """Components of a grid removed by SPC (not by RBE2 nor auto-SPC)."""
    row = int(model.node_index([node])[0])
    if int(node) in masters(model):
        return []
    auto = {int(c) for n, c in model.dofs.auto_spc if n == node}
    idx = model.dofs.index[row]
    if np.any((idx < model.n_dof) & ~np.isin(model.dofs.labels[np.minimum(idx, model.n_dof - 1), 0], [node])):
        return []
    return [c for c in range(1, 7) if c not in _own(model, row) and c not in auto]


def joint_pairs(model: Model, effect: Effect) -> list[tuple[int, int | None]]:
    """(grid, master or None) for each grid of a joint effect."""
    dep = masters(model)
    return [(n, dep.get(n)) for n in effect.nodes]


def _structural(model: Model):
    """(block name, element ids, pids, node rows) of beams, rods and bushes."""
    for name in ("beams", "rods", "bushes"):
        b = getattr(model, name)
        if len(b.ids):
            yield name, b.ids, b.pids, b.nodes


def elements_at(model: Model, node: int) -> dict[int, int]:
    """Structural element id → pid of the elements attached to a grid."""
    row = int(model.node_index([node])[0])
    out = {}
    for _, ids, pids, nodes in _structural(model):
        hit = np.any(nodes == row, axis=1)
        out.update({int(e): int(p) for e, p in zip(ids[hit], pids[hit])})
    return out


def total_mass(model: Model) -> float:
    """Structural plus lumped mass (kg), with the current mass factors."""
    b, sec, mat = model.beams, model.beam_sections, model.materials
    xyz = model.xyz
    total = 0.0
    if len(b.ids):
        length = np.linalg.norm(xyz[b.nodes[:, 1]] - xyz[b.nodes[:, 0]], axis=1)
        s = b.section
        total += float(jnp.sum((mat.rho[sec.material[s]] * sec.A[s] + sec.nsm[s]) * length * b.m_scale))
    r, rs = model.rods, model.rod_sections
    if len(r.ids):
        length = np.linalg.norm(xyz[r.nodes[:, 1]] - xyz[r.nodes[:, 0]], axis=1)
        s = r.section
        total += float(jnp.sum((mat.rho[rs.material[s]] * rs.A[s] + rs.nsm[s]) * length * r.m_scale))
    return total + float(jnp.sum(model.masses.m * model.masses.m_scale))


def _beam_stiffness_scale(model: Model, eids) -> tuple[float, float]:
    """(max E·A/L, max E·I/L) of beams and rods among ``eids`` (N/m, N·m/rad)."""
    ea, ei = [0.0], [0.0]
    for name, sec_name in (("beams", "beam_sections"), ("rods", "rod_sections")):
        b, sec = getattr(model, name), getattr(model, sec_name)
        hit = np.isin(b.ids, np.asarray(list(eids), np.int64))
        if not hit.any():
            continue
        s = b.section[hit]
        length = np.linalg.norm(model.xyz[b.nodes[hit, 1]] - model.xyz[b.nodes[hit, 0]], axis=1)
        e = np.asarray(model.materials.E)[sec.material[s]]
        ea.extend((e * np.asarray(sec.A)[s] / length).tolist())
        inertia = np.maximum(np.asarray(sec.I1)[s], np.asarray(sec.I2)[s]) if name == "beams" else np.asarray(sec.J)[s]
        ei.extend((e * inertia / length).tolist())
    return max(ea), max(ei)


def joint_reference(model: Model, nodes, side_eids) -> dict:
    """Starting values of a joint: rotations 10·E·I/L and translations 100·E·A/L of the
    stiffest element of the released side (a joint slightly softer than rigid)."""
    ea, ei = _beam_stiffness_scale(model, side_eids)
    if ei <= 0:
        raise ValueError(f"joint at grid(s) {list(nodes)}: no beam or rod on the released side")
    return {"k_trans": 100.0 * ea, "k_rot": 10.0 * ei}


# ---------------------------------------------------------------------------------------
# Traced parameterisation for batched fits


class Extension(eqx.Module):
    """An effect's free parameters θ as masks on the model's element scales.

    ``k_scale ← k_scale·exp(θ₀·k_log) + k_add·exp(θ₀)`` per stiffness block (likewise
    for mass), so θ₀ is a log-factor on a group (``k_log``) or wakes dormant elements
    (``k_add``: added springs or masses present with scale 0). With ``visco`` set, θ₁
    gives the law's ``a = exp(θ₁) − 1`` on the ``k_log`` group (reference ``f_ref``).
    """

    k_log: tuple[Float[Array, " n"], ...]
    k_add: tuple[Float[Array, " n"], ...]
    m_log: tuple[Float[Array, " n"], ...]
    m_add: tuple[Float[Array, " n"], ...]
    f_ref: Float[Array, ""]
    visco: bool = eqx.field(static=True)

    @property
    def n_params(self) -> int:
        return 2 if self.visco else 1

    def __call__(self, model: Model, theta: Float[Array, " e"]) -> Model:
        theta = jnp.clip(theta, -_THETA_MAX, _THETA_MAX)  # a wild trial step stays finite
        s = jnp.exp(theta[0])
        for name, log, add in zip(_K_BLOCKS, self.k_log, self.k_add):
            blk = getattr(model, name)
            model = eqx.tree_at(lambda m, name=name: getattr(m, name).k_scale, model,
                                blk.k_scale * jnp.exp(theta[0] * log) + add * s)
        for name, log, add in zip(_M_BLOCKS, self.m_log, self.m_add):
            blk = getattr(model, name)
            model = eqx.tree_at(lambda m, name=name: getattr(m, name).m_scale, model,
                                blk.m_scale * jnp.exp(theta[0] * log) + add * s)
        if self.visco:
            law = jaxfem.Viscoelastic(*self.k_log, jnp.expm1(jnp.minimum(theta[1], 1.0)), self.f_ref)  # a ≤ e − 1
            model = eqx.tree_at(lambda m: m.viscoelastic, model, law, is_leaf=lambda x: x is None)
        return model


def extension(model: Model, *, k_log=(), k_add=(), m_log=(), m_add=(), f_ref: float | None = None) -> Extension:
    """Masks from element ids: ``k_log`` etc. list the element ids of each role."""

    def masks(blocks, ids):
        ids = np.asarray(list(ids), np.int64)
        return tuple(jnp.asarray(np.isin(getattr(model, b).ids, ids), dtype=jnp.float64) for b in blocks)

    return Extension(masks(_K_BLOCKS, k_log), masks(_K_BLOCKS, k_add), masks(_M_BLOCKS, m_log),
                     masks(_M_BLOCKS, m_add), jnp.asarray(f_ref or 1.0), f_ref is not None)


# ---------------------------------------------------------------------------------------
# from the command line to an update


def parse_effect(spec: str) -> Effect:
    """``KIND:TARGET`` as on the command line, e.g. ``joint:node=6001``,
    ``joint:node=3007;pids=21,22``, ``stiffness:pid=41``, ``mass:eids=201-205``,
    ``added_mass:node=2015``, ``boundary_spring:node=1``,
    ``frequency_dependent_stiffness:pid=41``."""
    kind, _, target = spec.partition(":")
    if kind not in KINDS or not target:
        raise ValueError(f"effect {spec!r}: write KIND:TARGET with KIND one of {KINDS}, "
                         "TARGET like pid=41, node=1029, eids=201-205 (';' between several)")
    where: dict[str, tuple[int, ...]] = {"pids": (), "eids": (), "nodes": ()}
    for part in target.split(";"):
        key, _, value = part.partition("=")
        key = {"pid": "pids", "eid": "eids", "node": "nodes"}.get(key.strip(), key.strip())
        if key not in where or not value:
            raise ValueError(f"effect {spec!r}: unknown target {part!r} (pid(s)=, eid(s)=, node(s)=)")
        ids: list[int] = []
        try:
            for item in value.split(","):
                lo, _, hi = item.partition("-")
                ids += list(range(int(lo), int(hi or lo) + 1))
        except ValueError:
            raise ValueError(f"effect {spec!r}: {part!r} is not a list of integers") from None
        where[key] = tuple(ids)
    return Effect(kind, **where)


def at_reference(model: Model, effect: Effect, f_test_hz) -> Effect:
    """The effect with starting values for a fit: no change for group factors, a
    slightly flexible joint or support (:func:`joint_reference`), 1 % of the total mass,
    a support spring that alone would carry the structure at f₁/10, a = 0 at the
    geometric mean of the test frequencies."""
    kind = effect.kind
    f = np.asarray(f_test_hz, float)
    if kind in ("stiffness", "mass"):
        values = {}
    elif kind == "frequency_dependent_stiffness":
        values = {"a": 0.0, "f_ref_hz": float(np.exp(np.mean(np.log(f))))}
    elif kind == "added_mass":
        values = {"m": 0.01 * total_mass(model)}
    elif kind == "boundary_spring" and not any(constrained_components(model, n) for n in effect.nodes):
        values = {"k": total_mass(model) * (2 * np.pi * float(np.min(f)) / 10) ** 2}
    else:
        dep = masters(model)
        side = []
        for n in effect.nodes:
            at = elements_at(model, n)
            side += [e for e, p in at.items() if n in dep or kind == "boundary_spring" or p in effect.pids[1:]]
        if kind == "joint" and not all(n in dep for n in effect.nodes) and len(effect.pids) < 2:
            raise ValueError(f"joint at grid(s) {list(effect.nodes)}: not RBE2-dependent; name the two "
                             "groups, e.g. joint:node=3007;pids=21,22 (the second group is released)")
        values = joint_reference(model, effect.nodes, side)
    return Effect(kind, effect.pids, effect.eids, effect.nodes, values, effect.label)


def effect_parameters(effect: Effect, before: Model, after: Model) -> tuple:
    """Updating parameters of an effect added to ``before`` (giving ``after``)."""
    name = f"{effect.kind}"
    new = sorted(set(after.element_ids().tolist()) - set(before.element_ids().tolist()))
    target = {"eids": tuple(effect.eids)} if effect.eids else {"pids": tuple(effect.pids)}
    if effect.kind in ("stiffness", "mass"):
        return (Parameter(name, effect.kind, **target),)
    if effect.kind == "frequency_dependent_stiffness":
        return (Parameter(name + "_E0", "stiffness", **target),
                Parameter(name + "_a", "a", pids=tuple(effect.pids), bounds=(-0.5, 0.5)))
    if effect.kind == "added_mass":
        return (Parameter(name, "m", eids=tuple(new), bounds=(-1.0, 10.0)),)
    return (Parameter(name, "k", eids=tuple(new), bounds=(-0.999, 1e3)),)
