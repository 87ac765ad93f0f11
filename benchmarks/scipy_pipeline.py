"""The Monte-Carlo update a user would otherwise build: SciPy and NumPy, one process per core.

The reference of :mod:`benchmarks.perf_montecarlo` (issue 13): the same residual as
:mod:`updating._residuals` (eigenvalue rows w·(λ_e − λ_a)/λ_e, eq. 3.12 normalised;
eigenvector rows (φ_e − MSF·Cφ_a)/‖φ_e‖, eq. 3.21; regularisation √μ·θ, eq. 3.4) with the
same in-loop pairing (greedy in descending MAC, the rule of :func:`updating.pair_modes_masked`),
the same parameters θ = log(1 + α) with K(θ) = K_0 + Σ_k (e^θ_k − 1) K_k and
M(θ) = M_0 + Σ_k (e^θ_k − 1) M_k (eq. 3.1), and the same Gauss–Newton iteration
(eq. 3.11 with W_p = 0, the step by ``numpy.linalg.lstsq``) and stopping rule
(max |Δα| ≤ tolerance, at most ``max_iterations`` steps). Per residual evaluation:

1. the lowest ``n_model`` modes by ``scipy.linalg.eigh(M, K − σM, subset_by_index=…)``
   (LAPACK ``dsygvx`` on the largest ν = 1/(λ − σ), standardised with the Cholesky factor
   of the stiffness, as :func:`jaxfem.dense_modes`). ``standardise="mass"`` is the
   textbook ``eigh(K, M, subset_by_index=[0, n_model − 1])``, standardised with the mass:
   it loses ε·λ_max/λ_1 on the lowest modes (tree: λ_1 off by 5.6e-8 against 2e-10;
   λ_max/λ_1 = 8e8) and Gauss–Newton stalls at α changes of 1e-7…4e-6;
2. ``refine`` (default): one sweep of inverse iteration and Rayleigh–Ritz with K·X taken
   element by element (:func:`refine`). With the assembled K alone, λ_1, λ_2 of the tree
   move by 1e-10…3e-10 (relative) between θ 1e-13 apart — the rounding of the assembled
   entries — and Gauss–Newton jitters at α changes of 1e-9…2e-8, above the benchmark's
   tolerance of 1e-9; refined, its changes fall to 1e-11 in 4–5 steps;
3. eigenvalue derivatives ∂λ_r/∂θ_k = φ_rᵀ(∂K/∂θ_k − λ_r ∂M/∂θ_k)φ_r (eq. 3.18 with
   mass-normalised φ and ∂K/∂θ_k = e^θ_k K_k);
4. eigenvector derivatives by the modal expansion ∂φ_r/∂θ_k = Σ_s c_s φ_s (eq. 3.23), c_s
   of eq. 3.28 for s ≠ r (pairs with |λ_s − λ_r| ≤ 1e-6·|λ_r| left out) and the
   mass-normalisation term c_r of eq. 3.29 (zero for stiffness factors), **truncated to
   the computed subset** of ``n_model`` modes, where the thesis sums over all N_a modes.
   ``expansion="static"`` (default) adds the omitted modes to first order in λ_r/λ_s
   (the static, residual-flexibility term of the modified modal method, Wang 1991) with
   the factor of K − σM of step 2; ``expansion="subset"`` is the bare truncated sum.
   Tree, 10 test modes, 26 model modes: the Jacobian differs from the all-mode expansion
   by 1.6e-3 (relative; subset) and 4e-6 (static), and Gauss–Newton, which stops where
   its own Jacobian's normal equations vanish, ends 4e-5…9e-5 (subset) and 3e-8…4e-7
   (static) in α from the exact-Jacobian update of the same 1 %-error samples, in as many
   steps (the rate is set by the residual, not by the Jacobian's error);
5. the derivative of the MSF-scaled shape residual through MSF = φ_aᵀφ_e/φ_aᵀφ_a.

Samples are split over a ``multiprocessing`` pool of ``spawn``-ed processes (one per
core), each limited to one BLAS/LAPACK thread (``threadpoolctl``), one sample per task;
the workers import NumPy and SciPy only (:class:`ScipyPipeline` checks that no worker
imported JAX). The matrices (dense K_0, M_0, K_k, M_k; the element blocks of K) are taken
once, in the parent, from jaxfem (:meth:`ReferenceProblem.from_problem`) and checked
against it (:func:`verify`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import multiprocessing
import os
import sys

import numpy as np
import scipy.linalg as sl
from scipy import sparse

DEGENERATE_RTOL = 1e-6  # as jaxfem.DEGENERATE_RTOL (not imported: the workers stay JAX-free)
STATUS = ("ok", "not converged", "unpaired mode", "non-finite")  # as updating.studies._montecarlo.STATUS


@dataclasses.dataclass(frozen=True)
class ReferenceProblem:
    """Everything one sample's update needs, as NumPy arrays.

    ``K0``/``M0`` (n, n): the initial model; ``K_groups``/``M_groups`` (p, n, n): the
    matrices each factor scales (zero for a mass group's K, a stiffness group's M);
    ``C`` (n_s, n): observation matrix over the solved DoFs; ``lam_weight``/``active``
    (n_e,): eigenvalue-row weights, modes in the fit; ``mu``: regularisation; ``n_model``:
    modes computed; ``shift``: σ of the standardisation (below λ_1); pairing thresholds;
    stopping rule; ``elements``: per element kind, the blocks of K_0 (n_el, w, w), their
    DoFs (n_el, w; n is padding), ``coef`` (p, n_el: the part of each block factor k
    scales) and the scatter matrix of the blocks' rows; ``standardise``, ``refine``,
    ``expansion``: the variants of steps 1, 2 and 4 of the module docs.
    """

    K0: np.ndarray
    M0: np.ndarray
    K_groups: np.ndarray
    M_groups: np.ndarray
    C: np.ndarray
    lam_weight: np.ndarray
    active: np.ndarray
    mu: float
    use_lam: bool
    use_phi: bool
    n_model: int
    shift: float
    min_mac: float
    max_freq_dev: float
    tolerance: float
    max_iterations: int
    elements: tuple
    standardise: str = "stiffness"
    refine: bool = True
    expansion: str = "static"

    has_mass: bool = dataclasses.field(init=False)

    def __post_init__(self):
        object.__setattr__(self, "has_mass", bool(np.any(self.M_groups)))
        if self.standardise not in ("stiffness", "mass"):
            raise ValueError(f"standardise {self.standardise!r}: stiffness | mass")
        if self.expansion not in ("subset", "static"):
            raise ValueError(f"expansion {self.expansion!r}: subset | static")

    @classmethod
    def from_problem(cls, problem, *, shift: float, tolerance: float, max_iterations: int,
                     **variant) -> ReferenceProblem:
        """The matrices of an :class:`updating._residuals.Problem`: K_0, M_0 assembled at
        θ = 0, and K_k, M_k as the change of the assembled matrices when factor k alone
        doubles (α_k = 1). Exact for stiffness and mass factors (eq. 3.1); :func:`verify`
        checks the linearity at a random θ."""
        import jaxfem  # parent only

        p = len(problem.parameterisation.parameters)

        def matrices(theta):
            K, M = jaxfem.assemble(problem.model(np.asarray(theta, np.float64)))
            if len(M.massless):
                raise ValueError(f"{len(M.massless)} massless DoFs: the reference needs a mass on every DoF")
            return K, np.asarray(K.todense()), np.asarray(M.todense())

        (E0, K0, M0), *groups = [matrices(np.log(2.0) * e) for e in np.eye(p + 1, p, -1)]
        elements = []
        for t, (blocks, idx) in enumerate(zip(E0.blocks, E0.indices)):
            blocks, idx = np.asarray(blocks), np.asarray(idx)
            # coef[k, e]: element e's block changes by coef·block when α_k = 1 (eq. 3.1: 1 or 0)
            norm = np.maximum(np.sum(blocks**2, axis=(1, 2)), np.finfo(float).tiny)
            coef = np.stack([np.sum((np.asarray(E.blocks[t]) - blocks) * blocks, axis=(1, 2)) / norm
                             for E, _, _ in groups])
            scatter = sparse.csr_matrix((np.ones(idx.size), (idx.ravel(), np.arange(idx.size))),
                                        shape=(K0.shape[0] + 1, idx.size))  # row n: padding
            elements.append((blocks, idx, coef, scatter))
        return cls(K0=K0, M0=M0, K_groups=np.stack([K - K0 for _, K, _ in groups]),
                   M_groups=np.stack([M - M0 for _, _, M in groups]), C=np.asarray(problem.C),
                   lam_weight=np.asarray(problem.lam_weight), active=np.asarray(problem.active),
                   mu=float(problem.mu), use_lam=bool(problem.use_lam), use_phi=bool(problem.use_phi),
                   n_model=int(problem.n_model), shift=float(shift), min_mac=float(problem.min_mac),
                   max_freq_dev=float(problem.max_freq_dev), tolerance=float(tolerance),
                   max_iterations=int(max_iterations), elements=tuple(elements), **variant)

    def matrices(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """K(θ), M(θ) of eq. 3.1 with α = e^θ − 1."""
        alpha = np.expm1(theta)
        K = self.K0 + np.tensordot(alpha, self.K_groups, 1)
        M = self.M0 + np.tensordot(alpha, self.M_groups, 1) if self.has_mass else self.M0
        return K, M

    def stiffness_product(self, theta: np.ndarray, X: np.ndarray) -> np.ndarray:
        """K(θ) X element by element, Σ_e (1 + Σ_k α_k coef_ke) K_e X_e, without the
        assembled K: its entries, sums of element entries rounded, move λ_1 of the tree by
        1e-10 (relative) between nearby θ, the element products by 1e-13."""
        return self._element_products(X, lambda coef: (1.0 + np.expm1(theta) @ coef)[None])[0]

    def group_products(self, X: np.ndarray) -> np.ndarray:
        """K_k X for every factor k, (p, n, m), element by element."""
        return self._element_products(X, lambda coef: coef)

    def _element_products(self, X, weights) -> np.ndarray:
        Xp = np.vstack([X, np.zeros((1, X.shape[1]))])
        out = 0.0
        for blocks, idx, coef, scatter in self.elements:
            local = blocks @ Xp[idx]  # (n_el, w, m)
            w = weights(coef)  # (q, n_el)
            out = out + np.stack([scatter @ (local * wi[:, None, None]).reshape(-1, X.shape[1]) for wi in w])
        return out[:, :-1]


def modes(problem: ReferenceProblem, K: np.ndarray, M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The lowest ``n_model`` eigenpairs (λ ascending, φ mass-normalised) by
    ``scipy.linalg.eigh`` with a subset (module docs for the standardisation)."""
    n, m = K.shape[0], problem.n_model
    if problem.standardise == "mass":
        return sl.eigh(K, M, subset_by_index=[0, m - 1])
    # M v = ν (K − σM) v with vᵀ(K − σM)v = 1: λ = σ + 1/ν, φ = v/√ν (φᵀMφ = 1).
    nu, v = sl.eigh(M, K - problem.shift * M, subset_by_index=[n - m, n - 1])
    nu, v = nu[::-1], v[:, ::-1]
    return problem.shift + 1.0 / nu, v / np.sqrt(nu)


