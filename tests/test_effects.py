"""Effects on a model: structural edits, frequency-dependent stiffness solved per mode,
one parameterisation per effect (batched-fit masks, engine parameters, fitted values),
candidates and plausibility by kind, and the command-line effect syntax."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sl

import jaxfem
from benchmarks.frames import frame_bdf
from jaxfem.io import read_bdf_text
from updating import AbstractEffect
from updating.diagnosis._effects import (
    KINDS,
    AddedMass,
    BoundarySpring,
    Effect,
    FrequencyDependentStiffness,
    GroupMass,
    GroupStiffness,
    Joint,
    at_reference,
    parse_effect,
)
from updating._parameters import Parameter, parameterise
from updating.diagnosis._topology import elements_at, stiffness_pids, structural_pids, total_mass


@pytest.fixture(scope="module")
def model():
    return jaxfem.build_model(read_bdf_text(frame_bdf(2, 2, 4, n_groups=8)))


def _freqs(m, n=10):
    return np.asarray(jaxfem.frequencies_hz(jaxfem.modes(m, n)[0]))


def _law(model, a=0.3, f_ref=60.0, pid=3):
    return Effect("frequency_dependent_stiffness", pids=(pid,), values={"alpha": 0.0, "a": a, "f_ref_hz": f_ref}).apply(model)


def test_frequency_dependent_modes_match_brute_force(model):
    """Every mode solves K(f_j) φ = λ M φ at its own frequency (full eigh, fixed point).
    The layer's stiffness changes by −39 … +20 % over the modes; the enriched Ritz basis
    keeps λ within 1e-4 (measured 3.6e-5 at the lowest mode), far below test accuracy."""
    m = _law(model)
    lam, phi = jaxfem.modes(m, 12)
    assert lam.dtype == jnp.float64
    K0, M = (np.asarray(a.todense()) for a in jaxfem.assemble(model))
    doubled = jaxfem.correct(model, [model.element_ids(pids=[3]).tolist()], jnp.array([1.0]))
    Kg = np.asarray(jaxfem.assemble(doubled)[0].todense()) - K0  # stiffness of the layer (pid 3)
    for j in range(12):
        lj = float(lam[j])
        for _ in range(60):
            s = 0.3 * np.log(np.sqrt(lj) / (2 * np.pi) / 60.0)
            w, v = sl.eigh(K0 + s * Kg, M)
            lj = w[j]
        assert float(lam[j]) == pytest.approx(lj, rel=1e-4)
        mac = (v[:, j] @ np.asarray(phi[:, j])) ** 2 / ((v[:, j] @ v[:, j]) * float(phi[:, j] @ phi[:, j]))
        assert mac > 1 - 1e-4
    lam0 = jaxfem.modes(model, 12)[0]
    assert not np.allclose(lam, lam0, rtol=1e-3)  # the law does something


def test_frequency_dependent_derivatives_match_finite_differences(model):
    m = _law(model)

    group = [model.element_ids(pids=[3]).tolist()]

    def f(a, alpha):
        mm = eqx.tree_at(lambda q: q.viscoelastic.a, jaxfem.correct(m, group, jnp.stack([alpha])), a)
        lam, phi = jaxfem.modes(mm, 8)
        return jnp.concatenate([lam, phi[:12, 3]])

    for arg in (0, 1):
        x0 = [jnp.asarray(0.3), jnp.asarray(0.05)]
        tangent = [jnp.zeros(()), jnp.zeros(())]
        tangent[arg] = jnp.ones(())
        _, jvp = jax.jvp(f, x0, tangent)
        h = 1e-5
        xp, xm = list(x0), list(x0)
        xp[arg], xm[arg] = x0[arg] + h, x0[arg] - h
        fd = (f(*xp) - f(*xm)) / (2 * h)
        np.testing.assert_allclose(jvp, fd, rtol=2e-5, atol=1e-7 * float(jnp.max(jnp.abs(fd))))


def test_no_law_is_the_plain_eigenproblem(model):
    lam, _ = jaxfem.modes(model, 6)
    ref, _ = jaxfem.eigh(*jaxfem.assemble(model), 6)
    np.testing.assert_array_equal(lam, ref)


def test_stiff_joint_and_stiff_support_recover_the_rigid_model(model):
    base = _freqs(model)
    node = next(int(n) for n in model.node_ids if len(set(elements_at(model, int(n)).values())) == 2)
    pids = tuple(sorted(set(elements_at(model, node).values())))
    joint = at_reference(model, Effect("joint", pids=pids, nodes=(node,)), [20.0])
    stiff = Effect("joint", pids=pids, nodes=(node,), values={k: 1e4 * v for k, v in joint.values.items()})
    extended = stiff.apply(model)
    assert extended.n_dof == model.n_dof + 6 and len(extended.bushes.ids) == len(model.bushes.ids) + 2  # trans, rot
    np.testing.assert_allclose(_freqs(extended), base, rtol=1e-4)
    soft = Effect("joint", pids=pids, nodes=(node,), values={k: 1e-2 * v for k, v in joint.values.items()})
    assert np.all(_freqs(soft.apply(model)) <= base * (1 + 1e-9)) and not np.allclose(_freqs(soft.apply(model)), base, rtol=1e-3)
    support = at_reference(model, Effect("boundary_spring", nodes=(1,)), [20.0])
    assert set(support.values) == {"k_trans", "k_rot"}  # grid 1 is clamped: its SPC is released
    rigid = Effect("boundary_spring", nodes=(1,), values={k: 1e4 * v for k, v in support.values.items()})
    np.testing.assert_allclose(_freqs(rigid.apply(model)), base, rtol=1e-4)


def test_added_mass(model):
    heavier = Effect("added_mass", nodes=(14,), values={"m": 25.0}).apply(model)
    assert total_mass(heavier) == pytest.approx(total_mass(model) + 25.0, rel=1e-12)
    assert np.all(_freqs(heavier) <= _freqs(model) * (1 + 1e-12))


def test_a_spring_to_ground_on_one_translation(model):
    """A vertical support is not springs in all three translations (issue 46): a z-only
    spring stiffens the modes moving the grid in z and leaves a y-only one's alone."""
    z = parse_effect("boundary_spring:node=14;components=3")
    assert z == Effect("boundary_spring", nodes=(14,), components=(3,)) and z.to_json()["components"] == [3]
    k = 1e7
    stiff = z.updated([0.0]) if z.values else Effect("boundary_spring", nodes=(14,), components=(3,), values={"k": k})
    added = stiff.apply(model)
    s = added.springs
    new = np.flatnonzero(~np.isin(s.ids, model.springs.ids))
    assert len(new) == 1 and s.components[new[0], 0] == 3 and float(s.k[new[0]]) == k
    every = Effect("boundary_spring", nodes=(14,), values={"k": k}).apply(model)
    assert len(every.springs.ids) - len(model.springs.ids) == 3
    f0, fz, fxyz = _freqs(model), _freqs(added), _freqs(every)
    assert np.all(fz >= f0 * (1 - 1e-12)) and np.all(fxyz >= fz * (1 - 1e-12)) and np.any(fxyz > fz * 1.01)
    assert "on translation z of grid 14 only" in stiff.advice([0.1])
    with pytest.raises(ValueError, match="components"):
        Effect("boundary_spring", nodes=(14,), components=(4,))


