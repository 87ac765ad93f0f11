"""UFF coordinate systems (datasets 18 and 2420): node coordinates and measured directions
in global axes, on files laid out as a Testlab export (local rectangular and cylindrical
systems, millimetres) and as a BARC/Salome export (system 1 = global: no warning)."""

import math
import re

import numpy as np
import pytest

from identification import read_uff

from test_uff import _frf, _mode, _nodes, _units, _write


def _rz(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # rows: local x, y, z in global


def _ry(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


def _systems2420(labels, types, axes, origins_mm):
    return {"type": 2420, "Part_UID": 1, "Part_Name": "test", "CS_sys_labels": list(labels), "CS_types": list(types),
            "CS_colors": [8] * len(labels), "CS_names": [f"CS{k}" for k in labels],
            "CS_matrices": [np.vstack([a, o]) for a, o in zip(axes, origins_mm)]}


def _node_set(ids, coords, def_cs, disp_cs, kind=15):
    record = _nodes(ids, coords, kind=kind)
    record["def_cs"], record["disp_cs"] = np.asarray(def_cs), np.asarray(disp_cs)
    return record


# A global displacement field per mode at each node (m); the file stores its local components.
U = {1: np.array([[1.0, 0.2], [0.0, -0.5], [0.3, 0.1]]), 2: np.array([[-0.4, 0.6], [0.8, 0.0], [0.0, 0.9]]),
     3: np.array([[0.1, -0.7], [0.5, 0.4], [-0.2, 0.3]])}


def _testlab(tmp_path):
    """Nodes 1 (global), 2 (rectangular system 10, rotated 30° about z and 20° about y,
    origin at (100, 50, 0) mm), 3 (cylindrical system 11 about global z); each mode
    stores the local components of U; an FRF along local direction 3 of node 2."""
    axes10 = _ry(20.0) @ _rz(30.0)
    origin10 = np.array([100.0, 50.0, 0.0])
    x_global = {1: np.array([0.5, 0.0, 0.0]), 2: origin10 / 1000 + np.array([0.2, -0.1, 0.3]) @ axes10,
                3: np.array([0.3 * math.cos(math.radians(40.0)), 0.3 * math.sin(math.radians(40.0)), 0.25])}
    local = {1: x_global[1] * 1000, 2: (x_global[2] * 1000 - origin10) @ axes10.T, 3: np.array([300.0, 40.0, 250.0])}
    frames = {1: np.eye(3), 2: axes10,
              3: np.array([[math.cos(math.radians(40.0)), math.sin(math.radians(40.0)), 0.0],
                           [-math.sin(math.radians(40.0)), math.cos(math.radians(40.0)), 0.0], [0.0, 0.0, 1.0]])}
    stored = {g: frames[g] @ U[g] * 1000 for g in U}  # local components, mm
    x = np.linspace(1.0, 50.0, 8)
    path = _write(tmp_path / "testlab.uff", [
        _units(length=1000.0, force=1.0, code=9),
        _systems2420([10, 11], [0, 1], [axes10, np.eye(3)], [origin10, np.zeros(3)]),
        _node_set([1, 2, 3], [local[1], local[2], local[3]], [0, 10, 11], [0, 10, 11]),
        *[_mode(k + 1, 10.0 * (k + 1), [1, 2, 3], [stored[g][:, k] for g in (1, 2, 3)]) for k in range(2)],
        _frf((2, 3), (1, 3), x, np.full(8, 2.0 + 1.0j)),
    ])
    return path, x_global, frames


def test_testlab_local_systems_give_global_coordinates_and_directions(tmp_path):
    path, x_global, frames = _testlab(tmp_path)
    data = read_uff(path)
    for g, x in x_global.items():
        np.testing.assert_allclose(data["nodes"][g], x, rtol=0, atol=1e-12)
    modes = data["modes"]
    assert len(modes.sensors) == 9
    for s, (g, d) in enumerate(zip(modes.sensors.nodes, modes.sensors.directions)):
        # a sensor along the global direction d reads d · u: the stored local component
        np.testing.assert_allclose(modes.shapes[s], d @ U[int(g)], rtol=0, atol=1e-5)
        assert np.any(np.all(np.isclose(np.abs(frames[int(g)]), np.abs(d), atol=1e-12), axis=1))
    assert not np.allclose(modes.sensors.directions[3:6], np.eye(3))  # node 2's axes are rotated
    frf = read_uff(path)["frfs"]
    np.testing.assert_allclose(frf.outputs.directions[0], frames[2][2], atol=1e-12)
    np.testing.assert_allclose(frf.inputs.directions[0], [0.0, 0.0, 1.0])
    assert data["systems"][10]["type"] == "rectangular" and data["systems"][11]["type"] == "cylindrical"
    np.testing.assert_allclose(data["systems"][10]["origin"], [0.1, 0.05, 0.0])


def test_dataset_18_systems_chain_through_their_reference_systems(tmp_path):
    """System 5 is defined in system 4 (a 90° turn about z, origin (1, 0, 0) m), which is
    defined in global; a point (1, 0, 0) of system 5 and its x direction."""
    def cs(num, ref, origin, xpt, xzpt, kind=0):
        return num, kind, ref, np.asarray(origin, float), np.asarray(xpt, float), np.asarray(xzpt, float)

    rows = [cs(5, 4, [0, 1, 0], [0, 2, 0], [0, 1, 1]), cs(4, 0, [1, 0, 0], [1, 1, 0], [1, 0, 1])]
    record = {"type": 18, "cs_num": [r[0] for r in rows], "cs_type": [r[1] for r in rows],
              "ref_cs_num": [r[2] for r in rows], "color": [0, 0], "method": [1, 1], "cs_name": ["five", "four"],
              "ref_o": [r[3] for r in rows], "x_point": [r[4] for r in rows], "xz_point": [r[5] for r in rows]}
    path = _write(tmp_path / "cs18.uff", [
        _units(code=1), record, _node_set([7], [[1.0, 0.0, 0.0]], [5], [5]),
        _mode(1, 5.0, [7], [[1.0, 0.0, 0.0]]),
    ])
    data = read_uff(path)
    # system 4: x = global +y, origin (1, 0, 0); system 5 in 4: origin (0, 1, 0)₄ = (0, 0, 0), x = 4's +y = global −x
    np.testing.assert_allclose(data["systems"][5]["axes"][0], [-1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(data["nodes"][7], [-1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(data["modes"].sensors.directions, [[-1.0, 0.0, 0.0]], atol=1e-12)


def test_identity_system_one_gives_no_warning_and_undefined_systems_are_named(tmp_path):
    # BARC/Salome: system 1 is the global system, written out: read without a warning
    # (the suite turns warnings into errors)
    path = _write(tmp_path / "barc.uff", [
        _units(code=1), _systems2420([1], [0], [np.eye(3)], [np.zeros(3)]),
        _node_set([1, 2], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [1, 1], [1, 1], kind=2411),
        _mode(1, 5.0, [1, 2], [[0, 0, 1.0], [0, 0, 2.0]]),
    ])
    data = read_uff(path)
    assert data["modes"].sensors.labels == ["1+Z", "2+Z"]
    missing = _write(tmp_path / "missing.uff", [
        _units(code=1), _node_set([1, 2], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [0, 3], [0, 3]),
    ])
    with pytest.warns(UserWarning, match=re.escape("taken as global: system 3: nodes [2]")):
        read_uff(missing)


def test_bad_systems_are_named(tmp_path):
    skew = np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    path = _write(tmp_path / "skew.uff", [_units(code=1), _systems2420([3], [0], [skew], [np.zeros(3)])])
    with pytest.raises(ValueError, match=r"dataset #2: coordinate system 3: rows 1-3 of the matrix .* are not "
                                         "orthonormal"):
        read_uff(path)
    twice = _write(tmp_path / "twice.uff", [_units(code=1), _systems2420([3], [0], [np.eye(3)], [np.zeros(3)]),
                                            _systems2420([3], [0], [_rz(10.0)], [np.zeros(3)])])
    with pytest.raises(ValueError, match="coordinate system 3 of dataset #3 differs from dataset #2"):
        read_uff(twice)


def test_length_units_given_for_a_file_without_dataset_164(tmp_path):
    path = _write(tmp_path / "cm.uff", [_nodes([1, 2], [[0.0, 0.0, 0.0], [250.0, 0.0, 10.0]]),
                                       _mode(1, 5.0, [1, 2], [[0, 0, 1.0], [0, 0, 2.0]])])
    data = read_uff(path, length_units="cm")
    np.testing.assert_allclose(data["nodes"][2], [2.5, 0.0, 0.1])
    assert data["units"]["declared"] is False and data["units"]["length"] == 100.0
    with pytest.raises(ValueError, match="length units 'ft'"):
        read_uff(path, length_units="ft")
    declared = _write(tmp_path / "mm.uff", [_units(length=1000.0, code=9), _nodes([1], [[500.0, 0.0, 0.0]])])
    with pytest.warns(UserWarning, match="lengths taken in cm as given instead"):
        assert read_uff(declared, length_units="cm")["nodes"][1][0] == pytest.approx(5.0)


def test_testlab_file_with_rotated_systems_correlates_through_the_cli(tmp_path):
    """Triaxial sensors at plate grids, each node's coordinates and components in its own
    rotated system (2420, mm): read in global axes the model's own modes pair with MAC 1;
    the same numbers taken as global components (the systems ignored) do not."""
    import json

    from typer.testing import CliRunner

    import jaxfem
    from benchmarks.shell_models import plate
    from jaxfem.io import read_bdf_text
    from updating.report._shape_view import grid_translations
    from updating.cli import app

    text = plate(1.0, 0.8, 8, 8, "PSHELL,1,1,0.01,1,,1\nMAT1,1,70.E9,,0.3,2700.", bc="free")
    (tmp_path / "plate.bdf").write_text(text)
    model = jaxfem.build_model(read_bdf_text(text))
    lam, phi = jaxfem.modes(model, 12)
    u = grid_translations(model, np.asarray(phi))[:, :, 6:]  # (n_grid, 3, 6) elastic modes
    grids = [11, 15, 23, 30, 34, 41, 47, 52, 60, 66, 71, 78]
    rows = model.node_index(grids)
    labels = [10 + k for k in range(len(grids))]
    axes = [_ry(7.0 * k) @ _rz(25.0 * k) for k in range(len(grids))]
    origins_mm = [np.array([10.0 * k, -5.0 * k, 3.0]) for k in range(len(grids))]
    local_xyz = [(np.asarray(model.xyz)[r] * 1000 - o) @ a.T for r, a, o in zip(rows, axes, origins_mm)]
    stored = [a @ u[r] * 1000 for r, a in zip(rows, axes)]  # (3, modes) local components, mm
    f = np.asarray(jaxfem.frequencies_hz(lam))[6:]

    def write(path, systems: bool):
        cs = labels if systems else [0] * len(grids)
        sets = [_units(length=1000.0, force=1.0, code=9)]
        if systems:
            sets.append(_systems2420(labels, [0] * len(labels), axes, origins_mm))
        xyz = local_xyz if systems else [np.asarray(model.xyz)[r] * 1000 for r in rows]
        sets.append(_node_set(grids, xyz, cs, cs, kind=2411))
        sets += [_mode(k + 1, f[k], grids, [s[:, k] for s in stored]) for k in range(len(f))]
        return _write(path, sets)

    runner = CliRunner()
    macs = {}
    for systems in (True, False):
        path = write(tmp_path / f"testlab_{systems}.uff", systems)
        out = tmp_path / f"c_{systems}.json"
        result = runner.invoke(app, ["correlate", str(tmp_path / "plate.bdf"), str(path), "--json", str(out)])
        assert result.exit_code == 0, result.output
        data = json.loads(out.read_text())
        macs[systems] = [p["mac"] for p in data["paired_modes"]]
        if systems:
            assert data["test_geometry"]["method"] == "id"  # coordinates transformed onto the grids
            assert data["test_geometry"]["worst_distance_m"] < 1e-9
    assert len(macs[True]) == 6 and min(macs[True]) > 1 - 1e-6
    assert min(macs[False], default=0.0) < 0.99 or len(macs[False]) < 6


def test_time_channels_in_local_systems_are_named(tmp_path):
    from test_uff_time import time_record, write_records

    t = np.arange(64) / 1024.0
    path = write_records(tmp_path / "local_time.uff", [
        _units(code=1), _systems2420([4], [0], [_rz(30.0)], [np.zeros(3)]),
        _node_set([1, 2], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [0, 0], [0, 4], kind=2411),
        time_record("F", 1, 3, "force", t, np.sin(t)), time_record("A", 2, 1, "acceleration", t, np.cos(t)),
    ])
    with pytest.warns(UserWarning, match=re.escape("time channels at nodes [2] measure along the local axes")):
        assert read_uff(path)["time"].nodes.tolist() == [1, 2]


def test_datasets_that_hold_data_but_are_not_read_are_named(tmp_path):
    results = {"type": 2414, "analysis_dataset_label": 1, "analysis_dataset_name": "Mode shape record 1",
               "dataset_location": 1, "id1": "NONE", "id2": "NONE", "id3": "NONE", "id4": "NONE", "id5": "NONE",
               "model_type": 1, "analysis_type": 2, "data_characteristic": 2, "result_type": 8, "data_type": 2,
               "number_of_data_values_for_the_data_component": 3, "design_set_id": 1, "iteration_number": 0,
               "solution_set_id": 1, "boundary_condition": 0, "load_set": 1, "mode_number": 1,
               "time_step_number": 0, "frequency_number": 0, "creation_option": 0, "number_retained": 0,
               "time": 0.0, "frequency": 12.5, "eigenvalue": 6168.5, "modal_mass": 1.0, "viscous_damping": 0.0,
               "hysteretic_damping": 0.0, "real_part_eigenvalue": 0.0, "imaginary_part_eigenvalue": 0.0,
               "real_part_of_modal_A_or_modal_mass": 0.0, "imaginary_part_of_modal_A_or_modal_mass": 0.0,
               "real_part_of_modal_B_or_modal_mass": 0.0, "imaginary_part_of_modal_B_or_modal_mass": 0.0,
               "node_nums": np.array([1, 2]), "data_at_node": [np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 2.0])]}
    path = _write(tmp_path / "results.uff", [_units(code=1), _nodes([1, 2], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]),
                                             results])
    with pytest.warns(UserWarning, match=re.escape("datasets not read, ignored: type 2414 (#3)")):
        assert read_uff(path)["modes"] is None
