"""Generalised symmetric eigenproblem ``K φ = λ M φ`` with implicit-differentiation JVP.

Forward: massless DoFs (structurally zero rows of M) are condensed statically
(exact for them), ``K* = K_aa − K_ab K_bb⁻¹ K_ba``; then ``K* + σM_aa = L Lᵀ`` reduces
the problem to the standard one ``L⁻¹ M_aa L⁻ᵀ z = μ z``, ``μ = 1/(λ + σ)``, solved by
LAPACK through ``jnp.linalg.eigh``; ``φ_a = L⁻ᵀ z / √μ``. In this inverse form the lowest
modes are the largest μ and keep full relative accuracy even when the highest modes are
10¹² times stiffer (rotary inertia of thin shells: the direct form ``M = LLᵀ`` lost 10⁻⁶
there). σ is the smallest ``K_ii/M_ii``. All modes are computed, so the derivative rule
can use the complete modal expansion.

Derivative rule (all quantities at the solution, φ mass-normalised, full length):

    g_r  = (dK − λ_r dM) φ_r
    dλ_r = φ_rᵀ g_r                                             thesis eq. 3.18
    dφ_r = Σ_{s≠r} φ_s (−φ_sᵀ g_r)/(λ_s − λ_r)                  eq. 3.23, eq. 3.28
           − ½ (φ_rᵀ dM φ_r) φ_r                                 eq. 3.29
           − [0; K_bb⁻¹ (g_r)_b]                                 static part on massless DoFs

The last term is exact for massless DoFs: writing dφ = Φc + [0; w], the rows of
(K − λ_r M) dφ = −g_r + dλ_r M φ_r on the massless DoFs give K_bb w = −(g_r)_b, and the
remaining rows reduce to the expansion above with the full-length vectors.

Degenerate policy: modes whose eigenvalues differ by less than ``rtol·max(|λ_r|, |λ_s|)
+ atol`` (``atol = 10⁻⁸·max|λ|`` over the returned modes, which groups the rigid-body
modes, whose computed values are rounding noise; not over the whole spectrum, whose
stiff penalty modes would group distinct modes) form a cluster. Within a cluster the
eigenvectors are not unique, so the rule sets their mutual rotation coefficients to
zero: the derivative of the cluster's spectral projector (and of anything invariant to
the basis inside the cluster) is exact, and no division by a vanishing gap can occur.
Eigenvalue derivatives in a cluster come from the degenerate-subspace eigenproblem of
``D_rs = φ_rᵀ (dK − λ̄ dM) φ_s``: ``degenerate="mean"`` (default) returns for each
member the mean of its eigenvalues — the exact derivative of the cluster mean, linear in
the tangent and so valid in reverse mode (``jax.grad``); ``degenerate="split"`` returns
the sorted eigenvalues of D — the one-sided directional derivatives of the sorted
eigenvalues, valid in forward mode only (``jax.jvp``, ``jax.jacfwd``); under
``jax.grad`` it raises ``NotImplementedError`` pointing to ``"mean"``.
"""

from __future__ import annotations

import os
from typing import Literal, NamedTuple

import equinox as eqx
import jax
import jax.extend
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
from jax.interpreters import ad, batching, mlir
from jaxtyping import Array, Float

from ._eager import compiled_when_eager
from ._matrix import AbstractSymmetricMatrix, DenseMatrix
from ._model import Opaque, check_float64

DEGENERATE_RTOL = 1e-6


def _operator(name: str, a) -> AbstractSymmetricMatrix:
    if not isinstance(a, AbstractSymmetricMatrix):
        a = jnp.asarray(a)
        if a.ndim != 2 or a.shape[0] != a.shape[1]:
            raise ValueError(f"{name} must be a square matrix, got shape {a.shape}")
        a = DenseMatrix(a)
    check_float64(name, a.values())
    return a


