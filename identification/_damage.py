"""Damage localisation from damage-induced changes of modal damping, thesis §3.3 and §5.3.

A local damage (a delamination, a loosened joint) softens a few elements and adds
friction there. Both show up globally: the natural frequencies drop and the modal
damping rises, by an amount that depends on how much strain energy each mode puts into
the damaged region. Comparing measured relative damping changes (healthy → damaged)
with the changes a finite-element model predicts for a damage placed at each candidate
location, the correlation coefficient C of eq. 3.45 peaks at the true location
(eq. 3.46).

Damping model (§3.3.3). The healthy structure has Rayleigh damping ``D = μM + κK``
(eq. 1.29), i.e. modal ratios ``ζ_n = μ/(2ω_n) + κω_n/2`` (eq. 3.40; the thesis
writes them η_a,n), with μ, κ fitted to the measured healthy ratios by least squares
(:func:`fit_rayleigh`). A damage candidate G scales the stiffness of its elements by
``1 − s`` and gives them a structural loss factor η_d, i.e. adds ``iη_d K_G`` to the
dynamic stiffness (Ewins §2.3). For a delamination of a laminated shell (thesis
§5.3.2.1) only the transverse-shear stiffness of the candidate's shells is softened
(``part="shear"``, K_G⁰ the shear part; :mod:`identification._damage_model`), and the
candidates are patches of shell elements (:func:`identification.shell_patches`). Its
modal ratios follow from the real modes of the damaged model by modal strain energy
(first-order perturbation of the complex eigenvalue, Ungar & Kerwin 1962; Johnson &
Kienholz 1982):

    ζ_n^D = μ/(2ω_n^D) + κω_n^D/2 + ½ η_d φ_nᵀ K_G φ_n / φ_nᵀ K^D φ_n

with ``K^D = K − s K_G⁰`` the damaged stiffness and ``K_G = (1 − s) K_G⁰`` the damaged
stiffness of the group (φ mass-normalised, so ``φᵀK^Dφ = ω²``). The thesis (§5.3.2)
evaluates eq. 3.40 on the damaged model only; the loss-factor term is the
"additional friction" of §3.3.1, set to zero by ``loss_factor=0``.

Measured ratios come from the user (any modal fit, e.g. one SDOF inverse-FRF fit per
resonance, eq. 3.34, eq. 3.35, eq. 3.36, eq. 3.37, :func:`identification.sdof_fit`, as in the
demonstration ``benchmarks/damage_demo.py``). Units: frequencies in Hz at the boundary, ω in rad/s inside.

Here: the scan over the candidates (:func:`localise_damage`, :class:`DamageScan`). The
Rayleigh fit, deviations and C are in :mod:`identification._deviations`, the damping of a
damaged model in :mod:`identification._damage_model`, the map in
:mod:`identification._plots`.
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import numpy as np
from jaxtyping import Float, Int

from jaxfem import Model

from ._damage_model import PARTS, _check_n_modes, _check_part, _group_masks, _scan_damping, damage_damping
from ._deviations import _positive, _scalar, _vector, damping_correlation, damping_deviations, fit_rayleigh
from ._plots import plot_damage_map

# the scan, and the names tests and benchmarks import from here (before the split into
# _deviations, _damage_model and _plots they were defined here)
__all__ = ["DamageScan", "PARTS", "localise_damage", "damage_damping", "damping_correlation",
           "damping_deviations", "fit_rayleigh", "plot_damage_map"]


# ----------------------------------------------------------------------------- checks


def _modal_pair(name: str, data) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies_hz, damping_ratios) from a ModalData-like object or a pair of arrays."""
    if hasattr(data, "frequencies_hz") and hasattr(data, "damping_ratios"):
        f, z = data.frequencies_hz, data.damping_ratios
    else:
        try:
            f, z = data
        except (TypeError, ValueError):
            raise ValueError(
                f"{name} must be ModalData or a pair (frequencies_hz, damping_ratios)"
            ) from None
    f = _positive(f"{name} frequencies_hz", _vector(f"{name} frequencies_hz", f))
    z = _positive(f"{name} damping_ratios", _vector(f"{name} damping_ratios", z, len(f)))
    return f, z


