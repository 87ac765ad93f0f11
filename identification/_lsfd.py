"""LSFD: residues of all FRFs for known poles, and the mode shapes they give (thesis §2.3.1).

The receptance is modelled as H(ω) = Σ_r [R_r/(iω − s_r) + R_r*/(iω − s_r*)] − LR/ω² + UR
(Ewins §2.8) with poles s_r = −ζ_r ω_r + iω_r√(1−ζ_r²) (ω_r the undamped natural
frequency, ζ_r the viscous damping ratio); mobility and accelerance carry the factor iω
and −ω² on every term. :func:`lsfd` fits the residues R_r and the lower and upper
residuals LR, UR in linear least squares. For proportional damping φ_out φ_in = 2iω_d R
(ω_d = Im s) with mass-normalised real modes φ: the shape of a mode is the dominant
singular vector of its modal constants, scaled to unit modal mass through the driving
points (an output that is also an input) when there are any, and real normal modes
follow by :meth:`ModalData.real` (thesis §2.3.1). By Maxwell reciprocity (H_ij = H_ji)
the modal constants also give the shape at the inputs, so a shape covers every measured
or excited DoF (:func:`_modal_data`). NumPy float64 on the host.
"""

from __future__ import annotations

import numpy as np
from jaxtyping import ArrayLike, Complex, Float

from ._data import FRFData, ModalData, Sensors
from ._fit_data import _POWER, _data


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


def _union(outputs: Sensors, inputs: Sensors, driving: list[tuple[int, int, float]]) -> tuple[Sensors, np.ndarray]:
    """The outputs followed by the inputs that are not outputs (a driving point appears once,
    as its output); also the indices of those inputs."""
    measured = {i for _, i, _ in driving}
    extra = np.array([i for i in range(len(inputs)) if i not in measured], dtype=np.int64)
    sensors = Sensors(
        np.concatenate([outputs.nodes, inputs.nodes[extra]]),
        np.concatenate([outputs.directions, inputs.directions[extra]]),
        np.concatenate([outputs.rotational, inputs.rotational[extra]]),
    )
    return sensors, extra


def _shape(q: np.ndarray, driving: list[tuple[int, int, float]], extra: np.ndarray) -> tuple[np.ndarray, bool]:
    """Shape ψ at the outputs and at the inputs ``extra`` from the modal constants
    Q = ψ_out ψ_inᵀ (n_out, n_in) of one mode.

    ψ_out = c u, u the dominant left singular vector of Q (σ its singular value), and by
    reciprocity ψ_in = Qᵀū/c (as uᴴu = 1). With driving points (o, i, ±1) the scale c
    follows from Q_{o', i} = ±ψ_{o'} ψ_o in least squares (unit modal mass). Without a
    driving point, or when the mode has (almost) no motion at the driving points
    (|u_o| < 1e-6 max |u|), c = √σ (the relative scale of the outputs and ``extra`` is
    then a guess) and the largest component is set to 1. Returns (ψ (n_out + len(extra),),
    whether it has unit modal mass).
    """
    left, sigma, _ = np.linalg.svd(q, full_matrices=False)
    u, c, unit_mass = left[:, 0], np.sqrt(sigma[0]) + 0j, False
    if driving:
        outs = np.array([o for o, _, _ in driving])
        ins = np.array([i for _, i, _ in driving])
        sign = np.array([s for _, _, s in driving])
        if np.max(np.abs(u[outs])) >= 1e-6 * np.max(np.abs(u)):
            basis = u[:, None] * (sign * u[outs])[None, :]  # (n_out, n_driving)
            c, unit_mass = np.sqrt(np.vdot(basis, q[:, ins]) / np.vdot(basis, basis)), True
    psi = np.concatenate([c * u, q[:, extra].T @ u.conj() / c])
    return (psi, True) if unit_mass else (psi / psi[np.argmax(np.abs(psi))], False)


def _modal_data(frfs: FRFData, freqs, zetas, constants: np.ndarray, real: bool) -> tuple[ModalData, np.ndarray]:
    """ModalData from modal constants Q (m, n_out, n_in); also the complexity of each mode.

    The shapes are at every measured or excited DoF (:func:`_union`: the outputs, then
    the inputs not measured, their values by reciprocity, :func:`_shape`) when a driving
    point ties the two sides together; without one, at the larger side (the inputs of a
    roving-hammer test without an accelerometer at a hammer point, else the outputs).
    Generalised masses are 1 when every shape could be scaled through a driving point
    (real modes only: dataset 55 holds no mass for complex ones), else None.
    """
    outputs, inputs = frfs.outputs, frfs.inputs
    driving = _driving_points(outputs, inputs)
    if driving:
        sensors, extra = _union(outputs, inputs, driving)
    else:
        if len(inputs) > len(outputs):  # Q_r = ψ_out ψ_inᵀ, so Q_rᵀ has the inputs as rows
            outputs, constants = inputs, np.swapaxes(constants, 1, 2)
        sensors, extra = outputs, np.zeros(0, dtype=np.int64)
    shapes, complexity, scaled = [], [], True
    for q in constants:
        psi, unit_mass = _shape(q, driving, extra)
        shapes.append(psi)
        scaled &= unit_mass
        complexity.append(max(0.0, 1.0 - abs(np.sum(psi**2)) / np.sum(np.abs(psi) ** 2)))
    phi = np.column_stack(shapes) if shapes else np.zeros((len(sensors), 0), dtype=np.complex128)
    modes = ModalData(freqs, phi, sensors, damping_ratios=zetas)
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
