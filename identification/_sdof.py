"""SDOF modal fit: one resonance at a time by the inverse-receptance quadratic, thesis §3.3.2.

Near an isolated resonance the receptance is that of one viscously damped DoF
(eq. 3.34), so its inverse is a quadratic in ω (eq. 3.35) whose coefficients (eq. 3.36)
give the natural frequency and the damping ratio (eq. 3.37). :func:`sdof_fit` finds the
resonances (peaks of the mode indicator), starts ζ from the half-power points, fits every
FRF around each peak (:func:`_inverse_fit`), averages the FRFs and scales the shapes as
LSFD does (:func:`identification._lsfd._modal_data`). For well separated modes; closely
spaced ones need :func:`identification.identify`. NumPy/SciPy float64 on the host.
"""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np
from jaxtyping import ArrayLike, Float

from ._data import FRFData, ModalData
from ._fit_data import _POWER, _data, _indicator
from ._lsfd import _modal_data


def _basin(s: np.ndarray, k: int) -> tuple[int, int]:
    """Lines of the valleys either side of the peak at line k: the lowest points between
    it and the nearest higher line on each side (the bases of its prominence, so noise
    wiggles on the flanks do not end the basin)."""
    higher = np.flatnonzero(s > s[k])
    left, right = higher[higher < k], higher[higher > k]
    a = left[-1] if len(left) else 0
    b = right[0] if len(right) else len(s) - 1
    return a + int(np.argmin(s[a : k + 1])), k + int(np.argmin(s[k : b + 1]))


def _half_power_zeta(f: np.ndarray, s: np.ndarray, k: int) -> float:
    """ζ ≈ Δf/(2f) from the half-power points of the power indicator s around line k.

    Searched within the peak's basin only; a side that does not fall to half before its
    valley is mirrored from the other; 2 lines when neither does.
    """
    half = s[k] / 2
    lo, hi = _basin(s, k)
    sides = []
    below = np.flatnonzero(s[lo : k + 1] <= half)
    if len(below):
        j = lo + below[-1]
        sides.append(f[k] - np.interp(half, [s[j], s[j + 1]], [f[j], f[j + 1]]))
    above = np.flatnonzero(s[k : hi + 1] <= half)
    if len(above):
        j = k + above[0]
        sides.append(np.interp(half, [s[j], s[j - 1]], [f[j], f[j - 1]]) - f[k])
    if not sides:
        return 2 * (f[min(k + 1, len(f) - 1)] - f[max(k - 1, 0)]) / (2 * f[k])
    return max(float(np.mean(sides)) / f[k], 1e-6)


def _inverse_fit(w: np.ndarray, h: np.ndarray) -> tuple[float, float, complex, float]:
    """ω_r, ζ and modal constant A of 1/H = (ω_r² − ω² + 2iζω_r ω)/A, eq. 3.35, eq. 3.36.

    The coefficients of eq. 3.36 are tied: a = −1/A, b = 2iζω_r/A, c = ω_r²/A with one complex
    A (= 1/m per unit force; φ_out φ_in for a mode, complex for a complex one), so
    c/a = −ω_r² is real and b/a
    imaginary. Written as A/H − ω_r² − iω g = −ω² with g = 2ζω_r the fit is linear in
    Re A, Im A, ω_r², g (four real unknowns), and eq. 3.37 gives ζ = g/(2ω_r). A free
    complex a, b, c would be ill-conditioned over a narrow band: a 0.3 % offset from the
    other modes moves ω_r by tens of per cent. Rows are weighted by |H| so that the
    error is relative, |1 − H(ω_r² − ω² + iωg)/A|, and lines far from resonance, where
    |1/H| is largest, do not dominate. Also returns the RMS relative error of the fit.
    """
    inv = 1 / h
    weight = np.abs(h) / np.max(np.abs(h))
    cols = np.column_stack([inv, 1j * inv, -np.ones_like(w), -1j * w]) * weight[:, None]
    rhs = -(w**2) * weight
    lhs = np.concatenate([cols.real, cols.imag])
    x = np.linalg.lstsq(lhs, np.concatenate([rhs.real, rhs.imag]), rcond=None)[0]
    constant = complex(x[0], x[1])
    if not (x[2] > 0 and abs(constant) > 0):
        return math.nan, math.nan, constant, math.inf
    error = np.abs(h * (x[2] - w**2 + 1j * w * x[3]) / constant - 1)
    wr = math.sqrt(x[2])
    return wr, x[3] / (2 * wr), constant, float(np.sqrt(np.mean(error**2)))  # eq. 3.37: ζ = g/(2ω_r)


