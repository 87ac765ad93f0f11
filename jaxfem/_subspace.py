"""Lowest modes of a perturbed model by warm-started subspace iteration (Bathe & Wilson 1972).

Monte-Carlo and updating loops solve thousands of eigenproblems that are small
perturbations of one reference: a full LAPACK solve (all n modes, O(n³) with a large
constant) throws that away. :func:`subspace` starts from a basis of q ≥ m vectors close
to the wanted modes — the reference modes, or the previous iterate's — and repeats

    Y = V − S (K V − M V Μ)                 inverse iteration on the block
    K_r = YᵀKY, M_r = YᵀMY, K_r Q = M_r Q Μ  Rayleigh–Ritz,  V = Y Q

until every wanted Ritz vector passes the test ‖S r_r‖ ≤ tol ‖v_r‖ (r_r = K v_r − μ_r M v_r).
With S = (K − σM)⁻¹ (one Cholesky factorisation per solve) the first line is inverse
iteration, Y = S M V (Μ − σ), and mode r converges at the rate (λ_r − σ)/(λ_{q+1} − σ)
per sweep. With a fixed S ≈ (K − σM)⁻¹ of a nearby model (:func:`shifted_inverse`,
computed once for a whole batch of perturbed models) it is preconditioned inverse
iteration (Knyazev & Neymeyr 2003): no factorisation, every sweep is matrix products,
and the rate grows by about ‖I − S(K − σM)‖ — small for the perturbations of one study.
It carries no derivative: :func:`ritz_modes` picks converged modes from the result and
differentiates them exactly.

Derivative of a converged mode r (φ mass-normalised, g_r = (dK − λ_r dM) φ_r):

    dλ_r = φ_rᵀ g_r                                              thesis eq. 3.18
    dφ_r = Σ_{s≤m, s∉c(r)} φ_s (−φ_sᵀ g_r)/(λ_s − λ_r) − ½(φ_rᵀ dM φ_r) φ_r + z_r   eq. 3.23, eq. 3.28, eq. 3.29

with the sum over the m converged modes and z_r, M-orthogonal to them, the exact rest of
the modal expansion: (K − λ_r M) z_r = b_r, b_r = h_r − M Φ_m Φ_mᵀ h_r,
h_r = −g_r + dλ_r M φ_r. It is solved by preconditioned conjugate gradients (K − λ_r M
is positive definite on that complement) with B⁻¹ = U (Μ_u − λ_r)⁻¹ Uᵀ + P S Pᵀ (U: the
unconverged Ritz vectors, P: the projector M-orthogonal to the whole basis), whose
condition number is about (λ_{q+1} − σ)/(λ_{q+1} − λ_r) — the forward solve's S, no new
factorisation. Clusters of nearly
equal eigenvalues are handled as in :func:`jaxfem.eigh` (no rotation inside a cluster,
dλ the cluster mean).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float, Int

from . import _lapack
from ._eigen import (
    DEGENERATE_RTOL,
    _clusters,
    _operator,
    _signs,
    _tangent_matmul,
    _values_structure,
)
from ._model import Opaque


class Subspace(eqx.Module):
    """Result of :func:`subspace`: Ritz values ``lam`` (q,) ascending in (rad/s)², the
    M-orthonormal Ritz vectors ``basis`` (n, q) — the warm start of the next solve —,
    the inverse S it used: ``solver`` is the Cholesky factor of K − σM (``exact``), the
    fixed preconditioner, or a sparse factorisation (:func:`jaxfem.eigsh`), ``converged``  (all m wanted modes passed the test),
    ``residual`` (the largest test value), ``sweeps`` (inverse iterations done) and
    ``n_modes`` = m."""

    lam: Float[Array, " q"]
    basis: Float[Array, "n q"]
    solver: Float[Array, "n n"]
    converged: Bool[Array, ""]
    residual: Float[Array, ""]
    sweeps: Int[Array, ""]
    n_modes: int = eqx.field(static=True)
    exact: bool = eqx.field(static=True, default=True)

    def solve(self, r: Float[Array, "n k"]) -> Float[Array, "n k"]:
        """S r: (K − σM)⁻¹ r from the factor, or the preconditioner's approximation."""
        return _solve(self.solver, self.exact, r)


