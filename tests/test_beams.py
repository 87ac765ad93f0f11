"""Straight beams against closed-form and exact continuous solutions.

Euler–Bernoulli: classical βL roots. Timoshenko (shear + rotary inertia): the exact
frequencies of the continuous beam, found as roots of the 2×2 boundary determinant of
the transfer matrix exp(A(ω)L) of the first-order system in y = [w, ψ, w', ψ'].
"""

import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sl
from scipy.optimize import brentq

import jaxfem
from jaxfem.io import read_bdf_text

L, E, NU, RHO = 2.0, 2.1e11, 0.3, 7850.0
G = E / (2 * (1 + NU))
B, H = 0.04, 0.10  # plane-1 bending uses I1 = B·H³/12 (H along element y)
A = B * H
I1, I2 = B * H**3 / 12, H * B**3 / 12
J = 0.3 * B**3 * H  # any positive value: torsion tests use it consistently
KAPPA = 5.0 / 6.0


def beam_bdf(n_el, spc, k1=0.0, k2=0.0, coupmass=1, length=L):
    """A beam along x, y-orientation vector; `spc` maps station -> components string."""
    lines = [f"PARAM,COUPMASS,{coupmass}", f"MAT1,1,{E!r},,{NU},{RHO}"]
    kf = [f"{k1!r}" if k1 else "", f"{k2!r}" if k2 else ""]
    lines += [f"PBAR,1,1,{A!r},{I1!r},{I2!r},{J!r}", "+,,,,,,,,", f"+,{kf[0]},{kf[1]}"]
    for i in range(n_el + 1):
        lines.append(f"GRID,{i + 1},,{length * i / n_el!r},0.,0.")
    for i in range(n_el):
        lines.append(f"CBAR,{i + 1},1,{i + 1},{i + 2},0.,1.,0.")
    for station, comps in spc.items():
        grids = range(1, n_el + 2) if station == "all" else [1 if station == 0 else n_el + 1]
        for g in grids:
            lines.append(f"SPC1,1,{comps},{g}")
    return "\n".join(lines) + "\n"


def frequencies(text, n):
    model = jaxfem.build_model(read_bdf_text(text))
    K, M = jaxfem.assemble(model)
    lam, _ = jaxfem.eigh(K, M, n)
    return np.asarray(jaxfem.frequencies_hz(lam))


PLANE1 = "1345"  # leave T2 and R3 free: bending in the x–y plane (I1, K1)
EB_ROOTS = {
    "cantilever": [1.87510407, 4.69409113, 7.85475744, 10.99554073, 14.13716839],
    "simply_supported": [np.pi * n for n in range(1, 6)],
    "free_free": [4.73004074, 7.85320462, 10.99560784, 14.13716549, 17.27875966],
}
SUPPORTS = {
    "cantilever": {"all": PLANE1, 0: "26"},
    "simply_supported": {"all": PLANE1, 0: "2", 1: "2"},
    "free_free": {"all": PLANE1},
}


def euler_bernoulli_hz(case):
    beta_l = np.array(EB_ROOTS[case])
    return beta_l**2 * np.sqrt(E * I1 / (RHO * A * L**4)) / (2 * np.pi)


def timoshenko_hz(case, n_modes):
    """Exact frequencies of the continuous Timoshenko beam (plane 1)."""
    kga, ei, ra, ri = KAPPA * G * A, E * I1, RHO * A, RHO * I1

    def system(omega):
        w2 = omega**2
        # w'' = ψ' − ρAω²/(κGA) w ;  ψ'' = −(κGA(w' − ψ) + ρIω² ψ)/EI
        return np.array([
            [0, 0, 1, 0],
            [0, 0, 0, 1],
            [-ra * w2 / kga, 0, 0, 1],
            [0, (kga - ri * w2) / ei, -kga / ei, 0],
        ])

    # Start vectors satisfying the x = 0 conditions and end conditions at x = L.
    starts = {
        "cantilever": np.array([[0, 0, 1, 0], [0, 0, 0, 1]]).T,  # w = ψ = 0
        "simply_supported": np.array([[0, 1, 0, 0], [0, 0, 1, 0]]).T,  # w = ψ' = 0
        "free_free": np.array([[1, 0, 0, 0], [0, 1, 1, 0]]).T,  # ψ' = 0, w' = ψ
    }
    ends = {
        "cantilever": lambda y: [y[3], y[2] - y[1]],
        "simply_supported": lambda y: [y[0], y[3]],
        "free_free": lambda y: [y[3], y[2] - y[1]],
    }

    def det(omega):
        t = sl.expm(system(omega) * L) @ starts[case]
        rows = np.array([ends[case](t[:, j]) for j in range(2)]).T
        return np.linalg.det(rows)

    grid = np.linspace(1.0, 2 * np.pi * 1.3 * euler_bernoulli_hz(case)[n_modes - 1], 4000)
    values = np.array([det(w) for w in grid])
    roots = [brentq(det, a, b, xtol=1e-12) for a, b, fa, fb in
             zip(grid[:-1], grid[1:], values[:-1], values[1:]) if fa * fb < 0]
    return np.array(roots[:n_modes]) / (2 * np.pi)


