"""A payload on an interpolation element (:class:`updating.Payload`): a CONM2 at the
centroid of a footprint of grids (or its CG above it) with a plate's (a box's) inertia, carried
by an RBE3 on their translations (:func:`jaxfem._edit.add_rbe3`): the same matrices as the
bulk-data cards, the same as a dormant element woken by the diagnosis' masks, clear errors,
and no wider element blocks."""

from dataclasses import replace

import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.shell_models import plate
from jaxfem import _edit as edit
from jaxfem import node_transform
from jaxfem.io import read_bdf_text
from updating import Payload, parse_effect
from updating.diagnosis._candidates import augment, region_shells
from updating.diagnosis._topology import total_mass

MAT = "MAT1,1,7.0e10,,0.33,2700.0\nPSHELL,1,1,0.002,1\n"


@pytest.fixture(scope="module")
def text():
    """A free 0.4 × 0.3 m aluminium plate, 8 × 6 CQUAD4."""
    return plate(0.4, 0.3, 8, 6, MAT, bc="free")


@pytest.fixture(scope="module")
def model(text):
    return jaxfem.build_model(read_bdf_text(text))


def _shell(model, k=20):
    return [int(model.node_ids[r]) for r in model.quads.nodes[k]]


def _dense(model):
    K, M = jaxfem.assemble(model)
    return np.asarray(K.todense()), np.asarray(M.todense())


def test_payload_equals_the_bulk_data_rbe3_and_conm2(model, text):
    """The effect's matrices are those of GRID + RBE3 (123 of four grids) + CONM2 read from
    bulk data, the CONM2 with a uniform a × b plate's inertia (m b²/12, m a²/12,
    m (a² + b²)/12 about x, y, z); the structure's mass grows by m, its lowest elastic
    frequency falls."""
    grids = _shell(model)
    xyz = np.asarray(model.xyz)[model.node_index(grids)]
    x = xyz.mean(axis=0)
    a, b = np.ptp(xyz[:, 0]), np.ptp(xyz[:, 1])  # the shell's sides along x and y
    inertia = ",".join(repr(float(v)) for v in (0.5 * b * b / 12, 0.0, 0.5 * a * a / 12, 0.0, 0.0,
                                                0.5 * (a * a + b * b) / 12))
    cards = (f"GRID,99,,{float(x[0])!r},{float(x[1])!r},{float(x[2])!r}\n"
             f"RBE3,98,,99,123456,1.,123,{grids[0]},{grids[1]}\n,{grids[2]},{grids[3]}\n"
             f"CONM2,97,99,,0.5\n,{inertia}\n")
    truth = jaxfem.build_model(read_bdf_text(text + cards))
    added = model.with_effect(Payload(nodes=tuple(grids), m=0.5))
    (K1, M1), (K2, M2) = _dense(truth), _dense(added)
    np.testing.assert_array_equal(K2, K1)
    np.testing.assert_allclose(M2, M1, rtol=0, atol=1e-15 * np.abs(M1).max())
    assert total_mass(added) == pytest.approx(total_mass(model) + 0.5, rel=1e-12)
    f0, f1 = (np.asarray(jaxfem.frequencies_hz(jaxfem.modes(m, 8)[0]))[6:] for m in (model, added))
    assert np.all(f1 <= f0 * (1 + 1e-12)) and np.max(1 - f1 / f0) > 1e-3
    # the mass moves with the mean translation of its four grids: a rigid x-translation carries m
    u = np.array([1.0 if c == 1 else 0.0 for _, c in added.dofs.labels])
    assert u @ M2 @ u - u @ _dense(model)[1] @ u == pytest.approx(0.5, rel=1e-12)


