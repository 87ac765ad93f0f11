"""Auto-SPC is relative to each grid's own terms: a stiff spring elsewhere removes nothing."""

import numpy as np

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
    g, both = _first(STRIP + "GRID,99,,5.,5.,5.\nCELAS2,99,1.E18,99,3\nCONM2,98,99,,1.\n", 7)
    np.testing.assert_allclose(g[:4], f[:4], rtol=1e-9)
    assert f[0] < 1.0
    assert len(strip.dofs.auto_spc) == 0
    assert sorted(map(tuple, both.dofs.auto_spc.tolist())) == [(99, 4), (99, 5), (99, 6)]  # the spring grid's own


def test_an_overflow_in_the_elements_is_named_not_solved():
    """A shell 1e200 m thick overflows its stiffness: refused naming the DoFs, before any
    eigensolver sees inf or NaN."""
    import pytest

    from benchmarks.shell_models import plate

    deck = plate(1.0, 0.8, 2, 2, "PSHELL,1,1,1.E200,1,,1\nMAT1,1,70.E9,,0.3,2700.", bc="free")
    with pytest.raises(ValueError, match=r"the stiffness of \d+ DoF\(s\) is not finite, \(node, component\) \(1, 1\)"):
        jaxfem.build_model(read_bdf_text(deck))
