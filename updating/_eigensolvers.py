"""Eigensolvers of the updating engine: model at θ → paired modes with exact derivatives.

Every solver takes the parameters θ, the :class:`Problem` and a warm start (the previous
iterate's basis, or an empty array), and returns the :class:`Evaluation` of the model
modes paired with the test modes (in-loop pairing, footnote 1 of thesis §3.2.2; the
pairing carries no derivative), the next warm start and two flags: the solve converged,
and it needed a fresh preconditioner. Derivatives of the paired modes are exact
(implicit differentiation, thesis eq. 3.23, eq. 3.28, eq. 3.29).

- :class:`Dense`: all modes by ``jaxfem.modes`` (LAPACK ``eigh``; massless DoFs condensed;
  frequency-dependent stiffness). The default of ``update`` and ``diagnose``.
- :class:`Refined`: all modes by ``jaxfem.dense_modes`` (K-standardised, refined to
  rounding), derivatives of the paired ones by ``jaxfem.ritz_modes``.
- :class:`Subspace`: the lowest modes by ``jaxfem.subspace``, warm-started from the last
  iterate and preconditioned with a fixed (K − σM)⁻¹ of a nearby model (Monte-Carlo).

A new solver (e.g. sparse shift-invert) subclasses :class:`AbstractEigensolver`.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

import jaxfem

from ._residuals import Evaluation, Problem, evaluate, pair, paired_evaluation

LOCKSTEP = "lockstep"  # vmap axis name of samples updated together (Monte-Carlo)


class AbstractEigensolver(eqx.Module):
    """Solve the model at θ, pair its modes with the test modes."""

    @abc.abstractmethod
    def __call__(self, theta: Float[Array, " p"], problem: Problem, warm: Array
                 ) -> tuple[Evaluation, Array, Bool[Array, ""], Bool[Array, ""]]:
        """``(evaluation, next warm start, converged, refreshed)``."""


class Dense(AbstractEigensolver):
    """All modes by :func:`jaxfem.modes`; no warm start."""

    def __call__(self, theta, problem, warm):
        return evaluate(theta, problem), warm, jnp.asarray(True), jnp.asarray(False)


def _paired(K, M, sol, problem: Problem) -> Evaluation:
    """Pair the solve's lowest ``n_model`` modes, then differentiate only the paired ones."""
    phi_s = problem.C @ sol.basis[:, : problem.n_model]
    lam = sol.lam[: problem.n_model]
    index, paired = pair(lam, phi_s, problem)
    safe = jnp.where(paired, index, 0)
    lam_a, phi_a = jaxfem.ritz_modes(K, M, sol, safe)
    return paired_evaluation(lam_a, problem.C @ phi_a, index, paired, lam, phi_s, problem)


class Refined(AbstractEigensolver):
    """All modes by :func:`jaxfem.dense_modes` (accurate to rounding); no warm start."""

    shift: float = eqx.field(static=True, default=0.0)

    def __call__(self, theta, problem, warm):
        K, M = jaxfem.assemble(problem.model(theta))
        sol = jaxfem.dense_modes(K, M, problem.n_model, shift=self.shift)
        return _paired(K, M, sol, problem), warm, jnp.asarray(True), jnp.asarray(False)


class Subspace(AbstractEigensolver):
    """Subspace iteration from the warm basis with the fixed preconditioner ``inverse``
    ≈ (K − σM)⁻¹. A solve that does not converge with it (a fit running far away) goes on
    from the basis reached with (K − σM)⁻¹ of this model (``refreshed``); decided for the
    whole lockstep batch (``lockstep`` > 1 samples under ``vmap``), so it stays a branch."""

    inverse: Float[Array, "n n"]
    shift: float = eqx.field(static=True, default=0.0)
    lockstep: int = eqx.field(static=True, default=1)

    def __call__(self, theta, problem, warm):
        K, M = jaxfem.assemble(problem.model(theta))
        Ks, Ms = jax.lax.stop_gradient((K, M))  # the solve carries no derivative (ritz_modes does)
        solve = lambda start, inverse: jaxfem.subspace(Ks, Ms, start, problem.n_model, shift=self.shift,
                                                       preconditioner=inverse)
        sol = solve(warm, self.inverse)
        refreshed = ~sol.converged
        anywhere = jax.lax.psum(refreshed.astype(jnp.int32), LOCKSTEP) > 0 if self.lockstep > 1 else refreshed
        sol = jax.lax.cond(anywhere,
                           lambda: solve(sol.basis, jaxfem.shifted_inverse(Ks, Ms, shift=self.shift)),
                           lambda: sol)
        return _paired(K, M, sol, problem), sol.basis, sol.converged, refreshed
