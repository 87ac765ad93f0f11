"""Rigid-body mass properties of a model: Nastran's grid-point weight generator (GRDPNT).

The rigid-body mass matrix about a reference point is ``M0 = Σ_e D_eᵀ M_e D_e`` over the
element mass matrices in grid DoFs (basic axes) *before* constraints, as Nastran forms
it from MGG: mass on constrained and on rigid-element- or MPC-dependent DoFs counts.
``D_e`` stacks, for each grid of the element, the rigid-body motion of its six
components under a unit motion of the reference point: ``u = u0 + θ × r``,
``θ_grid = θ``, ``r = x_grid − x_ref`` (MSC Nastran Reference Manual, "Grid Point Weight
Generator"). Mass, centre of gravity and inertia follow from ``M0`` as Nastran's GPWG
module derives them. Units are those of the model: mass, length and mass·length² (kg,
m and kg·m² for an SI deck).

Each kind of mass enters through one function of :data:`_MASS_SOURCES`,
``(model, d) -> {name: M0 contribution (6, 6)}`` (one entry per element block), where
``d`` (grids, 6, 6) holds each grid's rigid-body rows; :func:`_block_mass` projects
element-stacked blocks on whole grids, :func:`_component_mass` blocks on single grid
components (scalar masses, matrices on (grid, component) DoFs).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import jax.numpy as jnp
import numpy as np

from ._assembly import _element_blocks, _scalar_blocks
from ._eager import compiled_when_eager
from ._model import COMPONENTS, Model

_INCONSISTENT = 1e-3  # Nastran's GPWG: off-diagonal/diagonal translational mass above this → S axes


def _rigid_rows(xyz, reference):
    """``d`` (grids, 6, 6): each grid's six components under a unit rigid motion
    ``[u0; θ]`` of the reference point, ``u = u0 − r × θ`` written ``[I, −skew(r)]``."""
    r = jnp.asarray(xyz) - reference
    zero = jnp.zeros(r.shape[0])
    minus_skew = jnp.stack([jnp.stack([zero, r[:, 2], -r[:, 1]], -1),
                            jnp.stack([-r[:, 2], zero, r[:, 0]], -1),
                            jnp.stack([r[:, 1], -r[:, 0], zero], -1)], 1)
    eye = jnp.broadcast_to(jnp.eye(3), minus_skew.shape)
    top = jnp.concatenate([eye, minus_skew], axis=2)
    bottom = jnp.concatenate([jnp.zeros_like(eye), eye], axis=2)
    return jnp.concatenate([top, bottom], axis=1)


def _block_mass(d, nodes: np.ndarray, blocks):
    """``Σ_e D_eᵀ M_e D_e`` of blocks (elements, 6·nn, 6·nn) on grid rows ``nodes`` (elements, nn)."""
    de = d[nodes].reshape(nodes.shape[0], nodes.shape[1] * COMPONENTS, COMPONENTS)
    return jnp.einsum("eia,eij,ejb->ab", de, blocks, de)


def _component_mass(d, rows: np.ndarray, components: np.ndarray, blocks, cd: np.ndarray | None = None):
    """``Σ_e D_eᵀ M_e D_e`` of blocks (elements, k, k) on single grid components: grid
    rows (elements, k), −1 for ground (no motion), global components 1..6 (elements, k),
    those of each grid's CD axes ``cd`` (grids, 3, 3; columns in basic; None: basic)."""
    safe, c = np.maximum(rows, 0), np.maximum(components, 1) - 1
    if cd is None:
        de = d[safe, c]
    else:
        axis = np.take_along_axis(np.asarray(cd)[safe], (c % 3)[..., None, None], axis=-1)[..., 0]
        half = jnp.where((c < 3)[..., None, None], d[safe][..., :3, :], d[safe][..., 3:, :])
        de = jnp.einsum("eki,ekib->ekb", axis, half)
    de = jnp.where((rows >= 0)[..., None], de, 0.0)
    return jnp.einsum("eia,eij,ejb->ab", de, blocks, de)


def _element_mass(model: Model, d) -> dict:
    """Beams, rods, shells and CONM2 (``masses``): the mass blocks of
    :func:`jaxfem._assembly._element_blocks`, one entry per block."""
    return {name: _block_mass(d, np.asarray(nodes), me)
            for name, (nodes, _, me) in _element_blocks(model).items() if me is not None}


def _scalar_mass(model: Model, d) -> dict:
    """Scalar masses (CMASS) and direct mass matrices on single global components: the mass
    blocks of :func:`jaxfem._assembly._scalar_blocks`; scalar points do not move with the
    rigid body (Nastran's GPWG leaves them out)."""
    still = np.zeros(len(model.node_ids), bool)
    if model.scalar_rows is not None:
        still[model.scalar_rows] = True
    out = {}
    for name, (nodes, components, _, me) in _scalar_blocks(model).items():
        if me is not None:
            nodes = np.asarray(nodes)
            rows = np.where(still[np.maximum(nodes, 0)], -1, nodes)
            out[name] = _component_mass(d, rows, np.asarray(components), me, model.dofs.cd)
    return out


