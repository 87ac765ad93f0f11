"""The Ritz basis of the diagnosis' reduced fits (:class:`updating._eigensolvers.Reduced`).

A diagnosis fits tens of candidates, each a change of one model in a few parameters. On a
large model every step of every fit would solve the full eigenproblem. The modes of the
changed model are sought in the span of

- the baseline's q lowest modes;
- along the engineer's parameters (groups, global): the static responses to the forces
  each parameter's change exerts on the paired modes, ``(K − σM)⁻¹ (∂_i K − λ_j ∂_i M) φ_j``
  (the first-order modal expansion with its static correction, eq. 3.23 with eq. 3.28);
- along a candidate's parameters (a local change): the static responses to unit loads at
  every DoF the change touches, ``(K − σM)⁻¹ e_d`` (attachment modes), and one step of
  inverse iteration on them, ``(K − σM)⁻¹ M (K − σM)⁻¹ e_d``. A change ΔK of any
  size on those DoFs changes the static flexibility only in their span (Woodbury), so
  these hold a joint released or a patch delaminated, not only a small step. A candidate
  touching more than ``ATTACH_MAX`` DoFs (a whole group) gets the first-order columns.

The basis is M-orthonormalised. The reduced eigenvalues are Rayleigh quotients, so their
error is of second order in the shapes' error. The baseline's part is made once.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem

from ._compiled import Compiled
from ._eigensolvers import Reduced
from ._element_sensitivity import _modes
from ._evidence import with_extension
from ._residuals import Problem, pair

ATTACH_MAX = 400  # DoFs a candidate may touch for attachment columns; more: first-order columns
WIDTHS = (64, 1.5, 32)  # a basis is padded to the next width of 64, then ×1.5 in multiples of 32 (one compiled fit per width)
MASS_FLOOR = 1e-10  # basis directions of M-norm² below this share of the largest are dropped


def _loads(theta, problem: Problem, tangents, phi, lam):
    """``(∂K − λ_j ∂M) φ_j`` along each row of ``tangents``: (n, tangents × modes)."""

    def one(d):
        (K, M), (dK, dM) = jax.jvp(lambda t: jaxfem.assemble(problem.model(t)), (theta,), (d,))
        return K.with_values(dK.values()).matmul(phi) - M.with_values(dM.values()).matmul(phi) * lam

    out = jax.lax.map(one, tangents)
    return jnp.moveaxis(out, 0, 1).reshape(phi.shape[0], -1)


def _touched(theta, problem: Problem, tangents):
    """Per DoF, Σ |∂K| + |∂M| over the rows along ``tangents``: nonzero where they touch."""

    def one(d):
        (K, M), (dK, dM) = jax.jvp(lambda t: jaxfem.assemble(problem.model(t)), (theta,), (d,))
        ones = jnp.ones((K.n, 1))
        return sum(A.with_values(jax.tree.map(jnp.abs, dA.values())).matmul(ones)[:, 0] for A, dA in ((K, dK), (M, dM)))

    return jnp.sum(jax.lax.map(one, tangents), axis=0)


def _mass(theta, problem: Problem):
    """M(θ), element-stacked: compiled once for all candidates (their masks are arrays),
    its products taken on the host (a compiled product would compile anew at every basis width)."""
    return jaxfem.assemble(problem.model(theta))[1]


class Bases:
    """The baseline's modes, its factorisation of K − σM and its static corrections along
    the engineer's parameters, at θ_b; :meth:`reduced` adds a candidate's columns.

    ``problem`` carries an extension of one parameter at 0 (the diagnosis' ``none``), θ_b
    the engineer's log-factors and that 0."""

    def __init__(self, problem: Problem, theta_b):
        self._loads, self._touched, self._mass = Compiled(_loads), Compiled(_touched), Compiled(_mass)
        theta = jnp.asarray(theta_b, dtype=jnp.float64)
        _, lam, Phi, self._solve, _ = _modes(problem, theta, problem.model(theta))
        q = problem.n_model
        lam, Phi = lam[:q], Phi[:, :q]
        index, paired = (np.asarray(a) for a in pair(jnp.asarray(lam), problem.C @ jnp.asarray(Phi), problem))
        j = np.unique(index[paired])
        self.phi, self.lam = Phi[:, j], lam[j]
        self.theta_b = np.asarray(theta[:-1])
        self.n_b = len(self.theta_b)
        common = [Phi] + ([self._corrections(problem, theta, np.eye(len(theta))[: self.n_b])] if self.n_b else [])
        self.common = np.concatenate(common, axis=1)

    def _corrections(self, problem: Problem, theta, tangents) -> np.ndarray:
        loads = self._loads(theta, problem, jnp.asarray(tangents), jnp.asarray(self.phi), jnp.asarray(self.lam))
        return np.asarray(self._solve(np.asarray(loads)))

    def reduced(self, problem: Problem, ext, theta_c) -> Reduced:
        """The :class:`Reduced` eigensolver of one candidate (``ext``, its θ at ``theta_c``):
        the baseline's columns and the candidate's (module docstring)."""
        p = with_extension(problem, ext)
        theta_c = np.atleast_1d(np.asarray(theta_c, float))
        theta = jnp.asarray(np.concatenate([self.theta_b, theta_c]))
        tangents = jnp.asarray(np.eye(len(theta))[self.n_b:])
        touched = np.flatnonzero(np.asarray(self._touched(theta, p, tangents)))
        M = self._mass(theta, p).tocsr()
        if len(touched) <= ATTACH_MAX:
            unit = np.zeros((len(self.phi), len(touched)))
            unit[touched, np.arange(len(touched))] = 1.0
            static = np.asarray(self._solve(unit))
            dynamic = np.asarray(self._solve(M @ static))
            own = np.concatenate([static, dynamic], axis=1)
        else:
            own = self._corrections(p, theta, tangents)
        V = np.concatenate([self.common, own], axis=1)
        V = _orthonormal(V, V.T @ (M @ V))
        r = _width(V.shape[1])
        return Reduced(jnp.asarray(np.pad(V, ((0, 0), (0, r - V.shape[1])))), jnp.arange(r) >= V.shape[1])


def _width(columns: int) -> int:
    """The padded width of a basis of ``columns`` (:data:`WIDTHS`: 64, 96, 160, 256, 384, 576, ...)."""
    r, growth, multiple = WIDTHS
    while r < columns:
        r = -(-int(r * growth) // multiple) * multiple
    return r


def _orthonormal(V: np.ndarray, G: np.ndarray) -> np.ndarray:
    """V M-orthonormalised from its Gram matrix G = Vᵀ M V, each column first scaled to a
    unit M-norm; directions of M-norm² below ``MASS_FLOOR`` then (a column repeated, a
    load that vanishes) dropped."""
    d = np.sqrt(np.maximum(np.diag(G), 0.0))
    d = np.where(d > 0, d, 1.0)
    w, U = np.linalg.eigh(0.5 * (G + G.T) / np.outer(d, d))
    keep = w > MASS_FLOOR * w.max()
    return (V / d) @ (U[:, keep] / np.sqrt(w[keep]))
