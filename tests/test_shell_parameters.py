"""Updating parameters on shell groups: which leaf each kind scales, private MAT8 copies,
laminate and frequency checks that could fail, gradients, refused targets, total mass.

Two models: a cantilever strip of three shell properties (PSHELL of a MAT1, an
unsymmetric PCOMP of MAT8 plies, a PSHELL of the same MAT8 on triangles) with a PBAR
along one edge sharing the MAT1; and a thin simply supported PSHELL plate, in-plane held.
Both with lumped mass (the Nastran default): with the consistent shell mass, whose rotary
inertia is ~(t/a)² of the translational, the Cholesky-standardised eigenproblem is so
ill-conditioned that the lowest eigenvalues carry relative errors of 1e-7 (strip) to 1e-6
(plate), measured as λ(1.3 K, M) / (1.3 λ(K, M)) − 1; lumped: 1e-10.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from jaxfem.elements import laminates
from jaxfem.io import read_bdf_text
from updating._parameters import Parameter, ParameterSet, parameterise
from updating.diagnosis._topology import total_mass

ALPHA = 0.3

MIXED_PROPERTIES = """
MAT1,1,7.0e10,,0.3,2700.0
MAT8,8,1.4e11,1.0e10,0.3,5.0e9,3.0e9,2.0e9,1600.0
PSHELL,1,1,0.002,1,,1,,0.3
PCOMP,2,,0.1,,,,,,
+,8,0.00025,0.0,,8,0.00025,45.0,
+,8,0.00025,-45.0,,8,0.00025,90.0
PSHELL,3,8,0.0015,8,,8
PBAR,10,1,1.0e-4,1.0e-9,2.0e-9,3.0e-9,0.05
"""
STRIP = (0.6, 0.2)  # m; pids 1, 2, 3 on thirds along x; pid 3 split into CTRIA3


def _grid_lines(a, b, nx, ny):
    gid = {(i, j): j * (nx + 1) + i + 1 for j in range(ny + 1) for i in range(nx + 1)}
    xs, ys = np.linspace(0.0, a, nx + 1), np.linspace(0.0, b, ny + 1)
    return gid, [f"GRID,{g},,{float(xs[i])!r},{float(ys[j])!r},0.0" for (i, j), g in gid.items()]


def _strip(nx=6, ny=2) -> str:
    gid, lines = _grid_lines(*STRIP, nx, ny)
    lines = [MIXED_PROPERTIES.strip()] + lines
    eid = 1
    for j in range(ny):
        for i in range(nx):
            pid = 1 + 3 * i // nx
            g = [gid[i, j], gid[i + 1, j], gid[i + 1, j + 1], gid[i, j + 1]]
            if pid == 3:
                lines += [f"CTRIA3,{eid},3,{g[0]},{g[1]},{g[2]}", f"CTRIA3,{eid + 1},3,{g[0]},{g[2]},{g[3]}"]
                eid += 2
            else:
                lines.append(f"CQUAD4,{eid},{pid},{g[0]},{g[1]},{g[2]},{g[3]}")
                eid += 1
    lines += [f"CBAR,{100 + i},10,{gid[i, 0]},{gid[i + 1, 0]},0.0,0.0,1.0" for i in range(nx)]
    lines += [f"SPC1,1,123456,{gid[0, j]}" for j in range(ny + 1)]
    return "\n".join(lines) + "\n"


def _ss_plate(a=1.0, b=0.8, t=0.001, n=4) -> str:
    """Thin PSHELL plate of MAT1 (blank MID3: shear rigid), hard simple support, in-plane
    DoFs and the drilling rotation held everywhere: only w, θx, θy are free."""
    gid, lines = _grid_lines(a, b, n, n)
    lines = ["MAT1,1,7.0e10,,0.3,2700.0", f"PSHELL,1,1,{t!r},1"] + lines
    eid = 1
    for j in range(n):
        for i in range(n):
            lines.append(f"CQUAD4,{eid},1,{gid[i, j]},{gid[i + 1, j]},{gid[i + 1, j + 1]},{gid[i, j + 1]}")
            eid += 1
    for (i, j), g in gid.items():
        held = set("126") | (set("34") if i in (0, n) else set()) | (set("35") if j in (0, n) else set())
        lines.append(f"SPC1,1,{''.join(sorted(held))},{g}")
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def strip():
    return jaxfem.build_model(read_bdf_text(_strip(), name="strip"))


@pytest.fixture(scope="module")
def plate():
    return jaxfem.build_model(read_bdf_text(_ss_plate(), name="plate"))


def _values(model) -> dict[str, np.ndarray]:
    """Every float leaf of the model by its path."""
    leaves = jax.tree_util.tree_leaves_with_path(jaxfem.partition(model)[0])
    return {jax.tree_util.keystr(path): np.asarray(v) for path, v in leaves}


def _apply(model, params, alpha):
    base, par = parameterise(model, params)
    return base, par.apply(base, jnp.log1p(jnp.asarray(alpha, dtype=jnp.float64)))


# (kind, pids, {leaf: index of the entries that change}); rows of the strip model:
# shell sections 1, 2, 3 → rows 0, 1, 2; materials MAT1 → 0, MAT8 → 1, private copies from 2.
LEAVES = [
    ("membrane", (2,), {".shell_sections.membrane": (1,)}),
    ("bending", (1, 3), {".shell_sections.bending": ([0, 2],)}),
    ("transverse_shear", (2,), {".shell_sections.shear": (1,)}),
    ("t", (1, 2), {".shell_sections.t": ([0, 1],), ".shell_sections.z0": ([0, 1],),
                   ".shell_sections.ply_t": (1,)}),
    ("nsm", (1, 2, 10), {".shell_sections.nsm": ([0, 1],), ".beam_sections.nsm": (0,)}),
    ("theta", (2,), {".shell_sections.ply_theta": (1,)}),
    ("E1", (2,), {".materials.E": (2,)}),
    ("E2", (2,), {".materials.E2": (2,)}),
    ("G12", (2,), {".materials.G": (2,)}),
    ("G1Z", (2,), {".materials.G1z": (2,)}),
    ("G2Z", (2,), {".materials.G2z": (2,)}),
    ("NU12", (3,), {".materials.nu": (2,)}),
    ("E", (1,), {".materials.E": (2,)}),
    ("G", (1,), {".materials.G": (2,)}),
    ("rho", (1, 2), {".materials.rho": ([2, 3],)}),
    ("rho", (2, 3), {".materials.rho": (1,)}),  # every user of the MAT8: no copy
    ("stiffness", (2,), {".quads.k_scale": ([2, 3, 6, 7],)}),  # eids 3, 4, 11, 12
    ("mass", (3,), {".trias.m_scale": (slice(None),)}),
]


@pytest.mark.parametrize(("kind", "pids", "expected"), LEAVES, ids=[f"{k}-{p}" for k, p, _ in LEAVES])
def test_each_kind_scales_exactly_its_leaf(strip, kind, pids, expected):
    base, after = _apply(strip, [Parameter("p", kind, pids=pids)], [ALPHA])
    before, after = _values(base), _values(after)
    assert before.keys() == after.keys()
    for path, index in expected.items():
        want = before[path].copy()
        want[index] = want[index] + ALPHA if kind == "theta" else want[index] * (1.0 + ALPHA)
        if kind == "theta":  # the plies only, not the padding of a shorter laminate
            want = np.where(np.asarray(base.shell_sections.ply_material) >= 0, want, before[path])
        np.testing.assert_allclose(after[path], want, rtol=1e-14, atol=1e-300, err_msg=path)
        assert not np.array_equal(after[path], before[path]), path
    for path in before.keys() - expected.keys():
        np.testing.assert_array_equal(after[path], before[path], err_msg=f"{kind} changed {path}")


def test_shared_materials_get_private_copies(strip):
    """A MAT8 shared by the target PCOMP and a PSHELL outside it (as MID1, MID2 and MID3),
    and a MAT1 shared by a target PSHELL and a PBAR: one copy each, used by every
    reference of the targets; the others keep the original rows, unchanged."""
    params = [Parameter("e1", "E1", pids=(2,)), Parameter("e", "E", pids=(1,))]
    base, after = _apply(strip, params, [ALPHA, -0.2])
    mats, sec = base.materials, base.shell_sections
    assert mats.ids.tolist() == [1, 8, -8, -1] and mats.kind.tolist() == [1, 8, 8, 1]
    assert sec.ply_material[1].tolist() == [2, 2, 2, 2]
    assert sec.materials[0].tolist() == [3, 3, 3, -1]  # PSHELL 1: all three roles on one copy
    assert sec.materials[2].tolist() == [1, 1, 1, -1] and base.beam_sections.material.tolist() == [0]
    for field in ("E", "G", "nu", "rho", "E2", "G1z", "G2z"):
        copy = np.asarray(getattr(mats, field))
        assert copy[2] == copy[1] and copy[3] == copy[0], field
    np.testing.assert_array_equal(after.materials.E[:2], strip.materials.E)  # PSHELL 3, PBAR: untouched
    np.testing.assert_allclose(after.materials.E[2:], strip.materials.E[::-1] * np.array([1.3, 0.8]), rtol=1e-15)
    # a second parameter on the same pid finds its material already private: no new copy
    twice, _ = parameterise(strip, [Parameter("e1", "E1", pids=(2,)), Parameter("e2", "E2", pids=(2,))])
    assert twice.materials.ids.tolist() == [1, 8, -8]


def test_t_and_theta_transform_the_laminate(strip):
    """PCOMP ``t``: plies and Z0 scaled together, so by CLT A·s, B·s², D·s³, S·s and the
    inertia I0 − NSM ∝ s, I2 ∝ s³. ``theta``: every ply turned by α is the element's
    material axis turned by α."""
    s, turn = 1.0 + ALPHA, 0.4
    rows, zero = np.array([1, 1]), jnp.zeros(2)

    def lam(model, theta=zero):
        return laminates(model.shell_sections, model.materials, rows, theta, zero)

    base, thick = _apply(strip, [Parameter("t", "t", pids=(2,))], [ALPHA])
    l0, l1 = lam(base), lam(thick)
    assert float(jnp.max(jnp.abs(l0.B))) > 0.01 * float(jnp.max(jnp.abs(l0.A))) * 0.001  # unsymmetric: B ≠ 0
    for name, power in (("A", 1), ("B", 2), ("D", 3), ("S", 1), ("I1", 2), ("I2", 3)):
        np.testing.assert_allclose(getattr(l1, name), getattr(l0, name) * s**power, rtol=1e-12, atol=1e-12,
                                   err_msg=name)
    nsm = float(base.shell_sections.nsm[1])
    np.testing.assert_allclose(l1.I0 - nsm, (l0.I0 - nsm) * s, rtol=1e-13)

    base, turned = _apply(strip, [Parameter("angle", "theta", pids=(2,))], [turn])
    l1, l2 = lam(turned), lam(base, zero + turn)
    for name in ("A", "B", "D", "S"):
        np.testing.assert_allclose(getattr(l1, name), getattr(l2, name), rtol=1e-12,
                                   atol=1e-12 * float(jnp.max(jnp.abs(getattr(l2, name)))), err_msg=name)


def test_bending_and_thickness_scale_plate_frequencies(plate):
    """Simply supported thin plate, in-plane held: K is bending (and the shear penalty of a
    shear-rigid section, ∝ D), so ``bending`` 1 + α scales every ω by √(1 + α); ``t`` by s
    gives D·s³ and (lumped, no rotary inertia) mass·s, so ω·s."""
    lam0, _ = jaxfem.modes(plate, 4)
    f0 = np.sqrt(np.asarray(lam0))
    # lowest mode against Kirchhoff: ω = π²(1/a² + 1/b²)√(D/ρt) (4 × 4, coarse)
    d = 7.0e10 * 0.001**3 / (12 * (1 - 0.3**2))
    assert f0[0] == pytest.approx(np.pi**2 * (1 + 1 / 0.8**2) * np.sqrt(d / (2700.0 * 0.001)), rel=0.1)
    _, stiffer = _apply(plate, [Parameter("b", "bending", pids=(1,))], [ALPHA])
    np.testing.assert_allclose(np.sqrt(np.asarray(jaxfem.modes(stiffer, 4)[0])), f0 * np.sqrt(1 + ALPHA), rtol=1e-9)
    _, thicker = _apply(plate, [Parameter("t", "t", pids=(1,))], [0.2])
    np.testing.assert_allclose(np.sqrt(np.asarray(jaxfem.modes(thicker, 4)[0])), f0 * 1.2, rtol=1e-9)


@pytest.mark.parametrize("pid", [1, 2, 3])
def test_stiffness_equals_membrane_bending_shear(strip, pid):
    """The correction factor of eq. 3.1 on a shell group is the three section factors at
    the same α (B scales by √(membrane·bending), the drilling penalty by tr A): exact,
    even for the unsymmetric PCOMP (B ≠ 0)."""
    _, whole = _apply(strip, [Parameter("k", "stiffness", pids=(pid,))], [ALPHA])
    _, parts = _apply(strip, [Parameter(k, k, pids=(pid,)) for k in ("membrane", "bending", "transverse_shear")],
                      [ALPHA] * 3)
    k1, k2 = (jaxfem.assemble(m)[0].todense() for m in (whole, parts))
    np.testing.assert_allclose(k2, k1, rtol=0, atol=1e-12 * float(jnp.max(jnp.abs(k1))))
    f1, f2 = (np.asarray(jaxfem.modes(m, 6)[0]) for m in (whole, parts))
    np.testing.assert_allclose(f2, f1, rtol=1e-8)
    assert not np.allclose(f1, np.asarray(jaxfem.modes(strip, 6)[0]), rtol=1e-4)


ALL_KINDS = [("membrane", (2,)), ("bending", (1,)), ("transverse_shear", (2,)), ("t", (3,)), ("nsm", (1,)),
             ("theta", (2,)), ("E1", (2,)), ("E2", (2,)), ("G12", (2,)), ("G1Z", (2,)), ("G2Z", (2,)),
             ("NU12", (3,)), ("E", (1,)), ("G", (1,)), ("rho", (3,)), ("stiffness", (1,)), ("mass", (2,))]


def test_gradient_of_a_frequency_in_every_kind(strip):
    """d λ₁ / d θ finite and non-zero for every kind, and equal to a central difference
    along a direction mixing all of them."""
    params = [Parameter(f"{k}{i}", k, pids=p) for i, (k, p) in enumerate(ALL_KINDS)]
    base, par = parameterise(strip, params)

    @jax.jit
    def lam1(theta):
        return jaxfem.modes(par.apply(base, theta), 2)[0][0]

    theta = jnp.full(len(params), 0.05)
    grad = np.asarray(jax.jit(jax.grad(lam1))(theta))
    assert np.all(np.isfinite(grad)) and np.all(grad != 0.0), dict(zip(par.parameters, grad))
    v = jnp.asarray(np.random.default_rng(0).uniform(-1, 1, len(params)))
    h = 1e-4
    fd = (float(lam1(theta + h * v)) - float(lam1(theta - h * v))) / (2 * h)
    assert fd == pytest.approx(float(grad @ np.asarray(v)), rel=1e-5)


@pytest.mark.parametrize(("kind", "pids", "message"), [
    ("E1", (1,), r"'bad': pids \[1\] use no MAT8 material"),
    ("NU12", (10,), r"pids \[10\] use no MAT8"),
    ("E", (2,), r"pids \[2\] use no MAT1 material"),
    ("theta", (1, 2), r"pids \[1\] are PSHELL"),
    ("membrane", (10,), r"pids \[10\] are not PSHELL or PCOMP"),
    ("nsm", (3,), "NSM is 0 on every target"),
    ("G1Z", (1,), r"use no MAT8"),
])
def test_targets_without_the_value_are_refused(strip, kind, pids, message):
    with pytest.raises(ValueError, match=message):
        parameterise(strip, [Parameter("bad", kind, pids=pids)])


def test_shear_rigid_targets_are_refused(plate):
    with pytest.raises(ValueError, match=r"'s': pids \[1\] are shear rigid"):
        parameterise(plate, [Parameter("s", "transverse_shear", pids=(1,))])


def test_shell_kinds_need_pids():
    """Section and material kinds need pids; a shell part factor or NSM may also name shell
    eids (the elements' own values, a patch effect), refused on elements that are not shells."""
    for kind in ("t", "theta", "E1", "G2Z"):
        with pytest.raises(ValueError, match="needs pids"):
            Parameter("x", kind, eids=(1,))
    for kind in ("membrane", "bending", "transverse_shear", "nsm"):
        assert Parameter("x", kind, eids=(1,)).eids == (1,)
    parsed = ParameterSet.from_dict({"parameter": [{"name": "ply", "kind": "theta", "pids": [2]}]}, "t.toml")
    assert parsed.parameters[0].kind == "theta"


def test_shell_eid_kinds_refuse_other_elements(strip):
    with pytest.raises(ValueError, match=r"eids \[100\] are not shells"):
        parameterise(strip, ParameterSet((Parameter("x", "transverse_shear", eids=(100,)),)))
    with pytest.raises(ValueError, match="own NSM is 0"):
        parameterise(strip, ParameterSet((Parameter("x", "nsm", eids=tuple(strip.quads.ids[:2].tolist())),)))


def test_total_mass_includes_shells(strip):
    """(ρt + NSM) × area per shell property, (ρA + NSM) × length of the bar; factors follow."""
    area = STRIP[0] / 3 * STRIP[1]
    shells = area * ((2700.0 * 0.002 + 0.3) + (1600.0 * 0.001 + 0.1) + 1600.0 * 0.0015)
    bar = (2700.0 * 1e-4 + 0.05) * STRIP[0]
    assert total_mass(strip) == pytest.approx(shells + bar, rel=1e-12)
    _, heavier = _apply(strip, [Parameter("r", "rho", pids=(3,)), Parameter("m", "mass", pids=(1,))], [0.5, 0.25])
    extra = area * (0.5 * 1600.0 * 0.0015 + 0.25 * (2700.0 * 0.002 + 0.3))
    assert total_mass(heavier) == pytest.approx(shells + bar + extra, rel=1e-12)