# Every mass source, (model, d) -> {block name: its (6, 6) share of M0}; a new kind of mass adds its function here.
_MASS_SOURCES = (_element_mass, _scalar_mass)


@compiled_when_eager
def _rigid_body_mass(model: Model, reference) -> dict:
    """M0 (6, 6) of each mass block about ``reference`` (3,), basic axes; differentiable in the model's values."""
    d = _rigid_rows(model.xyz, reference)
    out: dict = {}
    for source in _MASS_SOURCES:
        for name, m0 in source(model, d).items():
            out[name] = out[name] + m0 if name in out else m0
    return out


@dataclass(frozen=True)
class MassProperties:
    """Rigid-body mass properties, as Nastran's grid-point weight generator prints them.

    Model units throughout (mass; length; mass·length²). ``reference_grid``: the
    reference point's grid (0: the basic origin) at ``reference`` (basic). ``m0``: the
    6 × 6 rigid-body mass matrix about it, basic axes. ``s``: mass axes (columns in
    basic; the identity unless the direction masses differ, Nastran's S).
    ``direction_mass``: mass in each S direction; ``direction_cg``: row i the centre of
    gravity of the direction-i mass relative to the reference point, S axes, 0 on the
    diagonal (Nastran's X-C.G., Y-C.G., Z-C.G. table). ``mass``: total mass (mean of
    the direction masses); ``cg``: centre of gravity, basic coordinates. ``inertia``:
    inertia tensor about the CG, basic axes, off-diagonal terms −∫xy dm (CONM2's
    convention); ``i_s``: Nastran's I(S), S axes, off-diagonal terms +∫xy dm.
    ``principal_inertia``: I(Q), descending; ``principal_axes``: their directions,
    columns in basic axes (Nastran's Q is ``sᵀ @ principal_axes``). ``by_block``: mass
    of each mass block of the model (``beams``, ``rods``, ``quads``, ``trias``, ``masses``:
    CONM2, and so on).
    """

    reference_grid: int
    reference: np.ndarray
    m0: np.ndarray
    s: np.ndarray
    direction_mass: np.ndarray
    direction_cg: np.ndarray
    mass: float
    cg: np.ndarray
    inertia: np.ndarray
    i_s: np.ndarray
    principal_inertia: np.ndarray
    principal_axes: np.ndarray
    by_block: dict[str, float] = field(default_factory=dict)

    @property
    def q(self) -> np.ndarray:
        """Nastran's Q: principal axes (columns) in the S axes."""
        return self.s.T @ self.principal_axes

    def table(self) -> str:
        """The GRDPNT printout in brief: M0, S, direction masses and CGs, I(S), I(Q), Q."""
        def rows(a) -> list[str]:
            return ["  * " + " ".join(f"{v:13.6E}" for v in np.atleast_1d(row)) + " *" for row in a]

        where = ("basic origin" if self.reference_grid == 0 else f"grid {self.reference_grid}"
                 ) + " (" + ", ".join(f"{v:.6g}" for v in self.reference) + ")"
        out = [f"grid-point weight generator (as Nastran GRDPNT), reference point {where}; model units",
               "M0, rigid-body mass matrix about the reference point (basic axes)", *rows(self.m0),
               "S, mass axes (identity unless the direction masses differ)", *rows(self.s),
               f"  direction {'mass':>13} {'X-C.G.':>13} {'Y-C.G.':>13} {'Z-C.G.':>13}  (CG from the reference point)"]
        out += [f"  {axis:>9} {m:13.6E} " + " ".join(f"{v:13.6E}" for v in c)
                for axis, m, c in zip("XYZ", self.direction_mass, self.direction_cg)]
        out += ["I(S), inertia about the CG (S axes; off-diagonal +∫xy dm, as Nastran prints it)", *rows(self.i_s),
                "I(Q), principal inertias", *rows(self.principal_inertia[:, None]),
                "Q, principal axes (columns, S axes)", *rows(self.q),
                f"total mass {self.mass:.6E}; CG (basic) x {self.cg[0]:.6E}, y {self.cg[1]:.6E}, z {self.cg[2]:.6E}"]
        return "\n".join(out)

    def to_json(self) -> dict:
        """Plain JSON types: every field, arrays as nested lists."""
        return {"reference_grid": int(self.reference_grid), "reference": self.reference.tolist(),
                "mass": float(self.mass), "cg": self.cg.tolist(), "inertia": self.inertia.tolist(),
                "principal_inertia": self.principal_inertia.tolist(),
                "principal_axes": self.principal_axes.tolist(), "m0": self.m0.tolist(), "s": self.s.tolist(),
                "direction_mass": self.direction_mass.tolist(), "direction_cg": self.direction_cg.tolist(),
                "i_s": self.i_s.tolist(), "q": self.q.tolist(), "by_block": dict(self.by_block)}


