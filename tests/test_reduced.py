"""The diagnosis' reduced fits (updating.diagnosis._reduced): on the frame, a joint released by two
orders of magnitude (and both factors by e⁻¹²) keeps its eigenvalues within 1e-4 of the full model's in the basis made
at the stiff baseline; the reduced derivative equals finite differences; a fit on the
reduced model lands where the full one does. The diagnosis through reduced fits:
tests/test_diagnose.py::test_joint."""

import equinox as eqx
import jax
import jax.numpy as jnp
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse

import jaxfem
from benchmarks.frames import frame_bdf
from identification import Sensors
from jaxfem.io import read_bdf_text
from test_diagnose import measure
from updating import Direct, Options, Parameter, ParameterSet
from updating.diagnosis._candidates import augment, region_structures, structural_candidates
from updating.diagnosis import DiagnoseOptions
from updating.diagnosis._diagnose import FULL_MODEL_TOL, _on_full_model
from updating.diagnosis._effects import Effect, at_reference
from updating.diagnosis._fit import Fits, fit, scan_costs, with_extension
from updating._extension import extension
from updating.diagnosis._reduced import Bases
from updating._residuals import evaluate
from updating._solve import build_problem
from updating.diagnosis._topology import elements_at

NODE = 13


@pytest.fixture(scope="module")
def case():
    """The frame with grid 13's joint at 1/100 of its reference rotational stiffness."""
    model = jaxfem.build_model(read_bdf_text(frame_bdf(2, 2, 4, n_groups=8)))
    grids = list(range(5, 21))
    sensors = Sensors.from_components(np.repeat(grids, 2), np.tile([1, 2], len(grids)))
    pids = tuple(sorted(set(elements_at(model, NODE).values())))
    start = at_reference(model, Effect("joint", pids=pids, nodes=(NODE,)), [20.0])
    truth = Effect("joint", pids=pids, nodes=(NODE,),
                   values={"k_trans": start.values["k_trans"], "k_rot": start.values["k_rot"] / 100}).apply(model)
    return model, measure(truth, sensors)


@pytest.fixture(scope="module")
def joint(case):
    model, test = case
    nodes = [12, 13, 14, 15, 16]
    f_e = np.asarray(test.frequencies_hz)
    aug, _, stiffened = augment(model, nodes, region_structures(model, nodes, dict.fromkeys(nodes, 1.0),
                                                                 DiagnoseOptions().kinds, 4), f_e)
    problem = build_problem(aug, test, ParameterSet((), Options(regularisation=1e-6)))
    fits = Fits(DiagnoseOptions().settings)
    none = extension(aug)
    base = fit(fits, problem, none, np.zeros(1))
    bases = Bases(with_extension(problem, none), base.theta)
    c = next(c for c in structural_candidates(aug, stiffened) if c.reference.nodes == (NODE,))
    springs = next(r.ids() for r in stiffened if r.effect.nodes == (NODE,))
    return problem, fits, c, bases.reduced(problem, c.ext, np.zeros(2), held=True), (bases, springs)


def test_released_joint_eigenvalues_and_derivative(joint):
    problem, _, c, red, _ = joint
    p = with_extension(problem, c.ext)
    for theta in ([0.0, 0.0], [0.0, -4.6], [-2.0, -6.0], [0.0, -9.0], [-12.0, -12.0]):
        t = jnp.asarray(theta)
        full, reduced = evaluate(t, p), red(t, p, jnp.zeros(0))[0]
        assert reduced.lam_a.dtype == jnp.float64
        assert np.max(np.abs(np.asarray(reduced.lam_a) / np.asarray(full.lam_a) - 1)) < 1e-4, theta
    lam = lambda t: red(t, p, jnp.zeros(0))[0].lam_a  # noqa: E731
    t0, h = jnp.asarray([-1.0, -5.0]), 1e-4  # the reduced eigenvalues carry rounding of ~1e-11 relative
    fd = (lam(t0 + jnp.asarray([0.0, h])) - lam(t0 - jnp.asarray([0.0, h]))) / (2 * h)
    assert np.max(np.abs(jax.jacfwd(lam)(t0)[:, 1] - fd)) < 1e-5 * np.max(np.abs(fd))


