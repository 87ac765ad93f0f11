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
import scipy.sparse.linalg

import jaxfem
from jaxfem import FAST_COMPILE, STIFFNESS_BLOCKS, STRUCTURAL_BLOCKS, Model

from .. import Compiled, Problem, residuals


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

    r, J = Compiled(_stacked_with_jacobian, FAST_COMPILE)(theta, problem)
    return reduction(np.asarray(r), np.asarray(J))


def _stacked(theta, problem: Problem):
    eps, _ = residuals(theta, problem)
    return jnp.concatenate([jnp.ravel(v) for k, v in sorted(eps.items()) if k != "regularisation"])


def _stacked_with_jacobian(theta, problem: Problem):
    return _stacked(theta, problem), jax.jacfwd(_stacked)(theta, problem)


def residual_forces(model: Model, lam_e, phi_e, C) -> tuple[dict[int, float], dict[int, float]]:
    """Method (b): standardised residual-force indicator per element id.

    Each measured shape is expanded to all DoFs with the least residual force that still
    reproduces the measurement, ``min ‖f‖, f = W (K − λ_e M) φ̃, subject to C φ̃ = φ_e``
    (W: the inverse of the median stiffness diagonal of translations and of rotations, so
    that forces and moments mix as displacements do, without amplifying soft parts); f is
    where the model cannot be in equilibrium with the test. With φ̃ = A⁻¹ W⁻¹ f
    (A = K − λ_e M, symmetric) the constraint reads ``Z f = φ_e``, ``Zᵀ = W⁻¹ A⁻¹ Cᵀ``
    (n × n_s: one factorisation of A and n_s solves), and f is its minimum-norm solution
    ``f = F φ_e``, F = Z⁺ = U S⁻¹ Vᵀ from the thin SVD Zᵀ = U S Vᵀ (a sensor read twice
    only drops a singular value). Noise of σ per sensor puts the floor
    ``σ² Σ_j F_ij² = σ² Σ_k U_ik² / S_k²`` at DoF i (σ = ‖φ_e‖/√n_s, the same relative
    noise in every mode). A DoF scores Σ_modes f_i² / (floor_i + mean floor) — the mean
    keeps DoFs the noise hardly reaches from being amplified (on a frame with exact data, a
    bush's unmeasured grid came first) —, an element the mean over its DoFs; both are scaled
    to a maximum of 1. Raw forces point at stiff places a noisy sensor must bend and at the
    suspension modes, whose inertia forces are small.

    **Arguments:** the model; measured eigenvalues λ_e (rad/s)² (m,), real shapes at the
    sensors ``phi_e`` (n_s, m), the observation matrix ``C`` (n_s, n_dof).
    **Returns:** ({element id: indicator}, {grid id: Σ over its solved DoFs}).

    Sparse: one symmetric factorisation of A per mode (:mod:`jaxfem._sparse`, PARDISO or
    SuperLU), no n × n array; memory n × n_s per mode.
    """
    K, M = jaxfem.assemble(model)
    n = model.n_dof
    pat = jaxfem.sparse_pattern(tuple(K.indices) + tuple(M.indices), K.n)
    kd = pat.values(K.blocks, pat.slots[:len(K.blocks)])
    md = pat.values(M.blocks, pat.slots[len(K.blocks):])
    backend = jaxfem.resolve_sparse_backend("auto", quiet=True)  # the eigensolver warns where PARDISO is missed
    C = np.asarray(C, dtype=np.float64)
    ns = C.shape[0]
    rotation = model.dofs.labels[:, 1] > 3
    ka = pat.matrix(kd)
    diag = np.abs(ka.diagonal())
    w = np.where(rotation, 1.0 / np.median(diag[rotation]) if rotation.any() else 1.0,
                 1.0 / np.median(diag[~rotation]) if (~rotation).any() else 1.0)
    ct = np.ascontiguousarray(C.T)
    per_dof = np.zeros(n + 1)  # last entry: padding index
    shapes = np.asarray(phi_e, dtype=np.float64).T
    for mode, (lam, shape) in enumerate(zip(np.asarray(lam_e, dtype=np.float64), shapes)):
        data = kd - lam * md
        try:
            x = _solved(jaxfem.new_sparse_factor(pat, backend, data, definite=False), pat.matrix(data), ct)
        except ValueError as err:
            raise ValueError(f"residual forces, measured mode {mode + 1} (column {mode} of phi_e, "
                             f"{np.sqrt(max(lam, 0.0)) / (2 * np.pi):.6g} Hz): {err}") from None
        u, s, vt = np.linalg.svd(x / w[:, None], full_matrices=False)
        keep = s > s[0] * max(n, ns) * np.finfo(float).eps  # a sensor read twice: a zero singular value
        u, s, vt = u[:, keep], s[keep], vt[keep]
        f = u @ ((vt @ shape) / s)
        floor = (shape @ shape / ns) * np.sum((u / s) ** 2, axis=1)
        den = floor + floor.mean()  # zero only for a zero shape, whose forces are zero too
        per_dof[:n] += np.divide(f ** 2, den, out=np.zeros(n), where=den > 0)
    scores: dict[int, float] = {}
    for block, idx in _element_dofs(model):
        used = idx < model.n_dof
        value = np.sum(per_dof[idx] * used, axis=1) / np.maximum(used.sum(axis=1), 1)
        scores.update({int(e): float(v) for e, v in zip(block.ids, value)})
    nodes: dict[int, float] = {}
    for (node, _), f2 in zip(model.dofs.labels, per_dof[:n]):
        nodes[int(node)] = nodes.get(int(node), 0.0) + float(f2)
    return _unit(scores), _unit(nodes)


def _solved(factor, a, b: np.ndarray) -> np.ndarray:
    """``a⁻¹ b`` by ``factor`` and up to four steps of iterative refinement (PARDISO's
    perturbed pivots, SuperLU's rounding at λ_e next to an eigenvalue of the model); a
    ``ValueError`` when the solution is not finite or does not satisfy the system."""
    x = factor.solve(b)
    scale = scipy.sparse.linalg.norm(a, np.inf)
    big = lambda v: np.max(np.abs(v), axis=0)  # noqa: E731  (per right-hand side)
    for _ in range(4):
        if not np.all(np.isfinite(x)):
            break
        res = b - a @ x
        if np.all(big(res) <= 1e-12 * (scale * big(x) + big(b))):
            return x
        x = x + factor.solve(res)
    if np.all(np.isfinite(x)) and np.all(big(b - a @ x) <= 1e-8 * (scale * big(x) + big(b))):
        return x
    raise ValueError("K − λ_e M is singular to working precision (λ_e an eigenvalue of the model)")


def _unit(scores: dict) -> dict:
    top = max(scores.values(), default=0.0)
    return {k: v / top for k, v in scores.items()} if top > 0 else scores


def _element_dofs(model: Model):
    """(element block, solved-DoF indices per element) for blocks with stiffness."""

    for block in (getattr(model, name) for name in STRUCTURAL_BLOCKS):
        if len(block.ids):
            yield block, jaxfem.node_transform(model, block.nodes)[1]


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