def refine(problem: ReferenceProblem, theta, M, lam, Phi, factor) -> tuple[np.ndarray, np.ndarray]:
    """One sweep of inverse iteration in residual form, Φ − (K − σM)⁻¹(KΦ − MΦΛ), then
    Rayleigh–Ritz on the swept basis (as :func:`jaxfem.dense_modes`), with K·X element by
    element (:meth:`ReferenceProblem.stiffness_product`)."""
    W = Phi - sl.cho_solve(factor, problem.stiffness_product(theta, Phi) - (M @ Phi) * lam)
    kr, mr = W.T @ problem.stiffness_product(theta, W), W.T @ M @ W
    lam, y = sl.eigh(0.5 * (kr + kr.T), 0.5 * (mr + mr.T))
    return lam, W @ y


def eigenpairs(problem: ReferenceProblem, theta):
    """K(θ), M(θ), their lowest ``n_model`` eigenpairs (steps 1 and 2 of the module docs)
    and the Cholesky factor of K − σM where a step needs it. **Returns:**
    ``(K, M, λ, Φ, factor or None)``."""
    K, M = problem.matrices(theta)
    lam, Phi = modes(problem, K, M)
    factor = sl.cho_factor(K - problem.shift * M) if problem.refine or problem.expansion == "static" else None
    if problem.refine:
        lam, Phi = refine(problem, theta, M, lam, Phi, factor)
    return K, M, lam, Phi, factor


