"""The diagnosis on shell structures, on data no model of the diagnosis produced
(:mod:`benchmarks.perf_diagnose` at sizes the suite affords; the benchmark runs them at
full size): the barrel lacking a payload (its truth: the bulk data with one more CONM2
card, read on its own; the diagnosis on reduced models, as at 33k DoFs) and the CFRP
panel's delamination (its truth: a mesh of half the element size with the delaminated
elements on their own PCOMP; the diagnosis on the change between two states). Each must
rank the effect first at the right place with the held-out frequency error below twice
the noise; each control must claim nothing."""

import pytest

from benchmarks.perf_diagnose import run_barrel, run_panel

BARREL_DOF = 2_500  # above DiagnoseOptions.reduce_above: the candidates are fitted on reduced models
NOISE_F = 0.001  # the barrel's frequency noise (relative σ of f)
PANEL_SIZE, PANEL_MODES = 0.05, 10  # m, modes: the panel at twice the benchmark's element size
PANEL_NOISE_F = 1.4e-4  # σ of a difference of two states' frequencies (√2 × 0.01 %)


@pytest.mark.slow
def test_barrel_missing_payload():
    row = run_barrel(n_dof=BARREL_DOF)
    assert row["right"], row["verdict"]
    assert row["posterior"] > 0.5
    assert row["heldout_after_pct"] < min(row["heldout_before_pct"], 2 * 100 * NOISE_F), row


@pytest.mark.slow
def test_barrel_control_claims_nothing():
    row = run_barrel(control=True, n_dof=BARREL_DOF)
    assert row["outcome"] == "none_needed", row["verdict"]


@pytest.mark.slow
def test_panel_delamination():
    row = run_panel(element_size=PANEL_SIZE, n_modes=PANEL_MODES)
    assert row["right"], row["verdict"]
    assert row["posterior"] > 0.5
    assert row["heldout_after_pct"] < min(row["heldout_before_pct"], 2 * 100 * PANEL_NOISE_F), row


@pytest.mark.slow
def test_panel_control_claims_nothing():
    row = run_panel(control=True, element_size=PANEL_SIZE, n_modes=PANEL_MODES)
    assert row["outcome"] == "none_needed", row["verdict"]
