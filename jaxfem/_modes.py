"""Normal modes of a model, including frequency-dependent (visco-elastic) stiffness.

Without a :class:`jaxfem.Viscoelastic` law this is ``eigh(*assemble(model), n)``. With
one, ``K(f) = K_0 + s(f) K_g`` with ``s(f) = a ln(f/f_ref)`` and every mode j solves its
own eigenproblem at its own frequency, ``K(f_j) φ_j = λ_j M φ_j`` with ``λ_j = (2π f_j)²``
(self-consistency, as for the thesis' silicone layer, §4.2.4.2). Each mode is found by
Newton's method on ``h(λ) = λ − μ_j(s(λ))``, ``h'(λ) = 1 − (y_jᵀ G y_j)·a/(2λ)``, where
``μ_j(s)``, ``y_j`` are the j-th eigenpair of the Rayleigh–Ritz problem
``(K_r + s G, M_r)`` on the basis of the lowest modes of ``(K_0, M)`` enriched with their
static responses to ``K_g`` (``G = BᵀK_gB``). The iterations carry no derivative. The
returned values are written so that their value is the converged one and their first
derivative is exact: λ_j as one more Newton step on the (stationary) Rayleigh quotient —
the implicit-function derivative ``dλ_j = ∂μ_j/∂p / h'`` — and y_j as the first-order
modal expansion in the reduced space (Fox & Kapoor 1968), with no rotation inside
clusters of nearly equal μ (as :func:`jaxfem.eigh`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from ._assembly import assemble
from ._eager import compiled_when_eager
from ._eigen import DEGENERATE_RTOL, eigh
from ._model import STIFFNESS_BLOCKS, Model
from ._shift_invert import eigsh

_NEWTON = 4  # Newton steps; quadratic convergence, |Δλ|/λ < 1e-12 after 3 for |a| ≤ 0.3


SOLVERS = ("auto", "dense", "sparse")
SPARSE_ABOVE = 5000  # DoFs above which solver="auto" takes the sparse eigensolver


def use_sparse(model: Model, solver: str = "auto") -> bool:
    """Whether ``solver`` (``"auto"``, ``"dense"``, ``"sparse"``) means the sparse path for
    ``model``: ``"auto"`` takes it above :data:`SPARSE_ABOVE` DoFs, except for a
    frequency-dependent (visco-elastic) model, which only the dense path solves."""
    if solver not in SOLVERS:
        raise ValueError(f"eigensolver must be one of {', '.join(SOLVERS)}, got {solver!r}")
    if solver == "sparse" and model.viscoelastic is not None:
        raise ValueError("a frequency-dependent (visco-elastic) model needs the dense eigensolver")
    return solver == "sparse" or (solver == "auto" and model.viscoelastic is None and model.n_dof > SPARSE_ABOVE)


@compiled_when_eager
def modes(model: Model, n_modes: int, *, n_basis: int | None = None, solver: str = "auto"
          ) -> tuple[Float[Array, " m"], Float[Array, "n m"]]:
    """Eigenvalues λ (rad/s)² and mass-normalised mode shapes of ``model``.

    **Arguments:** the model, the number of lowest modes, for a frequency-dependent
    model the Ritz basis size (default ``n_modes + 10``, at most all modes; enriched
    with static corrections, see ``_enrich``), and the eigensolver: ``"dense"``
    (:func:`jaxfem.eigh`, all modes), ``"sparse"`` (:func:`jaxfem.eigsh`, shift-invert
    Lanczos) or ``"auto"`` (sparse above :data:`SPARSE_ABOVE` DoFs, see :func:`use_sparse`).
    **Returns:** ``(λ, φ)`` as :func:`jaxfem.eigh`; differentiable in every model value,
    including the law's ``a`` and ``f_ref``.
    """
    K, M = assemble(model)
    law = model.viscoelastic
    if use_sparse(model, solver):
        return eigsh(K, M, n_modes)
    if law is None:
        return eigh(K, M, n_modes)
    n_free = K.n - len(M.massless)
    n_b = min(n_free, n_basis or n_modes + 10)
    if n_b < n_modes:
        raise ValueError(f"n_basis = {n_b} < n_modes = {n_modes}")
    lam0, phi = eigh(K, M, n_b)
    layer = model
    for name, w in zip(STIFFNESS_BLOCKS, law.weights):
        layer = eqx.tree_at(lambda m, name=name: getattr(m, name).k_scale, layer, getattr(model, name).k_scale * w)
    k_g = assemble(layer)[0]
    basis = _enrich(K, M, k_g, lam0, phi, n_modes)
    k_r, g, m_r = (basis.T @ a.matmul(basis) for a in (K, k_g, M))
    dropped = jnp.concatenate([jnp.zeros(n_b), jnp.all(basis[:, n_b:] == 0.0, axis=0).astype(jnp.float64)])
    k_r = k_r + jnp.diag(dropped * 1e6 * lam0[-1])  # unused enrichment directions → far above
    m_r = m_r + jnp.diag(dropped)
    n_r = basis.shape[1]

    frozen = jax.lax.stop_gradient((law, k_r, g, m_r))
    chol = jnp.linalg.cholesky(frozen[3])

    def standard(a):
        b = jax.scipy.linalg.solve_triangular(chol, a, lower=True)
        return jax.scipy.linalg.solve_triangular(chol, b.T, lower=True)

    k_s, g_s = standard(frozen[1]), standard(frozen[2])

    def one(j):
        def newton(lam, _):
            mu, z = jnp.linalg.eigh(jnp.nan_to_num(k_s + _shift(frozen[0], lam) * g_s))
            slope = jnp.maximum(1.0 - (z[:, j] @ g_s @ z[:, j]) * _shift_slope(frozen[0], lam), 0.2)
            new = lam - (lam - mu[j]) / slope
            return jnp.where(jnp.isfinite(new), new, lam), None  # damped, never leaves the reals

        lam_star, _ = jax.lax.scan(newton, frozen[1][j, j] / frozen[3][j, j], None, length=_NEWTON)
        mu, z = jnp.linalg.eigh(jnp.nan_to_num(k_s + _shift(frozen[0], lam_star) * g_s))
        y = jax.scipy.linalg.solve_triangular(chol.T, z, lower=False)  # M_r-orthonormal
        yj = y[:, j]
        # λ: Rayleigh quotient at fixed s (stationary: exact first derivative), then the
        # implicit-function Newton step through s(λ)
        rq = yj @ (k_r + _shift(law, lam_star) * g) @ yj / (yj @ m_r @ yj)
        slope = jnp.maximum(1.0 - (yj @ frozen[2] @ yj) * _shift_slope(frozen[0], lam_star), 0.2)
        lam_j = lam_star - (lam_star - rq) / slope
        # φ: first-order modal expansion in the reduced space; its value is exactly y_j
        gap = mu[j] - mu
        apart = jnp.abs(gap) > DEGENERATE_RTOL * jnp.abs(mu[j])  # clusters: no rotation
        r = (k_r + _shift(law, lam_j) * g - mu[j] * m_r) @ yj
        coef = jnp.where(apart, (y.T @ r) / jnp.where(apart, gap, 1.0), 0.0)
        return lam_j, yj + y @ coef - 0.5 * yj * (yj @ (m_r - frozen[3]) @ yj)

    lam, y = jax.lax.map(one, jnp.arange(n_modes))  # one mode at a time: a native XLA-CPU crash was seen with vmap here
    shapes = basis @ y.T
    peak = jnp.take_along_axis(shapes, jnp.argmax(jnp.abs(shapes), axis=0)[None], axis=0)
    return lam, shapes * jax.lax.stop_gradient(jnp.sign(peak))  # largest component positive


def _floor(law):
    return (2 * jnp.pi * 1e-2 * law.f_ref) ** 2  # the law is held constant below f_ref/100


_S_RANGE = (-0.9, 9.0)  # the law's factor 1 + s is held within [0.1, 10]


def _raw_shift(law, lam):
    return law.a * 0.5 * jnp.log(jnp.maximum(lam, _floor(law)) / (2 * jnp.pi * law.f_ref) ** 2)


def _shift(law, lam):
    """s(f) = a ln(f/f_ref) at λ = (2π f)², limited to :data:`_S_RANGE`."""
    return jnp.clip(_raw_shift(law, lam), *_S_RANGE)


def _shift_slope(law, lam):
    """ds/dλ = a / (2λ) (zero below the floor and where s is limited)."""
    inside = (lam > _floor(law)) & (_raw_shift(law, lam) > _S_RANGE[0]) & (_raw_shift(law, lam) < _S_RANGE[1])
    return jnp.where(inside, law.a / (2 * jnp.maximum(lam, _floor(law))), 0.0)


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