def _sdof_resonance(f, w, h, usable, indicator, k, bandwidths):
    """f_r, ζ, modal constants (n_out, n_in), band half-width and best RMS relative error
    of the SDOF fit around line ``k``; ``ValueError`` when no consistent fit exists."""
    n_out, n_in = h.shape[1:]
    f_r, zeta = f[k], _half_power_zeta(f, indicator, k)
    basin = f[list(_basin(indicator, k))]  # the fitted resonance must stay in this peak's basin
    min_half = 3.5 * (f[min(k + 1, len(f) - 1)] - f[max(k - 1, 0)]) / 2  # ≥ 3 lines each side
    widen, valid, best = 1.0, 0, math.inf
    for _ in range(6):  # two valid passes; a pass that fails widens the band
        half = max(bandwidths * zeta * f_r, min_half) * widen
        band = np.abs(f - f_r) <= half
        est = []
        for o in range(n_out):
            for i in range(n_in):
                lines = band & usable[:, o, i]
                if np.count_nonzero(lines) < 5:
                    continue
                wr, z, _, error = _inverse_fit(w[lines], h[lines, o, i])
                if 0 < z < 1 and abs(wr / (2 * np.pi) - f_r) <= half:  # a resonance in this FRF's band
                    est.append((error, wr / (2 * np.pi), z))
        if est:
            est = np.asarray(est)
            weight = 1 / np.maximum(est[:, 0], 1e-9) ** 2
            f_new = float(np.sum(weight * est[:, 1]) / np.sum(weight))
            z_new = float(np.sum(weight * est[:, 2]) / np.sum(weight))
            if 0 < z_new < 1 and abs(f_new - f_r) <= half and basin[0] <= f_new <= basin[1]:
                f_r, zeta, widen, valid, best = f_new, z_new, 1.0, valid + 1, float(np.min(est[:, 0]))
                if valid == 2:
                    break
                continue
        widen *= 2
    if valid < 2:
        raise ValueError(
            f"resonance near {f[k]:.6g} Hz: no consistent SDOF fit (eq. 3.35) within ±{half:.3g} Hz: too few "
            "usable lines, or the resonance is not separated from its neighbours (use identify, pLSCF)"
        )
    # modal constants with the common ω_r, ζ and a constant residual for the other modes
    wr = 2 * np.pi * f_r
    constants = np.zeros((n_out, n_in), dtype=np.complex128)
    for o in range(n_out):
        for i in range(n_in):
            lines = band & usable[:, o, i]
            if np.count_nonzero(lines) >= 3:
                basis = np.column_stack([1 / (wr**2 - w[lines] ** 2 + 2j * zeta * wr * w[lines]), np.ones(lines.sum())])
                constants[o, i] = np.linalg.lstsq(basis, h[lines, o, i], rcond=None)[0][0]
    return f_r, zeta, constants, half, best


