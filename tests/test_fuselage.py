"""The generated fuselage barrel (benchmarks/fuselage.py): size, mass, parameter groups, damage.

References: the requested number of DoFs (within 5 %); the rigid-body mass u_xᵀ M u_x of
the assembled consistent mass matrix against a hand sum over the model's own elements
(skin and floor ρt·area + NSM, beams and rods (ρA + NSM)·length, CONM2 m) and against the
module's closed-form sum; every parameter group targets elements; a damaged barrel's K
and M equal the nominal's with the same relative changes applied as parameters.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks import fuselage as fz
from jaxfem.io import read_bdf_text
from updating import ParameterSet
from updating._parameters import parameterise

N_DOF = 3000


def _model(text):
    return jaxfem.build_model(read_bdf_text(text, name="barrel"))


@pytest.fixture(scope="module")
def barrel():
    return _model(fz.barrel_bdf(N_DOF))


def test_layout_sizes_meet_the_request():
    for n in (2000, 5000, 33000, 100000, 300000):
        layout = fz.barrel_layout(n)
        assert abs(layout.n_dof / n - 1.0) < 0.05, (n, layout.n_dof)
        a = layout.x[1] - layout.x[0]  # near-square skin elements
        arcs = np.diff(layout.theta[: layout.n_upper + 1]) * fz.RADIUS
        assert 0.9 < a / arcs.mean() < 1.1
    with pytest.raises(ValueError, match="below the smallest barrel"):
        fz.barrel_layout(1000)


def test_barrel_dofs_and_cards(barrel):
    layout = fz.barrel_layout(N_DOF)
    assert abs(barrel.n_dof / N_DOF - 1.0) < 0.05
    assert barrel.n_dof == layout.n_dof == 6 * len(barrel.node_ids)  # nothing constrained
    assert len(barrel.dofs.auto_spc) == 0
    nc, na, nf = layout.nc, layout.na, layout.nf
    assert len(barrel.quads.ids) == na * (nc + nf + 1)
    assert len(barrel.beams.ids) == na * fz.N_STRINGERS + len(layout.frames) * (nc + nf + 1)
    assert len(barrel.bushes.ids) == nc + nf and len(barrel.springs.ids) == 12
    assert len(barrel.rods.ids) == 2 * len(layout.frames)  # floor struts
    assert len(barrel.masses.ids) == len(layout.frames) * 4  # payload on the seat rails at the frames
    assert sorted(barrel.masses.ids.tolist()) == sorted(fz.payload_eids(layout))
    skin = np.isin(barrel.quads.pids, fz.SKIN_PIDS)
    r = np.hypot(barrel.xyz[barrel.quads.nodes[skin]][..., 1], barrel.xyz[barrel.quads.nodes[skin]][..., 2])
    np.testing.assert_allclose(r, fz.RADIUS, rtol=1e-12)


def test_rigid_body_mass_is_the_hand_sum(barrel):
    K, M = jaxfem.assemble(barrel)
    labels = barrel.dofs.labels
    xyz, mat = barrel.xyz, barrel.materials
    # hand sum over the model's elements
    q, sec = barrel.quads, barrel.shell_sections
    c = xyz[q.nodes]
    area = 0.5 * np.linalg.norm(np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 1]), axis=1)  # flat quads
    row = q.section
    rho = np.asarray(mat.rho)[np.asarray(sec.materials)[row, 0]]
    shells = float(np.sum(area * (rho * np.asarray(sec.t)[row] + np.asarray(sec.nsm)[row])))
    b, bs = barrel.beams, barrel.beam_sections
    length = np.linalg.norm(xyz[b.nodes[:, 1]] - xyz[b.nodes[:, 0]], axis=1)
    s = b.section
    beams = float(np.sum(length * (np.asarray(mat.rho)[bs.material[s]] * np.asarray(bs.A)[s] + np.asarray(bs.nsm)[s])))
    r, rs = barrel.rods, barrel.rod_sections
    length = np.linalg.norm(xyz[r.nodes[:, 1]] - xyz[r.nodes[:, 0]], axis=1)
    rods = float(np.sum(length * (np.asarray(mat.rho)[rs.material[r.section]] * np.asarray(rs.A)[r.section])))
    conm2 = float(np.sum(barrel.masses.m))
    hand = shells + beams + rods + conm2
    layout = fz.barrel_layout(N_DOF)
    parts = fz.masses(layout)
    np.testing.assert_allclose(conm2, parts["payload"], rtol=1e-12)
    np.testing.assert_allclose(conm2, fz.PAYLOAD * layout.length, rtol=1e-12)
    np.testing.assert_allclose(hand, sum(parts.values()), rtol=1e-12)
    for component in (1, 2, 3):  # a unit rigid translation: u_cᵀ M u_c = total mass
        u = jnp.asarray((labels[:, 1] == component).astype(np.float64))[:, None]
        np.testing.assert_allclose(float((u.T @ M.matmul(u))[0, 0]), hand, rtol=1e-10)
        assert float(jnp.max(jnp.abs(K.matmul(u)))) > 0.0  # suspended: K is not singular in translation
    assert 150.0 < hand < 400.0  # a 2.5 m barrel


@pytest.mark.parametrize("n", [10, 20])
def test_parameter_groups_target_elements(barrel, n, tmp_path):
    params = fz.parameter_groups(n)
    assert len(params) == n and len({p.name for p in params}) == n
    for p in params:
        assert len(barrel.element_ids(pids=p.pids)) > 0, p
    skin = [pid for p in params if p.name.startswith("skin") for pid in p.pids]
    assert sorted(skin) == sorted(fz.SKIN_PIDS)  # every skin bay in exactly one group
    parameterise(barrel, params)  # every target holds what its kind scales (e.g. NSM > 0)
    path = fz.write_parameters(tmp_path / "params.toml", n, {"tolerance": 1e-4, "passive_modes": [3, 7]})
    read = ParameterSet.from_toml(path)
    assert read.parameters == tuple(params)
    assert read.options.passive_modes == (3, 7) and read.options.tolerance == 1e-4
    with pytest.raises(ValueError, match="n must lie in"):
        fz.parameter_groups(21)


def test_damage_is_the_parameters_applied(barrel):
    damage = {"skin U3": -0.3, "skin L5": 0.2, "frames E": 0.1, "frames nsm": 0.5, "floor bending": -0.2,
              "floor nsm": 0.4, "floor beams stiffness": -0.25, "joint k": -0.5, "suspension k": 1.0}
    damaged = _model(fz.barrel_bdf(N_DOF, damage=damage))
    params = [p for p in fz.parameter_groups(20) if p.name in damage]
    base, par = parameterise(barrel, params)
    alpha = jnp.asarray([damage[p.name] for p in params])
    truth = par.apply(base, jnp.log1p(alpha))
    x = jax.random.normal(jax.random.key(1), (barrel.n_dof, 2))
    for a, b in zip(jaxfem.assemble(damaged), jaxfem.assemble(truth)):
        ax, bx = a.matmul(x), b.matmul(x)
        np.testing.assert_allclose(ax, bx, rtol=1e-9, atol=1e-9 * float(jnp.max(jnp.abs(bx))))
    with pytest.raises(ValueError, match="unknown group"):
        fz.barrel_bdf(N_DOF, damage={"skin X1": 0.1})