def test_the_whole_structure_and_groups_together_are_candidates(model):
    """A global error is the commonest of all: stiffness and mass of the whole structure,
    and of the best-screening groups together, join the group candidates (issue 46)."""
    from updating.diagnosis._candidates import Candidate, _wider

    groups = []
    for p, score in ((3, 0.9), (5, 0.8), (1, 0.1)):
        c = Candidate(GroupStiffness(pids=(p,)), None)
        c.screen = score
        groups.append(c)
    wider = {(e.kind, e.pids): e.where() for e in _wider(model, groups)}
    assert wider[("stiffness", tuple(stiffness_pids(model)))] == "the whole structure"
    assert ("mass", tuple(p for p in stiffness_pids(model) if p in structural_pids(model))) in wider
    assert wider[("stiffness", (3, 5))] == "pids 3, 5 together" and ("stiffness", (1, 3, 5)) in wider
    beam = jaxfem.build_model(read_bdf_text("\n".join(
        [f"GRID,{i + 1},,{0.1 * i:.1f},0.,0." for i in range(9)] + [f"CBAR,{i + 1},{1 + i // 4},{i + 1},{i + 2},0.,1.,0."
                                                                     for i in range(8)]
        + ["PBAR,1,1,1.e-4,1.e-8,2.e-8,1.e-8", "PBAR,2,1,2.e-4,2.e-8,3.e-8,2.e-8", "MAT1,1,70.E9,,0.3,2700.",
           "PARAM,COUPMASS,1"])))
    whole = Effect("stiffness", pids=tuple(stiffness_pids(beam)), values={"alpha": 0.05}).apply(beam)
    np.testing.assert_allclose(_freqs(whole, 16)[6:], _freqs(beam, 16)[6:] * np.sqrt(1.05), rtol=1e-9)  # K → 1.05 K