def eigh(
    K,
    M,
    n_modes: int | None = None,
    *,
    degenerate: Literal["mean", "split"] = "mean",
    rtol: float = DEGENERATE_RTOL,
) -> tuple[Float[Array, " m"], Float[Array, "n m"]]:
    """Lowest modes of ``K φ = λ M φ`` (thesis eq. 1.33), differentiable.

    **Arguments:**
    - ``K``, ``M``: symmetric matrices (arrays or :class:`jaxfem.ElementMatrix` from
      :func:`jaxfem.assemble`); K positive semidefinite, M positive definite on all DoFs
      except those listed in ``M.massless``.
    - ``n_modes``: number of lowest modes returned (default: all with mass).
    - ``degenerate``, ``rtol``: policy and relative threshold for clusters of (nearly)
      repeated eigenvalues; see the module documentation.

    **Returns:** ``(λ, Φ)``: eigenvalues λ = ω² in (rad/s)², ascending, and
    mass-normalised eigenvectors (ΦᵀMΦ = I) as columns, each signed so that its
    largest-magnitude component is positive.
    """
    K, M = _operator("K", K), _operator("M", M)
    if K.n != M.n:
        raise ValueError(f"K is {K.n}×{K.n} but M is {M.n}×{M.n}")
    n_free = M.n - len(M.massless)
    n_modes = n_free if n_modes is None else int(n_modes)
    if not 1 <= n_modes <= n_free:
        raise ValueError(f"n_modes must be in 1..{n_free} (DoFs with mass), got {n_modes}")
    if degenerate not in ("mean", "split"):
        raise ValueError(f"degenerate must be 'mean' or 'split', got {degenerate!r}")
    _check_memory(K.n)
    (kv, ks), (mv, ms) = _values_structure(K), _values_structure(M)
    return _eigh_of(kv, mv, ks, ms, n_modes, degenerate, float(rtol))


@compiled_when_eager
def _eigh_of(kv, mv, ks, ms, n_modes: int, degenerate: str, rtol: float):
    return _eigh(kv, mv, structure=Opaque((ks, ms)), n_modes=n_modes, degenerate=degenerate, rtol=rtol)


DENSE_ARRAYS = 8  # n × n float64 arrays alive at once in the dense solve and its JVP (an estimate)


def _check_memory(n: int) -> None:
    """Refuse a dense problem whose n × n arrays would not fit in 80 % of the physical memory."""
    need = DENSE_ARRAYS * 8.0 * n * n
    try:
        have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return
    if need > 0.8 * have:
        raise MemoryError(
            f"the dense eigensolver needs about {need / 2**30:.0f} GiB for {n} DoFs "
            f"({DENSE_ARRAYS} arrays of {n}²), more than 80 % of this machine's {have / 2**30:.0f} GiB"
        )


def _values_structure(a: AbstractSymmetricMatrix):
    return eqx.partition(a, lambda x: isinstance(x, jax.Array))


class _Eig(NamedTuple):
    """All modes with mass, as ``φ_a = L⁻ᵀ y`` with L the Cholesky factor of K* + σM_aa."""

    lam: Array  # (na,)
    y: Array  # (na, na): Z diag(μ^-½), Z orthonormal
    lm: Array  # Cholesky factor L of K* + σ M_aa (of the condensed problem)
    lb: Array | None  # Cholesky factor of K_bb (massless block)
    x: Array | None  # K_bb⁻¹ K_ba, so that φ_b = −x φ_a
    a: np.ndarray  # DoFs with mass
    b: np.ndarray  # massless DoFs


