"""Modes from FRFs in one call: pLSCF stabilisation diagram, pole selection, LSFD shapes.

:func:`identify` runs the polyreference LSCF estimator over many model orders
(:mod:`identification._lscf`; Peeters, Van der Auweraer, Guillaume & Leuridan, Shock
Vib. 11, 2004), keeps the poles that stay stable, fits the residues of all FRFs for them
with lower and upper residuals (:mod:`identification._lsfd`, Ewins §2.8) and returns real
normal modes (thesis §2.3.1) at every measured or excited DoF (Maxwell reciprocity,
H_ij = H_ji: a roving-hammer test gives the shapes at its hammer points) with a
JSON-ready report; when no mode is found, :class:`IdentificationError` carries the
diagram for the engineer to look at. The SDOF inverse-FRF fit of
thesis §3.3.2 is :func:`sdof_fit` in :mod:`identification._sdof`. NumPy/SciPy float64
on the host.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ._data import FRFData, ModalData
from ._fit_data import _POWER, _data, _indicator
from ._lscf import (
    _check_criteria,
    _clusters,
    _diagram_json,
    _min_orders,
    _orders,
    _stabilisation,
    lscf,
    stabilisation,
)
from ._lsfd import _lsfd, _modal_data, lsfd
from ._sdof import _inverse_fit, sdof_fit

# identify, and the names tests, benchmarks and docs/thesis.md import from here (before the
# split into _sdof, _lscf and _lsfd they were defined here)
__all__ = ["IdentificationError", "identify", "lscf", "lsfd", "sdof_fit", "stabilisation", "_inverse_fit"]


class IdentificationError(ValueError):
    """:func:`identify` found no modes. ``report`` is what it did find, JSON-ready: the
    options, the band, the stabilisation diagram and mode indicator (for
    :func:`identification._plots.plot_stabilisation`), ``identified: False`` and
    ``error`` (the reason, without the hint on which arguments to change)."""

    def __init__(self, message: str, report: dict):
        super().__init__(message)
        self.report = report


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

    1. pLSCF poles at every order in ``orders`` (default 2 … 40/n_ref), :func:`lscf`;
       the references are the inputs, or the outputs when there are more inputs than
       outputs (reciprocity, below), n_ref of them;
    2. stabilisation flags against the previous order, :func:`stabilisation`;
    3. poles stable in frequency, damping and MAC are clustered (|Δf|/f within
       ``tol_f``, MAC ≥ ``min_mac``); a cluster spanning at least
       max(3, ``min_fraction`` × n_orders) orders is a mode, with the median frequency
       and damping of its poles (the lowest order is never stable, so 3 orders find
       nothing);
    4. residues of all FRFs for those poles with lower and upper residuals (LSFD); the
       shape is the dominant singular vector of each mode's residue matrix, scaled to
       unit modal mass through driving points (output DoF = input DoF) when there are
       any (generalised masses 1), else to a largest component of 1;
    5. ``real=True``: real normal modes by :meth:`ModalData.real` (thesis §2.3.1);
       otherwise the complex shapes.

    Reciprocity (Maxwell, H_ij = H_ji): the residue matrix is φ_out φ_inᵀ, so its
    columns give the shape at the inputs as its rows do at the outputs. The shapes are
    returned at every measured or excited DoF, the outputs then the inputs not
    measured (a driving point once), when a driving point ties the two sides'
    scales together; without one, at the larger side. A roving-hammer test (one
    accelerometer, N hammer points) thus gives the shapes at every hammer point.

    Values with coherence below ``min_coherence`` are left out with a ``UserWarning``
    naming the bands (:func:`low_coherence_bands`); an FRF without any usable line is
    refused.

    **Returns:** ``(modes, report)``: :class:`ModalData` at the DoFs above (write it
    with :func:`write_uff`) and a JSON-ready dict: ``identified`` (True), ``options``
    (the arguments as used), ``band_hz``, ``n_lines``, ``coherence`` ("given"/"not
    given"), ``masked_bands_hz``, ``orders``, ``reciprocity`` (``references``: "inputs"
    or "outputs"; ``dofs_from_inputs``: the DoFs whose shapes come from the inputs'
    side; ``used``: either applies), ``sensors`` (labels), ``shapes`` (per mode, the
    values at ``sensors`` in full precision; complex: ``real``, ``imag``), per mode (``modes``) the
    frequency, damping, the number of orders it is stable over, the spread (std) of f
    and ζ across them and its complexity 1 − |Σψ²|/Σ|ψ|² (0: real, 1: circular), the
    fit (``fit``: normalised mean-square error % of the synthesis, mean and worst FRF),
    the diagram (``stabilisation``, see :func:`stabilisation`, with ``mode``) and the
    mode indicator (``indicator``) for :func:`identification._plots.plot_stabilisation`.

    Bad arguments and data raise ``ValueError``; when the diagram is made but no mode
    is found (no pole stable over enough orders, or a failing shape fit) it is an
    :class:`IdentificationError` whose ``report`` holds the diagram.
    """
    n_ref = min(len(frfs.outputs), len(frfs.inputs))
    orders = _orders(orders, n_ref)
    _check_criteria(tol_f, tol_zeta, min_mac)
    f, h, usable, bands = _data(frfs, fmin, fmax, min_coherence)
    power = _POWER[frfs.kind]
    table = _stabilisation(f, h, usable, orders, tol_f, tol_zeta, min_mac, max_damping)
    needed = _min_orders(len(orders), min_fraction)
    clusters = _clusters(table, tol_f, min_mac)
    selected = [idx for idx in clusters if len(idx) >= needed]
    options = {
        "fmin": fmin,
        "fmax": fmax,
        "orders": list(orders),
        "min_coherence": min_coherence,
        "tol_f": tol_f,
        "tol_zeta": tol_zeta,
        "min_mac": min_mac,
        "max_damping": max_damping,
        "min_fraction": min_fraction,
        "real": real,
    }
    report = _report(frfs, f, h, usable, bands, table, orders, needed, selected, options)
    if not selected:
        raise _no_modes(report, table, clusters, orders, needed, f)
    try:
        modes, complexity, fn, zn, fit = _shapes(frfs, f, h, usable, power, table, selected, real)
    except ValueError as err:
        report["error"] = str(err)
        raise IdentificationError(str(err), report) from err
    _add_modes(report, frfs, modes, selected, complexity, fn, zn, fit, real)
    return modes, report


