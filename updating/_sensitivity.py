"""Parameter selection aids of thesis §4.2.4.1: sensitivities, identifiability, test runs.

- :func:`sensitivities`: column norms of the eigen-gradient matrix, eq. 4.3, each scaled
  to a largest value of 1; a parameter below 0.1 in both is flagged (footnote 5).
- :func:`identifiability`: singular values, condition number and nearly collinear columns
  of the weighted residual Jacobian (ill-conditioning, footnote 3 of §4.2.4).
- :func:`test_run`: the test procedure of Fig. 4.4: inject the parameters as modelling
  errors, simulate the measurement at the sensors, update, check that α is recovered.

Derivatives are taken w.r.t. θ = log(1 + α) by forward mode through the implicit
differentiation rule of ``jaxfem.eigh``; at θ = 0, ∂/∂θ = (1 + α) ∂/∂α = ∂/∂α.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

from identification import ModalData, Sensors
from jaxfem import Model

from ._compiled import Compiled
from ._parameters import Parameter, ParameterSet, parameterise
from ._residuals import Problem, evaluate, residuals
from ._result import UpdateResult
from ._simulation import Noise, simulate_test
from ._solve import build_problem, update


def _paired_modes(theta: Float[Array, " p"], problem: Problem):
    """Paired model eigenvalues and sensor shapes (the model side of eq. 4.3)."""
    ev = evaluate(theta, problem)
    return (ev.lam_a, ev.phi_a), ev


def _jacobian(problem: Problem, theta: Float[Array, " p"]):
    """∂ε/∂θ per residual leaf as (rows, p), weights included, regularisation left out;
    and the :class:`Evaluation` at θ."""
    jac, ev = Compiled(jax.jacfwd(residuals, has_aux=True))(theta, problem)
    return {k: np.asarray(v).reshape(-1, theta.shape[0]) for k, v in jac.items() if k != "regularisation"}, ev


def _scaled(x: np.ndarray) -> np.ndarray:
    top = np.max(x)
    return x / top if top > 0 else np.zeros_like(x)


@dataclasses.dataclass
class Sensitivities:
    """Parameter sensitivities of eq. 4.3 over the modes ``modes``.

    ``s_lam``, ``s_phi`` (p,): S_λ,k and S_φ,k scaled so that the largest is 1;
    ``flagged`` (p,): both below ``threshold``; ``raw_lam``, ``raw_phi`` (p,): the unscaled
    norms; ``jac_lam`` (m, p): ∂λ_r/∂α_k in (rad/s)²; ``jac_phi`` (n_s, m, p): ∂φ_r/∂α_k of
    the mass-normalised shapes at the sensors; ``modes`` (m,): model mode numbers (1-based).
    """

    names: list[str]
    s_lam: np.ndarray
    s_phi: np.ndarray
    flagged: np.ndarray
    raw_lam: np.ndarray
    raw_phi: np.ndarray
    jac_lam: np.ndarray
    jac_phi: np.ndarray
    modes: np.ndarray
    threshold: float

    def table(self) -> list[dict]:
        """One row per parameter: name, S_λ, S_φ (scaled) and the flag."""
        return [{"name": n, "s_lam": float(a), "s_phi": float(b), "flagged": bool(f)}
                for n, a, b, f in zip(self.names, self.s_lam, self.s_phi, self.flagged)]

    def summary(self) -> str:
        width = max(len("parameter"), *(len(n) for n in self.names))
        lines = [f"{'parameter':<{width}}  S_lam   S_phi   (eq. 4.3, max = 1; modes {self.modes.tolist()})"]
        for row in self.table():
            flag = f"  < {self.threshold:g}: omit or redefine" if row["flagged"] else ""
            lines.append(f"{row['name']:<{width}}  {row['s_lam']:.3f}   {row['s_phi']:.3f}{flag}")
        return "\n".join(lines)


def _as_set(parameters: ParameterSet | Sequence[Parameter]) -> ParameterSet:
    return parameters if isinstance(parameters, ParameterSet) else ParameterSet(tuple(parameters))


def sensitivities(
    model: Model,
    parameters: ParameterSet | Sequence[Parameter],
    test_or_modes: ModalData | Sensors,
    *,
    n_modes: int | None = None,
    threshold: float = 0.1,
) -> Sensitivities:
    """Eigenvalue and eigenvector sensitivity of each parameter, thesis eq. 4.3.

    S_λ,k = ‖∂λ_a/∂α_k‖ over the modes and S_φ,k = ‖∂φ_a/∂α_k‖ over the modes and the
    measured DoFs, at α = 0, each divided by its largest value over the parameters. A
    parameter whose scaled S_λ and S_φ are both below ``threshold`` is flagged (0.1,
    §4.2.4.1 footnote 5).

    **Arguments:** the nominal model; the parameters; either measured modes (ModalData:
    the model modes paired with the active test modes, as in the updating residual) or
    Sensors with ``n_modes`` (the model's own lowest modes at the sensors serve as test).

    **Returns:** :class:`Sensitivities`.
    """
    pset = _as_set(parameters)
    if isinstance(test_or_modes, Sensors):
        if n_modes is None:
            raise ValueError("sensitivities at Sensors need n_modes, the number of model modes")
        test = _simulate(model, test_or_modes, pset, np.zeros(len(pset.parameters)), n_modes)
    elif isinstance(test_or_modes, ModalData):
        if n_modes is not None:
            raise ValueError("n_modes is only used with Sensors; ModalData selects its paired active modes")
        test = test_or_modes
    else:
        raise ValueError(f"test_or_modes must be ModalData or Sensors, got {type(test_or_modes).__name__}")
    # No residual weights in eq. 4.3: skip computing the automatic ones.
    unweighted = dataclasses.replace(pset, options=dataclasses.replace(pset.options, eigenvalue_weight=1.0))
    problem = build_problem(model, test, unweighted)
    names = [p.name for p in problem.parameterisation.parameters]
    (jl, jp), ev = Compiled(jax.jacfwd(_paired_modes, has_aux=True))(jnp.zeros(len(names)), problem)
    keep = np.asarray(ev.paired & problem.active)
    if not keep.any():
        raise ValueError("no active test mode is paired with a model mode")
    modes = np.asarray(ev.model_index)[keep] + 1
    jac_lam, jac_phi = np.asarray(jl)[keep], np.asarray(jp)[:, keep]
    raw_lam = np.linalg.norm(jac_lam, axis=0)
    raw_phi = np.linalg.norm(jac_phi, axis=(0, 1))
    s_lam, s_phi = _scaled(raw_lam), _scaled(raw_phi)
    return Sensitivities(names, s_lam, s_phi, (s_lam < threshold) & (s_phi < threshold),
                         raw_lam, raw_phi, jac_lam, jac_phi, modes, float(threshold))


@dataclasses.dataclass
class Identifiability:
    """Conditioning of the weighted residual Jacobian J = ∂ε/∂θ (rows of eq. 3.12, eq. 3.21).

    ``singular_values`` (p,), descending (zeros when J has fewer rows than columns);
    ``condition_number`` σ_max/σ_min (inf if σ_min = 0); ``cosines`` (p, p): |cos| of the
    angles between the columns of J; ``collinear``: pairs (a, b, |cos|) with |cos| ≥ the
    threshold; ``weakest``: the parameters that carry ``dominance`` of the squared
    components of the smallest right singular vector ``weakest_vector``.
    """

    names: list[str]
    singular_values: np.ndarray
    condition_number: float
    cosines: np.ndarray
    collinear: list[tuple[str, str, float]]
    weakest: list[str]
    weakest_vector: np.ndarray
    max_condition: float

    @property
    def well_posed(self) -> bool:
        """No collinear pair and a condition number ≤ ``max_condition``."""
        return not self.collinear and self.condition_number <= self.max_condition

    def summary(self) -> str:
        lines = [
            "singular values: " + ", ".join(f"{s:.3e}" for s in self.singular_values),
            f"condition number: {self.condition_number:.3e}",
            "collinear pairs: " + (", ".join(f"{a}–{b} (|cos| {c:.4f})" for a, b, c in self.collinear) or "none"),
            "smallest singular vector dominated by: " + ", ".join(self.weakest),
        ]
        if not self.well_posed:
            lines.append(f"WARNING: ill-conditioned parameter set (condition > {self.max_condition:g} or "
                         "collinear columns): merge, omit or redefine the parameters named above")
        return "\n".join(lines)


def identifiability(
    problem_or_model: Problem | Model,
    test: ModalData | None = None,
    parameters: ParameterSet | None = None,
    *,
    theta: Float[Array, " p"] | None = None,
    collinear: float = 0.95,
    max_condition: float = 1e6,
    dominance: float = 0.9,
) -> Identifiability:
    """Identifiability of the parameters from the weighted residual Jacobian.

    J stacks the eigenvalue and eigenvector rows of ε(θ) (eq. 3.12, eq. 3.21, weights
    included, regularisation rows excluded) at ``theta`` (default 0). A (near) rank
    deficiency, one parameter a linear combination of others (§4.2.4, footnote 3), shows
    as a large condition number; its direction is the smallest right singular vector.

    **Arguments:** a :class:`Problem`, or ``(model, test, parameters)`` to build one;
    ``collinear``: |cos| between columns from which a pair is reported; ``max_condition``:
    the condition number above which the set is ill-posed; ``dominance``: share of the
    squared smallest singular vector that the ``weakest`` parameters carry.

    **Returns:** :class:`Identifiability`.
    """
    if isinstance(problem_or_model, Problem):
        if test is not None or parameters is not None:
            raise ValueError("give either a Problem or (model, test, parameters), not both")
        problem = problem_or_model
    elif isinstance(problem_or_model, Model):
        if test is None or parameters is None:
            raise ValueError("identifiability(model, test, parameters) needs the test data and the parameters")
        problem = build_problem(problem_or_model, test, _as_set(parameters))
    else:
        raise ValueError(f"expected a Problem or a Model, got {type(problem_or_model).__name__}")
    names = [p.name for p in problem.parameterisation.parameters]
    n_p = len(names)
    theta = jnp.zeros(n_p) if theta is None else jnp.asarray(theta, dtype=jnp.float64)
    if theta.shape != (n_p,):
        raise ValueError(f"theta has shape {theta.shape} for {n_p} parameters")
    J = np.concatenate(list(_jacobian(problem, theta)[0].values()))
    _, s, vt = np.linalg.svd(J, full_matrices=True)
    s = np.concatenate([s, np.zeros(n_p - len(s))])
    cond = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    norms = np.linalg.norm(J, axis=0)
    unit = J / np.where(norms > 0, norms, 1.0)
    cos = np.abs(unit.T @ unit)
    i, j = np.nonzero(np.triu(cos >= collinear, k=1))
    pairs = [(names[a], names[b], float(cos[a, b])) for a, b in zip(i, j)]
    v = vt[-1]
    order = np.argsort(-(v**2))
    share = np.cumsum(v[order] ** 2) / np.sum(v**2)
    weakest = [names[k] for k in order[: int(np.searchsorted(share, dominance)) + 1]]
    return Identifiability(names, s, cond, cos, pairs, weakest, v, float(max_condition))


def _simulate(model: Model, sensors: Sensors, parameters: ParameterSet, alpha: np.ndarray, n_modes: int,
              noise: Noise | None = None, key: PRNGKeyArray | None = None) -> ModalData:
    """The model with the factors α applied, measured by :func:`simulate_test` (Fig. 4.4)."""
    base, par = parameterise(model, parameters)
    truth = par.apply(base, jnp.log1p(jnp.asarray(alpha, dtype=jnp.float64)))
    return simulate_test(truth, sensors, n_modes, noise, key)


@dataclasses.dataclass
class Recovery:
    """Outcome of :func:`test_run`: per parameter the injected α, the recovered α, the
    absolute error, the tolerance and whether it was met; the update and the
    identifiability of the set against the simulated data at the nominal model."""

    names: list[str]
    injected: np.ndarray
    alpha: np.ndarray
    error: np.ndarray
    tolerance: np.ndarray
    recovered: np.ndarray
    converged: bool
    identifiability: Identifiability
    simulated: ModalData
    update: UpdateResult

    @property
    def all_recovered(self) -> bool:
        """Every factor within its tolerance (convergence is reported apart)."""
        return bool(np.all(self.recovered))

    def table(self) -> list[dict]:
        return [{"name": n, "injected": float(a), "recovered_alpha": float(b), "error": float(e),
                 "tolerance": float(t), "recovered": bool(r)} for n, a, b, e, t, r in
                zip(self.names, self.injected, self.alpha, self.error, self.tolerance, self.recovered)]

    def summary(self) -> str:
        width = max(len("parameter"), *(len(n) for n in self.names))
        lines = [f"{'parameter':<{width}}  injected   recovered  |error|    tolerance"]
        for r in self.table():
            lines.append(f"{r['name']:<{width}}  {r['injected']:+.6f}  {r['recovered_alpha']:+.6f}  "
                         f"{r['error']:.2e}   {r['tolerance']:.2e}{'' if r['recovered'] else '  NOT RECOVERED'}")
        lines.append(f"all recovered: {self.all_recovered}; converged: {self.converged} "
                     f"in {self.update.iterations} iterations")
        if not self.identifiability.well_posed:
            lines.append(self.identifiability.summary())
        return "\n".join(lines)


def parameter_std(problem: Problem, theta: Float[Array, " p"], noise: Noise) -> np.ndarray:
    """Linearised standard deviation of the factors α at θ for measurement noise: Cov θ = J⁺ Σ J⁺ᵀ,
    Σ = diag(σ²) with σ = w σ_freq per eigenvalue row (eq. 3.12) and, per eigenvector row
    (eq. 3.21), the shape errors' σ over ‖φ_e,j‖: σ_rel |φ_e,ij| and a max_i |φ_e,ij| / √3
    of the uniform absolute error; σ_α = e^θ σ_θ."""
    jac, ev = _jacobian(problem, theta)
    rows = np.asarray(ev.paired & problem.active)
    phi_e = np.asarray(problem.phi_e)
    sigma = {
        "eigenvalue": np.where(rows, np.asarray(problem.lam_weight) * noise.frequency, 0.0),
        "eigenvector": np.where(rows[None, :], np.hypot(noise.relative * np.abs(phi_e),
                                                        noise.absolute * np.max(np.abs(phi_e), axis=0) / np.sqrt(3))
                                / np.linalg.norm(phi_e, axis=0), 0.0),
    }
    J = np.concatenate(list(jac.values()))
    s = np.concatenate([sigma[k].reshape(-1) for k in jac])
    pinv = np.linalg.pinv(J)
    return np.exp(np.asarray(theta)) * np.sqrt(np.sum((pinv * s[None, :]) ** 2, axis=1))


def test_run(
    model: Model,
    test_sensors: Sensors,
    parameters: ParameterSet | Sequence[Parameter],
    errors: Sequence[float],
    *,
    n_modes: int = 10,
    noise: Noise | None = None,
    key: PRNGKeyArray | None = None,
    tol: float = 1e-3,
) -> Recovery:
    """Test run of a parameter set, thesis Fig. 4.4 (§4.2.4.1, third step).

    The errors α (one per parameter) are applied to ``model`` to make the "truth"; its
    lowest ``n_modes`` modes at ``test_sensors`` are the simulated measurement, with
    optional :class:`Noise` drawn from ``key``; ``model`` is then updated against them.
    A well-posed set recovers every α: a parameter counts as recovered when
    |α − α_injected| ≤ ``tol``, or, with noise, ≤ 3 σ_α of the noise propagated through
    the linearised least-squares solution if larger.

    **Returns:** :class:`Recovery`.
    """
    parameters = _as_set(parameters)
    n_p = len(parameters.parameters)
    errors = np.asarray(errors, dtype=np.float64).reshape(-1)
    if errors.shape != (n_p,):
        raise ValueError(f"{len(errors)} errors for {n_p} parameters {parameters.names}")
    bad = [n for n, a in zip(parameters.names, errors) if not a > -1.0]
    if bad:
        raise ValueError(f"errors must be > -1 (α = value/value₀ − 1); not so for {bad}")
    if noise is not None and key is None:
        raise ValueError("noise needs a JAX random key")
    simulated = _simulate(model, test_sensors, parameters, errors, n_modes, noise, key)
    result = update(model, simulated, parameters)
    problem = build_problem(model, simulated, parameters)
    tolerance = np.full(n_p, float(tol))
    if noise is not None:
        tolerance = np.maximum(tolerance, 3.0 * parameter_std(problem, jnp.asarray(result.theta), noise))
    error = np.abs(result.alpha - errors)
    return Recovery(parameters.names, errors, result.alpha, error, tolerance, error <= tolerance,
                    result.converged, identifiability(problem), simulated, result)


test_run.__test__ = False  # a library function, not a pytest test, when imported into tests
