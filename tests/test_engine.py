"""The updating engine, its least-squares kernel and the measurement simulation."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import pytest

import jaxfem
from benchmarks.frames import frame_bdf
from identification import Sensors
from jaxfem.io import read_bdf_text
from updating import Noise, Options, Parameter, ParameterSet, build_problem, n_model_modes, parameterise, \
    perturb, simulate_test
from updating._compiled import Compiled
from updating._eigensolvers import Direct
from updating._engine import Settings, linearise, run
from updating._qr import HouseholderQR
from updating._residuals import residuals

ALPHA = np.array([0.12, -0.08, 0.05])


@pytest.fixture(scope="module")
def frame():
    model = jaxfem.build_model(read_bdf_text(frame_bdf(2, 2, 3, n_groups=6), name="frame"))
    params = (Parameter("a", "stiffness", pids=(1, 2)), Parameter("b", "stiffness", pids=(3, 4)),
              Parameter("c", "stiffness", pids=(5, 6)))
    base, par = parameterise(model, params)
    truth = par.apply(base, jnp.log1p(jnp.asarray(ALPHA)))
    free = model.node_ids[(model.node_ids > 4) & (model.node_ids < 900000)]
    sensors = Sensors.from_components(np.repeat(free, 2), np.tile([1, 2], len(free)))
    return model, ParameterSet(params, Options(tolerance=1e-9, solver="gauss-newton")), truth, sensors


def test_run_converges_and_keeps_its_history(frame):
    """From α = 0 to the truth; the history's rows are the accepted iterates, row 0 the
    start with its cost ½‖ε(0)‖²; the last accepted change is within the tolerance."""
    model, pset, truth, sensors = frame
    problem = build_problem(model, simulate_test(truth, sensors, 6), pset)
    settings = Settings.from_options(pset.options)
    state = Compiled(run)(jnp.zeros(3), problem, Direct(), jnp.zeros(0), settings)
    assert bool(state.converged) and state.theta.dtype == jnp.float64
    n = int(state.accepted)
    np.testing.assert_allclose(np.expm1(state.theta), ALPHA, rtol=1e-7)
    h = state.history
    eps, _ = residuals(jnp.zeros(3), problem)
    np.testing.assert_allclose(float(h.cost[0]), 0.5 * sum(float(jnp.sum(v ** 2)) for v in eps.values()), rtol=1e-10)
    np.testing.assert_allclose(h.alpha[0], 0.0)
    np.testing.assert_allclose(h.alpha[n], np.expm1(state.theta))
    assert np.all(np.isnan(np.asarray(h.cost[n + 1:])))
    assert np.all(np.diff(np.asarray(h.cost[: n + 1])) < 0)  # Gauss–Newton near a zero-residual solution
    assert float(state.change) <= 1e-9
    np.testing.assert_allclose(np.asarray(h.freq_dev[n]), 0.0, atol=1e-9)


def test_a_damped_step_that_is_short_is_not_convergence(frame):
    """Levenberg–Marquardt damps its first steps (λ = 1): with residuals 1000× smaller
    (JᵀJ ~ 1e-6) the first step moves α by ~1e-7, within any tolerance; the fit must
    still go on to the truth, for the Gauss–Newton step from there is not small."""
    model, pset, truth, sensors = frame
    problem = build_problem(model, simulate_test(truth, sensors, 6), pset)
    small = dataclasses.replace(problem, lam_weight=1e-3 * jnp.ones_like(problem.lam_weight), use_phi=False)
    state = Compiled(run)(jnp.zeros(3), small, Direct(), jnp.zeros(0), Settings(False, 1e-3, 50, 50, relative=True))
    assert bool(state.converged) and int(state.accepted) > 3
    np.testing.assert_allclose(np.expm1(state.theta), ALPHA, atol=2e-3)


def test_the_loop_keeps_the_jacobian_at_its_theta(frame):
    """The Jacobian the loop returns is that of a fresh linearisation at its θ: at the
    last accepted iterate of a Levenberg–Marquardt fit stopped early, and at θ₀ when the
    run only evaluates (``skip`` with ``evaluate_skipped``), where it takes no step."""
    model, pset, truth, sensors = frame
    problem = build_problem(model, simulate_test(truth, sensors, 6), pset)
    lm = Settings(False, 1e-9, 2, 8)
    theta0 = jnp.asarray([0.05, 0.0, -0.02])
    for skip in (False, True):
        state = Compiled(run)(theta0, problem, Direct(), jnp.zeros(0), lm, jnp.asarray(skip), None, True)
        eps, jac, aux = linearise(state.theta, problem, jnp.zeros(0), Direct())
        assert bool(jnp.all(state.theta == theta0)) == skip and state.jacobian.dtype == jnp.float64
        np.testing.assert_allclose(state.jacobian, jac, rtol=1e-12, atol=1e-12 * float(jnp.max(jnp.abs(jac))))
        np.testing.assert_allclose(state.evaluation.lam_a, aux.ev.lam_a, rtol=1e-12)


def test_a_padded_fit_is_the_unpadded_fit(frame):
    """A diagnosis' fit pads θ with inert entries (one compiled fit for extensions of one
    and of two parameters): θ, costs and Jacobian are those of the loop run unpadded."""
    from updating.diagnosis._fit import Fits, _cost_parts, with_extension
    from updating._extension import extension

    model, pset, truth, sensors = frame
    problem = build_problem(model, simulate_test(truth, sensors, 6), pset)
    beams = np.asarray(problem.model(jnp.zeros(3)).beams.ids)
    ext = extension(problem.model(jnp.zeros(3)), k_log=beams[:3])
    p = with_extension(problem, ext, np.ones(6, bool))
    settings = Settings(False, 1e-10, 30, 120)
    theta0 = jnp.asarray([0.0, 0.0, 0.0, 0.2])
    state = Compiled(run)(theta0, p, Direct(), jnp.zeros(0), settings)
    theta, (cf, cs), _, lam_a, _, _, jac = Fits(settings).solve(theta0, p)
    assert theta.shape == (4,) and jac.shape == (state.jacobian.shape[0] - 4, 4)
    np.testing.assert_allclose(theta, state.theta, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose([cf, cs], _cost_parts(state.theta, p, p.active, state.evaluation), rtol=1e-7,
                               atol=1e-9 * float(state.history.cost[0]))  # both near zero: the truth is reachable
    np.testing.assert_allclose(jac, state.jacobian[:-4], rtol=1e-6, atol=1e-9 * float(jnp.max(jnp.abs(jac))))


def test_iteration_cap_is_not_convergence(frame):
    model, pset, truth, sensors = frame
    problem = build_problem(model, simulate_test(truth, sensors, 6), pset)
    state = Compiled(run)(jnp.zeros(3), problem, Direct(), jnp.zeros(0), Settings(True, 1e-12, 2, 8))
    assert int(state.accepted) == 2 and not bool(state.converged)


def test_vmapped_runs_equal_single_runs(frame, key):
    """Two noisy samples in one vmapped run give the single runs' factors."""
    model, pset, truth, sensors = frame
    problem = build_problem(model, simulate_test(truth, sensors, 6), pset)
    settings = Settings.from_options(pset.options)
    noise = Noise(frequency=0.002, relative=0.01)
    data = [simulate_test(truth, sensors, 6, noise, k) for k in jax.random.split(key, 2)]
    lam = jnp.stack([(2 * jnp.pi * jnp.asarray(d.frequencies_hz)) ** 2 for d in data])
    phi = jnp.stack([jnp.asarray(d.shapes) for d in data])

    def one(lam_e, phi_e, problem):
        p = eqx.tree_at(lambda q: (q.lam_e, q.phi_e), problem, (lam_e, phi_e))
        return run(jnp.zeros(3), p, Direct(), jnp.zeros(0), settings).theta

    batched = Compiled(jax.vmap(one, in_axes=(0, 0, None)))(lam, phi, problem)
    single = [Compiled(one)(lam[i], phi[i], problem) for i in range(2)]
    np.testing.assert_allclose(batched, np.stack(single), atol=1e-10)
    assert float(jnp.max(jnp.abs(batched[0] - batched[1]))) > 1e-6  # the samples differ


