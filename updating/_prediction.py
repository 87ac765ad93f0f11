"""Validation by prediction (thesis §4.2.5.2–4.2.5.3): FRFs of a model at the test DoFs.

Passive modes are predicted by pairing the updated model with all test modes
(:attr:`UpdateResult.after`); this module adds the frequency responses, compared with
the measured ones by the frequency response assurance criterion and a magnitude error.
"""

from __future__ import annotations

import numpy as np

import jaxfem
from identification import FRFData, observation_matrix
from jaxfem import Model


def predict_frf(model: Model, frf: FRFData, *, zeta=0.01, n_modes: int | None = None) -> np.ndarray:
    """Model FRFs at the measured outputs/inputs and frequencies, in ``frf.kind`` units.

    Modal superposition over ``n_modes`` modes (default: all with mass) with viscous
    ratios ``zeta`` (scalar or one per mode), H = Σ c_out,r c_in,r / (λ_r − ω² + 2iζ_r ω_r ω),
    where c = Cφ are the modes seen by the sensors. **Returns:** complex (nf, n_out, n_in).
    """
    c_out, _ = observation_matrix(model, frf.outputs)
    c_in, _ = observation_matrix(model, frf.inputs)
    lam, phi = jaxfem.modes(model, n_modes)
    rows = np.vstack([c_out, c_in]) @ np.asarray(phi)
    n_out, n_in = c_out.shape[0], c_in.shape[0]
    zeta = np.broadcast_to(np.asarray(zeta, dtype=float), lam.shape)
    omega = 2 * np.pi * np.asarray(frf.frequencies_hz)
    h = np.asarray(jaxfem.frf_modal(lam, rows, omega, np.arange(n_out), n_out + np.arange(n_in), zeta=zeta))
    factor = {"receptance": 1.0, "mobility": 1j * omega, "accelerance": -(omega**2)}[frf.kind]
    return h * np.reshape(factor, (-1, 1, 1))


def frf_correlation(measured: np.ndarray, predicted: np.ndarray) -> dict[str, np.ndarray]:
    """Per FRF (output, input): FRAC = |Σ H_eᴴ H_a|² / (Σ|H_e|² Σ|H_a|²) (Heylen et al.,
    1997) and the mean absolute magnitude error in dB over the frequency lines."""
    num = np.abs(np.sum(np.conj(measured) * predicted, axis=0)) ** 2
    den = np.sum(np.abs(measured) ** 2, axis=0) * np.sum(np.abs(predicted) ** 2, axis=0)
    db = 20 * np.abs(np.log10(np.abs(predicted) / np.abs(measured)))
    return {"frac": num / den, "mean_abs_db": np.mean(db, axis=0)}
