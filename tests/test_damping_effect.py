"""The ``damping`` effect: element loss factors in the model and the diagnosis that finds a
local one from measured modal damping beyond uniform damping (Rayleigh and a loss factor
η0 on the whole structure), or says that uniform damping explains the ratios, or that
nothing among the candidates does: one verdict sentence per outcome, from its numbers.

References: K of the loss-factor elements from :func:`jaxfem.correct` (eq. 3.1) and a
uniform loss factor's modal loss factors (η for every mode); a direct complex solve for
the FRF; and, as the measurement, FRFs of the cantilever with a hysteretic loss in one
element (a direct solve per line, :func:`benchmarks.damage_demo.simulate_frf`), the
modes identified from them by SDOF inverse-FRF fits (thesis eq. 3.34–3.37).
"""

from dataclasses import asdict

import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks import damage_demo as dd
from identification import ModalData, Sensors, observation_matrix
from updating import LocalDamping, Noise, diagnose_damping, parse_effect
from updating.diagnosis._damping import regions

LOSS_ELEMENT, LOSS = 7, 0.15  # the truth: a loss factor in one element of the cantilever, no stiffness change


@pytest.fixture(scope="module")
def beam():
    return dd.build()


def test_loss_factors_enter_as_element_stiffness(beam):
    model, _, _ = beam
    K, M = jaxfem.assemble(model)
    lam, phi = jaxfem.eigh(K, M, 6)
    energies = jaxfem.element_strain_energies(model, phi)
    assert energies.dtype == jnp.float64 and energies.shape == (dd.N_ELEMENTS, 6)
    # Σ_e φᵀK_eφ = λ to rounding: the dense solve's λ₁ carries about ε‖K‖ (2.6e-10 relative on one machine's LAPACK)
    np.testing.assert_allclose(np.asarray(energies).sum(axis=0), np.asarray(lam), rtol=1e-9)

    everywhere = LocalDamping(eids=tuple(range(1, dd.N_ELEMENTS + 1)), eta=0.04).apply(model)
    np.testing.assert_allclose(np.asarray(jaxfem.modal_loss_factors(everywhere, lam, phi)), 0.04, rtol=1e-9)  # η Σ_e/λ

    patch = parse_effect("damping:eids=6-8").updated([0.2]).apply(model)
    k_without = np.asarray(jaxfem.assemble(jaxfem.correct(model, [[6, 7, 8]], jnp.array([-1.0])))[0].todense())
    G = np.asarray(jaxfem.damping_matrix(patch).todense())
    np.testing.assert_allclose(G, 0.2 * (np.asarray(K.todense()) - k_without), atol=1e-9 * np.abs(G).max())
    again = LocalDamping(eids=(8, 9), eta=0.5).apply(patch)  # element 8 takes the newer factor
    assert dict(zip(again.damping.eids, np.asarray(again.damping.eta).tolist())) == {6: 0.2, 7: 0.2, 8: 0.5, 9: 0.5}
    assert jaxfem.modal_loss_factors(model, lam, phi).tolist() == [0.0] * 6  # no damping set

    k, m, g = (np.asarray(a) for a in (K.todense(), M.todense(), G))
    w = np.array([50.0, 400.0])
    h = jaxfem.frf_direct(k, m, w, [5, 9], [9], G=g, eta=0.01)
    direct = np.linalg.inv((1 + 0.01j) * k[None] - w[:, None, None] ** 2 * m[None] + 1j * g[None])
    np.testing.assert_allclose(np.asarray(h), direct[:, [5, 9]][:, :, [9]], rtol=1e-10)
    with pytest.raises(ValueError, match="modal update cannot fit it"):
        LocalDamping(eids=(7,), eta=0.1).parameters(model, model)


def test_regions_hold_groups_elements_and_the_ladder(beam):
    model, _, _ = beam
    found = {r.where(): set(r.eids) for r in regions(model)}
    assert found["the 20 elements of pid 1"] == set(range(1, 21))
    assert found["element 7"] == {7}
    assert {6, 7} in found.values()  # the two elements at grid 7
    assert all(len(r.eids) for r in regions(model))
    assert len({frozenset(e) for e in found.values()}) == len(found)  # each set of elements once


def _identified(model, mu, kappa, elements, seed=0):
    """Modes identified from the tip's driving-point FRF (1 % complex noise per line) of the
    cantilever with loss factor LOSS in ``elements``."""
    lam, phi = jaxfem.eigh(*jaxfem.assemble(model), dd.N_MODES)
    tip = dd.dof_index(model, dd.N_ELEMENTS + 1, 2)
    lines = dd.frequency_lines()
    h = dd.simulate_frf(model, mu, kappa, lines, tip, tip, elements=elements, loss=LOSS)
    e = np.random.default_rng(seed).standard_normal((2, len(h)))
    f, zeta = dd.identify(lines, h * (1.0 + 0.01 * (e[0] + 1j * e[1]) / np.sqrt(2.0)),
                          np.asarray(jaxfem.frequencies_hz(lam)))
    return f, zeta, np.asarray(phi)


