"""Lowest modes of a large sparse model by shift-invert Lanczos, with exact derivatives.

Forward (host, through ``jax.pure_callback``): the CSR values of K and M are summed from
the element blocks (:mod:`jaxfem._sparse`), ``K − σM`` is factorised once (MKL PARDISO
or SuperLU) and ARPACK's implicitly restarted Lanczos (``scipy.sparse.linalg.eigsh``,
mode 3) finds the q = m + extra eigenvalues nearest σ of ``(K − σM)⁻¹ M``, σ below the
spectrum. Two sweeps of inverse iteration in residual form, ``V − (K − σM)⁻¹(K V − M V Λ)``,
each with a Rayleigh–Ritz step, refine them to rounding.

Derivatives: the q modes form a :class:`jaxfem.Subspace` whose inverse is the same
factorisation, and :func:`jaxfem.ritz_modes` differentiates the m wanted ones exactly —
the modal expansion over the q computed modes (thesis eq. 3.23, eq. 3.28, eq. 3.29) plus
its rest, M-orthogonal to them, solved on the host (:meth:`SparseInverse.rest`) by
preconditioned conjugate gradients, all parameters' right-hand sides of a mode as
columns of one block: modes far below λ_q+1 with the forward factorisation, the others
with one factorisation of K − σ_c M per group of close modes (σ_c a little below them,
so that a few sweeps suffice). Never one factorisation per mode and parameter, and no
modes beyond the q. Clusters of nearly equal eigenvalues are handled as in
:func:`jaxfem.eigh` with ``degenerate="mean"``, provided a cluster does not reach past
the q computed modes (``n_extra`` ≥ the size of any cluster at the m-th mode).
"""

from __future__ import annotations

import functools
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.linalg
import scipy.sparse.linalg
from jaxtyping import Array, Float

from . import _sparse
from ._eigen import DEGENERATE_RTOL, _operator
from ._matrix import ElementMatrix
from ._subspace import Subspace, ritz_modes

DENSE_BELOW = 400  # DoFs with mass below which the host solves the shifted problem densely
REFINE_SWEEPS = 2  # after the Lanczos iteration (one left jitter of 1e-9 in updates of the tree)
SIGMA_FRACTION = 1e-3  # automatic σ = −SIGMA_FRACTION · min K_ii/M_ii (below every eigenvalue)


class SparseInverse(eqx.Module):
    """``(K − σM)⁻¹`` by a sparse factorisation on the host, applied by :meth:`solve`."""

    k_blocks: tuple[Array, ...]
    m_blocks: tuple[Array, ...]
    sigma: Float[Array, ""]
    pattern: _sparse.SparsePattern = eqx.field(static=True)
    backend: str = eqx.field(static=True)
    n_k: int = eqx.field(static=True)

    def solve(self, r: Float[Array, "n k"]) -> Float[Array, "n k"]:
        args = (self.sigma, *self.k_blocks, *self.m_blocks, r)
        host = functools.partial(_host_solve, self.pattern, self.backend, self.n_k)
        return jax.pure_callback(host, jax.ShapeDtypeStruct(r.shape, r.dtype), *args, vmap_method="expand_dims")

    def rest(self, b, lam_r, V, lam, tol: float, max_sweeps: int):
        """The rest ``z_r`` of the modal expansion (:func:`jaxfem.ritz_modes`), M-orthogonal
        to the computed modes V: ``(K − λ_r M) z_r = b_r`` per column, on the host
        (:func:`_host_rest`)."""
        args = (self.sigma, *self.k_blocks, *self.m_blocks, V, lam, lam_r, b)
        host = functools.partial(_host_rest, self.pattern, self.backend, self.n_k, float(tol), int(max_sweeps))
        return jax.pure_callback(host, jax.ShapeDtypeStruct(b.shape, b.dtype), *args, vmap_method="expand_dims")


def _batches(nb: int, args, n_mat: int):
    """Group leading (``vmap``) axes: yields ``(matrix arguments, rest arguments, out
    index)`` per distinct matrix; the rest arguments are broadcast over the other axes."""
    out_shape = np.broadcast_shapes(*(np.shape(a)[:nb] for a in args))
    mat_shape = np.broadcast_shapes(*(np.shape(a)[:nb] for a in args[:n_mat]))
    for at in np.ndindex(mat_shape):
        pick = lambda a: np.asarray(a)[tuple(min(i, s - 1) for i, s in zip(at, np.shape(a)[:nb]))]  # noqa: E731
        sel = tuple(i if s > 1 else slice(None) for i, s in zip(at, mat_shape))
        rest = [np.broadcast_to(a, out_shape + np.shape(a)[nb:])[sel] for a in args[n_mat:]]
        yield [pick(a) for a in args[:n_mat]], rest, sel


