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
dynamic stiffness (Ewins §2.3). Its modal ratios follow from the real modes of the
damaged model by modal strain energy (first-order perturbation of the complex
eigenvalue, Ungar & Kerwin 1962; Johnson & Kienholz 1982):

    ζ_n^D = μ/(2ω_n^D) + κω_n^D/2 + ½ η_d φ_nᵀ K_G φ_n / φ_nᵀ K^D φ_n

with ``K^D = K − s K_G⁰`` the damaged stiffness and ``K_G = (1 − s) K_G⁰`` the damaged
stiffness of the group (φ mass-normalised, so ``φᵀK^Dφ = ω²``). The thesis (§5.3.2)
evaluates eq. 3.40 on the damaged model only; the loss-factor term is the
"additional friction" of §3.3.1, set to zero by ``loss_factor=0``.

Measured ratios come from the user (any modal fit, e.g. one SDOF inverse-FRF fit per
resonance, eq. 3.34, eq. 3.35, eq. 3.36, eq. 3.37, :func:`identification.sdof_fit`, as in the
demonstration ``benchmarks/damage_demo.py``). Units: frequencies in Hz at the boundary, ω in rad/s inside.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

import jaxfem
from jaxfem import Model

_BATCH = 16  # candidates per vmapped batch of the scan (bounds memory on large models)


# ----------------------------------------------------------------------------- checks


def _vector(name: str, x, n: int | None = None) -> np.ndarray:
    """``x`` as a finite float64 vector (of length ``n``); ValueError naming the bad entry."""
    a = np.asarray(x)
    if np.iscomplexobj(a) or a.dtype == object:
        raise ValueError(f"{name} must be real numbers, got dtype {a.dtype}")
    a = a.astype(np.float64)
    if a.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name} has {a.shape[0]} modes, expected {n}")
    bad = np.flatnonzero(~np.isfinite(a))
    if len(bad):
        raise ValueError(f"{name}: mode {bad[0]} has value {a[bad[0]]} (not finite)")
    return a


def _positive(name: str, a: np.ndarray) -> np.ndarray:
    bad = np.flatnonzero(a <= 0)
    if len(bad):
        raise ValueError(f"{name}: mode {bad[0]} has value {a[bad[0]]}, must be positive")
    return a


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


def _scalar(name: str, x, low: float, high: float = np.inf, *, open_high: bool = False) -> float:
    v = np.asarray(x)
    if v.ndim or not np.isfinite(v) or v < low or (v >= high if open_high else v > high):
        bound = f"[{low}, {high})" if open_high else f"[{low}, {high}]"
        raise ValueError(f"{name} must be a finite scalar in {bound}, got {x!r}")
    return float(v)


# ----------------------------------------------------------------------- Rayleigh fit


def fit_rayleigh(
    frequencies_hz: Float[ArrayLike, " m"], damping_ratios: Float[ArrayLike, " m"]
) -> tuple[Float[Array, ""], Float[Array, ""]]:
    """Rayleigh constants ``(μ, κ)`` fitted to measured modal damping, eq. 3.40.

    Least squares over the modes of ``ζ_n = μ/(2ω_n) + κω_n/2`` (eq. 3.40), unweighted as
    in the thesis; with two modes this is :func:`jaxfem.rayleigh_coefficients`.

    **Arguments:** natural frequencies (Hz, positive, at least two distinct) and viscous
    damping ratios ζ (dimensionless, finite) of the healthy structure.

    **Returns:** ``(μ, κ)`` in 1/s and s, float64 scalars (either may come out negative
    when the data demand it). Predict with :func:`jaxfem.rayleigh_ratio`.
    """
    f = _positive("frequencies_hz", _vector("frequencies_hz", frequencies_hz))
    z = _vector("damping_ratios", damping_ratios, len(f))
    if len(np.unique(f)) < 2:
        raise ValueError(f"a Rayleigh fit needs at least two distinct frequencies, got {f.tolist()} Hz")
    w = 2.0 * np.pi * f
    a = np.stack([0.5 / w, 0.5 * w], axis=1)  # eq. 3.40: ζ = a @ (μ, κ)
    scale = np.linalg.norm(a, axis=0)  # columns differ by ω²: equilibrate
    coef, *_ = np.linalg.lstsq(a / scale, z, rcond=None)
    mu, kappa = coef / scale
    return jnp.asarray(mu, dtype=jnp.float64), jnp.asarray(kappa, dtype=jnp.float64)


