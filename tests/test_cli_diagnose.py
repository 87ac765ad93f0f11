"""``jaxfem diagnose`` and ``update --add-effect`` end to end: a frame whose truth has a
missing 25 kg mass, measured modes in a universal file with 0.2 %/1 % noise."""

import json

import numpy as np
from typer.testing import CliRunner

import jaxfem
from benchmarks.frames import frame_bdf
from identification import ModalData, Sensors, observation_matrix, write_uff
from jaxfem.io import read_bdf
from updating import Effect
from updating.cli import app

runner = CliRunner()
PARAMS = '[[parameter]]\nname = "g2"\nkind = "stiffness"\npids = [2]\n'


def _case(tmp_path):
    bdf = tmp_path / "frame.bdf"
    bdf.write_text(frame_bdf(2, 2, 4, n_groups=8))
    model = jaxfem.build_model(read_bdf(bdf))
    truth = Effect("added_mass", nodes=(14,), values={"m": 25.0}).apply(model)
    grids = list(range(5, 21))
    sensors = Sensors.from_components(np.repeat(grids, 2), np.tile([1, 2], len(grids)))
    lam, phi = jaxfem.modes(truth, 12)
    C, _ = observation_matrix(truth, sensors)
    rng = np.random.default_rng(3)
    f = np.asarray(jaxfem.frequencies_hz(lam)) * (1 + 0.002 * rng.standard_normal(12))
    shapes = np.asarray(C @ phi) * (1 + 0.01 * rng.standard_normal((len(sensors), 12)))
    uff = tmp_path / "test.uff"
    write_uff(uff, nodes={int(n): model.xyz[i] for i, n in enumerate(model.node_ids)}, modes=ModalData(f, shapes, sensors))
    params = tmp_path / "params.toml"
    params.write_text(PARAMS)
    return bdf, uff, params


def test_diagnose_finds_the_missing_mass_and_writes_json_and_report(tmp_path):
    bdf, uff, params = _case(tmp_path)
    out, report = tmp_path / "diagnosis.json", tmp_path / "report"
    result = runner.invoke(app, ["diagnose", str(bdf), str(uff), "--params", str(params),
                                 "--json", str(out), "--report", str(report)])
    assert result.exit_code == 0, result.output
    d = json.loads(out.read_text())
    best = d["effects"][0]
    assert (best["kind"], best["nodes"], best["pids"], best["eids"]) == ("added_mass", [14], [], [])
    assert abs(best["parameters"]["m"] - 25.0) < 2.5  # kg
    assert best["warranted"] and d["outcome"] == "effect" and best["score"] > 50 and best["posterior"] > 0.9
    assert best["heldout_rms_freq_dev_pct_after"] < 0.5 < best["heldout_rms_freq_dev_pct_before"]
    assert [g["pid"] for g in d["localisation"]["groups"]] and d["localisation"]["nodes"][0]["score"] <= 1.0
    assert d["paired_modes"][0].keys() >= {"test", "model", "f_test_hz", "f_model_hz", "mac"}
    after = d["after"]  # the confirmation update, every fourth mode from the third held out
    assert after["passive_modes"] == [3, 7, 11]
    assert after["rms_freq_dev_pct_passive_after"] < 0.5 * after["rms_freq_dev_pct_passive_before"]
    assert abs(after["effect"]["parameters"]["m"] - 25.0) < 2.5
    html = (report / "report.html").read_text()
    assert html.count("data:image/png;base64,") >= 7 and "added_mass" in html
    assert "Add 2" in result.output and "kg" in result.output and "at grid 14: held-out frequency error" in result.output


def test_update_add_effect(tmp_path):
    bdf, uff, params = _case(tmp_path)
    out = tmp_path / "upd.json"
    result = runner.invoke(app, ["update", str(bdf), str(uff), "--params", str(params), "--json", str(out),
                                 "--add-effect", "added_mass:node=14"])
    assert result.exit_code == 0, result.output
    d = json.loads(out.read_text())
    assert [p["name"] for p in d["parameters"]] == ["g2", "added_mass"]  # named by updating.add_effect
    # One schema for the iteration history of update and of add_effect's report.
    keys = {"iteration", "alpha", "freq_dev_pct", "mac", "cost", "rms_freq_dev_pct_active", "rms_freq_dev_pct_passive"}
    assert d["history"][-1].keys() == d["add_effect"]["history"][-1].keys() == keys
    assert d["history"][-1]["rms_freq_dev_pct_passive"] is None  # all modes active
    assert "added added_mass at node 14: starting values m = " in result.output
    assert d["after"]["rms_freq_dev_pct"] < 0.5 and d["converged"]
    bad = runner.invoke(app, ["update", str(bdf), str(uff), "--params", str(params), "--json", str(out),
                              "--add-effect", "added_mass:grid=14"])
    assert bad.exit_code == 2 and "--add-effect added_mass:grid=14" in bad.output
