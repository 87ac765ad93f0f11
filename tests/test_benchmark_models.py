"""Benchmark models in benchmarks/models: GARTEUR SM-AG19 and the tree structure (thesis ch. 4).

The GARTEUR model is checked against thesis Tables 4.1-4.3 (mass, suspension modes, the 14
elastic modes in type and frequency); the tree model against sec. 4.3.2 (128 Timoshenko beams,
about 726 DoFs, 49 measured DoFs at 30 locations).
"""

import csv
import warnings

import numpy as np
import pytest

import jaxfem
from benchmarks.models import MODELS
from benchmarks.models.test_data import GARTEUR_TABLE_4_3, TREE_TABLE_4_6
from jaxfem.io import read_bdf


def _build(name):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bulk = read_bdf(MODELS / name)
        model = jaxfem.build_model(bulk)
    assert not bulk.unknown, bulk.report()
    return bulk, model


def _modes(model, n):
    K, M = jaxfem.assemble(model)
    lam, phi = jaxfem.eigh(K, M, n)
    return K, M, np.asarray(jaxfem.frequencies_hz(lam)), np.asarray(phi)


def _grid_motion(model, phi):
    """(n_grid, 6, n_mode) motion of every grid, dependent (RBE2) grids included."""
    index, coef = np.asarray(model.dofs.index), np.asarray(model.dofs.coef)
    padded = np.vstack([phi, np.zeros((1, phi.shape[1]))])
    return np.einsum("ncw,nwm->ncm", coef, padded[index])


def _sensors(name):
    with open(MODELS / name, newline="") as f:
        rows = list(csv.DictReader(f))
    return [(r["label"], int(r["node"]), int(r["component"])) for r in rows]


@pytest.fixture(scope="module")
def garteur():
    bulk, model = _build("garteur.bdf")
    K, M, f, phi = _modes(model, 24)
    return bulk, model, np.asarray(M.todense()), f, phi, _grid_motion(model, phi)


@pytest.fixture(scope="module")
def tree():
    bulk, model = _build("tree.bdf")
    _, _, f, _ = _modes(model, 20)
    return bulk, model, f


# ------------------------------------------------------------------------------- GARTEUR


def test_garteur_total_mass(garteur):
    _, model, M, _, _, _ = garteur
    labels = np.asarray(model.dofs.labels)
    heave = (labels[:, 1] == 3).astype(float)  # rigid translation along z
    mass = heave @ M @ heave
    assert abs(mass - 44.0) / 44.0 < 0.03, mass


def test_garteur_suspension_modes(garteur):
    _, _, _, f, _, _ = garteur
    # three vertical bungees only: x, y and yaw are free (zero), roll/pitch/heave on the springs
    assert np.all(f[:3] < 0.05), f[:6]
    assert np.all((f[3:6] > 0.3) & (f[3:6] < 3.0)), f[:6]
    assert f[6] > 5.0, f[6]


def _mode_type(model, M, phi, U, k):
    """Type of mode k: (kind, symmetry).

    The region with the largest share of the kinetic energy φᵀMφ (wing with drums and damping
    layer, fuselage, or fin with tailplane) decides: wing modes are 'bend' (flap), 'torsion'
    (drum twist) or 'inplane' (fore-aft) by their largest amplitude; fuselage/tail modes are
    'tailtorsion' (tailplane tips moving fore-aft in opposition) or 'lateral'. The model is
    symmetric about the x-z plane, so a mode is antisymmetric ('A') exactly when the fuselage
    and the fin move sideways, symmetric ('S') otherwise.
    """
    row = {int(g): i for i, g in enumerate(np.asarray(model.node_ids))}
    u = lambda g, c: U[row[g], c - 1, k]
    grid = np.asarray(model.dofs.labels)[:, 0]
    regions = {
        "wing": ((grid >= 2000) & (grid < 6000)) | (grid >= 8000),
        "fuselage": (grid >= 1000) & (grid < 2000),
        "tail": (grid >= 6000) & (grid < 8000),
    }
    energy = {r: (phi[:, k] * m) @ M @ (phi[:, k] * m) for r, m in regions.items()}
    centreline = list(range(1001, 1032)) + list(range(6001, 6008))
    side = max(abs(u(g, 2)) for g in centreline)
    sym = "A" if side > 1e-6 * np.abs(U[:, :3, k]).max() else "S"
    if max(energy, key=energy.get) == "wing":
        flap = max(abs(u(g, 3)) for g in list(range(2001, 2021)) + list(range(3001, 3021)))
        twist = max(abs(u(4001, 3) - u(4005, 3)), abs(u(5001, 3) - u(5005, 3))) / 2
        fore_aft = max(abs(u(4003, 1)), abs(u(5003, 1)))
        amplitude = {"bend": flap, "torsion": twist, "inplane": fore_aft}
        return max(amplitude, key=amplitude.get), sym
    tail_torsion = abs(u(7001, 1) - u(7009, 1)) / 2
    lateral = max(side, abs(u(7001, 3) - u(7009, 3)) / 2)
    return ("tailtorsion" if tail_torsion > lateral else "lateral"), sym


