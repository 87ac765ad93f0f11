"""Test geometry onto the model: test nodes keep their ids, units checked, frames aligned.

The test files mimic an ARTeMIS Modal export (nodes in dataset 15 in cm, trace lines 82,
elements 2412, complex modes 55, no units dataset 164) and are written record by record
with pyuff; the "measured" shapes are the model's own modes read at the test points by
its shell shape functions, so interpolated mapping must pair them with MAC 1.
"""

import json
import math
import re

import numpy as np
import pytest
import pyuff
from typer.testing import CliRunner

import jaxfem
from benchmarks.shell_models import plate
from identification import map_test_geometry
from jaxfem.io import read_bdf_text
from updating import aliasing
from updating.cli import app

runner = CliRunner()
PROPS = "PSHELL,1,1,0.01,1,,1\nMAT1,1,70.E9,,0.3,2700."
A, B = 1.0, 0.8
# test points on the plate, off the 8 × 8 grid (own ids 1..12)
POINTS = np.array([[0.07, 0.05, 0.0], [0.33, 0.06, 0.0], [0.61, 0.04, 0.0], [0.93, 0.07, 0.0],
                   [0.06, 0.41, 0.0], [0.36, 0.38, 0.0], [0.66, 0.43, 0.0], [0.94, 0.39, 0.0],
                   [0.05, 0.74, 0.0], [0.31, 0.77, 0.0], [0.64, 0.72, 0.0], [0.95, 0.76, 0.0]])
N_MODES = 6


@pytest.fixture(scope="module")
def plate_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("geometry")
    text = plate(A, B, 8, 8, PROPS, bc="free")
    (root / "plate.bdf").write_text(text)
    model = jaxfem.build_model(read_bdf_text(text))
    lam, phi = jaxfem.modes(model, 6 + N_MODES)
    f = np.asarray(jaxfem.frequencies_hz(lam))[6:]  # the elastic modes
    sm = jaxfem.locate_sensors(model, POINTS, [3] * len(POINTS), "interpolate")
    shapes = np.asarray(sm.observe(phi))[:, 6:]
    return root, model, f, shapes


def _artemis(path, xyz_cm, shapes, f, zeta=0.01, ids=None):
    """15 (cm) + 82 + 2412 + complex 55 (z only), no 164: an ARTeMIS-style export."""
    ids = np.arange(1, len(xyz_cm) + 1) if ids is None else np.asarray(ids)
    zeros = np.zeros(len(ids), dtype=int)
    sets = [{"type": 15, "node_nums": ids, "def_cs": zeros, "disp_cs": zeros, "color": zeros,
             "x": xyz_cm[:, 0], "y": xyz_cm[:, 1], "z": xyz_cm[:, 2]},
            {"type": 82, "trace_num": 1, "n_nodes": 4, "color": 1, "id": "edge", "nodes": ids[:4].astype(float)},
            {"type": 2412, 11: [{"element_nums": 1, "fe_descriptor": 11, "phys_table": 1, "mat_table": 1,
                                 "color": 1, "num_nodes": 2, "beam_orientation": 0, "beam_foreend_cross": 0,
                                 "beam_aftend_cross": 0, "nodes_nums": [int(ids[0]), int(ids[1])]}]}]
    for k in range(len(f)):
        omega = 2 * math.pi * f[k]
        psi = shapes[:, k] * (1 + 0.0j)
        sets.append({"type": 55, "model_type": 1, "analysis_type": 3, "data_ch": 2, "spec_data_type": 8,
                     "load_case": 1, "mode_n": k + 1, "eig": omega * complex(-zeta, math.sqrt(1 - zeta**2)),
                     "modal_a": 0j, "modal_b": 0j, "node_nums": ids, "r1": 0 * psi, "r2": 0 * psi, "r3": psi})
    pyuff.UFF(str(path)).write_sets(sets, mode="overwrite")
    return path


def _correlate(root, test, *extra):
    out = root / "c.json"
    result = runner.invoke(app, ["correlate", str(root / "plate.bdf"), str(test), "--json", str(out), *extra])
    return result, (json.loads(out.read_text()) if result.exit_code == 0 else None)


