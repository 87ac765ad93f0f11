"""The screening Jacobian: how much of the residual one Gauss–Newton step in a single
element's (group's) stiffness or mass removes (the linearised residual reduction ρ)."""

from __future__ import annotations

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from jaxfem import FAST_COMPILE, Model

from .. import Compiled, Parameter, Problem, residuals
from ._element_sensitivity import KINDS, ElementJacobian, element_jacobian
from ._localisation import reduction

MAC_LINEAR = 0.9  # a mode's shape rows enter the screen when it pairs with at least this MAC


@dataclass
class Screen:
    """Weighted residual ``r`` at the baseline and its linearisation: ``jac`` per element
    and kind of change (:mod:`updating.diagnosis._element_sensitivity`), ``J_b`` the baseline
    parameters; ``row_mode``: test mode of each row; ``f_e``, ``f_ref`` (Hz)."""

    r: np.ndarray
    jac: ElementJacobian
    J_b: np.ndarray
    row_mode: np.ndarray
    f_e: np.ndarray
    f_ref: float

    @classmethod
    def at(cls, problem: Problem, theta, model: Model, params: tuple[Parameter, ...], f_e: np.ndarray,
           kinds=KINDS, modes=None) -> Screen:
        """At θ of ``problem`` (whose first parameters are ``params`` of ``model``); the
        element columns of ``kinds`` (the baseline's stiffness and mass always); ``modes``:
        the model's at θ if solved (:func:`~updating.diagnosis._element_sensitivity.element_jacobian`)."""
        jac = element_jacobian(problem, np.asarray(theta), tuple(dict.fromkeys(("k", "m") + tuple(kinds))), modes)
        screen = cls(jac.r, jac, np.zeros((len(jac.r), 0)), _row_modes(problem),
                     f_e, float(np.exp(np.mean(np.log(f_e)))))
        if all(p.kind in ("stiffness", "mass") and not p.nodes for p in params):
            # a log-factor on a group is the sum of its elements' scales (d(k e^θ)/dθ = k)
            cols = [screen.column({"stiffness": "k", "mass": "m"}[p.kind], param_eids(model, p)) for p in params]
            screen.J_b = np.concatenate(cols, axis=1) if cols else screen.J_b
        else:
            screen.J_b = _baseline_columns(problem, theta, len(params))
        return screen

    def column(self, scales: str, eids) -> np.ndarray:
        """One column: the change ``scales`` (a kind of :data:`~updating.diagnosis._element_sensitivity.KINDS`:
        stiffness "k", mass "m", a shell part, shell non-structural mass) of ``eids`` together."""
        J, ids = self.jac.columns.get(scales), self.jac.ids.get(scales)
        if J is None:
            return np.zeros((len(self.r), 1))
        return J[:, np.isin(ids, np.asarray(list(eids), np.int64))].sum(axis=1, keepdims=True)

    def rho(self, columns: np.ndarray, joint: bool = False) -> np.ndarray | float:
        """Method (a), :func:`~updating.diagnosis._localisation.reduction` of ``columns`` beside the
        baseline's: on all rows or on the :meth:`linear` rows, whichever is higher."""
        rows = self.linear()
        return np.maximum(reduction(self.r, columns, self.J_b, joint=joint),
                          reduction(self.r[rows], columns[rows], self.J_b[rows], joint=joint))

    def linear(self) -> np.ndarray:
        """The rows a linearised step can follow: the eigenvalue rows and the shape rows of
        the modes paired with MAC ≥ :data:`MAC_LINEAR`. (A change that mixes modes, MAC 0.8,
        leaves shape residuals beyond the linear range that drown the other rows: on the
        2,500-DoF barrel they put a missing payload's mass screen on the skin. All rows
        still count in :meth:`rho`: without them a ground spring on the GARTEUR fuselage
        screened at the neighbouring grid.)"""
        return (np.arange(len(self.r)) < len(self.f_e)) | (self.jac.mac[self.row_mode] >= MAC_LINEAR)

    def element_reduction(self, scales: str = "k") -> dict[int, float]:
        """ρ (:meth:`rho`) of each element's change ``scales`` alone."""
        if scales not in self.jac.columns:
            return {}
        rho = self.rho(self.jac.columns[scales])
        return {int(e): float(v) for e, v in zip(self.jac.ids[scales], rho)}

    def step(self, columns: np.ndarray) -> np.ndarray:
        """The linearised (Gauss–Newton) step of ``columns``' amplitudes on the :meth:`linear`
        rows, the baseline parameters fitted with them."""
        rows = self.linear()
        a = np.concatenate([self.J_b, columns], axis=1)[rows]
        return np.linalg.lstsq(a, -self.r[rows], rcond=1e-10)[0][self.J_b.shape[1]:]

    def added_log_evidence(self, columns: np.ndarray, extra: np.ndarray, sd: float, sigma2: float) -> float:
        """Linearised ln B of one more column ``extra`` (its amplitude's prior N(0, sd²))
        beside ``columns`` and the baseline's, the rows' noise σ² (χ² = ‖r‖²/σ²): for a
        linear Gaussian model ``½ b²/(h + 1/sd²) − ½ ln(1 + h sd²)``, ``h = ‖j⊥‖²/σ²``,
        ``b = j⊥ᵀr/σ²``, ``j⊥`` the column with the others projected out; on all rows or
        on the :meth:`linear` rows, whichever is higher (as :meth:`rho`)."""
        def on(rows):
            q, _ = np.linalg.qr(np.concatenate([self.J_b, columns], axis=1)[rows])
            j = extra[rows, 0] - q @ (q.T @ extra[rows, 0])
            h, b = float(j @ j) / sigma2, float(j @ self.r[rows]) / sigma2
            return 0.5 * b * b / (h + 1 / sd ** 2) - 0.5 * np.log1p(h * sd ** 2)
        return max(on(np.ones(len(self.r), bool)), on(self.linear()))

    def law_columns(self, g: np.ndarray) -> np.ndarray:
        """A stiffness column and its frequency law: ``g`` and ``g·ln(f/f_ref)``."""
        return np.concatenate([g, g * np.log(self.f_e[self.row_mode] / self.f_ref)[:, None]], axis=1)


def _row_modes(problem: Problem) -> np.ndarray:
    """Test mode of each residual row (eigenvalue rows, then eigenvector rows)."""
    ne, ns = problem.phi_e.shape[1], problem.phi_e.shape[0]
    return np.concatenate([np.arange(ne), np.tile(np.arange(ne), ns)])


def _flat(theta, problem: Problem):
    eps, _ = residuals(theta, problem)
    return jnp.concatenate([jnp.ravel(eps[k]) for k in ("eigenvalue", "eigenvector")])


def _baseline_columns(problem: Problem, theta, n_b: int) -> np.ndarray:
    if n_b == 0:
        return np.zeros((len(_row_modes(problem)), 0))
    J = Compiled(jax.jacfwd(_flat), FAST_COMPILE)(jnp.asarray(theta), problem)
    return np.asarray(J)[:, :n_b]


def param_eids(model: Model, p: Parameter) -> np.ndarray:
    return np.union1d(model.element_ids(pids=p.pids) if p.pids else np.zeros(0, np.int64), np.asarray(p.eids, np.int64))
