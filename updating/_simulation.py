"""Simulated measurements: a model's modes at the sensors with the errors of Table 4.7.

The "measured" modes are the model's lowest modes with the surplus DoFs removed (no
reduction, thesis §4.3.3.2); the measurement errors of Table 4.7, each zero-mean, per
mode n and sensor component i:

    relative   φ̃_n = φ_n × (1 + δ_rel),    δ_rel,i ~ N(0, σ_rel²)
    absolute   φ̃_n = φ_n + δ_abs,          δ_abs,i ~ U(−a, a) × max_i |φ_n,i|
    frequency  λ̃_n = λ_n (1 + δ_freq,n),   δ_freq,n ~ N(0, σ_freq²)

Noise is stated as an engineer states it, σ on the frequencies f (:class:`Noise`); the
error multiplies the eigenvalue λ = ω² with twice that σ (for small δ, f changes by δ/2).
Table 4.7 states its frequency error on λ (§4.3.3.2): :meth:`Noise.table_4_7` converts.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray

import jaxfem
from identification import ModalData, Sensors, observation_matrix
from jaxfem import Model


class Noise(eqx.Module):
    """Measurement noise as stated by the engineer (relative standard deviations, fractions):
    ``frequency`` σ on each natural frequency f, ``relative`` σ on each shape component,
    ``absolute`` a of the uniform shape error relative to each mode's largest component
    (Table 4.7), ``damping`` σ on each damping ratio. The one statement of noise: it
    simulates measurements (:func:`perturb`) and weighs residuals (:func:`updating.diagnose`).
    Arrays under ``vmap``."""

    frequency: Float[Array, ""] | float = 0.0
    relative: Float[Array, ""] | float = 0.0
    absolute: Float[Array, ""] | float = 0.0
    damping: Float[Array, ""] | float = 0.0

    @property
    def eigenvalue(self):
        """σ on each eigenvalue λ = ω²: twice the frequency's (λ ∝ f², to first order)."""
        return 2 * self.frequency

    @classmethod
    def table_4_7(cls, relative=0.0, absolute=0.0, frequency=0.0) -> "Noise":
        """The Table 4.7 magnitudes, whose ``frequency`` error is σ on the eigenvalue λ."""
        return cls(frequency=frequency / 2, relative=relative, absolute=absolute)


def perturb(key: PRNGKeyArray, noise: Noise, lam: Float[Array, " n"], phi: Float[Array, "s n"]):
    """Measured (λ̃, φ̃) from exact (λ, φ) with the errors of ``noise`` (module docstring);
    jittable and vmappable. One key gives the same draws δ at every magnitude."""
    k_phi, k_lam = jax.random.split(key)
    rel = jax.random.normal(k_phi, phi.shape, dtype=phi.dtype)
    uni = jax.random.uniform(k_phi, phi.shape, dtype=phi.dtype, minval=-1.0, maxval=1.0)
    peak = jnp.max(jnp.abs(phi), axis=0)
    phi = phi * (1 + noise.relative * rel) + noise.absolute * peak * uni
    lam = lam * (1 + noise.eigenvalue * jax.random.normal(k_lam, lam.shape, dtype=lam.dtype))
    return lam, phi


def simulate_test(model: Model, sensors: Sensors, n_modes: int, noise: Noise | None = None,
                  key: PRNGKeyArray | None = None, *, skip: int = 0, solver: str = "auto") -> ModalData:
    """The model's modes ``skip … skip + n_modes − 1`` (e.g. ``skip = 6`` drops the rigid-body
    modes of a free structure) at ``sensors``, with the errors of ``noise`` drawn from
    ``key`` (thesis §4.3.3.2, Fig. 4.4, Fig. 4.23); ``solver`` as :func:`jaxfem.modes`.

    **Returns:** :class:`identification.ModalData` (frequencies in Hz, real shapes).
    """
    if noise is not None and key is None:
        raise ValueError("noise needs a JAX random key")
    lam, phi = jaxfem.modes(model, n_modes + skip, solver=solver)
    C, _ = observation_matrix(model, sensors)
    lam, shapes = lam[skip:], jnp.asarray(C) @ phi[:, skip:]
    if noise is not None:
        lam, shapes = perturb(key, noise, lam, shapes)
    return ModalData(np.asarray(jaxfem.frequencies_hz(lam)), np.asarray(shapes), sensors)
