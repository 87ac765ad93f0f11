"""FRF estimation: H1/H2 bias under input and output noise, coherence, windows, stepped sine, flags."""

import re

import numpy as np
import pytest
from _frf_models import chain, frf_data, receptance

from identification import FRFData, Sensors, read_uff, write_uff
from identification._frf import (
    coherence_mask,
    frf_from_time,
    frf_stepped_sine,
    low_coherence_bands,
    merge_inputs,
    sine_coefficients,
)

FS = 200.0
N = 2**17  # samples: 127 Hann blocks of 2048 with 50 % overlap, resolution 0.098 Hz
NPERSEG = 2048
M3, K3 = chain([1.0, 1.5, 0.8], [4e4, 3e4, 2e4])
ZETA3 = [0.03, 0.03, 0.04]  # half-power bandwidths ≥ 0.8 Hz: leakage of the Hann blocks stays small
OUT = Sensors.from_components([1, 2, 3], [3, 3, 3])
IN = Sensors.from_components([3], [3])
IN2 = Sensors.from_components([1, 3], [3, 3])


def _respond(force, in_dofs):
    """Steady-state (periodic) receptance response of the 3-DoF chain to a force record (N, n_in)."""
    f = np.fft.rfftfreq(len(force), 1 / FS)
    h = receptance(M3, K3, ZETA3, f, [0, 1, 2], in_dofs)
    return np.fft.irfft(np.einsum("koi,ki->ko", h, np.fft.rfft(force, axis=0)), n=len(force), axis=0)


def _exact(frfs, in_dofs=(2,)):
    return receptance(M3, K3, ZETA3, frfs.frequencies_hz, [0, 1, 2], list(in_dofs))


@pytest.fixture(scope="module")
def random_test():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((N, 1))
    return rng, x, _respond(x, [2])


def test_output_noise_h1_unbiased_h2_biased_high(random_test):
    rng, x, y = random_test
    sigma_n = 2e-6  # m; the response is ~1e-6..1e-4 m per √Hz-line: low SNR off resonance
    y_noisy = y + sigma_n * rng.standard_normal(y.shape)
    kw = {"inputs": IN, "outputs": OUT, "kind": "receptance", "nperseg": NPERSEG, "band": (2.0, 60.0)}
    h1 = frf_from_time(x, y_noisy, FS, estimator="H1", **kw)
    h2 = frf_from_time(x, y_noisy, FS, estimator="H2", **kw)
    h = _exact(h1)
    # bias of H2 and the coherence for white force (σ_x = 1) and white noise: Bendat & Piersol §9.2
    snr = np.abs(h) ** 2 / sigma_n**2
    bias = 1 + 1 / snr
    mid = (bias > 1.2) & (bias < 5)  # lines where the noise matters but does not swamp
    assert np.count_nonzero(mid) > 100
    r1, r2 = h1.values / h, h2.values / h
    assert abs(np.median(r1[mid].real) - 1) < 0.03  # H1: unbiased
    assert abs(np.median(np.abs(r2[mid]) / bias[mid]) - 1) < 0.05  # H2 ≈ H (1 + N/(|H|²X))
    assert np.median(np.abs(r2[mid])) > 1.3  # ... and that is far from 1
    assert abs(np.median(h1.coherence[mid] - 1 / bias[mid])) < 0.02  # γ² = 1/(1 + N/(|H|²X)); measured 0.010
    np.testing.assert_array_equal(h1.coherence, h2.coherence)  # γ² does not depend on the estimator
    assert h1.values.dtype == np.complex128 and h1.coherence.dtype == h1.frequencies_hz.dtype == np.float64


def test_input_noise_h2_unbiased_h1_biased_low(random_test):
    rng, x, y = random_test
    r = 0.3**2  # force-measurement noise power / force power
    x_noisy = x + 0.3 * rng.standard_normal(x.shape)
    kw = {"inputs": IN, "outputs": OUT, "kind": "receptance", "nperseg": NPERSEG, "band": (2.0, 60.0)}
    h1 = frf_from_time(x_noisy, y, FS, estimator="H1", **kw)
    h2 = frf_from_time(x_noisy, y, FS, estimator="H2", **kw)
    h = _exact(h1)
    ratio1, ratio2 = np.abs(h1.values / h), np.abs(h2.values / h)
    np.testing.assert_allclose(np.median(ratio1), 1 / (1 + r), rtol=0.01)  # H1 = H/(1 + r): 0.917
    np.testing.assert_allclose(np.median(ratio2), 1.0, atol=0.01)
    np.testing.assert_allclose(np.median(h1.coherence), 1 / (1 + r), atol=0.01)


