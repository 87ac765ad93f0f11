"""Warm-started subspace iteration (jaxfem.subspace) against the full solve (jaxfem.eigh)."""


import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.models import MODELS
from jaxfem.io import read_bdf

TREE = MODELS / "tree.bdf"
N, Q = 12, 30


@pytest.fixture(scope="module")
def tree():
    model = jaxfem.build_model(read_bdf(TREE))
    groups = [model.element_ids(pids=[2, 4]), model.element_ids(pids=[12])]
    _, start = jaxfem.eigh(*jaxfem.assemble(model), Q)  # the reference modes: the warm start
    return model, groups, start


def _solve(model, groups, start, a):
    K, M = jaxfem.assemble(jaxfem.correct(model, groups, a))
    sol = jaxfem.subspace(K, M, start, N)
    lam, phi = jaxfem.ritz_modes(K, M, sol, jnp.arange(N))
    return lam, phi, sol


def _mac_diag(a, b):
    return np.sum(a * b, axis=0) ** 2 / (np.sum(a * a, axis=0) * np.sum(b * b, axis=0))


def test_subspace_equals_full_solve(tree):
    """A −17 %/+10 % perturbation of two groups, solved from the reference modes: the
    modes equal the full LAPACK solve to its own accuracy (λ to 1e-8, MAC to 1e-9, in
    float64; the standardised full problem has λ_max/λ_1 ≈ 8e8, so its low modes carry
    relative errors of ~1e-9)."""
    model, groups, start = tree
    a = jnp.array([-0.17, 0.10])
    lam, phi, sol = jax.jit(lambda a, s: _solve(model, groups, s, a))(a, start)
    lam_full, phi_full = jaxfem.eigh(*jaxfem.assemble(jaxfem.correct(model, groups, a)), N)
    assert bool(sol.converged) and 1 <= int(sol.sweeps) < 40
    assert lam.dtype == phi.dtype == jnp.float64
    np.testing.assert_allclose(lam, lam_full, rtol=1e-8)
    assert np.min(_mac_diag(np.asarray(phi), np.asarray(phi_full))) > 1 - 1e-9
    # The result is a warm start: the converged basis converges again without a sweep.
    again = jaxfem.subspace(*jaxfem.assemble(jaxfem.correct(model, groups, a)), sol.basis, N)
    assert int(again.sweeps) == 0 and bool(again.converged)


def test_preconditioned_subspace_equals_exact(tree):
    """With the fixed preconditioner (K − σM)⁻¹ of the reference model (no factorisation
    of the perturbed one) the −17 %/+10 % model converges to the same modes as the exact
    inverse iteration (λ to 1e-10, vectors to 1e-8 of their largest component), in a few
    more sweeps; its derivatives equal the exact solve's (1e-8 of the largest); and a preconditioner of
    a model too far off (the modes of the −17 % groups at −90 %) is reported as not
    converged rather than returned."""
    model, groups, start = tree
    a = jnp.array([-0.17, 0.10])
    inverse = jaxfem.shifted_inverse(*jaxfem.assemble(model))
    K, M = jaxfem.assemble(jaxfem.correct(model, groups, a))
    exact = jaxfem.subspace(K, M, start, N)
    pre = jaxfem.subspace(K, M, start, N, preconditioner=inverse)
    assert bool(pre.converged) and int(exact.sweeps) <= int(pre.sweeps) < 40
    np.testing.assert_allclose(pre.lam[:N], exact.lam[:N], rtol=1e-10)
    u, v = np.asarray(pre.basis[:, :N]), np.asarray(exact.basis[:, :N])
    sign = np.sign(np.sum(u * v, axis=0))  # the sign rule may pick either of two equal components
    v = v * sign
    assert np.all(np.max(np.abs(u - v), axis=0) <= 1e-8 * np.max(np.abs(v), axis=0))

    def derivative(solve):  # the Jacobian and the modes of one evaluation, whose signs it carries
        def modes(a):
            K, M = jaxfem.assemble(jaxfem.correct(model, groups, a))
            return (jaxfem.ritz_modes(K, M, solve(K, M), jnp.arange(N)),) * 2
        return jax.jacfwd(modes, has_aux=True)(a)

    ((jl, jp), (_, u)), ((jl_e, jp_e), (_, v)) = (
        derivative(lambda K, M, p=p: jaxfem.subspace(K, M, start, N, preconditioner=p)) for p in (inverse, None))
    sign = np.sign(np.sum(np.asarray(u) * np.asarray(v), axis=0))
    np.testing.assert_allclose(jl, jl_e, rtol=1e-8, atol=1e-8 * float(np.max(np.abs(jl_e))))
    assert np.max(np.abs(jp - sign[:, None] * jp_e)) <= 1e-8 * np.max(np.abs(jp_e))
    far = jaxfem.subspace(*jaxfem.assemble(jaxfem.correct(model, groups, jnp.array([-0.9, 0.0]))), start, N,
                          preconditioner=inverse, max_sweeps=10)
    assert not bool(far.converged)


