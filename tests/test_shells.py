"""Shell elements against closed forms: patch tests, locking, plates, laminates, a cylinder.

References: Navier's solution of the simply supported plate, extended to Mindlin plates
(Reddy 2004, *Mechanics of Laminated Composite Plates and Shells*, §6.3.2: the 3 × 3
Fourier eigenproblem); Leissa (1973), J. Sound Vib. 31(3) 257–293, cantilever square
plate; Sanders' shell theory for a cylinder with shear-diaphragm ends (Leissa 1973,
*Vibration of Shells*, NASA SP-288, §2.3): exact Fourier modes sin(mπx/L)·cos(nφ).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.linalg as sl

import jaxfem
from benchmarks.shell_models import cylinder, plate
from jaxfem.io import read_bdf_text

E, NU, RHO = 7.0e10, 0.3, 2700.0
ALU = f"MAT1,1,7.+10,,0.3,2700."


def _pshell(t: float, mat: str = ALU, mid: int = 1) -> str:
    return f"PSHELL,1,{mid},{t!r},{mid},,{mid}\n{mat}"


def _build(text: str) -> jaxfem.Model:
    return jaxfem.build_model(read_bdf_text(text))


def _frequencies(model, n) -> np.ndarray:
    lam, _ = jaxfem.modes(model, n)
    return np.sqrt(np.abs(np.asarray(lam))) / (2 * np.pi)


def _static(model, prescribed: dict, loads: dict | None = None) -> dict:
    """Solve K u = f with prescribed (grid, component) values; returns (grid, component) → u."""
    K, _ = jaxfem.assemble(model)
    k = np.asarray(K.todense())
    labels = [tuple(int(v) for v in lab) for lab in model.dofs.labels]
    index = {lab: i for i, lab in enumerate(labels)}
    u, f = np.zeros(len(labels)), np.zeros(len(labels))
    held = np.zeros(len(labels), bool)
    for lab, v in prescribed.items():
        if lab in index:
            u[index[lab]], held[index[lab]] = v, True
    for lab, v in (loads or {}).items():
        f[index[lab]] += v
    free = ~held
    u[free] = np.linalg.solve(k[np.ix_(free, free)], f[free] - k[np.ix_(free, held)] @ u[held])
    return {lab: u[i] for lab, i in index.items()}


def _mindlin_navier(m, n, a, b, D, S, I0, I2):
    """Lowest ω/2π of mode (m, n) of a hard simply supported, specially orthotropic Mindlin
    plate: D = (D11, D12, D22, D66), S = (S_xz, S_yz), inertia I0, I2 (Reddy §6.3.2)."""
    p, q = m * np.pi / a, n * np.pi / b
    d11, d12, d22, d66 = D
    sx, sy = S
    k = np.array([
        [sx * p * p + sy * q * q, sx * p, sy * q],
        [sx * p, d11 * p * p + d66 * q * q + sx, (d12 + d66) * p * q],
        [sy * q, (d12 + d66) * p * q, d66 * p * p + d22 * q * q + sy],
    ])
    return np.sqrt(sl.eigh(k, np.diag([I0, I2, I2]), eigvals_only=True)[0]) / (2 * np.pi)


def _navier_set(a, b, D, S, I0, I2, count):
    return np.sort([_mindlin_navier(m, n, a, b, D, S, I0, I2) for m in range(1, 5) for n in range(1, 5)])[:count]


def _isotropic(h):
    d = E * h**3 / (12 * (1 - NU**2))
    g = E / (2 * (1 + NU))
    return (d, NU * d, d, (1 - NU) / 2 * d), (5 / 6 * g * h,) * 2, RHO * h, RHO * h**3 / 12


# ---------------------------------------------------------------------------------------
# Laminates: classical lamination theory by hand (Jones 1999, (2.85) and §4.2)


def _qbar(q11, q12, q22, q66, theta_deg):
    c, s = np.cos(np.radians(theta_deg)), np.sin(np.radians(theta_deg))
    return np.array([
        [q11 * c**4 + 2 * (q12 + 2 * q66) * s * s * c * c + q22 * s**4,
         (q11 + q22 - 4 * q66) * s * s * c * c + q12 * (s**4 + c**4),
         (q11 - q12 - 2 * q66) * s * c**3 + (q12 - q22 + 2 * q66) * s**3 * c],
        [0.0, q11 * s**4 + 2 * (q12 + 2 * q66) * s * s * c * c + q22 * c**4,
         (q11 - q12 - 2 * q66) * s**3 * c + (q12 - q22 + 2 * q66) * s * c**3],
        [0.0, 0.0, (q11 + q22 - 2 * q12 - 2 * q66) * s * s * c * c + q66 * (s**4 + c**4)],
    ])


def _hand_abd(e1, e2, nu12, g12, plies, t):
    nu21 = nu12 * e2 / e1
    d = 1 - nu12 * nu21
    q11, q22, q12, q66 = e1 / d, e2 / d, nu12 * e2 / d, g12
    z = -t * len(plies) / 2 + t * np.arange(len(plies) + 1)
    out = [np.zeros((3, 3)) for _ in range(3)]
    for k, angle in enumerate(plies):
        qb = _qbar(q11, q12, q22, q66, angle)
        qb = np.triu(qb) + np.triu(qb, 1).T
        for p in range(3):
            out[p] += qb * (z[k + 1] ** (p + 1) - z[k] ** (p + 1)) / (p + 1)
    return out


CFRP = "MAT8,2,1.4+11,1.+10,0.3,5.+9,5.+9,3.+9,1600."


@pytest.mark.parametrize("plies", [(0, 45, -45, 90), (0, 90)])
def test_laminate_abd_matches_hand_clt(plies):
    t = 0.000125
    fields = [f"2,{t!r},{float(a)!r}," for a in plies]
    rows = "\n".join("," + ",".join(fields[k:k + 2]) for k in range(0, len(fields), 2))
    text = (f"{CFRP}\nPCOMP,1,,,,,,,\n{rows}\n" "GRID,1,,0.,0.,0.\nGRID,2,,1.,0.,0.\nGRID,3,,1.,1.,0.\n"
            "GRID,4,,0.,1.,0.\nCQUAD4,1,1,1,2,3,4\n")
    model = _build(text)
    lam = jaxfem.elements.laminates(model.shell_sections, model.materials, model.quads.section,
                                    model.quads.theta, model.quads.zoffs)
    a, b, d = _hand_abd(1.4e11, 1.0e10, 0.3, 5.0e9, plies, t)
    for got, want in ((lam.A[0], a), (lam.B[0], b), (lam.D[0], d)):
        scale = np.abs(want).max()
        np.testing.assert_allclose(np.asarray(got), want, rtol=0, atol=1e-12 * scale)
    assert np.abs(b).max() > 1e-3 * np.abs(a).max() * t  # unsymmetric: B present
    assert lam.A.dtype == np.float64


# ---------------------------------------------------------------------------------------
# Patch tests and rigid-body modes


@pytest.mark.parametrize("triangles", [False, True])
def test_constant_membrane_strain_and_curvature_patch(triangles):
    """Boundary grids of a distorted mesh follow a linear in-plane field (or a quadratic
    deflection of constant curvature, rotations from it); the interior reproduces it exactly."""
    model = _build(plate(1.0, 0.6, 4, 4, _pshell(0.01), bc="free", distort=0.3, seed=3, triangles=triangles))
    xyz = np.asarray(model.xyz)
    edge = np.isclose(xyz[:, 0], 0) | np.isclose(xyz[:, 0], 1) | np.isclose(xyz[:, 1], 0) | np.isclose(xyz[:, 1], 0.6)
    ids = model.node_ids

    def membrane(x):  # u, v linear; θz = ω = ½(v,x − u,y)
        return {1: 1e-3 * (1 + 2 * x[0] + 3 * x[1]), 2: 1e-3 * (-1 + 0.5 * x[0] + 1.5 * x[1]), 6: 0.5e-3 * (0.5 - 3)}

    kx, ky, kxy = 1e-3, -2e-3, 1.5e-3

    def bending(x):  # w quadratic, θx = w,y, θy = −w,x (no transverse shear)
        w = 0.5 * (kx * x[0] ** 2 + ky * x[1] ** 2 + kxy * x[0] * x[1])
        return {3: w, 4: ky * x[1] + 0.5 * kxy * x[0], 5: -(kx * x[0] + 0.5 * kxy * x[1])}

    for field, other in ((membrane, (3, 4, 5)), (bending, (1, 2, 6))):
        held = {(int(g), c): v for g, x, e in zip(ids, xyz, edge) if e for c, v in field(x).items()}
        held.update({(int(g), c): 0.0 for g in ids for c in other})
        u = _static(model, held)
        err = max(abs(u[(int(g), c)] - v) for g, x in zip(ids, xyz) for c, v in field(x).items())
        assert err < 1e-8 * 1e-3  # round-off (1.4e-9 relative seen on the distorted triangles); a failed patch test is O(1)


@pytest.mark.parametrize("triangles", [False, True])
def test_free_warped_shell_has_exactly_six_rigid_body_modes(triangles):
    text = plate(1.0, 0.6, 3, 3, _pshell(0.01), bc="free", distort=0.2, triangles=triangles)
    lines = []
    for line in text.splitlines():  # a hyperbolic paraboloid: every quad warped
        if line.startswith("GRID"):
            f = line.split(",")
            x, y = float(f[3]), float(f[4])
            f[5] = repr(0.05 * (x - 0.5) * (y - 0.3))
            line = ",".join(f)
        lines.append(line)
    model = _build("\n".join(lines))
    K, _ = jaxfem.assemble(model)
    ev = np.linalg.eigvalsh(np.asarray(K.todense()))
    rel = ev / ev[-1]
    assert np.all(np.abs(rel[:6]) < 1e-13)
    assert rel[6] > 1e-9  # the first deformation mode (drilling) is far above round-off


# ---------------------------------------------------------------------------------------
# Locking


@pytest.mark.parametrize("nx, ny", [(8, 1), (8, 8)])
def test_thin_cantilever_strip_does_not_lock(nx, ny):
    """t/L = 1/1000, tip shear force: the tip deflection of Kirchhoff (ν = 0: a beam,
    PL³/3EI) within 1 %."""
    L, b, t = 1.0, 0.125, 0.001
    model = _build(plate(L, b, nx, ny, _pshell(t, "MAT1,1,7.+10,,0.,2700."), bc="cfff"))
    xyz = np.asarray(model.xyz)
    tip = [(int(g), x) for g, x in zip(model.node_ids, xyz) if np.isclose(x[0], L)]
    loads = {(g, 3): (0.5 if np.isclose(x[1], 0) or np.isclose(x[1], b) else 1.0) / ny for g, x in tip}
    u = _static(model, {}, loads)
    w = np.mean([u[(g, 3)] for g, _ in tip])
    assert w / (L**3 / (3 * E * b * t**3 / 12)) == pytest.approx(1.0, abs=0.01)


# ---------------------------------------------------------------------------------------
# Plates: Navier (isotropic, MAT8 orthotropic, PCOMP cross-ply), Mindlin thick, Leissa


def test_simply_supported_isotropic_plate_converges_to_navier_at_rate_two():
    a, b, h = 1.0, 0.8, 0.01
    ref = _navier_set(a, b, *_isotropic(h), 3)
    errors = []
    meshes = (6, 12, 24)
    for n in meshes:
        f = _frequencies(_build(plate(a, b, n, n, _pshell(h))), 3)
        errors.append(f / ref - 1)
    assert np.all(np.abs(errors[-1]) < 0.01)
    for mode in range(3):  # error ∝ h²
        assert np.polyfit(np.log(meshes), np.log([abs(e[mode]) for e in errors]), 1)[0] < -1.8


def test_simply_supported_triangle_plate_converges_to_navier():
    a, b, h = 1.0, 0.8, 0.01
    ref = _navier_set(a, b, *_isotropic(h), 2)
    e8, e16 = (np.abs(_frequencies(_build(plate(a, b, n, n, _pshell(h), triangles=True)), 2) / ref - 1)
               for n in (8, 16))
    assert np.all(e16 < 0.05) and np.all(e16 < 0.4 * e8)  # MITC3: stiffer than MITC4, same rate


def test_thick_mindlin_plate_matches_the_mindlin_closed_form():
    """h/a = 0.1, hard simple support: shear deformation and rotary inertia matter
    (Kirchhoff would be 3 % higher for the first mode)."""
    a, h = 1.0, 0.1
    ref = _navier_set(a, a, *_isotropic(h), 4)
    f = _frequencies(_build(plate(a, a, 24, 24, _pshell(h))), 4)
    np.testing.assert_allclose(f, ref, rtol=0.01)
    kirchhoff = np.pi / 2 * 2 / a**2 * np.sqrt(E * h**3 / (12 * (1 - NU**2)) / (RHO * h))
    assert kirchhoff / ref[0] > 1.02


def _orthotropic_d(h, plies=None):
    e1, e2, nu12, g12 = 1.4e11, 1.0e10, 0.3, 5.0e9
    if plies is None:
        nu21 = nu12 * e2 / e1
        d = 1 - nu12 * nu21
        q = np.array([e1 / d, nu12 * e2 / d, e2 / d, g12])
        return tuple(q * h**3 / 12)
    _, _, dm = _hand_abd(e1, e2, nu12, g12, plies, h / len(plies))
    assert np.abs(dm[0, 2]) < 1e-12 * dm[0, 0]
    return dm[0, 0], dm[0, 1], dm[1, 1], dm[2, 2]


@pytest.mark.parametrize("kind", ["MAT8 through PSHELL", "PCOMP cross-ply"])
def test_simply_supported_orthotropic_plate_matches_navier(kind):
    a, b, h = 1.0, 0.8, 0.008
    if kind == "PCOMP cross-ply":
        plies = (0, 90, 90, 0)
        cards = f"{CFRP}\nPCOMP,1,,,,,,,SYM\n,2,{h / 4!r},0.,,2,{h / 4!r},90.,\n"
        D = _orthotropic_d(h, plies)
        shear = 5 / 6 * h * np.array([0.5 * (5e9 + 3e9)] * 2)  # [0/90]s: half the plies each way
    else:
        cards = _pshell(h, CFRP, mid=2)
        D = _orthotropic_d(h)
        shear = 5 / 6 * h * np.array([5e9, 3e9])
    ref = _navier_set(a, b, D, shear, 1600.0 * h, 1600.0 * h**3 / 12, 3)
    f = _frequencies(_build(plate(a, b, 24, 24, cards)), 3)
    np.testing.assert_allclose(f, ref, rtol=0.01)


def test_cantilever_square_plate_matches_leissa():
    """Leissa (1973) Table 3 (C-F-F-F, a/b = 1, ν = 0.3): λ = ωa²√(ρh/D)."""
    a, h = 1.0, 0.001
    d = E * h**3 / (12 * (1 - NU**2))
    lam = 2 * np.pi * _frequencies(_build(plate(a, a, 16, 16, _pshell(h), bc="cfff")), 5) * a**2 * np.sqrt(RHO * h / d)
    np.testing.assert_allclose(lam, [3.4917, 8.5246, 21.429, 27.331, 31.111], rtol=0.01)


# ---------------------------------------------------------------------------------------
# Cylinder


def _sanders(m, n, R, L, h):
    """Lowest ω/2π of u = U cos λx cos nφ, v = V sin λx sin nφ, w = W sin λx cos nφ (λ = mπ/L)
    from Sanders' strain energy (Leissa 1973, (1.60))."""
    lam = m * np.pi / L
    c, d = E * h / (1 - NU**2), E * h**3 / (12 * (1 - NU**2))
    ex, et, g = np.array([-lam, 0, 0]), np.array([0, n / R, 1 / R]), np.array([-n / R, lam, 0])
    kx, kt = np.array([0, 0, lam**2]), np.array([0, n / R**2, n**2 / R**2])
    tau = np.array([n / (2 * R**2), 3 * lam / (2 * R), 2 * lam * n / R])
    o = np.outer

    def energy(a1, a2, shear):
        return o(a1, a1) + o(a2, a2) + NU * (o(a1, a2) + o(a2, a1)) + (1 - NU) / 2 * o(shear, shear)

    k = c * energy(ex, et, g) + d * energy(kx, kt, tau)
    return np.sqrt(sl.eigh(k, RHO * h * np.eye(3), eigvals_only=True)[0]) / (2 * np.pi)


