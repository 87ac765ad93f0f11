"""pLSCF: poles per model order, the stabilisation diagram and the automatic pole selection.

The polyreference least-squares complex frequency-domain estimator ("PolyMAX"; Peeters,
Van der Auweraer, Guillaume & Leuridan, Shock Vib. 11, 2004) fits all FRFs at once with
a right matrix-fraction model per output and gives the poles s_r = −ζ_r ω_r +
iω_r√(1−ζ_r²) of every model order (:func:`lscf`); a pole is stable when frequency,
damping and shape (MAC, complex-aware, thesis eq. 1.54) agree with the previous order
(:func:`stabilisation`), and clusters of stable poles that recur over many orders are
the modes (:func:`_select`). Closely spaced modes are resolved; their shapes come from
LSFD (:mod:`identification._lsfd`). The references of the matrix-fraction model are the
smaller side of the FRF matrix: the inputs, or, with more inputs than outputs (a roving
hammer test: one accelerometer, many hammer points), the outputs, the FRFs read by
Maxwell reciprocity H_ij = H_ji as n_in outputs of n_out references. NumPy/SciPy float64
on the host.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from jaxtyping import Complex

from ._correlation import mac as mac_matrix
from ._data import FRFData
from ._fit_data import _data


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
    left out at a line where one of its values is masked by ``min_coherence``. With more
    inputs than outputs the FRF matrix is transposed first (reciprocity, H_ij = H_ji):
    the outputs are the references and the inputs the rows.

    **Returns:** {order: poles s (rad/s), Im s > 0, Re s < 0, ζ ≤ ``max_damping``,
    undamped frequency in the band}, sorted by frequency.
    """
    f, h, usable, _ = _data(frfs, fmin, fmax, min_coherence)
    orders = sorted({int(p) for p in orders})
    if not orders or orders[0] < 1:
        raise ValueError(f"model orders must be positive integers, got {orders}")
    return {p: poles for p, (poles, _, _) in zip(orders, _lscf_poles(f, h, usable, orders, max_damping))}


def _reference_side(h: np.ndarray, usable: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """h, usable (nf, rows, references) with the smaller side of the FRF matrix as references.

    With more inputs than outputs the polyreference model would have more references
    than rows (one accelerometer, N hammer points: an N × N denominator fitted to one
    row, no shape to test by MAC); by reciprocity H_ij = H_ji the matrix is transposed.
    """
    if h.shape[2] > h.shape[1]:
        return np.swapaxes(h, 1, 2), np.swapaxes(usable, 1, 2)
    return h, usable


def _lscf_poles(f, h, usable, orders, max_damping):
    """[(poles, participation (n_ref, n), numerator shapes (n_rows, n))] per order, filtered to physical poles.

    Rows and references as :func:`_reference_side` orients them.
    """
    h, usable = _reference_side(h, usable)
    n_out, n_in = h.shape[1:]
    w = 2 * np.pi * f
    dt = 1.0 / (2 * f[-1])
    row_ok = np.all(usable, axis=2)  # (nf, n_out): an output row counts only where all its inputs are usable
    active = np.flatnonzero(np.any(row_ok, axis=0))
    if not len(active):
        raise ValueError("no frequency line where all references of a row are usable: pLSCF has no data")
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
            mac = np.asarray(mac_matrix(shapes, shapes0))
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
        np.concatenate(shapes_all, axis=1) if shapes_all else np.zeros((max(h.shape[1:]), 0), dtype=np.complex128)
    )
    return table


def _min_orders(n_orders: int, min_fraction: float) -> int:
    """Orders a cluster of stable poles must span to be a mode: max(3, ``min_fraction`` × n_orders)."""
    return max(3, math.ceil(min_fraction * n_orders))


def _select(table: dict, n_orders: int, tol_f: float, min_mac: float, min_fraction: float) -> list[np.ndarray]:
    """Clusters of stable poles (:func:`_clusters`) spanning at least :func:`_min_orders` orders: the modes."""
    needed = _min_orders(n_orders, min_fraction)
    return [idx for idx in _clusters(table, tol_f, min_mac) if len(idx) >= needed]


def _clusters(table: dict, tol_f: float, min_mac: float) -> list[np.ndarray]:
    """Clusters of poles stable in frequency, damping and MAC, by frequency.

    Distance between two stable poles: max(|Δf|/(f̄ tol_f), (1 − MAC)/(1 − min_mac));
    average-linkage clusters closer than 1. Returns, per cluster, the indices of its
    poles (one per order, the one nearest the cluster median).
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
        dist = np.maximum(df / tol_f, (1 - np.asarray(mac_matrix(shapes, shapes))) / (1 - min_mac))
        dist = 0.5 * (dist + dist.T)
        np.fill_diagonal(dist, 0.0)
        labels = fcluster(linkage(squareform(dist, checks=False), method="average"), t=1.0, criterion="distance")
    modes = []
    for label in np.unique(labels):
        members = stable[labels == label]
        fn = np.abs(table["pole"][members])
        centre = np.median(fn)
        chosen = []
        for p in np.unique(table["order"][members]):
            at_p = members[table["order"][members] == p]
            chosen.append(at_p[np.argmin(np.abs(np.abs(table["pole"][at_p]) - centre))])
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
    when MAC ≥ ``min_mac``. Poles of the lowest order are new. Default ``orders``:
    2 … 40/n_ref, n_ref the references (the smaller side of the FRF matrix, :func:`lscf`).

    **Returns:** a JSON-ready dict of lists, one entry per pole: ``order``,
    ``frequency_hz``, ``damping_ratio``, ``stable_frequency``, ``stable_damping``,
    ``stable_mac``; and ``orders``, ``criteria``.
    """
    orders = _orders(orders, min(len(frfs.outputs), len(frfs.inputs)))
    _check_criteria(tol_f, tol_zeta, min_mac)
    f, h, usable, _ = _data(frfs, fmin, fmax, min_coherence)
    table = _stabilisation(f, h, usable, orders, tol_f, tol_zeta, min_mac, max_damping)
    return _diagram_json(table, orders, tol_f, tol_zeta, min_mac)


def _orders(orders, n_ref: int) -> list[int]:
    """The model orders: ``orders`` sorted (at least 3), default 2 … 40/n_ref (n_ref: references)."""
    if orders is None:
        return list(range(2, max(4, 40 // n_ref) + 1))
    orders = sorted({int(p) for p in orders})
    if len(orders) < 3 or orders[0] < 1:
        raise ValueError(f"a stabilisation diagram needs at least 3 positive model orders, got {orders}")
    return orders


def _check_criteria(tol_f: float, tol_zeta: float, min_mac: float) -> None:
    for name, value, ok, what in (
        ("tol_f", tol_f, tol_f > 0, "positive"),
        ("tol_zeta", tol_zeta, tol_zeta > 0, "positive"),
        ("min_mac", min_mac, 0 < min_mac < 1, "in (0, 1)"),
    ):
        if not ok:
            raise ValueError(f"stability criterion {name} = {value} must be {what}")


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