def pair(f_a, phi_a, f_e, phi_e, min_mac: float, max_freq_dev: float) -> np.ndarray:
    """Greedy one-to-one pairing in descending MAC among the admissible candidates
    (MAC ≥ min_mac, |Δf| ≤ max_freq_dev), the rule of :func:`updating.pair_modes_masked`.
    **Returns:** the model mode of each test mode, −1 where unpaired."""
    den = np.sum(phi_a**2, axis=0)[:, None] * np.sum(phi_e**2, axis=0)[None, :]
    mac = np.where(den > 0, (phi_a.T @ phi_e) ** 2 / np.where(den > 0, den, 1.0), 0.0)
    dev = (f_a[:, None] - f_e[None, :]) / f_e[None, :]
    avail = (mac >= min_mac) & (np.abs(dev) <= max_freq_dev)
    index = np.full(f_e.shape[0], -1)
    for _ in range(min(mac.shape)):
        i, j = np.unravel_index(np.argmax(np.where(avail, mac, -np.inf)), mac.shape)
        if not avail[i, j]:
            break
        index[j] = i
        avail[i, :] = False
        avail[:, j] = False
    return index


def _hz(lam):
    return np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi)


def residual(problem: ReferenceProblem, theta, lam_e, phi_e):
    """ε(θ) and its Jacobian ∂ε/∂θ (approximate: the truncated modal expansion, module
    docs), and the pairing. **Returns:** ``(eps, jac, index)``."""
    P = problem
    scale = np.exp(theta)
    K, M, lam, Phi, factor = eigenpairs(P, theta)
    phi_s = P.C @ Phi
    index = pair(_hz(lam), phi_s, _hz(lam_e), phi_e, P.min_mac, P.max_freq_dev)
    fitted = (index >= 0) & P.active
    k = np.where(index >= 0, index, 0)
    # Modal-space matrices of ∂K/∂θ and ∂M/∂θ, (p, m, m).
    KkPhi = P.group_products(Phi)
    A = scale[:, None, None] * np.einsum("na,pnb->pab", Phi, KkPhi)
    MkPhi = P.M_groups @ Phi if P.has_mass else np.zeros_like(KkPhi)
    B = scale[:, None, None] * np.einsum("na,pnb->pab", Phi, MkPhi)
    D = A - lam[None, None, :] * B  # φ_sᵀ(∂K − λ_r ∂M)φ_r at [s, r]
    dlam = np.einsum("prr->pr", D)  # eq. 3.18 (M_a,r = 1)
    gap = lam[:, None] - lam[None, :]  # λ_s − λ_r
    apart = np.abs(gap) > DEGENERATE_RTOL * np.abs(lam)[None, :]
    c = np.where(apart, -D / np.where(apart, gap, 1.0), 0.0)  # eq. 3.28, s ≠ r
    c = c - 0.5 * np.einsum("prr->pr", B)[:, None, :] * np.eye(lam.shape[0])  # eq. 3.29
    dphi_s = phi_s @ c  # (p, n_s, m): eq. 3.23 over the subset, at the sensors
    if P.expansion == "static":
        # The omitted modes s > m to first order in λ_r/λ_s: c_s φ_s summed is
        # −[(K − σM)⁻¹ − Σ_{s≤m} φ_s φ_sᵀ/(λ_s − σ)] (∂K − λ_r ∂M) φ_r (modified modal method).
        used = np.unique(k)
        F = scale[:, None, None] * (KkPhi[:, :, used] - lam[used] * MkPhi[:, :, used])
        flex = sl.cho_solve(factor, F.transpose(1, 0, 2).reshape(K.shape[0], -1))
        flex = flex.reshape(K.shape[0], len(theta), -1).transpose(1, 0, 2)
        kept = Phi @ (D[:, :, used] / (lam - P.shift)[:, None])
        dphi_s[:, :, used] -= P.C @ (flex - kept)
    eps, jac = [], []
    if P.use_lam:
        w = np.where(fitted, P.lam_weight / lam_e, 0.0)
        eps.append(w * (lam_e - lam[k]))
        jac.append(-(w[:, None] * dlam[:, k].T))
    if P.use_phi:
        a, da = phi_s[:, k], dphi_s[:, :, k]  # (n_s, n_e), (p, n_s, n_e)
        aa = np.sum(a * a, axis=0)
        msf = np.sum(a * phi_e, axis=0) / aa
        dmsf = (np.sum(da * phi_e, axis=1) - 2 * msf * np.sum(da * a, axis=1)) / aa  # (p, n_e)
        norm = np.linalg.norm(phi_e, axis=0)
        mask = fitted / norm
        eps.append(((phi_e - msf * a) * mask).ravel())
        jac.append((-(dmsf[:, None, :] * a + msf * da) * mask).reshape(len(theta), -1).T)
    eps.append(np.sqrt(P.mu) * theta)
    jac.append(np.sqrt(P.mu) * np.eye(len(theta)))
    return np.concatenate(eps), np.concatenate(jac), index


