"""Auto-SPC is relative to each grid's own terms: a stiff spring elsewhere removes nothing."""

from pathlib import Path

import numpy as np
import pytest

import jaxfem
from jaxfem.io import read_bdf_text

W, H = 0.02, 0.001  # an aluminium strip: rotational stiffness 4EI/L of a few N·m/rad
STRIP = "\n".join(
    [f"GRID,{i + 1},,{0.1 * i:.3f},0.,0." for i in range(11)]
    + [f"CBAR,{i + 1},1,{i + 1},{i + 2},0.,0.,1." for i in range(10)]
    + [f"PBAR,1,1,{W * H:.6e},{W * H**3 / 12:.6e},{H * W**3 / 12:.6e},{W * H**3 / 3:.6e}",
       "MAT1,1,70.E9,,0.33,2700.", "SPC1,1,123456,1"]) + "\n"


def _first(text: str, n: int) -> tuple[np.ndarray, jaxfem.Model]:
    model = jaxfem.build_model(read_bdf_text(text), spc_set=1)
    f = np.asarray(jaxfem.frequencies_hz(jaxfem.modes(model, n)[0]))
    return f[np.abs(f) > 1e-3], model


def test_a_stiff_spring_elsewhere_leaves_the_rotations_of_a_light_cantilever():
    """Lumped mass: the strip's rotations are massless, their stiffness (≈ 4 N·m/rad) is
    12 orders below a 1e18 N/m spring on an unrelated grid. With one threshold for the
    whole model they were removed and the first bending mode went from 0.82 to 12.7 Hz."""
    f, strip = _first(STRIP, 4)
    with pytest.warns(UserWarning, match=r"2 DoF\(s\), \(node, component\) \(99, 1\), \(99, 2\) carry mass but no "
                      r"stiffness: each moves freely, a 0 Hz mode"):
        g, both = _first(STRIP + "GRID,99,,5.,5.,5.\nCELAS2,99,1.E18,99,3\nCONM2,98,99,,1.\n", 7)
    np.testing.assert_allclose(g[:4], f[:4], rtol=1e-9)
    assert f[0] < 1.0
    assert len(strip.dofs.auto_spc) == 0
    assert sorted(map(tuple, both.dofs.auto_spc.tolist())) == [(99, 4), (99, 5), (99, 6)]  # the spring grid's own


def test_an_overflow_in_the_elements_is_named_not_solved():
    """A shell 1e200 m thick overflows its stiffness: refused naming the DoFs, before any
    eigensolver sees inf or NaN."""
    from benchmarks.shell_models import plate

    deck = plate(1.0, 0.8, 2, 2, "PSHELL,1,1,1.E200,1,,1\nMAT1,1,70.E9,,0.3,2700.", bc="free")
    with pytest.raises(ValueError, match=r"non-finite stiffness at \d+ DoF\(s\), \(node, component\) \(1, 1\)"):
        jaxfem.build_model(read_bdf_text(deck))


FRAME = (Path(__file__).parent / "data" / "frame_free.bdf").read_text().replace("PARAM,COUPMASS,1\n", "")  # lumped


def _frame(extra: str) -> tuple[np.ndarray, jaxfem.Model]:
    model = jaxfem.build_model(read_bdf_text(FRAME.replace("ENDDATA", extra + "ENDDATA"), name="f.bdf"))
    return np.asarray(jaxfem.frequencies_hz(jaxfem.modes(model, 6)[0])), model


def test_the_issue_examples_leave_the_frame_bending_mode_at_6_50_hz():
    """Issue 19: on the lumped-mass frame, ``CELAS2,9,1.E18,3,3`` (a stiff spring to ground
    at grid 3) or a 1e-9 m bar stub removed rotations elsewhere and moved the 6.50 Hz
    bending mode to 11.47 Hz. Now nothing is removed and the mode stays within 2e-5 (the
    stub costs round-off: its bending stiffness is ~1e33 N/m)."""
    f, _ = _frame("")
    assert f[0] == pytest.approx(6.497, abs=1e-3)
    spring, with_spring = _frame("CELAS2,9,1.E18,3,3\n")
    stub, with_stub = _frame("GRID,11,,1.000000001,1.5,3.\nCBAR,105,1,7,11,0.,0.,1.\n")
    assert len(with_spring.dofs.auto_spc) == len(with_stub.dofs.auto_spc) == 0
    for g in (spring, stub):  # the spring does ground grid 3 in z: a real change of 2e-4 in mode 2
        assert g[0] == pytest.approx(f[0], rel=1e-4)
        np.testing.assert_allclose(g[:5], f[:5], rtol=1e-3)


def test_a_free_mass_is_announced_and_a_too_short_element_refused_with_its_length():
    with pytest.warns(UserWarning, match=r"\(node, component\) \(11, 2\), \(11, 3\) carry mass but no stiffness: each "
                      r"moves freely"):
        f, model = _frame("GRID,11,,1.000000001,1.5,3.\nCROD,105,6,7,11\n")  # a rod: no transverse stiffness
    np.testing.assert_allclose(f[:2], 0.0, atol=1e-3)
    assert sorted(map(tuple, model.dofs.auto_spc.tolist())) == [(11, 5), (11, 6)]  # no stiffness, no mass
    with pytest.raises(ValueError, match=r"f.bdf:\d+: CBAR 105 field 5 \(GB\): zero length: the ends \(offsets "
                       r"included\) are 1e-10 apart, at \[1.0, 1.5, 3.0\] and \[1.0000000001, 1.5, 3.0\]"):
        _frame("GRID,11,,1.0000000001,1.5,3.\nCBAR,105,1,7,11,0.,0.,1.\n")


def test_jaxfem_modes_names_the_auto_spc_and_the_free_mass(tmp_path):
    from typer.testing import CliRunner

    from updating.cli import app

    path = tmp_path / "stub.bdf"
    path.write_text(FRAME.replace("ENDDATA", "GRID,11,,1.000000001,1.5,3.\nCROD,105,6,7,11\nENDDATA"))
    result = CliRunner().invoke(app, ["modes", str(path), "-n", "4"])
    assert result.exit_code == 0, result.output
    assert "condensed; 2 auto-SPC)" in result.output, result.output
    assert "auto-SPC, neither stiffness nor mass, grid (components): 11 (56)" in result.output
    assert "(node, component) (11, 2), (11, 3) carry mass but no stiffness: each moves freely" in result.output
