"""Nastran's beam-section library (PBARL/PBEAML) against independent formulas, and its use.

Every TYPE's A, I1, I2, I12 against Green's theorem on the outline of the drawn shape; J
against the thin-walled (open: Σ l t³/3; closed: Bredt, two cells by a linear solve) and
exact formulas; shear factors against wall areas; gradients against central differences.
Then in models: a PBARL I cantilever against Euler–Bernoulli, an L section against the
equivalent PBAR in principal axes, tapered PBEAM/PBEAML, and the ``dim`` parameter.
"""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from jaxfem import _section_library as lib
from jaxfem.io import Card, read_bdf_text
from updating import Parameter, parameterise
from updating._parameters import identical_columns

# One section per TYPE: dimensions [m] (all different, so that a swapped DIM shows).
DIMS = {
    "ROD": (0.02,), "TUBE": (0.03, 0.025), "TUBE2": (0.03, 0.004), "BAR": (0.04, 0.06),
    "BOX": (0.1, 0.12, 0.006, 0.005), "BOX1": (0.1, 0.12, 0.006, 0.008, 0.005, 0.003),
    "I": (0.2, 0.1, 0.08, 0.006, 0.01, 0.008), "I1": (0.09, 0.007, 0.16, 0.18), "T": (0.1, 0.12, 0.01, 0.006),
    "T1": (0.1, 0.09, 0.008, 0.005), "T2": (0.1, 0.12, 0.01, 0.006), "L": (0.08, 0.12, 0.006, 0.008),
    "CHAN": (0.07, 0.15, 0.006, 0.009), "CHAN1": (0.06, 0.007, 0.13, 0.15), "CHAN2": (0.007, 0.009, 0.08, 0.12),
    "H": (0.08, 0.016, 0.12, 0.006), "Z": (0.05, 0.006, 0.13, 0.15), "HAT": (0.06, 0.004, 0.08, 0.03),
    "HAT1": (0.16, 0.07, 0.08, 0.003, 0.005), "CROSS": (0.09, 0.01, 0.12, 0.008), "HEXA": (0.02, 0.1, 0.07),
    "DBOX": (0.3, 0.12, 0.14, 0.006, 0.008, 0.005, 0.007, 0.009, 0.004, 0.006),
}


def _rect(z0, z1, y0, y1):
    return [(z0, y0), (z1, y0), (z1, y1), (z0, y1)]


def _outline(name, d):
    """Rings ``(points (z, y), +1 | −1 for a hole)`` of the shape of the QRG figure."""
    if name in ("BOX", "BOX1"):
        b, h, t3, t4, t5, t6 = d if name == "BOX1" else (d[0], d[1], d[2], d[2], d[3], d[3])
        return [(_rect(0, b, 0, h), 1), (_rect(t5, b - t6, t4, h - t3), -1)]
    if name in ("ROD", "TUBE", "TUBE2"):  # 16384-gons
        t = np.linspace(0.0, 2 * np.pi, 1 << 14, endpoint=False)
        ro, ri = (d[0], 0.0) if name == "ROD" else (d[0], d[1] if name == "TUBE" else d[0] - d[1])
        return [(np.c_[r * np.cos(t), r * np.sin(t)], sign) for r, sign in ((ro, 1), (ri, -1)) if r]
    if name == "HAT1":  # the plate and the hat on it, round the cell under the crown
        w, h, wc, t, tp = d
        e, g = wc / 2, w / 2
        return [([(-g, 0), (g, 0), (g, tp + t), (e, tp + t), (e, h), (-e, h), (-e, tp + t), (-g, tp + t)], 1),
                (_rect(t - e, e - t, tp, h - t), -1)]
    if name == "DBOX":
        w, h, c, t4, t5, t6, t7, t8, t9, t10 = d
        return [(_rect(0, w, 0, h), 1), (_rect(t4, c - t5 / 2, t8, h - t7), -1),
                (_rect(c + t5 / 2, w - t6, t10, h - t9), -1)]
    return [(points, 1) for points in _solid(name, d)]


