"""Modal residuals ε(θ) = z_e − z_a(θ) with in-loop pairing (thesis §3.2.2).

The residual is a pytree for Optimistix: eigenvalue rows (eq. 3.12, normalised by λ_e,
§3.2.2.3), eigenvector rows at the measured DoFs (eq. 3.21, model vector scaled by the
modal scale factor, normalised by ‖φ_e‖), and the regularisation √μ·θ (eq. 3.4 with
W_p = μ I). Test and model modes are paired inside the function with the jittable
masked assignment, redone at every evaluation (footnote 1 of §3.2.2), so that the
update survives mode crossing and stays vmappable; the pairing is a discrete choice and
carries no derivative. Unpaired and passive test modes contribute zero rows.
"""

from __future__ import annotations

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Float

import jaxfem
from identification import mac, pair_modes_masked
from jaxfem import Model, Opaque

from ._compiled import Compiled
from ._parameters import Parameterisation


class Problem(eqx.Module):
    """Everything the residual needs; ``values`` are traced, the rest is structure.

    - ``lam_e`` (n_e,): measured eigenvalues (2π f)² in (rad/s)²; ``phi_e`` (n_s, n_e):
      real measured shapes at the sensors; ``C`` (n_s, n_dof): observation matrix;
    - ``active`` (n_e,) bool: modes in the fit; ``lam_weight`` (n_e,): eigenvalue-row
      weights; ``mu``: regularisation; ``use_lam``/``use_phi``: residual kinds;
      ``sparse``: the problem's eigensolver, resolved once (:func:`updating.resolve_eigensolver`).
    """

    values: Model
    structure: Opaque = eqx.field(static=True)  # the model's NumPy structure
    parameterisation: Parameterisation
    lam_e: Float[Array, " ne"]
    phi_e: Float[Array, "ns ne"]
    C: Float[Array, "ns ndof"]
    active: Bool[Array, " ne"]
    lam_weight: Float[Array, " ne"]
    mu: Float[Array, ""]
    n_model: int = eqx.field(static=True)
    use_lam: bool = eqx.field(static=True)
    use_phi: bool = eqx.field(static=True)
    min_mac: float = eqx.field(static=True)
    max_freq_dev: float = eqx.field(static=True)
    sparse: bool = eqx.field(static=True, default=False)  # the sparse eigensolver, else the dense
    extension: eqx.Module | None = None  # a candidate effect's parameters (updating.Extension)

    def model(self, theta: Float[Array, " p"]) -> Model:
        """The model at θ: the parameters' factors, then the extension's (trailing θ entries)."""
        n = len(self.parameterisation.parameters)
        model = self.parameterisation.apply(eqx.combine(self.values, self.structure.value), theta[:n])
        return model if self.extension is None else self.extension(model, theta[n:])


class Evaluation(eqx.Module):
    """Model modes paired with the test modes at one parameter point."""

    lam_a: Float[Array, " ne"]  # paired model eigenvalue per test mode
    phi_a: Float[Array, "ns ne"]  # paired model shape at the sensors
    model_index: Array  # model mode per test mode, −1 if unpaired
    paired: Bool[Array, " ne"]
    mac: Float[Array, " ne"]
    lam_model: Float[Array, " nm"]  # all computed model eigenvalues
    phi_model: Float[Array, "ns nm"]  # and their shapes at the sensors


def model_modes(theta: Float[Array, " p"], problem: Problem):
    """Eigenvalues of the model at θ and its shapes at the sensors, ``(λ, C φ)``."""
    lam, phi = jaxfem.modes(problem.model(theta), problem.n_model, solver="sparse" if problem.sparse else "dense")
    return lam, problem.C @ phi


def evaluate(theta: Float[Array, " p"], problem: Problem) -> Evaluation:
    """Solve the model at θ and pair its modes with the test modes: all modes by
    :func:`jaxfem.modes`, or, on the sparse path (``problem.sparse``), the lowest by
    :func:`jaxfem.sparse_modes`, of which only
    the paired ones are differentiated."""
    model = problem.model(theta)
    if problem.sparse:
        K, M = jaxfem.assemble(model)
        return paired_subspace(K, M, jaxfem.sparse_modes(K, M, problem.n_model), problem)
    lam, phi_s = model_modes(theta, problem)
    index, paired = pair(lam, phi_s, problem)
    safe = jnp.where(paired, index, 0)
    return paired_evaluation(lam[safe], phi_s[:, safe], index, paired, lam, phi_s, problem)