@pytest.mark.parametrize("case", ["cantilever", "simply_supported", "free_free"])
def test_euler_bernoulli_bending(case):
    n_rigid = {"free_free": 2}.get(case, 0)  # planar free–free: translation + rotation
    f = frequencies(beam_bdf(20, SUPPORTS[case]), 5 + n_rigid)
    assert np.all(np.abs(f[:n_rigid]) < 1e-3)
    np.testing.assert_allclose(f[n_rigid:], euler_bernoulli_hz(case), rtol=5e-3)


@pytest.mark.parametrize("case", ["cantilever", "simply_supported", "free_free"])
def test_timoshenko_bending(case):
    n_rigid = {"free_free": 2}.get(case, 0)
    exact = timoshenko_hz(case, 5)
    # The section is deep enough that shear and rotary inertia matter (> 2 % on mode 5).
    assert abs(exact[4] / euler_bernoulli_hz(case)[4] - 1) > 0.02
    f = frequencies(beam_bdf(20, SUPPORTS[case], k1=KAPPA, k2=KAPPA), 5 + n_rigid)
    np.testing.assert_allclose(f[n_rigid:], exact, rtol=5e-3)


def test_bending_convergence_rate():
    """Cubic Hermite elements with consistent mass: frequency error ~ h⁴."""
    errors = []
    for n_el in (4, 8):
        f = frequencies(beam_bdf(n_el, SUPPORTS["cantilever"]), 3)
        errors.append(abs(f[2] / euler_bernoulli_hz("cantilever")[2] - 1))
    rate = np.log2(errors[0] / errors[1])
    assert 3.5 < rate < 4.5


@pytest.mark.parametrize("free, wave_speed", [("1", np.sqrt(E / RHO)),
                                              ("4", np.sqrt(G * J / (RHO * (I1 + I2))))])
def test_axial_and_torsion_second_order(free, wave_speed):
    """Cantilever axial / torsion: f_n = (2n−1) c / 4L.

    Linear elements with consistent mass overestimate ω by (kh)²/24 to leading order
    (k the wave number, h the element length): the error is asserted to that term.
    """
    others = "".join(c for c in "123456" if c != free)
    wave_number = (2 * np.arange(1, 4) - 1) * np.pi / (2 * L)
    exact = wave_number * wave_speed / (2 * np.pi)
    errors = []
    for n_el in (10, 20):
        f = frequencies(beam_bdf(n_el, {"all": others, 0: free}), 3)
        errors.append(f / exact - 1)
        np.testing.assert_allclose(errors[-1], (wave_number * L / n_el) ** 2 / 24, rtol=0.03)
    rates = np.log2(errors[0] / errors[1])
    np.testing.assert_allclose(rates, 2.0, atol=0.05)


def test_free_free_3d_beam_has_six_rigid_body_modes():
    f = frequencies(beam_bdf(20, {}), 12)
    assert np.all(f[:6] < 1e-3 * f[6])
    # Both bending planes appear among the elastic modes.
    plane2 = euler_bernoulli_hz("free_free")[0] * np.sqrt(I2 / I1)
    for target in (euler_bernoulli_hz("free_free")[0], plane2):
        assert np.min(np.abs(f[6:] / target - 1)) < 5e-3


def test_lumped_mass_condenses_rotations():
    """COUPMASS −1 (Nastran default): rotations are massless and condensed exactly."""
    text = beam_bdf(40, SUPPORTS["cantilever"], coupmass=-1)
    model = jaxfem.build_model(read_bdf_text(text))
    assert len(model.dofs.massless) == 40  # R3 at every free grid
    f = frequencies(text, 3)
    np.testing.assert_allclose(f, euler_bernoulli_hz("cantilever")[:3], rtol=5e-3)
    K, M = jaxfem.assemble(model)
    assert jnp.all(jnp.diagonal(M.todense())[model.dofs.massless] == 0)
