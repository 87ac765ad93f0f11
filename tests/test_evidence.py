"""The evidence of a candidate effect: the Laplace approximation against the exact
marginal likelihood of a linear-Gaussian model, and the verdict's states."""

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


def _result(where="node 214", chi2=1.1, log_z=250.0, passed=True, worse=()):
    from updating.diagnosis import CandidateResult, Checks

    effect = updating.Effect("added_mass", nodes=(int(where.split()[-1]),), values={"m": 0.4})
    checks = Checks(True, True, passed, True, True, not worse)
    return CandidateResult(
        effect=effect, rank=1, posterior=0.97, log_evidence=log_z, log_occam=0.0, theta_sd=(0.1,),
        advice="add 0.4 kg (±0.05 kg) at grid 214", delta_aic=0.0, score=None, screen=None, chi2_per_row=chi2,
        heldout_rms_freq_dev_pct_before=0.9, heldout_rms_freq_dev_pct_after=0.21, heldout_modes_compared=3,
        heldout_worse_modes=tuple(worse), heldout_mean_mac_before=None, heldout_mean_mac_after=None,
        rms_freq_dev_pct_after=None, plausibility=(), cross_validated=True, checks=checks,
        warranted=passed and not worse)


def _fit(freq_dev_pct, chi2_freq, chi2_shape, rows=(10, 100), sigma2=1.0):
    from updating.diagnosis import Fit

    n_f, n_s = rows
    d = np.asarray(freq_dev_pct, float) / 100
    return Fit(np.zeros(1), (chi2_freq * n_f + chi2_shape * n_s) * sigma2, chi2_freq * n_f * sigma2,
               chi2_shape * n_s * sigma2, d, np.ones(len(d)), None)


def _state(outcome, chi2_base, effects=(), ties=(), declared=(), final=None, base=None, withdrawn=None):
    """The state the numbers give and its sentence."""
    from updating.diagnosis import Baseline
    from updating.diagnosis._verdict import state, verdict

    b = Baseline((), 1.0, 0.9, 0.9, 0.9, chi2_base, 1.0, 1.0)
    final = final or base
    s = state(outcome, tuple(effects), tuple(declared), base, final)
    return s, verdict(s, tuple(effects), tuple(ties), b, tuple(declared), final, base, withdrawn)


NOISE_F = 0.002
AT_NOISE = _fit(np.full(10, 0.2), 1.0, 1.0)  # Δf at 1σ in every mode
UNDERSTATED = _fit(np.resize([1.0, -1.0], 10), 25.0, 9.0)  # 5σ in every mode alike: noise understated
TWO_MODES_OFF = _fit([0.2, -0.2, 3.0, 0.2, -0.2, 0.2, -2.5, 0.2, -0.2, 0.2], 38.0, 6.0)


def test_remainder_tells_noise_from_modes_left_off():
    from updating.diagnosis._evidence import remainder

    r = remainder(AT_NOISE, 1.0, NOISE_F, (10, 100))
    assert r.at_noise and r.noise_like and r.off == () and r.chi2_per_row == pytest.approx(1.0)
    u = remainder(UNDERSTATED, 1.0, NOISE_F, (10, 100))
    assert not u.at_noise and u.noise_like and u.freq_scale == pytest.approx(5.0) and u.shape_scale == pytest.approx(3.0)
    t = remainder(TWO_MODES_OFF, 1.0, NOISE_F, (10, 100))
    assert not t.noise_like and [j for j, _ in t.off] == [3, 7] and t.off[0][1] == pytest.approx(3.0)


def test_each_verdict_state_from_its_numbers():
    """One sentence per state, derived from the numbers (issue 46, item 5)."""
    from updating.diagnosis._evidence import remainder
    from updating.diagnosis._verdict import Declared, Withdrawn

    left = lambda f: remainder(f, 1.0, NOISE_F, (10, 100))  # noqa: E731
    e = _result()
    one = (Declared(1, e, None),)
    s, text = _state("effect", 30.0, [e], declared=one, final=left(AT_NOISE), base=left(TWO_MODES_OFF))
    assert s == "effect" and text == (
        "Add 0.4 kg (±0.05 kg) at grid 214: held-out frequency error 0.90 % → 0.21 % (posterior probability 0.97). "
        "With it the model explains the data to the stated noise (χ² per row 1.00).")
    s, text = _state("effect", 30.0, [e], [_result("node 215")], one, left(UNDERSTATED), left(TWO_MODES_OFF))
    assert s == "effect" and "cannot tell the last from node 215" in text
    assert "spread over all modes like noise" in text and "frequencies ×5.0, shapes ×3.0" in text
    assert "more than" not in text and "missing" not in text
    s, text = _state("none_needed", 30.0, [e], declared=one, final=left(TWO_MODES_OFF), base=left(TWO_MODES_OFF))
    assert s == "partial" and "Partially explained: modes 3 (+3.00 %), 7 (−2.50 %)".replace("−", "-") in text
    s, text = _state("none_needed", 1.0, [_result(chi2=0.9, passed=False)], base=left(AT_NOISE))
    assert s == "none_needed" and text.startswith("No extra effect is warranted: the baseline explains the data")
    assert "most probable candidate, added_mass at node 214 (χ²/row 0.90), is not confirmed: it does not lower "            "the held-out frequency error beyond noise" in text
    s, text = _state("none_needed", 17.0, [_result(chi2=16.0, log_z=2.0, passed=False)], base=left(UNDERSTATED))
    assert s == "none_needed" and "misfit (χ² per row 17.0) is spread over all modes like noise" in text
    s, text = _state("none_needed", 30.0, [_result(chi2=1.2, worse=(12,))], base=left(TWO_MODES_OFF))
    assert s == "unconfirmed" and text.startswith("added_mass at node 214 fits the data to the stated noise")
    assert "held-out modes worse beyond noise (mode 12)" in text and "outside" not in text
    s, text = _state("none_needed", 417.0, [_result(chi2=300.0, passed=False)], base=left(TWO_MODES_OFF))
    assert s == "unexplained" and text.startswith("No effect in the library explains the data") and "417" in text
    assert "model form" in text and "added_mass at node 214 (χ²/row 300.0)" in text and "modes 3 (+3.00 %)" in text
    ties = [_result("node 230", log_z=249.5), _result("node 301", log_z=249.8)]
    s, text = _state("cannot_localise", 30.0, [e], ties, base=left(TWO_MODES_OFF))
    assert s == "cannot_localise" and "equally well at node 214, node 230, node 301" in text
    w = Withdrawn(e, "its confirming update made passive mode 12 (-0.06 % → -6.87 %) worse beyond 2σ of the "
                     "frequency noise")
    s, text = _state("none_needed", 417.0, [_result(chi2=300.0, passed=False)], base=left(TWO_MODES_OFF), withdrawn=w)
    assert s == "unexplained" and text.endswith("added_mass at node 214 was withdrawn: its confirming update made "
                                                "passive mode 12 (-0.06 % → -6.87 %) worse beyond 2σ of the frequency noise.")


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