def _mode_indices(mode_indices, n: int) -> np.ndarray:
    if mode_indices is None:
        return np.arange(n, dtype=np.int64)
    idx = np.asarray(mode_indices)
    if idx.ndim != 1 or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"mode_indices must be a 1-D sequence of integers, got {mode_indices!r}")
    if len(idx) != n:
        raise ValueError(f"mode_indices has {len(idx)} entries for {n} measured modes")
    if np.any(idx < 0):
        raise ValueError(f"mode_indices must be non-negative (0 = lowest model mode), got {idx.tolist()}")
    if len(np.unique(idx)) != len(idx):
        raise ValueError(f"mode_indices has repeated entries: {idx.tolist()}")
    return idx.astype(np.int64)


# ----------------------------------------------------------------------- localisation


class DamageScan(eqx.Module):
    """Result of :func:`localise_damage`: eq. 3.45 at every candidate location.

    **Fields:**

    - ``groups``: the candidates, each a tuple of element ids.
    - ``correlation`` (c,): C per candidate, eq. 3.45.
    - ``predicted`` (c, m): Δη_a per candidate, eq. 3.42, eq. 3.44.
    - ``measured`` (m,): Δη_e, eq. 3.41, eq. 3.43.
    - ``predicted_hz`` (c, m): natural frequencies of each damaged model.
    - ``model_hz`` (m,), ``model_damping`` (m,): the healthy model's frequencies and
      eq. 3.40 ratios of the compared modes.
    - ``mode_indices`` (m,): model mode (0-based) of each measured mode.
    - ``mu`` (1/s), ``kappa`` (s): the Rayleigh constants used.
    """

    groups: tuple[tuple[int, ...], ...]
    correlation: Float[np.ndarray, " c"]
    predicted: Float[np.ndarray, "c m"]
    measured: Float[np.ndarray, " m"]
    predicted_hz: Float[np.ndarray, "c m"]
    model_hz: Float[np.ndarray, " m"]
    model_damping: Float[np.ndarray, " m"]
    mode_indices: Int[np.ndarray, " m"]
    mu: float
    kappa: float

    @property
    def best(self) -> int:
        """Index of the candidate with the largest C (the located damage, eq. 3.46)."""
        return int(np.argmax(self.correlation))

    @property
    def best_group(self) -> tuple[int, ...]:
        """Element ids of the located damage."""
        return self.groups[self.best]

    def ranking(self, k: int | None = None) -> list[tuple[tuple[int, ...], float]]:
        """The ``k`` best candidates (all by default) as ``(element ids, C)``, best first."""
        order = np.argsort(-self.correlation, kind="stable")[:k]
        return [(self.groups[i], float(self.correlation[i])) for i in order]

    def element_values(self) -> dict[int, float]:
        """C per element id (each element of a group gets its group's C; the largest if an
        element is in several groups); the ``element_values`` of a structure plot."""
        out: dict[int, float] = {}
        for g, c in zip(self.groups, self.correlation):
            for e in g:
                out[e] = max(out.get(e, -np.inf), float(c))
        return out


