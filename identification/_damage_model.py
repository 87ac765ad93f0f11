"""Frequencies and modal damping of a model with a damage in a group of elements, thesis §3.3.3.

A damage candidate G scales the stiffness K_G⁰ of the damaged *part* of its elements by
``1 − s`` and gives it a structural loss factor η_d; with Rayleigh damping ``μM + κK^D``
(eq. 1.29) the modal ratios of the damaged model are eq. 3.40 on its modes plus the
modal strain energy of the group, ``ζ_n^D = μ/(2ω_n^D) + κω_n^D/2 + ½ η_d φ_nᵀ K_G φ_n /
φ_nᵀ K^D φ_n`` with ``K^D = K − s K_G⁰``, ``K_G = (1 − s) K_G⁰`` (Ungar & Kerwin 1962;
Johnson & Kienholz 1982; see :mod:`identification._damage`).

The part (:data:`PARTS`): ``"all"``, the whole element stiffness (a crack, a loosened
joint); ``"shear"``, only the transverse-shear stiffness of shells, the thesis'
delamination model (§5.3.2.1: G_xz and G_yz of the damaged shell elements reduced by
90 %). A delamination separates plies: the laminate loses its interlaminar shear
stiffness there while the plies keep their in-plane stiffness. K_G⁰ of the shear part is
assembled from a copy of the model whose shell sections have ``membrane = bending = 0``
(A, B, D and with A the drilling penalty vanish; the transverse-shear matrix S stays) and
whose other blocks have ``k_scale = 0``, with ``k_scale = mask`` on the group: assembly is
linear in k_scale, and the element stiffness is linear in S, so ``K − s K_G⁰`` is
exactly the model with S × (1 − s) in the group (for MAT8 plies: G1Z and G2Z × (1 − s)).

:func:`_scan_damping` evaluates it for many candidates at once, either by an eigensolution
of each damaged model (vmapped batches over the candidates' group stiffness), pairing each
damaged mode with its healthy one by mass-weighted overlap, or to first order
(``first_order=True``): the healthy modes φ_n, ω_n with the modal strain energy of the
group ``g_n = φ_nᵀ K_G⁰ φ_n`` (Rayleigh quotient, first-order eigenvalue perturbation,
eq. 3.18), ``(ω_n^D)² ≈ ω_n² − s g_n`` and ``ζ_n^D ≈ μ/(2ω_n^D) + κω_n^D/2 + ½ η_d (1 −
s) g_n / (ω_n^D)²``. The energies of all elements come from one reverse-mode derivative
of the assembly, so a scan over hundreds of candidates costs one eigensolution; its
error grows with the damage (``s g_n / ω_n²``) and with mode-shape change near close
modes. :func:`damage_damping` does one candidate. Frequencies in Hz at the boundary, ω in
rad/s inside.
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import ArrayLike, Float, Int

import jaxfem
from jaxfem import STIFFNESS_BLOCKS, Model, element_strain_energies, stiffness_ids, with_k_scale

from ._deviations import _scalar

_BATCH = 16  # candidates per vmapped batch of the scan (bounds memory on large models)
PARTS = ("all", "shear")  # the stiffness a damage candidate softens (module docstring)
_SHELL_BLOCKS = ("quads", "trias")


def _check_part(part) -> str:
    if part not in PARTS:
        raise ValueError(f"part must be one of {', '.join(map(repr, PARTS))}, got {part!r}")
    return part


def _part_model(model: Model, part: str) -> Model:
    """The model whose assembly with ``k_scale`` × mask is K_G⁰ of the part (module docstring)."""
    if part == "all":
        return model
    sections = model.shell_sections
    zero = jnp.zeros_like(sections.membrane)
    model = eqx.tree_at(lambda m: (m.shell_sections.membrane, m.shell_sections.bending), model, (zero, zero))
    for name in STIFFNESS_BLOCKS:
        if name not in _SHELL_BLOCKS:
            model = eqx.tree_at(lambda m, name=name: getattr(m, name).k_scale, model,
                                jnp.zeros_like(getattr(model, name).k_scale))
    return model


def _shells(model: Model) -> dict[int, tuple[int, bool]]:
    """Shell element id -> (property id, shear rigid)."""
    out = {}
    for name in _SHELL_BLOCKS:
        block = getattr(model, name)
        rigid = np.asarray(model.shell_sections.shear_rigid)[np.asarray(block.section, dtype=np.int64)]
        out.update(zip(np.asarray(block.ids).tolist(), zip(np.asarray(block.pids).tolist(), rigid.tolist())))
    return out


def _shear_checks(shells: dict[int, tuple[int, bool]], i: int, g: list[int]) -> None:
    """part="shear": every element of candidate i a shell with transverse-shear flexibility."""
    other = sorted(set(g) - shells.keys())
    if other:
        raise ValueError(f"candidate {i}: part='shear' softens shells only; element(s) {other[:10]} are not "
                         "CQUAD4/CTRIA3")
    rigid_pids = sorted({shells[e][0] for e in g if shells[e][1]})
    if rigid_pids:
        raise ValueError(f"candidate {i}: property {rigid_pids} has no transverse-shear flexibility (blank MID3, "
                         "or MAT8 without G1Z/G2Z): part='shear' has nothing to soften")


def _group_masks(model: Model, groups: Sequence[Sequence[int]], part: str = "all") -> np.ndarray:
    """0/1 matrix (n_groups, n_stiffness_elements); ValueError naming unknown ids (and, for
    ``part="shear"``, elements that are not flexible shells)."""
    ids = stiffness_ids(model)
    known = set(ids.tolist())
    massive = set(np.asarray(model.masses.ids).tolist())
    shells = _shells(model) if part == "shear" else {}
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
        if part == "shear":
            _shear_checks(shells, i, g)
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
    part: str = "all",
    first_order: bool = False,
) -> tuple[Float[np.ndarray, " m"], Float[np.ndarray, "c m"], Float[np.ndarray, "c m"]]:
    """Healthy model ω (rad/s) of the selected modes, and per candidate the damaged ω and ζ.

    Eigensolution per candidate: damaged modes are paired with the selected healthy ones
    by the largest mass-weighted overlap ``|φ_Hᵀ M φ_D|`` among a few extra modes, so a
    mode that moves past a neighbour is still compared with itself. ``first_order``: the
    healthy modes and the group's modal strain energy (module docstring).
    """
    K0, M = jaxfem.assemble(model)
    base = _part_model(model, part)
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
    if first_order:
        phi = phi_h[:, mode_indices]

        energy = masks @ np.asarray(element_strain_energies(base, phi))  # g = φᵀ K_G⁰ φ per candidate and mode
        lam_d = lam_sel - reduction * energy
        if np.any(lam_d <= 0):
            raise ValueError("the first-order damaged eigenvalue is not positive: the damage is too large for "
                             "first_order=True; use the eigensolution")
        omega = np.sqrt(lam_d)
        zeta = 0.5 * (mu / omega + kappa * omega) + 0.5 * loss * (1.0 - reduction) * energy / lam_d
        return np.sqrt(lam_sel), omega, zeta  # eq. 3.40 at ω^D plus the strain-energy loss

    m_phi_h = M.matmul(phi_h[:, mode_indices])  # (n, m)
    K0 = K0.todense()

    def group_stiffness(mask):  # K_G⁰ = Σ_{e∈G} K_e (of the part): assembly is linear in k_scale
        return jaxfem.assemble(with_k_scale(base, mask))[0].todense()

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
    part: str = "all",
    first_order: bool = False,
) -> tuple[Float[np.ndarray, " m"], Float[np.ndarray, " m"]]:
    """Natural frequencies and modal damping of a model with a damage in ``elements``.

    The stiffness of the elements' damaged ``part`` (``"all"``: the whole element;
    ``"shear"``: the shells' transverse shear, the delamination model of thesis §5.3.2.1)
    is scaled by ``1 − stiffness_reduction`` and given the loss factor ``loss_factor``;
    the structure keeps Rayleigh damping ``μM + κK^D``. Modal ratios by eq. 3.40 on the
    damaged modes plus the modal strain energy of the group (module docstring), from an
    eigensolution of the damaged model or, with ``first_order``, from the healthy modes.
    ``elements=()`` gives the healthy model's ratios.

    **Arguments:** the model; element ids forming the damage (any element with
    stiffness; shells only for ``part="shear"``); the number of lowest modes;
    ``stiffness_reduction`` s in [0, 1); ``loss_factor`` η_d ≥ 0; Rayleigh constants μ
    (1/s), κ (s), e.g. from :func:`fit_rayleigh`; ``part`` and ``first_order``.

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
    part = _check_part(part)
    elements = tuple(int(e) for e in elements)
    masks = _group_masks(model, [elements], part) if elements else np.zeros((1, len(stiffness_ids(model))))
    _, omega, zeta = _scan_damping(model, masks, idx, s, eta, mu, kappa, part, bool(first_order))
    return omega[0] / (2.0 * np.pi), zeta[0]
