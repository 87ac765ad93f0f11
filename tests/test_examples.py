"""The scripts in ``examples/`` run and print what they claim: each ``main()`` is run and
one or two of its numbers are checked (physics where there is a law, else the value of
the run that pinned it, with a tolerance for compiler rounding). 02–04 took 7–31 s
each in the suite on 2 cores: ``-m "not slow"`` leaves them out while iterating."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def run(name: str, capsys) -> tuple[dict, str]:
    """Import ``examples/<name>.py`` by path (the names start with digits), run ``main()``."""
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    result = module.main()
    return result, capsys.readouterr().out


def test_01_correlate_garteur(capsys):
    r, out = run("01_correlate_garteur", capsys)
    assert r["n_paired"] == 13  # test mode 11 (the fin joint's mode) has no partner in the nominal model
    assert r["rms_freq_dev_pct"] == pytest.approx(1.28, abs=0.01)  # pinned from the run (1.28 %)
    assert r["worst_comac_sensor"] == "7001+X"  # the tailplane, carried by the flexible fin joint
    assert "unpaired" in out and "lowest COMAC" in out


@pytest.mark.slow
def test_02_update_lowers_the_frequency_error(capsys):
    r, out = run("02_update", capsys)
    assert r["converged"]
    assert r["rms_active_after"] < 0.85 * r["rms_active_before"]  # fitted modes: 1.35 % → 0.90 %
    assert r["rms_passive_after"] < 0.5 * r["rms_passive_before"]  # held-out modes predicted: 0.82 % → 0.14 %
    assert r["alpha"]["fuselage"] == pytest.approx(0.0467, abs=0.002)  # truth +6 %, biased by the missing joint
    assert "passive" in out


@pytest.mark.slow
def test_03_diagnose_finds_the_fin_joint(capsys):
    """31 s in the suite on 2 cores (measured quiet; about 4× that while other heavy jobs ran)."""
    r, _ = run("03_diagnose", capsys)
    assert (r["kind"], r["nodes"]) == ("joint", [6001])
    assert r["warranted"] and not r["no_effect_warranted"]


@pytest.mark.slow
def test_04_montecarlo(capsys):
    r, _ = run("04_montecarlo", capsys)
    assert r["failures"] == 0
    np.testing.assert_allclose(r["alpha_reference"], [1 / 0.83 - 1, 0.0, 0.0], atol=1e-6)  # exact correction
    small, large = r["delta_alpha"][0.01]["blades_2_4"], r["delta_alpha"][0.05]["blades_2_4"]
    assert 4 < large[1] / small[1] < 6  # std ∝ shape error (linear regime, common random numbers): 5.0


def test_05_identify(capsys):
    r, out = run("05_identify", capsys)
    assert r["n_modes"] == 3
    np.testing.assert_allclose(r["f_hz"], r["f_exact_hz"], rtol=1e-3)  # within 0.1 % (measured ≤ 0.0012 %)
    np.testing.assert_allclose(r["zeta"], [0.01, 0.015, 0.02], rtol=0.05)  # measured ≤ 0.2 %
    assert r["min_mac"] > 0.999