def test_a_payload_with_its_cg_above_the_footprint_is_a_box_conm2(model, text):
    """Height h: the bulk-data CONM2 with offset X3 = h (the plate lies in z = 0, n = +z)
    and a uniform box's inertia, 2h high (m (b² + 4h²)/12, m (a² + 4h²)/12, m (a² + b²)/12)."""
    grids = _shell(model)
    xyz = np.asarray(model.xyz)[model.node_index(grids)]
    x = xyz.mean(axis=0)
    a, b, m, h = np.ptp(xyz[:, 0]), np.ptp(xyz[:, 1]), 0.5, 0.04
    c = 2 * h
    inertia = ",".join(repr(float(v)) for v in (m * (b * b + c * c) / 12, 0.0, m * (a * a + c * c) / 12, 0.0, 0.0,
                                                m * (a * a + b * b) / 12))
    cards = (f"GRID,99,,{float(x[0])!r},{float(x[1])!r},{float(x[2])!r}\n"
             f"RBE3,98,,99,123456,1.,123,{grids[0]},{grids[1]}\n,{grids[2]},{grids[3]}\n"
             f"CONM2,97,99,,{m},0.,0.,{h}\n,{inertia}\n")
    truth = _dense(jaxfem.build_model(read_bdf_text(text + cards)))[1]
    payload = Payload(nodes=tuple(grids), m=m, height=h)
    M = _dense(model.with_effect(payload))[1]
    np.testing.assert_allclose(M, truth, rtol=0, atol=1e-15 * np.abs(truth).max())
    assert np.max(np.abs(M - _dense(model.with_effect(Payload(nodes=tuple(grids), m=m)))[1])) > 1e-3 * m * h
    ref = payload.at_reference(model, [50.0])
    assert ref.height == h and ref.size == pytest.approx(np.sqrt(a * b), rel=1e-12)  # a square of the same area
    assert "CG 0.04 m" in payload.advice([0.1, 0.2]) and "a box 0.08 m high" in payload.advice([0.1, 0.2])
    assert parse_effect(f"payload:nodes={','.join(map(str, grids))};height=0.04") == Payload(nodes=tuple(grids),
                                                                                             height=0.04)
    assert any("more than twice its size" in n for n in replace(ref, height=3 * ref.size).plausibility(1e3))


def test_the_rbe3_grid_widens_only_the_block_that_uses_it(model):
    """An RBE3 over four grids depends on 12 DoFs: the DoF map widens, the shells' element
    transforms keep their 6 columns a grid (assembly cost unchanged), the mass's takes 12."""
    added = model.with_effect(Payload(nodes=tuple(_shell(model)), m=0.5))
    assert added.dofs.index.shape[1] == 12
    t, idx = node_transform(added, added.quads.nodes)
    assert t.shape[1:] == (24, 24) and idx.shape[1] == 24
    t, idx = node_transform(added, added.masses.nodes[:, None])
    assert t.shape[1:] == (6, 12)


def test_a_dormant_payload_woken_by_its_mask_is_the_payload(model):
    """The diagnosis' shared model holds a dormant payload on each shell at the region's
    grids; its masks at θ give the mass matrix of the payload applied with m·e^θ₀ and its
    CG θ₁ footprint sizes high; an applied payload's own masks move it from its height."""
    node = int(model.node_ids[model.node_index([_shell(model)[2]])[0]])
    aug, dormant, _ = augment(model, [node], [], np.array([50.0, 80.0]))
    payloads = [(ref, ids) for ref, ids in dormant if isinstance(ref, Payload)]
    assert [ref.nodes for ref, _ in payloads] == [g for _, g in region_shells(model, [node])]
    assert len(payloads) == 4  # the four shells about an interior grid
    ref, ids = payloads[1]
    assert ref.m == pytest.approx(0.01 * total_mass(model)) and "shell" in ref.where()
    n = model.n_dof  # the shared model's extra DoFs (springs at the grid) come after the nominal ones
    for theta in ([np.log(2.5), 0.0], [np.log(2.5), 0.7], [-1.0, -0.4]):  # θ₁: the CG's height in sizes
        woken = ref.dormant_extension(aug, ids)(aug, jnp.array(theta))
        applied = ref.updated(theta).apply(model)
        M_woken, M_applied = _dense(woken)[1], _dense(applied)[1]
        np.testing.assert_allclose(M_woken[:n, :n], M_applied, rtol=0, atol=1e-14 * np.abs(M_applied).max())
    assert ref.updated([np.log(2.5), 0.7]).m == pytest.approx(2.5 * ref.m)
    assert ref.updated([np.log(2.5), 0.7]).height == pytest.approx(0.7 * ref.size)
    # the applied payload's own parameters at its height: θ₁ shifts it from there
    high = ref.updated([0.0, 0.7])
    moved = high.extension(model, high.apply(model))(high.apply(model), jnp.array([0.3, -0.2]))
    np.testing.assert_allclose(_dense(moved)[1], _dense(high.updated([0.3, -0.2]).apply(model))[1], rtol=0,
                               atol=1e-14 * np.abs(M_applied).max())


def test_payload_errors_and_its_command_line_form(model):
    grids = _shell(model)
    assert parse_effect("payload:nodes=" + ",".join(map(str, grids))) == Payload(nodes=tuple(grids))
    with pytest.raises(ValueError, match="at least 3 grids"):
        Payload(nodes=tuple(grids[:2]))
    line = [int(g) for g in model.node_ids[:3]]  # three grids on one edge of the plate
    with pytest.raises(ValueError, match=r"do not determine the motion of the new grid \(rotation about"):
        model.with_effect(Payload(nodes=tuple(line), m=1.0))
    with pytest.raises(ValueError, match="grid id"):
        edit.add_rbe3(model, [grids[0], 10**9])
    assert "on an RBE3 over grids" in Payload(nodes=tuple(grids), m=2.0).advice(0.1)