def _solve(K: AbstractSymmetricMatrix, M: AbstractSymmetricMatrix) -> _Eig:
    kd, md = K.todense(), M.todense()
    b = np.asarray(M.massless, dtype=np.int64)
    a = np.setdiff1d(np.arange(K.n), b)
    if len(b):
        kbb = kd[np.ix_(b, b)]
        lb = jnp.linalg.cholesky(kbb)
        lb = eqx.error_if(
            lb,
            ~jnp.all(jnp.isfinite(lb)),
            "stiffness of the massless DoFs is not positive definite (a mechanism)",
        )
        x = jsl.cho_solve((lb, True), kd[np.ix_(b, a)])
        ks = kd[np.ix_(a, a)] - kd[np.ix_(a, b)] @ x
        maa = md[np.ix_(a, a)]
    else:
        lb, x, ks, maa = None, None, kd, md
    sigma = _shift(ks, maa)
    lk = jnp.linalg.cholesky(ks + sigma * maa)
    lk = eqx.error_if(
        lk,
        ~jnp.all(jnp.isfinite(lk)),
        "K + σM is not positive definite: the stiffness has negative eigenvalues (a negative "
        "spring or modulus?), or the mass is indefinite, or massless DoFs are not declared in "
        "M.massless, or K has NaN or inf entries",
    )
    half = jsl.solve_triangular(lk, maa, lower=True)
    inverse = jsl.solve_triangular(lk, half.T, lower=True)
    mu, z = jnp.linalg.eigh(0.5 * (inverse + inverse.T))
    mu, z = mu[::-1], z[:, ::-1]
    mu = jnp.maximum(mu, jnp.finfo(mu.dtype).eps * mu[0])  # beyond the factor's precision: far above
    return _Eig(1.0 / mu - sigma, z / jnp.sqrt(mu), lk, lb, x, a, b)


def _shift(k: Array, m: Array) -> Array:
    """σ for the inverse form: the smallest ``K_ii/M_ii`` over DoFs with stiffness (a
    Rayleigh quotient, so σ ≥ λ₁; for structures it lies within a few decades of λ₁)."""
    ratio = jnp.where(jnp.diagonal(k) > 0, jnp.diagonal(k) / jnp.diagonal(m), jnp.inf)
    sigma = jnp.min(ratio)
    return jax.lax.stop_gradient(jnp.where(jnp.isfinite(sigma), sigma, 1.0))


def _full(e: _Eig, v: Array) -> Array:
    """Full-length physical vectors from standardised ones: φ_a = L⁻ᵀ v, φ_b = −x φ_a."""
    pa = jsl.solve_triangular(e.lm.T, v, lower=False)
    if not len(e.b):
        return pa
    inverse = np.argsort(np.concatenate([e.a, e.b]))  # a gather: transposable for jax.grad
    return jnp.concatenate([pa, -e.x @ pa])[inverse]


def _dual(e: _Eig, g: Array) -> Array:
    """``Φᵀ g`` for all modes, with Φ the full-length (unsigned) eigenvectors."""
    ga = g[e.a] - e.x.T @ g[e.b] if len(e.b) else g
    return e.y.T @ jsl.solve_triangular(e.lm, ga, lower=True)


def _signs(phi: Array) -> Array:
    """±1 per column so that the largest-magnitude component becomes positive."""
    big = jnp.take_along_axis(phi, jnp.argmax(jnp.abs(phi), axis=0)[None], axis=0)
    return jnp.where(big[0] < 0, -1.0, 1.0)


RIGID_ATOL = 1e-8  # × the largest returned λ (rigid-body modes came out at ±3e-4 beside 4e6)


def _clusters(lam: Float[Array, " k"], rtol: float, returned: int | None = None) -> Array:
    """Cluster index of each sorted eigenvalue (consecutive, transitive); the absolute
    threshold from the first ``returned`` of them (None: all), module docstring."""
    atol = RIGID_ATOL * jnp.max(jnp.abs(lam[:returned]))
    gap = jnp.diff(lam)
    scale = jnp.maximum(jnp.abs(lam[1:]), jnp.abs(lam[:-1]))
    new = gap > rtol * scale + atol
    return jnp.concatenate([jnp.zeros(1, jnp.int32), jnp.cumsum(new.astype(jnp.int32))])


