"""``jaxfem identify`` (FRFs → modes, diagram, UFF 55) and ``jaxfem appropriate``
(exciter sets ranked by predicted MIF) through the command line."""

import json

import numpy as np
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