@pytest.mark.slow
def test_cylinder_with_shear_diaphragm_ends_converges_to_sanders():
    R, L, h = 0.1, 0.5, 0.005
    ref = sorted(_sanders(m, n, R, L, h) for m in (1, 2) for n in range(1, 6))[:2]  # n = 2 and 3, m = 1
    errors = []
    for around, along in ((24, 10), (32, 14)):
        f = _frequencies(_build(cylinder(R, L, around, along, _pshell(h))), 5)
        assert f[0] < 1.0  # axial rigid-body translation
        np.testing.assert_allclose(f[1], f[2], rtol=1e-8)  # cos nφ and sin nφ pairs
        errors.append(np.array([f[1], f[3]]) / ref - 1)
    assert np.all(errors[1] > 0) and np.all(errors[1] < 0.5 * errors[0] + 1e-3)
    assert errors[1][0] < 0.015


# ---------------------------------------------------------------------------------------
# Formats


def _fixed(text: str, large: bool) -> str:
    lines = []
    for line in text.splitlines():
        name, *fields = line.split(",")
        if large:
            fields += [""] * (-len(fields) % 4)
            for k in range(0, len(fields), 4):
                head = f"{name}*" if k == 0 else "*"
                lines.append(f"{head:<8}" + "".join(f"{v:<16}" for v in fields[k:k + 4]))
        else:
            lines.append(f"{name:<8}" + "".join(f"{v:<8}" for v in fields))
    return "\n".join(lines)


