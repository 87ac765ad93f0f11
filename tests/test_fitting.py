"""Modal parameters from FRFs: SDOF inverse-FRF fit (thesis eqs. 3.34–3.37), pLSCF + LSFD.

Synthetic FRFs of spring–mass chains with known modes (tests/_frf_models.py); "1 % noise"
is complex Gaussian noise of 1 % of |H| on every value.
"""

import json
import re

import numpy as np
import pytest
import scipy.linalg as sl
from _frf_models import chain, frf_data, modes, receptance
from scipy.optimize import brentq

from identification import FRFData, ModalData, Sensors, read_uff, write_uff
from identification._fitting import IdentificationError, identify, lscf, lsfd, sdof_fit, stabilisation
from identification._plots import plot_stabilisation

M5, K5 = chain([1.0, 1.2, 0.9, 1.1, 1.0], [4e4, 3e4, 3e4, 2.5e4, 2e4])
ZETA5 = [0.01, 0.012, 0.015, 0.01, 0.02]
F5 = np.arange(0.0, 120.0, 0.05)
OUT5, IN5 = np.arange(5), [4]


def _mac(a, b):
    """MAC of matching columns (complex-aware)."""
    return np.abs(np.sum(a.conj() * b, axis=0)) ** 2 / (np.sum(np.abs(a) ** 2, axis=0) * np.sum(np.abs(b) ** 2, axis=0))


@pytest.fixture(scope="module")
def chain5():
    fn, phi, zeta = modes(M5, K5, ZETA5)
    h = receptance(M5, K5, ZETA5, F5, OUT5, IN5)
    return fn, phi, zeta, h


@pytest.fixture(scope="module")
def identified(chain5):
    *_, h = chain5
    return identify(frf_data(h, F5, OUT5, IN5, noise=0.01))


def test_identify_separated_modes_with_noise(chain5, identified):
    fn, phi, zeta, _ = chain5
    found, report = identified
    assert found.n_modes == 5
    np.testing.assert_allclose(found.frequencies_hz, fn, rtol=1e-3)  # measured ≤ 0.0014 %
    np.testing.assert_allclose(found.damping_ratios, zeta, rtol=0.05)  # measured ≤ 0.28 %
    assert np.all(_mac(found.shapes, phi) >= 0.99)  # measured ≥ 0.9999
    # driving point (5+Z / 5+Z): unit modal mass, φ ≈ ±the exact mass-normalised modes
    np.testing.assert_array_equal(found.generalised_masses, np.ones(5))
    scale = np.abs(np.sum(found.shapes * phi, axis=0) / np.sum(phi * phi, axis=0))
    np.testing.assert_allclose(scale[:4], 1.0, atol=0.01)  # measured ≤ 0.3 %
    np.testing.assert_allclose(scale[4], 1.0, atol=0.1)  # mode 5 is weak at the driving point: 6.5 %
    assert found.sensors.labels == ["1+Z", "2+Z", "3+Z", "4+Z", "5+Z"]
    assert not np.iscomplexobj(found.shapes)
    assert found.frequencies_hz.dtype == found.damping_ratios.dtype == found.shapes.dtype == np.float64
    assert report["fit"]["nmse_percent_worst"] < 0.05  # the synthesis fits to the noise level
    assert all(m["n_orders_stable"] >= 25 for m in report["modes"])  # of 39 orders; measured 26–28
    assert report["coherence"] == "not given" and report["masked_bands_hz"] == []
    assert report["identified"] is True and report["options"]["orders"] == list(range(2, 41))
    assert report["reciprocity"] == {"used": False, "references": "inputs", "dofs_from_inputs": []}
    json.dumps(report)  # JSON-ready for the CLI