def _solid(name, d):
    """Outlines of the shapes without holes (a T is its own polygon, not two rectangles)."""
    if name == "BAR":
        return [_rect(0, d[0], 0, d[1])]
    if name in ("I", "I1"):
        h, a, b, tw, ta, tb = d if name == "I" else (d[3], d[0] + d[1], d[0] + d[1], d[1], (d[3] - d[2]) / 2,
                                                     (d[3] - d[2]) / 2)
        return [[(-a / 2, 0), (a / 2, 0), (a / 2, ta), (tw / 2, ta), (tw / 2, h - tb), (b / 2, h - tb), (b / 2, h),
                 (-b / 2, h), (-b / 2, h - tb), (-tw / 2, h - tb), (-tw / 2, ta), (-a / 2, ta)]]
    if name in ("CHAN", "CHAN1"):
        b, h, tw, tf = d if name == "CHAN" else (d[0] + d[1], d[3], d[1], (d[3] - d[2]) / 2)
        return [[(0, 0), (b, 0), (b, tf), (tw, tf), (tw, h - tf), (b, h - tf), (b, h), (0, h)]]
    if name == "CHAN2":
        tl, tb, h, b = d
        return [[(0, 0), (b, 0), (b, h), (b - tl, h), (b - tl, tb), (tl, tb), (tl, h), (0, h)]]
    if name in ("T", "T2"):
        b, h, tf, tw = d
        return [[(-tw / 2, 0), (tw / 2, 0), (tw / 2, h - tf), (b / 2, h - tf), (b / 2, h), (-b / 2, h),
                 (-b / 2, h - tf), (-tw / 2, h - tf)]]
    if name == "T1":
        h, f, tv, th = d
        return [[(0, -h / 2), (tv, -h / 2), (tv, h / 2), (0, h / 2), (0, th / 2), (-f, th / 2), (-f, -th / 2),
                 (0, -th / 2)]]
    if name == "L":
        b, h, th, tv = d
        return [[(0, 0), (b, 0), (b, th), (tv, th), (tv, h), (0, h)]]
    if name == "Z":
        f, tw, hw, h = d
        tf = (h - hw) / 2
        return [[(tw / 2, h / 2), (-tw / 2 - f, h / 2), (-tw / 2 - f, h / 2 - tf), (-tw / 2, h / 2 - tf),
                 (-tw / 2, -h / 2), (tw / 2 + f, -h / 2), (tw / 2 + f, tf - h / 2), (tw / 2, tf - h / 2)]]
    return _solid_more(name, d)


def _solid_more(name, d):
    if name == "H":
        w, t2, h, tw = d
        e, f = w / 2, w / 2 + t2 / 2
        return [[(-f, -h / 2), (-e, -h / 2), (-e, -tw / 2), (e, -tw / 2), (e, -h / 2), (f, -h / 2), (f, h / 2),
                 (e, h / 2), (e, tw / 2), (-e, tw / 2), (-e, h / 2), (-f, h / 2)]]
    if name == "CROSS":
        w, tv, h, ta = d
        e, f = tv / 2, tv / 2 + w / 2
        return [[(-e, -h / 2), (e, -h / 2), (e, -ta / 2), (f, -ta / 2), (f, ta / 2), (e, ta / 2), (e, h / 2),
                 (-e, h / 2), (-e, ta / 2), (-f, ta / 2), (-f, -ta / 2), (-e, -ta / 2)]]
    if name == "HEXA":
        tip, w, h = d
        return [[(tip, 0), (w - tip, 0), (w, h / 2), (w - tip, h), (tip, h), (0, h / 2)]]
    if name == "HAT":
        h, t, w, f = d
        e, g = w / 2, w / 2 + f
        return [[(-g, 0), (-e + t, 0), (-e + t, h - t), (e - t, h - t), (e - t, 0), (g, 0), (g, t), (e, t),
                 (e, h), (-e, h), (-e, t), (-g, t)]]
    raise KeyError(name)


