"""Damping deviations and their correlation, and the Rayleigh fit they rest on; thesis §3.3.

The healthy structure's modal damping is fitted by Rayleigh damping, ``ζ_n = μ/(2ω_n) +
κω_n/2`` (eq. 3.40, from ``D = μM + κK``, eq. 1.29) in :func:`fit_rayleigh`; the relative
damage-induced deviations ``(η^D − η^H)/η^H``, measured (eq. 3.41) or analytical
(eq. 3.42), collected per mode into vectors (eq. 3.43, eq. 3.44), are compared by the
correlation coefficient C (eq. 3.45) in :func:`damping_correlation`. Also the checks of
per-mode vectors and scalars shared by :mod:`identification._damage_model` and
:mod:`identification._damage`. NumPy float64 on the host; μ, κ come back as JAX scalars.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

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