def test_stabilisation_diagram_is_written(tmp_path, identified):
    _, report = identified
    diagram = report["stabilisation"]
    n = len(diagram["order"])
    assert n > 100 and all(len(diagram[k]) == n for k in ("frequency_hz", "damping_ratio", "stable_mac", "mode"))
    assert sorted(set(diagram["mode"])) == [0, 1, 2, 3, 4, 5]
    path = plot_stabilisation(json.loads(json.dumps(report)), tmp_path / "plots" / "stabilisation.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 20_000


def test_the_report_of_a_failed_run_is_plotted(tmp_path, chain5):
    *_, h = chain5
    with pytest.raises(IdentificationError, match="no pole is stable over 3 of the orders 10–12") as info:
        identify(frf_data(h, F5, OUT5, IN5), orders=[10, 11, 12])
    report = json.loads(json.dumps(info.value.report))
    assert report["identified"] is False and set(report["stabilisation"]["mode"]) == {0}
    assert report["stabilisation"]["order"].count(12) == 5  # the poles found are all there: the 5 modes at order 12
    path = plot_stabilisation(report, tmp_path / "failed.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plot_refuses_a_report_without_diagram(tmp_path):
    with pytest.raises(ValueError, match="no stabilisation diagram"):
        plot_stabilisation({"modes": []}, tmp_path / "s.png")


def _close_pair():
    """Two nearly equal oscillators (DoFs 0, 1) coupled so their modes are exactly 1 % apart, and two more DoFs."""

    def build(kc):
        M, K = np.diag([1.0, 1.0, 0.5, 0.8]), np.zeros((4, 4))
        for i, j, k in [(0, None, 1.2e4), (1, None, 1e4), (0, 1, kc), (2, None, 3e4), (1, 2, 2e3), (3, None, 5e4),
                        (2, 3, 5e3)]:
            idx = [i] if j is None else [i, j]
            K[np.ix_(idx, idx)] += k * (np.eye(1) if j is None else np.array([[1.0, -1.0], [-1.0, 1.0]]))
        return M, K

    kc = brentq(lambda kc: np.divide(*modes(*build(kc), 0.01)[0][[1, 0]]) - 1.01, 0.0, 2000.0)
    return build(kc)


def test_modes_one_percent_apart_are_resolved():
    M, K = _close_pair()
    zeta = [0.01, 0.01, 0.015, 0.01]  # half-power bandwidth 2 %: the pair shows as one peak
    fn, phi, zeta = modes(M, K, zeta)
    np.testing.assert_allclose(fn[1] / fn[0], 1.01, rtol=1e-12)
    f = np.arange(0.0, 80.0, 0.02)
    h = receptance(M, K, zeta, f, [0, 1, 2, 3], [0, 2])  # two inputs: polyreference
    found, _ = identify(frf_data(h, f, [0, 1, 2, 3], [0, 2], noise=0.01))
    assert found.n_modes == 4
    np.testing.assert_allclose(found.frequencies_hz, fn, rtol=1e-3)  # measured ≤ 0.002 %
    np.testing.assert_allclose(found.damping_ratios, zeta, rtol=0.05)  # measured ≤ 0.12 %
    assert np.all(_mac(found.shapes, phi) >= 0.99)  # measured ≥ 0.99999
    assert _mac(found.shapes[:, :1], found.shapes[:, 1:2])[0] < 0.01  # two distinct shapes, not one twice
    # one input (DoF 0, where modes 3 and 4 are 1e-4 of the pair) splits the pair too
    single, _ = identify(frf_data(h[:, :, :1], f, [0, 1, 2, 3], [0], noise=0.01))
    np.testing.assert_allclose(single.frequencies_hz[:2], fn[:2], rtol=1e-4)  # measured 0.003 %
    np.testing.assert_allclose(single.damping_ratios[:2], zeta[:2], rtol=0.05)  # measured ≤ 0.36 %


def test_sdof_fit_of_separated_modes(chain5):
    fn, phi, zeta, h = chain5
    found = sdof_fit(frf_data(h, F5, OUT5, IN5, noise=0.01))
    assert found.n_modes == 5
    np.testing.assert_allclose(found.frequencies_hz, fn, rtol=1e-3)  # measured ≤ 0.02 %
    np.testing.assert_allclose(found.damping_ratios, zeta, rtol=0.05)  # measured ≤ 0.6 %, mode 5 2.4 %
    mac = _mac(found.shapes, phi)
    assert np.all(mac[:4] >= 0.9998) and mac[4] >= 0.98  # mode 5: weak at the excitation, 0.989


@pytest.mark.parametrize("kind", ["receptance", "mobility", "accelerance"])
def test_sdof_fit_is_exact_for_one_degree_of_freedom(kind):
    """Eq. (3.34) holds exactly: eqs. (3.35)–(3.37) return ω_n and η = ζ to round-off."""
    m, fn, zeta = 2.0, 12.5, 0.02
    f = np.arange(0.5, 40.0, 0.05)
    w, wn = 2 * np.pi * f, 2 * np.pi * fn
    h = 1 / (m * (wn**2 - w**2 + 2j * zeta * wn * w))  # eq. (3.34) with unit force
    d = frf_data(h[:, None, None], f, [0], [0], kind=kind)
    found = sdof_fit(d)
    np.testing.assert_allclose(found.frequencies_hz, [fn], rtol=1e-10)
    np.testing.assert_allclose(found.damping_ratios, [zeta], rtol=1e-8)
    np.testing.assert_allclose(found.generalised_masses, [1.0])
    np.testing.assert_allclose(np.abs(found.shapes), [[1 / np.sqrt(m)]], rtol=1e-8)  # φ² = 1/m


def test_identify_kinds_agree(chain5):
    *_, h = chain5
    results = [
        identify(frf_data(h, F5, OUT5, IN5, kind=kind), orders=range(2, 25))[0]
        for kind in ("receptance", "mobility", "accelerance")
    ]
    for other in results[1:]:
        np.testing.assert_allclose(other.frequencies_hz, results[0].frequencies_hz, rtol=1e-6)
        np.testing.assert_allclose(other.damping_ratios, results[0].damping_ratios, rtol=1e-4)
        np.testing.assert_allclose(other.shapes, results[0].shapes, rtol=1e-4, atol=1e-6)


def test_lscf_poles_and_lsfd_residues_are_exact_without_noise(chain5):
    fn, phi, zeta, h = chain5
    d = frf_data(h, F5, OUT5, IN5)
    exact = 2 * np.pi * fn * (-zeta + 1j * np.sqrt(1 - zeta**2))
    poles = lscf(d, [30])[30]
    nearest = np.array([np.min(np.abs(poles - s) / abs(s)) for s in exact])
    assert np.all(nearest < 1e-7)  # measured ≤ 5e-9
    residues, lower, upper = lsfd(d, exact)
    expected = phi[OUT5][:, None, :] * phi[IN5][None, :, :] / (2j * exact.imag)  # φ_o φ_i = 2iω_d R
    np.testing.assert_allclose(residues, np.moveaxis(expected, 2, 0), rtol=1e-8, atol=1e-14)
    np.testing.assert_allclose(lower, 0.0, atol=1e-10)
    np.testing.assert_allclose(upper, 0.0, atol=1e-12)
    # a band holding modes 2 and 3 only: the residual terms stand for the others
    band, *_ = lsfd(d, exact[1:3], fmin=15.0, fmax=38.0)
    np.testing.assert_allclose(band, np.moveaxis(expected, 2, 0)[1:3], rtol=0.02)


def test_complex_modes_of_non_proportional_damping():
    """A dashpot at one end only: complex modes; compared with the state-space eigenproblem."""
    M, K = chain([1.0, 1.0, 1.0], [3e4, 2e4, 2e4])
    C = np.zeros((3, 3))
    C[0, 0] = 40.0
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    lam, vec = sl.eig(A)
    keep = lam.imag > 0
    order = np.argsort(lam[keep].imag)
    lam, psi = lam[keep][order], vec[:3, keep][:, order]
    f = np.arange(0.0, 80.0, 0.02)
    w = 2 * np.pi * f
    h = np.linalg.inv(K[None] - w[:, None, None] ** 2 * M[None] + 1j * w[:, None, None] * C[None])
    d = frf_data(h[:, :, [0, 2]], f, [0, 1, 2], [0, 2])
    found, report = identify(d, real=False, orders=range(2, 25))
    np.testing.assert_allclose(found.frequencies_hz, np.abs(lam) / (2 * np.pi), rtol=1e-6)
    np.testing.assert_allclose(found.damping_ratios, -lam.real / np.abs(lam), rtol=1e-4)
    assert np.all(_mac(found.shapes, psi) > 0.99999)
    assert max(m["complexity"] for m in report["modes"]) > 1e-3  # measurably complex
    assert found.generalised_masses is None and np.iscomplexobj(found.shapes)
    real = found.real()  # §2.3.1: real modes for the comparison with a real model
    reference = ModalData(np.abs(lam) / (2 * np.pi), psi, found.sensors).real()
    assert not np.iscomplexobj(real.shapes) and np.all(_mac(real.shapes, reference.shapes) > 0.99999)


def test_low_coherence_band_is_masked_with_a_warning_not_used(chain5):
    fn, _, zeta, h = chain5
    coherence = np.ones(h.shape)
    garbage = (F5 >= 25.0) & (F5 <= 30.0)  # between modes 2 and 3
    coherence[garbage] = 0.0
    h = h.copy()
    h[garbage] *= 10.0  # would wreck the fit if it were used
    d = frf_data(h, F5, OUT5, IN5, coherence=coherence)
    with pytest.warns(UserWarning, match=r"coherence below 0.5 at 25–30 Hz: those values are left out of the fit"):
        found, report = identify(d, orders=range(2, 31))
    np.testing.assert_allclose(found.frequencies_hz, fn, rtol=1e-6)
    np.testing.assert_allclose(found.damping_ratios, zeta, rtol=1e-4)
    assert report["masked_bands_hz"] == [[25.0, 30.0]] and report["coherence"] == "given"
    with pytest.warns(UserWarning, match="coherence below 0.5 at 25–30 Hz"):
        np.testing.assert_allclose(sdof_fit(d).frequencies_hz, fn, rtol=1e-3)
    coherence[:, 2, 0] = 0.0  # one FRF without any trustworthy line
    dead = frf_data(h, F5, OUT5, IN5, coherence=coherence)
    with (pytest.warns(UserWarning, match="coherence below"),
          pytest.raises(ValueError, match=r"FRF 3\+Z / 5\+Z has no line with coherence ≥ 0.5")):
        identify(dead)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda d: identify(d, fmin=50.0, fmax=20.0), "frequency band [50.0, 20.0] Hz is empty"),
        (lambda d: identify(d, fmin=10.0, fmax=10.12), "3 frequency lines in [10, 10.12] Hz; at least 4"),
        (lambda d: stabilisation(d, orders=[4, 6]), "at least 3 positive model orders"),
        (lambda d: lscf(d, [0, 4]), "model orders must be positive integers"),
        (lambda d: lsfd(d, [-1.0 - 50.0j]), "poles must be finite with positive imaginary part"),
        (lambda d: sdof_fit(d, [150.0]), "resonance guess 150.0 Hz is outside the data"),
        (lambda d: identify(FRFData(d.frequencies_hz, np.ones(d.values.shape), d.outputs, d.inputs, "receptance")),
         "no pole is stable over 10 of the orders 2–40"),
        (lambda d: identify(d, min_mac=1.0), "stability criterion min_mac = 1.0 must be in (0, 1)"),
        (lambda d: stabilisation(d, tol_f=-0.01), "stability criterion tol_f = -0.01 must be positive"),
        (lambda d: identify(d, tol_zeta=0.0), "stability criterion tol_zeta = 0.0 must be positive"),
    ],
)
def test_fitting_errors(chain5, call, message):
    *_, h = chain5
    with pytest.raises(ValueError, match=re.escape(message)):
        call(frf_data(h, F5, OUT5, IN5))