def _green(rings):
    """A, I1 = ∫(y − ȳ)², I2 = ∫(z − z̄)², I12 = ∫(y − ȳ)(z − z̄) by Green's theorem on polygons."""
    total = np.zeros(6)
    for points, sign in rings:
        z, y = np.asarray(points, dtype=np.float64).T
        z1, y1 = np.roll(z, -1), np.roll(y, -1)
        c = z * y1 - z1 * y
        ring = np.array([c.sum() / 2, ((z + z1) * c).sum() / 6, ((y + y1) * c).sum() / 6,
                         ((y * y + y * y1 + y1 * y1) * c).sum() / 12, ((z * z + z * z1 + z1 * z1) * c).sum() / 12,
                         ((z * y1 + 2 * z * y + 2 * z1 * y1 + z1 * y) * c).sum() / 24])
        total += sign * np.sign(ring[0]) * ring
    a, sz, sy, iyy, izz, iyz = total
    return a, iyy - sy**2 / a, izz - sz**2 / a, iyz - sy * sz / a


def test_tables_agree_and_hold_every_type():
    assert set(lib.DIMENSIONS) == set(lib.SECTIONS) == set(DIMS) and lib.TYPES == tuple(lib.DIMENSIONS)
    assert all(len(DIMS[name]) == n for name, n in lib.DIMENSIONS.items())
    assert all(lib.LIMITS[name][2](DIMS[name]) for name in lib.LIMITS)


@pytest.mark.parametrize("name", list(DIMS))
def test_area_and_inertia_against_greens_theorem(name):
    values = lib.section(name, DIMS[name])
    expected = _green(_outline(name, DIMS[name]))
    rtol = 1e-6 if name in ("ROD", "TUBE", "TUBE2") else 1e-12  # a 16384-gon for the circles
    np.testing.assert_allclose(values[:3], expected[:3], rtol=rtol)
    np.testing.assert_allclose(values[3], expected[3], atol=1e-12 * (expected[1] + expected[2]))
    assert all(isinstance(v, float) for v in values)  # floats in, floats out (float64)


def _open(*walls):
    """Thin-walled open section: Σ l t³ / 3 over the walls (mid-line length l, thickness t)."""
    return sum(length * t**3 for length, t in walls) / 3


def _bredt(area, *walls):
    """One closed cell: 4 Aₘ² / ∮ ds/t."""
    return 4 * area**2 / sum(length / t for length, t in walls)


def _two_cells(a1, a2, walls1, walls2, shared):
    """Two cells sharing a wall (Bredt–Batho): [[∮₁, −s], [−s, ∮₂]] q = 2 A (Gθ = 1), J = 2 A·q."""
    s = shared[0] / shared[1]
    matrix = np.array([[sum(l / t for l, t in walls1) + s, -s], [-s, sum(l / t for l, t in walls2) + s]])
    q = np.linalg.solve(matrix, 2 * np.array([a1, a2]))
    return 2 * (a1 * q[0] + a2 * q[1])