def localise_damage(
    model: Model,
    healthy,
    damaged,
    *,
    stiffness_reduction: float,
    loss_factor: float,
    candidates: Sequence[Sequence[int]] | None = None,
    mode_indices: Sequence[int] | None = None,
    mu: float | None = None,
    kappa: float | None = None,
    part: str = "all",
    first_order: bool = False,
) -> DamageScan:
    """Locate a single damage by correlating damping deviations, thesis §3.3.4 and §5.3.5.

    Measured deviations Δη_e (eq. 3.41) are compared with the deviations Δη_a
    (eq. 3.42) that the model predicts for a damage of the given kind placed in each
    candidate in turn; the candidate with the largest C (eq. 3.45) is the located
    damage (eq. 3.46). Only the direction of Δη_a matters to C, so the damage
    size enters through the balance of the stiffness reduction (Rayleigh part, via the
    frequency shift) and the added loss factor.

    **Arguments:**

    - ``model``: the (preferably updated, §5.3) model of the healthy structure.
    - ``healthy``, ``damaged``: the measured modes of each state, as
      :class:`identification.ModalData` or pairs ``(frequencies_hz, damping_ratios)``;
      the same modes in the same order (at least two), damping ratios positive.
    - ``stiffness_reduction`` s in [0, 1) and ``loss_factor`` η_d ≥ 0: the damage
      model (module docstring).
    - ``candidates``: groups of element ids; default every beam and rod on its own.
    - ``mode_indices``: the model mode (0-based) of each measured mode; default
      0, 1, … (the lowest modes, in order).
    - ``mu``, ``kappa``: Rayleigh constants; default fitted to the healthy measurement
      (:func:`fit_rayleigh`, eq. 3.40). Give both or neither.
    - ``part``: the stiffness a candidate softens: ``"all"`` (default, the whole element
      stiffness) or ``"shear"`` (the transverse-shear stiffness of shells only: the
      delamination model of thesis §5.3.2.1, G_xz and G_yz reduced; candidates must then
      be shells with shear flexibility, e.g. from :func:`identification.shell_patches`).
    - ``first_order``: predict from the healthy modes by modal strain energy
      (``ω_D² ≈ ω² − s φᵀK_G⁰φ``, eq. 3.40 at ω_D plus the loss term;
      :mod:`identification._damage_model`) instead of an eigensolution per candidate: one
      eigensolution for the whole scan, for large models and many candidates; accurate
      while the damage shifts the frequencies little (``s φᵀK_G⁰φ ≪ ω²``).

    **Returns:** a :class:`DamageScan`.
    """
    f_h, z_h = _modal_pair("healthy", healthy)
    f_d, z_d = _modal_pair("damaged", damaged)
    if len(f_h) != len(f_d):
        raise ValueError(f"healthy data has {len(f_h)} modes but damaged data has {len(f_d)}")
    if len(f_h) < 2:
        raise ValueError(f"at least two modes are needed (C of one mode is always 1), got {len(f_h)}")
    idx = _mode_indices(mode_indices, len(f_h))
    _check_n_modes(model, idx)
    part = _check_part(part)
    s = _scalar("stiffness_reduction", stiffness_reduction, 0.0, 1.0, open_high=True)
    eta = _scalar("loss_factor", loss_factor, 0.0)
    if s == 0.0 and eta == 0.0:
        raise ValueError("the damage model changes nothing: give stiffness_reduction > 0 or loss_factor > 0")
    if (mu is None) != (kappa is None):
        raise ValueError("give both mu and kappa, or neither (then they are fitted to the healthy data)")
    if mu is None:
        mu, kappa = (float(v) for v in fit_rayleigh(f_h, z_h))
    else:
        mu, kappa = _scalar("mu", mu, -np.inf), _scalar("kappa", kappa, -np.inf)
    if candidates is None:
        candidates = [(int(e),) for e in np.concatenate([model.beams.ids, model.rods.ids])]
        if not candidates:
            raise ValueError("the model has no beams or rods: pass candidates explicitly "
                             "(for shells: identification.shell_patches)")
    groups = tuple(tuple(int(e) for e in g) for g in candidates)
    masks = _group_masks(model, groups, part)

    omega_h, omega_d, zeta_d = _scan_damping(model, masks, idx, s, eta, mu, kappa, part, bool(first_order))
    zeta_h = 0.5 * (mu / omega_h + kappa * omega_h)  # eq. 3.40
    if np.any(zeta_h <= 0):
        k = int(np.flatnonzero(zeta_h <= 0)[0])
        raise ValueError(
            f"the Rayleigh model gives damping {zeta_h[k]:.3g} for model mode {int(idx[k])}; "
            f"μ = {mu:.3g} 1/s, κ = {kappa:.3g} s do not describe the healthy structure"
        )
    measured = damping_deviations(z_d, z_h)  # eq. 3.41
    predicted = damping_deviations(zeta_d, zeta_h)  # eq. 3.42
    return DamageScan(
        groups=groups,
        correlation=damping_correlation(predicted, measured),  # eq. 3.45
        predicted=predicted,
        measured=measured,
        predicted_hz=omega_d / (2.0 * np.pi),
        model_hz=omega_h / (2.0 * np.pi),
        model_damping=zeta_h,
        mode_indices=idx,
        mu=mu,
        kappa=kappa,
    )
