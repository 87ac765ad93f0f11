"""The data a modal fit works on: the lines of a band, the usable values, a mode indicator.

Shared by the SDOF fit (:mod:`identification._sdof`, thesis §3.3.2), pLSCF
(:mod:`identification._lscf`) and LSFD (:mod:`identification._lsfd`): the frequency
lines in [fmin, fmax] without 0 Hz, the complex FRF values, the mask of the values whose
coherence is high enough (masked bands are warned about, an FRF left without a usable
line is refused), the power p of iω that makes a receptance of the measured kind
(H_kind = (iω)^p H_receptance), and the summed power Σ|H|², each FRF normalised to its
maximum, that peaks at every resonance. NumPy float64 on the host.
"""

from __future__ import annotations

import warnings

import numpy as np

from ._data import FRFData
from ._frf import _bands, _format_bands, coherence_mask

_POWER = {"receptance": 0, "mobility": 1, "accelerance": 2}  # H_kind = (iω)^p H_receptance


def _data(
    frfs: FRFData, fmin: float | None, fmax: float | None, min_coherence: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[tuple[float, float]]]:
    """Lines in [fmin, fmax] (0 Hz excluded), values, usable mask and the masked bands.

    Entries with coherence below ``min_coherence`` are masked, with a ``UserWarning``
    naming the bands; an FRF left with no usable line is refused.
    """
    f_all = np.asarray(frfs.frequencies_hz, dtype=np.float64)
    lo = 0.0 if fmin is None else float(fmin)
    hi = np.inf if fmax is None else float(fmax)
    if not lo < hi:
        raise ValueError(f"frequency band [{fmin}, {fmax}] Hz is empty")
    keep = (f_all > 0) & (f_all >= lo) & (f_all <= hi)
    if np.count_nonzero(keep) < 4:
        raise ValueError(
            f"{np.count_nonzero(keep)} frequency lines in [{lo:.6g}, {hi:.6g}] Hz; at least 4 are needed"
        )
    f = f_all[keep]
    h = np.asarray(frfs.values, dtype=np.complex128)[keep]
    usable = coherence_mask(frfs, min_coherence)[keep]
    masked = ~np.all(usable, axis=(1, 2))
    bands = _bands(f, masked)
    if bands:
        warnings.warn(
            f"coherence below {min_coherence:g} at {_format_bands(bands)}: those values are left out of the fit",
            stacklevel=3,
        )
    empty = np.argwhere(~np.any(usable, axis=0))
    if len(empty):
        o, i = empty[0]
        raise ValueError(
            f"FRF {frfs.outputs.labels[o]} / {frfs.inputs.labels[i]} has no line with coherence ≥ "
            f"{min_coherence:g} in [{f[0]:.6g}, {f[-1]:.6g}] Hz: nothing to fit"
        )
    return f, h, usable, bands


def _indicator(h: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """Σ over FRFs of |H|² normalised per FRF: peaks at every resonance."""
    mag = np.where(usable, np.abs(h), 0.0) ** 2
    peak = np.max(mag, axis=0, keepdims=True)
    return np.sum(mag / np.where(peak > 0, peak, 1.0), axis=(1, 2))
