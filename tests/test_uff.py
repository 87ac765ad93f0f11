"""Universal files: round trips, unit conversion, direction codes, and errors naming the item.

Files for the reader tests are written record by record with pyuff itself, so the reader
is checked against the format rather than against our writer.
"""

import re

import numpy as np
import pytest
import pyuff

from identification import FRFData, ModalData, Sensors, read_uff, write_uff

NODES = {101: np.array([0.0, 0.0, 0.0]), 102: np.array([1.0, 0.1234567890123, 0.0]), 103: np.array([2.0, 0.0, 1 / 3])}


def _units(length=1.0, force=1.0, code=9):
    return {"type": 164, "units_code": code, "units_description": "test", "temp_mode": 1,
            "length": length, "force": force, "temp": 1.0, "temp_offset": 273.15}


def _nodes(ids, xyz, kind=2411):
    xyz = np.asarray(xyz, dtype=float)
    zeros = np.zeros(len(ids), dtype=int)
    return {"type": kind, "node_nums": np.asarray(ids), "def_cs": zeros, "disp_cs": zeros, "color": zeros,
            "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]}


def _mode(mode, freq, node_ids, values, **extra):
    """Dataset 55, normal mode, 3 translations per node; values (n_nodes, 3)."""
    values = np.asarray(values, dtype=float)
    return {"type": 55, "model_type": 1, "analysis_type": 2, "data_ch": 2, "spec_data_type": 8,
            "load_case": 1, "mode_n": mode, "freq": freq, "modal_m": 0.0, "modal_damp_vis": 0.0,
            "modal_damp_his": 0.0, "node_nums": np.asarray(node_ids),
            "r1": values[:, 0], "r2": values[:, 1], "r3": values[:, 2]} | extra


def _frf(rsp, ref, x, data, ordinate=8, binary=0):
    return {"type": 58, "binary": binary, "func_type": 4, "rsp_node": rsp[0], "rsp_dir": rsp[1],
            "ref_node": ref[0], "ref_dir": ref[1], "abscissa_spacing": 0, "abscissa_spec_data_type": 18,
            "ordinate_spec_data_type": ordinate, "orddenom_spec_data_type": 13,
            "x": np.asarray(x, dtype=float), "data": np.asarray(data, dtype=complex)}


def _write(path, datasets):
    pyuff.UFF(str(path)).write_sets(datasets, mode="overwrite")
    return path


# -- round trips -----------------------------------------------------------------------


@pytest.fixture
def modal():
    rng = np.random.default_rng(0)
    sensors = Sensors.from_components([101, 101, 102, 103, 103], [1, 3, 3, 2, 3])
    return ModalData([1.234567, 20.5, 33.3], rng.normal(size=(5, 3)), sensors,
                     damping_ratios=[0.01, 0.02, 0.0], generalised_masses=[1.0, 2.5, 3.0], mode_ids=[3, 5, 7])


@pytest.fixture
def frfs():
    rng = np.random.default_rng(1)
    f = np.linspace(1.0, 100.0, 64) ** 1.01  # uneven axis, many digits
    values = rng.normal(size=(64, 2, 2)) + 1j * rng.normal(size=(64, 2, 2))
    return FRFData(f, values, Sensors.from_components([101, 102], [3, -3]), Sensors.from_components([1, 2], [3, 6]),
                   "accelerance", coherence=rng.uniform(size=(64, 2, 2)))


def test_round_trip_real_modes_nodes_and_frfs(tmp_path, modal, frfs):
    path = tmp_path / "test.uff"
    write_uff(path, nodes=NODES, modes=modal, frfs=frfs)
    data = read_uff(path)
    assert data["units"]["code"] == 1 and data["units"]["length"] == 1.0
    assert data["nodes"].keys() == NODES.keys()
    for g, xyz in NODES.items():
        np.testing.assert_array_equal(data["nodes"][g], xyz)  # 2411 is double precision: exact
    modes = data["modes"]
    assert modes.sensors.labels == modal.sensors.labels
    np.testing.assert_array_equal(modes.mode_ids, [3, 5, 7])
    # dataset 55 is E13.5: 6 significant digits
    np.testing.assert_allclose(modes.shapes, modal.shapes, rtol=5e-6)
    np.testing.assert_allclose(modes.frequencies_hz, modal.frequencies_hz, rtol=5e-6)
    np.testing.assert_allclose(modes.damping_ratios, modal.damping_ratios, rtol=5e-6)
    np.testing.assert_allclose(modes.generalised_masses, modal.generalised_masses, rtol=5e-6)
    again = tmp_path / "again.uff"
    write_uff(again, nodes=data["nodes"], modes=modes)
    np.testing.assert_array_equal(read_uff(again)["modes"].shapes, modes.shapes)  # idempotent after one trip
    out = data["frfs"]
    assert out.kind == "accelerance"
    assert out.outputs.labels == ["101+Z", "102-Z"] and out.inputs.labels == ["1+Z", "2+RZ"]
    np.testing.assert_array_equal(out.frequencies_hz, frfs.frequencies_hz)  # binary 58: exact
    np.testing.assert_array_equal(out.values, frfs.values)
    np.testing.assert_array_equal(out.coherence, frfs.coherence)


def test_round_trip_complex_modes(tmp_path, modal):
    rng = np.random.default_rng(2)
    psi = modal.shapes + 0.3j * rng.normal(size=modal.shapes.shape)
    complex_modes = ModalData(modal.frequencies_hz, psi, modal.sensors, damping_ratios=[0.01, 0.05, 0.2])
    write_uff(tmp_path / "c.uff", modes=complex_modes)
    modes = read_uff(tmp_path / "c.uff")["modes"]
    assert modes.shapes.dtype == np.complex128 and modes.generalised_masses is None
    np.testing.assert_allclose(modes.shapes, psi, rtol=1e-5, atol=1e-5 * np.abs(psi).max())
    # f = |λ|/2π and ζ = −Re λ/|λ| from the stored eigenvalue (6 digits per part)
    np.testing.assert_allclose(modes.frequencies_hz, modal.frequencies_hz, rtol=1e-5)
    np.testing.assert_allclose(modes.damping_ratios, [0.01, 0.05, 0.2], rtol=1e-4)
    np.testing.assert_allclose(modes.real().shapes, complex_modes.real().shapes, atol=1e-5)


def test_rotations_round_trip(tmp_path):
    sensors = Sensors.from_components([5, 5, 6], [3, 4, 6])
    modes = ModalData([4.0], [[1.0], [0.25], [-0.5]], sensors)
    write_uff(tmp_path / "r.uff", modes=modes, units={"length": 1000.0, "force": 1.0})
    back = read_uff(tmp_path / "r.uff")["modes"]
    assert back.sensors.labels == ["5+Z", "5+RX", "6+RZ"]
    np.testing.assert_allclose(back.shapes, modes.shapes, rtol=1e-15)  # rotations are not scaled


# -- units and directions --------------------------------------------------------------


def test_file_in_mm_and_newton_is_read_in_si(tmp_path):
    x = np.array([10.0, 20.0, 30.0])
    receptance_mm = np.array([1.0 + 2.0j, 3.0, -4.0j])  # mm/N
    path = _write(tmp_path / "mm.uff", [
        _units(length=1000.0, force=1.0),  # file units per SI unit: 1000 mm = 1 m
        _nodes([1, 2], [[1000.0, 0.0, 250.0], [0.0, -500.0, 0.0]]),
        _mode(1, 12.5, [1, 2], [[0.0, 0.0, 2.0], [4.0, 0.0, 0.0]], modal_m=3.0),  # N·s²/mm
        _frf((1, 3), (2, 1), x, receptance_mm),
    ])
    data = read_uff(path)
    assert data["units"] == {"code": 9, "description": "test", "length": 1000.0, "force": 1.0,
                             "temperature": 1.0, "temperature_offset": 273.15, "declared": True}
    np.testing.assert_allclose(data["nodes"][1], [1.0, 0.0, 0.25], rtol=1e-15)
    np.testing.assert_allclose(data["nodes"][2], [0.0, -0.5, 0.0], rtol=1e-15)
    modes = data["modes"]
    assert modes.sensors.labels == ["1+Z", "2+X"]  # components zero in every mode are not measured
    np.testing.assert_allclose(modes.shapes[:, 0], [2e-3, 4e-3], rtol=1e-15)
    np.testing.assert_allclose(modes.generalised_masses, [3000.0], rtol=1e-15)  # 1 N·s²/mm = 1000 kg
    np.testing.assert_allclose(modes.frequencies_hz, [12.5])  # Hz in every unit system
    np.testing.assert_allclose(data["frfs"].values[:, 0, 0], receptance_mm * 1e-3, rtol=1e-15)


def test_writer_converts_to_the_requested_units(tmp_path, frfs):
    path = tmp_path / "mm.uff"
    write_uff(path, nodes=NODES, frfs=frfs, units={"length": 1000.0, "force": 1.0})
    raw = pyuff.UFF(str(path)).read_sets()
    assert raw[0]["units_code"] == 9
    np.testing.assert_allclose(raw[1]["y"], [0.0, 123.4567890123, 0.0], rtol=1e-15)
    back = read_uff(path)
    np.testing.assert_allclose(back["nodes"][102], NODES[102], rtol=1e-15)
    np.testing.assert_allclose(back["frfs"].values, frfs.values, rtol=1e-14)


def test_negative_direction_codes(tmp_path):
    x = [1.0, 2.0]
    path = _write(tmp_path / "dir.uff", [_units(code=1), _frf((7, -3), (8, -2), x, [1.0, 2.0 + 1j])])
    frf = read_uff(path)["frfs"]
    assert frf.outputs.labels == ["7-Z"] and frf.inputs.labels == ["8-Y"]
    np.testing.assert_array_equal(frf.outputs.directions, [[0.0, 0.0, -1.0]])
    np.testing.assert_array_equal(frf.values[:, 0, 0], [1.0, 2.0 + 1j])  # the sign lives in the direction
    # dataset 55 holds global components: a −Z sensor is written as +Z with its values negated
    modes = ModalData([5.0], [[1.5], [-2.0]], Sensors.from_components([7, 8], [-3, 1]))
    write_uff(tmp_path / "neg.uff", modes=modes)
    back = read_uff(tmp_path / "neg.uff")["modes"]
    assert back.sensors.labels == ["7+Z", "8+X"]
    np.testing.assert_array_equal(back.shapes[:, 0], [-1.5, -2.0])


def test_missing_units_are_si_with_a_warning(tmp_path):
    path = _write(tmp_path / "nounits.uff", [_nodes([1], [[1.0, 2.0, 3.0]])])
    with pytest.warns(UserWarning, match="no units dataset \\(164\\); SI units assumed"):
        data = read_uff(path)
    np.testing.assert_array_equal(data["nodes"][1], [1.0, 2.0, 3.0])
    assert data["units"]["length"] == 1.0 and data["modes"] is None and data["frfs"] is None


# -- errors ----------------------------------------------------------------------------

X = [1.0, 2.0, 3.0]
ONE = [[1.0, 2.0, 3.0]]


@pytest.mark.parametrize(
    "datasets, message",
    [
        ([_units(1000.0, 1.0), _units(1.0, 1.0)],
         "units dataset #2 (code 9, length 1.0, force 1.0) contradicts units dataset #1 (code 9, length 1000.0"),
        ([_units(0.001, 1.0, code=5)], "declares code 5 (MM: mm, mN) but gives length factor 0.001"),
        ([_units(code=1), _nodes([1], ONE), _nodes([1], [[1.0, 2.0, 4.0]], kind=15)],
         "node 1 is at [1.0, 2.0, 3.0] m in dataset #2 but at [1.0, 2.0, 4.0] m in dataset #3"),
        ([_units(code=1), _nodes([1], ONE), _mode(4, 10.0, [1, 999], [[1, 0, 0], [0, 1, 0]])],
         "dataset #3 (mode 4): node(s) [999] are not defined in the node datasets"),
        ([_units(code=1), _mode(4, 10.0, [1, 2], [[1, 0, 0], [0, np.nan, 0]])],
         "dataset #2 (mode 4): value nan at DoF 2+Y"),
        ([_units(code=1), _mode(4, 10.0, [1, 1], [[1, 0, 0], [0, 1, 0]])],
         "dataset #2 (mode 4): node(s) [1] appear twice (duplicate DoFs)"),
        ([_units(code=1), _mode(1, 10.0, [1, 2], [[1, 0, 0], [0, 1, 0]]), _mode(2, 20.0, [1], ONE)],
         "dataset #3 (mode 2) lacks DoFs ['2+X', '2+Y', '2+Z'] present in other modes"),
        ([_units(code=1), _mode(1, -10.0, [1], ONE)], "mode 1: frequency -10.0 Hz is not finite and positive"),
        ([_units(code=1), _frf((1, 3), (9, 3), X, [1, 2, 3]), _frf((2, 3), (9, 3), [1.0, 2.0, 3.5], [1, 2, 3])],
         "dataset #3 (2+Z / 9+Z) has a frequency axis different from dataset #2 (1+Z / 9+Z)"),
        ([_units(code=1), _frf((1, 3), (9, 3), X, [1, 2, 3]), _frf((1, 3), (9, 3), X, [1, 2, 3])],
         "dataset #3 (1+Z / 9+Z) repeats dataset #2 (1+Z / 9+Z)"),
        ([_units(code=1), _frf((1, 3), (9, 3), X, [1, 2, 3]), _frf((2, 3), (8, 3), X, [1, 2, 3])],
         "FRFs missing for (output / input) pairs ['1+Z / 8+Z', '2+Z / 9+Z']"),
        ([_units(code=1), _frf((1, 3), (9, 3), X, [1, 2, 3]), _frf((2, 3), (9, 3), X, [1, 2, 3], ordinate=12)],
         "dataset #3 (2+Z / 9+Z) is a accelerance but dataset #2 (1+Z / 9+Z) is a receptance"),
        ([_units(code=1), _frf((1, 3), (9, 3), X, [1, 2, 3], ordinate=0)],
         "dataset #2 (1+Z / 9+Z): ordinate type 0 is not displacement (8), velocity (11) or acceleration (12)"),
        ([_units(code=1), _frf((1, 0), (9, 3), X, [1, 2, 3])], "dataset #2: direction codes 0, 3 are not ±1..6"),
    ],
)
def test_read_errors_name_the_item(tmp_path, datasets, message):
    path = _write(tmp_path / "bad.uff", datasets)
    with pytest.raises(ValueError, match=re.escape(message)):
        read_uff(path)


def test_nan_in_an_frf_names_record_and_frequency(tmp_path):
    path = _write(tmp_path / "nan.uff", [_units(code=1), _frf((1, 3), (9, 3), X, [1.0, 12345.0, 3.0])])
    text = path.read_text().replace("1.23450000000e+04", "              nan")  # pyuff writes no NaN itself
    path.write_text(text)
    with pytest.raises(ValueError, match=r"dataset #2 \(1\+Z / 9\+Z\): value \(nan.*\) at 2\.0 Hz"):
        read_uff(path)


def test_unparsable_dataset_is_named(tmp_path):
    path = _write(tmp_path / "broken.uff", [_units(code=1), _nodes([1], ONE)])
    path.write_text(path.read_text().replace("1.0000000000000000e+00", "one"))
    with pytest.raises(ValueError, match=re.escape("dataset #2 (type 2411) cannot be parsed")):
        read_uff(path)


def test_write_errors(tmp_path, modal):
    skew = ModalData([1.0], [[1.0]], Sensors.from_vectors([101], [[1.0, 1.0, 0.0]]))
    with pytest.raises(ValueError, match=re.escape("sensor 101:(0.71,0.71,0.00) is not along an axis")):
        write_uff(tmp_path / "w.uff", modes=skew)
    with pytest.raises(ValueError, match=re.escape("sensor node(s) [103] are not among the nodes written")):
        write_uff(tmp_path / "w.uff", nodes={101: NODES[101], 102: NODES[102]}, modes=modal)
    with pytest.raises(ValueError, match="units 'mm'"):
        write_uff(tmp_path / "w.uff", units="mm")
    rotating = ModalData([1.0], [[1.0 + 1j], [0.5j]], Sensors.from_components([101, 101], [3, 4]))
    with pytest.raises(ValueError, match="complex modes with rotational sensors cannot be written"):
        write_uff(tmp_path / "w.uff", modes=rotating)


def test_reader_warnings_name_what_is_dropped(tmp_path):
    local = _nodes([1, 2], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    local["def_cs"] = np.array([0, 3])
    path = _write(tmp_path / "warn.uff", [
        _units(code=1),
        local,
        _mode(1, 10.0, [1, 2], [[1, 0, 0], [0, 1, 0]], modal_m=2.0, modal_damp_his=0.04),
        _mode(2, 20.0, [1, 2], [[0, 0, 1], [1, 0, 0]]),
        _frf((1, 3), (9, 3), X, [1, 2, 3]) | {"func_type": 2},  # an auto spectrum
    ])
    with pytest.warns(UserWarning) as record:
        modes = read_uff(path)["modes"]
    messages = " | ".join(str(w.message) for w in record)
    assert "taken as global: system 3: nodes [2]" in messages
    assert "modes [1] give only a hysteretic damping value" in messages
    assert "only modes [1] give a modal mass; generalised masses dropped" in messages
    assert "dataset-58 function type(s) [2] are not FRFs or coherence; ignored" in messages
    assert modes.generalised_masses is None and modes.damping_ratios[0] == 0.0