def test_a_local_loss_factor_is_found_from_frfs(beam, tmp_path):
    """The truth: hysteretic loss in element 7 (exact complex stiffness), Rayleigh damping;
    measured at the tip, identified by SDOF fits, written to a universal file with the
    model's shapes at ten grids. The diagnosis' model is first order (modal strain energy
    on the real modes): through ``jaxfem diagnose`` element 7 ranks first, η within 5 % of
    the truth, held-out damping error below 2× the stated noise, the damping table and
    plot in the report; the structural diagnosis finds nothing to add. Its control
    (Rayleigh only) claims nothing."""
    import json

    from typer.testing import CliRunner

    from identification import write_uff
    from updating.cli import app

    model, mu, kappa = beam
    f, zeta, phi = _identified(model, mu, kappa, (LOSS_ELEMENT,))
    grids = list(range(3, dd.N_ELEMENTS + 2, 2))
    sensors = Sensors.from_components(grids, [2] * len(grids))
    C, _ = observation_matrix(model, sensors)
    test = ModalData(f, np.asarray(C) @ phi, sensors, damping_ratios=zeta)
    (tmp_path / "beam.bdf").write_text(dd.cantilever_bdf())
    write_uff(tmp_path / "modes.uff", modes=test)
    noise = 0.05
    result = CliRunner().invoke(app, ["diagnose", str(tmp_path / "beam.bdf"), str(tmp_path / "modes.uff"),
                                      "--json", str(tmp_path / "d.json"), "--report", str(tmp_path / "report"),
                                      "--noise-damping", str(100 * noise)])
    assert result.exit_code == 0, result.output
    rep = json.loads((tmp_path / "d.json").read_text())
    assert rep["outcome"] != "effect" and "after" not in rep
    d = rep["damping"]
    top = d["effects"][0]
    assert d["outcome"] == "effect" and top["eids"] == [LOSS_ELEMENT] and top["warranted"]
    assert top["where"] == f"element {LOSS_ELEMENT}" and top["posterior"] > 0.95
    assert abs(top["eta"] - LOSS) < 0.05 * LOSS
    assert top["heldout_rms_zeta_dev_pct_after"] < 2 * 100 * noise < top["heldout_rms_zeta_dev_pct_before"]
    assert rep["verdict"].endswith(d["verdict"]) and "Give element 7 a structural loss factor" in d["verdict"]
    assert d["baseline"]["eta0"] >= 0 and d["baseline"]["eta0_sd"] > 0 and top["checks"]["heldout_at_noise"]
    assert "element 7" in result.output and "Damping: a local loss factor" in (tmp_path / "report/report.html").read_text()
    assert (tmp_path / "report/damping.png").exists()

    f0, zeta0, _ = _identified(model, mu, kappa, ())
    control = diagnose_damping(model, ModalData(f0, test.shapes, sensors, damping_ratios=zeta0), noise=Noise(damping=noise))
    assert control.outcome == "none_needed" and control.effect is None
    assert control.baseline.heldout_rms_zeta_dev_pct < 2 * 100 * noise


def _exact(model, zeta_of, seed, scatter):
    """The beam's own modes seen at ten grids, with damping ratios ``zeta_of(ω, λ, φ)`` and
    ``scatter`` × a standard normal (fixed ``seed``) of multiplicative noise on each."""
    lam, phi = jaxfem.eigh(*jaxfem.assemble(model), dd.N_MODES)
    grids = list(range(3, dd.N_ELEMENTS + 2, 2))
    sensors = Sensors.from_components(grids, [2] * len(grids))
    C, _ = observation_matrix(model, sensors)
    zeta = zeta_of(np.sqrt(np.asarray(lam)), lam, phi)
    zeta = zeta * (1 + scatter * np.random.default_rng(seed).standard_normal(len(zeta)))
    return ModalData(np.asarray(jaxfem.frequencies_hz(lam)), np.asarray(C) @ np.asarray(phi), sensors,
                     damping_ratios=zeta)


def _uniform_part(u) -> str:
    return f"Rayleigh μ = {u.mu:.3g} 1/s, κ = {u.kappa:.3g} s, loss factor η0 = {u.eta0:.3g} (±{u.eta0_sd:.2g})"


