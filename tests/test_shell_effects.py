"""Effects on shells (patches: delamination, local membrane/bending stiffness, distributed
mass), their masks for the shared-structure fits, shell supports as candidates, and test
data relative to a reference state (updating.relative_to)."""

import warnings

import jax.numpy as jnp
from types import SimpleNamespace

import numpy as np
import pytest

import jaxfem
from benchmarks.shell_models import plate
from identification import ModalData, Sensors
from jaxfem.io import read_bdf_text
from updating import Delamination, DistributedMass, Effect, PatchStiffness, parse_effect, relative_to
from updating.diagnosis._effects import RADII, BoundarySpring
from updating._simulation import simulate_test
from updating.diagnosis._topology import shell_area, shell_size, total_mass

LAMINATE = """MAT8,8,5.4e10,5.4e10,0.05,5.0e9,2.0e9,2.0e9,1460.0
PCOMP,1,,,,,,,,
,8,0.002,0.,,8,0.002,0.,"""


@pytest.fixture(scope="module")
def panel():
    """A clamped 0.4 × 0.3 m CFRP plate, 10 × 8 CQUAD4 of 40 × 37.5 mm."""
    return jaxfem.build_model(read_bdf_text(plate(0.4, 0.3, 10, 8, LAMINATE, bc="cfff")))


def _grid_at(model, x, y):
    xyz = np.asarray(model.xyz)
    return int(model.node_ids[np.argmin(np.hypot(xyz[:, 0] - x, xyz[:, 1] - y))])


def _kd(model):
    K, M = jaxfem.assemble(model)
    return np.asarray(K.todense()), np.asarray(M.todense())


def test_patch_ladder_and_location(panel):
    """Radii of the ladder hold 4, 12, ... shells about an interior grid; the
    patch lists its elements and says where it is, in mm."""
    h = shell_size(panel)
    assert 0.0375 <= h <= 0.040  # the median edge of 40 × 37.5 mm elements
    node = _grid_at(panel, 0.2, 0.15)
    counts = [len(Delamination.at(panel, node, r * h).eids) for r in RADII]
    assert counts[:2] == [4, 12] and counts == sorted(counts) and counts[-1] > counts[1]
    d = Delamination.at(panel, node, 1.7 * h)
    assert d.where() == f"12 shells within {1000 * 1.7 * h:.0f} mm of grid {node}"
    assert d.to_json()["radius_m"] == pytest.approx(1.7 * h)
    assert parse_effect(f"delamination:node={node};radius=0.06").elements(panel).tolist() == list(
        Delamination.at(panel, node, 0.06).eids)
    with pytest.raises(ValueError, match="radius must be > 0"):
        Effect("delamination", nodes=(node,))
    with pytest.raises(ValueError, match="membrane or bending"):
        PatchStiffness(nodes=(node,), radius=0.05, part="shear")


@pytest.mark.parametrize("effect, part", [(Delamination, 2), (PatchStiffness, 1)])
def test_patch_part_apply_parameter_and_mask_agree(panel, effect, part):
    """A factor on the patch's shear (bending) stiffness: applied, as the update's
    parameter and as the diagnosis' mask, the same matrices; only the patch changes."""
    node = _grid_at(panel, 0.16, 0.12)
    ref = effect.at(panel, node, 0.06).at_reference(panel, [50.0])
    assert ref.factor == 1.0
    theta = np.log(0.2)
    applied = ref.updated([theta]).apply(panel)
    parts = np.asarray(applied.quads.parts)
    inside = np.isin(panel.quads.ids, ref.eids)
    np.testing.assert_allclose(parts[inside, part], 0.2)
    np.testing.assert_allclose(np.delete(parts, part, axis=1), 1.0)
    np.testing.assert_allclose(parts[~inside, part], 1.0)
    (param,) = ref.parameters(panel, panel)
    from updating import ParameterSet, parameterise

    base, par = parameterise(panel, ParameterSet((param,)))
    by_param = par.apply(base, jnp.array([theta]))
    by_mask = ref.extension(panel, panel)(panel, jnp.array([theta]))
    K0, _ = _kd(panel)
    for other in (by_param, by_mask):
        np.testing.assert_allclose(_kd(other)[0], _kd(applied)[0], atol=1e-9 * np.abs(K0).max())
    f0, f1 = (np.asarray(jaxfem.frequencies_hz(jaxfem.modes(m, 6)[0])) for m in (panel, applied))
    assert np.all(f1 < f0) and np.max(1 - f1 / f0) > 1e-4  # softer where the patch works