def test_one_shell_model_in_three_formats_gives_identical_matrices():
    text = plate(1.0, 0.5, 4, 2, "PSHELL,1,1,0.01,1,,1\nMAT1,1,7.+10,,0.3,2700.", bc="cfff", triangles=True)
    models = [_build(t) for t in (text, _fixed(text, False), _fixed(text, True))]
    mats = [[np.asarray(a.todense()) for a in jaxfem.assemble(m)] for m in models]
    for other in mats[1:]:
        for a, b in zip(mats[0], other):
            np.testing.assert_array_equal(a, b)
    assert mats[0][0].dtype == np.float64 and np.abs(mats[0][0]).max() > 0


# ---------------------------------------------------------------------------------------
# Derivatives through eigh on a stiffened laminated panel


def _stiffened_panel() -> str:
    """A 0.4 × 0.3 m PCOMP [0/45/−45/90] panel (offset, unsymmetric: B ≠ 0) clamped at
    x = 0, with a MAT8 PSHELL blade stringer along y = 0.15."""
    text = plate(0.4, 0.3, 8, 6, f"{CFRP}\nPCOMP,1,,,,,,,\n,2,0.0005,0.,,2,0.0005,45.,\n,2,0.0005,-45.,,2,0.0005,90.,\n"
                 "PSHELL,2,2,0.002,2,,2", bc="cfff")
    lines = text.splitlines()
    row = [9 * 3 + i + 1 for i in range(9)]  # grids on y = 0.15
    for k in (1, 2):
        lines += [f"GRID,{1000 * k + i},,{0.05 * i!r},0.15,{0.015 * k!r}" for i in range(9)]
    lines += ["SPC1,1,123456,1000,2000"]
    eid = 500
    for k, (lower, upper) in enumerate(((row, [1000 + i for i in range(9)]),
                                        ([1000 + i for i in range(9)], [2000 + i for i in range(9)]))):
        for i in range(8):
            lines.append(f"CQUAD4,{eid},2,{lower[i]},{lower[i + 1]},{upper[i + 1]},{upper[i]}")
            eid += 1
    lines = [ln + ",,0.0002" if ln.startswith("CQUAD4") and ln.split(",")[2] == "1" else ln for ln in lines]
    return "\n".join(lines)


