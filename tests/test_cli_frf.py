"""``jaxfem frf`` (time histories → FRFs, coherence, plot) and ``--dof-map`` for
channel-only exports (node 0, direction 0), through the command line."""

import json

import numpy as np
from _frf_models import chain, modes, receptance
from test_uff_time import MM, accelerance, chain_records, synthesise, time_record, write_records
from typer.testing import CliRunner

from identification import read_uff
from updating.cli import app

runner = CliRunner()


def _periodic_file(path, *, nodes=(3, 1, 2, 3), fs=1024, zeta=0.02):
    x, y = synthesise(fs, 1024, 8, zeta, seed=1)
    return write_records(path, [MM, *chain_records(fs, x, y, scale=1000.0, nodes=nodes)])


def test_frf_writes_the_exact_accelerance_coherence_plot_and_summary(tmp_path):
    path = _periodic_file(tmp_path / "time.uff")
    res = runner.invoke(app, ["frf", str(path), "--force", "F3", "--window", "rect", "--blocks", "8",
                              "--out", str(tmp_path / "frf.uff"), "--plots", str(tmp_path / "plots"),
                              "--json", str(tmp_path / "frf.json")])
    assert res.exit_code == 0, res.output
    assert "fs 1024 Hz, 8192 samples (8 s); block 1024 samples (1 s), resolution 1 Hz, 8 averages (rect" in res.output
    assert ("responses (accelerance) A1 (1+Z, acceleration), A2 (2+Z, acceleration), A3 (3+Z, acceleration)"
            in res.output)
    assert "3+Z / 3+Z   1.000    1.000" in res.output
    frfs = read_uff(tmp_path / "frf.uff")["frfs"]
    assert frfs.kind == "accelerance" and frfs.outputs.labels == ["1+Z", "2+Z", "3+Z"] and frfs.inputs.labels == ["3+Z"]
    f = frfs.frequencies_hz
    np.testing.assert_array_equal(f, np.arange(1.0, 513.0))
    np.testing.assert_allclose(frfs.values[:-1, :, 0], accelerance(0.02, f[:-1]), rtol=1e-7)  # all but Nyquist
    np.testing.assert_allclose(frfs.coherence, 1.0, atol=1e-9)
    summary = json.loads((tmp_path / "frf.json").read_text())
    assert (summary["fs_hz"], summary["block_length"], summary["n_averages"]) == (1024.0, 1024, 8)
    assert summary["estimator"] == "H1" and summary["inputs"] == [{"channel": "F3 (3+Z, force)", "dof": "3+Z"}]
    assert min(row["min"] for row in summary["coherence"]) > 1 - 1e-9
    assert (tmp_path / "plots" / "coherence.png").stat().st_size > 20_000


def test_frf_maps_channel_only_records_and_selects_the_force_by_dof(tmp_path):
    path = _periodic_file(tmp_path / "time.uff", nodes=(0, 0, 0, 0))
    (tmp_path / "map.csv").write_text("channel,node,direction\nF3,103,+Z\nA1,101,-3\nA2,102,3\nA3,103,3\n")
    res = runner.invoke(app, ["frf", str(path), "--force", "103:+3", "--h2", "--window", "rect", "--out",
                              str(tmp_path / "frf.uff"), "--dof-map", str(tmp_path / "map.csv")])
    assert res.exit_code == 0, res.output
    frfs = read_uff(tmp_path / "frf.uff")["frfs"]
    assert frfs.outputs.labels == ["101-Z", "102+Z", "103+Z"] and frfs.inputs.labels == ["103+Z"]
    # the values are what each channel recorded; the map only says along which DoF (A1 as read along −Z)
    np.testing.assert_allclose(frfs.values[:-1, :, 0], accelerance(0.02, frfs.frequencies_hz[:-1]), rtol=1e-7)

    no_map = runner.invoke(app, ["frf", str(path), "--force", "F3", "--out", str(tmp_path / "x.uff")])
    assert no_map.exit_code == 2
    assert "no DoF (direction 0) for channel(s) 'F3', 'A1', 'A2', 'A3'" in no_map.output
    assert "--dof-map" in no_map.output
    (tmp_path / "short.csv").write_text("channel,node,direction\nF3,103,+Z\nA1,101,-3\nA3,103,3\n")
    short = runner.invoke(app, ["frf", str(path), "--force", "F3", "--out", str(tmp_path / "x.uff"),
                                "--dof-map", str(tmp_path / "short.csv")])
    assert short.exit_code == 2 and "channel(s) 'A2' have no DoF in the file" in short.output


def test_frf_errors_are_one_line(tmp_path):
    path = _periodic_file(tmp_path / "time.uff")
    out = ["--out", str(tmp_path / "frf.uff")]
    res = runner.invoke(app, ["frf", str(path), "--force", "F9", *out])
    assert res.exit_code == 2
    assert ("error: " + str(path) + ": no channel matches force 'F9'; the channels are: F3 (3+Z, force); "
            "A1 (1+Z, acceleration); A2 (2+Z, acceleration); A3 (3+Z, acceleration)") in res.output
    res = runner.invoke(app, ["frf", str(path), "--force", "A1", *out])
    assert res.exit_code == 2 and "matches A1 (1+Z, acceleration), not a force channel" in res.output
    res = runner.invoke(app, ["frf", str(path), "--force", "F3", "--window", "flattop", *out])
    assert res.exit_code == 2 and "--window 'flattop': hann | rect" in res.output

    t = np.arange(64) / 256.0
    mixed = write_records(tmp_path / "mixed.uff", [MM, time_record("F", 1, 3, "force", t, np.sin(t)),
                                                    time_record("A", 2, 3, "acceleration", 2 * t, np.cos(t))])
    res = runner.invoke(app, ["frf", str(mixed), "--force", "F", *out])
    assert res.exit_code == 2
    assert "dataset #3 (channel 'A') samples at 128 Hz" in res.output and "mixed sampling rates" in res.output

    runner.invoke(app, ["frf", str(path), "--force", "F3", "--window", "rect", *out])
    res = runner.invoke(app, ["frf", str(tmp_path / "frf.uff"), "--force", "F3", "--out", str(tmp_path / "o.uff")])
    assert res.exit_code == 2 and "holds FRFs (UFF 58, function type 4), not time histories" in res.output