def test_distributed_mass(panel):
    """NSM over a patch: the reference carries 1 % of the total mass; applied and as a mask
    (woken at e^θ) the same mass matrix; the mass added is NSM × area."""
    node = _grid_at(panel, 0.2, 0.15)
    ref = DistributedMass.at(panel, node, 0.08).at_reference(panel, [50.0])
    area = shell_area(panel, ref.eids)
    assert ref.nsm * area == pytest.approx(0.01 * total_mass(panel), rel=1e-9)
    heavier = ref.updated([np.log(3.0)])
    assert total_mass(heavier.apply(panel)) - total_mass(panel) == pytest.approx(heavier.mass(panel), rel=1e-6)
    _, M_applied = _kd(heavier.apply(panel))
    _, M_mask = _kd(ref.extension(panel, panel)(panel, jnp.array([np.log(3.0)])))
    np.testing.assert_allclose(M_mask, M_applied, atol=1e-12 * np.abs(M_applied).max())
    assert "kg/m²" in heavier.advice(0.1)


def test_support_of_a_clamped_shell_edge(panel):
    """A clamped shell grid is a support candidate whose reference stiffness comes from the
    shells' own diagonal stiffness there (no beam needed)."""
    supports = BoundarySpring.candidates(panel)
    assert supports
    ref = supports[0].at_reference(panel, [50.0])
    assert ref.k_trans > 0 and ref.k_rot > 0 and ref.k_trans > 100 * ref.k_rot


def test_relative_to_carries_the_change_onto_the_model(panel):
    """A model 3 % too stiff against a 'healthy' truth: relative to the healthy test, the
    damaged test becomes the model's own modes times the measured change; the unchanged
    state gives back exactly the model's modes."""
    grids = [int(g) for g, x in zip(panel.node_ids, np.asarray(panel.xyz)) if x[0] > 0]
    sensors = Sensors.from_components(grids, np.full(len(grids), 3))
    healthy = jaxfem.correct(panel, [panel.element_ids().tolist()], jnp.array([-0.03]))
    node = _grid_at(panel, 0.2, 0.15)
    damaged = DistributedMass.at(healthy, node, 0.06).at_reference(healthy, [50.0]).apply(healthy)
    ref_test, dmg_test = simulate_test(healthy, sensors, 8), simulate_test(damaged, sensors, 8)
    model_test = simulate_test(panel, sensors, 8)
    same, _ = relative_to(panel, ref_test, ref_test)
    np.testing.assert_allclose(same.frequencies_hz, model_test.frequencies_hz, rtol=1e-12)
    np.testing.assert_allclose(np.abs(same.shapes), np.abs(model_test.shapes), atol=1e-9)
    data, rows = relative_to(panel, dmg_test, ref_test)
    change = dmg_test.frequencies_hz / ref_test.frequencies_hz
    np.testing.assert_allclose(data.frequencies_hz / model_test.frequencies_hz, change, rtol=1e-12)
    assert [r["change_pct"] for r in rows] == pytest.approx(list(100 * (change - 1)))
    assert min(change) < 0.999  # the mass is seen
    with pytest.raises(ValueError, match="same sensors"):
        relative_to(panel, dmg_test, ModalData(ref_test.frequencies_hz, ref_test.shapes[:-1],
                                               Sensors.from_components(grids[:-1], np.full(len(grids) - 1, 3))))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        relative_to(panel, ModalData(dmg_test.frequencies_hz[:6], dmg_test.shapes[:, :6], sensors), ref_test)
    assert any("reference modes [7, 8]" in str(w.message) for w in caught)


