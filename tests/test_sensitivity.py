"""Parameter selection aids (thesis §4.2.4.1) on a small frame: the sensitivities of
eq. (4.3) with the 0.1 rule, identifiability of the weighted residual Jacobian, and the
test run of Fig. 4.4 (inject errors, simulate the measurement, update, recover)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.frames import frame_bdf
from identification import Sensors
from jaxfem.io import read_bdf_text
from updating import (Noise, Options, Parameter, ParameterSet, identifiability, parameterise, sensitivities,
                      test_run)

N_MODES = 6
OPTIONS = Options(tolerance=1e-10, max_iterations=30, eigenvalue_weight=1.0)  # fixed weight: fewer compilations
GROUPS = [Parameter(f"g{i}", "stiffness", pids=(i,)) for i in range(1, 7)]
JOINT = Parameter("joint", "k", pids=(7,))  # the CBUSH column joint, 1e9 N/m: far stiffer than the frame
MASS = Parameter("m3", "mass", pids=(3,))
WELL_POSED = ParameterSet((GROUPS[0], GROUPS[3], GROUPS[5], MASS), OPTIONS)
DUPLICATE = ParameterSet((GROUPS[0], Parameter("g1_again", "stiffness", pids=(1,)), GROUPS[3]), OPTIONS)


@pytest.fixture(scope="module")
def frame():
    model = jaxfem.build_model(read_bdf_text(frame_bdf(3, 3, 3, n_groups=6), name="frame"))
    nodes = model.node_ids[(model.node_ids > 9) & (model.node_ids < 900000)]  # above the clamped base
    return model, Sensors.from_components(np.repeat(nodes, 2), np.tile([1, 2], len(nodes)))


@pytest.fixture(scope="module")
def sens(frame):
    model, sensors = frame
    return sensitivities(model, GROUPS + [JOINT, MASS], sensors, n_modes=N_MODES)


@pytest.fixture(scope="module")
def recovered(frame):
    model, sensors = frame
    return test_run(model, sensors, WELL_POSED, [0.1, -0.1, 0.05, 0.08], n_modes=N_MODES, tol=1e-6)


@pytest.fixture(scope="module")
def duplicated(frame):
    model, sensors = frame
    with pytest.warns(UserWarning, match="'g1' and 'g1_again' .* identical Jacobian columns"):
        return test_run(model, sensors, DUPLICATE, [0.1, -0.05, 0.05], n_modes=N_MODES)


def test_eigenvalue_sensitivity_matches_finite_differences(frame, sens):
    model, _ = frame
    base, par = parameterise(model, GROUPS + [JOINT, MASS])
    lam = jax.jit(lambda a: jaxfem.eigh(*jaxfem.assemble(par.apply(base, jnp.zeros(8).at[0].set(jnp.log1p(a)))),
                                        N_MODES)[0])
    h = 1e-5
    fd = (np.asarray(lam(h)) - np.asarray(lam(-h))) / (2 * h)
    np.testing.assert_allclose(sens.jac_lam[:, 0], fd, rtol=1e-6)
    np.testing.assert_allclose(sens.raw_lam[0], np.linalg.norm(fd), rtol=1e-7)
    assert sens.s_lam[0] == pytest.approx(sens.raw_lam[0] / sens.raw_lam.max(), rel=1e-14)
    assert sens.jac_lam.shape == (N_MODES, 8) and sens.jac_phi.shape == (54, N_MODES, 8)
    np.testing.assert_array_equal(sens.modes, np.arange(1, N_MODES + 1))  # each model mode paired with itself


def test_rule_of_one_tenth_flags_the_stiff_joint(sens):
    assert sens.s_lam.max() == 1.0 and sens.s_phi.max() == 1.0
    rows = {r["name"]: r for r in sens.table()}
    assert rows["joint"]["flagged"] and rows["joint"]["s_lam"] < 0.1 and rows["joint"]["s_phi"] < 0.1
    dominant = sens.names[int(np.argmax(sens.s_lam))]
    assert dominant.startswith("g") and not rows[dominant]["flagged"]
    assert [n for n, f in zip(sens.names, sens.flagged) if f] == ["joint"]
    assert "joint" in sens.summary() and "omit or redefine" in sens.summary()


def test_well_posed_set_is_recovered(recovered):
    assert recovered.converged and recovered.all_recovered
    np.testing.assert_allclose(recovered.alpha, [0.1, -0.1, 0.05, 0.08], atol=1e-6)
    assert np.all(recovered.error <= 1e-6)
    check = recovered.identifiability
    assert check.well_posed and not check.collinear and check.condition_number < 1e6
    assert "WARNING" not in check.summary() and "NOT RECOVERED" not in recovered.summary()


def test_duplicate_targets_are_collinear_and_not_recovered(duplicated):
    check = duplicated.identifiability
    assert check.condition_number > 1e6 and not check.well_posed
    assert [(a, b) for a, b, _ in check.collinear] == [("g1", "g1_again")]
    assert check.collinear[0][2] == pytest.approx(1.0, abs=1e-12)
    assert set(check.weakest) == {"g1", "g1_again"}
    assert "WARNING" in check.summary()
    assert not duplicated.all_recovered
    assert not duplicated.recovered[0] and not duplicated.recovered[1] and duplicated.recovered[2]
    assert "NOT RECOVERED" in duplicated.summary() and "WARNING" in duplicated.summary()


def test_noise_widens_the_tolerance_to_what_it_warrants(frame, recovered, key):
    """Table 4.7 errors: α is off by about the linearised 3σ, which becomes the tolerance."""
    model, sensors = frame
    noisy = test_run(model, sensors, WELL_POSED, recovered.injected, n_modes=N_MODES, tol=1e-6,
                     noise=Noise(frequency=0.0025, relative=0.01), key=key)
    assert noisy.converged and noisy.all_recovered
    assert np.all(noisy.tolerance > 1e-3) and np.all(noisy.tolerance < 0.1)
    assert np.any(noisy.error > 1e-4)  # the noise does move the factors
    assert not np.allclose(noisy.simulated.frequencies_hz, recovered.simulated.frequencies_hz, rtol=1e-4)


def test_bad_input_is_refused(frame):
    model, sensors = frame
    with pytest.raises(ValueError, match="3 errors for 4 parameters"):
        test_run(model, sensors, WELL_POSED, [0.1, 0.1, 0.1])
    with pytest.raises(ValueError, match="> -1"):
        test_run(model, sensors, WELL_POSED, [0.1, -1.0, 0.1, 0.1])
    with pytest.raises(ValueError, match="key"):
        test_run(model, sensors, WELL_POSED, [0.1, 0.1, 0.1, 0.1], noise=Noise(frequency=0.005, relative=0.01))
    with pytest.raises(ValueError, match="n_modes"):
        sensitivities(model, GROUPS, sensors)
    with pytest.raises(ValueError, match="needs the test data"):
        identifiability(model, parameters=WELL_POSED)
