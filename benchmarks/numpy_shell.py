"""An independent NumPy CQUAD4, one element per call: the reference of the shell assembly
benchmark (``benchmarks/perf_shell_assembly.py``) and the cross-check of
``tests/test_numpy_shell.py``. Nothing here imports jaxfem element code.

Written from the published formulations, with jaxfem's conventions (the docstrings of
``jaxfem.elements.shell_stiffness``, ``shell_mass`` and ``shell_frame``):

- DoFs [u, v, w, θx, θy, θz] per grid, basic axes; through the thickness
  u(z) = u + z·θy, v(z) = v − z·θx, so γxz = w,x + θy, γyz = w,y − θx and the curvatures
  κ = [θy,x, −θx,y, θy,y − θx,x].
- Element frame: normal n along (x3 − x1) × (x4 − x2), x along G1→G2 projected on the
  plane normal to n, y = n × x. Corners projected on the mean plane through their
  centroid; each grid is tied to its flat corner by a rigid link over the warping height
  h_i (the corner's distance from that plane): u_flat = u_grid + θ × (−h_i·n).
- Membrane: bilinear u, v plus the incompatible modes (1 − ξ²), (1 − η²) of QM6
  (Taylor, Beresford & Wilson 1976, Int. J. Numer. Meth. Eng. 10, 1211–1219): their
  Cartesian derivatives taken with the centre Jacobian J0 and scaled by det J0 / det J,
  condensed statically.
- Transverse shear: MITC4 (Dvorkin & Bathe 1984, Eng. Comput. 1, 77–88), covariant
  e_ξ = w,ξ + θy·x,ξ − θx·y,ξ tied at (0, ±1), e_η at (±1, 0), interpolated linearly
  in η (ξ), γ = J⁻¹ [ẽ_ξ, ẽ_η].
- Drilling penalty ½∫γ_d (θz − ½(v,x − u,y))² dA (Hughes & Brezzi 1989) on the
  bilinear u, v, θz, γ_d = 10⁻⁶·K6ROT·tr(A)/3, at the 2 × 2 Gauss points.
- Section [[A, B], [B, D]] and S scaled by the interpolated corner thickness ratio r
  (A, S ∝ r, B ∝ r², D ∝ r³); 2 × 2 Gauss integration.
- Consistent mass: kinetic energy density I0 (u² + v² + w²) + 2 I1 (u θy − v θx)
  + I2 (θx² + θy²) (no θz inertia), I0 ∝ r, I1 ∝ r², I2 ∝ r³, 2 × 2 Gauss points.

The section of an isotropic PSHELL (MID1 = MID2 = MID3, no MID4) is :func:`pshell`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DRILLING = 1e-6  # γ_d per unit of K6ROT, relative to tr(A)/3

_XI = np.array([-1.0, 1.0, 1.0, -1.0])
_ETA = np.array([-1.0, -1.0, 1.0, 1.0])


def shape(xi: float, eta: float) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear N_i (4,) and their derivatives [∂/∂ξ; ∂/∂η] (2, 4) at (ξ, η)."""
    n = 0.25 * (1.0 + _XI * xi) * (1.0 + _ETA * eta)
    dn = np.array([0.25 * _XI * (1.0 + _ETA * eta), 0.25 * _ETA * (1.0 + _XI * xi)])
    return n, dn


_G = 1.0 / np.sqrt(3.0)
GAUSS = [(_G * a, _G * b) for a, b in zip(_XI, _ETA)]  # 2 × 2 points, unit weights
_AT_GAUSS = [(p, *shape(*p)) for p in GAUSS]
# MITC4 tying points: A (0, 1), C (0, −1) for e_ξ; D (1, 0), B (−1, 0) for e_η.
_TIE = {k: shape(*p) for k, p in {"A": (0.0, 1.0), "C": (0.0, -1.0), "D": (1.0, 0.0), "B": (-1.0, 0.0)}.items()}
_DN0 = shape(0.0, 0.0)[1]

# Columns of each DoF kind in the 24 element DoFs (node-major, 6 per node).
_U, _V, _W, _TX, _TY, _TZ = (slice(c, 24, 6) for c in range(6))


