"""Symmetric matrices as linear operators: dense, or element-stacked (sparse).

:func:`jaxfem.eigh` accepts either. The element-stacked form keeps the matrix as the
sum of small element blocks scattered into the solved DoFs, so that its tangent
(the derivative of K with respect to a parameter) stays element-sized: ``dK @ φ``
costs a few flops per element instead of an n×n product.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import scipy.sparse
from jaxtyping import Array, Float, Int


class AbstractSymmetricMatrix(eqx.Module):
    """A real symmetric n×n matrix known through ``todense`` and ``matmul``.

    ``massless`` lists DoFs whose rows and columns are structurally zero (for a mass
    matrix: DoFs without inertia); the eigen solver condenses them statically.
    """

    massless: eqx.AbstractVar[Int[np.ndarray, " nb"]]

    @property
    @abc.abstractmethod
    def n(self) -> int:
        """Size of the matrix."""

    @abc.abstractmethod
    def todense(self) -> Float[Array, "n n"]:
        """The matrix as a dense array."""

    @abc.abstractmethod
    def matmul(self, x: Float[Array, "n k"]) -> Float[Array, "n k"]:
        """``A @ x``, linear in the matrix data."""

    @abc.abstractmethod
    def with_values(self, values) -> "AbstractSymmetricMatrix":
        """The same structure with other numerical data (used for tangents)."""

    @abc.abstractmethod
    def values(self):
        """The numerical data (a pytree of float arrays)."""


class DenseMatrix(AbstractSymmetricMatrix):
    """A dense symmetric matrix."""

    array: Float[Array, "n n"]
    massless: Int[np.ndarray, " nb"]

    def __init__(self, array, massless=None):
        self.array = array
        self.massless = np.zeros(0, np.int64) if massless is None else np.asarray(massless, np.int64)

    @property
    def n(self) -> int:
        return self.array.shape[0]

    def todense(self):
        return self.array

    def matmul(self, x):
        return self.array @ x

    def with_values(self, values):
        return DenseMatrix(values, self.massless)

    def values(self):
        return self.array


class ElementMatrix(AbstractSymmetricMatrix):
    """``A = Σ_e P_eᵀ A_e P_e``: element blocks scattered at solved-DoF indices.

    ``blocks[t]`` has shape (n_el, w, w) and ``indices[t]`` shape (n_el, w); an index
    equal to ``size`` is padding and is dropped.
    """

    blocks: tuple[Float[Array, "nel w w"], ...]
    indices: tuple[Int[np.ndarray, "nel w"], ...]
    massless: Int[np.ndarray, " nb"]
    size: int = eqx.field(static=True)

    @property
    def n(self) -> int:
        return self.size

    def todense(self):
        a = jnp.zeros((self.size, self.size))
        for blk, idx in zip(self.blocks, self.indices):
            a = a.at[idx[:, :, None], idx[:, None, :]].add(blk, mode="drop")
        return a

    def matmul(self, x):
        out = jnp.zeros((self.size + 1,) + x.shape[1:])
        xp = jnp.concatenate([x, jnp.zeros((1,) + x.shape[1:])])
        for blk, idx in zip(self.blocks, self.indices):
            local = jnp.einsum("eij,ej...->ei...", blk, xp[idx])
            out = out.at[idx].add(local)
        return out[: self.size]

    def project(self, V: Float[Array, "n k"]) -> Float[Array, "k k"]:
        """``Vᵀ A V`` summed element by element (no n × k product: cheap for a few elements)."""
        Vp = jnp.concatenate([V, jnp.zeros((1, V.shape[1]))])
        out = jnp.zeros((V.shape[1], V.shape[1]))
        for blk, idx in zip(self.blocks, self.indices):
            g = Vp[idx]
            out = out + g.reshape(-1, V.shape[1]).T @ jnp.einsum("eij,ejb->eib", blk, g).reshape(-1, V.shape[1])
        return out

    def tocsr(self) -> scipy.sparse.csr_matrix:
        """The matrix as SciPy CSR, on the host (concrete values only; no n × n array)."""
        rows, cols, vals = [], [], []
        for blk, idx in zip(self.blocks, self.indices):
            idx = np.asarray(idx)
            r, c = np.broadcast_arrays(idx[:, :, None], idx[:, None, :])
            keep = (r < self.size) & (c < self.size)
            rows.append(r[keep])
            cols.append(c[keep])
            vals.append(np.asarray(blk)[keep])
        cat = lambda parts, dtype: np.concatenate(parts) if parts else np.zeros(0, dtype)  # noqa: E731
        return scipy.sparse.coo_matrix((cat(vals, float), (cat(rows, np.int64), cat(cols, np.int64))),
                                       shape=(self.size, self.size)).tocsr()

    def with_values(self, values):
        return ElementMatrix(
            blocks=tuple(values), indices=self.indices, massless=self.massless, size=self.size
        )

    def values(self):
        return self.blocks
