"""Where does the model fail? Error-localisation indicators by two independent methods.

(a) Sensitivity-based: for each candidate parameter k alone, the fraction of the
    (weighted, linearised) residual cost that one Gauss–Newton step in k removes,
    ``ρ_k = (J_kᵀ ε)² / (J_kᵀJ_k · εᵀε)`` (the squared cosine between the residual and
    the sensitivity column; Friswell & Mottershead 1995, §7, "best subset" selection).
(b) Residual forces ``f = (K − λ_e M) φ̃`` of the measured modes, expanded to the model
    with the least residual force that reproduces the measurement; f vanishes where the
    model is in equilibrium with the test (Friswell & Mottershead 1995, §8), so elements
    are scored by the forces at their DoFs, each force standardised by the force that
    the measurement noise alone puts there.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse
import scipy.sparse.linalg

import jaxfem
from jaxfem import STIFFNESS_BLOCKS, STRUCTURAL_BLOCKS, Model
from jaxfem._assembly import _sparse_block

from ._compiled import Compiled
from ._residuals import Problem, residuals


def reduction(r: np.ndarray, columns: np.ndarray, baseline: np.ndarray | None = None,
              *, joint: bool = False) -> np.ndarray | float:
    """Method (a): share ρ ∈ [0, 1] of ‖r‖² that a linearised least-squares step removes.

    Per column ``ρ_k = (J_kᵀ r)² / (‖J_k‖² ‖r‖²)``, or with ``joint=True`` one ρ for the
    span of all columns. Columns of ``baseline`` (parameters fitted anyway) are projected
    out first, so ρ is what a candidate adds to them.
    """
    r, J = np.asarray(r, float), np.asarray(columns, float)
    if baseline is not None and baseline.shape[1]:
        q, _ = np.linalg.qr(baseline)
        J = J - q @ (q.T @ J)
    rr = float(r @ r)
    if rr == 0:
        return 0.0 if joint else np.zeros(J.shape[1])
    if joint:
        coef = np.linalg.lstsq(J, r, rcond=1e-10)[0]
        fit = J @ coef
        return float(fit @ fit) / rr
    den = np.sum(J * J, axis=0) * rr
    return np.where(den > 0, (J.T @ r) ** 2 / np.where(den > 0, den, 1.0), 0.0)


def parameter_reduction(problem: Problem, theta=None) -> np.ndarray:
    """Method (a) for the parameters of ``problem``: ρ_k per parameter (at θ, default 0)."""
    n_p = len(problem.parameterisation.parameters)
    theta = jnp.zeros(n_p) if theta is None else theta

    r, J = Compiled(_stacked_with_jacobian)(theta, problem)
    return reduction(np.asarray(r), np.asarray(J))


def _stacked(theta, problem: Problem):
    eps, _ = residuals(theta, problem)
    return jnp.concatenate([jnp.ravel(v) for k, v in sorted(eps.items()) if k != "regularisation"])


def _stacked_with_jacobian(theta, problem: Problem):
    return _stacked(theta, problem), jax.jacfwd(_stacked)(theta, problem)


PROBES = 32
"""Noise probes per mode for the noise floor of the residual forces (:func:`residual_forces`);
with at most this many sensors, each sensor's column instead (the floor exact)."""


