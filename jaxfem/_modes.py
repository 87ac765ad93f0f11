"""Normal modes of a model, including frequency-dependent (visco-elastic) stiffness.

Without a :class:`jaxfem.Viscoelastic` law this is ``eigh(*assemble(model), n)``. With
one, ``K(f) = K_0 + s(f) K_g`` with ``s(f) = a ln(f/f_ref)`` and every mode j solves its
own eigenproblem at its own frequency, ``K(f_j) φ_j = λ_j M φ_j`` with ``λ_j = (2π f_j)²``
(self-consistency, as for the thesis' silicone layer, §4.2.4.2). Each mode is found by
Newton's method on ``h(λ) = λ − μ_j(s(λ))`` in the Rayleigh–Ritz basis of the lowest
``n_basis`` modes Φ of ``(K_0, M)``: ``μ_j(s)`` is the j-th eigenvalue of
``Λ_0 + s ΦᵀK_gΦ``, and ``h'(λ) = 1 − (y_jᵀ ΦᵀK_gΦ y_j)·a/(2λ)``. The iterations carry no
derivative; one last Newton step does, which gives the implicit-function derivative
``dλ_j = dμ_j / h'(λ_j)`` exactly at the converged point.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._assembly import assemble
from ._eigen import eigh
from ._model import Model

_NEWTON = 4  # quadratic convergence: |Δλ|/λ < 1e-12 after 3 steps for |a| ≤ 0.3


def modes(model: Model, n_modes: int, *, n_basis: int | None = None
          ) -> tuple[Float[Array, " m"], Float[Array, "n m"]]:
    """Eigenvalues λ (rad/s)² and mass-normalised mode shapes of ``model``.

    **Arguments:** the model, the number of lowest modes, and for a frequency-dependent
    model the Ritz basis size (default ``n_modes + 40``, at most all modes).
    **Returns:** ``(λ, φ)`` as :func:`jaxfem.eigh`; differentiable in every model value,
    including the law's ``a`` and ``f_ref``.
    """
    K, M = assemble(model)
    law = model.viscoelastic
    if law is None:
        return eigh(K, M, n_modes)
    n_free = K.n - len(M.massless)
    n_b = min(n_free, n_basis or n_modes + 40)
    if n_b < n_modes:
        raise ValueError(f"n_basis = {n_b} < n_modes = {n_modes}")
    lam0, phi = eigh(K, M, n_b)
    layer = eqx.tree_at(
        lambda m: (m.beams.k_scale, m.rods.k_scale, m.springs.k_scale, m.bushes.k_scale), model,
        (model.beams.k_scale * law.beams, model.rods.k_scale * law.rods,
         model.springs.k_scale * law.springs, model.bushes.k_scale * law.bushes),
    )
    k_g = assemble(layer)[0]
    basis = _enrich(K, M, k_g, lam0, phi, n_modes)
    k_r, g, m_r = (basis.T @ a.matmul(basis) for a in (K, k_g, M))
    dropped = jnp.concatenate([jnp.zeros(n_b), jnp.all(basis[:, n_b:] == 0.0, axis=0)])
    k_r = k_r + jnp.diag(dropped * 1e6 * lam0[-1])  # unused enrichment directions → far above
    m_r = m_r + jnp.diag(dropped)
    n_r = basis.shape[1]

    def one(j):
        frozen = jax.lax.stop_gradient((law, k_r, g, m_r))
        chol = jnp.linalg.cholesky(frozen[3])

        def standard(a):
            b = jax.scipy.linalg.solve_triangular(chol, a, lower=True)
            return jax.scipy.linalg.solve_triangular(chol, b.T, lower=True)

        k_s, g_s = standard(frozen[1]), standard(frozen[2])

        def newton(lam, _):
            mu, y = jnp.linalg.eigh(k_s + _shift(frozen[0], lam) * g_s)
            slope = 1.0 - (y[:, j] @ g_s @ y[:, j]) * _shift_slope(frozen[0], lam)
            return lam - (lam - mu[j]) / slope, None

        lam_star, _ = jax.lax.scan(newton, jax.lax.stop_gradient(lam0[j]), None, length=_NEWTON)
        mu, y = eigh(k_r + _shift(law, lam_star) * g, m_r, n_r)
        slope = jax.lax.stop_gradient(1.0 - (y[:, j] @ g @ y[:, j]) * _shift_slope(law, lam_star))
        lam_j = lam_star - (lam_star - mu[j]) / slope  # differentiable Newton step (IFT)
        _, y = eigh(k_r + _shift(law, lam_j) * g, m_r, n_r)
        return lam_j, y[:, j]

    lam, y = jax.vmap(one)(jnp.arange(n_modes))
    shapes = basis @ y.T
    peak = jnp.take_along_axis(shapes, jnp.argmax(jnp.abs(shapes), axis=0)[None], axis=0)
    return lam, shapes * jax.lax.stop_gradient(jnp.sign(peak))  # largest component positive


def _floor(law):
    return (2 * jnp.pi * 1e-2 * law.f_ref) ** 2  # the law is held constant below f_ref/100


def _shift(law, lam):
    """s(f) = a ln(f/f_ref) at λ = (2π f)²."""
    return law.a * 0.5 * jnp.log(jnp.maximum(lam, _floor(law)) / (2 * jnp.pi * law.f_ref) ** 2)


def _shift_slope(law, lam):
    """ds/dλ = a / (2λ) (zero below the floor)."""
    return jnp.where(lam > _floor(law), law.a / (2 * jnp.maximum(lam, _floor(law))), 0.0)


def _enrich(K, M, k_g, lam0, phi, n_modes):
    """Ritz basis ``[Φ, Q]``: the modes plus the static responses ``(K + σM)⁻¹ K_g φ_j`` of
    the first ``n_modes`` modes to the layer's stiffness, M-orthogonalised against Φ and
    each other (a first-order correction of the truncated basis, exact for the shift of
    one mode's shape to first order in s). Directions without layer energy are zero."""
    kd, md = K.todense(), M.todense()
    sigma = jnp.maximum(lam0[n_modes - 1], 1.0)  # shift: K may be singular (free-free)
    r = jnp.linalg.solve(kd + sigma * md, k_g.matmul(phi[:, :n_modes]))
    r = r - phi @ (phi.T @ (md @ r))
    d, u = jax.lax.stop_gradient(jnp.linalg.eigh(r.T @ md @ r))
    keep = d > 1e-10 * jnp.max(d)
    q = r @ (u * jnp.where(keep, 1.0 / jnp.sqrt(jnp.where(keep, d, 1.0)), 0.0))
    return jnp.concatenate([phi, q], axis=1)