def test_uniform_damping_is_no_local_effect(beam):
    """ζ = 0.5 % in every mode, 10 % noise on each ratio (the hidden-case trial): Rayleigh
    alone cannot make a constant ζ, a uniform loss factor η0 = 2ζ can, so no region is
    declared and η0 is found within its σ."""
    model, _, _ = beam
    found = diagnose_damping(model, _exact(model, lambda w, lam, phi: np.full(len(w), 0.005), 0, 0.1),
                             noise=Noise(damping=0.1))
    b = found.baseline
    assert found.outcome == "none_needed" and found.effect is None and b.at_noise
    assert not any(r.warranted for r in found.regions) and found.regions[0].posterior < 0.5
    assert abs(b.uniform.eta0 - 0.01) < 2 * b.uniform.eta0_sd < 0.002
    assert found.noise_scale == b.chi2_per_row  # reported, not used
    assert found.verdict == (f"No local damping effect: uniform damping ({_uniform_part(b.uniform)}) explains the "
                             f"measured ratios to the stated noise (χ²/row {b.chi2_per_row:.2f} at 10 % on each ratio).")
    assert found.verdict.startswith("No local damping effect: uniform damping (Rayleigh μ = ")
    base = found.to_json()["baseline"]
    assert base["eta0"] == b.uniform.eta0 and base["eta0_sd"] == b.uniform.eta0_sd and base["at_noise"]
    assert "the 20 elements of pid 1" not in {r.effect.where() for r in found.regions}  # the whole beam is η0


def test_rayleigh_damping_alone_is_no_local_effect(beam):
    """Rayleigh damping as the benchmark's, 10 % noise on each ratio: nothing declared, η0 ≈ 0."""
    model, mu, kappa = beam
    found = diagnose_damping(model, _exact(model, lambda w, lam, phi: mu / (2 * w) + kappa * w / 2, 0, 0.1),
                             noise=Noise(damping=0.1))
    u = found.baseline.uniform
    assert found.outcome == "none_needed" and found.effect is None
    assert 0 <= u.eta0 < 2 * u.eta0_sd and abs(u.mu / mu - 1) < 0.2 and abs(u.kappa / kappa - 1) < 0.2
    assert found.verdict.startswith(f"No local damping effect: uniform damping ({_uniform_part(u)}) explains")


def test_a_local_loss_factor_is_declared_on_top_of_uniform_damping(beam):
    """Rayleigh damping, a uniform η0 = 0.004 and η = 0.15 in element 7, the first-order
    ratios with 2 % noise (stated 5 %): element 7 is declared with both parts."""
    model, mu, kappa = beam
    local = LocalDamping(eids=(LOSS_ELEMENT,), eta=LOSS).apply(LocalDamping(
        eids=tuple(range(1, dd.N_ELEMENTS + 1)), eta=0.004).apply(model))

    def zeta(w, lam, phi):
        return mu / (2 * w) + kappa * w / 2 + 0.5 * np.asarray(jaxfem.modal_loss_factors(local, lam, phi))

    found = diagnose_damping(model, _exact(model, zeta, 0, 0.02), noise=Noise(damping=0.05))
    top = found.regions[0]
    assert found.outcome == "effect" and found.effect.eids == (LOSS_ELEMENT,) and top.warranted
    assert all(asdict(top.checks).values()) and top.posterior >= 0.5
    assert abs(top.eta - LOSS) < 3 * top.eta_sd and abs(top.uniform.eta0 - 0.004) < 3 * top.uniform.eta0_sd
    assert found.noise_scale == top.chi2_per_row
    assert found.verdict == (f"Give element 7 a structural loss factor η = {top.eta:.3g} (±{top.eta_sd:.2g}) on top "
                             f"of uniform damping ({_uniform_part(top.uniform)}): held-out damping error "
                             f"{top.heldout_rms_zeta_dev_pct_before:.1f} % → {top.heldout_rms_zeta_dev_pct_after:.1f} % "
                             f"(posterior probability {top.posterior:.2f}).")


def test_ratios_scattering_beyond_the_stated_noise_are_unexplained(beam):
    """ζ = 0.5 % with 30 % scatter, stated as 5 %: uniform damping leaves χ²/row far above 1;
    a region fits the eight ratios in-sample (decisive, most probable) but its held-out
    χ² stays above the noise level, so nothing is declared and the scatter is estimated."""
    model, _, _ = beam
    found = diagnose_damping(model, _exact(model, lambda w, lam, phi: np.full(len(w), 0.005), 0, 0.3),
                             noise=Noise(damping=0.05))
    b, top = found.baseline, found.regions[0]
    assert found.outcome == "unexplained" and found.effect is None and not b.at_noise
    assert top.checks.decisive_over_baseline and top.posterior >= 0.5  # the posterior does not declare:
    assert not top.checks.heldout_at_noise and not top.warranted  # the held-out error is not at the noise level
    assert found.noise_scale == b.chi2_per_row > 2
    assert found.verdict == (f"No local damping effect is declared, but uniform damping ({_uniform_part(b.uniform)}) "
                             f"leaves χ²/row {b.chi2_per_row:.2f} at the stated 5 % on each ratio and no region passes "
                             f"the checks for a local loss factor (the most probable, {top.effect.where()} with η = "
                             f"{top.eta:.3g}, posterior {top.posterior:.2f}, held-out χ²/row "
                             f"{top.heldout_chi2_per_row:.2f}, fails: held-out χ² at the noise level): the ratios "
                             f"scatter about uniform damping by about {5 * np.sqrt(b.chi2_per_row):.0f} % or need "
                             f"physics outside the candidates.")
    assert found.verdict.startswith("No local damping effect is declared, but uniform damping (Rayleigh μ = ")