# ------------------------------------------------------------- deviations, correlation


def damping_deviations(
    damaged: Float[ArrayLike, "*batch m"], healthy: Float[ArrayLike, " m"]
) -> Float[np.ndarray, "*batch m"]:
    """Relative damage-induced damping deviations ``(η^D − η^H)/η^H``, eq. 3.41, eq. 3.42.

    **Arguments:** damping ratios of the damaged state (one vector, or a batch of
    vectors, e.g. one per candidate) and of the healthy state (positive), per mode.

    **Returns:** Δη, dimensionless, shaped like ``damaged`` (the vectors of
    eq. 3.43, eq. 3.44).
    """
    h = _positive("healthy damping", _vector("healthy damping", healthy))
    d = np.asarray(damaged, dtype=np.float64)
    if d.ndim < 1 or d.shape[-1] != len(h):
        raise ValueError(f"damaged damping has shape {d.shape}, expected (..., {len(h)}) modes")
    bad = np.argwhere(~np.isfinite(d))
    if len(bad):
        raise ValueError(f"damaged damping: mode {bad[0][-1]} has value {d[tuple(bad[0])]} (not finite)")
    return (d - h) / h  # eq. 3.41, eq. 3.42


def damping_correlation(
    predicted: Float[ArrayLike, "*batch m"], measured: Float[ArrayLike, " m"]
) -> Float[np.ndarray, " *batch"]:
    """Correlation coefficient of eq. 3.45 between predicted and measured deviations.

    ``C = (Δη_aᵀΔη_e)² / ((Δη_aᵀΔη_a)(Δη_eᵀΔη_e))``, in [0, 1]; 1 when the two
    vectors are parallel (a modal assurance criterion on the deviation vectors). A
    candidate that predicts no deviation at all gets C = 0.

    **Arguments:** Δη_a per candidate (``(..., m)``) and the measured Δη_e (``(m,)``,
    not all zero).

    **Returns:** C per candidate, shape ``(...)``.
    """
    e = _vector("measured deviations", measured)
    a = np.asarray(predicted, dtype=np.float64)
    if a.ndim < 1 or a.shape[-1] != len(e):
        raise ValueError(f"predicted deviations have shape {a.shape}, expected (..., {len(e)}) modes")
    if not np.all(np.isfinite(a)):
        raise ValueError("predicted deviations contain non-finite values")
    ee = float(e @ e)
    if ee == 0.0:
        raise ValueError("measured damping deviations are all zero: no damage-induced change to locate")
    aa = np.einsum("...m,...m->...", a, a)
    ae = a @ e
    return np.where(aa > 0, ae**2 / np.where(aa > 0, aa, 1.0) / ee, 0.0)  # eq. 3.45


# --------------------------------------------------------------- analytical damping


def _stiffness_ids(model: Model) -> np.ndarray:
    """Ids of the elements with stiffness, in the order beams, rods, springs, bushes."""
    return np.concatenate(
        [np.asarray(b.ids, dtype=np.int64) for b in (model.beams, model.rods, model.springs, model.bushes)]
    )


def _with_k_scale(model: Model, factor: Float[Array, " nk"]) -> Model:
    """``model`` with each stiffness element's ``k_scale`` multiplied by ``factor`` (order of
    :func:`_stiffness_ids`)."""
    start = 0
    for name in ("beams", "rods", "springs", "bushes"):
        block = getattr(model, name)
        n = len(block.ids)
        new = block.k_scale * factor[start : start + n]
        model = eqx.tree_at(lambda m, name=name: getattr(m, name).k_scale, model, new)
        start += n
    return model