def test_rectangular_window_is_exact_for_periodic_excitation():
    """Each block a periodic multisine of its own (random phases): no leakage, H1 exact."""
    rng = np.random.default_rng(2)
    n_blocks, n = 8, 512
    lines = np.fft.rfftfreq(n, 1 / FS)
    spectrum = np.exp(2j * np.pi * rng.random((n_blocks, len(lines), 2)))
    spectrum[:, 0] = 0.0
    spectrum[:, -1] = 0.0
    x = np.fft.irfft(spectrum, n=n, axis=1)  # (blocks, n, 2)
    h = receptance(M3, K3, ZETA3, lines, [0, 1, 2], [0, 2])
    y = np.fft.irfft(np.einsum("koi,bki->bko", h, spectrum), n=n, axis=1)
    frfs = frf_from_time(
        x.reshape(-1, 2), y.reshape(-1, 3), FS, inputs=IN2, outputs=OUT, kind="receptance",
        window="rect", nperseg=n, overlap=0.0, band=(0.0, 99.7),  # DC and Nyquist are not excited
    )
    np.testing.assert_allclose(frfs.values, h[1:-1], rtol=1e-9, atol=0)
    np.testing.assert_allclose(frfs.coherence, 1.0, atol=1e-9)  # multiple coherence, noise-free


def test_single_block_has_no_coherence():
    x = np.random.default_rng(3).standard_normal(1024)
    y = _respond(x[:, None], [2])
    frfs = frf_from_time(x, y, FS, inputs=IN, outputs=OUT, kind="receptance", window="rect", nperseg=1024)
    assert frfs.coherence is None  # it would be 1 by construction
    spectrum = np.fft.rfft(x)
    spectrum[np.fft.rfftfreq(1024, 1 / FS) > 80.0] = 0.0  # periodic, no force above 80 Hz
    x = np.fft.irfft(spectrum, n=1024)
    with pytest.warns(UserWarning, match=r"no force at 80.07\d*–100 Hz .*left out \(one block: no coherence\)"):
        frfs = frf_from_time(x, _respond(x[:, None], [2]), FS, inputs=IN, outputs=OUT, kind="receptance",
                             window="rect", nperseg=1024)
    assert frfs.coherence is None and frfs.frequencies_hz[-1] < 80.0
    np.testing.assert_allclose(frfs.values, _exact(frfs), rtol=1e-9)  # one period of a periodic signal: exact


def test_force_without_energy_in_a_band_is_flagged_not_silent():
    """Periodic blocks with no force line above 50 Hz: those lines get H = 0, γ² = 0 and a warning."""
    rng = np.random.default_rng(4)
    n_blocks, n = 6, 1024
    lines = np.fft.rfftfreq(n, 1 / FS)
    spectrum = np.exp(2j * np.pi * rng.random((n_blocks, len(lines), 1))) * (lines <= 50.0)[None, :, None]
    x = np.fft.irfft(spectrum, n=n, axis=1).reshape(-1, 1)
    h = receptance(M3, K3, ZETA3, lines, [0, 1, 2], [2])
    y = np.fft.irfft(np.einsum("koi,bki->bko", h, spectrum), n=n, axis=1).reshape(-1, 3)  # periodic per block
    with pytest.warns(UserWarning, match=r"no force at 50.1\d+–100 Hz .*H set to 0 and coherence to 0 there"):
        frfs = frf_from_time(x, y, FS, inputs=IN, outputs=OUT, kind="receptance", window="rect", nperseg=n,
                             overlap=0.0)
    dead = frfs.frequencies_hz > 50.0
    assert np.all(frfs.coherence[dead] == 0) and np.all(frfs.values[dead] == 0)
    assert np.all(frfs.coherence[~dead] > 0.999)
    ((lo, hi),) = low_coherence_bands(frfs, 0.5)
    assert lo == frfs.frequencies_hz[dead][0] and hi == 100.0


def test_sine_coefficients_are_eq_2_2_for_whole_periods():
    n, periods = 400, 7
    t = np.arange(n) / FS
    f0 = periods * FS / n
    x = 0.3 + 2.0 * np.cos(2 * np.pi * f0 * t - 0.4)
    coefficient = sine_coefficients(x, FS, f0)
    a_j = np.sum(x * np.cos(2 * np.pi * periods * np.arange(n) / n)) / n  # eq. (2.2), t_n = n/FS from n = 0
    b_j = np.sum(x * np.sin(2 * np.pi * periods * np.arange(n) / n)) / n
    np.testing.assert_allclose(coefficient, 2 * (a_j - 1j * b_j), rtol=1e-12)
    np.testing.assert_allclose(coefficient, 2.0 * np.exp(-0.4j), rtol=1e-12)