def _solve(solver, exact: bool, r):
    if not isinstance(solver, jax.Array):  # a host factorisation (jaxfem.eigsh)
        return solver.solve(r)
    return _lapack.cho_solve(solver, r) if exact else solver @ r


def _shifted_factor(K, M, shift: float):
    """Lower Cholesky factor of the dense K − σM (NaN where it is not positive definite)."""
    Kd = K.todense()
    return _lapack.cholesky(Kd - jnp.asarray(shift, Kd.dtype) * M.todense() if shift else Kd)


def _rayleigh_ritz(K, M, Y):
    """Ritz pairs of (K, M) on span Y: values ascending, vectors V M-orthonormal; and the
    residuals K V − M V Μ."""
    KY, MY = K.matmul(Y), M.matmul(Y)
    kr, mr = Y.T @ KY, Y.T @ MY
    lr = _lapack.cholesky(0.5 * (mr + mr.T))
    a = _lapack.solve_lower(lr, _lapack.solve_lower(lr, kr).T)
    mu, z = _lapack.eigh(0.5 * (a + a.T))
    q = _lapack.solve_upper(lr.T, z)
    return mu, Y @ q, KY @ q - (MY @ q) * mu


def shifted_inverse(K, M, *, shift: float = 0.0) -> Float[Array, "n n"]:
    """(K − σM)⁻¹ as a dense matrix: the fixed preconditioner of :func:`subspace` for
    models near (K, M) (one factorisation, n right-hand sides)."""
    K, M = _operator("K", K), _operator("M", M)
    factor = _shifted_factor(K, M, shift)
    inverse = _lapack.cho_solve(factor, jnp.eye(factor.shape[0], dtype=factor.dtype))
    return 0.5 * (inverse + inverse.T)


def subspace(K, M, start: Float[Array, "n q"], n_modes: int, *, shift: float = 0.0,
             tol: float = 1e-9, max_sweeps: int = 40, preconditioner: Float[Array, "n n"] | None = None
             ) -> Subspace:
    """Lowest ``n_modes`` modes of ``K φ = λ M φ`` by subspace iteration from ``start``.

    **Arguments:** K (positive definite after the shift), M (positive definite), as arrays
    or :class:`jaxfem.ElementMatrix`; ``start``: q > n_modes vectors near the wanted modes
    (e.g. the reference modes, or ``basis`` of a previous solve); ``shift`` σ below the
    lowest eigenvalue (negative for a free structure); ``tol``: test on each wanted mode;
    ``max_sweeps``: the cap — the caller falls back to a full solve when ``converged`` is
    False; ``preconditioner``: a fixed S ≈ (K − σM)⁻¹ (:func:`shifted_inverse` of a nearby
    model) in place of a factorisation of K − σM.

    **Returns:** :class:`Subspace`; no derivative flows through it (see :func:`ritz_modes`).
    """
    K, M = _operator("K", K), _operator("M", M)
    if len(M.massless):
        raise ValueError("subspace iteration needs a mass on every DoF; use jaxfem.eigh for massless DoFs")
    q = start.shape[1]
    if not 1 <= n_modes < q:
        raise ValueError(f"need 1 ≤ n_modes < q basis vectors, got n_modes = {n_modes}, q = {q}")
    K, M, start, preconditioner = jax.lax.stop_gradient((K, M, start, preconditioner))
    exact = preconditioner is None
    solver = _shifted_factor(K, M, shift) if exact else preconditioner

    def test(V, R):
        step = _solve(solver, exact, R)
        err = jnp.linalg.norm(step[:, :n_modes], axis=0) / jnp.linalg.norm(V[:, :n_modes], axis=0)
        return V - step, jnp.max(err)

    def cond(carry):
        k, *_, err = carry
        return (k < max_sweeps) & ~(err <= tol)  # NaN (indefinite K − σM) stops too

    def body(carry):
        k, _, _, Y, _ = carry
        mu, V, R = _rayleigh_ritz(K, M, Y)
        return (k + 1, mu, V, *test(V, R))

    mu, V, R = _rayleigh_ritz(K, M, start / jnp.linalg.norm(start, axis=0))
    k, mu, V, _, err = jax.lax.while_loop(cond, body, (jnp.asarray(0), mu, V, *test(V, R)))
    V = V * _signs(V)
    return Subspace(mu, V, solver, err <= tol, err, k, n_modes, exact)