@dataclass(frozen=True)
class Section:
    """Shell section, element axes: A [N/m], B [N], D [N·m] (3 × 3), S [N/m] (2 × 2),
    inertia per unit area I0 [kg/m²], I1 [kg/m], I2 [kg]."""

    A: np.ndarray
    B: np.ndarray
    D: np.ndarray
    S: np.ndarray
    I0: float
    I1: float
    I2: float


def pshell(E: float, nu: float, t: float, rho: float, *, i_ratio: float = 1.0, ts_ratio: float = 5.0 / 6.0,
           nsm: float = 0.0) -> Section:
    """Isotropic PSHELL (one MAT1 as MID1, MID2, MID3): A = t·Q, B = 0, D = (12I/T³)·t³/12·Q,
    S = (TS/T)·t·G·I, I0 = ρt + NSM, I1 = 0, I2 = ρt³/12, with Q the plane-stress matrix
    E/(1 − ν²)·[[1, ν, 0], [ν, 1, 0], [0, 0, (1 − ν)/2]] and G = E/(2(1 + ν))."""
    g = E / (2.0 * (1.0 + nu))
    q = E / (1.0 - nu * nu) * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.0]])
    q[2, 2] = g
    return Section(A=t * q, B=np.zeros((3, 3)), D=i_ratio * t**3 / 12.0 * q, S=ts_ratio * t * g * np.eye(2),
                   I0=rho * t + nsm, I1=0.0, I2=rho * t**3 / 12.0)


def frame(xyz: np.ndarray) -> np.ndarray:
    """Rows x, y, n of the element frame (basic axes) of a quad's corners (4, 3)."""
    n = np.cross(xyz[2] - xyz[0], xyz[3] - xyz[1])
    n /= np.linalg.norm(n)
    x = xyz[1] - xyz[0]
    x = x - np.dot(x, n) * n
    x /= np.linalg.norm(x)
    return np.array([x, np.cross(n, x), n])