def test_householder_qr_is_least_squares(key):
    A = jax.random.normal(key, (3, 12, 4), dtype=jnp.float64)
    b = jax.random.normal(jax.random.fold_in(key, 1), (3, 12), dtype=jnp.float64)
    solve = jax.vmap(lambda A, b: lx.linear_solve(lx.MatrixLinearOperator(A), b, HouseholderQR()).value)
    x = solve(A, b)
    for i in range(3):
        np.testing.assert_allclose(x[i], np.linalg.lstsq(A[i], b[i], rcond=None)[0], rtol=1e-10)
    with pytest.raises(ValueError, match="underdetermined"):
        lx.linear_solve(lx.MatrixLinearOperator(A[0].T), b[0, :4], HouseholderQR())


def test_frequency_error_multiplies_the_eigenvalue(key):
    """λ̃ = λ (1 + δ), δ ~ N(0, σ_λ²) with σ_λ = 2 σ_f (thesis §4.3.3.2; the noise is stated on
    f): the draw is exactly the key's normal numbers; relative and absolute shape errors as
    Table 4.7, whose frequency magnitude is σ_λ (Noise.table_4_7)."""
    lam = jnp.linspace(1e3, 2e4, 2000)
    phi = jnp.ones((5, 2000)) * jnp.arange(1.0, 6.0)[:, None]
    lam_f, phi_f = perturb(key, Noise(frequency=0.01), lam, phi)
    z = jax.random.normal(jax.random.split(key)[1], lam.shape, dtype=lam.dtype)
    np.testing.assert_allclose(lam_f, lam * (1 + 0.02 * z), rtol=1e-14)
    np.testing.assert_allclose(phi_f, phi)
    assert abs(float(jnp.std(jnp.sqrt(lam_f / lam) - 1)) - 0.01) < 1e-3  # about σ_f on the frequency
    assert Noise.table_4_7(frequency=0.02).eigenvalue == 0.02 and Noise.table_4_7(frequency=0.02).frequency == 0.01
    _, phi_r = perturb(key, Noise(relative=0.05), lam, phi)
    assert abs(float(jnp.std(phi_r / phi - 1)) - 0.05) < 3e-3
    _, phi_a = perturb(key, Noise(absolute=0.01), lam, phi)
    err = (phi_a - phi) / 5.0  # the mode's largest component is 5
    assert float(jnp.max(jnp.abs(err))) <= 0.01 and abs(float(jnp.std(err)) - 0.01 / np.sqrt(3)) < 3e-4