def _report(frfs: FRFData, f, h, usable, bands, table, orders, needed, selected, options: dict) -> dict:
    """The report of :func:`identify` before the shape fit: options, band, diagram and mode indicator."""
    indicator = _indicator(h, usable)
    tol_f, tol_zeta, min_mac = options["tol_f"], options["tol_zeta"], options["min_mac"]
    return {
        "method": "pLSCF (Peeters et al. 2004) + LSFD with lower/upper residuals",
        "identified": False,
        "options": options,
        "kind": frfs.kind,
        "band_hz": [float(f[0]), float(f[-1])],
        "n_lines": len(f),
        "coherence": "not given" if frfs.coherence is None else "given",
        "min_coherence": options["min_coherence"],
        "masked_bands_hz": [list(b) for b in bands],
        "orders": list(orders),
        "min_orders": needed,
        "reciprocity": {"used": len(frfs.inputs) > len(frfs.outputs),
                        "references": "outputs" if len(frfs.inputs) > len(frfs.outputs) else "inputs",
                        "dofs_from_inputs": []},
        "stabilisation": _diagram_json(table, orders, tol_f, tol_zeta, min_mac, selected),
        "indicator": {"frequency_hz": f.tolist(), "value": (indicator / max(np.max(indicator), 1e-300)).tolist()},
    }


def _no_modes(report: dict, table, clusters, orders, needed, f) -> IdentificationError:
    """The :class:`IdentificationError` when no pole is stable over ``needed`` orders; sets ``report["error"]``."""
    n_stable = int(np.count_nonzero(table["stable_frequency"] & table["stable_damping"] & table["stable_mac"]))
    reason = (
        f"no pole is stable over {needed} of the orders {orders[0]}–{orders[-1]} in "
        f"[{f[0]:.6g}, {f[-1]:.6g}] Hz ({n_stable} of {len(table['pole'])} poles stable in frequency, "
        "damping and MAC"
    )
    if clusters:
        best = max(clusters, key=len)
        reason += (f"; the most persistent, at {np.median(np.abs(table['pole'][best])) / (2 * np.pi):.6g} Hz, "
                   f"over {len(best)} orders")
    reason += ")"
    if len(orders) <= needed:
        reason += f"; the lowest order is never stable, so {needed} stable orders need at least {needed + 1}"
    report["error"] = reason
    return IdentificationError(
        f"{reason}; try more or higher orders, looser tol_f, tol_zeta or min_mac, another band "
        "(fmin, fmax) or a lower min_coherence",
        report,
    )


def _add_modes(report: dict, frfs: FRFData, modes: ModalData, selected, complexity, fn, zn, fit, real: bool) -> None:
    """Complete ``report`` with the identified modes: reciprocity, sensors, shapes, per-mode table and fit."""
    measured = set(frfs.outputs.labels)
    from_inputs = [label for label in modes.sensors.labels if label not in measured]
    report["identified"] = True
    report["reciprocity"]["dofs_from_inputs"] = from_inputs
    report["reciprocity"]["used"] = report["reciprocity"]["used"] or bool(from_inputs)
    report["sensors"] = modes.sensors.labels
    shapes = np.asarray(modes.shapes)
    report["shapes"] = (shapes.T.tolist() if not np.iscomplexobj(shapes)
                        else [{"real": c.real.tolist(), "imag": c.imag.tolist()} for c in shapes.T])
    report["real_modes"] = real
    report["mass_normalised"] = modes.generalised_masses is not None
    report["modes"] = [
        {
            "mode": r + 1,
            "frequency_hz": float(modes.frequencies_hz[r]),
            "damping_ratio": float(modes.damping_ratios[r]),
            "n_orders_stable": len(selected[r]),
            "frequency_std_hz": float(np.std(fn[r])),
            "damping_std": float(np.std(zn[r])),
            "complexity": float(complexity[r]),
        }
        for r in range(modes.n_modes)
    ]
    report["fit"] = fit


def _shapes(frfs: FRFData, f, h, usable, power, table, selected, real):
    """Modes for the selected clusters of poles: median f and ζ, LSFD residues, shapes; and the fit."""
    fn = [np.abs(table["pole"][idx]) / (2 * np.pi) for idx in selected]
    zn = [-table["pole"][idx].real / np.abs(table["pole"][idx]) for idx in selected]
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
    fit = {
        "nmse_percent_mean": float(np.mean(nmse)),
        "nmse_percent_worst": float(nmse[o, i]),
        "worst_frf": f"{frfs.outputs.labels[o]} / {frfs.inputs.labels[i]}",
    }
    return modes, complexity, fn, zn, fit