def test_seam_springs_per_unit_length_on_a_barrel():
    """A frame-to-skin seam of the small barrel: candidates along every frame, each grid's
    share half the distance to its neighbours (the run's shares sum to its length between
    the end grids' outer half-spans), springs = value × share, and a released seam softens
    the barrel while the reference (slightly softer than rigid) hardly does."""
    from benchmarks import fuselage
    from updating.diagnosis._effects import SEAM_GRIDS, Seam

    model = jaxfem.build_model(read_bdf_text(fuselage.barrel_bdf(3000)))
    seams = [s for s in Seam.candidates(model) if s.pids == (101, 201)]
    assert seams and all(len(s.nodes) <= SEAM_GRIDS for s in seams)
    seam = next(s for s in seams if len(s.nodes) == SEAM_GRIDS)
    xyz = np.asarray(model.xyz)[model.node_index(list(seam.nodes))]
    gaps = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
    shares = seam.shares(model)
    np.testing.assert_allclose(shares[1:-1], 0.5 * (gaps[:-1] + gaps[1:]), rtol=1e-12)
    ref = seam.at_reference(model, [10.0])
    extended = ref.apply(model)
    new = np.isin(extended.bushes.ids, np.setdiff1d(extended.bushes.ids, model.bushes.ids))
    k = np.asarray(extended.bushes.k)[new]
    np.testing.assert_allclose(np.sort(k[:, 0][k[:, 0] > 0]), np.sort(ref.k_trans * shares), rtol=1e-12)
    np.testing.assert_allclose(np.sort(k[:, 3][k[:, 3] > 0]), np.sort(ref.k_rot * shares), rtol=1e-12)
    f = [np.asarray(jaxfem.frequencies_hz(jaxfem.modes(m, 12)[0]))[6:] for m in
         (model, extended, ref.updated(np.log([1e-4, 1e-4])).apply(model))]
    assert np.max(np.abs(f[1] / f[0] - 1)) < 0.005  # the reference: almost rigid
    assert np.max(np.abs(f[2] / f[0] - 1)) > 0.01 and np.all(f[2] <= f[0] * (1 + 1e-9))  # released: softer
    with pytest.raises(ValueError, match="name the shell group and the beam group"):
        Seam(nodes=seam.nodes, pids=(101,))


def test_the_joints_and_seams_of_a_region_release_each_grid_once():
    """A floor grid of the barrel that is both a joint (floor shell and floor beam) and on a
    seam: the region's structures release it once, and the augmented model (every
    structure released and held stiffer than its reference) keeps the nominal frequencies.
    Released twice, the second release cut the first's grid loose: a rotation of one grid
    mixed into the modes above 100 Hz and lowered them by up to 12 %."""
    from benchmarks import fuselage
    from updating.diagnosis._candidates import _moved, augment, region_structures
    from updating.diagnosis._effects import KINDS, Joint, Seam, _seam_lines
    from updating.diagnosis._topology import masters

    model = jaxfem.build_model(read_bdf_text(fuselage.barrel_bdf(2500)))
    joints, seams = {n for j in Joint.candidates(model) for n in j.nodes}, Seam.candidates(model)
    both = sorted({n for s in seams for n in s.nodes if n in joints})
    region = [both[0], next(n for n in both[1:] if not any({both[0], n} <= set(s.nodes) for s in seams))]
    structures = region_structures(model, region, {}, KINDS, 4)
    dep, lines = masters(model), _seam_lines(model)
    released = [m for s in structures if s.kind != "boundary_spring" for m in _moved(s, model, dep, lines)]
    assert set(region) <= {g for g, _ in released} and len(released) == len(set(released))
    f0 = np.asarray(jaxfem.frequencies_hz(jaxfem.modes(model, 26, solver="sparse")[0]))
    aug, _, stiffened = augment(model, [], structures, f0[6:])
    assert len(stiffened) == len(structures) >= 2
    f1 = np.asarray(jaxfem.frequencies_hz(jaxfem.modes(aug, 26, solver="sparse")[0]))
    assert np.max(np.abs(f1[6:] / f0[6:] - 1)) < 1e-3