def _group_masks(model: Model, groups: Sequence[Sequence[int]]) -> np.ndarray:
    """0/1 matrix (n_groups, n_stiffness_elements); ValueError naming unknown ids."""
    ids = _stiffness_ids(model)
    known = set(ids.tolist())
    massive = set(np.asarray(model.masses.ids).tolist())
    masks = []
    for i, g in enumerate(groups):
        try:
            g = [int(e) for e in g]
        except (TypeError, ValueError):
            raise ValueError(f"candidate {i} must be a sequence of element ids, got {g!r}") from None
        if not g:
            raise ValueError(f"candidate {i} is empty")
        unknown = sorted(set(g) - known)
        if unknown:
            no_k = sorted(set(unknown) & massive)
            what = f"element(s) {no_k} carry no stiffness (CONM2)" if no_k else f"element id(s) {unknown} not in the model"
            raise ValueError(f"candidate {i}: {what}")
        masks.append(np.isin(ids, g).astype(np.float64))
    return np.stack(masks)


def _scan_damping(
    model: Model,
    masks: Float[np.ndarray, "c nk"],
    mode_indices: Int[np.ndarray, " m"],
    reduction: float,
    loss: float,
    mu: float,
    kappa: float,
) -> tuple[Float[np.ndarray, " m"], Float[np.ndarray, "c m"], Float[np.ndarray, "c m"]]:
    """Healthy model ω (rad/s) of the selected modes, and per candidate the damaged ω and ζ.

    Damaged modes are paired with the selected healthy ones by the largest mass-weighted
    overlap ``|φ_Hᵀ M φ_D|`` among a few extra modes, so a mode that moves past a
    neighbour is still compared with itself.
    """
    K0, M = jaxfem.assemble(model)
    n_free = M.n - len(M.massless)
    n_compute = int(min(int(mode_indices.max()) + 3, n_free))
    lam_h, phi_h = jaxfem.eigh(K0, M, n_compute)
    lam_sel = np.asarray(lam_h)[mode_indices]
    bad = np.flatnonzero(~(lam_sel > 1e-9 * float(np.max(np.abs(np.asarray(lam_h))))))
    if len(bad):
        raise ValueError(
            f"model mode {int(mode_indices[bad[0]])} has eigenvalue {lam_sel[bad[0]]:.3g} (a rigid-body "
            "mode): Rayleigh damping is undefined there; select elastic modes with mode_indices"
        )
    m_phi_h = M.matmul(phi_h[:, mode_indices])  # (n, m)
    K0 = K0.todense()

    def group_stiffness(mask):  # K_G⁰ = Σ_{e∈G} K_e: assembly is linear in k_scale
        return jaxfem.assemble(_with_k_scale(model, mask))[0].todense()

    def damped_modes(k_g0):
        lam, phi = jaxfem.eigh(K0 - reduction * k_g0, M, n_compute)  # K^D = K − s K_G⁰
        energy = (1.0 - reduction) * jnp.einsum("ir,ij,jr->r", phi, k_g0, phi)  # φᵀ K_G φ
        omega = jnp.sqrt(jnp.maximum(lam, 0.0))
        safe = jnp.where(omega > 0, omega, 1.0)
        zeta = 0.5 * (mu / safe + kappa * omega) + 0.5 * loss * energy / (safe * safe)  # eq. 3.40 + MSE
        j = jnp.argmax(jnp.abs(m_phi_h.T @ phi), axis=1)
        return omega[j], zeta[j]

    # Eager vmap (no jit): op-by-op dispatch reuses compiled primitives from call to
    # call, where a jitted scan would recompile for every model and damage size.
    size = min(_BATCH, len(masks))
    n_pad = -len(masks) % size  # pad the last batch: one shape for all batches
    padded = np.concatenate([masks, np.zeros((n_pad, masks.shape[1]))])
    omegas, zetas = [], []
    for start in range(0, len(padded), size):
        k_g0 = jax.vmap(group_stiffness)(jnp.asarray(padded[start : start + size]))
        o, z = jax.vmap(damped_modes)(k_g0)
        omegas.append(np.asarray(o))
        zetas.append(np.asarray(z))
    n = len(masks)
    return np.sqrt(lam_sel), np.concatenate(omegas)[:n], np.concatenate(zetas)[:n]


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


