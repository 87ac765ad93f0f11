"""The ``correlate`` and ``update`` commands: JSON, tables, plots and input errors.

The test data are modes of the 3×3×3 benchmark frame with two stiffness groups off by
+15 % and −10 %, written to a universal file (dataset 55 keeps 6 significant digits, so
the recovered factors carry a data error of a few 1e-6).
"""

import json

import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

import jaxfem
from benchmarks.frames import frame_bdf
from identification import FRFData, ModalData, Sensors, observation_matrix, read_uff, write_uff
from jaxfem.io import read_bdf
from updating import n_model_modes, pair_modes, predict_frf
from updating._parameters import Parameter, ParameterSet, parameterise
from updating.report._plots import plot_freq_dev, plot_mac
from updating.cli import app

runner = CliRunner()
PIDS = (1, 4)
TRUE_ALPHA = (0.15, -0.10)
N_TEST = 8

PARAMS_TOML = """
[[parameter]]
name = "columns"
kind = "stiffness"
pids = [1]
bounds = [-0.5, 0.5]

[[parameter]]
name = "beams"
kind = "stiffness"
pids = [4]

[options]
tolerance = 1e-8
"""


def _nodes(model) -> dict:
    return {int(g): np.asarray(x) for g, x in zip(model.node_ids, model.xyz)}


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """``(dir, model.bdf, test.uff, nominal model)``; X and Y sensors on every free grid."""
    d = tmp_path_factory.mktemp("cli_updating")
    bdf = d / "frame.bdf"
    bdf.write_text(frame_bdf(3, 3, 3, n_groups=6))
    model = jaxfem.build_model(read_bdf(bdf))
    params = ParameterSet(tuple(Parameter(f"p{p}", "stiffness", pids=(p,)) for p in PIDS))
    base, par = parameterise(model, params)
    truth = par.apply(base, jnp.log1p(jnp.asarray(TRUE_ALPHA)))
    lam, phi = jaxfem.eigh(*jaxfem.assemble(truth), N_TEST)
    nodes = np.asarray(model.node_ids[9:])  # above the clamped base
    sensors = Sensors.from_components(np.repeat(nodes, 2), np.tile([1, 2], nodes.size))
    C, _ = observation_matrix(model, sensors)
    test = ModalData(np.asarray(jaxfem.frequencies_hz(lam)), C @ np.asarray(phi), sensors)
    uff = d / "test.uff"
    write_uff(uff, nodes=_nodes(model), modes=test)
    # Measured FRFs of the truth (1 % modal damping, the CLI's default without test damping).
    out, inp = Sensors.from_components([14, 27], [1, 2]), Sensors.from_components([27], [2])
    freqs = np.linspace(5.0, 60.0, 111)
    probe = FRFData(freqs, np.zeros((111, 2, 1)), out, inp, "receptance")
    frf = FRFData(freqs, predict_frf(truth, probe, zeta=0.01), out, inp, "receptance")
    write_uff(d / "frf.uff", nodes=_nodes(model), frfs=frf)
    return d, bdf, uff, model


