"""Frequency response (receptance) of the damped structure, thesis eq. 1.24, eq. 1.47.

With ``u(t) = û e^{iωt}`` and ``f(t) = f̂ e^{iωt}`` the equation of motion gives
``û = H(ω) f̂`` with the dynamic stiffness of eq. 1.47, viscous damping D and a
structural (hysteretic) loss factor η as complex stiffness (Ewins, *Modal Testing*,
2nd ed., §2.2–2.3):

    H(ω) = (−ω²M + iωD + (1 + iη)K)⁻¹                                   (m/N)

When D is proportional (modal damping, or Rayleigh eq. 1.29) the real, mass-normalised
undamped modes diagonalise it, ``ΦᵀDΦ = diag(2ζ_r ω_r)``, and

    H(ω) = Σ_r φ_r φ_rᵀ / (λ_r − ω² + 2iζ_r ω_r ω + iη λ_r),    λ_r = ω_r²

(Ewins §2.6), exact when summed over all modes. For Rayleigh damping
``2ζ_r ω_r = μ + κλ_r`` (eq. 1.30 times 2ω_r), which also holds for rigid-body modes.
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
from jaxtyping import Array, ArrayLike, Complex, Float, Int

from ._damping import _check, _real, _square


def _frequencies(omega) -> Float[Array, " f"]:
    omega = _real("omega", omega)
    if omega.ndim != 1 or omega.shape[0] == 0:
        raise ValueError(f"omega must be a non-empty 1-D array (rad/s), got shape {omega.shape}")
    return _check(omega, lambda w: w < 0, "omega must be non-negative (rad/s)")


def _dofs(name: str, dofs: Sequence[int] | np.ndarray, n: int) -> Int[np.ndarray, " k"]:
    idx = np.asarray(dofs)
    if idx.ndim != 1 or idx.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty 1-D sequence of DoF indices, got shape {idx.shape}")
    if not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"{name} must hold integer DoF indices, got dtype {idx.dtype}")
    bad = idx[(idx < 0) | (idx >= n)]
    if bad.size:
        raise ValueError(f"{name}: DoF index {bad[0]} is out of range 0..{n - 1}")
    return idx.astype(np.int64)


def _loss_factor(eta) -> Float[Array, ""]:
    eta = _real("eta", eta)
    if eta.ndim:
        raise ValueError(f"eta must be a scalar, got shape {eta.shape}")
    return _check(eta, lambda e: e < 0, "eta must be non-negative")


def frf_direct(
    K,
    M,
    omega: Float[ArrayLike, " f"],
    out_dofs: Sequence[int] | np.ndarray,
    in_dofs: Sequence[int] | np.ndarray,
    *,
    D=None,
    eta: ArrayLike = 0.0,
    G=None,
) -> Complex[Array, "f o i"]:
    """Receptance ``H(ω) = (−ω²M + iωD + (1+iη)K + iG)⁻¹`` by a direct solve (thesis eq. 1.47).

    Per frequency the complex dynamic stiffness is LU-factored once and solved for the
    unit loads at ``in_dofs`` only (lineax, vmapped over ω); differentiable in K, M, D
    and η.

    **Arguments:**
    - ``K`` (N/m), ``M`` (kg): real symmetric n×n arrays (or jaxfem matrix operators,
      densified).
    - ``omega``: angular frequencies (rad/s), 1-D, non-negative.
    - ``out_dofs``, ``in_dofs``: response and excitation DoF indices in 0..n−1.
    - ``D``: viscous damping matrix (N·s/m), e.g. :func:`jaxfem.rayleigh`; none if omitted.
    - ``eta``: structural loss factor (dimensionless, ≥ 0), multiplies K.
    - ``G``: structural damping matrix (N/m) of element loss factors, e.g.
      :func:`jaxfem.damping_matrix`; none if omitted.

    **Returns:** H, complex128, shape (n_freq, n_out, n_in), in m/N. Singular where the
    dynamic stiffness is (undamped resonance; ω = 0 with rigid-body modes).
    """
    K, M = _square("K", K), _square("M", M)
    if K.shape != M.shape:
        raise ValueError(f"K has shape {K.shape} but M has shape {M.shape}")
    if D is not None:
        D = _square("D", D)
        if D.shape != K.shape:
            raise ValueError(f"D has shape {D.shape} but K has shape {K.shape}")
    G = _loss_factor(eta) * K if G is None else _loss_factor(eta) * K + _square("G", G)
    if G.shape != K.shape:
        raise ValueError(f"G has shape {G.shape} but K has shape {K.shape}")
    n = K.shape[0]
    return _frf_direct(
        K,
        M,
        D,
        G,
        _frequencies(omega),
        _dofs("out_dofs", out_dofs, n),
        _dofs("in_dofs", in_dofs, n),
    )


@eqx.filter_jit
def _frf_direct(K, M, D, G, omega, out_idx, in_idx):
    n = K.shape[0]
    loads = jnp.zeros((n, in_idx.shape[0]), jnp.complex128).at[in_idx, jnp.arange(in_idx.shape[0])].set(1.0)

    def one(w):
        im = G if D is None else w * D + G
        op = lx.MatrixLinearOperator(jax.lax.complex(K - w**2 * M, im))
        # Batching over the right-hand sides only: lineax factors the operator once.
        solve = jax.vmap(lambda b: lx.linear_solve(op, b, lx.LU()).value, in_axes=1, out_axes=1)
        return solve(loads)[out_idx]

    return jax.vmap(one)(omega)


def frf_modal(
    lam: Float[ArrayLike, " m"],
    phi: Float[ArrayLike, "n m"],
    omega: Float[ArrayLike, " f"],
    out_dofs: Sequence[int] | np.ndarray,
    in_dofs: Sequence[int] | np.ndarray,
    *,
    zeta: Float[ArrayLike, " m"] | None = None,
    eta: ArrayLike = 0.0,
    mu: ArrayLike | None = None,
    kappa: ArrayLike | None = None,
) -> Complex[Array, "f o i"]:
    """Receptance by modal superposition (Ewins §2.6; damping from thesis eq. 1.30).

    ``H(ω) = Σ_r φ_r,out φ_r,inᵀ / (λ_r − ω² + 2iζ_r ω_r ω + iη λ_r)``, exact for
    proportional damping when all modes are included; with a subset it is the
    truncated expansion (no residual terms).

    **Arguments:**
    - ``lam``: eigenvalues λ_r = ω_r² ((rad/s)²), e.g. from :func:`jaxfem.eigh`;
      rigid-body modes (λ ≈ 0) allowed.
    - ``phi``: mass-normalised modes (ΦᵀMΦ = I) as columns, shape (n, m), in 1/√kg.
    - ``omega``, ``out_dofs``, ``in_dofs``, ``eta``: as in :func:`frf_direct`.
    - ``zeta``: viscous ratios ζ_r (scalar or one per mode, ≥ 0); or else
    - ``mu`` (1/s), ``kappa`` (s): Rayleigh constants (eq. 1.29), ``2ζ_r ω_r = μ + κλ_r``;
      one of them may be omitted (zero). No viscous damping if all three are omitted.

    **Returns:** H, complex128, shape (n_freq, n_out, n_in), in m/N.
    """
    lam, phi = _real("lam", lam), _real("phi", phi)
    if lam.ndim != 1 or phi.ndim != 2 or phi.shape[1] != lam.shape[0]:
        raise ValueError(f"lam must have shape (m,) and phi (n, m); got {lam.shape} and {phi.shape}")
    m = lam.shape[0]
    if zeta is not None:
        if mu is not None or kappa is not None:
            raise ValueError("give either zeta (modal damping) or mu/kappa (Rayleigh damping), not both")
        zeta = _real("zeta", zeta)
        if zeta.shape not in ((), (m,)):
            raise ValueError(f"zeta must be a scalar or have one ratio per mode ({m},), got shape {zeta.shape}")
        zeta = _check(zeta, lambda z: z < 0, "zeta must be non-negative")
        pos = lam > 0
        omega_r = jnp.where(pos, jnp.sqrt(jnp.where(pos, lam, 1.0)), 0.0)
        c = 2.0 * zeta * omega_r
    else:
        mu = _real("mu", 0.0 if mu is None else mu)
        kappa = _real("kappa", 0.0 if kappa is None else kappa)
        if mu.ndim or kappa.ndim:
            raise ValueError(f"mu and kappa must be scalars, got shapes {mu.shape}, {kappa.shape}")
        c = mu + kappa * lam
    n = phi.shape[0]
    return _frf_modal(
        lam,
        phi,
        c,
        _loss_factor(eta),
        _frequencies(omega),
        _dofs("out_dofs", out_dofs, n),
        _dofs("in_dofs", in_dofs, n),
    )


@eqx.filter_jit
def _frf_modal(lam, phi, c, eta, omega, out_idx, in_idx):
    w = omega[:, None]
    den = jax.lax.complex(lam[None, :] - w**2, w * c[None, :] + eta * lam[None, :])
    p_out = phi[out_idx].astype(jnp.complex128)
    p_in = phi[in_idx].astype(jnp.complex128)
    return jnp.einsum("or,ir,fr->foi", p_out, p_in, 1.0 / den)
