"""Roving-hammer FRFs (one accelerometer, many hammer points) through ``identify``.

By Maxwell reciprocity H_ij = H_ji the residue matrix φ_out φ_inᵀ gives the shapes at
the inputs as well as at the outputs; pLSCF takes the smaller side as references.
Synthetic FRFs of spring–mass chains with known modes (tests/_frf_models.py).
"""

import numpy as np
import pytest
from _frf_models import chain, frf_data, modes, receptance

from identification._fitting import IdentificationError, identify, stabilisation

M5, K5 = chain([1.0, 1.2, 0.9, 1.1, 1.0], [4e4, 3e4, 3e4, 2.5e4, 2e4])
ZETA5 = [0.01, 0.012, 0.015, 0.01, 0.02]
F5 = np.arange(0.0, 120.0, 0.05)


def _truth_at(labels, phi):
    """Rows of the exact shapes at sensors labelled ``<dof + 1>+Z``."""
    return phi[[int(label.removesuffix("+Z")) - 1 for label in labels]]


def _scaled_error(shapes, truth):
    """Per mode: the least-squares scale s of truth onto shapes and max|ψ − sφ| / max|φ|."""
    s = np.sum(shapes * truth, axis=0) / np.sum(truth * truth, axis=0)
    return s, np.max(np.abs(shapes - s * truth), axis=0) / np.max(np.abs(truth), axis=0)


def test_roving_hammer_gives_shapes_at_every_hammer_point():
    """1 accelerometer (3+Z) × 5 hammer points, noise-free: shapes at all 5 DoFs, unit modal mass."""
    fn, phi, zeta = modes(M5, K5, ZETA5)
    out, inp = [2], [0, 1, 2, 3, 4]
    found, report = identify(frf_data(receptance(M5, K5, ZETA5, F5, out, inp), F5, out, inp))
    assert found.sensors.labels == ["3+Z", "1+Z", "2+Z", "4+Z", "5+Z"]  # the driving point 3+Z once
    np.testing.assert_allclose(found.frequencies_hz, fn, rtol=1e-7)  # measured ≤ 5e-9
    np.testing.assert_allclose(found.damping_ratios, zeta, rtol=1e-5)  # measured ≤ 2e-7
    scale, err = _scaled_error(found.shapes, _truth_at(found.sensors.labels, phi))
    assert np.all(err < 1e-6)  # measured ≤ 3e-8
    np.testing.assert_allclose(np.abs(scale), 1.0, atol=1e-6)  # unit modal mass through 3+Z; measured ≤ 6e-8
    np.testing.assert_array_equal(found.generalised_masses, np.ones(5))
    assert report["reciprocity"] == {"used": True, "references": "outputs",
                                     "dofs_from_inputs": ["1+Z", "2+Z", "4+Z", "5+Z"]}
    assert report["orders"] == list(range(2, 41))  # one reference: 2 … 40, not 2 … 40/5
    assert report["sensors"] == found.sensors.labels and report["identified"] is True


def test_roving_hammer_equals_the_transposed_measurement():
    """Reading H (1 × 5) by reciprocity gives what the transposed FRFs (5 × 1) give."""
    out, inp = [2], [0, 1, 2, 3, 4]
    h = receptance(M5, K5, ZETA5, F5, out, inp)
    d = frf_data(h, F5, out, inp, noise=0.01)
    t = frf_data(np.swapaxes(d.values, 1, 2), F5, inp, out)  # same noisy values, transposed
    roving, _ = identify(d)
    fixed, _ = identify(t)
    np.testing.assert_allclose(roving.frequencies_hz, fixed.frequencies_hz, rtol=1e-12)
    np.testing.assert_allclose(roving.damping_ratios, fixed.damping_ratios, rtol=1e-10)
    rows = [fixed.sensors.labels.index(label) for label in roving.sensors.labels]
    np.testing.assert_allclose(roving.shapes, fixed.shapes[rows], rtol=1e-8, atol=1e-10)