def _pngs_written(folder, names):
    for name in names:
        png = folder / name
        assert png.is_file() and png.stat().st_size > 0, png
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_correlate_json_matches_library_and_plots(case):
    d, bdf, uff, model = case
    out, plots = d / "correlate.json", d / "correlate_plots"
    result = runner.invoke(app, ["correlate", str(bdf), str(uff), "--json", str(out), "--plots", str(plots)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    for key in ("paired_modes", "unpaired_test", "unpaired_model", "warnings", "automac", "comac",
                "rms_freq_dev_pct", "mean_mac"):
        assert key in data, key

    # The same correlation through the library.
    test = read_uff(uff)["modes"]
    C, _ = observation_matrix(model, test.sensors)
    lam, phi = jaxfem.eigh(*jaxfem.assemble(model), n_model_modes(model, N_TEST))
    p = pair_modes(np.asarray(jaxfem.frequencies_hz(lam)), C @ np.asarray(phi),
                   test.frequencies_hz, test.shapes, min_mac=0.65, max_freq_dev=0.30)
    rows = data["paired_modes"]
    assert [r["test"] for r in rows] == (p.test + 1).tolist()
    assert [r["model"] for r in rows] == (p.model + 1).tolist()
    np.testing.assert_allclose([r["freq_dev_pct"] for r in rows], 100 * p.freq_dev, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose([r["mac"] for r in rows], p.mac, rtol=1e-9)
    np.testing.assert_allclose([r["f_test_hz"] for r in rows], test.frequencies_hz, rtol=1e-12)
    assert len(rows) == N_TEST and data["unpaired_test"] == [] and data["warnings"] == []
    assert len(data["unpaired_model"]) == n_model_modes(model, N_TEST) - N_TEST
    np.testing.assert_allclose(data["rms_freq_dev_pct"], np.sqrt(np.mean((100 * p.freq_dev) ** 2)), rtol=1e-9)
    np.testing.assert_allclose(data["mean_mac"], np.mean(p.mac), rtol=1e-9)

    auto = np.asarray(data["automac"])
    assert auto.shape == (N_TEST, N_TEST)
    np.testing.assert_allclose(np.diag(auto), 1.0, rtol=1e-12)
    comac = [c["value"] for c in data["comac"]]
    assert len(comac) == len(test.sensors) and comac == sorted(comac)
    assert {c["sensor"] for c in data["comac"]} == set(test.sensors.labels)

    assert "Δf [%]" in result.output and "COMAC" in result.output and "AutoMAC" in result.output
    _pngs_written(plots, ["mac.png", "freq_dev.png"])


def test_update_recovers_injected_factors(case):
    d, bdf, uff, _ = case
    toml = d / "params.toml"
    toml.write_text(PARAMS_TOML)
    out, plots = d / "update.json", d / "update_plots"
    result = runner.invoke(app, ["update", str(bdf), str(uff), "--params", str(toml), "--json", str(out),
                                 "--plots", str(plots), "--frf", str(d / "frf.uff")])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["converged"] is True
    names = [p["name"] for p in data["parameters"]]
    assert names == ["columns", "beams"]
    np.testing.assert_allclose([p["alpha"] for p in data["parameters"]], TRUE_ALPHA, atol=1e-5)
    assert all(p["within_bounds"] for p in data["parameters"])
    assert data["parameters"][0]["bounds"] == [-0.5, 0.5] and data["parameters"][0]["kind"] == "stiffness"

    history = data["history"]
    assert len(history) == data["iterations"] + 1 and history[0]["iteration"] == 0
    assert set(history[-1]["alpha"]) == set(names)
    assert len(history[0]["freq_dev_pct"]) == N_TEST and len(history[0]["mac"]) == N_TEST
    assert history[-1]["cost"] < history[0]["cost"]
    assert history[-1]["rms_freq_dev_pct_active"] < 1e-2 and history[-1]["rms_freq_dev_pct_passive"] is None
    assert data["active_modes"] == list(range(1, N_TEST + 1)) and data["passive_modes"] == []
    assert data["before"]["rms_freq_dev_pct"] > 0.5
    assert data["after"]["rms_freq_dev_pct"] < 1e-2  # data carry 6 significant digits
    assert len(data["after"]["paired_modes"]) == N_TEST
    # The initial Δf of the history are those of the "before" pairing.
    np.testing.assert_allclose(history[0]["freq_dev_pct"],
                               [r["freq_dev_pct"] for r in data["before"]["paired_modes"]], rtol=1e-8)

    assert "iteration   1" in result.stderr and "max|Δα|" in result.stderr
    assert "active" in result.stdout and "converged" in result.stdout
    _pngs_written(plots, ["mac_before.png", "mac_after.png", "freq_dev.png", "convergence.png", "frf.png"])
    # Validation by prediction: the updated model reproduces the measured FRFs.
    frf = data["frf"]
    assert frf["zeta"] == 0.01 and len(frf["pairs"]) == 2
    for pair in frf["pairs"]:
        assert pair["frac_after"] > 0.999 > pair["frac_before"]
        assert pair["mean_abs_db_after"] < pair["mean_abs_db_before"]


@pytest.mark.parametrize(
    "text, named",
    [
        (PARAMS_TOML.replace('pids = [4]', 'pids = [4]\nstiffness_factor = 2.0'), "stiffness_factor"),
        (PARAMS_TOML.replace("tolerance = 1e-8", "tolerence = 1e-8"), "tolerence"),
        (PARAMS_TOML.replace('kind = "stiffness"\npids = [4]', 'kind = "stifness"\npids = [4]'), "stifness"),
        (PARAMS_TOML.replace("pids = [4]", "pids = [77]"), "77"),
    ],
)
def test_bad_toml_exits_2_naming_the_key(case, text, named):
    d, bdf, uff, _ = case
    toml = d / "bad.toml"
    toml.write_text(text)
    result = runner.invoke(app, ["update", str(bdf), str(uff), "--params", str(toml), "--json", str(d / "x.json")])
    assert result.exit_code == 2, result.output
    assert named in result.stderr and "Traceback" not in result.output
    assert len(result.stderr.strip().splitlines()) == 1


def test_unknown_sensor_node_exits_2_naming_the_node(case):
    d, bdf, _, model = case
    sensors = Sensors.from_components([10, 11, 4242], [1, 1, 2])
    test = ModalData([30.0, 40.0], np.array([[1.0, 0.2], [0.5, -1.0], [0.3, 0.4]]), sensors)
    uff = d / "unknown_node.uff"
    write_uff(uff, nodes={**_nodes(model), 4242: np.array([9.0, 9.0, 9.0])}, modes=test)
    toml = d / "ok.toml"
    toml.write_text(PARAMS_TOML)
    for args in (["correlate", str(bdf), str(uff), "--json", str(d / "x.json")],
                 ["update", str(bdf), str(uff), "--params", str(toml), "--json", str(d / "x.json")]):
        result = runner.invoke(app, args)
        assert result.exit_code == 2, result.output
        assert "4242" in result.stderr and "Traceback" not in result.output


def test_unreadable_files_exit_2(case, tmp_path):
    d, bdf, uff, _ = case
    bad_bdf = tmp_path / "bad.bdf"
    bad_bdf.write_text("GRID,1,,0.,0.,abc\n")
    no_modes = tmp_path / "empty.uff"
    write_uff(no_modes, nodes={1: np.zeros(3)})
    for args, named in (
        (["correlate", str(bad_bdf), str(uff), "--json", str(tmp_path / "x.json")], "bad.bdf:1"),
        (["correlate", str(bdf), str(no_modes), "--json", str(tmp_path / "x.json")], "dataset 55"),
        (["correlate", str(bdf), str(tmp_path / "missing.uff"), "--json", str(tmp_path / "x.json")], "missing.uff"),
    ):
        result = runner.invoke(app, args)
        assert result.exit_code == 2, result.output
        assert named in result.output and "Traceback" not in result.output


def test_plot_functions(tmp_path):
    dev = np.array([-1.5, np.nan, 2.0])
    path = plot_freq_dev(dev, np.array([0.1, 0.5, np.nan]), ["1", "2", "3"], tmp_path / "f.png",
                         active=[True, True, False])
    assert path == tmp_path / "f.png" and path.stat().st_size > 0
    with pytest.raises(ValueError, match="test labels"):
        plot_mac(np.eye(2), ["1", "2", "3"], ["1", "2"], tmp_path / "m.png")