PANEL_PARAMETERS = ("E1", "G12", "G1Z", "t", "ply angle", "membrane", "transverse shear")


def _panel_model(model):
    def with_p(p):
        mat = model.materials
        sec = model.shell_sections
        row = int(np.flatnonzero(np.asarray(mat.ids) == 2)[0])
        unit = np.zeros(len(mat.ids))
        unit[row] = 1.0
        plate_row = (np.asarray(sec.ids) == 1).astype(np.float64)
        ply = np.zeros(sec.ply_theta.shape)
        ply[plate_row > 0, 1] = 1.0
        m = eqx.tree_at(lambda q: (q.materials.E, q.materials.G, q.materials.G1z), model,
                        (mat.E * (1 + p[0] * unit), mat.G * (1 + p[1] * unit), mat.G1z * (1 + p[2] * unit)))
        return eqx.tree_at(
            lambda q: (q.shell_sections.t, q.shell_sections.ply_theta, q.shell_sections.membrane,
                       q.shell_sections.shear), m,
            (sec.t * (1 + p[3] * (1 - plate_row)), sec.ply_theta + p[4] * ply, sec.membrane * (1 + p[5] * plate_row),
             sec.shear * (1 + p[6] * plate_row)))
    return with_p


@pytest.fixture(scope="module")
def panel():
    model = _build(_stiffened_panel())
    with_p = _panel_model(model)
    n_modes = 6

    def modes(p):
        return jaxfem.modes(with_p(p), n_modes)

    def dense(p):
        K, M = jaxfem.assemble(with_p(p))
        return K.todense(), M.todense()

    p0 = jnp.zeros(len(PANEL_PARAMETERS))
    lam, phi = modes(p0)
    jl, jp = jax.jacfwd(modes)(p0)
    return model, modes, dense, p0, lam, phi, jl, jp