def test_roving_hammer_with_noise_over_eight_points():
    """1 × 8 with 1 % noise: failed before ("no pole is stable over 3 of the orders 2–5")."""
    n = 8
    M, K = chain(np.linspace(1.0, 1.5, n), np.linspace(4e4, 2e4, n))
    fn, phi, zeta = modes(M, K, 0.01)
    f = np.arange(0.0, 60.0, 0.02)
    out, inp = [0], list(range(n))
    found, report = identify(frf_data(receptance(M, K, zeta, f, out, inp), f, out, inp, noise=0.01))
    assert found.n_modes == n and len(found.sensors) == n
    np.testing.assert_allclose(found.frequencies_hz, fn, rtol=2e-4)  # measured ≤ 3e-5
    np.testing.assert_allclose(found.damping_ratios, zeta, rtol=0.03)  # measured ≤ 0.23 %
    truth = _truth_at(found.sensors.labels, phi)
    mac = np.sum(found.shapes * truth, axis=0) ** 2 / (np.sum(found.shapes**2, axis=0) * np.sum(truth**2, axis=0))
    assert np.all(mac >= 0.9999)  # measured ≥ 0.999998


def test_roving_hammer_without_driving_point_gives_the_hammer_points():
    """Accelerometer 5+Z never hammered: the two sides cannot be scaled together, so the
    shapes are at the larger side (the 4 hammer points), not mass-normalised."""
    _, phi, _ = modes(M5, K5, ZETA5)
    out, inp = [4], [0, 1, 2, 3]
    found, report = identify(frf_data(receptance(M5, K5, ZETA5, F5, out, inp), F5, out, inp))
    assert found.sensors.labels == ["1+Z", "2+Z", "3+Z", "4+Z"] and found.generalised_masses is None
    _, err = _scaled_error(found.shapes, _truth_at(found.sensors.labels, phi))
    assert np.all(err < 1e-6)  # measured ≤ 3e-7
    assert report["reciprocity"]["references"] == "outputs"


def test_inputs_that_are_not_outputs_get_shapes_by_reciprocity():
    """3 outputs, 2 inputs (one a driving point): the shape at the other input comes from the residues."""
    _, phi, _ = modes(M5, K5, ZETA5)
    out, inp = [0, 1, 2], [2, 4]
    found, report = identify(frf_data(receptance(M5, K5, ZETA5, F5, out, inp), F5, out, inp))
    assert found.sensors.labels == ["1+Z", "2+Z", "3+Z", "5+Z"]
    scale, err = _scaled_error(found.shapes, _truth_at(found.sensors.labels, phi))
    assert np.all(err < 1e-6)  # measured ≤ 2.4e-7
    np.testing.assert_allclose(np.abs(scale), 1.0, atol=1e-6)  # measured ≤ 9e-8
    assert report["reciprocity"] == {"used": True, "references": "inputs", "dofs_from_inputs": ["5+Z"]}


def test_stabilisation_of_a_roving_hammer_uses_the_hammer_points_as_rows():
    """With one output as reference the pLSCF shapes span the hammer points, so the MAC test means something."""
    out, inp = [2], [0, 1, 2, 3, 4]
    d = frf_data(receptance(M5, K5, ZETA5, F5, out, inp), F5, out, inp, noise=0.01)
    diagram = stabilisation(d)
    assert diagram["orders"] == list(range(2, 41))
    assert 0.3 < np.mean(diagram["stable_mac"]) < 1.0  # measured 0.52; not all true, as a one-component shape would be


def test_failure_carries_the_diagram():
    out, inp = [2], [0, 1, 2, 3, 4]
    d = frf_data(receptance(M5, K5, ZETA5, F5, out, inp), F5, out, inp)
    with pytest.raises(IdentificationError, match="the lowest order is never stable") as info:
        identify(d, orders=[2, 3, 4])
    report = info.value.report
    assert report["identified"] is False and report["error"].startswith("no pole is stable over 3 of the orders 2–4")
    assert report["options"]["orders"] == [2, 3, 4] and len(report["stabilisation"]["order"]) >= 2
    assert "modes" not in report