def _expected_j_and_web_areas(name, d):
    """(J, area of the walls along y, along z) of the thin-walled rules (walls clear of the
    walls they meet; closed sections at full length)."""
    if name == "I":
        h, a, b, tw, ta, tb = d
        return _open((a, ta), (b, tb), (h - ta / 2 - tb / 2, tw)), tw * (h - ta - tb), (a - tw) * ta + (b - tw) * tb
    if name in ("I1", "Z"):
        f, tw, hw, h = d
        tf = (h - hw) / 2
        flange = f + tw if name == "I1" else f + tw / 2
        return _open((flange, tf), (flange, tf), (h - tf, tw)), tw * hw, 2 * f * tf
    if name in ("CHAN", "CHAN1"):
        b, h, tw, tf = d if name == "CHAN" else (d[0] + d[1], d[3], d[1], (d[3] - d[2]) / 2)
        return _open((b - tw / 2, tf), (b - tw / 2, tf), (h - tf, tw)), tw * (h - 2 * tf), 2 * (b - tw) * tf
    if name == "CHAN2":
        tl, tb, h, b = d
        return _open((b - tl, tb), (h - tb / 2, tl), (h - tb / 2, tl)), 2 * tl * (h - tb), (b - 2 * tl) * tb
    if name in ("T", "T2"):
        b, h, tf, tw = d
        return _open((b, tf), (h - tf / 2, tw)), tw * (h - tf), (b - tw) * tf
    if name == "T1":
        h, f, tv, th = d
        return _open((h, tv), (f + tv / 2, th)), (h - th) * tv, f * th
    if name == "L":
        b, h, th, tv = d
        return _open((b - tv / 2, th), (h - th / 2, tv)), (h - th) * tv, (b - tv) * th
    if name == "H":
        w, t2, h, tw = d
        return _open((h, t2 / 2), (h, t2 / 2), (w + t2 / 2, tw)), t2 * h, w * tw
    if name == "CROSS":
        w, tv, h, ta = d
        return _open((h, tv), (w + tv, ta)), tv * (h - ta), w * ta
    if name == "HAT":
        h, t, w, f = d
        return _open((w - t, t), (h - t, t), (h - t, t), (f + t / 2, t), (f + t / 2, t)), 2 * t * (h - 2 * t), \
            (w - 2 * t + 2 * f) * t
    return _closed(name, d)


def _closed(name, d):
    if name in ("BOX", "BOX1"):
        b, h, t3, t4, t5, t6 = d if name == "BOX1" else (d[0], d[1], d[2], d[2], d[3], d[3])
        bm, hm = b - (t5 + t6) / 2, h - (t3 + t4) / 2
        return _bredt(bm * hm, (bm, t3), (bm, t4), (hm, t5), (hm, t6)), (t5 + t6) * h, (t3 + t4) * b
    if name == "HAT1":
        w, h, wc, t, tp = d
        bm, hm, f = wc - t, h - (t + tp) / 2, (w - wc) / 2
        cell = _bredt(bm * hm, (bm, t), (bm, tp), (hm, t), (hm, t))
        return cell + _open((f, t + tp), (f, t + tp)), 2 * t * (h - tp - t), w * tp + 2 * f * t + (wc - 2 * t) * t
    w, h, c, t4, t5, t6, t7, t8, t9, t10 = d  # DBOX
    b1, h1, b2, h2 = c - t4 / 2, h - (t7 + t8) / 2, w - c - t6 / 2, h - (t9 + t10) / 2
    j = _two_cells(b1 * h1, b2 * h2, [(b1, t7), (b1, t8), (h1, t4)], [(b2, t9), (b2, t10), (h2, t6)],
                   ((h1 + h2) / 2, t5))
    return j, (t4 + t5 + t6) * h, (t7 + t8) * c + (t9 + t10) * (w - c)


THIN_WALLED = [n for n in DIMS if n not in ("ROD", "TUBE", "TUBE2", "BAR", "HEXA")]


@pytest.mark.parametrize("name", THIN_WALLED)
def test_torsion_and_shear_factors_of_the_thin_walled_rules(name):
    area, *_, j, k1, k2 = lib.section(name, DIMS[name])
    expected_j, along_y, along_z = _expected_j_and_web_areas(name, DIMS[name])
    np.testing.assert_allclose([j, k1, k2], [expected_j, along_y / area, along_z / area], rtol=1e-12)