def test_stiffened_panel_has_enough_dofs_and_distinct_modes(panel):
    model, *_, lam, phi, jl, jp = panel
    assert model.n_dof >= 300 and len(model.quads.ids) == 48 + 16
    assert np.all(np.diff(np.asarray(lam)) > 1e-3 * float(lam[-1]))
    assert lam.dtype == jl.dtype == jp.dtype == np.float64
    assert np.all(np.abs(np.asarray(jl)).max(axis=0) > 0)  # every parameter moves some frequency


def test_panel_derivatives_agree_with_nelson(panel):
    model, _, dense, p0, lam, phi, jl, jp = panel
    K, M = dense(p0)
    dK, dM = jax.jacfwd(dense)(p0)
    lscale, pscale = float(jnp.max(jnp.abs(jl))), float(jnp.max(jnp.abs(jp)))
    for i in range(len(PANEL_PARAMETERS)):
        for r in range(len(lam)):
            dl, dp = jaxfem.nelson(K, M, lam[r], phi[:, r], dK[:, :, i], dM[:, :, i])
            np.testing.assert_allclose(dl, jl[r, i], rtol=1e-8, atol=1e-8 * lscale, err_msg=PANEL_PARAMETERS[i])
            np.testing.assert_allclose(dp, jp[:, r, i], atol=1e-8 * pscale, err_msg=PANEL_PARAMETERS[i])