def residual_forces(model: Model, lam_e, phi_e, C) -> tuple[dict[int, float], dict[int, float]]:
    """Method (b): standardised residual-force indicator per element id.

    Each measured shape is expanded to all DoFs with the least residual force that still
    reproduces the measurement, ``min ‖W (K − λ_e M) φ̃‖ subject to C φ̃ = φ_e`` (W: the
    inverse of the median stiffness diagonal of translations and of rotations, so that
    forces and moments mix as displacements do, without amplifying soft parts); the
    remaining force ``f = W (K − λ_e M) φ̃`` is where the model cannot be in
    equilibrium with the test. f is linear in the measured shape, ``f = F φ_e``, so noise
    of σ per sensor puts the floor ``σ² Σ_j F_ij²`` at DoF i (σ = ‖φ_e‖/√n_s, the same
    relative noise in every mode; F's row norms from the sensors' columns, or estimated
    from :data:`PROBES` Gaussian probes with more sensors). A DoF scores
    Σ_modes f_i² / (floor_i + mean floor) — the mean keeps DoFs the noise hardly reaches
    from being amplified (on a frame with exact data, a bush's unmeasured grid came
    first) —, an element the mean over its DoFs; both are scaled to a maximum of 1. Raw
    forces point at stiff places a noisy sensor must bend and at the suspension modes,
    whose inertia forces are small.

    **Arguments:** the model; measured eigenvalues λ_e (rad/s)² (m,), real shapes at the
    sensors ``phi_e`` (n_s, m), the observation matrix ``C`` (n_s, n_dof).
    **Returns:** ({element id: indicator}, {grid id: Σ over its solved DoFs}).

    Sparse throughout (one sparse LU per mode, see :func:`_expanded`): no n × n array.
    """
    K, M = jaxfem.assemble(model)
    n = model.n_dof
    every = np.arange(n)
    ks, ms = _sparse_block(K, every).tocsr(), _sparse_block(M, every).tocsr()
    C = np.asarray(C, dtype=np.float64)
    ns = C.shape[0]
    rotation = model.dofs.labels[:, 1] > 3
    diag = np.abs(ks.diagonal())
    w = np.where(rotation, 1.0 / np.median(diag[rotation]) if rotation.any() else 1.0,
                 1.0 / np.median(diag[~rotation]) if (~rotation).any() else 1.0)
    cs = scipy.sparse.csr_matrix(C)
    # Σ_j F_ij² = ‖F_i P‖² for P = I, or its expectation for Gaussian P with variance 1/PROBES
    probes = np.eye(ns) if ns <= PROBES else np.random.default_rng(0).standard_normal((ns, PROBES)) / np.sqrt(PROBES)
    per_dof = np.zeros(n + 1)  # last entry: padding index
    order = None
    shapes = np.asarray(phi_e, dtype=np.float64).T
    for mode, (lam, shape) in enumerate(zip(np.asarray(lam_e, dtype=np.float64), shapes)):
        a = (scipy.sparse.diags(w) @ (ks - lam * ms)).tocsc()
        order = _pair_order(a, cs) if order is None else order
        f = a @ _expanded(a, cs, np.column_stack([shape, probes]), mode, order)
        floor = (shape @ shape / ns) * np.sum(f[:, 1:] ** 2, axis=1)
        den = floor + floor.mean()  # zero only for a zero shape, whose forces are zero too
        per_dof[:n] += np.divide(f[:, 0] ** 2, den, out=np.zeros(n), where=den > 0)
    scores: dict[int, float] = {}
    for block, idx in _element_dofs(model):
        used = idx < model.n_dof
        value = np.sum(per_dof[idx] * used, axis=1) / np.maximum(used.sum(axis=1), 1)
        scores.update({int(e): float(v) for e, v in zip(block.ids, value)})
    nodes: dict[int, float] = {}
    for (node, _), f2 in zip(model.dofs.labels, per_dof[:n]):
        nodes[int(node)] = nodes.get(int(node), 0.0) + float(f2)
    return _unit(scores), _unit(nodes)


DENSE_FALLBACK_BELOW = 3000
"""DoF count below which a mode whose expansion system is singular is solved by the dense
least-squares fallback instead of raising a ``ValueError``."""


def _expanded(a, cs, shape: np.ndarray, mode: int, order: np.ndarray) -> np.ndarray:
    """φ̃ minimising ‖a φ̃‖ subject to ``cs φ̃ = shape`` (a: sparse n × n, cs: sparse n_s × n;
    ``shape`` (n_s, k): k right-hand sides, one factorisation).

    The optimality (KKT) conditions in augmented form, with the residual force
    ``r = a φ̃`` as an unknown, ``[[−I, a, 0], [aᵀ, 0, csᵀ], [0, cs, 0]] [r; φ̃; μ] = [0; 0; shape]``
    (eliminating r gives the normal form ``[[aᵀa, csᵀ], [cs, 0]] [φ̃; μ] = [0; shape]``):
    its condition number is that of a, about 10¹³ on a shell where λ_e lies next to an
    eigenvalue of the model, not the square, at which least squares on the normal form
    misses the minimum by orders of magnitude. One sparse LU (SuperLU) in the fill-reducing
    ``order`` of :func:`_pair_order` with diagonal pivots, then iterative refinement; when
    that LU fails or its solution does not satisfy the system, one with partial pivoting.
    When the system is singular (C of deficient row rank, e.g. a sensor read twice, or
    [a; C] of deficient column rank): the minimum-norm least-squares solution of the dense normal form for models
    under :data:`DENSE_FALLBACK_BELOW` DoFs, else a ``ValueError``.
    """
    n, ns = a.shape[1], cs.shape[0]
    aug = scipy.sparse.bmat([[-scipy.sparse.identity(n), a, None], [a.T, None, cs.T], [None, cs, None]],
                            format="csr")
    rhs = np.concatenate([np.zeros((2 * n, shape.shape[1])), shape])
    permuted = aug[order][:, order].tocsc()
    sol, why = _lu_solve(permuted, rhs[order], permc_spec="NATURAL", diag_pivot_thresh=0.0,
                         options={"SymmetricMode": True})
    if sol is not None:
        return sol[np.argsort(order)][n:2 * n]
    sol, why = _lu_solve(aug.tocsc(), rhs)
    if sol is not None:
        return sol[n:2 * n]
    if n < DENSE_FALLBACK_BELOW:
        ad = a.toarray()
        kkt = np.block([[ad.T @ ad, cs.T.toarray()], [cs.toarray(), np.zeros((ns, ns))]])
        return np.linalg.lstsq(kkt, np.concatenate([np.zeros((n, shape.shape[1])), shape]), rcond=None)[0][:n]
    raise ValueError(
        f"residual forces, measured mode {mode + 1} (column {mode} of phi_e): the expansion system "
        f"is singular ({why}). The sensors must read independent DoFs and, with the model, "
        f"determine the expanded shape ({n} DoFs, {ns} sensors; no dense fallback at "
        f"{DENSE_FALLBACK_BELOW} DoFs or more)."
    )