def _check_n_modes(model: Model, idx: np.ndarray) -> None:
    n_free = model.n_dof - len(model.dofs.massless)
    if int(idx.max()) >= n_free:
        raise ValueError(f"model mode {int(idx.max())} requested but the model has {n_free} modes")


def damage_damping(
    model: Model,
    elements: Sequence[int],
    n_modes: int,
    *,
    stiffness_reduction: float,
    loss_factor: float,
    mu: float | ArrayLike,
    kappa: float | ArrayLike,
) -> tuple[Float[np.ndarray, " m"], Float[np.ndarray, " m"]]:
    """Natural frequencies and modal damping of a model with a damage in ``elements``.

    The elements' stiffness is scaled by ``1 − stiffness_reduction`` and given the loss
    factor ``loss_factor``; the structure keeps Rayleigh damping ``μM + κK^D``. Modal
    ratios by eq. 3.40 on the damaged modes plus the modal strain energy of the
    group (module docstring). ``elements=()`` gives the healthy model's ratios.

    **Arguments:** the model; element ids (beams, rods, springs, bushes) forming the
    damage; the number of lowest modes; ``stiffness_reduction`` s in [0, 1);
    ``loss_factor`` η_d ≥ 0; Rayleigh constants μ (1/s), κ (s), e.g. from
    :func:`fit_rayleigh`.

    **Returns:** ``(frequencies_hz, damping_ratios)``, NumPy float64 of shape
    ``(n_modes,)``, ordered as the healthy model's lowest modes (paired by mass-weighted
    overlap).
    """
    if isinstance(n_modes, bool) or not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise ValueError(f"n_modes must be a positive integer, got {n_modes!r}")
    idx = np.arange(int(n_modes), dtype=np.int64)
    _check_n_modes(model, idx)
    s = _scalar("stiffness_reduction", stiffness_reduction, 0.0, 1.0, open_high=True)
    eta = _scalar("loss_factor", loss_factor, 0.0)
    mu, kappa = _scalar("mu", mu, -np.inf), _scalar("kappa", kappa, -np.inf)
    elements = tuple(int(e) for e in elements)
    masks = _group_masks(model, [elements]) if elements else np.zeros((1, len(_stiffness_ids(model))))
    _, omega, zeta = _scan_damping(model, masks, idx, s, eta, mu, kappa)
    return omega[0] / (2.0 * np.pi), zeta[0]


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
            raise ValueError("the model has no beams or rods: pass candidates explicitly")
    groups = tuple(tuple(int(e) for e in g) for g in candidates)
    masks = _group_masks(model, groups)

    omega_h, omega_d, zeta_d = _scan_damping(model, masks, idx, s, eta, mu, kappa)
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


# ----------------------------------------------------------------------------- plot