SHIFT_RATE = 0.2  # rest solve: a mode shares a shift while (λ_r − σ_c) ≤ SHIFT_RATE (λ_q+1 − σ_c)
SHIFT_OFFSET = 0.05  # a group's shift lies this fraction of λ_q+1 − λ below its lowest eigenvalue


def _host_rest(pat, backend, n_k, tol, max_sweeps, sigma, *args):
    """Batched :meth:`SparseInverse.rest`. Modes near each other share a shift σ_c just
    below their eigenvalues, and K − σ_c M is factorised once for them: with the computed
    modes projected out, preconditioned conjugate gradients then converge at the rate of
    (λ_r − σ_c)/(λ_s − σ_c), s > q, i.e. in a few sweeps (modes far below λ_q+1, e.g.
    rigid-body modes, use the forward solve's factorisation)."""
    *mats, V, lam, lam_r, b = args
    nb = np.ndim(b) - 2
    out = np.empty(np.broadcast_shapes(*(np.shape(a)[:nb] for a in args)) + np.shape(b)[nb:])
    for (sig, *blocks, V, lam), (lam_r, b), sel in _batches(nb, (sigma, *mats, V, lam, lam_r, b), 1 + len(mats) + 2):
        kd, md = pat.values(blocks[:n_k], pat.slots[:n_k]), pat.values(blocks[n_k:], pat.slots[n_k:])
        n, k = b.shape[-2:]
        cols = np.moveaxis(b, -2, 0).reshape(n, -1)
        shifts = np.broadcast_to(lam_r, b.shape[:-2] + (k,)).reshape(-1)
        z = _rest(pat, backend, kd, md, float(sig), V, lam, shifts, cols, tol, max_sweeps)
        out[sel] = np.moveaxis(z.reshape((n,) + b.shape[:-2] + (k,)), 0, -2)
    return out


def _rest(pat, backend, kd, md, sigma, V, lam, lam_r, b, tol, max_sweeps):
    Mc = pat.matrix(md)
    both = _sparse.stacked(pat.matrix(kd), Mc)  # K and M in one product, for every group
    MV = Mc @ V
    top = lam[-1] + (lam[-1] - lam[0]) / max(len(lam) - 1, 1)  # a floor for λ_q+1
    z = np.zeros_like(b)
    order = np.argsort(lam_r)
    start = 0
    while start < len(order):
        first = lam_r[order[start]]
        shift = sigma if (first - sigma) <= SHIFT_RATE * (top - sigma) else first - SHIFT_OFFSET * (top - first)
        f = _sparse.factor(pat, backend, kd, md, shift)  # cached: a Jacobian in chunks of tangents reuses it
        stop = start + 1
        while stop < len(order) and lam_r[order[stop]] - shift <= SHIFT_RATE * (top - shift):
            stop += 1
        cols = order[start:stop]
        z[:, cols] = _pcg(both, V, MV, f, lam_r[cols], b[:, cols], tol, max_sweeps)
        start = stop
    return z


def _pcg(both, V, MV, f, lam_r, b, tol, max_sweeps):
    """Preconditioned conjugate gradients, one system per column, ``(K − λ_r M) z = b`` on
    the M-orthogonal complement of V (``both``: K stacked on M), preconditioner P S Pᵀ
    (S from ``f``); converged columns leave the block; a column still moving after
    ``max_sweeps`` is warned about."""
    def precondition(r):
        x = f.solve(r - MV @ (V.T @ r))
        return x - V @ (MV.T @ x)

    z = np.zeros_like(b)
    r = b.copy()
    y = precondition(r)
    p = y.copy()
    ry = np.einsum("ij,ij->j", r, y)
    active = np.arange(b.shape[1])
    for _ in range(max_sweeps):
        if not len(active):
            break
        pa = p[:, active]
        kp, mp = _sparse.matmul(both, pa)
        ap = kp - mp * lam_r[active]
        den = np.einsum("ij,ij->j", pa, ap)
        alpha = np.where(den != 0, ry[active] / np.where(den != 0, den, 1.0), 0.0)
        dz = pa * alpha
        z[:, active] += dz
        r[:, active] -= ap * alpha
        step = np.abs(dz).max(axis=0) / np.maximum(np.abs(z[:, active]).max(axis=0), np.finfo(float).tiny)
        y = precondition(r[:, active])
        ry_new = np.einsum("ij,ij->j", r[:, active], y)
        beta = np.where(ry[active] != 0, ry_new / np.where(ry[active] != 0, ry[active], 1.0), 0.0)
        p[:, active] = y + pa * beta
        ry[active] = ry_new
        active = active[step > tol]
    if len(active):
        warnings.warn(f"eigenvector derivatives: {len(active)} of {b.shape[1]} right-hand sides still changed "
                      f"by more than {tol:g} after {max_sweeps} conjugate-gradient sweeps", stacklevel=2)
    return z