def _tangent_matmul(A: AbstractSymmetricMatrix, dA, x: Array) -> Array:
    """``dA @ x`` for a tangent of A given as a pytree with None for symbolic zeros."""
    if dA is None:
        return jnp.zeros_like(x)
    values = jax.tree.map(
        lambda p, t: jnp.zeros_like(p) if t is None else t,
        A.values(),
        dA.values(),
        is_leaf=lambda t: t is None,
    )
    return A.with_values(values).matmul(x)


@eqx.filter_custom_jvp
def _eigh(kv, mv, *, structure, n_modes, degenerate, rtol):
    ks, ms = structure.value
    e = _solve(eqx.combine(kv, ks), eqx.combine(mv, ms))
    phi = _full(e, e.y[:, :n_modes])
    return e.lam[:n_modes], phi * _signs(phi)


@_eigh.def_jvp
def _eigh_jvp(primals, tangents, *, structure, n_modes, degenerate, rtol):
    ks, ms = structure.value
    K, M = eqx.combine(primals[0], ks), eqx.combine(primals[1], ms)
    dK, dM = tangents
    e = _solve(K, M)
    lam = e.lam
    m = n_modes
    m_ext = min(lam.shape[0], m + 6)  # clusters reaching past the returned modes
    pe = _full(e, e.y[:, :m_ext])
    sign = _signs(pe)
    pe = pe * sign
    gk = _tangent_matmul(K, dK, pe)
    gm = _tangent_matmul(M, dM, pe)
    g = gk - gm * lam[:m_ext]  # columns g_r = (dK − λ_r dM) φ_r
    cluster = _clusters(lam, rtol, m)
    ce = cluster[:m_ext]
    same_e = ce[:, None] == ce[None, :]
    # Degenerate-subspace matrix D_rs = φ_rᵀ (dK − ½(λ_r+λ_s) dM) φ_s within clusters.
    d = pe.T @ gk - 0.5 * (lam[:m_ext, None] + lam[None, :m_ext]) * (pe.T @ gm)
    d = jnp.where(same_e, 0.5 * (d + d.T), 0.0)
    if degenerate == "mean":
        dlam = (same_e.astype(d.dtype) @ jnp.diagonal(d)) / same_e.sum(axis=1).astype(d.dtype)
    else:
        dlam = jax.lax.cond(
            jnp.any(same_e.sum(axis=1) > 1),
            lambda: _forward_only_p.bind(_split_clusters(d, ce)),
            lambda: jnp.diagonal(d),
        )
    dlam = dlam[:m]
    # Eigenvector derivatives by the complete modal expansion, eq. 3.23, eq. 3.28, eq. 3.29; the
    # sums over s are formed in the standardised space (Φ = L⁻ᵀY), whose column signs
    # cancel in φ_s φ_sᵀ except for the s = r term.
    c = -_dual(e, g[:, :m])  # φ_sᵀ h_r for s ≠ r
    same = cluster[:, None] == cluster[None, :m]
    denom = lam[:, None] - lam[None, :m]
    coef = jnp.where(same, 0.0, c / jnp.where(same, 1.0, denom))
    c_rr = -0.5 * jnp.sum(pe[:, :m] * gm[:, :m], axis=0) * sign[:m]
    diag = np.arange(lam.shape[0])[:, None] == np.arange(m)[None, :]
    coef = jnp.where(diag, c_rr[None, :], coef)
    dphi = _full(e, e.y @ coef)
    if len(e.b):
        dphi = dphi.at[e.b].add(-jsl.cho_solve((e.lb, True), g[e.b, :m]))
    return (lam[:m], pe[:, :m]), (dlam, dphi)


# degenerate="split" returns eigenvalues of the tangent matrix D: not linear in the tangent,
# so it has no reverse mode. jax.grad transposes the JVP from its outputs back, and this
# identity, applied to those tangents, is reached before the eigenvalue solve whose
# transpose JAX lacks: it says what to use instead of "Transpose rule for 'eigh' not
# implemented".
SPLIT_REVERSE_MODE = (
    "eigh(degenerate='split') gives one-sided directional derivatives of repeated eigenvalues, which "
    "exist in forward mode only (jax.jvp, jax.jacfwd, jax.linearize without transposing); for jax.grad, "
    "jax.vjp or jax.jacrev use degenerate='mean' (the default: the exact derivative of each cluster's mean)"
)