def test_bad_damping_input_is_refused(beam):
    model, _, _ = beam
    sensors = Sensors.from_components([21], [2])
    few = ModalData(np.array([10.0, 60.0, 170.0, 330.0]), np.ones((1, 4)), sensors,
                    damping_ratios=np.array([0.01, 0.0, 0.01, 0.0]))
    with pytest.raises(ValueError, match="noise.damping must be a positive"):
        diagnose_damping(model, few, noise=Noise(damping=0.0))
    with pytest.raises(ValueError, match="at least 4 modes, got 2"):
        diagnose_damping(model, few)
    far = ModalData(np.array([1e3, 2e3, 3e3, 4e3]) * 50, np.ones((1, 4)), sensors, damping_ratios=np.full(4, 0.01))
    with pytest.raises(ValueError, match="only 0 measured modes with damping pair"):
        diagnose_damping(model, far)


@pytest.mark.slow(seconds=35)  # measured 32 s
def test_a_viscoelastic_patch_on_the_cfrp_panel_is_found():
    """The coarse CFRP panel (25 mm shells, thesis §5.3) with a visco-elastic patch: loss
    factor 0.3 on the whole stiffness of the four shells of the benchmark's delamination,
    Rayleigh damping as the benchmark's; the truth's poles from the complex eigenproblem
    in the basis of 80 real modes (the local loss couples them), its 14 lowest modes in
    40 Hz – 1.28 kHz with 2 % noise on the ratios. The patch ranks first, exactly, with η
    within 5 % and the held-out damping error below 2× the stated noise (measured: the
    four shells, η = 0.297, 32 % → 1.7 %, posterior 1.00)."""
    from benchmarks import cfrp_panel as cp

    model = cp.build(cp.COARSE)
    damaged = cp.build(cp.COARSE, (*cp.DAMAGE_CENTRE, cp.DAMAGE_RADIUS))
    true = np.asarray(damaged.quads.ids)[np.isin(damaged.quads.pids, (cp.PID_DAMAGED, cp.PID_DAMAGED_PIEZO))]
    k, m = jaxfem.assemble(model)
    lam, phi = (np.asarray(a) for a in jaxfem.eigh(k, m, cp.N_BASIS))
    band = np.flatnonzero((lam >= (2 * np.pi * cp.F_BAND[0]) ** 2) & (lam <= (2 * np.pi * cp.F_BAND[1]) ** 2))
    mu, kappa = (float(v) for v in jaxfem.rayleigh_coefficients(np.sqrt(lam[band[0]]), np.sqrt(lam[band[-1]]),
                                                                  cp.ZETA_BAND, cp.ZETA_BAND))
    patch = LocalDamping(eids=tuple(true.tolist()), eta=0.3)
    f, zeta = cp.damped_poles(lam, phi, np.asarray(jaxfem.damping_matrix(patch.apply(model)).todense()), mu, kappa)
    ids, xyz = np.asarray(model.node_ids), np.asarray(model.xyz)
    plate = ids[(np.abs(xyz[:, 2]) < 1e-9) & (xyz[:, 0] > 1e-9)]  # the base plate's free grids, out of plane
    sensors = Sensors.from_components(plate.tolist(), [3] * len(plate))
    C, _ = observation_matrix(model, sensors)
    sel = band[:14]
    noisy = zeta[sel] * (1 + 0.02 * np.random.default_rng(0).standard_normal(len(sel)))
    noise = 0.05
    found = diagnose_damping(model, ModalData(f[sel], np.asarray(C) @ phi[:, sel], sensors, damping_ratios=noisy),
                             noise=Noise(damping=noise))
    top = found.regions[0]
    assert found.effect is not None and set(found.effect.eids) == set(true.tolist())
    assert abs(top.eta - 0.3) < 0.05 * 0.3 and top.posterior > 0.95
    assert top.heldout_rms_zeta_dev_pct_after < 2 * 100 * noise < top.heldout_rms_zeta_dev_pct_before
