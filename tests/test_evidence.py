"""The evidence of a candidate effect: the Laplace approximation against the exact
marginal likelihood of a linear-Gaussian model, and the verdict's three outcomes."""

import numpy as np

import updating
import pytest

from updating.diagnosis._evidence import log_evidence


def test_laplace_is_exact_for_a_linear_gaussian_model():
    """r(θ) = y − Aθ, noise σ², prior N(μ, diag s²): at the posterior mode the Laplace
    approximation is the exact ln Z (up to the data's normalisation, common to all models)."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((40, 3))
    y = A @ np.array([0.3, -0.2, 0.5]) + 0.05 * rng.standard_normal(40)
    sigma2, mu, sd = 0.05 ** 2, np.array([0.0, 0.1, 0.0]), np.array([1.0, 0.5, 2.0])
    P = np.diag(1 / sd ** 2)
    H = A.T @ A / sigma2 + P
    theta = np.linalg.solve(H, A.T @ y / sigma2 + P @ mu)  # the posterior mode
    r = y - A @ theta
    lz, occam, post_sd = log_evidence(theta, float(r @ r), -A, mu, sd, sigma2)
    # exact: y ~ N(Aμ, σ²I + A S Aᵀ); drop −(n/2) ln(2πσ²) as log_evidence does
    C = sigma2 * np.eye(40) + A @ np.diag(sd ** 2) @ A.T
    d = y - A @ mu
    exact = -0.5 * d @ np.linalg.solve(C, d) - 0.5 * np.linalg.slogdet(C)[1] + 20 * np.log(sigma2)
    assert lz == pytest.approx(exact, rel=1e-10)
    assert occam == pytest.approx(lz + 0.5 * r @ r / sigma2, rel=1e-12)
    np.testing.assert_allclose(post_sd, np.sqrt(np.diag(np.linalg.inv(H))), rtol=1e-10)
    assert log_evidence(None, np.inf, None, mu, sd, sigma2)[0] == -np.inf  # a failed fit ranks last


def _result(where="node 214", chi2=1.1, log_z=250.0):
    from updating.diagnosis import CandidateResult, Checks

    effect = updating.Effect("added_mass", nodes=(int(where.split()[-1]),), values={"m": 0.4})
    return CandidateResult(effect, 1, 0.97, log_z, 0.0, (0.1,), "add 0.4 kg (±0.05 kg) at grid 214", 0.0, None, None,
                           chi2, 0.9, 0.21, 3, None, None, None, (), True, Checks(*[True] * 5), True)


def _verdict(outcome, chi2_base, effects=(), ties=()):
    from updating.diagnosis import Baseline
    from updating.diagnosis._verdict import verdict

    return verdict(outcome, tuple(effects), tuple(ties), Baseline((), 1.0, 0.9, 0.9, 0.9, chi2_base, 1.0, 1.0))


def test_verdict_says_what_to_do_or_that_nothing_single_explains_the_data():
    e = _result()
    assert _verdict("effect", 30.0, [e]) == (
        "Add 0.4 kg (±0.05 kg) at grid 214: held-out frequency error 0.90 % → 0.21 % (posterior probability 0.97).")
    tie = _result("node 215")
    assert "cannot tell it apart from node 215" in _verdict("effect", 30.0, [e], [tie])
    assert "more than this one effect" in _verdict("effect", 30.0, [_result(chi2=9.0)])
    text = _verdict("unexplained", 417.0, [_result(chi2=300.0)])
    assert text.startswith("No single effect explains the data") and "417" in text and "model form" in text
    assert "added_mass at node 214" in text  # the best partial candidate
    assert _verdict("none_needed", 0.9).startswith("No extra effect is warranted")


def test_scan_start_refines_the_first_factor_about_the_best_point(monkeypatch):
    """A heavy added mass pairs every mode only in a narrow valley (the 33k barrel's 20 kg:
    θ ≈ 0.9 ± 0.2, between the grid's 0 and 1.5): the scan is refined about its best point
    and starts there; a scan of two factors is refined along the first (a 20 kg box's
    mass, its CG height held: the valley is e^±0.2 wide in the mass)."""
    from updating.diagnosis import _fit as _evidence

    calls = []

    def costs(fits, problem, ext, theta_b, grid, solver):
        calls.append(len(grid))
        return np.array([1.0 if np.ndim(t) == 0 and abs(t - 0.9) < 0.2
                         or np.ndim(t) == 1 and abs(t[0] - 2.0) < 0.2 and t[1] == 0.3
                         else 500.0 + np.sum(np.abs(np.subtract(t, 1.5))) for t in grid])

    monkeypatch.setattr(_evidence, "scan_costs", costs)
    assert _evidence.scan_start(None, None, None, np.zeros(0), (0.0, -1.5, -3.0, 1.5)) == pytest.approx([1.0])
    assert calls == [4, 4]
    calls.clear()
    np.testing.assert_array_equal(_evidence.scan_start(None, None, None, np.zeros(0), ((0.0, 0.0), (1.5, 0.3))),
                                  [2.0, 0.3])
    assert calls == [2, 4]


def test_a_fit_whose_model_fails_in_a_host_check_is_reported_not_ranked(monkeypatch):
    """A trial step that makes the model fail a check in a host callback (K + σM not
    positive definite) reaches the fit as a RuntimeError or, on a thread, as a ValueError
    naming the callback: the candidate gets cost inf and the error; other errors propagate."""
    from types import SimpleNamespace

    import updating.diagnosis._fit as ev
    from updating.diagnosis._fit import fit

    monkeypatch.setattr(ev, "with_extension", lambda problem, *a: problem)
    problem = SimpleNamespace(lam_e=np.ones(3))
    for err in (RuntimeError("K + σM is not positive definite"),
                ValueError("INTERNAL: CpuCallback error calling callback: K + σM is not positive definite")):
        def fail(*args, err=err):
            raise err

        res = fit(SimpleNamespace(solve=fail), problem, None, np.zeros(2))
        assert res.cost == np.inf and np.isnan(res.freq_dev).all() and res.error == str(err)
    def other(*args):
        raise ValueError("shapes differ")

    with pytest.raises(ValueError, match="shapes"):
        fit(SimpleNamespace(solve=other), problem, None, np.zeros(2))
