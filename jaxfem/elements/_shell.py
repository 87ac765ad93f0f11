"""Flat shell elements: MITC4 quadrilateral and MITC3 triangle, with laminate properties.

Element frame (:func:`shell_frame`): normal n from the diagonals (quad) or the sides
(triangle), x along the G1→G2 side projected on the mean plane, y = n × x. Corners are
projected on the mean plane through their centroid; a warped quad is tied to its grids
by rigid links over the warping heights h_i (MacNeal 1994, *Finite Elements: their design
and performance*, §9.4), so rigid-body motions of the grids stay strain-free.
"""

import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._beam import skew
from ._laminate import Laminate


def shell_frame(xyz: Float[ArrayLike, "nn 3"]) -> Float[Array, "3 3"]:
    """Rows x, y, n of the element frame in basic axes, for 3 or 4 corner positions [m]."""
    xyz = jnp.asarray(xyz)
    if xyz.shape[0] == 4:
        n = jnp.cross(xyz[2] - xyz[0], xyz[3] - xyz[1])
    else:
        n = jnp.cross(xyz[1] - xyz[0], xyz[2] - xyz[0])
    n = n / jnp.linalg.norm(n)
    side = xyz[1] - xyz[0]
    x = side - (side @ n) * n
    x = x / jnp.linalg.norm(x)
    return jnp.stack([x, jnp.cross(n, x), n])


# ---------------------------------------------------------------------------------------
# Integration rules and shape functions (flat element, local x, y)

_G = 1.0 / np.sqrt(3.0)
QUAD_CORNERS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
_QUAD_POINTS = _G * QUAD_CORNERS  # 2 × 2 Gauss, weights 1
_TRIA_POINTS = np.array([[1 / 6, 1 / 6], [2 / 3, 1 / 6], [1 / 6, 2 / 3]])  # weights 1/6
_TRIA_DN = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])
DRILLING = 1e-6  # drilling penalty per unit of PARAM K6ROT, relative to the membrane stiffness
RIGID_SHEAR = 1e4  # shear stiffness of a section without shear flexibility, relative to 12·D/area