def test_identified_modes_round_trip_through_uff55(tmp_path, identified):
    found, _ = identified
    nodes = {int(g): np.array([float(g), 0.0, 0.0]) for g in found.sensors.nodes}
    write_uff(tmp_path / "modes.uff", nodes=nodes, modes=found)
    back = read_uff(tmp_path / "modes.uff")["modes"]
    np.testing.assert_allclose(back.frequencies_hz, found.frequencies_hz, rtol=1e-5)  # E13.5: 6 digits
    np.testing.assert_allclose(back.damping_ratios, found.damping_ratios, rtol=1e-5)
    np.testing.assert_allclose(back.shapes, found.shapes, rtol=1e-5, atol=1e-8)
    np.testing.assert_allclose(back.generalised_masses, 1.0)
    assert back.sensors.labels == found.sensors.labels


def test_sensors_need_not_be_z():
    """A driving point along −X: the sign is taken into account in the unit-modal-mass scaling."""
    _, phi, _ = modes(M5, K5, ZETA5)
    h = receptance(M5, K5, ZETA5, F5, OUT5, IN5)
    outputs = Sensors.from_components([1, 2, 3, 4, 5], [-1, -1, -1, -1, -1])  # output 5−X = −(input 5+X)
    d = FRFData(F5, -h, outputs, Sensors.from_components([5], [1]), "receptance")
    found, _ = identify(d, orders=range(2, 25))
    np.testing.assert_array_equal(found.generalised_masses, np.ones(5))
    scale = np.abs(np.sum(found.shapes * phi, axis=0) / np.sum(phi * phi, axis=0))
    np.testing.assert_allclose(scale, 1.0, rtol=1e-4)  # measured ≤ 8e-6