def test_a_frames_and_a_stringers_seams_crossing_at_a_hot_grid_are_both_offered():
    """The hot grid where a frame and a stringer cross the skin: both seams are offered
    (the best of each beam group first), each releasing its own beams there; a grid one
    element from a scored grid takes 0.9 of its score (_dilated)."""
    from benchmarks import fuselage
    from updating.diagnosis._candidates import _dilated, neighbours, region_structures
    from updating.diagnosis._effects import KINDS, Seam

    model = jaxfem.build_model(read_bdf_text(fuselage.barrel_bdf(2500)))
    frame, stringer = fuselage.PID_FRAME, fuselage.PID_STRINGER
    lines: dict[int, set] = {}
    for s in Seam.candidates(model):
        lines.setdefault(s.pids[1], set()).update(s.nodes)
    cross = min(g for g in lines[frame] & lines[stringer] if not any(g in v for p, v in lines.items()
                                                                     if p not in (frame, stringer)))
    near = _dilated(model, {cross: 1.0}, 0.9)
    assert near.pop(cross) == 1.0 and near == dict.fromkeys(neighbours(model, cross), 0.9)
    structures = region_structures(model, [cross], {cross: 1.0}, KINDS, 4)
    beams = {s.pids[1] for s in structures if isinstance(s, Seam) and cross in s.line(model)}
    assert beams == {frame, stringer}


def test_a_seams_line_is_released_once_and_its_runs_are_masks_on_it():
    """A frame-to-skin seam is released along its whole line in the shared model
    (:func:`updating.diagnosis._candidates.augment`), held stiff; a run of the line softened through its
    own grids' springs (a mask) gives the frequencies of the nominal model with only that
    run released (Seam.apply), and the runs next to it are one grid along the line either
    way, each end out or in, and (coarse) half its length along, each end a quarter of it
    out or in, and the next lengths of the ladder about the same centre."""
    from dataclasses import replace

    import equinox as eqx

    from benchmarks import fuselage
    from updating.diagnosis._candidates import STIFF, augment, seam_onward, structural_candidate, structural_candidates
    from updating.diagnosis._effects import SEAM_GRIDS, SEAM_LENGTHS, SEAM_SCREEN, Seam

    model = jaxfem.build_model(read_bdf_text(fuselage.barrel_bdf(2500)))
    seam = next(s for s in Seam.candidates(model) if s.pids[1] == 201 and len(s.nodes) == SEAM_GRIDS
                and s.nodes[0] != s.line(model)[0])
    line = seam.line(model)
    start = line.index(seam.nodes[0])
    assert line[start:start + SEAM_GRIDS] == seam.nodes and len(line) > SEAM_LENGTHS[2]
    near = [n.nodes for n in seam.neighbours(line)]
    assert near == [line[start - 1:start + 4], line[start + 1:start + 6],  # one grid along
                    line[start - 1:start + 5], line[start:start + 6],  # an end out
                    line[start + 1:start + 5], line[start:start + 4]]  # an end in
    coarse = [n.nodes for n in seam.neighbours(line, coarse=True)]
    assert coarse[:2] == [line[max(0, start - 2):max(0, start - 2) + 5], line[start + 2:start + 7]]  # half along
    assert coarse[2:6] == near[2:]  # an end a quarter of its length (one grid) out or in
    assert coarse[6:8] == [line[start - 1:start + 6], line[start + 1:start + 4]]  # both ends out or in
    assert coarse[8:] == [line[start - 2:start + 6]]  # the ladder (3 about its centre: both ends in) up to 8
    long = seam.run(line, start, 9)
    assert [n.nodes for n in long.neighbours(line, coarse=True)][2:8] == [  # an end or both two grids out or in
        line[start - 2:start + 9], line[start:start + 11], line[start + 2:start + 9], line[start:start + 7],
        line[start - 2:start + 11], line[start + 2:start + 7]]
    longer = [(line.index(r.nodes[0]), len(r.nodes)) for r in seam.longer(line)]  # screened beside it
    assert len(set(longer)) == len(longer) and {m for _, m in longer} == {m for m in SEAM_SCREEN if m < len(line)}
    assert all(line[i:i + m] == r.nodes for (i, m), r in zip(longer, seam.longer(line)))
    assert all(i <= start + SEAM_GRIDS and i + m >= start for i, m in longer)  # overlapping it or next to it
    assert any(i <= start and i + m >= start + SEAM_GRIDS for i, m in longer if m == SEAM_SCREEN[0])  # one holds it

    f0 = np.asarray(jaxfem.frequencies_hz(jaxfem.modes(model, 20, solver="sparse")[0]))
    aug, _, (released,) = augment(model, [], [seam], f0[6:])
    assert released.line == line and set(released.springs) == set(line)
    assert all(len(t) == len(r) == 1 for t, r in released.springs.values())
    screened = structural_candidates(aug, [released])
    assert [c.reference.nodes for c in screened] == [seam.nodes] + [r.nodes for r in seam.longer(line)]
    assert all(c.released.line == line and c.scan for c in screened)
    assert released.trans == tuple(released.springs[g][0][0] for g in seam.nodes)
    assert released.rot == tuple(released.springs[g][1][0] for g in seam.nodes)
    soft = np.log([1e-5, 1e-5])
    run = released.seam(released.effect.run(line, start + 1, 8))
    c = structural_candidate(aug, run, theta0=soft)
    assert c.scan is None and c.released.line == line and c.reference.nodes == line[start + 1:start + 9]
    a = structural_candidate(aug, released.seam(seam), theta0=soft)  # a fine move, an end out: made once more
    b = structural_candidate(aug, released.seam(released.effect.run(line, start - 1, SEAM_GRIDS + 1)), theta0=soft)
    a.fit, b.fit = SimpleNamespace(theta=soft), SimpleNamespace(theta=soft + 1)
    ahead = seam_onward(aug, a, b)
    assert ahead.reference.nodes == line[start - 2:start + SEAM_GRIDS] and np.allclose(ahead.theta0, soft + 1)
    assert seam_onward(aug, b, a) is not None and seam_onward(aug, a, replace(b, reference=released.effect.run(
        line, 0, len(line)))) is None  # past the line's ends
    scale = {**{e: np.exp(soft[0]) for e in run.trans}, **{e: np.exp(soft[1]) for e in run.rot}}
    b = aug.bushes
    masked = eqx.tree_at(lambda m: m.bushes.k_scale, aug,
                         jnp.asarray([scale.get(int(e), 1.0) for e in b.ids]) * b.k_scale)
    alone = c.reference.updated(soft).apply(model)
    f_masked, f_alone = (np.asarray(jaxfem.frequencies_hz(jaxfem.modes(m, 20, solver="sparse")[0]))[6:]
                         for m in (masked, alone))
    assert np.max(np.abs(f_alone / f0[6:] - 1)) > 0.002  # the run released and softened moves the modes (0.4 %)
    np.testing.assert_allclose(f_masked, f_alone, rtol=2e-4)  # the rest of the line held STIFF × reference
    assert c.reference.k_trans == pytest.approx(replace(seam).at_reference(model, f0[6:]).k_trans * STIFF, rel=1e-12)


