"""Modes from FRFs in one call: pLSCF stabilisation diagram, pole selection, LSFD shapes.

:func:`identify` runs the polyreference LSCF estimator over many model orders
(:mod:`identification._lscf`; Peeters, Van der Auweraer, Guillaume & Leuridan, Shock
Vib. 11, 2004), keeps the poles that stay stable, fits the residues of all FRFs for them
with lower and upper residuals (:mod:`identification._lsfd`, Ewins §2.8) and returns real
normal modes (thesis §2.3.1) with a JSON-ready report. The SDOF inverse-FRF fit of
thesis §3.3.2 is :func:`sdof_fit` in :mod:`identification._sdof`. NumPy/SciPy float64
on the host.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ._data import FRFData, ModalData
from ._fit_data import _POWER, _data, _indicator
from ._lscf import _diagram_json, _mac, _orders, _select, _stabilisation, lscf, stabilisation
from ._lsfd import _lsfd, _modal_data, lsfd
from ._sdof import _inverse_fit, sdof_fit

# identify, and the names tests, benchmarks and docs/thesis.md import from here (before the
# split into _sdof, _lscf and _lsfd they were defined here)
__all__ = ["identify", "lscf", "lsfd", "sdof_fit", "stabilisation", "_inverse_fit", "_mac"]


def _poles(frequencies_hz, damping_ratios) -> np.ndarray:
    w = 2 * np.pi * np.asarray(frequencies_hz, dtype=np.float64)
    z = np.asarray(damping_ratios, dtype=np.float64)
    return w * (-z + 1j * np.sqrt(1 - z**2))


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
