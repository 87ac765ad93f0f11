"""FRF estimation from measured signals, and flags for lines that cannot be trusted.

Two ways to an FRF, as in thesis §2.1:

- broadband excitation (random, burst, periodic): H1 or H2 and the coherence from
  block-averaged auto- and cross-spectra (Welch), :func:`frf_from_time`;
- stepped sine: the fundamental Fourier coefficient of force and response at each step
  frequency (thesis eq. 2.1, eq. 2.2) and their ratio (eq. 2.3), :func:`frf_stepped_sine`.

With the block spectra X_b, Y_b of force and response (one-sided, n_in and n_out
channels) and G_xx = Σ_b X_b X_bᴴ, G_yx = Σ_b Y_b X_bᴴ, G_yy = Σ_b |Y_b|²
(Bendat & Piersol, *Random Data*, 4th ed., §§9.1–9.2, 7.3):

    H1 = G_yx G_xx⁻¹          unbiased by noise on the response, biased low by noise on the force
    H2 = G_yy / G_xy          (one input) unbiased by noise on the force, biased high by noise on the response
    γ² = |G_yx|² / (G_xx G_yy) (one input; with several inputs the multiple coherence of
                                each output, G_yx G_xx⁻¹ G_xy / G_yy, is given for every input)

Window correction: every spectrum is formed from the same windowed blocks, so the
window's power correction 1/Σw² (and the PSD scale 2/f_s) is a common factor that
cancels in H1, H2 and γ²; no amplitude or energy correction is applied.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
from jaxtyping import ArrayLike, Bool, Complex, Float

from ._data import FRF_KINDS, FRFData, Sensors

WINDOWS = ("hann", "rect")
ESTIMATORS = ("H1", "H2")
_NO_FORCE = 1e-12  # force autospectrum (smallest eigenvalue) below this × its peak: no excitation
_NO_SIGNAL = 1e-12  # stepped sine: force amplitude below this × the largest one


def _bands(f: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """Contiguous runs of True in ``mask`` as (first Hz, last Hz)."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(float(f[a]), float(f[b])) for a, b in zip(starts, stops)]


def _format_bands(bands: list[tuple[float, float]], limit: int = 8) -> str:
    text = ", ".join(f"{a:.6g} Hz" if a == b else f"{a:.6g}–{b:.6g} Hz" for a, b in bands[:limit])
    return text + (f" and {len(bands) - limit} more" if len(bands) > limit else "")


def _channels(x, name: str, n_sensors: int) -> np.ndarray:
    """(n_samples, n_channels) float64, finite, one channel per sensor."""
    arr = np.asarray(x)
    if np.iscomplexobj(arr):
        raise ValueError(f"{name} must be real time histories, got dtype {arr.dtype}")
    arr = arr.astype(np.float64)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise ValueError(f"{name} must have shape (n_samples, n_channels), got {arr.shape}")
    if arr.shape[1] != n_sensors:
        raise ValueError(f"{name} has {arr.shape[1]} channel(s) but {n_sensors} sensor(s) are given")
    bad = np.argwhere(~np.isfinite(arr))
    if len(bad):
        n, c = bad[0]
        raise ValueError(f"{name} channel {c}: value {arr[n, c]} at sample {n}")
    return arr


def _window(name: str, n: int) -> np.ndarray:
    if name == "hann":  # periodic Hann, the DFT-even form used for spectral analysis
        return 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(n) / n)
    if name == "rect":
        return np.ones(n)
    raise ValueError(f"window {name!r} is not one of {WINDOWS}")


