"""Time histories in UFF dataset 58 (function type 1), channel-only records with a DoF
map, and FRFs estimated from the histories (H1/H2, coherence) against the exact FRFs of
a spring–mass chain.

The files are written here, record by record through pyuff as a test system exports
them; the signals are steady-state responses synthesised in the frequency domain
(periodic over the record), so the exact accelerance is known at every line.
"""

import warnings

import numpy as np
import pyuff
import pytest
from _frf_models import chain, receptance

from identification import TimeHistories, frf_from_histories, read_dof_map, read_uff

MASSES, SPRINGS = [1.0, 1.5, 0.8], [4e4, 3e4, 2e4]  # modes at 12.5, 31.3, 46.0 Hz
MM = {"type": 164, "units_code": 5, "units_description": "MM", "temp_mode": 1, "length": 1000.0, "force": 1000.0,
      "temp": 1.0, "temp_offset": 273.15}  # mm and mN: 1000 file units per m and per N


def accelerance(zeta, f, out_dofs=(0, 1, 2), in_dof=2):
    """Exact accelerance (nf, n_out) of the chain, force at ``in_dof``."""
    M, K = chain(MASSES, SPRINGS)
    h = receptance(M, K, zeta, f, list(out_dofs), [in_dof])[:, :, 0]
    return -((2 * np.pi * np.asarray(f))[:, None] ** 2) * h


def synthesise(fs, n_period, n_periods, zeta, *, seed=0, flat=True):
    """Force (n,) in N and accelerations (n, 3) in m/s² of the chain driven at mass 3:
    a random force periodic in ``n_period`` samples (flat spectrum with random phases
    when ``flat``, else Gaussian), the response its exact steady state."""
    rng = np.random.default_rng(seed)
    f = np.fft.rfftfreq(n_period, 1.0 / fs)
    if flat:
        X = np.exp(2j * np.pi * rng.random(len(f)))
    else:
        X = rng.standard_normal(len(f)) + 1j * rng.standard_normal(len(f))
    X[0], X[-1] = 0.0, 1.0  # no DC; the Nyquist line of a real signal is real
    x = np.fft.irfft(X, n_period)
    y = np.fft.irfft(accelerance(zeta, f) * X[:, None], n_period, axis=0)
    return np.tile(x, n_periods), np.tile(y, (n_periods, 1))


def time_record(name, node, direction, quantity, t, values, *, binary=0, id1=None, **extra):
    """A dataset-58 time record (function type 1) as pyuff writes it."""
    spec = {"force": 13, "displacement": 8, "velocity": 11, "acceleration": 12}.get(quantity, quantity)
    return {"type": 58, "binary": binary, "func_type": 1, "id1": name if id1 is None else id1,
            "rsp_ent_name": name, "rsp_node": node, "rsp_dir": direction, "ref_node": 0, "ref_dir": 0,
            "abscissa_spacing": 1, "abscissa_spec_data_type": 17, "ordinate_spec_data_type": spec,
            "orddenom_spec_data_type": 0, "x": t, "data": values, **extra}


def write_records(path, records):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)  # pyuff leaves binary-58 handles to the collector
        pyuff.UFF(str(path)).write_sets(records, mode="overwrite")
    return path


def chain_records(fs, x, y, *, scale=1.0, names=("F3", "A1", "A2", "A3"), nodes=(3, 1, 2, 3), binary=0):
    """Force at mass 3 and the three accelerations, values × ``scale`` (file units)."""
    t = np.arange(len(x)) / fs
    quantities = ("force", "acceleration", "acceleration", "acceleration")
    signals = (x, y[:, 0], y[:, 1], y[:, 2])
    return [time_record(n, g, 3 if g else 0, q, t, s * scale, binary=binary)
            for n, g, q, s in zip(names, nodes, quantities, signals)]


def test_time_histories_read_in_si_with_the_sampling_rate(tmp_path):
    fs = 1024  # Δt = 9.765625e-4 s is written E13.5: 9.76562e-04, 1/Δt = 1024.0016 Hz
    x, y = synthesise(fs, 256, 2, 0.02)
    path = write_records(tmp_path / "t.uff", [MM, *chain_records(fs, x, y, scale=1000.0)])
    th = read_uff(path)["time"]
    assert th.fs == 1024.0
    assert th.names == ("F3", "A1", "A2", "A3")
    assert th.quantities == ("force", "acceleration", "acceleration", "acceleration")
    assert th.dof_labels == ["3+Z", "1+Z", "2+Z", "3+Z"]
    assert th.n_samples == 512 and th.start_s == 0.0
    np.testing.assert_allclose(th.values, np.column_stack([x, y]), rtol=1e-10, atol=1e-12 * np.abs(y).max())
    assert th.units(0) == "N" and th.units(1) == "m/s²"
    assert read_uff(path)["frfs"] is None