def _host_solve(pat, backend, n_k, sigma, *args):
    """Batched (leading axes from ``vmap``) right-hand sides; one factorisation per
    distinct matrix, all its right-hand sides as columns of one solve."""
    nb = np.ndim(args[-1]) - 2
    out = np.empty(np.broadcast_shapes(*(np.shape(a)[:nb] for a in (sigma, *args))) + np.shape(args[-1])[nb:])
    for (sig, *blocks), (r,), sel in _batches(nb, (sigma, *args), len(args)):
        f = _host_factor(pat, backend, float(sig), blocks, n_k)
        n, k = r.shape[-2:]
        cols = np.moveaxis(r, -2, 0).reshape(n, -1)
        out[sel] = np.moveaxis(f.solve(cols).reshape((n,) + r.shape[:-2] + (k,)), 0, -2)
    return out


def _host_factor(pat, backend, sigma, blocks, n_k):
    return _sparse.factor(pat, backend, pat.values(blocks[:n_k], pat.slots[:n_k]),
                          pat.values(blocks[n_k:], pat.slots[n_k:]), sigma)


def eigsh(K, M, n_modes: int, *, n_extra: int | None = None, sigma: float | None = None,
          backend: str = "auto", rtol: float = DEGENERATE_RTOL
          ) -> tuple[Float[Array, " m"], Float[Array, "n m"]]:
    """Lowest ``n_modes`` modes of ``K φ = λ M φ`` for sparse K, M, differentiable.

    **Arguments:**
    - ``K``, ``M``: :class:`jaxfem.ElementMatrix` from :func:`jaxfem.assemble`
      (massless DoFs allowed; ``K − σM`` must be nonsingular).
    - ``n_modes``: m, the number of lowest modes returned.
    - ``n_extra``, ``sigma``, ``backend``: as :func:`sparse_modes`.
    - ``rtol``: relative threshold of clusters, as :func:`jaxfem.eigh`.

    **Returns:** ``(λ, Φ)`` as :func:`jaxfem.eigh`: λ = ω² ascending, Φ mass-normalised,
    each column's largest-magnitude component positive. Forward- and reverse-mode
    derivatives are exact (module documentation).
    """
    sol = sparse_modes(K, M, n_modes, n_extra=n_extra, sigma=sigma, backend=backend)
    return ritz_modes(K, M, sol, jnp.arange(int(n_modes)), rtol=rtol)