# Table 4.3 mode types (thesis order). Mode 2 'fuselage rotation' is the fuselage and tail
# rolling against the antisymmetrically bending wings; modes 11 and 12 (lateral fuselage, 2nd
# tail bending) are lateral fuselage/fin modes. Modes 9 and 10 (64.9 / 66.1 Hz) may swap.
GARTEUR_TYPES = [
    ("bend", "S"), ("lateral", "A"), ("torsion", "A"), ("torsion", "S"), ("bend", "A"), ("bend", "S"),
    ("inplane", "A"), ("inplane", "S"), ("bend", "A"), ("tailtorsion", "A"), ("lateral", "A"),
    ("lateral", "A"), ("bend", "S"), ("bend", "A"),
]


def test_garteur_elastic_modes_match_table_4_3(garteur):
    _, model, M, f, phi, U = garteur
    elastic = f[6:20]
    types = [_mode_type(model, M, phi, U, 6 + k) for k in range(14)]
    report = "\n".join(
        f"{r['mode']:2d} {r['description']:<38s} thesis {r['f_analytical_hz']:7.2f}  model {fm:7.2f} "
        f"({100 * (fm - r['f_analytical_hz']) / r['f_analytical_hz']:+5.1f} %)  {t}"
        for r, fm, t in zip(GARTEUR_TABLE_4_3, elastic, types)
    )
    print(report)
    # mode 1: 2-node (1st symmetric) wing bending near the measured 6.38 Hz
    assert types[0] == ("bend", "S")
    assert abs(elastic[0] - 6.38) / 6.38 < 0.10, report
    for r, fm in zip(GARTEUR_TABLE_4_3, elastic):
        assert abs(fm - r["f_analytical_hz"]) / r["f_analytical_hz"] < 0.15, report
    for k, expected in enumerate(GARTEUR_TYPES):
        if k in (8, 9):
            continue
        assert types[k] == expected, (k + 1, types[k], expected, report)
    assert sorted(types[8:10]) == sorted(GARTEUR_TYPES[8:10]), report


def test_garteur_sensors(garteur):
    _, model, _, _, _, _ = garteur
    rows = _sensors("garteur_sensors.csv")
    assert len(rows) == 24 and len(set(rows)) == 24
    assert len({r[0] for r in rows}) == 24
    model.node_index([n for _, n, _ in rows])  # every sensor grid exists
    assert all(1 <= abs(c) <= 6 for _, _, c in rows)


def test_garteur_property_regions(garteur):
    _, model, _, _, _, _ = garteur
    pids = set(np.asarray(model.beams.pids).tolist())
    # fuselage, wing sections (left 11-13, right 21-23), drums, fin, tailplane, damping layer
    assert {1, 11, 12, 13, 21, 22, 23, 31, 32, 41, 42, 51, 52} <= pids
    assert 100 <= len(model.beams.ids) <= 150
    assert sorted(np.asarray(model.masses.ids).tolist())[:5] == [801, 802, 803, 804, 805]
    assert np.allclose(np.asarray(model.springs.k), 4000.0) and len(model.springs.ids) == 3


# ------------------------------------------------------------------------------- tree


def test_tree_size_and_frequencies(tree):
    _, model, f = tree
    assert abs(model.n_dof - 726) / 726 < 0.10, model.n_dof
    assert abs(len(model.beams.ids) - 128) <= 10
    print("tree: n_dof", model.n_dof, "first frequencies [Hz]:", np.round(f[:20], 3))
    assert np.all(f > 1.0) and np.all(np.diff(f) >= -1e-9)


def test_tree_sensors(tree):
    _, model, _ = tree
    rows = _sensors("tree_sensors.csv")
    assert len(rows) == 49 and len(set(rows)) == 49
    assert len({n for _, n, _ in rows}) == 30  # 49 measured DoFs at 30 locations (thesis 4.3.2)
    model.node_index([n for _, n, _ in rows])
    assert all(1 <= abs(c) <= 6 for _, _, c in rows)


def test_tree_table_4_6_groups(tree):
    _, model, _ = tree
    pids = set(np.asarray(model.beams.pids).tolist())
    assert {1, 2, 3, 4, 11, 12, 21, 22} <= pids  # blades 1-4, pylon sections, joint blocks
    for error in TREE_TABLE_4_6:
        group = model.element_ids(pids=error["pids"])
        assert len(group) > 0
        assert np.isclose(error["factor"], 1.0 + error["alpha"])
        assert np.isclose(error["factor"] * (1.0 + error["alpha_exact_correction"]), 1.0)
        erroneous = jaxfem.correct(model, [group], np.array([error["alpha"]]))
        scale = np.asarray(erroneous.beams.k_scale)
        in_group = np.isin(np.asarray(model.beams.ids), group)
        assert np.allclose(scale[in_group], error["factor"]) and np.allclose(scale[~in_group], 1.0)