def quad_shape(xi, eta) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear N (..., 4) and dN/d(ξ, η) (..., 2, 4) at natural coordinates (...),
    corners (−1, −1), (1, −1), (1, 1), (−1, 1)."""
    c = QUAD_CORNERS
    a = 1 + np.asarray(xi)[..., None] * c[:, 0]
    b = 1 + np.asarray(eta)[..., None] * c[:, 1]
    return 0.25 * a * b, 0.25 * np.stack([c[:, 0] * b, c[:, 1] * a], axis=-2)


def _tria_shape(r: float, s: float) -> tuple[np.ndarray, np.ndarray]:
    return np.array([1.0 - r - s, r, s]), _TRIA_DN


def _rows(*columns):
    """(rows, nn, 6) blocks of per-node coefficients on [u, v, w, θx, θy, θz] → (rows, 6·nn)."""
    return jnp.stack([jnp.stack(c, axis=-1) for c in columns]).reshape(len(columns), -1)


def _membrane(dndx):
    """ε = [u,x, v,y, u,y + v,x]."""
    z = jnp.zeros_like(dndx[0])
    return _rows((dndx[0], z, z, z, z, z), (z, dndx[1], z, z, z, z), (dndx[1], dndx[0], z, z, z, z))


def _bending(dndx):
    """κ = [θy,x, −θx,y, θy,y − θx,x] for u(z) = u + zθy, v(z) = v − zθx."""
    z = jnp.zeros_like(dndx[0])
    return _rows((z, z, z, z, dndx[0], z), (z, z, z, -dndx[1], z, z), (z, z, z, -dndx[0], dndx[1], z))


def _drilling(n, dndx):
    """θz − ½(v,x − u,y) (Hughes & Brezzi 1989, the penalty term of their functional)."""
    z = jnp.zeros_like(n)
    return _rows((0.5 * dndx[1], -0.5 * dndx[0], z, z, z, jnp.asarray(n)))[0]


def _covariant_shear(n, dn, jac):
    """Covariant transverse shear [e_ξ, e_η] = w,ξ + θy·x,ξ − θx·y,ξ (and η): rows (2, 6·nn)."""
    z = jnp.zeros_like(jnp.asarray(n))
    n = jnp.asarray(n)
    return _rows(*((z, z, dn[a], -n * jac[a, 1], n * jac[a, 0], z) for a in range(2)))


# Closed forms instead of LAPACK for the element's 2 × 2 and 4 × 4 algebra: batched over
# tens of thousands of elements inside a compiled program, jaxlib 0.10.2's LAPACK kernels
# split their batch over the XLA-CPU worker threads and wait on them from a worker; with
# several such calls in flight both workers of a 2-core machine wait and the program
# hangs at 0 % CPU (seen with 50,000 quads: a jitted 300k-DoF assembly hung 3 times of 3).


def _det2(a):
    return a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]


def _inv2(a):
    return jnp.array([[a[1, 1], -a[0, 1]], [-a[1, 0], a[0, 0]]]) / _det2(a)


def _spd_solve(a, b):
    """``a⁻¹ b`` for a small symmetric positive definite ``a``: unrolled Cholesky."""
    n = a.shape[0]
    low = [[None] * n for _ in range(n)]
    for j in range(n):
        d = a[j, j] - sum(low[j][k] ** 2 for k in range(j))
        low[j][j] = jnp.sqrt(d)
        for i in range(j + 1, n):
            low[i][j] = (a[i, j] - sum(low[i][k] * low[j][k] for k in range(j))) / low[j][j]
    y = []
    for i in range(n):
        y.append((b[i] - sum(low[i][k] * y[k] for k in range(i))) / low[i][i])
    x = [None] * n
    for i in reversed(range(n)):
        x[i] = (y[i] - sum(low[k][i] * x[k] for k in range(i + 1, n))) / low[i][i]
    return jnp.stack(x)


def _stiff_local(xy, lam, r_corner, k6rot, points, weights, shape, shear_at):
    """Local stiffness (6·nn + extra) of a flat element, summed over the integration points.

    ``shear_at(xi, eta)`` gives the assumed covariant shear rows; ``extra`` incompatible
    membrane modes come from :func:`_incompatible` (quad) or none (triangle).
    """
    nn = xy.shape[0]
    _, dn0 = shape(*points.mean(axis=0))
    jac0 = dn0 @ xy
    at = [(p, w, *shape(*p)) for p, w in zip(points, weights)]
    jacs = [dn @ xy for *_, dn in at]
    dets = [_det2(j) for j in jacs]
    area = sum(w * d for (_, w, *_), d in zip(at, dets))
    rigid_s = RIGID_SHEAR * 12.0 * 0.5 * (lam.D[0, 0] + lam.D[1, 1]) / area * jnp.eye(2)
    s_mat = jnp.where(lam.rigid > 0, rigid_s, lam.S)
    extra = 4 if nn == 4 else 0
    size = 6 * nn + extra
    k = jnp.zeros((size, size))
    for (p, w, n, dn), jac, det in zip(at, jacs, dets):
        jinv = _inv2(jac)
        dndx = jinv @ dn
        bm, bb = _membrane(dndx), _bending(dndx)
        if extra:
            bm = jnp.concatenate([bm, _incompatible(p, jac0, det)], axis=1)
            bb = jnp.concatenate([bb, jnp.zeros((3, extra))], axis=1)
        bs = jnp.pad(jinv @ shear_at(*p), ((0, 0), (0, extra)))
        drill = jnp.pad(_drilling(n, dndx), (0, extra))
        r = jnp.asarray(n) @ r_corner
        c = jnp.block([[lam.A * r, lam.B * r**2], [lam.B * r**2, lam.D * r**3]])
        b = jnp.concatenate([bm, bb])
        gamma = DRILLING * k6rot * (lam.A[0, 0] + lam.A[1, 1] + lam.A[2, 2]) / 3.0 * r
        k = k + w * det * (b.T @ c @ b + bs.T @ (s_mat * r) @ bs + gamma * jnp.outer(drill, drill))
    if not extra:
        return k
    m = 6 * nn
    kii = k[m:, m:]
    kii = kii + jnp.eye(extra) * (jnp.trace(kii) == 0.0).astype(jnp.float64)  # no membrane: nothing to condense
    return k[:m, :m] - k[:m, m:] @ _spd_solve(kii, k[m:, :m])


def _incompatible(p, jac0, det):
    """Membrane strains of the modes (1 − ξ²), (1 − η²) in u and v, with the centre
    Jacobian and the factor det J₀/det J that makes them pass the patch test (Taylor,
    Beresford & Wilson 1976, QM6): columns [u·P1, u·P2, v·P1, v·P2]."""
    dp = jnp.array([[-2.0 * p[0], 0.0], [0.0, -2.0 * p[1]]])  # rows d/dξ, d/dη; columns P1, P2
    d = _inv2(jac0) @ dp * (_det2(jac0) / det)
    z = jnp.zeros(2)
    return jnp.stack([jnp.concatenate([d[0], z]), jnp.concatenate([z, d[1]]), jnp.concatenate([d[1], d[0]])])


def _quad_shear(xy):
    """MITC4 (Dvorkin & Bathe 1984): e_ξ from the tying points (0, ±1), e_η from (±1, 0)."""

    def at(xi, eta):
        n, dn = quad_shape(xi, eta)
        return _covariant_shear(n, dn, dn @ xy)

    ea, ec = at(0.0, 1.0)[0], at(0.0, -1.0)[0]
    eb, ed = at(-1.0, 0.0)[1], at(1.0, 0.0)[1]

    def shear(xi, eta):
        return jnp.stack([0.5 * (1 + eta) * ea + 0.5 * (1 - eta) * ec, 0.5 * (1 + xi) * ed + 0.5 * (1 - xi) * eb])

    return shear


def _tria_shear(xy):
    """MITC3 (Lee & Bathe 2004): e_r from (½, 0), e_s from (0, ½), the edge r + s = 1 from
    (½, ½): ẽ_r = e_r⁽¹⁾ + c·s, ẽ_s = e_s⁽²⁾ − c·r, c = e_s⁽²⁾ − e_r⁽¹⁾ − e_s⁽³⁾ + e_r⁽³⁾."""
    jac = _TRIA_DN @ xy

    def at(r, s):
        n, dn = _tria_shape(r, s)
        return _covariant_shear(n, dn, jac)

    e1, e2, e3 = at(0.5, 0.0), at(0.0, 0.5), at(0.5, 0.5)
    c = e2[1] - e1[0] - e3[1] + e3[0]
    return lambda r, s: jnp.stack([e1[0] + c * s, e2[1] - c * r])


def _mass_local(xy, lam, r_corner, points, weights, shape, lumped):
    """Consistent mass of u(z) = u + zθy, v(z) = v − zθx, w: kinetic energy density
    I0(u² + v² + w²) + 2 I1 (u θy − v θx) + I2 (θx² + θy²); lumped: I0·area/nn on each
    translation of each node."""
    nn = xy.shape[0]
    m = jnp.zeros((6 * nn, 6 * nn))
    total = 0.0
    for p, w in zip(points, weights):
        n, dn = shape(*p)
        n = jnp.asarray(n)
        z = jnp.zeros_like(n)
        da = w * _det2(dn @ xy)
        r = n @ r_corner
        total = total + da * lam.I0 * r
        u, v, wz, tx, ty = _rows((n, z, z, z, z, z), (z, n, z, z, z, z), (z, z, n, z, z, z),
                                 (z, z, z, n, z, z), (z, z, z, z, n, z))
        coupling = jnp.outer(u, ty) - jnp.outer(v, tx)
        m = m + da * (lam.I0 * r * (jnp.outer(u, u) + jnp.outer(v, v) + jnp.outer(wz, wz))
                      + lam.I1 * r**2 * (coupling + coupling.T)
                      + lam.I2 * r**3 * (jnp.outer(tx, tx) + jnp.outer(ty, ty)))
    if lumped:
        translations = np.tile(np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0]), nn)
        return jnp.diag(total / nn * translations)
    return m


def _rule(nn: int):
    if nn == 4:
        return _QUAD_POINTS, np.ones(4), quad_shape
    return _TRIA_POINTS, np.full(3, 1.0 / 6.0), _tria_shape


def _geometry(xyz):
    """Frame, flat local corner coordinates (nn, 2) and the basic-to-local transformation
    T (6·nn × 6·nn) through the rigid links over the warping heights."""
    xyz = jnp.asarray(xyz)
    frame = shell_frame(xyz)
    local = (xyz - xyz.mean(axis=0)) @ frame.T
    nn = xyz.shape[0]
    blocks = []
    for i in range(nn):
        w = -local[i, 2] * frame[2]  # flat corner minus grid
        link = jnp.block([[jnp.eye(3), -skew(w)], [jnp.zeros((3, 3)), jnp.eye(3)]])
        blocks.append(jsl.block_diag(frame, frame) @ link)
    return local[:, :2], jsl.block_diag(*blocks)


def shell_stiffness(
    xyz: Float[ArrayLike, "nn 3"], lam: Laminate, t_ratio: Float[ArrayLike, " nn"], k6rot: float
) -> Float[Array, "6nn 6nn"]:
    """Stiffness of a CQUAD4 (MITC4 shear, QM6 membrane) or CTRIA3 (MITC3 shear, constant
    strain membrane) in basic axes, on the 6 DoFs of each grid.

    Membrane–bending energy ``½∫[ε; κ]ᵀ[[A, B], [B, D]][ε; κ] dA`` with the section scaled
    by the local thickness ratio r (A, S ∝ r, B ∝ r², D ∝ r³), transverse shear
    ``½∫γᵀSγ dA`` from the assumed strains, and the drilling penalty
    ``½∫γ_d(θz − ω)² dA``, ``γ_d = 10⁻⁶·K6ROT·tr(A)/3`` (small enough to leave membrane
    results unchanged, large enough to keep θz off the null space). A section without
    shear flexibility gets ``S = 10⁴·12·D/area``. 2 × 2 Gauss points (quad) or three
    points (triangle); the quad's incompatible modes are condensed statically.

    **Arguments:** corner positions [m] (G1..Gn order), the element's :class:`Laminate`,
    corner thickness ratios, PARAM K6ROT. **Returns:** (6·nn, 6·nn) [N/m, N, N·m].
    """
    xy, t = _geometry(xyz)
    nn = xy.shape[0]
    points, weights, shape = _rule(nn)
    shear = _quad_shear(xy) if nn == 4 else _tria_shear(xy)
    k = _stiff_local(xy, lam, jnp.asarray(t_ratio), k6rot, points, weights, shape, shear)
    return t.T @ k @ t


def shell_mass(
    xyz: Float[ArrayLike, "nn 3"], lam: Laminate, t_ratio: Float[ArrayLike, " nn"], lumped: bool
) -> Float[Array, "6nn 6nn"]:
    """Mass of a CQUAD4/CTRIA3 in basic axes: consistent (with rotary inertia I2 and the
    coupling I1 of offsets and unsymmetric laminates) or lumped (``lumped``, PARAM
    COUPMASS −1: translations only). **Returns:** (6·nn, 6·nn) [kg, kg·m, kg·m²]."""
    xy, t = _geometry(xyz)
    points, weights, shape = _rule(xy.shape[0])
    return t.T @ _mass_local(xy, lam, jnp.asarray(t_ratio), points, weights, shape, lumped) @ t