def gauss_newton(problem: ReferenceProblem, theta0, f_e, phi_e) -> dict:
    """One sample's update from θ_0: Gauss–Newton steps Δθ = −lstsq(∂ε/∂θ, ε) (eq. 3.11)
    until max |Δα| ≤ tolerance (converged) or ``max_iterations`` steps.
    **Returns:** θ, iterations (steps), converged, the last change, whether every test
    mode was paired at the last evaluation, and the status code of ``STATUS``."""
    lam_e, phi_e = (2 * np.pi * np.asarray(f_e)) ** 2, np.asarray(phi_e)
    theta = np.asarray(theta0, np.float64).copy()
    converged, change, iterations, paired = False, np.inf, 0, False
    while iterations < problem.max_iterations:
        eps, jac, index = residual(problem, theta, lam_e, phi_e)
        paired = bool(np.all(index >= 0))
        new = theta - np.linalg.lstsq(jac, eps, rcond=None)[0]
        iterations += 1
        if not np.all(np.isfinite(new)):
            theta = new
            break
        change = float(np.max(np.abs(np.expm1(new) - np.expm1(theta))))
        theta = new
        if change <= problem.tolerance:
            converged = True
            break
    status = 3 if not np.all(np.isfinite(theta)) else 1 if not converged else 2 if not paired else 0
    return {"theta": theta, "iterations": iterations, "converged": converged, "change": change,
            "paired": paired, "status": status}


