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