def test_artemis_file_in_cm_stops_with_the_units_that_fit_then_maps_by_interpolation(plate_files):
    root, model, f, shapes = plate_files
    test = _artemis(root / "artemis.uff", POINTS * 100, shapes, f)
    result, _ = _correlate(root, test)
    assert result.exit_code == 2
    assert "the file's lengths are in cm (--test-units cm)" in result.output
    assert "100×" in result.output or "100x" in result.output or "near 100" in result.output
    result, data = _correlate(root, test, "--test-units", "cm", "--map", "interpolate")
    assert result.exit_code == 0, result.output
    geometry = data["test_geometry"]
    assert geometry["method"] == "interpolate"
    xyz = np.array([n["xyz_m"] for n in geometry["nodes"]])
    np.testing.assert_allclose(xyz, POINTS, rtol=0, atol=1e-6)  # dataset 15 is single precision
    assert [n["test_node"] for n in geometry["nodes"]] == list(range(1, 13))  # test ids kept
    assert geometry["worst_distance_m"] < 1e-6
    assert all(n["reads"].startswith("CQUAD4") for n in geometry["nodes"])
    pairs = data["paired_modes"]
    assert len(pairs) == N_MODES
    assert min(p["mac"] for p in pairs) > 1 - 1e-6
    np.testing.assert_allclose([p["f_model_hz"] for p in pairs], [p["f_test_hz"] for p in pairs], rtol=1e-5)
    assert "test geometry: 12 test nodes mapped by interpolate" in result.output
    # the nearest grid instead: same pairs, MAC lower, distances up to half a grid diagonal
    result, near = _correlate(root, test, "--test-units", "cm")
    assert result.exit_code == 0, result.output
    assert near["test_geometry"]["method"] == "nearest"
    assert "coordinates differ from the model grids of the same ids" in near["test_geometry"]["note"]
    assert 0.01 < near["test_geometry"]["worst_distance_m"] <= math.hypot(A / 16, B / 16) + 1e-9
    assert len(near["paired_modes"]) == N_MODES
    assert min(p["mac"] for p in near["paired_modes"]) < 1 - 1e-4


def test_test_ids_that_are_model_grids_elsewhere_get_new_grids(plate_files):
    root, model, f, shapes = plate_files
    test = _artemis(root / "clash.uff", POINTS, shapes, f, ids=np.arange(1, 13) + 20)  # model grids 21..32
    result, data = _correlate(root, test, "--map", "interpolate")
    assert result.exit_code == 0, result.output
    assert [n["grid"] for n in data["test_geometry"]["nodes"]] == list(range(121, 133))  # model grids 1..81
    assert "test nodes whose ids are model grids elsewhere read as new grids: 21 → 121, 22 → 122" in result.output
    assert min(p["mac"] for p in data["paired_modes"]) > 1 - 1e-6


def test_implausible_distances_are_refused_naming_the_override(plate_files):
    root, model, f, shapes = plate_files
    lifted = POINTS + [0.0, 0.0, 0.2]  # 20 cm above the plate: 16 % of its size, 2 grid spacings
    test = _artemis(root / "lifted.uff", lifted, shapes, f)
    result, _ = _correlate(root, test, "--map", "interpolate")
    assert result.exit_code == 2
    assert re.search(r"12 test node\(s\) lie farther than 0.15 m from the model \(the larger of 5 % of its size, 1.28 m, and 1.5 "
                     r"median grid spacings, 0.1 m\).* --max-distance", result.output)
    result, data = _correlate(root, test, "--map", "interpolate", "--max-distance", "0.25")
    assert result.exit_code == 0, result.output
    assert 0.2 < data["test_geometry"]["worst_distance_m"] <= math.hypot(0.2, A / 16, B / 16) + 1e-9
    assert "read the nearest grid instead (too far from every shell element)" in result.output


def test_align_moves_a_rotated_and_shifted_test_frame_onto_the_model(plate_files):
    _, model, _, _ = plate_files
    grids = [11, 15, 30, 34, 47, 52, 60, 66, 78]  # test nodes at these model grids, in a turned frame
    p = np.asarray(model.xyz)[model.node_index(grids)]
    c, s = math.cos(math.radians(3.0)), math.sin(math.radians(3.0))
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    t = np.array([0.02, -0.015, 0.01])
    test_xyz = (p - t) @ R  # the test frame: p = R q + t
    nodes = {100 + k: x for k, x in enumerate(test_xyz)}
    _, gmap = map_test_geometry(model, nodes, method="nearest", align_frames=True, max_distance=1.0)
    a = gmap.alignment
    np.testing.assert_allclose(a["rotation"], R, atol=1e-10)
    np.testing.assert_allclose(a["translation"], t, atol=1e-10)
    assert a["rms_after"] < 1e-10 < a["rms_before"]
    assert gmap.reads == tuple(f"grid {g}" for g in grids)
    np.testing.assert_allclose(gmap.distance, 0.0, atol=1e-10)


