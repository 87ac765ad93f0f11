"""Eigensolvers of the updating engine: model at θ → paired modes with exact derivatives.

Every solver takes the parameters θ, the :class:`Problem` and a warm start (the previous
iterate's basis, or an empty array), and returns the :class:`Evaluation` of the model
modes paired with the test modes (in-loop pairing, footnote 1 of thesis §3.2.2; the
pairing carries no derivative), the next warm start and two flags: the solve converged,
and it needed a fresh preconditioner. Derivatives of the paired modes are exact
(implicit differentiation, thesis eq. 3.23, eq. 3.28, eq. 3.29).

- :class:`Direct`: the problem's own eigensolver (:func:`updating.evaluate`), chosen once
  when the problem is built (:func:`resolve_eigensolver`, ``Problem.sparse``): dense (``jaxfem.modes``: LAPACK ``eigh``, all modes; massless DoFs condensed;
  frequency-dependent stiffness) or sparse (``jaxfem.sparse_modes``, the lowest modes,
  derivatives of the paired ones by ``jaxfem.ritz_modes``). The default of ``update``
  and ``diagnose``.
- :class:`Refined`: all modes by ``jaxfem.dense_modes`` (K-standardised, refined to
  rounding), derivatives of the paired ones by ``jaxfem.ritz_modes``.
- :class:`Subspace`: the lowest modes by ``jaxfem.subspace``, warm-started from the last
  iterate and preconditioned with a fixed (K − σM)⁻¹ of a nearby model (Monte-Carlo).
- :class:`Reduced`: Rayleigh–Ritz on a fixed basis (:mod:`updating.diagnosis._reduced`): the
  diagnosis' candidate fits on a large model.

A new solver subclasses :class:`AbstractEigensolver`. One vocabulary names the choice
everywhere (``--solver``, ``Options.eigensolver``, ``DiagnoseOptions.eigensolver``,
``simulate_test``): :data:`EIGENSOLVERS`; a Monte-Carlo study's samples add ``subspace``
(:data:`STUDY_EIGENSOLVERS`, its ``dense`` being :class:`Refined`).
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

import jaxfem

from ._extension import THETA_MAX
from ._residuals import (
    Evaluation,
    Problem,
    evaluate,
    pair,
    paired_evaluation,
    paired_subspace,
)

LOCKSTEP = "lockstep"  # vmap axis name of samples updated together (Monte-Carlo)
EIGENSOLVERS = jaxfem.EIGENSOLVERS  # auto: sparse above jaxfem.SPARSE_ABOVE DoFs, unless frequency-dependent
STUDY_EIGENSOLVERS = ("subspace", "dense", "sparse")  # a Monte-Carlo study's samples


def eigensolver_name(requested: str | None, parameters=None) -> str:
    """The eigensolver asked for: ``requested`` (``--solver``, ``DiagnoseOptions.eigensolver``)
    unless it is None or ``auto``, then the parameter set's own; checked against :data:`EIGENSOLVERS`."""
    name = "auto" if requested is None else requested
    if name not in EIGENSOLVERS:
        raise ValueError(f"eigensolver must be one of {', '.join(EIGENSOLVERS)}, got {name!r}")
    if name == "auto" and parameters is not None:
        name = parameters.options.eigensolver
    return name


def resolve_eigensolver(name: str, model) -> bool:
    """The one resolver: whether ``name`` (:data:`EIGENSOLVERS`) means the sparse path for
    ``model`` (:func:`jaxfem.use_sparse`); a problem stores the answer (``Problem.sparse``)."""
    return jaxfem.use_sparse(model, eigensolver_name(name))


class AbstractEigensolver(eqx.Module):
    """Solve the model at θ, pair its modes with the test modes."""

    @abc.abstractmethod
    def __call__(self, theta: Float[Array, " p"], problem: Problem, warm: Array
                 ) -> tuple[Evaluation, Array, Bool[Array, ""], Bool[Array, ""]]:
        """``(evaluation, next warm start, converged, refreshed)``."""


class Direct(AbstractEigensolver):
    """The problem's own eigensolver (dense or sparse: ``problem.sparse``); no warm start."""

    def __call__(self, theta, problem, warm):
        return evaluate(theta, problem), warm, jnp.asarray(True), jnp.asarray(False)


class Refined(AbstractEigensolver):
    """All modes by :func:`jaxfem.dense_modes` (accurate to rounding); no warm start."""

    shift: float = eqx.field(static=True, default=0.0)

    def __call__(self, theta, problem, warm):
        K, M = jaxfem.assemble(problem.model(theta))
        sol = jaxfem.dense_modes(K, M, problem.n_model, shift=self.shift)
        return paired_subspace(K, M, sol, problem), warm, jnp.asarray(True), jnp.asarray(False)


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
        return paired_subspace(K, M, sol, problem), sol.basis, sol.converged, refreshed