def test_channel_names_fall_back_to_id1_and_other_quantities_are_ignored(tmp_path):
    t = np.arange(64) / 128.0
    s = np.sin(2 * np.pi * 8 * t)
    path = write_records(tmp_path / "t.uff", [
        MM,
        time_record("NONE", 5, -2, "force", t, s, id1="Hammer tip"),
        time_record("mic", 6, 1, 15, t, s),  # a pressure: not force or motion
        time_record("vel", 5, 5, "velocity", t, 2 * s),  # a rotation rate: rad/s, no length factor
    ])
    with pytest.warns(UserWarning, match=r"type 15: datasets #3"):
        th = read_uff(path)["time"]
    assert th.names == ("Hammer tip", "vel")
    assert th.dof_labels == ["5-Y", "5+RY"]
    np.testing.assert_allclose(th.values[:, 0], s / 1000.0, rtol=1e-10, atol=1e-14)  # mN → N
    np.testing.assert_allclose(th.values[:, 1], 2 * s, rtol=1e-10, atol=1e-14)
    assert th.fs == 128.0


def test_channel_only_time_records_need_a_dof_map(tmp_path):
    fs = 256
    x, y = synthesise(fs, 64, 1, 0.02)
    path = write_records(tmp_path / "t.uff", [MM, *chain_records(fs, x, y, nodes=(0, 0, 0, 0))])
    with pytest.raises(ValueError, match=r"no DoF \(direction 0\) for channel\(s\) 'F3', 'A1', 'A2', 'A3'.*"
                                         r"--dof-map"):
        read_uff(path)
    dof_map = {"F3": (103, 3), "A1": (101, -3), "A2": (102, 3), "A3": (103, 3)}
    th = read_uff(path, dof_map=dof_map)["time"]
    assert th.dof_labels == ["103+Z", "101-Z", "102+Z", "103+Z"]
    with pytest.raises(ValueError, match=r"'A2' have no DoF in the file .* no row in the DoF map"):
        read_uff(path, dof_map={k: v for k, v in dof_map.items() if k != "A2"})
    with pytest.raises(ValueError, match=r"rows name channel\(s\) 'A9' absent from the file; its channels are 'A1'"):
        read_uff(path, dof_map={**dof_map, "A9": (109, 3)})
    with pytest.raises(ValueError, match=r"channel 'A1' maps to node 101, direction 7"):
        read_uff(path, dof_map={**dof_map, "A1": (101, 7)})


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"x": np.arange(32) / 512.0}, r"dataset #3 \(channel 'A1'\) samples at 512 Hz .* but dataset #2 \(channel "
                                       r"'F3'\) at 256 Hz: mixed sampling rates \(record 7, field 5\)"),
        ({"x": np.arange(16) / 256.0, "data": np.ones(16)}, r"dataset #3 .* has 16 samples but .* has 32"),
        ({"x": 0.5 + np.arange(32) / 256.0}, r"dataset #3 .*starts at 0.5 s but dataset #2 .* at 0.0 s"),
        ({"abscissa_spec_data_type": 18}, r"dataset #3 \(channel 'A1'\): abscissa specific data type 18 is not time"),
        ({"data": np.ones(32) * (1 + 1j)}, r"dataset #3 \(channel 'A1'\): ordinate data type 6 is complex"),
        ({"rsp_dir": 7}, r"dataset #3 \(channel 'A1'\): response direction 7 is not ±1..6 \(record 6, field 7\)"),
        ({"rsp_dir": 0, "rsp_ent_name": "NONE", "id1": "NONE"},
         r"dataset #3: response direction 0 is not ±1..6 \(record 6, field 7\) \(and no channel name for a DoF map\)"),
    ],
)
def test_bad_time_records_are_named(tmp_path, change, message):
    t = np.arange(32) / 256.0
    records = [time_record("F3", 3, 3, "force", t, np.sin(t)), time_record("A1", 1, 3, "acceleration", t, np.cos(t))]
    records[1] = {**records[1], **change}
    path = write_records(tmp_path / "bad.uff", [MM, *records])
    with pytest.raises(ValueError, match=str(tmp_path / "bad.uff").replace(".", r"\.") + ": " + message):
        read_uff(path)


def test_a_nan_sample_is_named(tmp_path):
    t = np.arange(32) / 256.0
    values = np.r_[np.ones(30), 123.0, 1.0]
    path = write_records(tmp_path / "nan.uff", [MM, time_record("A1", 1, 3, "acceleration", t, values)])
    path.write_text(path.read_text().replace("1.23000000000e+02", "nan".rjust(17)))  # pyuff writes NaN as 0
    with pytest.raises(ValueError, match=r"dataset #2 \(channel 'A1'\): value nan at sample 30 \(0.117\d* s\)"):
        read_uff(path)


