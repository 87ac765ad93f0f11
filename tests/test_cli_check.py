"""``jaxfem check``: what was read, with the mass table, against a hand computation."""

import json
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from jaxfem.io import read_bdf_text
from updating.cli import app

runner = CliRunner()

DECK = """SOL 103
CEND
BEGIN BULK
PLOTEL,10,1,2
PARAM,COUPMASS,1
GRID,1,,0.,0.,0.
GRID,2,,2.,0.,0.
GRID,3,,2.,1.,0.
MAT1,1,2.1e11,,0.3,7800.
PBAR,1,1,1.e-4,1.e-8,2.e-8,3.e-8,0.2
CBAR,1,1,1,2,0.,1.,0.
CBAR,2,1,2,3,0.,0.,1.
CONM2,3,3,,4.,0.,0.,0.5
SPC1,1,123456,1
ENDDATA
"""
# (ρA + NSM)·L at each beam's middle, the CONM2 at grid 3 + offset
PARTS = [((7800 * 1e-4 + 0.2) * 2.0, (1.0, 0.0, 0.0)), ((7800 * 1e-4 + 0.2) * 1.0, (2.0, 0.5, 0.0)),
         (4.0, (2.0, 1.0, 0.5))]
MASS = sum(m for m, _ in PARTS)
CG = sum(m * np.array(x) for m, x in PARTS) / MASS


def test_check_prints_mass_cg_and_ignored_cards(tmp_path):
    deck = tmp_path / "frame.bdf"
    deck.write_text(DECK)
    out = tmp_path / "check.json"
    result = runner.invoke(app, ["check", str(deck), "--json", str(out)])
    assert result.exit_code == 0, result.output
    text = result.output
    found = re.search(r"total mass (\S+); CG \(basic\) x (\S+), y (\S+), z (\S+)", text)
    assert found, text
    printed = [float(v) for v in found.groups()]
    np.testing.assert_allclose(printed, [MASS, *CG], rtol=1e-6, atol=1e-12)
    assert "ignored cards (no effect on stiffness or mass): PLOTEL x1" in text
    assert f"files read: {deck}" in text
    assert "elements: CBAR 2, CONM2 1" in text and "properties: PBAR 1" in text and "materials: MAT1 1" in text
    assert "grids: 3; bounding box x 0 … 2, y 0 … 1, z 0 … 0" in text
    assert "SPC set 1" in text and "6 grid DoFs constrained" in text and "DoFs solved: 12 of 18" in text
    assert "COUPMASS 1 (consistent mass)" in text and "units: SI: lengths in m, masses in kg" in text
    data = json.loads(out.read_text())
    assert abs(data["mass"]["mass"] - MASS) <= 1e-12 * MASS
    np.testing.assert_allclose(data["mass"]["cg"], CG, rtol=0, atol=1e-12 * np.abs(CG).max())
    assert data["ignored_cards"] == {"PLOTEL": [f"{deck}:4"]} and data["unsupported_cards"] == {}
    assert data["cards"]["elements"] == {"CBAR": 2, "CONM2": 1}
    assert data["constraints"]["constrained_dofs"] == 6 and data["dofs"] == {"grid": 18, "solved": 12, "massless": 0}


def test_check_reference_grid_and_unsupported_cards(tmp_path):
    """GRDPNT picks the reference grid; --allow-unsupported lists what was left out; a bad
    --reference exits 2."""
    deck = tmp_path / "frame.bdf"
    deck.write_text(DECK.replace("ENDDATA", "PARAM,GRDPNT,2\nRBE2,9,2,123456,3\nCHEXA,900,1,1,2,3,1,2,3,\n,1,2\n"
                                            "ENDDATA").replace("SPC1,1,123456,1", "SPC1,1,123456,1\nSPC1,2,3,2"))
    result = runner.invoke(app, ["check", str(deck), "--allow-unsupported", "--spc-set", "1"])
    assert result.exit_code == 0, result.output
    assert "reference point grid 2 (2, 0, 0)" in result.output
    assert "unsupported structural cards, left out (--allow-unsupported): CHEXA x1" in result.output
    assert "SPC set 1 (in the deck: [1, 2])" in result.output
    assert "rigid elements: RBE2 1; 6 dependent DoFs" in result.output
    result = runner.invoke(app, ["check", str(deck), "--allow-unsupported", "--spc-set", "1", "--reference", "7"])
    assert result.exit_code == 2 and "--reference 7: no such grid" in result.output


def test_check_shows_the_subcase_choices(tmp_path):
    """With case control (when the reader keeps it): the subcase's SPC and METHOD shown, and
    the SPC set it chooses is the one applied."""
    text = DECK.replace("CEND\n", "CEND\nSUBCASE 1\n  SPC = 2\n  METHOD = 10\n").replace(
        "SPC1,1,123456,1", "SPC1,1,123456,1\nSPC1,2,123456,1\nEIGRL,10,,,6")
    if getattr(read_bdf_text(text), "case_control", None) is None:
        pytest.skip("the reader does not keep case control")
    deck = tmp_path / "frame.bdf"
    deck.write_text(text)
    result = runner.invoke(app, ["check", str(deck)])
    assert result.exit_code == 0, result.output
    assert "case control: SOL 103; subcase 1: SPC = 2, METHOD = 10" in result.output
    assert "SPC set 2 (in the deck: [1, 2])" in result.output


def test_check_names_the_units_and_the_mass_in_input_units_under_wtmass(tmp_path):
    """With PARAM WTMASS 0.5 the table holds mass (input × 0.5) and the note Nastran's GRDPNT
    total (input units); --units names the system."""
    deck = tmp_path / "frame.bdf"
    deck.write_text(DECK.replace("ENDDATA", "PARAM,WTMASS,0.5\nENDDATA"))
    result = runner.invoke(app, ["check", str(deck), "--units", "in-lbf-s"])
    assert result.exit_code == 0, result.output
    found = re.search(r"total mass (\S+);", result.output)
    np.testing.assert_allclose(float(found.group(1)), 0.5 * MASS, rtol=1e-6)
    assert f"Nastran's GRDPNT prints input units: total {MASS:.6E}" in result.output
    assert "units: in-lbf-s: lengths in in, masses in lbf·s²/in, forces in lbf" in result.output
    result = runner.invoke(app, ["check", str(deck), "--units", "furlongs"])
    assert result.exit_code == 2 and "--units 'furlongs': use one of SI, mm-t-s" in result.output