def test_torsion_and_shear_factors_of_the_solid_sections():
    for name in ("ROD", "TUBE", "TUBE2"):  # polar moment, from the outline
        _, i1, i2, _ = _green(_outline(name, DIMS[name]))
        np.testing.assert_allclose(lib.section(name, DIMS[name])[4], i1 + i2, rtol=1e-6)
    assert [lib.section(n, DIMS[n])[5:] for n in ("ROD", "TUBE", "BAR", "HEXA")] == [
        (0.9, 0.9), (0.5, 0.5), (5 / 6, 5 / 6), (5 / 6, 5 / 6)]
    b, h = DIMS["BAR"]  # Roark against the exact series (Timoshenko & Goodier §109)
    n = np.arange(1, 200, 2)
    exact = h * b**3 / 3 * (1 - 192 / np.pi**5 * b / h * np.sum(np.tanh(n * np.pi * h / (2 * b)) / n**5))
    np.testing.assert_allclose(lib.section("BAR", (b, h))[4], exact, rtol=2e-3)
    a, i1, i2, _ = _green(_outline("HEXA", DIMS["HEXA"]))  # Saint-Venant's approximation
    np.testing.assert_allclose(lib.section("HEXA", DIMS["HEXA"])[4], a**4 / (4 * np.pi**2 * (i1 + i2)), rtol=1e-12)


def test_two_cells_alike_twist_as_one():
    """Symmetric DBOX: equal shear flows, the middle wall idle: the outer box's Bredt."""
    w, h, t, s = 0.3, 0.12, 0.006, 0.005
    j = lib.section("DBOX", (w, h, w / 2, s, 0.004, s, t, t, t, t))[4]
    np.testing.assert_allclose(j, _bredt((w - s) * (h - t), (w - s, t), (w - s, t), (h - t, s), (h - t, s)),
                               rtol=1e-12)


@pytest.mark.parametrize("name", list(DIMS))
def test_jit_and_gradient_against_central_differences(name):
    d0 = np.asarray(DIMS[name])
    values = jax.jit(lambda d: jnp.stack(lib.section(name, d)))
    jac = np.asarray(jax.jit(jax.jacfwd(lambda d: jnp.stack(lib.section(name, d))))(jnp.asarray(d0)))
    assert values(jnp.asarray(d0)).dtype == jac.dtype == np.float64
    np.testing.assert_allclose(values(jnp.asarray(d0)), lib.section(name, DIMS[name]), rtol=1e-13, atol=1e-30)
    for k in range(len(d0)):
        h = 1e-6 * d0[k]
        up, down = d0.copy(), d0.copy()
        up[k] += h
        down[k] -= h
        fd = (np.asarray(lib.section(name, tuple(up))) - np.asarray(lib.section(name, tuple(down)))) / (2 * h)
        scale = np.abs(jac).max(axis=1) + 1e-300
        np.testing.assert_allclose(jac[:, k] / scale, fd / scale, atol=1e-6, err_msg=f"{name} DIM{k + 1}")


def test_principal_axes_of_the_inertia_tensor():
    """θ turns y, z into the eigenvectors of [[I1, I12], [I12, I2]], |θ| ≤ π/4."""
    for name in ("L", "Z", "BOX1", "DBOX"):
        _, i1, i2, i12, *_ = lib.section(name, DIMS[name])
        theta, p1, p2, k1, k2 = (float(v) for v in lib.principal(i1, i2, i12, 0.3, 0.7))
        y_axis = np.array([np.cos(theta), np.sin(theta)])
        tensor = np.array([[i1, i12], [i12, i2]])
        np.testing.assert_allclose(tensor @ y_axis, p1 * y_axis, rtol=1e-12, atol=1e-12 * p1)
        np.testing.assert_allclose(sorted([p1, p2]), np.linalg.eigvalsh(tensor), rtol=1e-12)
        np.testing.assert_allclose(k1 + k2, 1.0, rtol=1e-14)
        assert abs(theta) <= np.pi / 4 and abs(i12) > 1e-3 * (i1 + i2)
    assert [float(v) for v in lib.principal(2.0, 2.0, 0.0, 0.5, 0.5)] == [0.0, 2.0, 2.0, 0.5, 0.5]
    grad = jax.grad(lambda i: lib.principal(i, i, 0.0, 1.0, 1.0)[1])(3.0)  # guarded at I1 = I2, I12 = 0
    assert np.isfinite(grad)