def test_simulate_test_skips_and_measures(frame):
    model, _, truth, sensors = frame
    full = simulate_test(truth, sensors, 6)
    skipped = simulate_test(truth, sensors, 4, skip=2)
    np.testing.assert_allclose(skipped.frequencies_hz, full.frequencies_hz[2:], rtol=1e-10)
    assert full.shapes.shape == (len(sensors), 6) and full.shapes.dtype == np.float64
    with pytest.raises(ValueError, match="key"):
        simulate_test(truth, sensors, 6, Noise(relative=0.01))


def test_one_rule_for_the_number_of_model_modes(frame):
    model = frame[0]
    n_free = model.n_dof - len(model.dofs.massless)
    assert n_model_modes(model, 5) == 11 and n_model_modes(model, 10) == 20
    assert n_model_modes(model, 5, 9) == 9
    assert n_model_modes(model, 10 * n_free) == n_free


def test_a_scan_cost_is_the_cost_of_a_fit_without_a_step(frame):
    """A diagnosis' scan point (``Fits.cost``, its own compiled function without step or
    Jacobian) costs what the fit evaluated at θ₀ without a step does."""
    from updating.diagnosis._fit import Fits, with_extension
    from updating._extension import extension

    model, pset, truth, sensors = frame
    problem = build_problem(model, simulate_test(truth, sensors, 6), pset)
    beams = np.asarray(problem.model(jnp.zeros(3)).beams.ids)
    p = with_extension(problem, extension(problem.model(jnp.zeros(3)), k_log=beams[:3]), np.ones(6, bool))
    fits = Fits(Settings(False, 1e-10, 30, 120))
    for theta0 in ([0.0, 0.0, 0.0, 0.2], [0.1, -0.2, 0.0, -1.5]):
        cost = fits.cost(theta0, p)
        assert cost > 0
        np.testing.assert_allclose(cost, float(sum(fits.solve(theta0, p, skip=True)[1])), rtol=1e-10)
