"""The residual's derivative w.r.t. every element's stiffness, mass and shell parts, at once.

Screening a diagnosis' candidates needs ∂ε/∂u_e for every element e and every kind of
change u (its stiffness or mass scale, a shell's membrane, bending or transverse-shear
factor, a shell's non-structural mass): 10⁴ columns on a shell model. Forward mode would
carry one tangent per column through the eigensolver; here the columns come from element
blocks and the computed modes alone:

- eigenvalues, eq. 3.18: ``∂λ_j = φ_jᵀ (∂K − λ_j ∂M) φ_j``;
- eigenvectors, eq. 3.23, eq. 3.28, eq. 3.29: ``∂φ_j = Σ_{k≠j} φ_k φ_kᵀ v / (λ_j − λ_k)
  − ½ φ_j φ_jᵀ ∂M φ_j`` with ``v = (∂K − λ_j ∂M) φ_j``, summed over the computed modes
  (all of them on the dense path); the modes not computed enter by their static
  correction ``−[(K − σM)⁻¹ − Σ_k φ_k φ_kᵀ / (λ_k − σ)] v`` (exact for λ_j ≪ λ of the
  first mode left out; on the dense path it is the massless DoFs' flexibility only);
- the residual rows' own dependence on the paired (λ_j, Cφ_j) by forward mode through
  :func:`updating._residuals.rows` (a small Jacobian, block-diagonal by mode).

Each ∂K of one element is its block; φ_k enters at that element's DoFs only, so the cost
is one pass over the elements per paired mode, and the derivative of the modes at the
sensors needs one factorisation and n_s solves ``(K − σM)⁻¹ Cᵀ``.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg
import scipy.sparse

import jaxfem
from jaxfem import FAST_COMPILE, Model, compiled_when_eager

from .. import Problem, evaluate, paired_subspace, rows

CLUSTER_RTOL = 1e-6  # modes closer than this (relative) count as one cluster: no coefficient between them

# The element scales a column is taken w.r.t. (relative: u ↦ s·(1 + u), a dormant element woken at its
# reference), the shell parts (relative) and the shells' non-structural mass (absolute, kg/m²).
KINDS = ("k", "m", "membrane", "bending", "shear", "nsm")
_PART = {"membrane": 0, "bending": 1, "shear": 2}
_K_ORDER = ("beams", "rods", "bushes", "quads", "trias", "springs")  # assemble()'s block order
_M_ORDER = ("beams", "rods", "quads", "trias", "masses")


@dataclasses.dataclass
class ElementJacobian:
    """Weighted residual ``r`` (rows) and ``columns[kind]`` (rows × elements) with element ids
    ``ids[kind]``, for each of :data:`KINDS` the model has; ``mac`` of each test mode with
    its paired model mode (0: unpaired)."""

    r: np.ndarray
    columns: dict[str, np.ndarray]
    ids: dict[str, np.ndarray]
    mac: np.ndarray


def _tangent(model: Model, kind: str) -> Model:
    """The model-shaped tangent of one kind: every element moved at once (each element's
    block depends on its own entry only, so one JVP gives all element blocks)."""
    # built in NumPy and put on the device whole: eager jnp operations compile one small
    # program per operation and shape (some 20 of a GARTEUR screen's cold 7 s)
    zero = jax.tree.map(lambda x: np.zeros(x.shape, x.dtype), jaxfem.partition(model)[0])
    for name in _K_ORDER + ("masses",):
        block = getattr(model, name)
        if kind in ("k", "m") and hasattr(block, f"{kind}_scale"):
            s = np.asarray(getattr(block, f"{kind}_scale"))
            zero = eqx.tree_at(lambda t, name=name: getattr(getattr(t, name), f"{kind}_scale"), zero,
                               np.where(s == 0, 1.0, s))
        elif name in ("quads", "trias") and kind in _PART:
            p, part = np.asarray(block.parts), np.zeros(block.parts.shape)
            part[:, _PART[kind]] = p[:, _PART[kind]]
            zero = eqx.tree_at(lambda t, name=name: getattr(t, name).parts, zero, part)
        elif name in ("quads", "trias") and kind == "nsm":
            zero = eqx.tree_at(lambda t, name=name: getattr(t, name).nsm, zero, np.ones(block.nsm.shape))
    return jax.tree.map(jnp.asarray, zero)


@compiled_when_eager(compiler_options=FAST_COMPILE)
def _assembly_jvp(model: Model, tangent):
    """K, M and their derivatives along ``tangent`` (values-shaped), compiled whole (one
    program for every kind; run eagerly, the JVP compiled hundreds of small ones: 52 s of
    a 111 s screen at 33,000 DoFs)."""
    values, static = jaxfem.partition(model)
    return jax.jvp(lambda v: jaxfem.assemble(eqx.combine(v, static)), (values,), (tangent,))


def _blocks(model: Model, kind: str):
    """(dK blocks, dM blocks) of ``kind``, each a list of (names, blocks (n_el, w, w), indices)."""
    (K, M), (dK, dM) = _assembly_jvp(model, _tangent(model, kind))
    k_names = [n for n in _K_ORDER if len(getattr(model, n).ids)]
    m_names = [n for n in _M_ORDER if len(getattr(model, n).ids)]
    return (list(zip(k_names, map(np.asarray, dK.blocks), map(np.asarray, K.indices))),
            list(zip(m_names, map(np.asarray, dM.blocks), map(np.asarray, M.indices))))


def _modes(problem: Problem, theta, model: Model):
    """The paired evaluation at θ and all computed modes (λ, Φ: n × q), a solver of
    (K − σM) and σ (on the sparse path from one solve)."""
    if problem.sparse:
        K, M = jaxfem.assemble(model)
        sol = jaxfem.sparse_modes(K, M, problem.n_model)
        inverse = sol.solver
        return (paired_subspace(K, M, sol, problem), np.asarray(sol.lam), np.asarray(sol.basis),
                lambda b: np.asarray(inverse.solve(jnp.asarray(b))), float(inverse.sigma))
    ev, lam, phi, kd, md = jax.tree.map(np.asarray, _dense_modes(jnp.asarray(theta), problem))
    d = np.diag(md)
    sigma = -1e-3 * float(np.min(np.diag(kd)[d > 0] / d[d > 0]))
    factor = scipy.linalg.cho_factor(kd - sigma * md)
    return ev, lam, phi, lambda b: scipy.linalg.cho_solve(factor, b), sigma


@compiled_when_eager(compiler_options=FAST_COMPILE)
def _dense_modes(theta, problem: Problem):
    """The paired evaluation at θ, all modes, dense K and M: one compiled program (run
    eagerly, the pairing and densifying compiled some 60 small ones, 3.5 s of 7.5 cold)."""
    K, M = jaxfem.assemble(problem.model(theta))
    lam, phi = jaxfem.eigh(K, M)
    return evaluate(theta, problem), lam, phi, K.todense(), M.todense()


@compiled_when_eager(compiler_options=FAST_COMPILE)
def _row_derivatives(theta, problem: Problem, ev):
    """The weighted residual rows at ``ev`` and their forward derivatives in the paired
    (λ_j, Cφ_j), compiled whole."""

    def flat(lam_a, phi_a):
        eps = rows(theta, problem, dataclasses.replace(ev, lam_a=lam_a, phi_a=phi_a))
        return jnp.concatenate([jnp.ravel(eps[k]) for k in ("eigenvalue", "eigenvector")])

    return flat(ev.lam_a, ev.phi_a), *jax.jacfwd(flat, argnums=(0, 1))(ev.lam_a, ev.phi_a)


class _RowChain:
    """The residual rows' derivative in the paired (λ_j, Cφ_j), rows and columns ordered
    [λ (ne), Cφ sensor-major (ns × ne)]: block-diagonal by test mode when each row depends
    on its own mode only, then applied one dense (1 + ns)² block per mode (a sparse product
    with 10⁴ element columns took 17 s at 33,000 DoFs); else as a sparse matrix."""

    def __init__(self, G: np.ndarray, ne: int):
        self.modes = np.arange(len(G)) % max(ne, 1)  # row ne + s·ne + j belongs to mode j
        own = self.modes[:, None] == self.modes[None, :]
        self.blocks = None if np.any(G[~own]) else [G[np.ix_(self.modes == j, self.modes == j)] for j in range(ne)]
        self.sparse = scipy.sparse.csr_matrix(G) if self.blocks is None else None

    def __matmul__(self, X: np.ndarray) -> np.ndarray:
        if self.sparse is not None:
            return np.asarray(self.sparse @ X)
        out = np.empty((len(self.modes), X.shape[1]))
        for j, B in enumerate(self.blocks):
            out[self.modes == j] = B @ X[self.modes == j]
        return out


def element_jacobian(problem: Problem, theta, kinds=KINDS, modes=None) -> ElementJacobian:
    """The weighted residual ``_flat`` rows (eigenvalue rows, then eigenvector rows
    sensor-major) at θ and their derivatives w.r.t. each element of each of ``kinds``
    (module docstring). A kind the model has no element of is left out. ``modes``: those
    of :func:`_modes` at this θ if already solved."""
    theta = jnp.asarray(theta)
    model = problem.model(theta)
    ev, lam, Phi, solve, sigma = modes or _modes(problem, theta, model)
    C = np.asarray(problem.C)
    index, paired = np.asarray(ev.model_index), np.asarray(ev.paired)

    r, g_lam, g_phi = (np.asarray(g) for g in _row_derivatives(theta, problem, jax.tree.map(jnp.asarray, ev)))
    ns, ne = C.shape[0], len(index)
    G = _RowChain(np.concatenate([g_lam, g_phi.reshape(len(r), ns * ne)], axis=1), ne)

    modes = [int(i) for i in index[paired]]
    # the paired modes signed as in the residual: its Ritz vectors (or a second solve) may
    # return any of them negated
    Phi = Phi.copy()
    Phi[:, modes] *= np.where(np.sum((C @ Phi[:, modes]) * np.asarray(ev.phi_a)[:, paired], axis=0) < 0, -1.0, 1.0)
    Cphi = C @ Phi
    flex = solve(C.T).T - (Cphi / (lam - sigma)) @ Phi.T  # C [(K − σM)⁻¹ − Σ φφᵀ/(λ − σ)]: ns × n
    Phi_p = np.vstack([Phi, np.zeros((1, Phi.shape[1]))])  # padding index → 0
    flex_p = np.hstack([flex, np.zeros((ns, 1))])
    columns, ids = {}, {}
    for kind in kinds:
        found = _element_derivatives(model, kind, lam, Phi_p, Cphi, flex_p, paired, modes)
        if found is not None:
            D, ids[kind] = found
            columns[kind] = G @ np.concatenate([D[0], D[1:].reshape(ns * ne, -1)])
    return ElementJacobian(r, columns, ids, np.asarray(ev.mac))


def _element_derivatives(model: Model, kind: str, lam, Phi_p, Cphi, flex_p, paired, modes):
    """``(D, element ids)`` of one kind: ∂λ_j and ∂(Cφ_j) of each paired mode j per element
    (``D``: (1 + ns) × ne × elements), None where the model has no element of the kind.
    ``Phi_p``, ``flex_p``: the modes and the residual flexibility at the sensors, padded
    with a zero row (index −1); ``modes``: the model mode of each paired test mode."""
    k_blocks, m_blocks = _blocks(model, kind)
    k_blocks = [b for b in k_blocks if np.any(b[1])]
    m_blocks = [b for b in m_blocks if np.any(b[1])]
    names = [n_ for n_ in _K_ORDER + ("masses",) if n_ in {b[0] for b in k_blocks + m_blocks}]
    if not names:
        return None
    eids = np.concatenate([getattr(model, n_).ids for n_ in names])
    offset = dict(zip(names, np.cumsum([0] + [len(getattr(model, n_).ids) for n_ in names])[:-1]))
    n, ns, ne = Phi_p.shape[0] - 1, Cphi.shape[0], len(paired)
    D = np.zeros((1 + ns, ne, len(eids)))  # ∂λ_j and ∂(Cφ_j) per element

    def scatter(blocks, scale, j):
        """(∂K − λ_j ∂M) φ_j of each element as a sparse n × elements matrix."""
        data, at, col = [], [], []
        for name, blk, idx in blocks:
            data.append(scale * np.einsum("eab,eb->ea", blk, Phi_p[idx, j]).ravel())
            at.append(idx.ravel())
            col.append(np.repeat(offset[name] + np.arange(len(blk)), idx.shape[1]))
        if not data:
            return scipy.sparse.csr_matrix((n + 1, len(eids)))
        return scipy.sparse.csr_matrix((np.concatenate(data), (np.concatenate(at), np.concatenate(col))),
                                       shape=(n + 1, len(eids)))

    for col, j in zip(np.flatnonzero(paired), modes):
        lj = lam[j]
        coef = np.where(np.abs(lam - lj) > CLUSTER_RTOL * abs(lj), 1.0 / np.where(lam == lj, 1.0, lj - lam), 0.0)
        coef[j] = 0.0
        v_m = scatter(m_blocks, -lj, j)
        v = scatter(k_blocks, 1.0, j) + v_m
        proj = np.asarray((v.T @ Phi_p).T)  # φ_kᵀ v per mode k and element
        D[0, col] = proj[j]  # eq. 3.18
        # eq. 3.23 with eq. 3.28, the static correction, and eq. 3.29: c_j = −½ φ_jᵀ ∂M φ_j
        D[1:, col] = Cphi @ (coef[:, None] * proj) - np.asarray((v.T @ flex_p.T).T)
        if m_blocks and lj != 0:
            D[1:, col] += 0.5 * Cphi[:, [j]] * (np.asarray(v_m.T @ Phi_p[:, j]) / lj)[None, :]
    return D, eids
