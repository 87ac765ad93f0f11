"""Frequencies and modal damping of a model with a damage in a group of elements, thesis §3.3.3.

A damage candidate G scales the stiffness of its elements by ``1 − s`` and gives them a
structural loss factor η_d; with Rayleigh damping ``μM + κK^D`` (eq. 1.29) the modal
ratios of the damaged model are eq. 3.40 on its modes plus the modal strain energy of the
group, ``ζ_n^D = μ/(2ω_n^D) + κω_n^D/2 + ½ η_d φ_nᵀ K_G φ_n / φ_nᵀ K^D φ_n`` (Ungar &
Kerwin 1962; Johnson & Kienholz 1982; see :mod:`identification._damage`).
:func:`_scan_damping` evaluates it for many candidates at once (vmapped batches over the
candidates' group stiffness), pairing each damaged mode with its healthy one by
mass-weighted overlap; :func:`damage_damping` for one. Frequencies in Hz at the boundary,
ω in rad/s inside.
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

import jaxfem
from jaxfem import STIFFNESS_BLOCKS, Model

from ._deviations import _scalar

_BATCH = 16  # candidates per vmapped batch of the scan (bounds memory on large models)


def _stiffness_ids(model: Model) -> np.ndarray:
    """Ids of the elements with stiffness, in the order of :data:`jaxfem.STIFFNESS_BLOCKS`."""
    return np.concatenate([np.asarray(getattr(model, b).ids, dtype=np.int64) for b in STIFFNESS_BLOCKS])


def _with_k_scale(model: Model, factor: Float[Array, " nk"]) -> Model:
    """``model`` with each stiffness element's ``k_scale`` multiplied by ``factor`` (order of
    :func:`_stiffness_ids`)."""
    start = 0
    for name in STIFFNESS_BLOCKS:
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