def test_time_histories_to_modes():
    """Random force, 2 % noise on the responses → H1 and coherence → pLSCF, the low-coherence lines left out."""
    from identification._frf import frf_from_time

    M, K = chain([1.0, 1.5, 0.8], [4e4, 3e4, 2e4])
    zeta = [0.03, 0.03, 0.04]
    fn, phi, zeta = modes(M, K, zeta)
    fs, n = 200.0, 2**17
    rng = np.random.default_rng(1)
    x = rng.standard_normal(n)
    lines = np.fft.rfftfreq(n, 1 / fs)
    y = np.fft.irfft(receptance(M, K, zeta, lines, [0, 1, 2], [2])[:, :, 0] * np.fft.rfft(x)[:, None], n=n, axis=0)
    y += 0.02 * np.std(y, axis=0) * rng.standard_normal(y.shape)
    frfs = frf_from_time(x, y, fs, inputs=Sensors.from_components([3], [3]),
                         outputs=Sensors.from_components([1, 2, 3], [3, 3, 3]), kind="receptance", nperseg=4096,
                         band=(1.0, 60.0))
    with pytest.warns(UserWarning, match="coherence below 0.5 at"):  # antiresonances and the noisy tail
        found, report = identify(frfs)
    assert report["masked_bands_hz"] and report["coherence"] == "given"
    np.testing.assert_allclose(found.frequencies_hz, fn, rtol=1e-3)  # measured ≤ 0.005 %
    np.testing.assert_allclose(found.damping_ratios, zeta, rtol=0.05)  # measured ≤ 0.6 % (Hann leakage)
    assert np.all(_mac(found.shapes, phi) >= 0.99)