def mass_properties(model: Model, reference: int | None = None) -> MassProperties:
    """Mass, centre of gravity and inertia of ``model`` (Nastran PARAM GRDPNT output).

    **Arguments:** a :class:`jaxfem.Model`; ``reference``: the grid id whose position is
    the reference point of ``m0`` (None or 0: the basic origin, as GRDPNT = 0).
    **Returns:** :class:`MassProperties` (NumPy, model units), from the element mass
    before constraints (mass on SPC'd and dependent DoFs counts), with the current
    mass scale factors. ValueError for a reference that is not a grid.
    """
    if reference in (None, 0):
        grid, point = 0, np.zeros(3)
    else:
        grid = int(reference)
        point = np.asarray(model.xyz, dtype=np.float64)[model.node_index([grid])[0]]
    blocks = {name: np.asarray(m, dtype=np.float64)
              for name, m in _rigid_body_mass(model, jnp.asarray(point, dtype=jnp.float64)).items()}
    m0 = sum(blocks.values(), np.zeros((COMPONENTS, COMPONENTS)))
    by_block = {name: float(np.trace(m[:3, :3]) / 3.0) for name, m in blocks.items()}
    return replace(_gpwg(0.5 * (m0 + m0.T), grid, point), by_block=by_block)


def _gpwg(m0: np.ndarray, grid: int, point: np.ndarray) -> MassProperties:
    """Nastran's GPWG steps from M0: S axes, direction masses and CGs, I(S), I(Q) and Q."""
    mtt = m0[:3, :3]
    delta = np.linalg.norm(np.diag(mtt))
    epsilon = np.linalg.norm(mtt[np.triu_indices(3, 1)])
    s = np.linalg.eigh(mtt)[1] if delta > 0 and epsilon / delta > _INCONSISTENT else np.eye(3)
    mtt, mtr, mrr = s.T @ mtt @ s, s.T @ m0[:3, 3:] @ s, s.T @ m0[3:, 3:] @ s
    masses = np.diag(mtt).copy()
    moments = np.array([[mtr[0, 0], -mtr[0, 2], mtr[0, 1]],
                        [mtr[1, 2], mtr[1, 1], -mtr[1, 0]],
                        [-mtr[2, 1], mtr[2, 0], mtr[2, 2]]])
    cg_dir = np.divide(moments, masses[:, None], out=np.zeros((3, 3)), where=masses[:, None] != 0.0)
    (_, yx, zx), (xy, _, zy), (xz, yz, _) = cg_dir
    mx, my, mz = masses
    i_s = np.array([
        [mrr[0, 0] - my * zy**2 - mz * yz**2, -mrr[0, 1] - mz * xz * yz, -mrr[0, 2] - my * xy * zy],
        [-mrr[0, 1] - mz * xz * yz, mrr[1, 1] - mz * xz**2 - mx * zx**2, -mrr[1, 2] - mx * yx * zx],
        [-mrr[0, 2] - my * xy * zy, -mrr[1, 2] - mx * yx * zx, mrr[2, 2] - mx * yx**2 - my * xy**2]])
    tensor_s = 2.0 * np.diag(np.diag(i_s)) - i_s
    cg_s = np.array([_weighted(cg_dir[[1, 2], 0], masses[[1, 2]]), _weighted(cg_dir[[0, 2], 1], masses[[0, 2]]),
                     _weighted(cg_dir[[0, 1], 2], masses[[0, 1]])])
    values, vectors = np.linalg.eigh(tensor_s)
    order = np.argsort(values)[::-1]
    return MassProperties(
        reference_grid=grid, reference=np.asarray(point, dtype=np.float64), m0=m0, s=s, direction_mass=masses,
        direction_cg=cg_dir, mass=float(masses.mean()), cg=point + s @ cg_s, inertia=s @ tensor_s @ s.T,
        i_s=i_s, principal_inertia=values[order], principal_axes=s @ _oriented(vectors[:, order]))


def _weighted(values: np.ndarray, weights: np.ndarray) -> float:
    """Mass-weighted mean of a CG coordinate over the two directions that give it (0 without mass)."""
    total = weights.sum()
    return float(values @ weights / total) if total != 0.0 else 0.0


def _oriented(q: np.ndarray) -> np.ndarray:
    """Columns with their largest component positive, then right-handed (det +1)."""
    q = q * np.where(q[np.argmax(np.abs(q), axis=0), np.arange(3)] < 0.0, -1.0, 1.0)
    if np.linalg.det(q) < 0.0:
        q[:, 2] = -q[:, 2]
    return q
