"""Test data relative to a reference state: what changed, carried onto the model.

A damage (a delamination, a loose seam) changes the modes by less than the model's own
error (the CFRP panel's delamination shifts frequencies by ≤ 0.6 %, the mesh alone by
0.2–4 %), so the thesis locates it from the *differences* between the healthy and the
damaged structure (§5.3.2.2: damping deviations Δη between two measured states, eq. 3.43).
The same idea for modal data: the change measured between a reference test (healthy)
and a test (damaged) is applied to the model's own modes,

    f = f_a · f_test / f_ref,      φ = C φ_a + s (φ_test − φ_ref),

(s: the modal scale factor of φ_ref onto C φ_a), so that the model without the
effect matches the data up to the change alone: its own error cancels to first order and
a diagnosis explains the change. The noise of the result is that of a difference (√2 ×
the noise of one test, when the two are measured alike).
"""

from __future__ import annotations

import warnings

import numpy as np

import jaxfem
from identification import MAX_FREQ_DEV, ModalData, observation_matrix, pair_modes
from jaxfem import Model

from .. import n_model_modes

REFERENCE_MAC = 0.8  # two tests of one structure at the same sensors pair more strictly than test and model


def relative_to(model: Model, test: ModalData, reference: ModalData, *, n_modes: int | None = None,
                min_mac: float = REFERENCE_MAC, max_freq_dev: float = MAX_FREQ_DEV, solver: str = "auto") -> tuple[ModalData, list[dict]]:
    """The change from ``reference`` to ``test`` on the model's modes (module docstring).

    **Arguments:** the model; the test (e.g. damaged) and the reference (healthy) modes,
    measured at the same sensors; ``n_modes`` model modes to pair with (default
    :func:`updating.n_model_modes`); pairing thresholds (reference ↔ model, and test ↔ reference with
    ``min_mac`` and a tenth of ``max_freq_dev``); the eigensolver (:func:`jaxfem.modes`).

    **Returns:** the data (one mode per reference mode paired both ways, in test order)
    and one row per reference mode: its frequency, its partners' (Hz) and the change in %
    (None where unpaired). A reference mode without a partner is named in a warning.
    """
    if list(test.sensors.labels) != list(reference.sensors.labels):
        raise ValueError("the test and the reference must be measured at the same sensors, in the same order "
                         f"({len(test.sensors.labels)} and {len(reference.sensors.labels)} sensors given)")
    lam, phi = jaxfem.modes(model, n_model_modes(model, len(reference.frequencies_hz), n_modes), solver=solver)
    f_a = np.asarray(jaxfem.frequencies_hz(lam))
    C, _ = observation_matrix(model, reference.sensors)
    shapes_a = np.asarray(C @ phi)
    f_r, f_t = np.asarray(reference.frequencies_hz), np.asarray(test.frequencies_hz)
    phi_r, phi_t = np.real(reference.real().shapes), np.real(test.real().shapes)
    to_model = pair_modes(f_a, shapes_a, f_r, phi_r, min_mac=min_mac, max_freq_dev=max_freq_dev)
    to_test = pair_modes(f_r, phi_r, f_t, phi_t, min_mac=min_mac, max_freq_dev=max_freq_dev / 10)
    test_of = dict(zip(to_test.model.tolist(), to_test.test.tolist()))
    freqs, shapes, rows, order = [], [], [], []
    for r, m in zip(to_model.test.tolist(), to_model.model.tolist()):
        t = test_of.get(r)
        if t is None:
            continue
        a, ref, new = shapes_a[:, m], phi_r[:, r], phi_t[:, t]
        s = float(ref @ a) / float(ref @ ref)  # modal scale factor
        new = new * np.sign(float(new @ ref))
        freqs.append(f_a[m] * f_t[t] / f_r[r])
        shapes.append(a + s * (new - ref))
        order.append(t)
    paired = set(to_model.test.tolist()) & set(test_of)
    for r in range(len(f_r)):
        t = test_of.get(r)
        rows.append({"reference_mode": r + 1, "f_reference_hz": float(f_r[r]),
                     "f_test_hz": float(f_t[t]) if t is not None else None,
                     "change_pct": float(100 * (f_t[t] / f_r[r] - 1)) if t is not None else None,
                     "used": r in paired})
    lost = [r + 1 for r in range(len(f_r)) if r not in paired]
    if lost:
        warnings.warn(f"reference modes {lost} have no partner in the model or in the test "
                      f"(MAC ≥ {min_mac}): left out of the change", stacklevel=2)
    if not freqs:
        raise ValueError("no reference mode is paired with both the model and the test: nothing to compare")
    by_test = np.argsort(order)
    data = ModalData(np.asarray(freqs)[by_test], np.stack(shapes, axis=1)[:, by_test], reference.sensors,
                     mode_ids=np.asarray(order)[by_test] + 1)
    return data, rows