def test_a_climb_makes_its_last_move_again_before_asking_every_neighbour():
    """``_climb`` with ``onward``: down a valley (cost (x − 7)², from x = 2) the
    neighbours are asked at the start and at the bottom only."""
    from types import SimpleNamespace

    from updating.diagnosis._refine import _climb

    at = {x: SimpleNamespace(x=x, fit=SimpleNamespace(cost=float((x - 7) ** 2))) for x in range(12)}
    asked = []

    def near(c):
        asked.append(c.x)
        return [at[x] for x in (c.x - 1, c.x + 1) if x in at]

    moves = _climb(at[2], near, lambda a, b: at.get(2 * b.x - a.x))
    assert [b.x for _, b in moves] == [3, 4, 5, 6, 7] and asked == [2, 7]
    assert [b.x for _, b in _climb(at[2], near)] == [3, 4, 5, 6, 7]  # without: every step asks


def test_the_margin_about_a_region_goes_ring_by_ring_best_first_and_skips_clamped_grids(panel):
    """The place walk's margin (updating.diagnosis._candidates.margin): the region's neighbours
    first, then the next ring, each best scoring first, never a clamped grid."""
    from updating.diagnosis._candidates import margin, neighbours

    edge = _grid_at(panel, 0.04, 0.15)  # one element from the clamped edge x = 0
    ring1 = set(neighbours(panel, edge))
    clamped = {g for g in ring1 if abs(float(panel.xyz[panel.node_index([g])[0], 0])) < 1e-9}
    assert len(ring1) == 8 and len(clamped) == 3
    assert set(margin(panel, [edge], 5, {})) == ring1 - clamped
    ring2 = {g for r in ring1 for g in neighbours(panel, r)} - ring1 - {edge} - clamped
    favourite = max(ring2)
    got = margin(panel, [edge], 7, {favourite: 1.0})
    assert set(got[:5]) == ring1 - clamped and got[5] == favourite and got[6] in ring2
