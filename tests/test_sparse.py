"""The sparse path (jaxfem.eigsh: shift-invert Lanczos on a sparse factorisation) against
the dense solver (jaxfem.eigh): values, Jacobians, clusters, rigid-body modes, errors."""

import json
import sys
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.models import MODELS
from benchmarks.shell_models import plate
from jaxfem import _sparse
from jaxfem.io import read_bdf, read_bdf_text
from test_shells import PANEL_PARAMETERS, _panel_model, _stiffened_panel

with warnings.catch_warnings():  # the missing-library warning is tested below
    warnings.simplefilter("ignore")
    BACKENDS = ["superlu"] + (["pardiso"] if _sparse.resolve_backend("auto") == "pardiso" else [])
ALU_PLATE = "MAT1,1,7.+10,,0.3,2700.\nPSHELL,1,1,0.003,1,,1"


def _aligned(phi, ref):
    """φ with each column's sign matched to ``ref`` (equal peaks can pick either sign)."""
    return phi * np.sign(np.sum(np.asarray(phi) * np.asarray(ref), axis=0))


def _garteur():
    model = jaxfem.build_model(read_bdf(MODELS / "garteur.bdf"))
    groups = [model.element_ids(pids=[p]) for p in sorted(set(np.asarray(model.beams.section).tolist()))[:3]]
    return model, [g for g in groups if len(g)]


def _assert_agree(solve_p, p0, n, *, skip=0, lam_tol=1e-10, jac_tol=1e-8):
    """Sparse and dense modes ``skip`` … n − 1 and their forward Jacobians at ``p0``."""
    def run(solver):  # values and Jacobian from one evaluation: a tie of peaks can sign a mode either way
        f = lambda p: jax.tree.map(lambda x: x[..., skip:], solver(*jaxfem.assemble(solve_p(p)), n))  # noqa: E731
        jac, value = jax.jacfwd(lambda p: (f(p),) * 2, has_aux=True)(p0)
        return value, jac

    (lam_d, phi_d), (jl_d, jp_d) = run(jaxfem.eigh)
    (lam_s, phi_s), (jl_s, jp_s) = run(jaxfem.eigsh)
    sign = np.sign(np.sum(np.asarray(phi_s) * np.asarray(phi_d), axis=0))
    np.testing.assert_allclose(lam_s, lam_d, rtol=lam_tol)
    np.testing.assert_allclose(phi_s * sign, phi_d, atol=1e-8 * np.abs(phi_d).max())
    np.testing.assert_allclose(jl_s, jl_d, rtol=0, atol=jac_tol * np.abs(jl_d).max())
    scale = np.abs(np.asarray(jp_d)).max(axis=(0, 2), keepdims=True)
    assert np.abs(np.asarray(jp_s) * sign[None, :, None] - jp_d).max(axis=(0, 2)).max() \
        <= jac_tol * scale.max(), (np.abs(np.asarray(jp_s) * sign[None, :, None] - jp_d) / scale).max(axis=(0, 2))


def test_beam_model_agrees_with_dense_in_values_and_jacobians():
    """GARTEUR (CBAR, CONM2 on a soft suspension): 14 modes, 3 stiffness groups. The three
    rigid-body and two suspension modes are left out: K's spectrum spans 10¹³, so both
    solvers give them only to about 10⁻⁶ relative (eigen-residuals of 10⁻⁶ for each), and
    the elastic modes to ~10⁻⁹ (the dense solver and LAPACK's dsygvd differ by 2·10⁻⁸ at
    the first elastic mode): 10⁻⁸ here, 10⁻¹⁰ on the shell models below."""
    model, groups = _garteur()
    _assert_agree(lambda a: jaxfem.correct(model, groups, a), jnp.array([0.1, -0.05, 0.2])[: len(groups)], 14,
                  skip=5, lam_tol=1e-8)


def test_laminated_stiffened_panel_agrees_with_dense():
    """The offset PCOMP panel with its MAT8 blade stringer (shells only, massless drilling
    DoFs none): 8 modes and the Jacobians in seven laminate parameters."""
    model = jaxfem.build_model(read_bdf_text(_stiffened_panel()))
    _assert_agree(_panel_model(model), jnp.zeros(len(PANEL_PARAMETERS)), 8)


