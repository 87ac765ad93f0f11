"""Reduction of K and M to measured (master) DoFs for correlation: Guyan static condensation
and the SEREP mass matrix (thesis §1.3.3.2); the orthogonality checks of
:func:`identification.cross_orthogonality` use the reduced mass."""

from __future__ import annotations

import functools
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int


def _common(*xs) -> tuple[Array, ...]:
    """Cast to one double-precision dtype (explicitly: strict promotion allows no mixing)."""
    xs = tuple(jnp.asarray(x) for x in xs)
    dtype = np.result_type(*(x.dtype for x in xs), np.float64)
    return tuple(x.astype(dtype) for x in xs)


def _master_dofs(master: Sequence[int] | np.ndarray, n: int) -> Int[np.ndarray, " m"]:
    """Master DoF indices (integers, or a boolean mask of length n), checked."""
    idx = np.asarray(master)
    if idx.dtype == bool:
        if idx.shape != (n,):
            raise ValueError(f"a boolean master mask must have shape ({n},), got {idx.shape}")
        idx = np.flatnonzero(idx)
    if idx.ndim != 1 or idx.shape[0] == 0 or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"master must be a non-empty 1-D array of DoF indices, got {master!r}")
    bad = idx[(idx < 0) | (idx >= n)]
    if bad.size:
        raise ValueError(f"master DoF index {bad[0]} is out of range 0..{n - 1}")
    if np.unique(idx).size != idx.size:
        raise ValueError("master DoF indices must be unique")
    return idx.astype(np.int64)


def _square(name: str, x) -> Float[Array, "n n"]:
    x = jnp.asarray(x)
    if x.ndim != 2 or x.shape[0] != x.shape[1]:
        raise ValueError(f"{name} must be a square matrix, got shape {x.shape}")
    return x


def guyan(
    K: Float[ArrayLike, "n n"], M: Float[ArrayLike, "n n"], master: Sequence[int] | np.ndarray
) -> tuple[Float[Array, "m m"], Float[Array, "m m"]]:
    """Guyan (1965) static condensation onto the master DoFs (thesis §1.3.3.2).

    The slaves s follow the masters m statically, ``u_s = −K_ss⁻¹ K_sm u_m``, so
    ``T = [I; −K_ss⁻¹ K_sm]`` and ``K_red = Tᵀ K T``, ``M_red = Tᵀ M T``. The reduced
    eigenvalues bound the full ones from above (Rayleigh–Ritz) and are exact when the
    slaves carry no mass. Dense arrays (``ElementMatrix.todense()``); differentiable.

    **Arguments:** symmetric ``K`` (positive definite on the slaves), ``M``; ``master``:
    DoF indices (or a boolean mask); the reduced DoFs follow the order of ``master``.

    **Returns:** ``(K_red, M_red)``.
    """
    K, M = _square("K", K), _square("M", M)
    if K.shape != M.shape:
        raise ValueError(f"K is {K.shape} but M is {M.shape}")
    n = K.shape[0]
    m = _master_dofs(master, n)
    s = np.setdiff1d(np.arange(n), m)
    return _condense(*_common(K, M), tuple(m.tolist()), tuple(s.tolist()))


@functools.partial(jax.jit, static_argnums=(2, 3))
def _condense(K: Float[Array, "n n"], M: Float[Array, "n n"], m: tuple[int, ...], s: tuple[int, ...]):
    m, s = np.asarray(m, np.int64), np.asarray(s, np.int64)
    T = jnp.zeros((K.shape[0], m.size), K.dtype).at[m, np.arange(m.size)].set(1.0)
    if s.size:
        op = lx.MatrixLinearOperator(K[np.ix_(s, s)], (lx.symmetric_tag, lx.positive_semidefinite_tag))
        # Batching over the right-hand sides only: lineax factors K_ss once.
        solve = jax.vmap(lambda b: lx.linear_solve(op, b, lx.Cholesky()).value, in_axes=1, out_axes=1)
        x = solve(K[np.ix_(s, m)])
        x = eqx.error_if(
            x, ~jnp.all(jnp.isfinite(x)), "K_ss is singular: the slaves form a mechanism"
        )
        T = T.at[s].set(-x)
    k_red, m_red = T.T @ K @ T, T.T @ M @ T
    return 0.5 * (k_red + k_red.T), 0.5 * (m_red + m_red.T)


def serep(
    phi_full: Float[ArrayLike, "n r"], M: Float[ArrayLike, "n n"], master: Sequence[int] | np.ndarray
) -> Float[Array, "m m"]:
    """SEREP mass matrix on the master DoFs (O'Callahan, Avitabile & Riemer 1989).

    ``T = Φ Φ_m⁺`` maps master motion onto the span of the r retained modes ``Φ`` (rows
    ``Φ_m`` at the masters, ``r ≤ n_master``, full column rank); ``M_red = Tᵀ M T``.
    Since ``T Φ_m = Φ``, the retained modes stay M_red-orthonormal at the masters and,
    with ``K_red = Tᵀ K T``, their frequencies are reproduced exactly.

    **Arguments:** ``phi_full``: retained modes on all n DoFs; ``M``: full mass matrix;
    ``master``: DoF indices (or a boolean mask), order kept.
    """
    phi = jnp.asarray(phi_full)
    M = _square("M", M)
    if phi.ndim != 2 or phi.shape[0] != M.shape[0]:
        raise ValueError(f"phi_full must be ({M.shape[0]}, r), got shape {phi.shape}")
    m = _master_dofs(master, M.shape[0])
    if phi.shape[1] > m.size:
        raise ValueError(f"SEREP needs at most {m.size} retained modes (one per master), got {phi.shape[1]}")
    phi, M = _common(phi, M)
    T = phi @ jnp.linalg.pinv(phi[m])
    m_red = T.T @ M @ T
    return 0.5 * (m_red + m_red.T)