def _lu_solve(mat, rhs: np.ndarray, **options) -> tuple[np.ndarray | None, str]:
    """``mat⁻¹ rhs`` by SuperLU and up to three refinement steps, or (None, why) when the
    factorisation fails or the solution is not finite or does not satisfy the system."""
    try:
        lu = scipy.sparse.linalg.splu(mat, **options)
    except RuntimeError as err:  # "Factor is exactly singular"
        return None, f"SuperLU: {err}"
    sol = lu.solve(rhs)
    scale = scipy.sparse.linalg.norm(mat, np.inf)
    big = lambda v: np.max(np.abs(v), axis=0)  # noqa: E731  (per right-hand side)
    for _ in range(4):
        if not np.all(np.isfinite(sol)):
            return None, "non-finite solution"
        res = rhs - mat @ sol
        if np.all(big(res) <= 1e-12 * (scale * big(sol) + big(rhs))):
            return sol, ""
        sol = sol + lu.solve(res)
    if np.all(np.isfinite(sol)) and np.all(big(rhs - mat @ sol) <= 1e-8 * (scale * big(sol) + big(rhs))):
        return sol, ""
    return None, "the LU solution does not satisfy the system"


def _pair_order(a, cs) -> np.ndarray:
    """Order of the unknowns [r; φ̃; μ] of :func:`_expanded` for an LU with diagonal pivots:
    DoF k as the pair (r_k, φ̃_k), the pairs in the minimum-degree order of the graph of
    a + aᵀ + csᵀcs (SuperLU's MMD, read off the factorisation of a diagonally dominant
    matrix of that pattern), each multiplier μ_j after the last DoF that sensor j reads.
    Pivoting on r_k (−1), then φ̃_k (the Schur complement aᵀa is positive definite), then
    μ (negative definite) needs no row interchanges; fill as that of a, not of aᵀa."""
    n, ns = a.shape[1], cs.shape[0]
    pattern = (abs(a) + abs(a).T + abs(cs.T @ cs)).tocsc()
    pattern.data[:] = 1.0
    proxy = (pattern + scipy.sparse.diags(np.full(n, float(n)))).tocsc()
    pos = scipy.sparse.linalg.splu(proxy, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                   options={"SymmetricMode": True}).perm_c
    csr = cs.tocsr()
    last = np.array([pos[csr.indices[csr.indptr[j]:csr.indptr[j + 1]]].max(initial=-1) for j in range(ns)])
    key = np.concatenate([2.0 * pos, 2.0 * pos + 1, 2.0 * last + 1.5])
    return np.argsort(key, kind="stable")

def _unit(scores: dict) -> dict:
    top = max(scores.values(), default=0.0)
    return {k: v / top for k, v in scores.items()} if top > 0 else scores


def _element_dofs(model: Model):
    """(element block, solved-DoF indices per element) for blocks with stiffness."""
    from jaxfem._assembly import _node_transform

    for block in (getattr(model, name) for name in STRUCTURAL_BLOCKS):
        if len(block.ids):
            yield block, _node_transform(model, block.nodes)[1]


def group_scores(element_scores: dict[int, float], model: Model) -> dict[int, float]:
    """Mean element score per property id, normalised so that the largest is 1, best first."""
    pid_of = {}
    for block in (getattr(model, name) for name in STIFFNESS_BLOCKS):
        pid_of.update({int(e): int(p) for e, p in zip(block.ids, block.pids)})
    sums: dict[int, list[float]] = {}
    for eid, v in element_scores.items():
        if eid in pid_of:
            sums.setdefault(pid_of[eid], []).append(v)
    scores = {p: float(np.mean(v)) for p, v in sums.items()}
    top = max(scores.values(), default=1.0) or 1.0
    return {p: v / top for p, v in sorted(scores.items(), key=lambda kv: -kv[1])}