def test_reduced_fit_lands_where_the_full_one_does(joint):
    problem, fits, c, red, _ = joint
    full = fit(fits, problem, c.ext, np.array([0.0, -4.6]))
    reduced = fit(fits, problem, c.ext, np.array([0.0, -4.6]), red)
    assert np.allclose(reduced.theta, full.theta, atol=1e-3)
    assert abs(reduced.cost / full.cost - 1) < 1e-3


def _run(fits, problem, sigma2, say):
    return SimpleNamespace(fits=fits, problem=problem, sigma2=sigma2, say=say)


def test_a_reduced_fit_is_checked_on_the_full_model(joint, monkeypatch):
    """The diagnosis reports the full model's values at a reduced fit's θ, and fits again
    on the full model only where its cost there differs by more than FULL_MODEL_TOL χ²
    and more than FULL_MODEL_REL of its χ²."""
    import updating.diagnosis._diagnose as d

    problem, fits, c, red, _ = joint
    monkeypatch.setattr(d, "FULL_MODEL_REL", 0.0)  # first the absolute tolerance alone
    c.fit = fit(fits, problem, c.ext, np.array([0.0, -4.6]), red)
    full = fit(fits, problem, c.ext, c.fit.theta, skip=True)
    said = []
    gap = abs(full.cost - c.fit.cost)
    assert gap > 0
    kept = _on_full_model(_run(fits, problem, 2 * gap / FULL_MODEL_TOL, said.append), c)  # the gap: half the tolerance
    assert said == [] and np.array_equal(kept.theta, c.fit.theta)
    assert kept.cost == full.cost and np.array_equal(kept.jac, full.jac)
    again = _on_full_model(_run(fits, problem, gap / FULL_MODEL_TOL / 10, said.append), c)  # ten times the tolerance
    assert len(said) == 1 and "fitted again" in said[0]
    direct = fit(fits, problem, c.ext, np.array([0.0, -4.6]))  # on the full model from the start
    assert again.cost <= full.cost and abs(again.cost / direct.cost - 1) < 1e-4
    share = gap / full.cost  # then a gap of this share of the cost, far above FULL_MODEL_TOL χ²
    monkeypatch.setattr(d, "FULL_MODEL_REL", 2 * share)
    assert _on_full_model(_run(fits, problem, gap / FULL_MODEL_TOL / 1e3, said.append), c).cost == full.cost
    assert len(said) == 1  # kept: the gap is half the relative tolerance
    monkeypatch.setattr(d, "FULL_MODEL_REL", share / 2)
    _on_full_model(_run(fits, problem, gap / FULL_MODEL_TOL / 1e3, said.append), c)
    assert len(said) == 2 and "fitted again" in said[1]


def test_pool_assembles_only_what_changes(joint, monkeypatch):
    """With a pool holding the joint's springs (and a beam it does not change), each step
    assembles only the pool and adds the rest once; the springs' stiffness being linear in
    each of the two factors, the reduced matrices are the projected derivatives' sums
    (``linear``), not assembled at all: both give the eigenvalues and derivatives of the
    whole model assembled in the same basis, to rounding. A pool missing one of them is
    not used."""
    problem, _, c, red, (bases, springs) = joint
    p = with_extension(problem, c.ext)
    beam = int(np.asarray(problem.structure.value.beams.ids)[0])
    bases.pool = tuple(sorted(springs + [beam]))
    try:
        linear = bases.reduced(problem, c.ext, np.zeros(2), held=True)
        with monkeypatch.context() as m:
            m.setattr(Bases, "_linear", lambda *a: False)
            pooled = bases.reduced(problem, c.ext, np.zeros(2), held=True)
        bases.pool = (beam,) + tuple(sorted(springs))[1:]
        missing = bases.reduced(problem, c.ext, np.zeros(2), held=True)
    finally:
        bases.pool = None
    assert linear.linear is not None and linear.linear[0].shape[0] == 2
    assert pooled.pool == tuple(sorted(springs + [beam])) and pooled.linear is None
    assert missing.pool is None and missing.linear is None and red.pool is None and red.linear is None
    lam = lambda solver, t: solver(t, p, jnp.zeros(0))[0].lam_a  # noqa: E731
    for theta in ([0.0, 0.0], [-2.0, -6.0], [0.5, -9.0]):
        t = jnp.asarray(theta)
        for solver in (pooled, linear):
            np.testing.assert_allclose(lam(solver, t), lam(red, t), rtol=1e-9)
            np.testing.assert_allclose(jax.jacfwd(lambda t: lam(solver, t))(t), jax.jacfwd(lambda t: lam(red, t))(t),
                                       rtol=1e-7, atol=1e-9 * float(np.max(np.asarray(lam(red, t)))))