def verify(reference: ReferenceProblem, problem, *, seed: int = 0) -> dict:
    """Check the reference against jaxfem (parent only): K(θ), M(θ) at a random θ against
    the assembled matrices (relative, largest entry; K also element by element), and the
    pipeline's λ, Cφ at θ = 0 (:func:`eigenpairs`) against
    :func:`updating._residuals.model_modes` (:func:`jaxfem.eigh`) and against
    :func:`jaxfem.dense_modes` (the engine's full solve). Raises ``ValueError`` when the
    matrices differ by more than 1e-10."""
    import jaxfem
    from updating._residuals import model_modes

    p = reference.K_groups.shape[0]
    theta = np.random.default_rng(seed).normal(0.0, 0.3, p)
    K, M = (np.asarray(a.todense()) for a in jaxfem.assemble(problem.model(theta)))
    Kr, Mr = reference.matrices(theta)
    Ke = reference.stiffness_product(theta, np.eye(K.shape[0]))
    out = {"K_rel": float(np.max(np.abs(K - Kr)) / np.max(np.abs(K))),
           "K_elements_rel": float(np.max(np.abs(K - Ke)) / np.max(np.abs(K))),
           "M_rel": float(np.max(np.abs(M - Mr)) / np.max(np.abs(M)))}
    if max(out.values()) > 1e-10:
        raise ValueError(f"the reference's K(θ), M(θ) differ from jaxfem's by {out}: "
                         "a parameter is not linear in e^θ (only stiffness and mass factors are)")
    _, _, lam, Phi, _ = eigenpairs(reference, np.zeros(p))
    phi_s = reference.C @ Phi
    K0, M0 = jaxfem.assemble(problem.model(np.zeros(p)))
    dense = jaxfem.dense_modes(K0, M0, reference.n_model, shift=reference.shift)
    against = {"model_modes": tuple(np.asarray(x) for x in model_modes(np.zeros(p), problem)),
               "dense_modes": (np.asarray(dense.lam[:reference.n_model]),
                               np.asarray(problem.C @ dense.basis[:, :reference.n_model]))}
    for name, (lam_j, phi_j) in against.items():
        sign = np.sign(np.sum(phi_s * phi_j, axis=0))
        out[f"lam_rel_{name}"] = float(np.max(np.abs(lam - lam_j) / np.abs(lam_j)))
        out[f"phi_rel_{name}"] = float(np.max(np.abs(phi_s * sign - phi_j)) / np.max(np.abs(phi_j)))
    return out


