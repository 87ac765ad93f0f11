"""Modal parameters from FRFs: SDOF inverse-FRF fit and polyreference LSCF + LSFD.

- :func:`sdof_fit`: one resonance at a time, the inverse receptance of a viscously
  damped single-DoF system is a quadratic in ω (thesis §3.3.2, eq. 3.34, eq. 3.35,
  eq. 3.36, eq. 3.37). For well separated modes.
- :func:`lscf` / :func:`stabilisation` / :func:`lsfd` / :func:`identify`: the
  polyreference least-squares complex frequency-domain estimator (pLSCF, "PolyMAX";
  Peeters, Van der Auweraer, Guillaume & Leuridan, Shock Vib. 11, 2004) on all FRFs at
  once, a stabilisation diagram over model orders with automatic selection of the
  poles that stay stable, and the mode shapes by a least-squares fit of residues with
  lower and upper residual terms (LSFD). Closely spaced modes are resolved.

Poles are s_r = −ζ_r ω_r + iω_r√(1−ζ_r²) (ω_r the undamped natural frequency, ζ_r the
viscous damping ratio), and the receptance is modelled as

    H(ω) = Σ_r [R_r/(iω − s_r) + R_r*/(iω − s_r*)] − LR/ω² + UR            (Ewins §2.8)

For proportional damping φ_out φ_in = 2iω_d R (ω_d = Im s) with mass-normalised
real modes φ; that scales the shapes when an output is also an input (driving point).
Mobility and accelerance carry the factor iω and −ω² on every term. Everything here
is NumPy/SciPy float64 on the host.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Sequence

import numpy as np
from jaxtyping import ArrayLike, Complex, Float

from ._data import FRFData, ModalData, Sensors
from ._frf import _bands, _format_bands, coherence_mask

_POWER = {"receptance": 0, "mobility": 1, "accelerance": 2}  # H_kind = (iω)^p H_receptance


# -- shared helpers --------------------------------------------------------------------


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


def _poles(frequencies_hz, damping_ratios) -> np.ndarray:
    w = 2 * np.pi * np.asarray(frequencies_hz, dtype=np.float64)
    z = np.asarray(damping_ratios, dtype=np.float64)
    return w * (-z + 1j * np.sqrt(1 - z**2))


def _driving_points(outputs: Sensors, inputs: Sensors) -> list[tuple[int, int, float]]:
    """(output index, input index, ±1) for outputs measuring an input's DoF (−1: opposite direction)."""
    pairs = []
    for i in range(len(inputs)):
        same = np.flatnonzero(
            (outputs.nodes == inputs.nodes[i])
            & (outputs.rotational == inputs.rotational[i])
            & (np.abs(outputs.directions @ inputs.directions[i]) > 1 - 1e-9)
        )
        if len(same):
            o = int(same[0])
            pairs.append((o, i, float(np.sign(outputs.directions[o] @ inputs.directions[i]))))
    return pairs


def _shape(q: np.ndarray, driving: list[tuple[int, int, float]]) -> tuple[np.ndarray, bool]:
    """Shape ψ from the modal constants Q = φ_out φ_inᵀ (n_out, n_in) of one mode.

    ψ ∝ the dominant left singular vector u of Q; with driving points (o, i, ±1) the
    scale c of ψ = c u follows from Q_{o', i} = ±ψ_{o'} ψ_o in least squares (unit modal
    mass). Without a driving point, or when the mode has (almost) no motion at the
    driving points (|u_o| < 1e-6 max |u|), the largest component is set to 1. Returns
    (ψ, whether it has unit modal mass).
    """
    u = np.linalg.svd(q, full_matrices=False)[0][:, 0]
    if driving:
        outs = np.array([o for o, _, _ in driving])
        ins = np.array([i for _, i, _ in driving])
        sign = np.array([s for _, _, s in driving])
        if np.max(np.abs(u[outs])) >= 1e-6 * np.max(np.abs(u)):
            basis = u[:, None] * (sign * u[outs])[None, :]  # (n_out, n_driving)
            c2 = np.vdot(basis, q[:, ins]) / np.vdot(basis, basis)
            return np.sqrt(c2) * u, True
    return u / u[np.argmax(np.abs(u))], False


