"""``jaxfem identify`` (FRFs → modes, diagram, UFF 55) and ``jaxfem appropriate``
(exciter sets ranked by predicted MIF) through the command line."""

import json

import numpy as np
import pytest
from _frf_models import chain, frf_data, modes, receptance
from typer.testing import CliRunner

import jaxfem
from benchmarks.frames import frame_bdf
from identification import read_uff, write_uff
from jaxfem.io import read_bdf_text
from updating.cli import app

runner = CliRunner()


def test_identify_writes_modes_diagram_and_uff(tmp_path):
    M, K = chain([1.0, 1.2, 0.9, 1.1], [4e4, 3e4, 3e4, 2.5e4])
    zeta = [0.01, 0.015, 0.01, 0.02]
    f = np.arange(0.5, 100.0, 0.05)
    frfs = frf_data(receptance(M, K, zeta, f, np.arange(4), [3]), f, np.arange(4), [3], noise=0.01)
    write_uff(tmp_path / "frf.uff", frfs=frfs)
    res = runner.invoke(app, ["identify", str(tmp_path / "frf.uff"), "--json", str(tmp_path / "modes.json"),
                              "--plots", str(tmp_path / "plots"), "--uff", str(tmp_path / "modes.uff")])
    assert res.exit_code == 0, res.output
    fn, _, z = modes(M, K, zeta)
    out = json.loads((tmp_path / "modes.json").read_text())
    found = np.array([m["frequency_hz"] for m in out["modes"]])
    np.testing.assert_allclose(found, fn, rtol=1e-3)
    np.testing.assert_allclose([m["damping_ratio"] for m in out["modes"]], z, rtol=0.05)
    assert (tmp_path / "plots" / "stabilisation.png").stat().st_size > 10_000
    back = read_uff(tmp_path / "modes.uff")["modes"]
    np.testing.assert_allclose(back.frequencies_hz, found, rtol=1e-5)


def test_identify_refuses_a_file_without_frfs(tmp_path):
    M, K = chain([1.0, 1.0], [1e4, 1e4])
    fn, phi, _ = modes(M, K, 0.01)
    from identification import ModalData, Sensors

    write_uff(tmp_path / "modes.uff", modes=ModalData(fn, phi, Sensors.from_components([1, 2], [3, 3])))
    res = runner.invoke(app, ["identify", str(tmp_path / "modes.uff"), "--json", str(tmp_path / "o.json")])
    assert res.exit_code == 2 and "no FRFs" in res.output
    assert res.output.count(str(tmp_path / "modes.uff")) == 1


def test_identify_roving_hammer_uff(tmp_path):
    """1 accelerometer (2+Z) × 5 hammer points: the modes written have shapes at every hammer point."""
    M, K = chain([1.0, 1.2, 0.9, 1.1, 1.0], [4e4, 3e4, 3e4, 2.5e4, 2e4])
    zeta = [0.01, 0.012, 0.015, 0.01, 0.02]
    f = np.arange(0.0, 120.0, 0.05)
    out, inp = [1], [0, 1, 2, 3, 4]
    write_uff(tmp_path / "rh.uff", frfs=frf_data(receptance(M, K, zeta, f, out, inp), f, out, inp))
    res = runner.invoke(app, ["identify", str(tmp_path / "rh.uff"), "--json", str(tmp_path / "m.json"),
                              "--uff", str(tmp_path / "m.uff"), "--orders", "2:40:2", "--stab-freq", "0.005",
                              "--stab-damp", "0.1", "--stab-mac", "0.95"])
    assert res.exit_code == 0, res.output
    assert "pLSCF orders 2:40:2 (--orders), references: the outputs (reciprocity H_ij = H_ji)" in res.output
    assert "≤ 0.005 (--stab-freq)" in res.output and "≤ 0.1 (--stab-damp)" in res.output
    assert "MAC ≥ 0.95 (--stab-mac)" in res.output
    fn, phi, _ = modes(M, K, zeta)
    report = json.loads((tmp_path / "m.json").read_text())
    assert report["options"]["orders"] == list(range(2, 41, 2)) and report["options"]["tol_f"] == 0.005
    assert report["options"]["tol_zeta"] == 0.1 and report["options"]["min_mac"] == 0.95
    np.testing.assert_allclose([m["frequency_hz"] for m in report["modes"]], fn, rtol=1e-7)
    back = read_uff(tmp_path / "m.uff")["modes"]
    assert sorted(back.sensors.labels) == ["1+Z", "2+Z", "3+Z", "4+Z", "5+Z"]
    truth = phi[[int(label.removesuffix("+Z")) - 1 for label in back.sensors.labels]]
    scale = np.sum(back.shapes * truth, axis=0) / np.sum(truth * truth, axis=0)
    np.testing.assert_allclose(np.abs(scale), 1.0, atol=1e-5)  # unit modal mass through the driving point 2+Z
    np.testing.assert_allclose(back.shapes, scale * truth, atol=1e-5 * np.max(np.abs(truth)))  # UFF: 6 digits
    exact = np.array(report["shapes"]).T  # the JSON keeps full precision
    truth = phi[[int(label.removesuffix("+Z")) - 1 for label in report["sensors"]]]
    scale = np.sum(exact * truth, axis=0) / np.sum(truth * truth, axis=0)
    np.testing.assert_allclose(exact, scale * truth, rtol=0, atol=1e-6 * np.max(np.abs(truth)))
    np.testing.assert_allclose(np.abs(scale), 1.0, atol=1e-6)