def sparse_modes(K, M, n_modes: int, *, n_extra: int | None = None, sigma: float | None = None,
                 backend: str = "auto") -> Subspace:
    """The lowest ``n_modes`` + ``n_extra`` modes by shift-invert Lanczos, as a
    :class:`jaxfem.Subspace` whose inverse is the sparse factorisation, for
    :func:`jaxfem.ritz_modes` (no derivative flows through it).

    **Arguments:** ``K``, ``M`` as :func:`eigsh`; ``n_extra``: further modes, for the
    derivative's expansion and for clusters at the last wanted mode (default
    ``max(4, n_modes // 4)``); ``sigma``: the shift σ in (rad/s)², below the lowest
    eigenvalue (default −10⁻³·min K_ii/M_ii: negative, so that free structures are
    covered); ``backend``: ``"auto"``, ``"pardiso"`` or ``"superlu"`` (:mod:`jaxfem._sparse`).
    """
    K, M = _operator("K", K), _operator("M", M)
    if not (isinstance(K, ElementMatrix) and isinstance(M, ElementMatrix)):
        raise TypeError("the sparse eigensolver needs element-stacked matrices (jaxfem.assemble); "
                        "use jaxfem.eigh for arrays")
    if K.n != M.n:
        raise ValueError(f"K is {K.n}×{K.n} but M is {M.n}×{M.n}")
    n_free = M.n - len(M.massless)
    m = int(n_modes)
    extra = max(4, m // 4) if n_extra is None else int(n_extra)
    q = min(m + extra, n_free - 1)
    if not 1 <= m <= q:
        raise ValueError(f"n_modes must be in 1..{n_free - 2} for the sparse solver ({n_free} DoFs with mass), got {m}")
    pat = _sparse.pattern(tuple(K.indices) + tuple(M.indices), K.n)
    backend = _sparse.resolve_backend(backend)
    n_k = len(K.blocks)
    blocks = jax.lax.stop_gradient(tuple(K.blocks) + tuple(M.blocks))
    auto = sigma is None
    shape = (jax.ShapeDtypeStruct((), jnp.float64), jax.ShapeDtypeStruct((q,), jnp.float64),
             jax.ShapeDtypeStruct((K.n, q), jnp.float64))

    def host(*blocks):
        return _host_modes(pat, backend, None if auto else float(sigma), q, list(blocks), n_k)

    sig, lam, V = jax.pure_callback(host, shape, *blocks, vmap_method="sequential")
    inverse = SparseInverse(blocks[:n_k], blocks[n_k:], sig, pat, backend, n_k)
    return Subspace(lam, V, inverse, jnp.asarray(True), jnp.zeros(()), jnp.zeros((), jnp.int32), q)


def _host_modes(pat, backend, sigma, q, blocks, n_k):
    kd, md = pat.values(blocks[:n_k], pat.slots[:n_k]), pat.values(blocks[n_k:], pat.slots[n_k:])
    Kc, Mc = pat.matrix(kd), pat.matrix(md)
    if sigma is None:
        dk, dm = Kc.diagonal(), Mc.diagonal()
        ratio = np.where((dm > 0) & (dk > 0), dk / np.where(dm > 0, dm, 1.0), np.inf)
        sigma = -SIGMA_FRACTION * float(ratio.min()) if np.isfinite(ratio.min()) else -1.0
    f = _sparse.factor(pat, backend, kd, md, sigma)
    n_free = int(np.count_nonzero(Mc.diagonal() > 0))
    ncv = min(n_free - 1, max(2 * q + 1, 20))
    if n_free <= DENSE_BELOW or ncv <= q:
        lam, V = _small(Kc, Mc, sigma, q)
    else:
        op = scipy.sparse.linalg.LinearOperator(Kc.shape, matvec=f.solve, dtype=np.float64)
        v0 = np.random.default_rng(0).random(pat.n)
        try:
            lam, V = scipy.sparse.linalg.eigsh(Kc, k=q, M=Mc, sigma=sigma, OPinv=op, which="LM", v0=v0,
                                               ncv=ncv, tol=0.0)
        except scipy.sparse.linalg.ArpackNoConvergence as e:
            raise RuntimeError(f"the Lanczos iteration did not converge for {q} modes ({e})") from None
        order = np.argsort(lam)
        lam, V = lam[order], V[:, order]
    if lam[0] < sigma:
        raise ValueError(f"sigma = {sigma:.6g} (rad/s)² lies above the lowest eigenvalue {lam[0]:.6g}")
    # sweeps of inverse iteration in residual form, each with Rayleigh–Ritz (refined to rounding)
    for _ in range(REFINE_SWEEPS):
        V = V - f.solve(Kc @ V - (Mc @ V) * lam)
        kr, mr = V.T @ (Kc @ V), V.T @ (Mc @ V)
        lam, Z = scipy.linalg.eigh(0.5 * (kr + kr.T), 0.5 * (mr + mr.T))
        V = V @ Z
    big = np.take_along_axis(V, np.argmax(np.abs(V), axis=0)[None], axis=0)[0]
    return np.float64(sigma), lam, V * np.where(big < 0, -1.0, 1.0)


def _small(Kc, Mc, sigma, q):
    """The q modes nearest σ of a small problem, densely: K − σM = L Lᵀ, the standard
    problem L⁻¹ M L⁻ᵀ z = ν z, λ = σ + 1/ν, φ = L⁻ᵀ z/√ν (M may be singular)."""
    a = (Kc - sigma * Mc).toarray()
    try:
        low = np.linalg.cholesky(0.5 * (a + a.T))
    except np.linalg.LinAlgError:
        raise _sparse._singular("dense Cholesky failed") from None
    half = scipy.linalg.solve_triangular(low, Mc.toarray(), lower=True)
    nu, z = np.linalg.eigh(scipy.linalg.solve_triangular(low, half.T, lower=True))
    nu, z = nu[::-1][:q], z[:, ::-1][:, :q]
    return sigma + 1.0 / nu, scipy.linalg.solve_triangular(low.T, z, lower=False) / np.sqrt(nu)
