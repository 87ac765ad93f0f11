"""LAPACK-backed dense kernels with batching rules that never batch a factorisation call.

On XLA-CPU (jaxlib 0.10.2) a vmapped LAPACK call spreads its batch over the intra-op
thread pool and waits for it from a thread of the same pool; inside a vmapped
``while_loop`` (a batched updating loop) every pool thread ends up waiting and the
process hangs at 0 % CPU (seen with 8 samples on 2 cores; the native stack shows
``jax::ParallelBatchMap`` in ``lapack_dtrsm_ffi`` blocked on a ``BlockingCounter``).
Under ``vmap`` these kernels therefore loop over batched matrices (``lax.map``), and a
solve with a shared factor takes all batched right-hand sides as columns of one call
(one BLAS-3 solve, as jax does for a triangular solve with an unbatched matrix).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl


@jax.custom_batching.sequential_vmap
def cholesky(a):
    """Lower Cholesky factor (NaN where ``a`` is not positive definite)."""
    return jnp.linalg.cholesky(a)


@jax.custom_batching.sequential_vmap
def eigh(a):
    """Eigenvalues (ascending) and orthonormal eigenvectors of a symmetric matrix."""
    return jnp.linalg.eigh(a)


def _solver(solve):
    @jax.custom_batching.custom_vmap
    def f(factor, b):
        return solve(factor, b)

    @f.def_vmap
    def _batched(axis_size, in_batched, factor, b):
        factor_batched, b_batched = in_batched
        if not factor_batched:  # shared factor: batched right-hand sides become columns
            cols = jnp.moveaxis(b, 0, -1)
            x = f(factor, cols.reshape(cols.shape[0], -1)).reshape(cols.shape)
            return jnp.moveaxis(x, -1, 0), True
        if not b_batched:
            b = jnp.broadcast_to(b, (axis_size,) + b.shape)
        return jax.lax.map(lambda fb: f(*fb), (factor, b)), True

    return f


cho_solve = _solver(lambda factor, b: jsl.cho_solve((factor, True), b))
cho_solve.__doc__ = "``A⁻¹ b`` from the lower Cholesky factor of A."
solve_lower = _solver(lambda factor, b: jsl.solve_triangular(factor, b, lower=True))
solve_lower.__doc__ = "``L⁻¹ b`` for lower-triangular L."
solve_upper = _solver(lambda factor, b: jsl.solve_triangular(factor, b, lower=False))
solve_upper.__doc__ = "``U⁻¹ b`` for upper-triangular U."