@pytest.mark.parametrize("plots", [False, True])
def test_identify_failure_writes_diagram_and_json(tmp_path, plots):
    """Too few orders: exit 2, the options that help named, the diagram and what was found written anyway."""
    M, K = chain([1.0, 1.2, 0.9, 1.1], [4e4, 3e4, 3e4, 2.5e4])
    f = np.arange(0.5, 100.0, 0.05)
    write_uff(tmp_path / "frf.uff", frfs=frf_data(receptance(M, K, 0.01, f, np.arange(4), [3]), f, np.arange(4), [3]))
    args = ["identify", str(tmp_path / "frf.uff"), "--json", str(tmp_path / "out" / "f.json"), "--orders", "2:4"]
    res = runner.invoke(app, args + (["--plots", str(tmp_path / "plots")] if plots else []))
    assert res.exit_code == 2, res.output
    error = next(line for line in res.output.splitlines() if line.startswith("error:"))
    assert "no pole is stable over 3 of the orders 2–4" in error and "lowest order is never stable" in error
    for option in ("--orders (now 2:4", "--stab-freq (now 0.01)", "--stab-damp (now 0.05)", "--stab-mac (now 0.98)",
                   "--fmin/--fmax", "--min-coherence (now 0.5)"):
        assert option in error
    assert error.count(str(tmp_path / "frf.uff")) == 1
    png = tmp_path / "plots" / "stabilisation.png" if plots else tmp_path / "out" / "f_stabilisation.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and str(png) in error
    report = json.loads((tmp_path / "out" / "f.json").read_text())
    assert report["identified"] is False and report["error"].startswith("no pole is stable")
    assert report["options"]["orders"] == [2, 3, 4] and report["options"]["min_mac"] == 0.98
    diagram = report["stabilisation"]
    assert set(diagram["order"]) <= {2, 3, 4} and len(diagram["order"]) == len(diagram["stable_mac"]) > 0


@pytest.mark.parametrize(
    "option, message",
    [
        (["--orders", "4:2"], "--orders 4:2: the lowest order 4 is above the highest 2"),
        (["--orders", "2.5:9"], "--orders '2.5:9': give A:B or A:B:STEP, whole numbers"),
        (["--orders", "2:40:0"], "--orders 2:40:0: the lowest order and the step must be at least 1"),
        (["--orders", "2:3"], "--orders 2:3 gives 2 model order(s): a stabilisation diagram needs at least 3"),
        (["--stab-freq", "-0.01"], "--stab-freq -0.01: must be positive"),
        (["--stab-damp", "0"], "--stab-damp 0: must be positive"),
        (["--stab-mac", "1.2"], "--stab-mac 1.2: must be between 0 and 1"),
    ],
)
def test_identify_refuses_bad_options(tmp_path, option, message):
    M, K = chain([1.0, 1.0], [1e4, 1e4])
    f = np.arange(0.0, 50.0, 0.5)
    write_uff(tmp_path / "frf.uff", frfs=frf_data(receptance(M, K, 0.01, f, [0, 1], [1]), f, [0, 1], [1]))
    res = runner.invoke(app, ["identify", str(tmp_path / "frf.uff"), "--json", str(tmp_path / "o.json"), *option])
    assert res.exit_code == 2 and f"error: {message}" in res.output
    assert not (tmp_path / "o.json").exists()


def test_identify_names_an_unreadable_file_once(tmp_path):
    """read_uff's messages begin with the path: the CLI does not add it a second time."""
    M, K = chain([1.0, 1.0], [1e4, 1e4])
    f, g = np.arange(0.0, 50.0, 0.5), np.arange(0.0, 50.0, 0.25)
    write_uff(tmp_path / "a.uff", frfs=frf_data(receptance(M, K, 0.01, f, [0], [0]), f, [0], [0]))
    write_uff(tmp_path / "b.uff", frfs=frf_data(receptance(M, K, 0.01, g, [1], [0]), g, [1], [0]))
    bad = tmp_path / "bad.uff"
    bad.write_bytes((tmp_path / "a.uff").read_bytes() + (tmp_path / "b.uff").read_bytes())  # two frequency axes
    res = runner.invoke(app, ["identify", str(bad), "--json", str(tmp_path / "o.json")])
    assert res.exit_code == 2 and "has a frequency axis different from" in res.output
    assert res.output.count(str(bad)) == 1, res.output


def test_appropriate_ranks_exciter_pairs(tmp_path):
    bdf = tmp_path / "frame.bdf"
    bdf.write_text(frame_bdf(2, 2, 2, n_groups=2))
    model = jaxfem.build_model(read_bdf_text(bdf.read_text()))
    grids = [int(g) for g in model.node_ids if int(g) > 4][:4]
    cands = ",".join(f"{g}:1" for g in grids)
    res = runner.invoke(app, ["appropriate", str(bdf), "--candidates", cands, "--exciters", "2", "--modes", "3",
                              "--json", str(tmp_path / "a.json")])
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "a.json").read_text())
    lam, _ = jaxfem.eigh(*jaxfem.assemble(model), 3)
    np.testing.assert_allclose([m["natural_frequency_hz"] for m in out["modes"]],
                               np.asarray(jaxfem.frequencies_hz(lam)), rtol=1e-8)
    assert out["n_subsets"] == 6 and out["candidate_labels"] == [f"{g}:1" for g in grids]
    for m in out["modes"]:
        mifs = [r["mif"] for r in m["ranking"] if r["mif"] is not None]
        assert mifs == sorted(mifs, reverse=True) and 0 <= mifs[0] <= 1000
    bad = runner.invoke(app, ["appropriate", str(bdf), "--candidates", "99999:1", "--exciters", "1",
                              "--json", str(tmp_path / "b.json")])
    assert bad.exit_code == 2 and "99999" in bad.output