def _spectra(x: np.ndarray, y: np.ndarray, nperseg: int, step: int, window: np.ndarray):
    """Averaged G_xx (nf, ni, ni), G_yx (nf, no, ni), diag G_yy (nf, no) and the block count."""
    n_blocks = 1 + (len(x) - nperseg) // step
    idx = np.arange(nperseg)[None, :] + step * np.arange(n_blocks)[:, None]
    X = np.fft.rfft(window[None, :, None] * x[idx], axis=1)  # (b, nf, ni)
    Y = np.fft.rfft(window[None, :, None] * y[idx], axis=1)  # (b, nf, no)
    gxx = np.einsum("bki,bkj->kij", X, X.conj()) / n_blocks
    gyx = np.einsum("bko,bki->koi", Y, X.conj()) / n_blocks
    gyy = np.mean(np.abs(Y) ** 2, axis=0)
    return gxx, gyx, gyy, n_blocks


def frf_from_time(
    force: Float[ArrayLike, "n_samples n_in"],
    response: Float[ArrayLike, "n_samples n_out"],
    fs: float,
    *,
    inputs: Sensors,
    outputs: Sensors,
    kind: str,
    estimator: str = "H1",
    window: str = "hann",
    nperseg: int | None = None,
    overlap: float = 0.5,
    band: tuple[float, float] | None = None,
) -> FRFData:
    """H1 or H2 FRFs and coherence from force and response time histories (Welch).

    **Arguments:**

    - ``force`` (n_samples, n_in) in N (N·m for rotational inputs), ``response``
      (n_samples, n_out) in m, m/s or m/s² as ``kind`` says; 1-D for one channel.
      Sampled together at ``fs`` Hz.
    - ``inputs``, ``outputs``: the excitation and response DoFs, one per channel.
    - ``kind``: "receptance", "mobility" or "accelerance" (what the response measures).
    - ``estimator``: "H1" (G_yx G_xx⁻¹, any number of inputs) or "H2" (G_yy/G_xy, one
      input only).
    - ``window``: "hann" (random excitation) or "rect" (periodic excitation whose period
      is the block, or transients that die out within a block). The window's power
      correction cancels in H and γ² (module docstring).
    - ``nperseg``: block length in samples (default n_samples // 8); the resolution is
      fs/nperseg. ``overlap``: fraction of a block shared by consecutive blocks, in [0, 1).
    - ``band``: (f_lo, f_hi) Hz to keep; default every line but DC (0 Hz).

    **Returns:** :class:`FRFData` with the coherence (ordinary for one input, multiple
    for several, eq. in the module docstring), or None when there is a single block (it
    would be 1 by construction; lines without force are then left out).

    Raises ``ValueError`` for mismatched lengths or channel counts, NaN or infinite
    samples, a force or response channel that is zero throughout, or bad settings.
    Lines where the force has no energy (its autospectrum, or with several inputs the
    smallest eigenvalue of G_xx, below 1e-12 of its peak: band-limited or correlated
    excitation) get H = 0 and coherence 0 with a ``UserWarning`` naming the bands; so do
    H2 lines with G_xy = 0. :func:`low_coherence_bands` finds them again and the fitting
    functions leave them out.
    """
    if kind not in FRF_KINDS:
        raise ValueError(f"FRF kind {kind!r} is not one of {FRF_KINDS}")
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator {estimator!r} is not one of {ESTIMATORS}")
    if not (np.isfinite(fs) and fs > 0):
        raise ValueError(f"sampling rate fs = {fs} Hz is not finite and positive")
    x = _channels(force, "force", len(inputs))
    y = _channels(response, "response", len(outputs))
    if len(x) != len(y):
        raise ValueError(f"force has {len(x)} samples but response has {len(y)}: they must be sampled together")
    if estimator == "H2" and x.shape[1] != 1:
        raise ValueError(f"H2 needs a single input, got {x.shape[1]}; use H1 for several inputs")
    for name, arr, sensors in (("force", x, inputs), ("response", y, outputs)):
        c = np.flatnonzero(~np.any(arr != 0, axis=0))
        if len(c):
            raise ValueError(f"{name} channel {c[0]} ({sensors.labels[c[0]]}) is zero throughout")
    n = len(x)
    nperseg = n // 8 if nperseg is None else int(nperseg)
    if not 2 <= nperseg <= n:
        raise ValueError(f"nperseg = {nperseg} must be in 2..{n} (the number of samples)")
    if not 0 <= overlap < 1:
        raise ValueError(f"overlap = {overlap} must be in [0, 1)")
    step = max(1, round(nperseg * (1 - overlap)))
    gxx, gyx, gyy, n_blocks = _spectra(x, y, nperseg, step, _window(window, nperseg))
    f = np.fft.rfftfreq(nperseg, 1.0 / fs)
    lo, hi = (0.0, np.inf) if band is None else (float(band[0]), float(band[1]))
    if not lo < hi:
        raise ValueError(f"band {band} is empty: give (f_lo, f_hi) with f_lo < f_hi in Hz")
    keep = (f > 0) & (f >= lo) & (f <= hi)
    if not np.any(keep):
        raise ValueError(f"band {band} holds no frequency line of the estimate (resolution {fs / nperseg:.6g} Hz)")
    f, gxx, gyx, gyy = f[keep], gxx[keep], gyx[keep], gyy[keep]

    power = np.linalg.eigvalsh(gxx)  # ascending, (nf, ni)
    dead = power[:, 0] <= _NO_FORCE * np.max(power[:, -1])
    safe_gxx = np.where(dead[:, None, None], np.eye(x.shape[1]), gxx)
    h1 = np.linalg.solve(np.swapaxes(safe_gxx, 1, 2), np.swapaxes(gyx, 1, 2)).swapaxes(1, 2)  # H G_xx = G_yx
    explained = np.real(np.einsum("koi,koi->ko", h1, gyx.conj()))  # G_yx G_xx⁻¹ G_xy, per output
    if estimator == "H1":
        h = h1
    else:
        gxy = gyx[:, :, 0].conj()
        dead |= np.all(gxy == 0, axis=1)
        h = (gyy / np.where(gxy == 0, 1.0, gxy))[:, :, None]
    coherence = np.clip(np.where(gyy > 0, explained / np.where(gyy > 0, gyy, 1.0), 0.0), 0.0, 1.0)
    h = np.where(dead[:, None, None], 0.0, h)
    coherence = np.where(dead[:, None], 0.0, coherence)
    if np.any(dead):
        why = f"force autospectrum below {_NO_FORCE:g} of its peak"
        why += "" if x.shape[1] == 1 else ", or correlated inputs"
        why += ", or G_xy = 0 (H2)" if estimator == "H2" else ""
        action = "H set to 0 and coherence to 0 there" if n_blocks > 1 else "left out (one block: no coherence)"
        warnings.warn(f"no force at {_format_bands(_bands(f, dead))} ({why}): {action}", stacklevel=2)
    if n_blocks == 1:
        return FRFData(f[~dead], h[~dead], outputs, inputs, kind)
    coherence = np.broadcast_to(coherence[:, :, None], h.shape).copy()
    return FRFData(f, h, outputs, inputs, kind, coherence=coherence)