# --------------------------------------------------------------------------- the process pool

_WORKER: dict = {}


def _start_worker(problem: ReferenceProblem, barrier) -> None:
    from threadpoolctl import threadpool_limits

    _WORKER["limits"] = threadpool_limits(limits=1)  # kept: the limit holds for the process
    _WORKER["problem"] = problem
    _WORKER["barrier"] = barrier
    # Warm-up (LAPACK loaded and touched): one evaluation against the initial model's modes.
    n_e = len(problem.lam_weight)
    _, _, lam, Phi, _ = eigenpairs(problem, np.zeros(problem.K_groups.shape[0]))
    residual(problem, np.zeros(problem.K_groups.shape[0]), lam[:n_e], problem.C @ Phi[:, :n_e])


def _ready(_) -> dict:
    from threadpoolctl import threadpool_info

    _WORKER["barrier"].wait()  # every worker has started (and warmed up) before timing
    return {"pid": os.getpid(), "jax_imported": "jax" in sys.modules,
            "blas_threads": sorted({int(i["num_threads"]) for i in threadpool_info()})}


def _update(task) -> dict:
    theta0, f_e, phi_e, variant = task
    problem = dataclasses.replace(_WORKER["problem"], **variant) if variant else _WORKER["problem"]
    return gauss_newton(problem, theta0, f_e, phi_e)


@contextlib.contextmanager
def _bare_main():
    """``spawn`` re-runs the parent's ``__main__`` module in every worker (to find what
    is defined there); the workers need only this module, and the benchmark's main
    module imports JAX: hide it while the pool starts its processes."""
    main = sys.modules["__main__"]
    saved = {k: main.__dict__[k] for k in ("__spec__", "__file__") if k in main.__dict__}
    main.__dict__.pop("__file__", None)
    main.__spec__ = None
    try:
        yield
    finally:
        main.__dict__.update(saved)


class ScipyPipeline:
    """A pool of ``processes`` spawned single-threaded workers holding one
    :class:`ReferenceProblem`. Started (and warmed up) on construction; use as a context
    manager or :meth:`close`. :meth:`update` runs samples, split over the workers
    one sample at a time."""

    def __init__(self, problem: ReferenceProblem, processes: int = 2):
        ctx = multiprocessing.get_context("spawn")
        with _bare_main():
            self._pool = ctx.Pool(processes, initializer=_start_worker, initargs=(problem, ctx.Barrier(processes)))
        self.workers = self._pool.map(_ready, range(processes), chunksize=1)
        if any(w["jax_imported"] for w in self.workers):
            raise RuntimeError("a worker of the SciPy pipeline imported JAX")

    def update(self, theta0, f, phi, **variant) -> dict:
        """Samples (f (S, n_e) Hz, φ (S, n_s, n_e)) from θ_0; ``variant``: fields of the
        :class:`ReferenceProblem` to change (``standardise``, ``refine``, ``expansion``).
        **Returns:** ``alpha`` (S, p), ``iterations``, ``status`` (codes of ``STATUS``),
        ``change`` per sample."""
        theta0 = np.asarray(theta0, np.float64)
        tasks = [(theta0, np.asarray(f[j]), np.asarray(phi[j]), variant) for j in range(len(f))]
        out = self._pool.map(_update, tasks, chunksize=1)
        return {"alpha": np.expm1(np.stack([o["theta"] for o in out])),
                "iterations": np.array([o["iterations"] for o in out]),
                "status": np.array([o["status"] for o in out], np.int64),
                "change": np.array([o["change"] for o in out])}

    def close(self) -> None:
        self._pool.close()
        self._pool.join()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