def test_stepped_sine_is_exact_for_noise_free_sines():
    steps = np.linspace(5.0, 40.0, 36)
    h = receptance(M3, K3, ZETA3, steps, [0, 1, 2], [2])
    rng = np.random.default_rng(5)
    force, response = [], []
    for k, f0 in enumerate(steps):
        n = 300 + 37 * k  # not a whole number of periods
        t = np.arange(n) / FS
        amplitude = 10.0 * np.exp(2j * np.pi * rng.random())
        force.append(np.real(amplitude * np.exp(2j * np.pi * f0 * t)))
        response.append(np.real(amplitude * h[k, :, 0][None, :] * np.exp(2j * np.pi * f0 * t)[:, None]))
    frfs = frf_stepped_sine(steps, force, response, FS, inputs=IN, outputs=OUT, kind="receptance")
    np.testing.assert_allclose(frfs.values, h, rtol=1e-10)
    assert frfs.coherence is None


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda x, y: frf_from_time(x[:-1], y, FS, inputs=IN, outputs=OUT, kind="receptance"),
         "force has 4095 samples but response has 4096"),
        (lambda x, y: frf_from_time(x, y[:, :2], FS, inputs=IN, outputs=OUT, kind="receptance"),
         "response has 2 channel(s) but 3 sensor(s)"),
        (lambda x, y: frf_from_time(x, np.where(np.arange(4096)[:, None] == 7, np.nan, y), FS, inputs=IN,
                                    outputs=OUT, kind="receptance"), "response channel 0: value nan at sample 7"),
        (lambda x, y: frf_from_time(0 * x, y, FS, inputs=IN, outputs=OUT, kind="receptance"),
         "force channel 0 (3+Z) is zero throughout"),
        (lambda x, y: frf_from_time(np.hstack([x, x]), y, FS, inputs=IN2, outputs=OUT, kind="receptance",
                                    estimator="H2"), "H2 needs a single input"),
        (lambda x, y: frf_from_time(x, y, FS, inputs=IN, outputs=OUT, kind="receptance", nperseg=8192),
         "nperseg = 8192 must be in 2..4096"),
        (lambda x, y: frf_from_time(x, y, FS, inputs=IN, outputs=OUT, kind="strain"), "FRF kind 'strain'"),
        (lambda x, y: frf_from_time(x, y, FS, inputs=IN, outputs=OUT, kind="receptance", window="flattop"),
         "window 'flattop' is not one of"),
        (lambda x, y: frf_stepped_sine([1.0, 2.0], [x[:, 0]] * 3, [y] * 3, FS, inputs=IN, outputs=OUT,
                                       kind="receptance"), "2 step frequencies but 3 force and 3 response records"),
        (lambda x, y: frf_stepped_sine([2.0, 2.0], [x[:, 0]] * 2, [y] * 2, FS, inputs=IN, outputs=OUT,
                                       kind="receptance"), "not strictly increasing: 2.0 Hz after 2.0 Hz"),
        (lambda x, y: frf_stepped_sine([1.0, 2.0], [x[:, 0], x[:-1, 0]], [y] * 2, FS, inputs=IN, outputs=OUT,
                                       kind="receptance"), "step 1 (2 Hz): force has 4095 samples but response"),
        (lambda x, y: frf_stepped_sine([1.0, 2.0], [x[:, 0], 0 * x[:, 0]], [y] * 2, FS, inputs=IN, outputs=OUT,
                                       kind="receptance"), "step 1 (2 Hz): no force at the step frequency"),
        (lambda x, y: frf_stepped_sine([150.0], [x[:, 0]], [y], FS, inputs=IN, outputs=OUT, kind="receptance"),
         "step 0 (150 Hz): frequency 150.0 Hz is not in (0, fs/2 = 100.0 Hz)"),
        (lambda x, y: frf_stepped_sine([0.01], [x[:, 0]], [y], FS, inputs=IN, outputs=OUT, kind="receptance"),
         "holds 0.205 periods"),
        (lambda x, y: frf_stepped_sine([1.0], [x], [y], FS, inputs=IN2, outputs=OUT, kind="receptance"),
         "stepped sine with 2 inputs"),
    ],
)
def test_bad_input_is_named(call, message):
    rng = np.random.default_rng(6)
    x = rng.standard_normal((4096, 1))
    y = _respond(x, [2])
    with pytest.raises(ValueError, match=re.escape(message)):
        call(x, y)