def geometry(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Flat local corner coordinates (4, 2) and T (24 × 24): local DoFs = T · grid DoFs.

    Node block ``[[R, h·L], [0, R]]`` with R the frame rows and L = [−y; x; 0]: the link
    arm from grid to flat corner is d = −h·n, so u_flat = u + θ × d = u + h·(n × θ), whose
    local components are (x·(n × θ), y·(n × θ), n·(n × θ)) = (−y·θ, x·θ, 0)."""
    xyz = np.asarray(xyz, dtype=np.float64)
    r = frame(xyz)
    local = (xyz - xyz.mean(axis=0)) @ r.T
    link = np.array([-r[1], r[0], np.zeros(3)])  # rows: local u, v, w per unit h and θ (basic)
    t = np.zeros((24, 24))
    for i in range(4):
        a = 6 * i
        t[a:a + 3, a:a + 3] = r
        t[a + 3:a + 6, a + 3:a + 6] = r
        t[a:a + 3, a + 3:a + 6] = local[i, 2] * link
    return local[:, :2], t


def _tied_shear(xy: np.ndarray, point: str, row: int) -> np.ndarray:
    """Covariant shear e_ξ (row 0) or e_η (row 1) at a tying point, on the 24 DoFs."""
    n, dn = _TIE[point]
    dx = dn[row] @ xy  # (x,ξ, y,ξ) or (x,η, y,η) there
    e = np.zeros(24)
    e[_W] = dn[row]
    e[_TX] = -n * dx[1]
    e[_TY] = n * dx[0]
    return e


def stiffness_local(xy: np.ndarray, sec: Section, k6rot: float = 100.0, t_ratio=None) -> np.ndarray:
    """Stiffness (24 × 24) on the local DoFs of the flat element, QM6 modes condensed."""
    r_corner = np.ones(4) if t_ratio is None else np.asarray(t_ratio, dtype=np.float64)
    e_a, e_c = _tied_shear(xy, "A", 0), _tied_shear(xy, "C", 0)
    e_b, e_d = _tied_shear(xy, "B", 1), _tied_shear(xy, "D", 1)
    j0 = _DN0 @ xy
    det0 = np.linalg.det(j0)
    j0inv = np.linalg.inv(j0)
    gamma_d = DRILLING * k6rot * np.trace(sec.A) / 3.0
    k = np.zeros((28, 28))
    bm = np.zeros((3, 28))
    bb = np.zeros((3, 28))
    bs = np.zeros((2, 28))
    bd = np.zeros(28)
    for (xi, eta), n, dn in _AT_GAUSS:
        jac = dn @ xy
        det = jac[0, 0] * jac[1, 1] - jac[0, 1] * jac[1, 0]
        jinv = np.array([[jac[1, 1], -jac[0, 1]], [-jac[1, 0], jac[0, 0]]]) / det
        dx, dy = jinv @ dn  # ∂N/∂x, ∂N/∂y
        # membrane, compatible part
        bm[0, _U], bm[1, _V] = dx, dy
        bm[2, _U], bm[2, _V] = dy, dx
        # QM6: P1 = 1 − ξ², P2 = 1 − η²; [P,x; P,y] = J0⁻¹ [P,ξ; P,η] · det J0 / det J
        f = det0 / det
        p1 = j0inv[:, 0] * (-2.0 * xi) * f
        p2 = j0inv[:, 1] * (-2.0 * eta) * f
        bm[0, 24:28] = (p1[0], p2[0], 0.0, 0.0)
        bm[1, 24:28] = (0.0, 0.0, p1[1], p2[1])
        bm[2, 24:28] = (p1[1], p2[1], p1[0], p2[0])
        # bending
        bb[0, _TY] = dx
        bb[1, _TX] = -dy
        bb[2, _TY], bb[2, _TX] = dy, -dx
        # MITC4 shear
        e_xi = 0.5 * (1.0 + eta) * e_a + 0.5 * (1.0 - eta) * e_c
        e_eta = 0.5 * (1.0 + xi) * e_d + 0.5 * (1.0 - xi) * e_b
        bs[:, :24] = jinv @ np.array([e_xi, e_eta])
        # drilling: θz − ½(v,x − u,y)
        bd[_TZ], bd[_U], bd[_V] = n, 0.5 * dy, -0.5 * dx
        r = n @ r_corner
        c = np.block([[sec.A * r, sec.B * r**2], [sec.B * r**2, sec.D * r**3]])
        b = np.vstack([bm, bb])
        k += det * (b.T @ c @ b + bs.T @ (sec.S * r) @ bs + gamma_d * r * np.outer(bd, bd))
    kcc, kci, kii = k[:24, :24], k[:24, 24:], k[24:, 24:]
    return kcc - kci @ np.linalg.solve(kii, kci.T)


def mass_local(xy: np.ndarray, sec: Section, t_ratio=None) -> np.ndarray:
    """Consistent mass (24 × 24) on the local DoFs of the flat element."""
    r_corner = np.ones(4) if t_ratio is None else np.asarray(t_ratio, dtype=np.float64)
    m = np.zeros((24, 24))
    for _, n, dn in _AT_GAUSS:
        jac = dn @ xy
        det = jac[0, 0] * jac[1, 1] - jac[0, 1] * jac[1, 0]
        r = n @ r_corner
        i0, i1, i2 = sec.I0 * r, sec.I1 * r**2, sec.I2 * r**3
        node = np.diag([i0, i0, i0, i2, i2, 0.0])  # per node pair, times N_a N_b
        node[0, 4] = node[4, 0] = i1
        node[1, 3] = node[3, 1] = -i1
        m += det * np.kron(np.outer(n, n), node)
    return m


def cquad4_stiffness(xyz: np.ndarray, sec: Section, k6rot: float = 100.0, t_ratio=None) -> np.ndarray:
    """Stiffness (24 × 24) of a CQUAD4 in basic axes on its grids' DoFs [N/m, N, N·m]."""
    xy, t = geometry(xyz)
    return t.T @ stiffness_local(xy, sec, k6rot, t_ratio) @ t


def cquad4_mass(xyz: np.ndarray, sec: Section, t_ratio=None) -> np.ndarray:
    """Consistent mass (24 × 24) of a CQUAD4 in basic axes [kg, kg·m, kg·m²]."""
    xy, t = geometry(xyz)
    return t.T @ mass_local(xy, sec, t_ratio) @ t


def cquad4(xyz: np.ndarray, sec: Section, k6rot: float = 100.0, t_ratio=None) -> tuple[np.ndarray, np.ndarray]:
    """(K, M) of one CQUAD4, the geometry computed once."""
    xy, t = geometry(xyz)
    return t.T @ stiffness_local(xy, sec, k6rot, t_ratio) @ t, t.T @ mass_local(xy, sec, t_ratio) @ t