E, NU, RHO = 2.1e11, 0.3, 7850.0
I_DIMS = (0.1, 0.06, 0.06, 0.004, 0.006, 0.006)
L_DIMS = (0.08, 0.12, 0.006, 0.008)


def _fields(values) -> str:
    return ",".join(f"{v:.15E}" if isinstance(v, float) else str(v) for v in values)


def _cantilever(length: float, n: int, pids=(1,), spring: float = 0.0, beam: str = "CBAR", more: str = "") -> str:
    """Clamped at x = 0, ``n`` elements along x (the first half on pids[0], the rest on
    pids[-1]), v = basic y; a grounded spring along y at the tip; ``more`` bulk data."""
    lines = ["BEGIN BULK", "PARAM,COUPMASS,1", f"MAT1,1,{_fields([E])},,{NU},{RHO}", more.strip()]
    lines += [f"GRID,{i + 1},,{_fields([length * i / n])},0.,0." for i in range(n + 1)]
    lines += [f"{beam},{i + 1},{pids[0] if i < n // 2 else pids[-1]},{i + 1},{i + 2},0.,1.,0." for i in range(n)]
    lines += [f"CELAS2,{n + 1},{_fields([spring])},{n + 1},2"] if spring else []
    return "\n".join(lines + ["SPC1,1,123456,1", "ENDDATA"]) + "\n"


def _library_card(name: str, pid: int, kind: str, stations, xxb=(0.0, 1.0), nsm=(0.0, 0.0)) -> Card:
    """A PBARL (one station of dimensions) or PBEAML as the bulk-data reader gives it."""
    values = {"PID": pid, "MID": 1, "GROUP": "MSCBML0", "TYPE": kind}
    if name == "PBARL":
        values |= {f"DIM{k}": float(d) for k, d in enumerate(stations[0], 1)} | {"NSM": 0.0}
    else:
        values |= {"DIMS": tuple(tuple(s) for s in stations), "XXB": xxb, "NSM": nsm}
    return Card(name, values, "m.bdf", 90 + pid, {})


def _bulk(text: str, *cards: Card):
    """The bulk data of ``text`` and of hand-made ``cards``."""
    bulk = read_bdf_text(text, name="m.bdf")
    more = {name: bulk[name] + [c for c in cards if c.name == name] for name in {c.name for c in cards}}
    return dataclasses.replace(bulk, cards={**bulk.cards, **more})


def _model(text: str, *cards: Card):
    return jaxfem.build_model(_bulk(text, *cards))


def _eigenvalues(model, n=8):
    return np.asarray(jaxfem.eigh(*jaxfem.assemble(model), n)[0])


def test_pbarl_i_cantilever_against_euler_bernoulli():
    h, a, _, tw, tf, _ = I_DIMS
    area = 2 * a * tf + (h - 2 * tf) * tw
    strong = (a * h**3 - (a - tw) * (h - 2 * tf) ** 3) / 12  # textbook I-beam, about z
    weak = (2 * tf * a**3 + (h - 2 * tf) * tw**3) / 12
    length = 10.0
    model = _model(_cantilever(length, 20), _library_card("PBARL", 1, "I", [I_DIMS]))
    lam = _eigenvalues(model)
    assert lam.dtype == np.float64 and model.beam_sections.A.dtype == np.float64
    for inertia in (weak, strong):  # first bending mode in each plane: (β L)⁴ E I / (ρ A L⁴)
        expected = 1.8751040687**4 * E * inertia / (RHO * area * length**4)
        assert np.min(np.abs(lam / expected - 1.0)) < 1e-3, (lam, expected)