def test_pool_holds_the_engineers_parameters_too(case):
    """A fit moves the engineer's factors with the candidate's: a pool that holds the added
    mass but not the engineer's group is not used; with the group in it, it is."""
    model, test = case
    f_e = np.asarray(test.frequencies_hz)
    aug, dormant, _ = augment(model, [NODE], [], f_e)
    pid = min(elements_at(model, NODE).values())
    problem = build_problem(aug, test, ParameterSet((Parameter("g", "stiffness", pids=(pid,)),),
                                                    Options(regularisation=1e-6)))
    bases = Bases(with_extension(problem, extension(aug)), np.zeros(2))
    ref, ids = next((ref, ids) for ref, ids in dormant if ref.kind == "added_mass")
    ext = ref.dormant_extension(aug, ids)
    bases.pool = tuple(sorted(ids))
    assert bases.reduced(problem, ext, np.zeros(1)).pool is None
    bases.pool = tuple(sorted(set(ids) | set(aug.element_ids(pids=(pid,)).tolist())))
    assert bases.reduced(problem, ext, np.zeros(1)).pool == bases.pool


def test_a_groups_factor_is_projected_once(joint):
    """Without the engineer's parameters, a candidate scaling whole elements' stiffness and
    mass (a group's factor) changes the reduced matrices along one projected derivative
    each: no assembly at any θ, and the same eigenvalues and derivatives as assembling
    the whole model in the same basis. A candidate that also wakes an element does not
    qualify."""
    from updating._eigensolvers import Reduced

    problem, _, c, _, (bases, springs) = joint
    aug = problem.structure.value
    pids = sorted(set(np.asarray(aug.beams.pids).tolist()))
    ext = extension(aug, k_log=aug.element_ids(pids=(pids[0],)), m_log=aug.element_ids(pids=(pids[1],)))
    bases.pool = tuple(sorted(springs))
    try:
        red = bases.reduced(problem, ext, np.zeros(1))
        woken = bases.reduced(problem, extension(aug, k_log=aug.element_ids(pids=(pids[0],)), k_add=springs[:1]),
                              np.zeros(1))
    finally:
        bases.pool = None
    assert red.linear is not None and woken.linear is None
    whole = Reduced(red.basis, red.padding, red.observed)
    p = with_extension(problem, ext)
    lam = lambda solver, t: solver(t, p, jnp.zeros(0))[0].lam_a  # noqa: E731
    for theta in ([0.0], [-2.0], [1.5]):
        t = jnp.asarray(theta)
        np.testing.assert_allclose(lam(red, t), lam(whole, t), rtol=1e-9)
        np.testing.assert_allclose(jax.jacfwd(lambda t: lam(red, t))(t), jax.jacfwd(lambda t: lam(whole, t))(t),
                                   rtol=1e-7, atol=1e-9 * float(np.max(np.asarray(lam(whole, t)))))