def test_mixed_shell_and_beam_model_with_massless_dofs_agrees_with_dense():
    """A cantilever plate with a CBAR stiffener and lumped mass (COUPMASS off: rotations
    without mass, condensed by the dense solver, kept by shift-invert)."""
    text = plate(0.5, 0.3, 8, 4, ALU_PLATE, bc="cfff").replace("PARAM,COUPMASS,1\n", "")
    lines = text.splitlines()
    lines += ["PBAR,7,1,2.e-4,1.e-8,2.e-8,1.e-8", "CONM2,900,27,,0.4"]  # grid 27: the tip of y = 0.15
    lines += [f"CBAR,{700 + i},7,{19 + i},{20 + i},0.,0.,1." for i in range(8)]
    model = jaxfem.build_model(read_bdf_text("\n".join(lines)))
    assert len(model.dofs.massless) > 0
    groups = [model.element_ids(pids=[1]), model.element_ids(pids=[7])]
    _assert_agree(lambda a: jaxfem.correct(model, groups, a), jnp.array([0.05, -0.1]), 8)


@pytest.mark.parametrize("backend", BACKENDS)
def test_backends_agree(backend):
    model, groups = _garteur()
    K, M = jaxfem.assemble(model)
    lam_d, _ = jaxfem.eigh(K, M, 12)
    lam, phi = jaxfem.eigsh(K, M, 12, backend=backend)
    np.testing.assert_allclose(lam[5:], lam_d[5:], rtol=1e-8)
    assert phi.dtype == jnp.float64 and lam.dtype == jnp.float64


def test_repeated_modes_of_a_square_plate_give_the_cluster_mean_not_nan():
    """A free square plate has pairs of equal eigenvalues (symmetry): the derivatives of the
    pairs are the cluster means, as the dense solver's, finite, and grad works."""
    model = jaxfem.build_model(read_bdf_text(plate(0.4, 0.4, 8, 8, ALU_PLATE, bc="ss")))  # (1,2) = (2,1)
    K, M = jaxfem.assemble(model)
    lam, _ = jaxfem.eigsh(K, M, 8)
    rel_gap = np.diff(np.asarray(lam)) / np.asarray(lam[1:])
    assert rel_gap.min() < 1e-9  # a repeated pair is there

    def f(solver, a):
        m = eqx.tree_at(lambda q: q.materials.E, model, model.materials.E * (1 + a))
        return solver(*jaxfem.assemble(m), 8)[0]

    d_dense = jax.jacfwd(lambda a: f(jaxfem.eigh, a))(0.1)
    d_sparse = jax.jacfwd(lambda a: f(jaxfem.eigsh, a))(0.1)
    np.testing.assert_allclose(d_sparse, d_dense, rtol=1e-8)
    g = jax.grad(lambda a: jnp.sum(f(jaxfem.eigsh, a)))(0.1)
    assert np.isfinite(g) and abs(g / jnp.sum(d_dense) - 1) < 1e-8


def test_reverse_mode_equals_forward_mode():
    model, groups = _garteur()

    def loss(a):
        lam, phi = jaxfem.eigsh(*jaxfem.assemble(jaxfem.correct(model, groups, a)), 10)
        return jnp.sum(lam[6:] / lam[6]) + jnp.sum(phi[:50, 6:] ** 2)

    a0 = jnp.array([0.1, -0.05, 0.2])[: len(groups)]
    np.testing.assert_allclose(jax.grad(loss)(a0), jax.jacfwd(loss)(a0), rtol=1e-8)  # eigen-residuals 1e-6 here


def test_jit_and_vmap_over_samples_match_single_solves():
    model, groups = _garteur()
    f = jax.jit(lambda a: jaxfem.eigsh(*jaxfem.assemble(jaxfem.correct(model, groups, a)), 10)[0])
    batch = jnp.array([[0.0, 0.1, -0.1], [0.2, -0.1, 0.0]])[:, : len(groups)]
    together = jax.vmap(f)(batch)
    for a, row in zip(batch, together):
        np.testing.assert_allclose(row, f(a), rtol=1e-12)


def test_a_mechanism_gives_a_clear_error():
    """A lumped-mass plate (rotations without mass) whose stiffness is scaled to zero: the
    massless DoFs have no stiffness, K − σM is singular, and the message says so."""
    text = plate(0.2, 0.2, 4, 4, ALU_PLATE, bc="cfff").replace("PARAM,COUPMASS,1\n", "")
    model = jaxfem.build_model(read_bdf_text(text))
    soft = jaxfem.correct(model, [model.element_ids(pids=[1])], jnp.array([-1.0]))
    with pytest.raises(Exception, match="mechanism"):
        jaxfem.eigsh(*jaxfem.assemble(soft), 3)
    negative = jaxfem.correct(model, [model.element_ids(pids=[1])], jnp.array([-2.0]))
    with pytest.raises(Exception, match="negative stiffness"):
        jaxfem.eigsh(*jaxfem.assemble(negative), 3)