def test_l_section_equals_the_equivalent_pbar_in_principal_axes():
    """PBARL L (I12 ≠ 0) against a PBAR with the eigenvalues of the inertia tensor and v
    along an eigenvector, K blank (Nastran ignores K of a bar with I12 ≠ 0); a tip spring
    along y makes the modes depend on the axes."""
    area, i1, i2, i12 = _green(_outline("L", L_DIMS))
    j = _expected_j_and_web_areas("L", L_DIMS)[0]
    moments, vectors = np.linalg.eigh(np.array([[i1, i12], [i12, i2]]))
    ey, ez = vectors[:, 1]  # element y' of the PBAR: the axis of the larger moment
    library = _model(_cantilever(2.0, 8, spring=5e4), _library_card("PBARL", 1, "L", [L_DIMS]))
    text = _cantilever(2.0, 8, spring=5e4, more=f"PBAR,1,1,{_fields([area, moments[1], moments[0], j])}")
    equivalent = _model(text.replace(",0.,1.,0.", f",0.,{_fields([ey, ez])}"))
    naive = _model(_cantilever(2.0, 8, spring=5e4, more=f"PBAR,1,1,{_fields([area, i1, i2, j])}"))
    np.testing.assert_allclose(_eigenvalues(library), _eigenvalues(equivalent), rtol=1e-9)
    assert np.max(np.abs(_eigenvalues(naive) / _eigenvalues(library) - 1)) > 0.01  # the turn matters
    sec = library.beam_sections
    assert (sec.K1[0], sec.K2[0], sec.section_type[0]) == (0.0, 0.0, lib.TYPES.index("L"))


def test_constant_pbeaml_is_its_pbarl(recwarn):
    text = _cantilever(2.0, 4).replace("CBAR,4,1", "CBEAM,4,3")
    model = _model(text, _library_card("PBARL", 1, "I", [I_DIMS]), _library_card("PBEAML", 3, "I", [I_DIMS] * 2))
    sec = model.beam_sections
    for name in ("A", "I1", "I2", "J", "K1", "K2", "nsm", "angle", "dims"):
        np.testing.assert_array_equal(getattr(sec, name)[0], getattr(sec, name)[1])
    assert sec.section_type.tolist() == [lib.TYPES.index("I")] * 2 and not recwarn.list
    assert model.beams.section.tolist() == [0, 0, 0, 1]


def test_tapered_pbeaml_and_pbeam_are_averaged_with_a_warning():
    text = _cantilever(2.0, 4, pids=(3, 2), beam="CBEAM", more="PBEAM,2,1,3.-3,9.-6,4.-6,,1.2-5")
    bulk = _bulk(text, _library_card("PBEAML", 3, "I", [I_DIMS, (0.12, *I_DIMS[1:])], nsm=(0.1, 0.3)))
    (pbeam,) = bulk["PBEAM"]
    stations = ((0.5, 3e-3, 9e-6, 4e-6, 0.0, 1.2e-5, 0.0), (1.0, 5e-3, 9e-6, 4e-6, 0.0, 1.2e-5, 0.0))
    pbeam = dataclasses.replace(pbeam, values={**pbeam.values, "STATIONS": stations})
    bulk = dataclasses.replace(bulk, cards={**bulk.cards, "PBEAM": [pbeam]})
    with pytest.warns(UserWarning) as caught:
        sec = jaxfem.build_model(bulk).beam_sections
    messages = [str(w.message) for w in caught]
    assert any(m.startswith("m.bdf:93: PBEAML 3: tapered PBEAML") for m in messages), messages
    assert any(m.startswith("m.bdf:4: PBEAM 2: tapered PBEAM") for m in messages), messages
    ends = [lib.section("I", d)[0] for d in (I_DIMS, (0.12, *I_DIMS[1:]))]
    np.testing.assert_allclose([sec.A[0], sec.A[1], sec.nsm[1]], [(3e-3 * 1.5 + 5e-3 / 2) / 2, sum(ends) / 2, 0.2],
                               rtol=1e-12)
    assert sec.section_type.tolist() == [-1, -1] and sec.dims.shape == (2, 0)