def test_a_frequency_law_survives_elements_added_after_it(model):
    """A diagnosis round after a declared law adds dormant springs and bushes: the law's
    weights grow with the blocks (the new elements are not in the layer), its modes unchanged."""
    law = FrequencyDependentStiffness(pids=(3,), alpha=0.0, a=0.1, f_ref_hz=50.0).apply(model)
    more, _ = jaxfem.add_ground_springs(law, 14, 0.0, (1, 2, 3))
    more, _ = jaxfem.add_bush(more, 14, 15, [0.0] * 6)
    assert [w.shape[0] for w in more.viscoelastic.weights][2:4] == [len(more.springs.ids), len(more.bushes.ids)]
    np.testing.assert_allclose(_freqs(more, 8), _freqs(law, 8), rtol=1e-12)


def test_parse_effect():
    assert parse_effect("joint:node=3007;pids=21,22") == Effect("joint", pids=(21, 22), nodes=(3007,))
    assert parse_effect("mass:eids=201-203,207").eids == (201, 202, 203, 207)
    for bad in ("joint", "spring:node=1", "joint:grid=5", "mass:eids=a-b"):
        with pytest.raises(ValueError, match="effect"):
            parse_effect(bad)


def test_law_coefficient_is_an_updating_parameter(model):
    m = _law(model, a=0.1)
    m2, par = parameterise(m, [Parameter("a", "a", pids=(3,))])
    updated = par.apply(m2, jnp.log1p(jnp.array([0.2])))
    assert float(updated.viscoelastic.a) == pytest.approx(0.3)
    with pytest.raises(ValueError, match="frequency law"):
        parameterise(model, [Parameter("a", "a", pids=(3,))])[1].apply(model, jnp.zeros(1))


def _shared_grid(model):
    node = next(int(n) for n in model.node_ids if len(set(elements_at(model, int(n)).values())) == 2)
    return node, tuple(sorted(set(elements_at(model, node).values())))


def _examples(model):
    node, pids = _shared_grid(model)
    f = [5.0, 20.0, 80.0]
    return [GroupStiffness(pids=(2,), alpha=0.1), GroupMass(pids=(7,), eids=(), beta=-0.05),
            FrequencyDependentStiffness(pids=(3,), alpha=0.05, a=0.1, f_ref_hz=60.0),
            Joint(nodes=(node,), pids=pids).at_reference(model, f), AddedMass(nodes=(14,), m=3.0),
            BoundarySpring(nodes=(14,)).at_reference(model, f), BoundarySpring(nodes=(1,)).at_reference(model, f)]


def test_one_parameterisation_per_effect(model):
    """At the same θ the batched fit's masks (``extension``), the engine's parameters
    (``parameters``) and the fitted values (``updated``, applied to the nominal model)
    give the same model: with a₀ = 0.1 the law's ``a = a₀ + (e^θ₁ − 1)`` everywhere."""
    for effect in _examples(model):
        extended = effect.apply(model)
        theta = np.log1p(np.array([0.2, 0.15]))[: len(effect.parameters(model, extended))]
        masked = effect.extension(model, extended)(extended, jnp.asarray(theta))
        base, par = parameterise(extended, effect.parameters(model, extended))
        engine = par.apply(base, jnp.asarray(theta))
        fitted = effect.updated(theta)
        expected = _freqs(fitted.apply(model))
        for m in (masked, engine):
            np.testing.assert_allclose(_freqs(m), expected, rtol=1e-10, err_msg=effect.kind)
        assert not np.allclose(_freqs(extended), expected, rtol=1e-4), effect.kind
        assert effect.updated(np.zeros_like(theta)) == effect  # θ = 0: the reference
    law = FrequencyDependentStiffness(pids=(3,), alpha=0.05, a=0.1, f_ref_hz=60.0).updated(np.log1p([0.2, 0.15]))
    assert (law.alpha, law.a) == pytest.approx((1.05 * 1.2 - 1, 0.25), abs=1e-14)