def padded(kr, mr, padding):
    """The symmetric reduced matrices with each ``padding`` column an uncoupled mode just
    above the others: M 1, K twice the bound λ_max(K_r)/λ_min(M_r) of the largest
    eigenvalue (λ_min(M_r) floored at ε·max M_r), no further. :func:`jaxfem.eigh` groups
    eigenvalues closer than 1e3·ε·max|λ| as one cluster: padding at 1e3× the stiffest
    diagonal widened that enough to merge distinct modes and average their derivatives
    (on the 33k barrel, springs held stiff, the reduced gradient came out 25–57× too
    small and the seam's fits stalled)."""
    pad = padding.astype(mr.dtype)
    ks, ms = jax.lax.stop_gradient((kr, mr + jnp.diag(pad)))
    lk, lm = jnp.linalg.eigvalsh(ks)[-1], jnp.linalg.eigvalsh(ms)[0]
    floor = jnp.finfo(mr.dtype).eps * jnp.max(jnp.abs(jnp.diagonal(ms)))
    top = 2.0 * jnp.abs(lk) / jnp.maximum(lm, floor) + 1.0
    return kr + jnp.diag(top * pad), mr + jnp.diag(pad)


class Reduced(AbstractEigensolver):
    """The modes of the model projected on a fixed basis V (n × r): ``Vᵀ K(θ) V y = λ Vᵀ M(θ) V y``,
    φ = V y (Rayleigh–Ritz). The reduced matrices are assembled from K(θ), M(θ) at every θ,
    so their derivatives are those of the reduced problem, exact (:func:`jaxfem.eigh`).
    With a ``pool`` of element ids holding every element that θ changes, only the pool
    is assembled: ``Vᵀ K(θ) V = fixed + Vᵀ K_pool(θ) V`` (``fixed``: the rest, constant),
    exact and cheap on a large model. With ``linear`` (K and M linear in each factor
    e^θᵢ of the extension's parameters, checked by :meth:`updating.diagnosis._reduced.Bases._linear`:
    a group's factor, dormant masses or springs woken, springs that hold a connection,
    a patch's part of its shells' stiffness): ``Vᵀ K(θ) V = fixed + Σᵢ (e^(θᵢ − cᵢ) − 1)
    Vᵀ ∂ᵢK V`` about the basis' ``centre`` c, no assembly at all (600 shells projected at
    r = 768: 0.3 s, an eigensolution of that size 0.07 s; the 33k seam's fits 3.5× faster). Accurate while the basis spans the changed shapes
    (:mod:`updating.diagnosis._reduced`). Columns ``padding`` (zero, so that bases of different
    sizes share a compiled fit) enter as uncoupled modes just above the others (:func:`padded`). ``observed``:
    the basis at the sensors, C V, formed once (C V at every θ took a fifth of a reduced
    evaluation at 33,000 DoFs)."""

    basis: Float[Array, "n r"]
    padding: Bool[Array, " r"]
    observed: Float[Array, "s r"]
    fixed: tuple[Float[Array, "r r"], Float[Array, "r r"]] | None = None
    pool: tuple[int, ...] | None = eqx.field(static=True, default=None)
    linear: tuple[Float[Array, "p r r"], Float[Array, "p r r"]] | None = None
    centre: Float[Array, " p"] | None = None

    def __call__(self, theta, problem, warm):
        V = self.basis
        if self.linear is not None:  # K and M linear in the extension's factors, nothing else moving
            n = len(problem.parameterisation.parameters)
            g = jnp.expm1(jnp.clip(theta[n:n + self.centre.shape[0]], -THETA_MAX, THETA_MAX) - self.centre)
            kr, mr = (f + jnp.tensordot(g, d, axes=1) for f, d in zip(self.fixed, self.linear))
        elif self.pool is None:
            K, M = jaxfem.assemble(problem.model(theta))
            kr, mr = V.T @ K.matmul(V), V.T @ M.matmul(V)
        else:
            K, M = jaxfem.assemble(problem.model(theta).restricted(self.pool))
            kr, mr = self.fixed[0] + K.project(V), self.fixed[1] + M.project(V)
        kr, mr = padded(0.5 * (kr + kr.T), 0.5 * (mr + mr.T), self.padding)
        lam, y = jaxfem.eigh(kr, mr, problem.n_model)
        phi_s = self.observed @ y
        index, paired = pair(lam, phi_s, problem)
        safe = jnp.where(paired, index, 0)
        ev = paired_evaluation(lam[safe], phi_s[:, safe], index, paired, lam, phi_s, problem)
        return ev, warm, jnp.asarray(True), jnp.asarray(False)