def test_uneven_abscissa_of_a_constant_rate_is_read(tmp_path):
    t = 0.25 + np.arange(40) / 100.0  # abscissa values stored (spacing flag 0), starting at 0.25 s
    records = [time_record(n, g, 3, q, t, np.cos(t * g), binary=1, abscissa_spacing=0)
               for n, g, q in (("F", 1, "force"), ("D", 2, "displacement"))]
    th = read_uff(write_records(tmp_path / "t.uff", [MM, *records]))["time"]
    assert th.fs == 100.0 and th.start_s == 0.25
    np.testing.assert_allclose(th.values[:, 1], np.cos(2 * t) / 1000.0, rtol=1e-14)  # mm → m
    jitter = t.copy()
    jitter[7] += 0.2 / 100.0
    records = [{**r, "x": jitter} for r in records]
    with pytest.raises(ValueError, match=r"dataset #2 \(channel 'F'\): sample 7 .* off the uniform time axis"):
        read_uff(write_records(tmp_path / "j.uff", [MM, *records]))


def test_h1_of_periodic_random_excitation_is_the_exact_accelerance(tmp_path):
    """Periodic excitation, rectangular window, block = period: no leakage and no noise,
    so H1 = H2 = the exact accelerance at every line and γ² = 1 (to rounding of the
    12-digit ASCII values)."""
    fs, period, zeta = 1024, 1024, 0.02
    x, y = synthesise(fs, period, 8, zeta, seed=1)
    path = write_records(tmp_path / "t.uff", [MM, *chain_records(fs, x, y, scale=1000.0)])
    th = read_uff(path)["time"]
    for estimator in ("H1", "H2"):
        est = frf_from_histories(th, ["3:+3"], estimator=estimator, window="rect", blocks=8)
        assert (est.block_length, est.n_averages, est.resolution_hz) == (1024, 8, 1.0)
        f = est.frfs.frequencies_hz
        np.testing.assert_array_equal(f, np.arange(1, 513, dtype=np.float64))
        exact = accelerance(zeta, f[:-1])  # the Nyquist line of a real signal keeps only the real part
        np.testing.assert_allclose(est.frfs.values[:-1, :, 0], exact, rtol=1e-7)
        np.testing.assert_allclose(est.frfs.coherence[:-1], 1.0, atol=1e-9)
    assert est.frfs.kind == "accelerance"
    assert est.frfs.inputs.labels == ["3+Z"] and est.frfs.outputs.labels == ["1+Z", "2+Z", "3+Z"]


def test_h1_is_unbiased_by_response_noise_where_h2_is_not():
    """Gaussian random force, Hann blocks (2·64 − 1 averages): noise-free, H1 is within
    0.2 % (median) of the exact accelerance where γ² > 0.9; with noise on the responses,
    at the lines the noise dominates (γ² < 0.5) H1 stays unbiased (|H1/H| median 1 ± 10
    %) and H2 = H1/γ² is biased high (median > 2)."""
    fs, n, zeta = 512, 2**17, 0.05
    x, y = synthesise(fs, n, 1, zeta, seed=2, flat=False)
    rng = np.random.default_rng(3)
    for noise in (0.0, 0.2):
        noisy = y + noise * y.std(axis=0) * rng.standard_normal(y.shape)
        th = TimeHistories(np.column_stack([x, noisy]), fs, [3, 1, 2, 3], [3, 3, 3, 3], ["F", "A1", "A2", "A3"],
                           ["force", "acceleration", "acceleration", "acceleration"])
        h1, h2 = (frf_from_histories(th, ["F"], estimator=e, blocks=64) for e in ("H1", "H2"))
        assert h1.n_averages == 127 and h1.resolution_hz == 0.25
        f = h1.frfs.frequencies_hz
        band = f < 100.0
        ratio1 = (h1.frfs.values[:, :, 0] / accelerance(zeta, f))[band]
        ratio2 = (h2.frfs.values[:, :, 0] / accelerance(zeta, f))[band]
        coherence = h1.frfs.coherence[band, :, 0]
        np.testing.assert_array_equal(coherence, h2.frfs.coherence[band, :, 0])
        if noise == 0.0:
            high = coherence > 0.9
            assert high.mean() > 0.95
            assert np.median(np.abs(ratio1[high] - 1)) < 2e-3
            assert np.max(np.abs(ratio1[high] - 1)) < 0.1
            assert np.median(coherence) > 0.999
        else:
            low = coherence < 0.5
            assert low.sum() > 100
            assert abs(np.median(np.abs(ratio1[low])) - 1) < 0.1
            assert np.median(np.abs(ratio2[low])) > 2.0
            np.testing.assert_allclose(np.abs(ratio2[low]), np.abs(ratio1[low]) / coherence[low], rtol=1e-8)