def test_factory_builds_the_typed_effect_and_round_trips(model):
    for effect in _examples(model):
        assert isinstance(effect, AbstractEffect) and effect.kind in KINDS
        again = Effect(effect.kind, **effect.location(), values=effect.values, label=effect.label)
        assert type(again) is type(effect) and again == effect
        row = effect.to_json()
        assert list(row) == ["kind", "pids", "eids", "nodes", "where", "parameters"] + (
            ["components"] if effect.kind == "boundary_spring" else [])
        assert row["parameters"] == effect.values and row["where"] == effect.where()
    assert Effect("joint", nodes=(6001,), values={"k_trans": 1e8, "k_rot": 4e4}) == Joint(nodes=(6001,), k_trans=1e8, k_rot=4e4)
    assert Effect("stiffness", pids=(3,)).values == {} and Effect("mass", pids=(1, 2)).where() == "pid 1, 2"
    for kind, kw in (("added_mass", {"pids": (1,)}), ("joint", {"nodes": (1,), "values": {"m": 1.0}}),
                     ("joint", {}), ("stiffness", {}), ("frequency_dependent_stiffness", {"eids": (1,)}),
                     ("spring", {"nodes": (1,)})):
        with pytest.raises(ValueError, match="effect"):
            Effect(kind, **kw)
    with pytest.raises(ValueError, match="k_rot"):
        Joint(nodes=(_shared_grid(model)[0],), pids=_shared_grid(model)[1], k_trans=1.0).apply(model)


def test_candidates_by_kind(model):
    stiffness = GroupStiffness.candidates(model)
    whole = {e.pids[0] for e in stiffness if not e.eids}
    assert whole == set(stiffness_pids(model)) >= set(range(1, 9))  # the 8 beam groups and the rest
    assert {e.pids[0] for e in stiffness if e.eids} <= set(structural_pids(model))  # halves: beams and rods
    assert {e.pids[0] for e in FrequencyDependentStiffness.candidates(model)} == whole  # none above half the structure
    assert not any(e.eids for e in FrequencyDependentStiffness.candidates(model))
    assert {e.pids[0] for e in GroupMass.candidates(model)} == set(structural_pids(model)) & whole
    joints = Joint.candidates(model)
    assert joints and all(len(e.pids) == 2 and len(e.nodes) == 1 for e in joints)
    assert _shared_grid(model)[0] in {e.nodes[0] for e in joints}
    supports = BoundarySpring.candidates(model)
    assert [e.nodes for e in supports] == [(n,) for n in (1, 2, 3, 4)]  # the clamped base
    assert set(supports[0].at_reference(model, [20.0]).values) == {"k_trans", "k_rot"}


def test_plausibility(model):
    mass = total_mass(model)
    assert GroupStiffness(pids=(1,), alpha=0.3).plausibility(mass) == []
    assert "outside" in GroupMass(pids=(1,), beta=-0.7).plausibility(mass)[0]
    law = FrequencyDependentStiffness(pids=(3,), alpha=0.0, a=0.8, f_ref_hz=50.0)
    assert law.plausibility(mass) == ["a = 0.80 beyond ±0.5"]
    assert AddedMass(nodes=(14,), m=0.1 * mass).plausibility(mass) == []
    assert "% of the total" in AddedMass(nodes=(14,), m=0.5 * mass).plausibility(mass)[0]
    node, pids = _shared_grid(model)
    ref = Joint(nodes=(node,), pids=pids).at_reference(model, [20.0])
    assert ref.updated(np.log([10.0, 10.0])).plausibility(mass, ref) == []
    assert "rigid" in ref.updated(np.log([1.0, 2e3])).plausibility(mass, ref)[0]


def test_a_joint_that_would_release_nothing_is_refused(model):
    """A joint given at a grid that is neither RBE2-dependent nor shared by the groups named
    added springs to a new grid nothing was attached to: the model's modes unchanged, no
    word. It is refused, naming the grid and what to give instead."""
    from importlib import resources

    node, pids = _shared_grid(model)
    values = {"k_trans": 1e8, "k_rot": 1e4}
    assert not np.allclose(_freqs(Effect("joint", pids=pids, nodes=(node,), values=values).apply(model)),
                           _freqs(model), rtol=1e-3)
    for wrong in ((), (pids[0],), (pids[0], 999)):
        with pytest.raises(ValueError, match=rf"joint at grid {node} releases nothing.*give two pids meeting there"):
            Effect("joint", pids=wrong, nodes=(node,), values=values).apply(model)
    garteur = jaxfem.build_model(read_bdf_text((resources.files("updating") / "data" / "garteur.bdf").read_text()))
    with pytest.raises(ValueError, match=r"grid 1013 is the master of an RBE2: give its dependent grids \(2000, 2001, 3001\)"):
        Effect("joint", nodes=(1013,), values=values).apply(garteur)
    released = Effect("joint", nodes=(2000, 2001, 3001), values=values).apply(garteur)
    assert released.n_dof == garteur.n_dof + 18  # the three dependent grids, now independent