def test_auto_selection_and_the_missing_library_warning(monkeypatch):
    model, _ = _garteur()
    assert not jaxfem.use_sparse(model) and jaxfem.use_sparse(model, "sparse")
    monkeypatch.setattr(jaxfem, "SPARSE_ABOVE", 0)
    monkeypatch.setattr("jaxfem._modes.SPARSE_ABOVE", 100)
    assert jaxfem.use_sparse(model)
    with pytest.raises(ValueError, match="eigensolver"):
        jaxfem.use_sparse(model, "lanczos")
    monkeypatch.setattr(_sparse, "_warned", False)
    monkeypatch.setitem(sys.modules, "pypardiso", None)  # as if not installed: importing it fails
    monkeypatch.setattr(_sparse, "_warned", False)
    with pytest.warns(UserWarning, match="SuperLU"):
        assert _sparse.resolve_backend("auto") == "superlu"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _sparse.resolve_backend("auto") == "superlu"  # warned once
    with pytest.raises(ImportError, match="pypardiso"):
        _sparse.resolve_backend("pardiso")


def test_modes_command_solves_dense_and_sparse_alike(tmp_path):
    from typer.testing import CliRunner

    from updating.cli import app

    out = {}
    for solver in ("dense", "sparse"):
        path = tmp_path / f"{solver}.json"
        result = CliRunner().invoke(app, ["modes", str(MODELS / "garteur.bdf"), "-n", "12", "--solver", solver,
                                          "--json", str(path)])
        assert result.exit_code == 0, result.output
        assert f"{solver} eigensolver" in result.output
        out[solver] = json.loads(path.read_text())
        assert out[solver]["eigensolver"] == solver
    np.testing.assert_allclose(out["sparse"]["frequencies_hz"][5:], out["dense"]["frequencies_hz"][5:], rtol=1e-8)
    bad = CliRunner().invoke(app, ["modes", str(MODELS / "garteur.bdf"), "--solver", "lanczos"])
    assert bad.exit_code == 2 and "dense | sparse" in bad.output


@pytest.mark.slow
def test_barrel_of_20k_dofs_matches_central_differences():
    """The generated fuselage barrel at 20,000 DoFs (shells, beams, rods, bushes, springs,
    masses): forward-mode derivatives of the 10 lowest eigenvalues (six suspension, four
    elastic) and of the first two elastic shapes in three parameters against central
    differences (h = 1e-5 in θ = ln(1 + α))."""
    from benchmarks import fuselage
    from updating import parameterise

    model = jaxfem.build_model(read_bdf_text(fuselage.barrel_bdf(20000), name="barrel"))
    assert model.n_dof >= 20000
    chosen = [p for p in fuselage.parameter_groups(10) if p.name in ("skin upper", "frames E", "joint k")]
    base, par = parameterise(model, chosen)

    def f(theta):
        return jaxfem.eigsh(*jaxfem.assemble(par.apply(base, theta)), 10)

    t0 = jnp.zeros(3)
    lam0, phi0 = f(t0)
    h = 1e-5
    for j in range(3):
        e = jnp.zeros(3).at[j].set(1.0)
        _, (dlam, dphi) = jax.jvp(f, (t0,), (e,))
        (lp, pp), (lm, pm) = f(t0 + h * e), f(t0 - h * e)
        np.testing.assert_allclose(dlam, (lp - lm) / (2 * h), rtol=1e-5, atol=1e-5 * float(jnp.abs(dlam).max()))
        # shapes: the two lowest elastic modes (the suspension modes at 0.5–3 Hz and the
        # close pair 8/9 make central differences of shapes meaningless at this h)
        fd = np.asarray((pp - pm) / (2 * h))[:, 6:8]
        d = np.asarray(dphi)[:, 6:8]
        # 1e-4: central differences of shapes carry ~ε_φ/h ≈ 1e-7 of max|φ| (4e-5 of dφ seen)
        assert (np.abs(d - fd).max(axis=0) <= 1e-4 * np.abs(d).max(axis=0)).all()