def test_identify_says_to_make_frfs_from_time_histories(tmp_path):
    for nodes in ((3, 1, 2, 3), (0, 0, 0, 0)):  # with DoFs, and channel-only without a map
        path = _periodic_file(tmp_path / "time.uff", nodes=nodes)
        res = runner.invoke(app, ["identify", str(path), "--json", str(tmp_path / "modes.json")])
        assert res.exit_code == 2
        assert (f"error: {path} holds time histories (UFF 58, function type 1), not FRFs: make FRFs with "
                f"`jaxfem frf {path} --force ...`") in res.output


def _channel_only_frfs(path, f, h, names):
    """Receptance records (function type 4) with node 0, direction 0 and channel names."""
    records = [{"type": 58, "binary": 0, "func_type": 4, "id1": f"{name} / hammer", "rsp_ent_name": name,
                "rsp_node": 0, "rsp_dir": 0, "ref_ent_name": "hammer", "ref_node": 0, "ref_dir": 0,
                "abscissa_spacing": 1, "abscissa_spec_data_type": 18, "ordinate_spec_data_type": 8,
                "orddenom_spec_data_type": 13, "x": f, "data": h[:, o]} for o, name in enumerate(names)]
    return write_records(path, [{**MM, "units_code": 1, "units_description": "SI", "length": 1.0, "force": 1.0},
                                *records])


def test_identify_reads_channel_only_frfs_through_a_dof_map(tmp_path):
    M, K = chain([1.0, 1.2, 0.9, 1.1], [4e4, 3e4, 3e4, 2.5e4])
    zeta = [0.01, 0.015, 0.01, 0.02]
    f = np.arange(0.5, 100.0, 0.05)
    h = receptance(M, K, zeta, f, np.arange(4), [3])[:, :, 0]
    path = _channel_only_frfs(tmp_path / "frf.uff", f, h, ["acc1", "acc2", "acc3", "acc4"])
    rows = "".join(f"acc{k},{100 + k},+Z\n" for k in (1, 2, 3, 4))
    (tmp_path / "map.csv").write_text("channel,node,direction\n" + rows + "hammer,104,+Z\n")
    res = runner.invoke(app, ["identify", str(path), "--json", str(tmp_path / "modes.json"), "--uff",
                              str(tmp_path / "modes.uff"), "--dof-map", str(tmp_path / "map.csv")])
    assert res.exit_code == 0, res.output
    back = read_uff(tmp_path / "modes.uff")["modes"]
    assert sorted(set(back.sensors.nodes.tolist())) == [101, 102, 103, 104]
    assert set(back.sensors.labels) <= {f"{g}{s}{a}" for g in (101, 102, 103, 104) for s in "+-" for a in "XYZ"}
    fn, phi, _ = modes(M, K, zeta)
    np.testing.assert_allclose(back.frequencies_hz, fn, rtol=1e-3)
    z = back.shapes[[back.sensors.labels.index(f"{g}+Z") for g in (101, 102, 103, 104)]]
    mac = np.abs(np.sum(z * phi, axis=0)) ** 2 / (np.sum(z * z, axis=0) * np.sum(phi * phi, axis=0))
    assert np.all(mac > 0.999)

    res = runner.invoke(app, ["identify", str(path), "--json", str(tmp_path / "o.json")])
    assert res.exit_code == 2
    assert "no DoF (direction 0) for channel(s) 'acc1', 'hammer', 'acc2', 'acc3', 'acc4'" in res.output
    assert "--dof-map CSV" in res.output
    (tmp_path / "short.csv").write_text("channel,node,direction\n" + rows.replace("acc3,103,+Z\n", "") +
                                        "hammer,104,+Z\n")
    res = runner.invoke(app, ["identify", str(path), "--json", str(tmp_path / "o.json"), "--dof-map",
                              str(tmp_path / "short.csv")])
    assert res.exit_code == 2 and "FRF channel(s) 'acc3' have no DoF in the file" in res.output
    (tmp_path / "extra.csv").write_text("channel,node,direction\n" + rows + "hammer,104,+Z\nacc9,109,3\n")
    res = runner.invoke(app, ["identify", str(path), "--json", str(tmp_path / "o.json"), "--dof-map",
                              str(tmp_path / "extra.csv")])
    assert res.exit_code == 2 and "DoF map rows name channel(s) 'acc9' absent from the file" in res.output
    (tmp_path / "bad.csv").write_text("channel,node,direction\nacc1,101,+Z\nacc2,one-o-two,+Z\n")
    res = runner.invoke(app, ["identify", str(path), "--json", str(tmp_path / "o.json"), "--dof-map",
                              str(tmp_path / "bad.csv")])
    assert res.exit_code == 2
    assert f"error: --dof-map: {tmp_path / 'bad.csv'}, line 3: field 'node': 'one-o-two' is not a node id" in res.output
