"""Acceptance of the updating loop on the thesis benchmark structures (§4.2, §4.3)."""

import csv

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.models import MODELS
from benchmarks.models.test_data import TREE_TABLE_4_6
from identification import ModalData, Sensors
from jaxfem.io import read_bdf
from updating import (Noise, Options, Parameter, ParameterSet, build_problem, parameter_std, parameterise, perturb,
                      simulate_test, update)


def _sensors(name):
    with open(MODELS / f"{name}_sensors.csv") as f:
        rows = list(csv.DictReader(f))
    return Sensors.from_components([int(r["node"]) for r in rows], [int(r["component"]) for r in rows])


def _simulate(truth, sensors, n_modes, skip=0):
    measured = simulate_test(truth, sensors, n_modes, skip=skip)
    return measured.frequencies_hz, measured.shapes


def test_tree_table_4_6_model_1_noise_free():
    """Thesis §4.3: the erroneous model 1 (blades 2 & 4 at 83 % stiffness) is updated with
    10 noise-free modes at the 49 measured DoFs; the factors return to the reference."""
    reference = jaxfem.build_model(read_bdf(MODELS / "tree.bdf"))
    err = TREE_TABLE_4_6[0]
    erroneous = jaxfem.correct(reference, [reference.element_ids(pids=err["pids"])], jnp.array([err["alpha"]]))
    sensors = _sensors("tree")
    assert len(sensors) == 49
    f, shapes = _simulate(reference, sensors, 10)
    params = (Parameter("blades_2_4", "stiffness", pids=(2, 4)), Parameter("blade_1", "stiffness", pids=(1,)),
              Parameter("blade_3", "stiffness", pids=(3,)), Parameter("pylon_upper", "stiffness", pids=(12,)))
    res = update(erroneous, ModalData(f, shapes, sensors), ParameterSet(params, Options(tolerance=1e-10)))
    assert res.converged
    expected = np.array([err["alpha_exact_correction"], 0.0, 0.0, 0.0])
    np.testing.assert_allclose(res.alpha[0], expected[0], rtol=1e-6)  # the erroneous group
    np.testing.assert_allclose(res.alpha[1:], 0.0, atol=1e-6)  # untouched groups stay at zero
    assert np.max(np.abs(res.history[-1].freq_dev)) * 100 < 1e-6  # Δf below 1e-6 %


GARTEUR_PARAMS = (
    Parameter("fuselage", "stiffness", pids=(1,)),
    Parameter("left_wing_root", "stiffness", pids=(11,)),
    Parameter("right_wing_mid", "stiffness", pids=(22,)),
    Parameter("fin", "stiffness", pids=(41,)),
    Parameter("wings_I2", "I2", pids=(11, 12, 13, 21, 22, 23)),
    Parameter("shakers", "m", eids=(804, 805)),
)
GARTEUR_TRUTH = np.array([0.06, -0.12, 0.08, -0.10, -0.05, 0.25])


@pytest.fixture(scope="module")
def garteur():
    model = jaxfem.build_model(read_bdf(MODELS / "garteur.bdf"))
    base, par = parameterise(model, GARTEUR_PARAMS)
    truth = par.apply(base, jnp.log1p(jnp.asarray(GARTEUR_TRUTH)))
    sensors = _sensors("garteur")
    n_rigid = 6  # three free (x, y, yaw) and three suspension modes
    f, shapes = _simulate(truth, sensors, 14, skip=n_rigid)
    assert f[0] > 3.0  # the first kept mode is elastic
    return model, sensors, f, shapes


def test_garteur_out_of_order_with_a_missing_mode(garteur):
    model, sensors, f, shapes = garteur
    order = [1, 0, 3, 2, 4, 6, 5, 7, 9, 8, 11, 10, 13]  # shuffled, test mode 13 (index 12) missing
    test = ModalData(f[order], shapes[:, order], sensors)
    res = update(model, test, ParameterSet(GARTEUR_PARAMS, Options(tolerance=1e-10)))
    assert res.converged
    np.testing.assert_allclose(res.alpha, GARTEUR_TRUTH, rtol=1e-6)
    # Pairing: test mode j is paired with the model mode of its true rank (+6 rigid).
    truth_rank = {j: order[j] + 6 for j in range(len(order))}
    assert dict(zip(res.after.test.tolist(), res.after.model.tolist())) == truth_rank
    assert len(res.after.unpaired_test) == 0


def test_garteur_noise_within_derived_tolerance(garteur):
    """1 % relative shape noise, 0.2 % frequency noise: each recovered factor within 5σ of
    the truth, σ from first-order propagation of the noise through the weighted residual
    Jacobian at the solution (Cov θ = J⁺ Σ J⁺ᵀ; see tests/test_update.py)."""
    model, sensors, f, shapes = garteur
    noise = Noise(frequency=0.002, relative=0.01)  # σ 0.2 % on the frequencies: 0.4 % on λ
    lam, phi = perturb(jax.random.key(7), noise, (2 * np.pi * f) ** 2, shapes)
    noisy = ModalData(np.asarray(jaxfem.frequencies_hz(lam)), np.asarray(phi), sensors)
    pset = ParameterSet(GARTEUR_PARAMS, Options(tolerance=1e-8))
    res = update(model, noisy, pset)
    assert res.converged
    problem = build_problem(model, ModalData(f, shapes, sensors), pset)
    theta = jnp.log1p(jnp.asarray(GARTEUR_TRUTH))
    sigma = parameter_std(problem, theta, noise)
    err = np.abs(res.alpha - GARTEUR_TRUTH)
    assert np.all(err <= 5 * sigma), (err, sigma)
    assert np.all(sigma < 0.1)