def test_dense_modes_are_refined_to_rounding(tree):
    """The full-solve reference: its lowest 2m modes pass the inverse-iteration test at
    1e-11 (the back substitution alone leaves up to 2e-10 on the tree, enough to make
    full-solve updates jitter at 1e-8)."""
    model, _, _ = tree
    K, M = jaxfem.assemble(model)
    sol = jaxfem.dense_modes(K, M, N)
    V, lam = sol.basis[:, :2 * N], sol.lam[:2 * N]
    step = jaxfem.shifted_inverse(K, M) @ (K.matmul(V) - M.matmul(V) * lam)
    assert float(jnp.max(jnp.linalg.norm(step, axis=0) / jnp.linalg.norm(V, axis=0))) <= 1e-11
    np.testing.assert_allclose(lam[:N], jaxfem.eigh(K, M, N)[0], rtol=1e-8)


def test_ritz_derivatives_match_finite_differences_and_eigh(tree):
    """dλ against the implicit rule of jaxfem.eigh (1e-8 relative) and dφ against central
    finite differences of the subspace solve (1e-5, step 1e-5, sign of φ fixed by a
    component away from ties); modes that are not near-repeated also against eigh (1e-5)."""
    model, groups, start = tree
    a = jnp.array([-0.17, 0.10])
    lam0, phi0, _ = _solve(model, groups, start, a)
    ref = np.argsort(-np.abs(np.asarray(phi0)), axis=0)[1]
    fix = lambda p: p * jnp.sign(p[ref, jnp.arange(N)])

    def fixed(lam, phi, *_):
        return lam, fix(phi)

    jl, jp = jax.jit(jax.jacfwd(lambda a: fixed(*_solve(model, groups, start, a))))(a)
    jl_full, jp_full = jax.jacfwd(
        lambda a: fixed(*jaxfem.eigh(*jaxfem.assemble(jaxfem.correct(model, groups, a)), N)))(a)
    np.testing.assert_allclose(jl, jl_full, rtol=1e-8, atol=1e-8 * float(np.max(np.abs(jl_full))))
    h = 1e-5
    step = jax.jit(lambda a: fix(_solve(model, groups, start, a)[1]))
    for i in range(2):
        e = jnp.zeros(2).at[i].set(h)
        fd = (step(a + e) - step(a - e)) / (2 * h)
        assert np.max(np.abs(fd - jp[:, :, i])) <= 1e-5 * np.max(np.abs(jp[:, :, i]))
    lam = np.asarray(lam0)
    gap = np.minimum(np.abs(np.diff(lam, prepend=-np.inf)), np.abs(np.diff(lam, append=np.inf))) / lam
    separated = gap > 0.05
    assert separated.sum() >= 4
    err = np.max(np.abs(np.asarray(jp) - np.asarray(jp_full)), axis=(0, 2))[separated]
    assert np.all(err <= 1e-5 * np.max(np.abs(np.asarray(jp_full))))


def test_vmapped_subspace_equals_unbatched(tree):
    """Three perturbed models in one vmapped solve (the LAPACK kernels loop over the batch:
    a batched LAPACK call inside the loop hangs XLA-CPU) give the unbatched modes."""
    model, groups, start = tree
    a = jnp.array([[-0.17, 0.10], [0.05, -0.05], [0.0, 0.2]])
    lam_b, phi_b, _ = jax.jit(jax.vmap(lambda a: _solve(model, groups, start, a)))(a)
    for i in range(3):
        lam, phi, _ = _solve(model, groups, start, a[i])
        np.testing.assert_allclose(lam_b[i], lam, rtol=1e-11)  # round-off: 1.2e-12 seen on a fresh install
        np.testing.assert_allclose(np.abs(phi_b[i]), np.abs(phi), atol=1e-9)


def test_subspace_rejects_bad_sizes(tree):
    model, _, start = tree
    K, M = jaxfem.assemble(model)
    with pytest.raises(ValueError, match="n_modes < q"):
        jaxfem.subspace(K, M, start, Q)