def test_aliasing_names_the_modes():
    x = np.linspace(0.0, 1.0, 4)
    phi_e = np.column_stack([np.sin(np.pi * x), np.sin(np.pi * x) + 0.05 * x, np.cos(3 * np.pi * x)])
    phi_a = np.column_stack([phi_e[:, 0], phi_e[:, 2], np.sin(np.pi * x) + 0.1])
    lines = aliasing(phi_a, phi_e, np.array([10.0, 20.0, 30.0]))
    assert any(line.startswith("test modes 1 and 2 have AutoMAC") for line in lines)
    assert any(re.match(r"test mode 1 has MAC ≥ 0.65 with 2 model modes \(1 \(10 Hz\) MAC 1.00, 3 \(30 Hz\)", line)
               for line in lines)
    assert not any("test mode 3" in line for line in lines)
    # with frequencies, a look-alike far outside twice the pairing window does not count
    lines = aliasing(phi_a, phi_e, np.array([10.0, 20.0, 30.0]), np.array([10.0, 10.5, 20.0]))
    assert not any(line.startswith("test mode 1 has") for line in lines)
    with pytest.raises(ValueError, match="max_automac"):
        aliasing(phi_a, phi_e, max_automac=1.5)


@pytest.mark.slow(seconds=80)
def test_diagnose_finds_a_hidden_mass_through_test_nodes_of_their_own(tmp_path):
    """The truth carries 0.5 kg at the plate's centre grid 41; the test file (cm, own node
    ids, no units dataset) is read at its points by interpolation: the diagnosis must
    name the mass there, and the held-out error fall."""
    text = plate(A, B, 8, 8, PROPS, bc="free")
    (tmp_path / "plate.bdf").write_text(text)
    truth = jaxfem.build_model(read_bdf_text(text.replace("ENDDATA", "") + "\nCONM2,9001,41,,0.5\n"))
    lam, phi = jaxfem.modes(truth, 14)
    f = np.asarray(jaxfem.frequencies_hz(lam))[6:]
    shapes = np.asarray(jaxfem.locate_sensors(truth, POINTS, [3] * len(POINTS), "interpolate").observe(phi))[:, 6:]
    test = _artemis(tmp_path / "test.uff", POINTS * 100, shapes, f)
    out = tmp_path / "d.json"
    result = runner.invoke(app, ["diagnose", str(tmp_path / "plate.bdf"), str(test), "--json", str(out),
                                 "--test-units", "cm", "--map", "interpolate"])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    best = data["effects"][0]
    assert data["outcome"] == "effect" and best["warranted"]
    assert best["kind"] == "added_mass" and best["where"] == "node 41"
    assert data["test_geometry"]["worst_distance_m"] < 1e-6
    after = data["after"]
    assert after["rms_freq_dev_pct_passive_after"] < 0.05 < after["rms_freq_dev_pct_passive_before"]


def test_correlate_warns_of_spatial_aliasing_with_too_few_sensors(plate_files):
    root, model, f, shapes = plate_files
    few = [0, 3, 9]  # three corners: six modes cannot be told apart
    test = _artemis(root / "few.uff", POINTS[few], shapes[few], f)
    result, data = _correlate(root, test, "--map", "interpolate")
    assert result.exit_code == 0, result.output
    auto = np.array(data["automac"])
    i, j = np.unravel_index(np.argmax(np.triu(auto, k=1)), auto.shape)
    assert auto[i, j] > 0.9
    assert f"warning: test modes {i + 1} and {j + 1} have AutoMAC {auto[i, j]:.2f} > 0.90" in result.output
    assert any("spatial aliasing" in line for line in data["aliasing"])
    assert any(re.match(r"test mode \d+ has MAC ≥ 0.65 with \d model modes", line) for line in data["aliasing"])