def _mac(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """MAC between the columns of a (n, p) and b (n, q), complex-aware (thesis eq. 1.54)."""
    num = np.abs(a.conj().T @ b) ** 2
    return num / np.outer(np.sum(np.abs(a) ** 2, axis=0), np.sum(np.abs(b) ** 2, axis=0))


def _modal_data(frfs: FRFData, freqs, zetas, constants: np.ndarray, real: bool) -> tuple[ModalData, np.ndarray]:
    """ModalData from modal constants Q (m, n_out, n_in); also the complexity of each mode.

    Generalised masses are 1 when every shape could be scaled through a driving point
    (real modes only: dataset 55 holds no mass for complex ones), else None.
    """
    driving = _driving_points(frfs.outputs, frfs.inputs)
    shapes, complexity, scaled = [], [], True
    for q in constants:
        psi, unit_mass = _shape(q, driving)
        shapes.append(psi)
        scaled &= unit_mass
        complexity.append(1.0 - abs(np.sum(psi**2)) / np.sum(np.abs(psi) ** 2))
    phi = np.column_stack(shapes) if shapes else np.zeros((len(frfs.outputs), 0), dtype=np.complex128)
    modes = ModalData(freqs, phi, frfs.outputs, damping_ratios=zetas)
    if real:
        modes = modes.real()
        if scaled:
            modes = ModalData(
                modes.frequencies_hz,
                modes.shapes,
                modes.sensors,
                damping_ratios=modes.damping_ratios,
                generalised_masses=np.ones(modes.n_modes),
                mode_ids=modes.mode_ids,
            )
    return modes, np.asarray(complexity)


# -- SDOF: eq. 3.34, eq. 3.35, eq. 3.36, eq. 3.37 --------------------------------------


def _indicator(h: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """Σ over FRFs of |H|² normalised per FRF: peaks at every resonance."""
    mag = np.where(usable, np.abs(h), 0.0) ** 2
    peak = np.max(mag, axis=0, keepdims=True)
    return np.sum(mag / np.where(peak > 0, peak, 1.0), axis=(1, 2))


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


# -- pLSCF: poles per model order --------------------------------------------------------


def _normal_blocks(w: np.ndarray, h: np.ndarray, weight: np.ndarray, dt: float, p: int):
    """Reduced normal-equation blocks R_o, S_o, T_o of pLSCF at the highest order p.

    With Ω_r(ω) = e^{iωΔt r}, X_o = w_o[Ω_0 … Ω_p] and Y_o = −w_o[Ω_0 H_o … Ω_p H_o]
    (Peeters et al. 2004, eqs. 4–8): R_o = Re X_oᴴX_o, S_o = Re X_oᴴY_o, T_o = Re Y_oᴴY_o.
    Each depends on r − s only (Toeplitz), so it is built from sums over lines of
    w²e^{iωΔt d}(·), d = −p…p. Columns of S and T run order-major, input-minor, so the
    blocks of a lower order are leading sub-blocks.
    """
    d = np.arange(-p, p + 1)
    e = np.exp(1j * np.outer(w * dt, d))  # (nf, 2p+1)
    w2 = weight**2  # (nf, n_out)
    g_r = np.einsum("ko,kd->od", w2, e)
    g_s = np.einsum("ko,koj,kd->ojd", w2, h, e)
    g_t = np.einsum("ko,koi,koj,kd->oijd", w2, h.conj(), h, e)
    idx = d[None, p:] - d[p:, None] + p  # (r, s) → s − r + p
    n_out, n_in = h.shape[1:]
    q = (p + 1) * n_in
    R = g_r[:, idx].real
    S = -g_s[:, :, idx].real.transpose(0, 2, 3, 1).reshape(n_out, p + 1, q)
    T = g_t[:, :, :, idx].real.transpose(0, 3, 1, 4, 2).reshape(n_out, q, q)
    return R, S, T


def _order_poles(R, S, T, p: int, n_in: int, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poles s (continuous), participation vectors L (n_in, n) and shapes (n_out, n) of the order-p model.

    The shapes are the numerators at each pole, ψ_o ∝ N_o(z_r) L_r with the eliminated
    numerator coefficients recovered as β_o = −R_o⁻¹S_o α (the residue of N_o D⁻¹ at
    z_r up to a factor common to all outputs): cheap, and enough for the MAC test of the
    stabilisation diagram; :func:`lsfd` gives the final shapes.
    """
    q = (p + 1) * n_in
    r, s, t = R[:, : p + 1, : p + 1], S[:, : p + 1, :q], T[:, :q, :q]
    M = np.sum(t - np.swapaxes(s, 1, 2) @ np.linalg.solve(r, s), axis=0)  # Σ_o T_o − S_oᵀR_o⁻¹S_o
    a = p * n_in
    alpha = -np.linalg.lstsq(M[:a, :a], M[:a, a:], rcond=None)[0]  # constraint α_p = I
    companion = np.zeros((a, a))
    companion[: a - n_in, n_in:] = np.eye(a - n_in)
    companion[a - n_in :, :] = -np.concatenate([alpha[k * n_in : (k + 1) * n_in] for k in range(p)], axis=1)
    z, v = np.linalg.eig(companion)
    with np.errstate(divide="ignore", invalid="ignore"):  # z = 0: no finite pole, dropped by the caller
        poles = np.log(z.astype(np.complex128)) / dt  # z = e^{sΔt}
    beta = -np.linalg.solve(r, s @ np.concatenate([alpha, np.eye(n_in)]))  # (n_out, p + 1, n_in)
    participation = v[:n_in]
    numerators = np.einsum("rk,okj->orj", np.power.outer(z.astype(np.complex128), np.arange(p + 1)), beta)
    shapes = np.einsum("orj,jr->or", numerators, participation)
    return poles, participation, shapes


def lscf(
    frfs: FRFData,
    orders: Sequence[int],
    *,
    fmin: float | None = None,
    fmax: float | None = None,
    min_coherence: float = 0.5,
    max_damping: float = 0.2,
) -> dict[int, Complex[np.ndarray, " n"]]:
    """Physical poles of the polyreference LSCF model at each model order.

    Right matrix-fraction model per output row, H_o(ω) = N_o(ω) D(ω)⁻¹ with matrix
    polynomials in z = e^{iωΔt}, Δt = 1/(2 f_max); the equation errors
    w_o(N_o − H_o D) are minimised in least squares with the denominator normalised by
    α_p = I, the numerators eliminated (reduced normal equations), and the poles are the
    eigenvalues z_r of the companion matrix of D, s_r = ln(z_r)/Δt (Peeters et al. 2004).
    Each output row is weighted by 1/RMS‖H_o‖ so every sensor counts alike; a row is
    left out at a line where one of its values is masked by ``min_coherence``.

    **Returns:** {order: poles s (rad/s), Im s > 0, Re s < 0, ζ ≤ ``max_damping``,
    undamped frequency in the band}, sorted by frequency.
    """
    f, h, usable, _ = _data(frfs, fmin, fmax, min_coherence)
    orders = sorted({int(p) for p in orders})
    if not orders or orders[0] < 1:
        raise ValueError(f"model orders must be positive integers, got {orders}")
    return {p: poles for p, (poles, _, _) in zip(orders, _lscf_poles(f, h, usable, orders, max_damping))}


def _lscf_poles(f, h, usable, orders, max_damping):
    """[(poles, participation (n_in, n), numerator shapes (n_out, n))] per order, filtered to physical poles."""
    n_out, n_in = h.shape[1:]
    w = 2 * np.pi * f
    dt = 1.0 / (2 * f[-1])
    row_ok = np.all(usable, axis=2)  # (nf, n_out): an output row counts only where all its inputs are usable
    active = np.flatnonzero(np.any(row_ok, axis=0))
    if not len(active):
        raise ValueError("no frequency line where all inputs of an output are usable: pLSCF has no data")
    row_ok = row_ok[:, active]
    h_act = np.where(usable, h, 0.0)[:, active]
    power = np.sum(np.where(row_ok[:, :, None], np.abs(h_act) ** 2, 0.0), axis=(0, 2)) / np.sum(row_ok, axis=0)
    weight = row_ok / np.where(power > 0, np.sqrt(power), 1.0)[None, :]
    R, S, T = _normal_blocks(w, h_act, weight, dt, max(orders))
    out = []
    for p in orders:
        s, participation, shapes_act = _order_poles(R, S, T, p, n_in, dt)
        wn = np.abs(s)
        keep = np.isfinite(s) & (s.imag > 0) & (s.real < 0) & (wn >= w[0]) & (wn <= w[-1])
        keep &= -s.real <= max_damping * wn
        order = np.flatnonzero(keep)[np.argsort(wn[keep])]
        shapes = np.zeros((n_out, len(order)), dtype=np.complex128)
        shapes[active] = shapes_act[:, order]
        out.append((s[order], participation[:, order], shapes))
    return out


# -- LSFD: residues for known poles -----------------------------------------------------------


def _lsfd_basis(w: np.ndarray, poles: np.ndarray, power: int, lower: bool, upper: bool) -> np.ndarray:
    """Complex basis (nf, 2m + residuals) whose real coefficients are Re R, Im R, LR, UR."""
    iw = 1j * w[:, None]
    a, b = 1 / (iw - poles[None, :]), 1 / (iw - poles.conj()[None, :])
    cols = [a + b, 1j * (a - b)]  # R/(iω−s) + R*/(iω−s*) = Re R (a + b) + Im R · i(a − b)
    if lower:
        cols.append(-1 / w[:, None] ** 2)
    if upper:
        cols.append(np.ones((len(w), 1)))
    return np.concatenate(cols, axis=1) * (1j * w[:, None]) ** power


def _lsfd(f, h, usable, poles, power, lower=True, upper=True):
    """Residues (m, n_out, n_in), lower and upper residuals (n_out, n_in), synthesis (nf, n_out, n_in).

    Real least squares over the stacked real and imaginary parts, columns scaled to unit
    norm, one solve per pattern of masked lines.
    """
    w = 2 * np.pi * f
    m = len(poles)
    basis = _lsfd_basis(w, poles, power, lower, upper)
    scale = np.linalg.norm(basis, axis=0)
    scale[scale == 0] = 1.0
    basis_n = basis / scale
    n_out, n_in = h.shape[1:]
    flat_h = h.reshape(len(f), -1)
    flat_mask = usable.reshape(len(f), -1)
    coef = np.zeros((basis.shape[1], n_out * n_in))
    patterns: dict[bytes, list[int]] = {}
    for j in range(flat_h.shape[1]):
        patterns.setdefault(flat_mask[:, j].tobytes(), []).append(j)
    for cols in patterns.values():
        rows = flat_mask[:, cols[0]]
        b, y = (basis_n, flat_h[:, cols]) if rows.all() else (basis_n[rows], flat_h[rows][:, cols])
        lhs = np.concatenate([b.real, b.imag])
        coef[:, cols] = np.linalg.lstsq(lhs, np.concatenate([y.real, y.imag]), rcond=None)[0]
    coef /= scale[:, None]
    residues = (coef[:m] + 1j * coef[m : 2 * m]).reshape(m, n_out, n_in)
    k = 2 * m
    lr = coef[k].reshape(n_out, n_in) if lower else np.zeros((n_out, n_in))
    ur = coef[k + int(lower)].reshape(n_out, n_in) if upper else np.zeros((n_out, n_in))
    synthesis = (basis @ coef).reshape(len(f), n_out, n_in)
    return residues, lr, ur, synthesis


def lsfd(
    frfs: FRFData,
    poles: Complex[ArrayLike, " m"],
    *,
    fmin: float | None = None,
    fmax: float | None = None,
    lower_residual: bool = True,
    upper_residual: bool = True,
    min_coherence: float = 0.5,
) -> tuple[Complex[np.ndarray, "m nout nin"], Float[np.ndarray, "nout nin"], Float[np.ndarray, "nout nin"]]:
    """Residues R_r of every FRF for known poles, with lower and upper residuals (LSFD).

    Fits H(ω) = Σ_r [R_r/(iω − s_r) + R_r*/(iω − s_r*)] − LR/ω² + UR (times iω or −ω²
    for mobility or accelerance) to each FRF in linear least squares, real and
    imaginary parts stacked; masked values (``min_coherence``) are left out.

    **Returns:** (R (m, n_out, n_in) complex, LR (n_out, n_in), UR (n_out, n_in)); for a
    receptance R in m/(N·s), LR in m/N·(rad/s)², UR in m/N (mobility and accelerance:
    the same, as the factor iω or −ω² is in the basis).
    """
    poles = np.asarray(poles, dtype=np.complex128).reshape(-1)
    if np.any(~np.isfinite(poles)) or np.any(poles.imag <= 0):
        raise ValueError("poles must be finite with positive imaginary part (one of each conjugate pair)")
    f, h, usable, _ = _data(frfs, fmin, fmax, min_coherence)
    residues, lr, ur, _ = _lsfd(f, h, usable, poles, _POWER[frfs.kind], lower_residual, upper_residual)
    return residues, lr, ur


# -- stabilisation diagram and automatic selection -------------------------------------------


def _stabilisation(f, h, usable, orders, tol_f, tol_zeta, min_mac, max_damping) -> dict:
    poles_by_order = _lscf_poles(f, h, usable, orders, max_damping)
    rows = {key: [] for key in ("order", "pole", "stable_frequency", "stable_damping", "stable_mac")}
    shapes_all = []
    previous = None
    for p, (poles, _, shapes) in zip(orders, poles_by_order):
        fn, zn = np.abs(poles) / (2 * np.pi), -poles.real / np.abs(poles)
        sf = np.zeros(len(poles), dtype=bool)
        sd, sv = sf.copy(), sf.copy()
        if previous is not None and len(previous[0]) and len(poles):
            f0, z0, shapes0 = previous
            df = np.abs(fn[:, None] - f0[None, :]) / fn[:, None]
            mac = _mac(shapes, shapes0)
            j = np.argmin(df + (1 - mac), axis=1)  # the previous-order pole most like this one
            k = np.arange(len(poles))
            sf = df[k, j] <= tol_f
            sd = np.abs(zn - z0[j]) <= tol_zeta * zn
            sv = mac[k, j] >= min_mac
        rows["order"] += [p] * len(poles)
        rows["pole"] += poles.tolist()
        rows["stable_frequency"] += sf.tolist()
        rows["stable_damping"] += sd.tolist()
        rows["stable_mac"] += sv.tolist()
        shapes_all.append(shapes)
        previous = (fn, zn, shapes)
    table = {key: np.asarray(val) for key, val in rows.items()}
    table["pole"] = table["pole"].astype(np.complex128)
    table["shape"] = (
        np.concatenate(shapes_all, axis=1) if shapes_all else np.zeros((h.shape[1], 0), dtype=np.complex128)
    )
    return table


def _select(table: dict, n_orders: int, tol_f: float, min_mac: float, min_fraction: float) -> list[np.ndarray]:
    """Clusters of poles stable in frequency, damping and MAC that recur over many orders.

    Distance between two stable poles: max(|Δf|/(f̄ tol_f), (1 − MAC)/(1 − min_mac));
    average-linkage clusters closer than 1; a cluster counts as a mode when it holds
    poles from at least max(3, ``min_fraction`` × number of orders) orders. Returns, per
    mode, the indices of its poles (one per order, the one nearest the cluster median).
    """
    from scipy.cluster.hierarchy import fcluster, linkage
    from scipy.spatial.distance import squareform

    stable = np.flatnonzero(table["stable_frequency"] & table["stable_damping"] & table["stable_mac"])
    if len(stable) == 0:
        return []
    if len(stable) == 1:
        labels = np.array([1])
    else:
        fn = np.abs(table["pole"][stable]) / (2 * np.pi)
        shapes = table["shape"][:, stable]
        df = np.abs(fn[:, None] - fn[None, :]) / (0.5 * (fn[:, None] + fn[None, :]))
        dist = np.maximum(df / tol_f, (1 - _mac(shapes, shapes)) / (1 - min_mac))
        dist = 0.5 * (dist + dist.T)
        np.fill_diagonal(dist, 0.0)
        labels = fcluster(linkage(squareform(dist, checks=False), method="average"), t=1.0, criterion="distance")
    needed = max(3, math.ceil(min_fraction * n_orders))
    modes = []
    for label in np.unique(labels):
        members = stable[labels == label]
        fn = np.abs(table["pole"][members])
        centre = np.median(fn)
        chosen = []
        for p in np.unique(table["order"][members]):
            at_p = members[table["order"][members] == p]
            chosen.append(at_p[np.argmin(np.abs(np.abs(table["pole"][at_p]) - centre))])
        if len(chosen) >= needed:
            modes.append(np.asarray(chosen))
    return sorted(modes, key=lambda idx: np.median(np.abs(table["pole"][idx])))


def stabilisation(
    frfs: FRFData,
    orders: Sequence[int] | None = None,
    *,
    fmin: float | None = None,
    fmax: float | None = None,
    min_coherence: float = 0.5,
    tol_f: float = 0.01,
    tol_zeta: float = 0.05,
    min_mac: float = 0.98,
    max_damping: float = 0.2,
) -> dict:
    """Stabilisation diagram of pLSCF poles over model orders.

    A pole at order p is compared with the most similar pole at the previous order
    (smallest |Δf|/f + 1 − MAC; shapes from the pLSCF numerators at the pole): stable in
    frequency when |Δf|/f ≤ ``tol_f``, in damping when |Δζ|/ζ ≤ ``tol_zeta``, in shape
    when MAC ≥ ``min_mac``. Poles of the lowest order are new.

    **Returns:** a JSON-ready dict of lists, one entry per pole: ``order``,
    ``frequency_hz``, ``damping_ratio``, ``stable_frequency``, ``stable_damping``,
    ``stable_mac``; and ``orders``, ``criteria``.
    """
    orders = _orders(orders, len(frfs.inputs))
    f, h, usable, _ = _data(frfs, fmin, fmax, min_coherence)
    table = _stabilisation(f, h, usable, orders, tol_f, tol_zeta, min_mac, max_damping)
    return _diagram_json(table, orders, tol_f, tol_zeta, min_mac)


def _orders(orders, n_in: int) -> list[int]:
    if orders is None:
        return list(range(2, max(4, 40 // n_in) + 1))
    orders = sorted({int(p) for p in orders})
    if len(orders) < 3 or orders[0] < 1:
        raise ValueError(f"a stabilisation diagram needs at least 3 positive model orders, got {orders}")
    return orders


def _diagram_json(table: dict, orders, tol_f, tol_zeta, min_mac, selected=None) -> dict:
    s = table["pole"]
    out = {
        "orders": list(orders),
        "criteria": {"tol_frequency": tol_f, "tol_damping": tol_zeta, "min_mac": min_mac},
        "order": table["order"].astype(int).tolist(),
        "frequency_hz": (np.abs(s) / (2 * np.pi)).tolist(),
        "damping_ratio": (-s.real / np.abs(s)).tolist() if len(s) else [],
        "stable_frequency": table["stable_frequency"].astype(bool).tolist(),
        "stable_damping": table["stable_damping"].astype(bool).tolist(),
        "stable_mac": table["stable_mac"].astype(bool).tolist(),
    }
    if selected is not None:
        mode = np.zeros(len(s), dtype=int)
        for r, idx in enumerate(selected):
            mode[idx] = r + 1
        out["mode"] = mode.tolist()  # 1-based mode number of the poles that made each mode, 0 otherwise
    return out


# -- all in one ------------------------------------------------------------------------------------


def identify(
    frfs: FRFData,
    *,
    fmin: float | None = None,
    fmax: float | None = None,
    orders: Sequence[int] | None = None,
    min_coherence: float = 0.5,
    tol_f: float = 0.01,
    tol_zeta: float = 0.05,
    min_mac: float = 0.98,
    max_damping: float = 0.2,
    min_fraction: float = 0.25,
    real: bool = True,
) -> tuple[ModalData, dict]:
    """Modes from FRFs: pLSCF stabilisation diagram, automatic pole selection, LSFD shapes.

    1. pLSCF poles at every order in ``orders`` (default 2 … 40/n_in), :func:`lscf`;
    2. stabilisation flags against the previous order, :func:`stabilisation`;
    3. poles stable in frequency, damping and MAC are clustered (|Δf|/f within
       ``tol_f``, MAC ≥ ``min_mac``); a cluster spanning at least
       max(3, ``min_fraction`` × n_orders) orders is a mode, with the median frequency
       and damping of its poles;
    4. residues of all FRFs for those poles with lower and upper residuals (LSFD); the
       shape is the dominant singular vector of each mode's residue matrix, scaled to
       unit modal mass through driving points (output DoF = input DoF) when there are
       any (generalised masses 1), else to a largest component of 1;
    5. ``real=True``: real normal modes by :meth:`ModalData.real` (thesis §2.3.1);
       otherwise the complex shapes.

    Values with coherence below ``min_coherence`` are left out with a ``UserWarning``
    naming the bands (:func:`low_coherence_bands`); an FRF without any usable line is
    refused.

    **Returns:** ``(modes, report)``: :class:`ModalData` at ``frfs.outputs`` (write it
    with :func:`write_uff`) and a JSON-ready dict: ``band_hz``, ``n_lines``,
    ``coherence`` ("given"/"not given"), ``masked_bands_hz``, ``orders``, per mode
    (``modes``) the frequency, damping, the number of orders it is stable over, the
    spread (std) of f and ζ across them and its complexity 1 − |Σψ²|/Σ|ψ|² (0: real,
    1: circular), the fit (``fit``: normalised mean-square error % of the synthesis,
    mean and worst FRF), the diagram (``stabilisation``, see :func:`stabilisation`,
    with ``mode``) and the mode indicator (``indicator``) for
    :func:`identification._plots.plot_stabilisation`.

    Raises ``ValueError`` when no pole is stable over enough orders.
    """
    orders = _orders(orders, len(frfs.inputs))
    f, h, usable, bands = _data(frfs, fmin, fmax, min_coherence)
    power = _POWER[frfs.kind]
    table = _stabilisation(f, h, usable, orders, tol_f, tol_zeta, min_mac, max_damping)
    clusters = _select(table, len(orders), tol_f, min_mac, min_fraction)
    if not clusters:
        raise ValueError(
            f"no pole is stable over {max(3, math.ceil(min_fraction * len(orders)))} of the orders {orders[0]}–"
            f"{orders[-1]} in [{f[0]:.6g}, {f[-1]:.6g}] Hz; try higher orders or looser criteria"
        )
    fn = [np.abs(table["pole"][idx]) / (2 * np.pi) for idx in clusters]
    zn = [-table["pole"][idx].real / np.abs(table["pole"][idx]) for idx in clusters]
    freqs = np.array([np.median(x) for x in fn])
    zetas = np.array([np.median(x) for x in zn])
    poles = _poles(freqs, zetas)
    residues, _, _, synthesis = _lsfd(f, h, usable, poles, power)
    constants = 2j * poles.imag[:, None, None] * residues  # φ_out φ_in = 2iω_d R
    modes, complexity = _modal_data(frfs, freqs, zetas, constants, real)
    err = np.where(usable, np.abs(h - synthesis) ** 2, 0.0).sum(axis=0)
    ref = np.where(usable, np.abs(h) ** 2, 0.0).sum(axis=0)
    nmse = 100 * err / ref
    o, i = np.unravel_index(np.argmax(nmse), nmse.shape)
    indicator = _indicator(h, usable)
    report = {
        "method": "pLSCF (Peeters et al. 2004) + LSFD with lower/upper residuals",
        "kind": frfs.kind,
        "band_hz": [float(f[0]), float(f[-1])],
        "n_lines": len(f),
        "coherence": "not given" if frfs.coherence is None else "given",
        "min_coherence": min_coherence,
        "masked_bands_hz": [list(b) for b in bands],
        "orders": list(orders),
        "min_orders": max(3, math.ceil(min_fraction * len(orders))),
        "real_modes": real,
        "mass_normalised": modes.generalised_masses is not None,
        "modes": [
            {
                "mode": r + 1,
                "frequency_hz": float(freqs[r]),
                "damping_ratio": float(zetas[r]),
                "n_orders_stable": len(clusters[r]),
                "frequency_std_hz": float(np.std(fn[r])),
                "damping_std": float(np.std(zn[r])),
                "complexity": float(complexity[r]),
            }
            for r in range(len(freqs))
        ],
        "fit": {
            "nmse_percent_mean": float(np.mean(nmse)),
            "nmse_percent_worst": float(nmse[o, i]),
            "worst_frf": f"{frfs.outputs.labels[o]} / {frfs.inputs.labels[i]}",
        },
        "stabilisation": _diagram_json(table, orders, tol_f, tol_zeta, min_mac, clusters),
        "indicator": {"frequency_hz": f.tolist(), "value": (indicator / max(np.max(indicator), 1e-300)).tolist()},
    }
    return modes, report