def test_panel_derivatives_agree_with_central_differences(panel):
    """Fourth-order central differences, (−f(2h) + 8f(h) − 8f(−h) + f(−2h)) / 12h."""
    _, modes, _, p0, lam, phi, jl, jp = panel
    h = 1e-3
    for i, name in enumerate(PANEL_PARAMETERS):
        (l2, p2), (l1, p1), (m1, q1), (m2, q2) = (modes(p0.at[i].set(s * h)) for s in (2, 1, -1, -2))
        fd_l = (-l2 + 8 * l1 - 8 * m1 + m2) / (12 * h)
        fd_p = (-p2 + 8 * p1 - 8 * q1 + q2) / (12 * h)
        np.testing.assert_allclose(fd_l, jl[:, i], rtol=1e-5, atol=1e-5 * float(jnp.max(jnp.abs(jl))), err_msg=name)
        np.testing.assert_allclose(fd_p, jp[:, :, i], atol=1e-5 * float(jnp.max(jnp.abs(jp))), err_msg=name)


@pytest.mark.parametrize("coupmass", [True, False])
@pytest.mark.parametrize("triangles", [False, True])
def test_rigid_translation_carries_the_whole_mass(coupmass, triangles):
    """uᵀMu for a unit translation = (ρt + NSM)·area, consistent or lumped, with an offset."""
    t, nsm = 0.004, 0.5
    text = plate(0.5, 0.3, 5, 3, f"PSHELL,1,1,{t!r},1,,1,,{nsm!r}\n{ALU}", bc="free", distort=0.2,
                 coupmass=coupmass, triangles=triangles)
    text = "\n".join(ln + ",,0.001" if ln.startswith(("CQUAD4", "CTRIA3")) else ln for ln in text.splitlines())
    model = _build(text)
    _, M = jaxfem.assemble(model)
    m = np.asarray(M.todense())
    for c in (1, 2, 3):
        u = (np.asarray(model.dofs.labels)[:, 1] == c).astype(float)
        assert u @ m @ u == pytest.approx((RHO * t + nsm) * 0.5 * 0.3, rel=1e-12)