def test_sensors_on_a_beam_surface_see_torsion_through_the_rigid_link(tmp_path):
    """Jim-Beam-like: a free-free bar, test nodes of their own on its top face at both
    edges (ARTeMIS style, cm, no dataset 164), measuring z. Nearest-grid mapping links each
    node rigidly to its grid (u_z + θx·y), so the torsion modes are seen and pair with MAC 1."""
    n, length, w, h = 12, 1.2, 0.05, 0.02
    lines = [f"GRID,{i + 1},,{length * i / n:.6f},0.,0." for i in range(n + 1)]
    lines += [f"CBAR,{i + 1},1,{i + 1},{i + 2},0.,0.,1." for i in range(n)]
    torsion = w * h**3 * (1 / 3 - 0.21 * h / w * (1 - h**4 / (12 * w**4)))  # rectangle, Roark
    lines += [f"PBAR,1,1,{w * h:.6e},{w * h**3 / 12:.6e},{h * w**3 / 12:.6e},{torsion:.6e}",
              "MAT1,1,210.E9,,0.3,7850.", "PARAM,COUPMASS,1", "ENDDATA"]
    (tmp_path / "beam.bdf").write_text("\n".join(lines) + "\n")
    model = jaxfem.build_model(read_bdf_text("\n".join(lines)))
    lam, phi = jaxfem.modes(model, 16)
    phi = np.asarray(phi)[:, 6:]
    stations = [1, 3, 5, 7, 9, 11, 13]
    labels = [tuple(x) for x in np.asarray(model.dofs.labels).tolist()]
    uz = phi[[labels.index((g, 3)) for g in stations]]
    rx = phi[[labels.index((g, 4)) for g in stations]]
    xyz, values = [], []
    for side in (-1.0, 1.0):
        for k, g in enumerate(stations):
            xyz.append(np.asarray(model.xyz)[g - 1] + [0.0, side * w / 2, h / 2])
            values.append(uz[k] + rx[k] * side * w / 2)  # (θ × d)_z = θx d_y − θy d_x, d_x = 0
    values = np.array(values)
    seen = np.linalg.norm(values, axis=0) > 1e-3 * np.linalg.norm(values, axis=0).max()
    f = np.asarray(jaxfem.frequencies_hz(lam))[6:][seen]
    twist = np.flatnonzero(np.linalg.norm(rx, axis=0)[seen] * w > np.linalg.norm(uz, axis=0)[seen])
    assert len(twist) >= 1  # a torsion mode among the measured ones
    test = _artemis(tmp_path / "jim.uff", np.array(xyz) * 100, values[:, seen], f, ids=np.arange(101, 115))
    result = runner.invoke(app, ["correlate", str(tmp_path / "beam.bdf"), str(test), "--json",
                                 str(tmp_path / "c.json"), "--test-units", "cm", "-n", "24"])
    assert result.exit_code == 0, result.output
    data = json.loads((tmp_path / "c.json").read_text())
    assert data["test_geometry"]["method"] == "nearest"
    assert data["test_geometry"]["worst_distance_m"] == pytest.approx(math.hypot(w / 2, h / 2), rel=1e-6)
    pairs = {p["test"]: p for p in data["paired_modes"]}
    assert len(pairs) == int(seen.sum())
    assert all(pairs[j + 1]["mac"] > 1 - 1e-6 for j in twist)
    assert min(p["mac"] for p in pairs.values()) > 1 - 1e-6


def test_a_model_in_mm_t_s_reads_the_test_geometry_in_its_length_unit(plate_files, tmp_path):
    """The plate written in mm–t–s: with --units mm-t-s the test points (m in the file) map
    onto it as onto the SI plate: same reads, distances and pairs, reported in m."""
    root, model, f, shapes = plate_files
    test = _artemis(root / "artemis_mm.uff", POINTS * 100, shapes, f)
    (tmp_path / "plate.bdf").write_text(plate(A * 1000, B * 1000, 8, 8, "PSHELL,1,1,10.,1,,1\nMAT1,1,70.E3,,0.3,2.7-9",
                                              bc="free"))
    args = ["--test-units", "cm", "--map", "interpolate"]
    result, si = _correlate(root, test, *args)
    assert result.exit_code == 0, result.output
    result, mm = _correlate(tmp_path, test, *args, "--units", "mm-t-s")
    assert result.exit_code == 0, result.output
    for a, b in zip(si["test_geometry"]["nodes"], mm["test_geometry"]["nodes"]):
        assert a["reads"] == b["reads"]
        np.testing.assert_allclose(a["xyz_m"], b["xyz_m"], atol=1e-9)
    np.testing.assert_allclose([p["f_model_hz"] for p in mm["paired_modes"]],
                               [p["f_model_hz"] for p in si["paired_modes"]], rtol=1e-9)