def _two_sections(i_dims=I_DIMS, l_dims=L_DIMS, more=""):
    """A cantilever half PBARL I (pid 1), half PBARL L (pid 2), a tip spring along y."""
    return _model(_cantilever(2.0, 8, pids=(1, 2), spring=5e4, more=more),
                  _library_card("PBARL", 1, "I", [i_dims]), _library_card("PBARL", 2, "L", [l_dims]))


DIM_PARAMETERS = (Parameter("flange", "dim", pids=(1,), dim=6), Parameter("leg", "dim", pids=(2,), dim=3))


def test_dim_parameter_gradient_against_central_differences():
    model, par = parameterise(_two_sections(), DIM_PARAMETERS)
    eigenvalues = jax.jit(lambda theta: jaxfem.eigh(*jaxfem.assemble(par.apply(model, theta)), 4)[0])
    theta = jnp.zeros(2)
    jac = np.asarray(jax.jit(jax.jacfwd(eigenvalues))(theta))
    assert jac.dtype == np.float64 and np.all(np.abs(jac) > 0.0)
    h = 1e-5
    for k in range(2):
        step = h * np.eye(2)[k]
        fd = (np.asarray(eigenvalues(theta + step)) - np.asarray(eigenvalues(theta - step))) / (2 * h)
        np.testing.assert_allclose(jac[:, k], fd, rtol=1e-6)


def test_dim_parameter_gives_the_model_built_with_that_dimension():
    """θ = log 1.2 on the flange, log 0.9 on the leg: the model built from the scaled DIMs,
    turned principal axes (v) included."""
    model, par = parameterise(_two_sections(), DIM_PARAMETERS)
    updated = par.apply(model, jnp.log(jnp.array([1.2, 0.9])))
    l_dims = (L_DIMS[0], L_DIMS[1], 0.9 * L_DIMS[2], L_DIMS[3])
    built = _two_sections((*I_DIMS[:5], 1.2 * I_DIMS[5]), l_dims)
    for name in ("A", "I1", "I2", "J", "K1", "K2", "angle", "dims"):
        np.testing.assert_allclose(getattr(updated.beam_sections, name), getattr(built.beam_sections, name),
                                   rtol=1e-12, atol=1e-15, err_msg=name)
    np.testing.assert_allclose(updated.beams.v, built.beams.v, rtol=1e-12, atol=1e-15)
    assert float(updated.beam_sections.angle[1]) != float(model.beam_sections.angle[1])  # the L's axes turned
    np.testing.assert_allclose(_eigenvalues(updated), _eigenvalues(built), rtol=1e-10)


def test_dim_parameter_targets_are_checked():
    model = _two_sections(more="PBAR,3,1,1.-3,1.-6,1.-6,1.-6")
    with pytest.raises(ValueError, match=r"'bar': pids \[3\] are not PBARL or constant PBEAML properties"):
        parameterise(model, [Parameter("bar", "dim", pids=(3,), dim=1)])
    with pytest.raises(ValueError, match=r"'seven': pids \[2\] have no DIM7"):
        parameterise(model, [Parameter("seven", "dim", pids=(2,), dim=7)])
    with pytest.raises(ValueError, match=r"'five': pids \[2\] have no DIM5"):
        parameterise(model, [Parameter("five", "dim", pids=(1, 2), dim=5)])
    with pytest.raises(ValueError, match="kind dim needs dim = n"):
        Parameter("x", "dim", pids=(1,))
    with pytest.raises(ValueError, match="dim = 2 is only for kind dim, not kind A"):
        Parameter("x", "A", pids=(1,), dim=2)
    assert identical_columns(model, [Parameter("a", "dim", pids=(1,), dim=5), Parameter("b", "dim", pids=(1,),
                                                                                         dim=6)]) is None