def sine_coefficients(
    x: Float[ArrayLike, " n_samples *channels"], fs: float, frequency_hz: float
) -> Complex[np.ndarray, "*channels"]:
    """Complex amplitude X of the fundamental, x(t) ≈ a₀/2 + Re(X e^{iωt}), X = a − ib.

    The coefficients of eq. 2.1 at the excitation frequency ω = 2πf, fitted by least
    squares to x(t_n), t_n = n/fs, over the whole record. For a record of whole periods
    the fit is the discrete Fourier sum of eq. 2.2 (a = 2a_j, b = 2b_j: this function
    returns the physical amplitude); for any other length it still recovers a pure sine
    plus offset exactly, where eq. 2.2 would leak.

    Raises ``ValueError`` for NaN samples, a frequency at or above fs/2 (Nyquist), or a
    record shorter than one period.
    """
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 0 or arr.shape[0] < 3:
        raise ValueError(f"a sine record needs at least 3 samples, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        n = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"sample {n[0]} is {arr[tuple(n)]}")
    if not 0 < frequency_hz < fs / 2:
        raise ValueError(f"frequency {frequency_hz} Hz is not in (0, fs/2 = {fs / 2} Hz)")
    periods = arr.shape[0] / fs * frequency_hz
    if periods < 1:
        raise ValueError(f"the record holds {periods:.3g} periods of {frequency_hz} Hz; at least one is needed")
    wt = 2 * np.pi * frequency_hz * np.arange(arr.shape[0]) / fs
    basis = np.column_stack([np.ones_like(wt), np.cos(wt), np.sin(wt)])  # eq. 2.1, fundamental only
    coef, *_ = np.linalg.lstsq(basis, arr.reshape(arr.shape[0], -1), rcond=None)
    return (coef[1] - 1j * coef[2]).reshape(arr.shape[1:])


def frf_stepped_sine(
    frequencies_hz: Float[ArrayLike, " n_steps"],
    force: Sequence[Float[ArrayLike, " n_samples"]],
    response: Sequence[Float[ArrayLike, "n_samples n_out"]],
    fs: float,
    *,
    inputs: Sensors,
    outputs: Sensors,
    kind: str,
) -> FRFData:
    """Stepped-sine FRFs: H(ω) = U(ω)/F(ω) of the fundamental coefficients, eq. 2.1, eq. 2.2,
    eq. 2.3.

    **Arguments:**

    - ``frequencies_hz`` (n_steps,): the step (excitation) frequencies, strictly
      increasing.
    - ``force``: one record per step, (n_samples_k,) in N, of the single input;
      ``response``: one record per step, (n_samples_k, n_out), sampled with the force.
      Records may differ in length between steps; the steady state is assumed (trim
      the transient before).
    - ``fs``: sampling rate, Hz; ``inputs`` (one sensor), ``outputs``, ``kind`` as in
      :func:`frf_from_time`.

    **Returns:** :class:`FRFData` without coherence (a single record per step gives no
    noise estimate).

    Raises ``ValueError`` for a step count that differs between the frequency axis and
    the records, mismatched record lengths, NaN samples, several inputs, and a step
    whose force amplitude at the step frequency is zero (below 1e-12 of the largest).
    """
    if kind not in FRF_KINDS:
        raise ValueError(f"FRF kind {kind!r} is not one of {FRF_KINDS}")
    if len(inputs) != 1:
        raise ValueError(
            f"stepped sine with {len(inputs)} inputs: one run excites one force pattern, so give one input per call"
        )
    freqs = np.asarray(frequencies_hz, dtype=np.float64).reshape(-1)
    if not (len(freqs) == len(force) == len(response)):
        raise ValueError(
            f"{len(freqs)} step frequencies but {len(force)} force and {len(response)} response records"
        )
    k = np.flatnonzero(np.diff(freqs) <= 0)
    if len(k):
        raise ValueError(f"step frequencies not strictly increasing: {freqs[k[0] + 1]} Hz after {freqs[k[0]]} Hz")
    f_coef = np.empty(len(freqs), dtype=np.complex128)
    u_coef = np.empty((len(freqs), len(outputs)), dtype=np.complex128)
    for step, (frequency, x, y) in enumerate(zip(freqs, force, response)):
        where = f"step {step} ({frequency:.6g} Hz)"
        try:
            x = _channels(x, "force", 1)
            y = _channels(y, "response", len(outputs))
            if len(x) != len(y):
                raise ValueError(f"force has {len(x)} samples but response has {len(y)}")
            f_coef[step] = sine_coefficients(x[:, 0], fs, frequency)
            u_coef[step] = sine_coefficients(y, fs, frequency)
        except ValueError as err:
            raise ValueError(f"{where}: {err}") from err
    level = np.abs(f_coef)
    k = np.flatnonzero(~(level > _NO_SIGNAL * np.max(level)))
    if len(k):
        raise ValueError(
            f"step {k[0]} ({freqs[k[0]]:.6g} Hz): no force at the step frequency (amplitude {level[k[0]]:.3g})"
        )
    h = u_coef / f_coef[:, None]  # eq. 2.3
    return FRFData(freqs, h[:, :, None], outputs, inputs, kind)


def merge_inputs(frf_sets: Sequence[FRFData]) -> FRFData:
    """One FRF matrix from runs with different inputs (e.g. one stepped-sine run per shaker).

    The runs must share the kind, the outputs (same labels, same order) and the frequency
    axis (to 1e-9 relative); their inputs are concatenated and must differ. The
    coherence is kept when every run has it; otherwise it is dropped with a
    ``UserWarning``. Raises ``ValueError`` naming the first run that does not match.
    """
    if not frf_sets:
        raise ValueError("no FRF sets to merge")
    first = frf_sets[0]
    f0 = np.asarray(first.frequencies_hz)
    for k, other in enumerate(frf_sets[1:], start=1):
        f = np.asarray(other.frequencies_hz)
        if other.kind != first.kind:
            raise ValueError(f"FRF set {k} is a {other.kind}, set 0 a {first.kind}")
        if other.outputs.labels != first.outputs.labels:
            raise ValueError(f"FRF set {k} has outputs {other.outputs.labels}, set 0 {first.outputs.labels}")
        if len(f) != len(f0):
            raise ValueError(
                f"FRF set {k} has a frequency axis different from set 0 ({len(f)} lines against {len(f0)})"
            )
        off = np.flatnonzero(~np.isclose(f, f0, rtol=1e-9, atol=0.0))
        if len(off):
            raise ValueError(
                f"FRF set {k} has a frequency axis different from set 0 (line {off[0]}: {f[off[0]]} Hz against "
                f"{f0[off[0]]} Hz)"
            )
    inputs = [s.inputs for s in frf_sets]
    nodes = np.concatenate([i.nodes for i in inputs])
    directions = np.concatenate([i.directions for i in inputs])
    rotational = np.concatenate([i.rotational for i in inputs])
    merged_inputs = Sensors(nodes, directions, rotational)  # refuses an input measured twice
    values = np.concatenate([np.asarray(s.values) for s in frf_sets], axis=2)
    coherence = None
    if all(s.coherence is not None for s in frf_sets):
        coherence = np.concatenate([np.asarray(s.coherence) for s in frf_sets], axis=2)
    elif any(s.coherence is not None for s in frf_sets):
        warnings.warn("only some FRF sets carry a coherence; it is dropped from the merged set", stacklevel=2)
    return FRFData(f0, values, first.outputs, merged_inputs, first.kind, coherence=coherence)


def coherence_mask(frfs: FRFData, threshold: float = 0.5) -> Bool[np.ndarray, "nf nout nin"]:
    """True where an FRF value is usable: coherence ≥ ``threshold`` (all True without coherence)."""
    if not 0 <= threshold <= 1:
        raise ValueError(f"coherence threshold {threshold} is not in [0, 1]")
    if frfs.coherence is None:
        return np.ones(np.shape(frfs.values), dtype=bool)
    return np.asarray(frfs.coherence) >= threshold


def low_coherence_bands(frfs: FRFData, threshold: float = 0.5) -> list[tuple[float, float]]:
    """Frequency bands (first Hz, last Hz) where the coherence of some FRF is below ``threshold``.

    Zero coherence marks lines without excitation (:func:`frf_from_time`) or data a
    reader flagged; a low value marks noise, leakage or non-linearity. Returns [] when
    the FRFs carry no coherence (nothing to judge; :func:`identification._fitting.identify`
    reports that).
    """
    bad = ~np.all(coherence_mask(frfs, threshold), axis=(1, 2))
    return _bands(np.asarray(frfs.frequencies_hz), bad)