def paired_subspace(K, M, sol: jaxfem.Subspace, problem: Problem) -> Evaluation:
    """Pair the lowest ``n_model`` modes of a solve without derivative (:class:`jaxfem.Subspace`),
    then differentiate only the paired ones (:func:`jaxfem.ritz_modes`)."""
    phi_s = problem.C @ sol.basis[:, : problem.n_model]
    lam = sol.lam[: problem.n_model]
    index, paired = pair(lam, phi_s, problem)
    safe = jnp.where(paired, index, 0)
    lam_a, phi_a = jaxfem.ritz_modes(K, M, sol, safe)
    return paired_evaluation(lam_a, problem.C @ phi_a, index, paired, lam, phi_s, problem)


def pair(lam: Float[Array, " nm"], phi_s: Float[Array, "ns nm"], problem: Problem):
    """Masked one-to-one pairing of model modes with the test modes (no derivative):
    the model mode per test mode and whether it is paired."""
    f_a = jaxfem.frequencies_hz(jax.lax.stop_gradient(lam))
    f_e = jnp.sqrt(problem.lam_e) / (2 * jnp.pi)
    return pair_modes_masked(f_a, jax.lax.stop_gradient(phi_s), f_e, problem.phi_e,
                             min_mac=problem.min_mac, max_freq_dev=problem.max_freq_dev)


def paired_evaluation(lam_a, phi_a, index, paired, lam, phi_s, problem: Problem) -> Evaluation:
    """The :class:`Evaluation` from the paired model modes (λ_a, φ_a per test mode)."""
    macs = jnp.diagonal(mac(jax.lax.stop_gradient(phi_a), problem.phi_e))
    return Evaluation(lam_a, phi_a, index, paired, jnp.where(paired, macs, 0.0), lam, phi_s)


def residuals(theta: Float[Array, " p"], problem: Problem):
    """ε(θ) as a dict pytree, and the :class:`Evaluation` as auxiliary output."""
    ev = evaluate(theta, problem)
    return rows(theta, problem, ev), ev


def rows(theta: Float[Array, " p"], problem: Problem, ev: Evaluation) -> dict:
    """The residual rows of the paired active test modes, eq. 3.12, eq. 3.21, eq. 3.4."""
    fitted = ev.paired & problem.active
    out = {}
    if problem.use_lam:
        eps = (problem.lam_e - ev.lam_a) / problem.lam_e  # eq. 3.12, normalised
        out["eigenvalue"] = jnp.where(fitted, problem.lam_weight * eps, 0.0)
    if problem.use_phi:
        phi_e = problem.phi_e
        msf = jnp.sum(ev.phi_a * phi_e, axis=0) / jnp.sum(ev.phi_a * ev.phi_a, axis=0)
        eps = (phi_e - msf * ev.phi_a) / jnp.linalg.norm(phi_e, axis=0)  # eq. 3.21
        out["eigenvector"] = jnp.where(fitted[None, :], eps, 0.0)
    out["regularisation"] = jnp.sqrt(problem.mu) * theta
    return out


def auto_eigenvalue_weights(theta: Float[Array, " p"], problem: Problem) -> Float[Array, " ne"]:
    """Eigenfrequency weighting of §5.2.4: per mode, the eigenvalue row is scaled so that
    its gradient norm equals that of the mode's eigenvector rows (at θ), never below 1:
    frequencies keep at least their unweighted influence (the thesis' aim is that they
    weigh no less than the shapes), also where the shapes do not depend on θ."""
    unit = dataclasses.replace(problem, lam_weight=jnp.ones_like(problem.lam_weight),
                               use_lam=True, use_phi=True)
    jac = Compiled(jax.jacfwd(lambda t, p: residuals(t, p)[0]))(theta, unit)
    g_lam = jnp.linalg.norm(jac["eigenvalue"], axis=-1)
    g_phi = jnp.linalg.norm(jac["eigenvector"], axis=(0, 2))
    return jnp.maximum(1.0, jnp.where(g_lam > 0, g_phi / jnp.where(g_lam > 0, g_lam, 1.0), 1.0))


def paired_freq_dev(lam_a, paired, lam_e):
    """Δf = f_a/f_e − 1 of each test mode (eq. 4.1, with f ∝ √λ) from the paired model
    eigenvalues; NaN where unpaired (an unpaired row holds mode 0)."""
    return jnp.where(paired, jnp.sqrt(jnp.maximum(lam_a / lam_e, 0.0)) - 1, jnp.nan)