def test_candidate_fits_on_two_threads_equal_one_thread(joint):
    """The diagnosis fits its candidates on a thread per CPU (one compiled fit shared): the
    same θ₀, θ and cost, in the same order, as one after another."""
    from updating.diagnosis._fit import threaded as _threaded
    from updating._eigensolvers import Direct
    from updating.diagnosis._fit import candidate_fit

    problem, fits, c, red, _ = joint
    jobs = [(0, c.ext, np.zeros(0), None, np.array([0.0, -4.6]), Direct()),
            (1, c.ext, np.zeros(0), c.scan, np.zeros(2), red),
            (2, c.ext, np.zeros(0), None, np.array([-1.0, -3.0]), red)]
    fitted = lambda job: (job[0], candidate_fit(fits, problem, *job[1:]))  # noqa: E731
    one, two = list(_threaded(fitted, jobs, 1)), list(_threaded(fitted, jobs, 2))
    assert [k for k, _ in two] == [0, 1, 2]
    for (_, (t0, a)), (_, (u0, b)) in zip(one, two):
        np.testing.assert_array_equal(t0, u0)
        np.testing.assert_allclose(b.theta, a.theta, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(b.cost, a.cost, rtol=1e-9)


def test_cross_validation_on_two_threads_equals_one_thread(joint):
    """The folds of a cross-validation fitted on two threads: the same held-out costs and
    per-mode Δf, MAC as one after another."""
    from updating._eigensolvers import Direct
    from updating.diagnosis._fit import cross_validate, fit, fold_masks

    problem, fits, c, _, _ = joint
    result = fit(fits, problem, c.ext, np.array([0.0, -4.6]), Direct())
    masks = fold_masks(len(np.asarray(problem.lam_e)), 3)
    one = cross_validate(fits, problem, c.ext, result, masks)
    two = cross_validate(fits, problem, c.ext, result, masks, threads=2)
    np.testing.assert_allclose([two.freq, two.shape], [one.freq, one.shape], rtol=1e-9)
    np.testing.assert_allclose(two.freq_dev, one.freq_dev, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(two.mac, one.mac, rtol=1e-9, atol=1e-12)
    assert np.isfinite(one.freq_dev).sum() > len(one.freq_dev) // 2  # compared on numbers, not NaN alone


def test_fits_on_threads_call_blas_on_one_thread_each():
    """Two fits on two threads, each calling a two-thread OpenBLAS, oversubscribed two cores
    (garteur-added-mass alone: 77–85 s, 56–67 s with one BLAS thread per fit): inside
    ``threaded`` BLAS runs on one thread, and the process' setting returns after it."""
    from threadpoolctl import threadpool_info, threadpool_limits

    from updating.diagnosis._fit import threaded as _threaded

    blas = lambda _: sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})  # noqa: E731
    with threadpool_limits(2, user_api="blas"):
        assert list(_threaded(blas, [0, 1, 2], 2)) == [[1]] * 3
        assert blas(None) == [2]
        assert list(_threaded(blas, [0, 1], 1)) == [[2]] * 2  # one after another: the process' own


def test_a_springs_change_loads_are_kept_once():
    """A spring's change load k (e_a − e_b) comes from either end: ``_distinct`` keeps one
    column per direction, whatever its sign and scale, and keeps different ones."""
    from updating.diagnosis._reduced import _distinct

    e = np.eye(6)
    a, b, c = 2.0 * (e[0] - e[3]), 5.0 * (e[1] - e[4]), e[2] + 0.5 * e[5]
    loads = np.stack([a, -a, b, 3.0 * c, -b, 0.1 * a, c], axis=1)
    np.testing.assert_array_equal(_distinct(scipy.sparse.csc_matrix(loads)).toarray(), loads[:, [0, 2, 3]])


def test_padding_leaves_close_modes_their_own_derivatives():
    """A reduced problem's padding columns become modes just above its spectrum
    (``updating._eigensolvers.padded``), not 1e3× its stiffest DoF: modes 1 % apart keep
    their own derivatives (jaxfem.eigh grouped eigenvalues within 1e3·ε·max|λ| of the whole
    spectrum; at the old padding, with a spring held stiff in the basis, the pair's
    derivatives were averaged)."""
    from updating._eigensolvers import padded

    padding = jnp.asarray([False, False, False, False, True, True])

    def lam(t, old=False):  # a stiff spring's DoF (1e12) beside two modes 1 % apart, one moved by t
        kr = jnp.diag(jnp.stack([1e4 * jnp.exp(t), 1.01e4, 5e4, 1e12, 0.0, 0.0]))
        mr = jnp.diag(jnp.asarray([1.0, 1.0, 1.0, 1.0, 0.0, 0.0]))
        if old:
            top = 1e3 * 1e12 + 1.0
            kr, mr = kr + jnp.diag(jnp.where(padding, top, 0.0)), mr + jnp.diag(padding.astype(mr.dtype))
        else:
            kr, mr = padded(kr, mr, padding)
        return jaxfem.eigh(kr, mr, 3)[0]

    lam0 = np.asarray(lam(0.0))
    np.testing.assert_allclose(lam0, [1e4, 1.01e4, 5e4], rtol=1e-12)
    np.testing.assert_allclose(np.asarray(jax.jacfwd(lam)(0.0)), [1e4, 0.0, 0.0], atol=1e-6 * 1e4)
    # the old padding too, now that eigh's cluster floor comes from the returned modes alone
    np.testing.assert_allclose(np.asarray(jax.jacfwd(lambda t: lam(t, old=True))(0.0)), [1e4, 0.0, 0.0], atol=1e-2)
    kr, mr = padded(jnp.diag(jnp.asarray([1e4, 2e4, 0.0])), jnp.diag(jnp.asarray([1.0, 0.5, 0.0])),
                    jnp.asarray([False, False, True]))
    assert 4e4 < float(kr[2, 2]) <= 2 * 2e4 / 0.5 + 1 and float(mr[2, 2]) == 1.0  # above λ_max = 4e4, no further


