"""Proportional (Rayleigh) viscous damping, thesis section 1.2.7.2.

``D = μM + κK`` (eq. 1.29) is diagonalised by the undamped modes, with modal viscous
ratio ``ζ(ω) = ½(κω + μ/ω)`` (eq. 1.30; the thesis writes the ratio as η, jaxfem keeps
η for the structural loss factor). μ in 1/s, κ in s, ω in rad/s.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._matrix import AbstractSymmetricMatrix
from ._model import check_float64


def _real(name: str, x) -> Array:
    """``x`` as a float64 array, refusing other floating dtypes."""
    if isinstance(x, AbstractSymmetricMatrix):
        x = x.todense()
    check_float64(name, x)
    return jnp.asarray(x, dtype=jnp.float64)


def _check(x: Array, bad: Callable, message: str) -> Array:
    """ValueError if ``bad(x)`` holds anywhere for a concrete ``x``; a runtime
    (``eqx.error_if``) check when ``x`` is traced."""
    try:
        v = np.asarray(x)
    except jax.errors.TracerArrayConversionError:
        return eqx.error_if(x, jnp.any(bad(x)), message)
    mask = np.broadcast_to(bad(v), v.shape)
    if np.any(mask):
        raise ValueError(f"{message}; got {v[mask].tolist() if v.ndim else v.item()}")
    return x


def _square(name: str, a) -> Float[Array, "n n"]:
    a = _real(name, a)
    if a.ndim != 2 or a.shape[0] != a.shape[1]:
        raise ValueError(f"{name} must be a square matrix, got shape {a.shape}")
    return a


def rayleigh(K, M, mu: ArrayLike, kappa: ArrayLike) -> Float[Array, "n n"]:
    """Rayleigh damping matrix ``D = μM + κK`` (thesis eq. 1.29).

    **Arguments:** ``K`` (N/m), ``M`` (kg) as dense n×n arrays (or jaxfem matrix
    operators, densified); ``mu`` (1/s) and ``kappa`` (s), scalars.

    **Returns:** D (N·s/m), dense n×n.
    """
    K, M = _square("K", K), _square("M", M)
    if K.shape != M.shape:
        raise ValueError(f"K has shape {K.shape} but M has shape {M.shape}")
    mu, kappa = _real("mu", mu), _real("kappa", kappa)
    if mu.ndim or kappa.ndim:
        raise ValueError(f"mu and kappa must be scalars, got shapes {mu.shape}, {kappa.shape}")
    return mu * M + kappa * K


def rayleigh_coefficients(
    omega1: ArrayLike, omega2: ArrayLike, zeta1: ArrayLike, zeta2: ArrayLike
) -> tuple[Float[Array, ""], Float[Array, ""]]:
    """``(μ, κ)`` giving viscous ratios ζ₁ at ω₁ and ζ₂ at ω₂ (thesis eq. 1.30 twice).

    Solving ``2ζ_j = κω_j + μ/ω_j``, j = 1, 2:
    ``μ = 2ω₁ω₂(ζ₁ω₂ − ζ₂ω₁)/(ω₂² − ω₁²)``, ``κ = 2(ζ₂ω₂ − ζ₁ω₁)/(ω₂² − ω₁²)``.

    **Arguments:** two distinct positive frequencies ω₁, ω₂ (rad/s) and the ratios
    ζ₁, ζ₂ (dimensionless) wanted there.

    **Returns:** ``(μ, κ)`` in 1/s and s. Either may be negative when the targets
    demand it (e.g. ζ₂/ζ₁ > ω₂/ω₁ gives μ < 0).
    """
    w1, w2, z1, z2 = (
        _real(n, x) for n, x in (("omega1", omega1), ("omega2", omega2), ("zeta1", zeta1), ("zeta2", zeta2))
    )
    for name, x in (("omega1", w1), ("omega2", w2), ("zeta1", z1), ("zeta2", z2)):
        if x.ndim:
            raise ValueError(f"{name} must be a scalar, got shape {x.shape}")
    w1 = _check(w1, lambda w: w <= 0, "omega1 must be positive (rad/s)")
    w2 = _check(w2, lambda w: w <= 0, "omega2 must be positive (rad/s)")
    den = _check(w2**2 - w1**2, lambda d: d == 0, "omega1 and omega2 must differ (ω₂² − ω₁² = 0)")
    mu = 2.0 * w1 * w2 * (z1 * w2 - z2 * w1) / den
    kappa = 2.0 * (z2 * w2 - z1 * w1) / den
    return mu, kappa


def rayleigh_ratio(omega: ArrayLike, mu: ArrayLike, kappa: ArrayLike) -> Float[Array, "*shape"]:
    """Viscous damping ratio of Rayleigh damping, ``ζ(ω) = ½(κω + μ/ω)`` (thesis eq. 1.30).

    **Arguments:** ``omega`` (rad/s, positive, any shape); ``mu`` (1/s), ``kappa`` (s).

    **Returns:** ζ, dimensionless, shaped like ``omega``.
    """
    omega, mu, kappa = _real("omega", omega), _real("mu", mu), _real("kappa", kappa)
    omega = _check(omega, lambda w: w <= 0, "omega must be positive (rad/s)")
    return 0.5 * (kappa * omega + mu / omega)