def dense_modes(K, M, n_modes: int, *, shift: float = 0.0) -> Subspace:
    """All modes of ``K φ = λ M φ`` by one dense LAPACK solve, as a :class:`Subspace` for
    :func:`ritz_modes` (the full-solve reference of warm-started subspace iteration).

    The problem is standardised with the Cholesky factor of K − σM = L Lᵀ:
    (L⁻¹ M L⁻ᵀ) y = ν y, λ = σ + 1/ν, φ = L⁻ᵀ y / √ν. The lowest modes are the largest ν
    and come out to relative accuracy ε; standardising with M (:func:`jaxfem.eigh`)
    loses ε λ_max/λ_1 on them (eigen-residuals 1e-8 on the tree, λ_max/λ_1 = 8e8). The
    lowest 2m modes are refined by one sweep of inverse iteration.
    """
    K, M = _operator("K", K), _operator("M", M)
    if len(M.massless):
        raise ValueError("the K-standardised solve needs a mass on every DoF; use jaxfem.eigh for massless DoFs")
    K, M = jax.lax.stop_gradient((K, M))
    Md = M.todense()
    factor = _shifted_factor(K, M, shift)
    a = _lapack.solve_lower(factor, _lapack.solve_lower(factor, Md).T)
    nu, y = _lapack.eigh(0.5 * (a + a.T))
    nu, y = nu[::-1], y[:, ::-1]
    lam, V = shift + 1.0 / nu, _lapack.solve_upper(factor.T, y) / jnp.sqrt(nu)
    # The back substitution leaves errors of ε·√cond(K) in φ (1e-10 on the tree, enough
    # to make updates jitter at 1e-8): one sweep of inverse iteration in residual form,
    # V − (K − σM)⁻¹ (K V − M V Λ), on the lowest 2m modes removes them (the correction
    # is itself that small, so its own rounding is negligible).
    p = min(lam.shape[0], 2 * n_modes)
    R = K.matmul(V[:, :p]) - M.matmul(V[:, :p]) * lam[:p]
    mu, Vp, _ = _rayleigh_ritz(K, M, V[:, :p] - _lapack.cho_solve(factor, R))
    lam, V = lam.at[:p].set(mu), V.at[:, :p].set(Vp)
    one = jnp.asarray(True)
    return Subspace(lam, V * _signs(V), factor, one, jnp.zeros((), Md.dtype), jnp.asarray(0), n_modes, True)


def ritz_modes(K, M, solution: Subspace, index: Int[Array, " k"], *, rtol: float = DEGENERATE_RTOL,
               refine_tol: float = 1e-12, max_refine: int = 50
               ) -> tuple[Float[Array, " k"], Float[Array, "n k"]]:
    """The converged modes ``index`` (< ``solution.n_modes``) of a :func:`subspace` solve,
    ``(λ, φ)``, with exact derivatives in the values of K and M (module documentation).

    The values are those of ``solution`` (computed without derivative); forward-mode
    derivatives (``jax.jvp``, ``jax.jacfwd``) solve the rest of the modal expansion with
    the solution's factorisation, to a relative change ≤ ``refine_tol`` or
    ``max_refine`` sweeps.
    """
    K, M = _operator("K", K), _operator("M", M)
    (kv, ks), (mv, ms) = _values_structure(K), _values_structure(M)
    return _ritz(kv, mv, solution=jax.lax.stop_gradient(solution), index=jnp.asarray(index),
                 structure=Opaque((ks, ms)), rtol=float(rtol), refine_tol=float(refine_tol),
                 max_refine=int(max_refine))


@eqx.filter_custom_jvp
def _ritz(kv, mv, *, solution, index, structure, rtol, refine_tol, max_refine):
    return solution.lam[index], solution.basis[:, index]