def test_a_mass_raised_off_its_grid_is_assembled_not_linear(case):
    """A woken point mass is linear in its factor (``linear``); the same mass with its CG
    raised by θ₁ (a payload's height: inertia quadratic in θ₁) is not, and is assembled
    from the pool at each step: both give the eigenvalues of the whole model assembled
    in the same basis."""
    from updating._eigensolvers import Reduced

    model, test = case
    aug, dormant, _ = augment(model, [NODE], [], np.asarray(test.frequencies_hz))
    problem = build_problem(aug, test, ParameterSet((), Options(regularisation=1e-6)))
    bases = Bases(with_extension(problem, extension(aug)), np.zeros(1))
    ids = next(ids for ref, ids in dormant if ref.kind == "added_mass")
    raised = {ids[0]: (np.array([0.0, 0.0, 0.1]), np.diag([1.0, 1.0, 0.0]), np.diag([2.0, 2.0, 0.0]))}
    bases.pool = tuple(sorted(ids))
    woken, lifted = (bases.reduced(problem, ext, np.zeros(ext.n_params)) for ext in (
        extension(aug, m_add=ids), extension(aug, m_add=ids, height=raised)))
    assert woken.linear is not None and lifted.linear is None and lifted.pool == bases.pool
    for red, theta in ((woken, [[0.0], [1.2], [-2.0]]), (lifted, [[0.0, 0.0], [0.5, 3.0], [-1.0, -2.0]])):
        p = with_extension(problem, extension(aug, m_add=ids, height=raised if red is lifted else None))
        whole = Reduced(red.basis, red.padding, red.observed)
        for t in map(jnp.asarray, theta):
            np.testing.assert_allclose(red(t, p, jnp.zeros(0))[0].lam_a, whole(t, p, jnp.zeros(0))[0].lam_a, rtol=1e-9)


class _IndefiniteAbove(Direct):
    """The problem's own solve, failing as an indefinite K + σM does (a runtime error of the
    compiled solve) where the candidate's log-factor exceeds ``limit``: the scan point a
    reduced basis' linear form can make indefinite (the GARTEUR joint RBE2 5003 at 616 DoFs)."""

    limit: float = 2.0

    def __call__(self, theta, problem, warm):
        ev, *rest = super().__call__(theta, problem, warm)
        lam = eqx.error_if(ev.lam_a, theta[-1] > self.limit, "K + σM is not positive definite")
        return (eqx.tree_at(lambda e: e.lam_a, ev, lam), *rest)


def test_a_scan_point_that_cannot_be_solved_costs_inf_not_a_traceback(joint):
    """Item 7 of issue 46: the point is no start (cost inf), the others are scanned as before,
    and a fit started there is reported with its reason, not raised."""
    problem, fits, c, _, _ = joint
    grid = [(0.0, 0.0), (0.0, 3.0), (0.0, -1.5)]
    costs = scan_costs(fits, problem, c.ext, np.zeros(0), grid, _IndefiniteAbove())
    assert np.isinf(costs[1]) and np.all(np.isfinite(costs[[0, 2]]))
    assert np.allclose(costs[[0, 2]], scan_costs(fits, problem, c.ext, np.zeros(0), grid[::2]), rtol=1e-12)
    failed = fit(fits, problem, c.ext, np.array([0.0, 3.0]), _IndefiniteAbove())
    assert np.isinf(failed.cost) and "positive definite" in failed.error
