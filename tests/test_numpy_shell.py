"""The independent NumPy CQUAD4 of the shell assembly benchmark (benchmarks/numpy_shell.py)
against jaxfem's element: stiffness and consistent mass of a distorted, warped quad in
a general orientation, isotropic PSHELL, to 1e-10 (relative, entries scaled by the
diagonal: |ΔA_ij| <= 1e-10·sqrt(|A_ii A_jj|), so that the small bending, drilling and
warping terms are checked too, not only the largest membrane entries)."""

from __future__ import annotations

import jax
import numpy as np
import pytest

import jaxfem
from benchmarks import numpy_shell
from jaxfem.io import read_bdf_text

E, NU, RHO, T = 7.0e10, 0.3, 2700.0, 0.012


def _quad_xyz() -> np.ndarray:
    """A distorted quad, corners ±h off its mean plane (warp 0.088), rotated and moved."""
    flat = np.array([[0.0, 0.0], [1.1, 0.15], [1.25, 0.95], [-0.1, 0.8]])
    h = 0.06
    local = np.column_stack([flat, [h, -h, h, -h]])
    rotation, _ = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))
    return local @ rotation.T + np.array([0.3, -0.2, 0.5])


def _model(xyz, k6rot, corners):
    grids = "\n".join(f"GRID,{i + 1},,{float(x)!r},{float(y)!r},{float(z)!r}" for i, (x, y, z) in enumerate(xyz))
    quad = "CQUAD4,1,1,1,2,3,4,0.,0."
    if corners is not None:
        quad += "\n,,,," + ",".join(repr(T * c) for c in corners)
    text = (f"PSHELL,1,1,{T!r},1,1.0,1,{5 / 6!r}\nMAT1,1,{E!r},,{NU!r},{RHO!r}\n"
            f"PARAM,K6ROT,{k6rot!r}\nPARAM,COUPMASS,1\n{grids}\n{quad}\n")
    with pytest.warns(UserWarning, match="warped quad"):
        return jaxfem.build_model(read_bdf_text(text))


def _scaled_error(got, want):
    d = np.sqrt(np.abs(np.diag(want)))
    d = np.maximum(d, 1e-12 * d.max())
    return float(np.max(np.abs(got - want) / np.outer(d, d)))


@pytest.mark.parametrize("k6rot, corners", [(100.0, None), (1.0e4, (0.9, 1.1, 1.2, 0.8))],
                         ids=["uniform", "corner-thickness"])
def test_numpy_cquad4_equals_jaxfem(k6rot, corners):
    model = _model(_quad_xyz(), k6rot, corners)
    lam = jaxfem.elements.laminates(model.shell_sections, model.materials, model.quads.section,
                                    model.quads.theta, model.quads.zoffs)
    lam = jax.tree.map(lambda a: a[0], lam)
    xyz = np.asarray(model.xyz)[model.quads.nodes[0]]
    ratio = np.asarray(model.quads.t_ratio[0])
    k_jax = np.asarray(jaxfem.elements.shell_stiffness(xyz, lam, ratio, model.k6rot))
    m_jax = np.asarray(jaxfem.elements.shell_mass(xyz, lam, ratio, model.lumped))

    section = numpy_shell.pshell(E, NU, T, RHO)
    k_np = numpy_shell.cquad4_stiffness(xyz, section, k6rot, ratio)
    m_np = numpy_shell.cquad4_mass(xyz, section, ratio)

    assert _scaled_error(k_np, k_jax) < 1e-10
    assert _scaled_error(m_np, m_jax) < 1e-10
    assert np.max(np.abs(k_np - k_jax)) < 1e-10 * np.max(np.abs(k_jax))
    assert np.max(np.abs(m_np - m_jax)) < 1e-10 * np.max(np.abs(m_jax))

    # The reference itself: six strain-free rigid-body motions of the warped quad, the
    # total mass I0·area in each translation.
    rigid = np.zeros((24, 6))
    for a, x in enumerate(xyz):
        rigid[6 * a:6 * a + 3, :3] = np.eye(3)
        rigid[6 * a:6 * a + 3, 3:] = -np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])
        rigid[6 * a + 3:6 * a + 6, 3:] = np.eye(3)
    assert np.max(np.abs(k_np @ rigid)) < 1e-8 * np.max(np.abs(k_np))
    xy, _ = numpy_shell.geometry(xyz)
    d1, d2 = xy[2] - xy[0], xy[3] - xy[1]
    area = 0.5 * abs(d1[0] * d2[1] - d1[1] * d2[0])
    if corners is None:
        mass = RHO * T * area
        np.testing.assert_allclose(rigid[:, :3].T @ m_np @ rigid[:, :3], mass * np.eye(3), rtol=0, atol=1e-12 * mass)
