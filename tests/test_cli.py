"""The command line: tables, JSON and errors."""

import json
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

import jaxfem
from jaxfem.io import read_bdf
from updating.cli import app

runner = CliRunner()


def test_modes_json_matches_library(tmp_path):
    out = tmp_path / "modes.json"
    result = runner.invoke(app, ["modes", "tests/data/frame_free.bdf", "-n", "5", "--json", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    model = jaxfem.build_model(read_bdf("tests/data/frame_free.bdf"))
    lam, _ = jaxfem.eigh(*jaxfem.assemble(model), 5)
    assert data["n_dof"] == model.n_dof
    np.testing.assert_allclose(data["frequencies_hz"], jaxfem.frequencies_hz(lam), rtol=1e-12)
    assert "f [Hz]" in result.output


def test_json_goes_into_a_new_directory_and_a_directory_is_refused_first(tmp_path):
    out = tmp_path / "new" / "deeper" / "modes.json"
    result = runner.invoke(app, ["modes", "tests/data/frame_free.bdf", "-n", "2", "--json", str(out)])
    assert result.exit_code == 0, result.output
    assert len(json.loads(out.read_text())["frequencies_hz"]) == 2
    result = runner.invoke(app, ["modes", "tests/data/frame_free.bdf", "-n", "2", "--json", str(tmp_path)])
    assert result.exit_code == 2 and "is a directory" in result.output
    assert "f [Hz]" not in result.output  # refused before the solve


def test_malformed_model_names_the_field(tmp_path):
    bad = tmp_path / "bad.bdf"
    bad.write_text("GRID,1,,0.,0.,abc\n")
    result = runner.invoke(app, ["modes", str(bad)])
    assert result.exit_code == 2
    assert "bad.bdf:1: GRID 1 field 6 (X3)" in result.output
    assert "Traceback" not in result.output


def test_unsupported_structural_cards_stop_unless_allowed(tmp_path):
    """A CHEXA the reader cannot build changes the structure: exit 2 naming the card and the
    option; with --allow-unsupported the model is built without it, with a warning."""
    text = Path("tests/data/frame_free.bdf").read_text().replace("ENDDATA", "")
    deck = tmp_path / "solid.bdf"
    deck.write_text(text + "CHEXA,900,1,1,2,3,4,5,6,\n,7,8\nENDDATA\n")
    result = runner.invoke(app, ["modes", str(deck), "-n", "3"])
    assert result.exit_code == 2
    assert "CHEXA" in result.output and "--allow-unsupported builds it without them" in result.output
    result = runner.invoke(app, ["modes", str(deck), "-n", "3", "--allow-unsupported"])
    assert result.exit_code == 0, result.output
    assert "CHEXA" in result.output  # the warning names what was left out


def test_a_deck_with_two_spc_sets_needs_spc_set(tmp_path):
    """Two SPC sets (say free and clamped in one deck): exit 2 naming both with their lines
    and the option; ``--spc-set`` picks one, as case control ``SPC = SID`` would."""
    deck = tmp_path / "two.bdf"
    deck.write_text(Path("tests/data/frame_free.bdf").read_text().replace("ENDDATA", "SPC1,2,123456,3,4\nENDDATA"))
    result = runner.invoke(app, ["modes", str(deck), "-n", "3"])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert (f"{deck}:61: SPC1 2 field 2 (SID): several SPC sets [1, 2] (SPC1 1 at {deck}:59, SPC1 2 at {deck}:61); "
            "choose one in the case control (SPC = n) or with spc_set (--spc-set)") in result.output.replace("\n", ""), result.output
    first = {}
    for sid in (1, 2):
        out = tmp_path / f"set{sid}.json"
        result = runner.invoke(app, ["modes", str(deck), "-n", "3", "--spc-set", str(sid), "--json", str(out)])
        assert result.exit_code == 0, result.output
        first[sid] = json.loads(out.read_text())["frequencies_hz"][0]
    model = jaxfem.build_model(read_bdf(deck), spc_set=2)
    assert first[2] == np.float64(jaxfem.frequencies_hz(jaxfem.modes(model, 3)[0])[0]) and first[2] != first[1]
    result = runner.invoke(app, ["modes", str(deck), "--spc-set", "7"])
    assert result.exit_code == 2 and "SPC set 7 (spc_set or case control) is not in the bulk data (sets: [1, 2])" in result.output