def _no_transpose(cotangent, x):
    raise NotImplementedError(SPLIT_REVERSE_MODE)


_forward_only_p = jax.extend.core.Primitive("jaxfem_split_eigenvalue_tangent")
_forward_only_p.def_impl(lambda x: x)
_forward_only_p.def_abstract_eval(lambda x: x)
mlir.register_lowering(_forward_only_p, lambda ctx, x: [x])
batching.defvectorized(_forward_only_p)
ad.deflinear2(_forward_only_p, _no_transpose)


def _split_clusters(d: Array, cluster: Array) -> Array:
    """Sorted eigenvalues of each diagonal cluster block of ``d``, in cluster order."""
    spacing = 2.0 * jnp.linalg.norm(d) + 1.0
    shift = spacing * cluster.astype(d.dtype)
    w = jnp.linalg.eigvalsh(d + jnp.diag(shift))
    return w - shift


def nelson(
    K: Float[Array, "n n"],
    M: Float[Array, "n n"],
    lam: Float[Array, ""],
    phi: Float[Array, " n"],
    dK: Float[Array, "n n"],
    dM: Float[Array, "n n"],
) -> tuple[Float[Array, ""], Float[Array, " n"]]:
    """Derivative of one simple eigenpair by Nelson's method, using mode r only.

    Nelson (1976), AIAA J. 14(9); thesis eq. 3.15, eq. 3.18. With ``f = −(dK − λ dM −
    dλ M) φ``, solve ``(K − λM) v = f`` with the component k of largest |φ_k| held at
    zero (this removes the singularity), then add ``c φ`` with ``c = −φᵀMv − ½φᵀ dM φ``
    to keep the mass normalisation. Works with singular M (massless DoFs).

    **Arguments:** dense K, M; a mass-normalised eigenpair ``(λ, φ)``; tangents dK, dM.
    **Returns:** ``(dλ, dφ)``.
    """
    for name, x in (("K", K), ("M", M), ("dK", dK), ("dM", dM)):
        check_float64(name, x)
    g = (dK - lam * dM) @ phi
    dlam = phi @ g
    f = -(g - dlam * (M @ phi))
    k = jnp.argmax(jnp.abs(phi))
    a = K - lam * M
    unit = jnp.arange(phi.shape[0]) == k
    a = jnp.where(unit[:, None] | unit[None, :], 0.0, a) + jnp.diag(unit.astype(a.dtype))
    v = jnp.linalg.solve(a, jnp.where(unit, 0.0, f))
    c = -phi @ (M @ v) - 0.5 * phi @ (dM @ phi)
    return dlam, v + c * phi


@jax.custom_jvp
def frequencies_hz(lam: Float[Array, " m"]) -> Float[Array, " m"]:
    """Natural frequencies f = √λ / 2π in Hz; round-off negatives (rigid-body modes) give 0.

    Derivative: df/dλ = 1/(4π√λ) = 1/(8π² f) for λ > 0 and 0 for λ ≤ 0 (a rigid-body
    mode's frequency stays at 0), so ``jax.grad`` through rigid-body modes is finite
    instead of the NaN of √λ at 0.
    """
    return jnp.sqrt(jnp.maximum(lam, 0.0)) / (2 * jnp.pi)


@frequencies_hz.defjvp
def _frequencies_hz_jvp(primals, tangents):
    (lam,), (dlam,) = primals, tangents
    f = frequencies_hz(lam)
    positive = lam > 0
    return f, jnp.where(positive, dlam / (8 * jnp.pi**2 * jnp.where(positive, f, 1.0)), 0.0)