def test_low_coherence_bands_and_mask():
    f = np.arange(1.0, 11.0)
    coherence = np.ones((10, 2, 1))
    coherence[2:4, 1, 0] = 0.1  # 3–4 Hz, one FRF
    coherence[7, 0, 0] = 0.0  # 8 Hz
    frfs = FRFData(f, np.ones((10, 2, 1)), Sensors.from_components([1, 2], [3, 3]), IN, "mobility",
                   coherence=coherence)
    assert low_coherence_bands(frfs, 0.5) == [(3.0, 4.0), (8.0, 8.0)]
    assert low_coherence_bands(frfs, 0.05) == [(8.0, 8.0)]
    assert np.count_nonzero(~coherence_mask(frfs, 0.5)) == 3
    no_coherence = FRFData(f, np.ones((10, 2, 1)), frfs.outputs, IN, "mobility")
    assert low_coherence_bands(no_coherence) == []
    with pytest.raises(ValueError, match=r"coherence threshold 1.5 is not in \[0, 1\]"):
        coherence_mask(frfs, 1.5)


def test_estimated_frfs_round_trip_through_uff58_with_coherence(tmp_path, random_test):
    _, x, y = random_test
    frfs = frf_from_time(x[:2**13], y[:2**13], FS, inputs=IN, outputs=OUT, kind="receptance", nperseg=512,
                         band=(1.0, 50.0))
    write_uff(tmp_path / "frf.uff", frfs=frfs)
    back = read_uff(tmp_path / "frf.uff")["frfs"]
    np.testing.assert_array_equal(back.frequencies_hz, frfs.frequencies_hz)
    np.testing.assert_array_equal(back.values, frfs.values)
    np.testing.assert_array_equal(back.coherence, frfs.coherence)
    assert back.outputs.labels == OUT.labels and back.inputs.labels == IN.labels


def test_frf_data_helper_adds_relative_noise():
    f = np.linspace(1.0, 50.0, 200)
    h = receptance(M3, K3, ZETA3, f, [0, 1, 2], [2])
    noisy = frf_data(h, f, [0, 1, 2], [2], noise=0.01)
    np.testing.assert_allclose(np.std(np.abs(noisy.values / h - 1)), 0.01 * np.sqrt(1 - np.pi / 4), rtol=0.15)


def test_merge_inputs_of_separate_runs():
    steps = np.linspace(5.0, 40.0, 8)
    sets = []
    for inp in (0, 2):
        h = receptance(M3, K3, ZETA3, steps, [0, 1, 2], [inp])
        sets.append(FRFData(steps, h, OUT, Sensors.from_components([inp + 1], [3]), "receptance"))
    merged = merge_inputs(sets)
    np.testing.assert_array_equal(merged.values, receptance(M3, K3, ZETA3, steps, [0, 1, 2], [0, 2]))
    assert merged.inputs.labels == ["1+Z", "3+Z"] and merged.coherence is None
    shifted = FRFData(steps * (1 + 1e-6), sets[1].values, OUT, sets[1].inputs, "receptance")
    with pytest.raises(ValueError, match=r"FRF set 1 has a frequency axis different from set 0 \(line 0: 5.000005 Hz"):
        merge_inputs([sets[0], shifted])
    short = FRFData(steps[:-1], sets[1].values[:-1], OUT, sets[1].inputs, "receptance")
    with pytest.raises(ValueError, match=r"frequency axis different from set 0 \(7 lines against 8\)"):
        merge_inputs([sets[0], short])
    with pytest.raises(ValueError, match="FRF set 1 is a mobility, set 0 a receptance"):
        merge_inputs([sets[0], FRFData(steps, sets[1].values, OUT, sets[1].inputs, "mobility")])
    with pytest.raises(ValueError, match="measure the same DoF"):
        merge_inputs([sets[0], sets[0]])
    with_coherence = FRFData(steps, sets[1].values, OUT, sets[1].inputs, "receptance",
                             coherence=np.ones(sets[1].values.shape))
    with pytest.warns(UserWarning, match="only some FRF sets carry a coherence"):
        assert merge_inputs([sets[0], with_coherence]).coherence is None