def sdof_fit(
    frfs: FRFData,
    frequencies_hz: Float[ArrayLike, " m"] | None = None,
    *,
    bandwidths: float = 1.0,
    max_error: float = 0.05,
    min_coherence: float = 0.5,
    fmin: float | None = None,
    fmax: float | None = None,
    real: bool = True,
) -> ModalData:
    """Natural frequency, damping and shape of each resonance by the inverse-FRF quadratic fit.

    Near resonance r the receptance is that of one viscously damped DoF, eq. 3.34, so
    1/H = aω² + bω + c (eq. 3.35) with a = −m/f, b = 2iζω_r m/f, c = ω_r² m/f (eq. 3.36),
    whence ω_r² = −c/a and ζ = −b/(2iω_r a) (eq. 3.37). The fit keeps the structure of
    eq. 3.36, one complex scale A = −1/a times real ω_r² and ζ (see ``_inverse_fit``
    for why). Mobility and accelerance are first divided by iω and −ω².

    Each FRF is fitted on the lines within ``bandwidths`` × ζf of the peak (at least 3
    lines each side), twice (the second pass centred on the fitted f with the fitted
    ζ); f_r and ζ_r average the FRFs whose fit shows a resonance in the band (0 < ζ < 1),
    weighted by 1/e², e the RMS relative error of each FRF's fit (an FRF where the mode
    does not dominate fits badly and counts little). The modal constants A are then
    refitted per FRF with the common ω_r, ζ and a constant residual for the other modes,
    H ≈ A/(ω_r² − ω² + 2iζω_rω) + B; the shape is their dominant singular vector over
    the inputs, scaled to unit modal mass through a driving point if there is one.

    **Arguments:**

    - ``frfs``: measured FRFs.
    - ``frequencies_hz``: approximate resonance frequencies. By default every peak of
      Σ|H|² (each FRF normalised) standing out by a factor 1.25 (scipy ``find_peaks``)
      is tried, and kept when its fit converges with a best-FRF RMS relative error
      ≤ ``max_error`` (noise peaks do not fit a resonance); fits that land within each
      other's band are merged (the better kept).
    - ``min_coherence``: values with lower coherence are left out (warned).
    - ``fmin``, ``fmax``: band of lines used, Hz. ``real``: real normal modes
      (:meth:`ModalData.real`), else complex shapes.

    **Returns:** :class:`ModalData` at ``frfs.outputs``, ordered by frequency.

    Raises ``ValueError`` when a given resonance has no consistent fit (fewer than 5
    usable lines, no positive ω², damping outside (0, 1)) or, by default, when no peak
    fits. Warns when the bands of two resonances overlap: the SDOF assumption does not
    hold there; use :func:`identify`.
    """
    from scipy.signal import find_peaks

    f, h, usable, _ = _data(frfs, fmin, fmax, min_coherence)
    w = 2 * np.pi * f
    h = h / (1j * w[:, None, None]) ** _POWER[frfs.kind]
    indicator = _indicator(h, usable)
    auto = frequencies_hz is None
    if auto:
        floor = np.min(indicator[indicator > 0]) if np.any(indicator > 0) else 1.0  # masked lines: no peak
        peaks, _ = find_peaks(np.log10(np.maximum(indicator, floor)), prominence=np.log10(1.25))
        lines = list(peaks)
    else:
        guesses = np.sort(np.asarray(frequencies_hz, dtype=np.float64).reshape(-1))
        outside = guesses[(guesses < f[0]) | (guesses > f[-1])]
        if len(outside):
            raise ValueError(f"resonance guess {outside[0]} Hz is outside the data [{f[0]:.6g}, {f[-1]:.6g}] Hz")
        lines = []
        for r, guess in enumerate(guesses):  # the peak nearest each guess, within half-way to its neighbours
            lo = guess - (guess - guesses[r - 1]) / 2 if r > 0 else f[0]
            hi = guess + (guesses[r + 1] - guess) / 2 if r + 1 < len(guesses) else f[-1]
            near = np.flatnonzero((f >= lo) & (f <= hi))
            lines.append(near[np.argmax(indicator[near])] if len(near) else int(np.argmin(np.abs(f - guess))))
    fits = []
    for k in lines:
        try:
            fit = _sdof_resonance(f, w, h, usable, indicator, k, bandwidths)
        except ValueError:
            if auto:
                continue
            raise
        if not auto or fit[4] <= max_error:
            fits.append(fit)
    if auto:
        kept: list = []
        for fit in sorted(fits, key=lambda x: x[4]):  # best fits first; drop those inside a kept band
            if all(abs(fit[0] - other[0]) > max(fit[3], other[3]) for other in kept):
                kept.append(fit)
        fits = sorted(kept, key=lambda x: x[0])
        if not fits:
            raise ValueError(
                f"no resonance in [{f[0]:.6g}, {f[-1]:.6g}] Hz fits an SDOF model within {max_error:g} "
                "(give frequencies_hz, or use identify)"
            )
    for a, b in itertools.pairwise(fits):
        if a[0] + a[3] > b[0] - b[3]:
            warnings.warn(
                f"the fitting bands of the resonances at {a[0]:.6g} and {b[0]:.6g} Hz overlap: the SDOF "
                "assumption of eq. 3.34 does not hold there (use identify, pLSCF)",
                stacklevel=2,
            )
            break
    freqs = np.array([x[0] for x in fits])
    zetas = np.array([x[1] for x in fits])
    modes, _ = _modal_data(frfs, freqs, zetas, np.array([x[2] for x in fits]), real)
    return modes