@_ritz.def_jvp
def _ritz_jvp(primals, tangents, *, solution, index, structure, rtol, refine_tol, max_refine):
    ks, ms = structure.value
    K, M = eqx.combine(primals[0], ks), eqx.combine(primals[1], ms)
    dK, dM = tangents
    m = solution.n_modes
    lam, V = solution.lam, solution.basis
    lam_m, phi_m = lam[:m], V[:, :m]
    gk, gm = _tangent_matmul(K, dK, phi_m), _tangent_matmul(M, dM, phi_m)
    # Eigenvalue derivatives, eq. 3.18, cluster means as in jaxfem.eigh.
    cluster = _clusters(lam_m, rtol)
    same = cluster[:, None] == cluster[None, :]
    d = jnp.sum(phi_m * (gk - lam_m * gm), axis=0)
    dlam_m = (same.astype(d.dtype) @ d) / same.sum(axis=1).astype(d.dtype)
    # Modal expansion over the converged modes, eq. 3.23, eq. 3.28, eq. 3.29.
    lam_r, phi_r = lam_m[index], phi_m[:, index]
    g = gk[:, index] - lam_r * gm[:, index]
    h = -g + dlam_m[index] * M.matmul(phi_r)
    c = phi_m.T @ h
    same_r = same[:, index]
    denom = lam_m[:, None] - lam_r[None, :]
    coef = jnp.where(same_r, 0.0, c / jnp.where(same_r, 1.0, denom))
    own = jnp.arange(m, dtype=index.dtype)[:, None] == index[None, :]
    coef = jnp.where(own, -0.5 * jnp.sum(phi_r * gm[:, index], axis=0)[None, :], coef)
    dphi = phi_m @ coef
    # The rest z_r, M-orthogonal to the converged modes: (K − λ_r M) z_r = b_r.
    z = _rest(K, M, solution, lam_r, h - M.matmul(phi_m @ c), refine_tol, max_refine)
    return (lam_r, phi_r), (dlam_m[index], dphi + z)


def _rest(K, M, solution, lam_r, b, refine_tol, max_refine):
    """The part z_r of each mode derivative outside the converged modes, M-orthogonal to
    them: (K − λ_r M) z_r = b_r, by preconditioned conjugate gradients (a host factor's
    own solve where the solution has one), as a transposable symmetric linear solve."""
    m = solution.n_modes
    lam, V = solution.lam, solution.basis
    U, lam_u = V[:, m:], lam[m:]

    def precondition(r):
        coarse = U @ ((U.T @ r) / (lam_u[:, None] - lam_r[None, :]))
        rp = r - M.matmul(V @ (V.T @ r))
        x = solution.solve(rp)
        return coarse + x - V @ (V.T @ M.matmul(x))

    def operator(z):
        return K.matmul(z) - lam_r * M.matmul(z)

    def ratio(num, den):
        return jnp.where(den != 0, num / jnp.where(den != 0, den, 1.0), 0.0)

    def cond(carry):
        k, *_, step = carry
        return (k < max_refine) & (step > refine_tol)

    def body(carry):  # one step of preconditioned conjugate gradients per column
        k, z, res, p, ry, _ = carry
        ap = operator(p)
        alpha = ratio(ry, jnp.sum(p * ap, axis=0))
        dz = alpha * p
        z, res = z + dz, res - alpha * ap
        y = precondition(res)
        ry_new = jnp.sum(res * y, axis=0)
        scale = jnp.maximum(jnp.max(jnp.abs(z)), jnp.finfo(z.dtype).tiny)
        return k + 1, z, res, y + ratio(ry_new, ry) * p, ry_new, jnp.max(jnp.abs(dz)) / scale

    def solve(_, b):
        if hasattr(solution.solver, "rest"):  # a host factorisation solves it on the host
            return solution.solver.rest(b, lam_r, V, lam, refine_tol, max_refine)
        y0 = precondition(b)
        start = (jnp.asarray(0), jnp.zeros_like(b), b, y0, jnp.sum(b * y0, axis=0), jnp.asarray(jnp.inf, b.dtype))
        return jax.lax.while_loop(cond, body, start)[1]

    # a symmetric linear solve: transposable, so that reverse mode (jax.grad) works too
    return jax.lax.custom_linear_solve(operator, b, solve, symmetric=True)
