"""The least-squares kernel of the updating step: Householder QR as a lineax solver.

The Gauss–Newton / Levenberg–Marquardt step of thesis eq. 3.11 solves an overdetermined
system J Δθ ≈ −ε (more residual rows than parameters). :class:`HouseholderQR` implements
``lineax.AbstractLinearSolver`` (public API only) with two properties the engine needs:

- the LAPACK kernels loop over a ``vmap`` batch instead of batching the call
  (``jax.custom_batching.sequential_vmap``): a batched LAPACK call inside a batched
  ``while_loop`` can deadlock XLA-CPU (see ``jaxfem._lapack``);
- the right-hand side is flattened by its own leaves, with no check that its pytree
  structure equals the operator's: inside ``shard_map`` one of them carries the manual
  mesh and the other not, which lineax' own QR rejects.
"""

from __future__ import annotations

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import lineax as lx
import numpy as np


@jax.custom_batching.sequential_vmap
def _householder(matrix):
    h, taus = jnp.linalg.qr(matrix, mode="raw")
    return h.mT, taus


@jax.custom_batching.sequential_vmap
def _householder_solve(a, taus, b):
    n = a.shape[1]
    return jsl.solve_triangular(a[:n], jax.lax.linalg.ormqr(a, taus, b[:, None], transpose=True)[:n, 0])


class _Structure(eqx.Module):
    """The solution's pytree structure and leaf shapes (static)."""

    treedef: Any = eqx.field(static=True)
    shapes: tuple = eqx.field(static=True)

    def unflatten(self, x):
        parts = jnp.split(x, np.cumsum([int(np.prod(s)) for s in self.shapes])[:-1])
        return jax.tree.unflatten(self.treedef, [p.reshape(s) for p, s in zip(parts, self.shapes)])


class HouseholderQR(lx.AbstractLinearSolver):
    """Least-squares solution of a full-column-rank overdetermined system by Householder QR."""

    def init(self, operator, options):
        del options
        matrix = operator.as_matrix()
        if matrix.shape[1] > matrix.shape[0]:
            raise ValueError(f"{matrix.shape[1]} parameters but only {matrix.shape[0]} residual rows: "
                             "the update is underdetermined")
        leaves, treedef = jax.tree.flatten(operator.in_structure())
        return _householder(matrix), _Structure(treedef, tuple(tuple(s.shape) for s in leaves))

    def compute(self, state, vector, options):
        del options
        (a, taus), structure = state
        b = jnp.concatenate([jnp.ravel(v) for v in jax.tree.leaves(vector)])
        return structure.unflatten(_householder_solve(a, taus, b)), lx.RESULTS.successful, {}

    def transpose(self, state, options):
        raise NotImplementedError("HouseholderQR solves the forward least-squares step only")

    def conj(self, state, options):
        raise NotImplementedError("HouseholderQR solves real systems only")

    def assume_full_rank(self):
        return True