def plot_damage_map(
    model: Model,
    scan: DamageScan,
    path: str | Path,
    *,
    true_elements: Sequence[int] = (),
    title: str = "Correlation of damage-induced damping deviations, eq. 3.45",
) -> Path:
    """Map of C over the structure (cf. thesis Figure 5.28) and C per candidate, as a PNG.

    Top: elements with stiffness as lines between their grids, coloured by C of the
    candidates containing them (grey: not a candidate); the located damage outlined in
    black, ``true_elements`` (when known) in red. A model in a plane (or on a line) is
    drawn in that plane, any other in 3-D. Bottom: C per candidate, labelled by its
    first element id. Matplotlib is imported here (the ``plot`` extra); the figure
    lives on its own Agg canvas (no pyplot state).

    **Returns:** the path written.
    """
    try:
        from matplotlib import colormaps
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.cm import ScalarMappable
        from matplotlib.collections import LineCollection
        from matplotlib.colors import Normalize
        from matplotlib.figure import Figure
        from mpl_toolkits.mplot3d.art3d import Line3DCollection
    except ImportError as err:
        raise ImportError("plots need matplotlib: install jaxfem[plot] (pip install 'jaxfem[plot]')") from err

    xyz = np.asarray(model.xyz, dtype=np.float64)
    rows, eids = model.segments()
    values = scan.element_values()
    c = np.array([values.get(int(e), np.nan) for e in eids])
    used = xyz[np.unique(rows)] if len(rows) else xyz
    spread = np.ptp(used, axis=0)
    dims = np.flatnonzero(spread > 1e-9 * max(float(spread.max()), 1e-300))
    flat = len(dims) <= 2
    if flat:
        dims = np.array([0, 1]) if len(dims) == 0 else dims
        dims = np.array([dims[0], (dims[0] + 1) % 3]) if len(dims) == 1 else dims

    fig = Figure(figsize=(8.0, 7.0), dpi=120, layout="constrained")
    FigureCanvasAgg(fig)
    line = flat and not np.all(spread[dims] > 1e-9 * max(float(spread.max()), 1e-300))
    grid = fig.add_gridspec(2, 1, height_ratios=(1, 2) if line else (3, 2))
    ax = fig.add_subplot(grid[0]) if flat else fig.add_subplot(grid[0], projection="3d")
    cmap = colormaps["viridis"]
    has = np.isfinite(c)
    norm = Normalize(0.0, max(float(np.nanmax(c)) if has.any() else 1.0, 1e-12))
    seg = xyz[rows][:, :, dims] if flat else xyz[rows]
    collection = LineCollection if flat else Line3DCollection

    def draw(mask, **style):
        if mask.any():
            lc = collection(seg[mask], **style)
            ax.add_collection(lc) if flat else ax.add_collection3d(lc)

    truth = np.isin(eids, np.asarray(true_elements, dtype=np.int64))
    located = np.isin(eids, np.asarray(scan.best_group, dtype=np.int64))
    draw(truth, colors="tab:red", linewidths=14.0, label="true damage")
    draw(located, colors="k", linewidths=9.0, label=f"located (C = {scan.correlation[scan.best]:.3f})")
    draw(np.ones(len(eids), bool), colors=[cmap(norm(v)) if ok else "0.8" for v, ok in zip(c, has)],
         linewidths=np.where(has, 5.0, 1.0))
    fig.colorbar(ScalarMappable(norm, cmap), ax=ax, label="C", shrink=0.8)
    names = "xyz"
    if flat:
        ax.set_xlabel(f"{names[dims[0]]} (m)")
        ax.set_ylabel(f"{names[dims[1]]} (m)")
        ax.autoscale()
        if not line:
            ax.set_aspect("equal", adjustable="datalim")
        ax.margins(0.05)
    else:
        lo, hi = used.min(axis=0), used.max(axis=0)
        ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), zlim=(lo[2], hi[2]), xlabel="x (m)", ylabel="y (m)",
               zlabel="z (m)")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title, fontsize=10)

    bars = fig.add_subplot(grid[1])
    k = np.arange(len(scan.groups))
    true_set = {int(e) for e in true_elements}
    colours = ["k" if i == scan.best else "tab:red" if set(g) & true_set else "tab:blue"
               for i, g in enumerate(scan.groups)]
    bars.bar(k, scan.correlation, color=colours)
    step = max(1, len(k) // 30)
    bars.set_xticks(k[::step], [str(g[0]) for g in scan.groups[::step]], fontsize=7)
    bars.set(xlabel="candidate (first element id)", ylabel="C", ylim=(0.0, 1.05))
    bars.set_title("black: located; red: true damage", fontsize=8)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, format="png")
    return path