def test_force_selection_and_its_errors():
    fs = 256
    x, y = synthesise(fs, 64, 4, 0.02)
    th = TimeHistories(np.column_stack([x, y]), fs, [3, 1, 2, 3], [3, 3, 3, -3], ["F3", "A1", "A2", "A3"],
                       ["force", "acceleration", "acceleration", "acceleration"])
    assert th.find("3:3") == [0, 3] and th.find("3:+3") == [0] and th.find("3:-3") == [3]
    assert th.find("3-z") == [3] and th.find("A2") == [2] and th.find("A9") == []
    est = frf_from_histories(th, ["3:3"], window="rect", blocks=4)
    assert est.input_channels == ("F3 (3+Z, force)",)
    assert est.output_channels == ("A1 (1+Z, acceleration)", "A2 (2+Z, acceleration)", "A3 (3-Z, acceleration)")
    with pytest.raises(ValueError, match=r"no channel matches force 'F9'; the channels are: F3 \(3\+Z, force\); "
                                         r"A1 \(1\+Z, acceleration\)"):
        frf_from_histories(th, ["F9"])
    with pytest.raises(ValueError, match=r"force 'A1' matches A1 \(1\+Z, acceleration\), not a force channel"):
        frf_from_histories(th, ["A1"])
    with pytest.raises(ValueError, match=r"H2 needs a single input"):
        frf_from_histories(TimeHistories(np.column_stack([x, x[::-1], y[:, 0]]), fs, [3, 2, 1], [3, 3, 3],
                                         ["F3", "F2", "A1"], ["force", "force", "acceleration"]),
                           ["F3", "F2"], estimator="H2")
    two_forces = TimeHistories(np.column_stack([x, x[::-1], y[:, 0]]), fs, [3, 2, 1], [3, 3, 3], ["F3", "F2", "A1"],
                               ["force", "force", "acceleration"])
    with pytest.raises(ValueError, match=r"force channel\(s\) F2 \(2\+Z, force\) not named as inputs"):
        frf_from_histories(two_forces, ["F3"])
    mixed = TimeHistories(np.column_stack([x, y[:, :2]]), fs, [3, 1, 2], [3, 3, 3], ["F3", "A1", "D2"],
                          ["force", "acceleration", "displacement"])
    with pytest.raises(ValueError, match=r"responses of mixed quantities .*acceleration: A1 .*displacement: D2"):
        frf_from_histories(mixed, ["F3"])
    with pytest.raises(ValueError, match=r"both measure acceleration at 1\+Z"):
        TimeHistories(np.column_stack([x, y[:, 0], y[:, 1]]), fs, [3, 1, 1], [3, 3, 3], ["F", "a", "b"],
                      ["force", "acceleration", "acceleration"])


def test_dof_map_csv(tmp_path):
    path = tmp_path / "map.csv"
    path.write_text("channel, node, direction\nacc 1,101,+Z\nacc2,102,-3\nhammer,103,3\nrot,104,-RX\n")
    assert read_dof_map(path) == {"acc 1": (101, 3), "acc2": (102, -3), "hammer": (103, 3), "rot": (104, -4)}
    for text, message in [
        ("channel,node\nacc1,101\n", r"line 1: missing column\(s\) \['direction'\]"),
        ("channel,node,direction\nacc1,101,3\nacc2,1o2,3\n", r"line 3: field 'node': '1o2' is not a node id"),
        ("channel,node,direction\nacc1,101,7\n", r"line 2: field 'direction': '7' is not a direction code"),
        ("channel,node,direction\nacc1,101,3\n,102,3\n", r"line 3: field 'channel' is empty"),
        ("channel,node,direction\nacc1,101,3\nacc1,102,3\n", r"line 3: channel 'acc1' repeats line 2"),
        ("channel,node,direction\nacc1,101,3,9\n", r"line 2: more fields than the header's 3"),
        ("channel,node,direction\n", r"no rows"),
        ("channel,node,direction\nacc1,\u0661,3\n", r"line 2: field 'node': '\u0661' is not a node id"),  # int() took it
        ("channel,node,direction\nacc1,99999999999,3\n", r"line 2: field 'node': 99999999999 is outside 0\.\.2,147,483,647"),
    ]:
        path.write_text(text)
        with pytest.raises(ValueError, match=str(path).replace(".", r"\.") + ".*" + message):
            read_dof_map(path)
