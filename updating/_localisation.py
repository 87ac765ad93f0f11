"""Where does the model fail? Error-localisation indicators by two independent methods.

(a) Sensitivity-based: for each candidate parameter k alone, the fraction of the
    (weighted, linearised) residual cost that one Gauss–Newton step in k removes,
    ``ρ_k = (J_kᵀ ε)² / (J_kᵀJ_k · εᵀε)`` (the squared cosine between the residual and
    the sensitivity column; Friswell & Mottershead 1995, §7, "best subset" selection).
(b) Residual forces ``f = (K − λ_e M) φ̃`` of the measured modes, expanded to the model
    with the least residual force that reproduces the measurement; f vanishes where the
    model is in equilibrium with the test (Friswell & Mottershead 1995, §8), so elements
    are scored by the forces at their DoFs.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem
from jaxfem import STIFFNESS_BLOCKS, STRUCTURAL_BLOCKS, Model

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


def residual_forces(model: Model, lam_e, phi_e, C) -> tuple[dict[int, float], dict[int, float]]:
    """Method (b): residual-force indicator per element id.

    Each measured shape is expanded to all DoFs with the least residual force that still
    reproduces the measurement, ``min ‖W (K − λ_e M) φ̃‖ subject to C φ̃ = φ_e`` (W: the
    inverse of the median stiffness diagonal of translations and of rotations, so that
    forces and moments mix as displacements do, without amplifying soft parts); the
    remaining force ``f = W (K − λ_e M) φ̃`` is where the model cannot be in
    equilibrium with the test. A DoF scores Σ_modes f², an element the mean over its DoFs;
    both are scaled to a maximum of 1.

    **Arguments:** the model; measured eigenvalues λ_e (rad/s)² (m,), real shapes at the
    sensors ``phi_e`` (n_s, m), the observation matrix ``C`` (n_s, n_dof).
    **Returns:** ({element id: indicator}, {grid id: Σ f² over its solved DoFs}).
    """
    K, M = jaxfem.assemble(model)
    kd, md = np.asarray(K.todense()), np.asarray(M.todense())
    C = np.asarray(C)
    rotation = model.dofs.labels[:, 1] > 3
    diag = np.abs(np.diag(kd))
    w = np.where(rotation, 1.0 / np.median(diag[rotation]) if rotation.any() else 1.0,
                 1.0 / np.median(diag[~rotation]) if (~rotation).any() else 1.0)
    n, ns = kd.shape[0], C.shape[0]
    per_dof = np.zeros(n + 1)  # last entry: padding index
    for lam, shape in zip(np.asarray(lam_e), np.asarray(phi_e).T):
        a = w[:, None] * (kd - lam * md)
        kkt = np.block([[a.T @ a, C.T], [C, np.zeros((ns, ns))]])
        sol = np.linalg.lstsq(kkt, np.concatenate([np.zeros(n), shape]), rcond=None)[0]
        per_dof[:n] += (a @ sol[:n]) ** 2
    scores: dict[int, float] = {}
    for block, idx in _element_dofs(model):
        used = idx < model.n_dof
        value = np.sum(per_dof[idx] * used, axis=1) / np.maximum(used.sum(axis=1), 1)
        scores.update({int(e): float(v) for e, v in zip(block.ids, value)})
    nodes: dict[int, float] = {}
    for (node, _), f2 in zip(model.dofs.labels, per_dof[:n]):
        nodes[int(node)] = nodes.get(int(node), 0.0) + float(f2)
    return _unit(scores), _unit(nodes)


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
