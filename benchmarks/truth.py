"""Independent finite-element "truth" for testing model updating: plain NumPy/SciPy.

Builds its own model from Nastran bulk data (parsed by :func:`jaxfem.io.read_bdf`; no other
jaxfem code) with physics deliberately outside the jaxfem model family, and returns
"measured" modes as :class:`identification.ModalData`:

- every CBAR is split into ``refine`` Timoshenko sub-elements (new internal grids); the
  element matrices come from the exact static fields of a shear-deformable beam
  (θ quadratic, v cubic), integrated by Gauss quadrature; consistent mass including rotary
  inertia ρI for every beam (also Euler–Bernoulli ones) and torsional inertia ρ(I1+I2);
- RBE2 links are stiff penalty springs on d = u_dep − T u_master (not eliminated): d is
  made a coordinate (u = X q), so the penalty energy ½ α Σ d² is diagonal in the transformed
  K and rounding errors stay at the scale of the structural stiffness (with the penalty
  added to K in u, α = 1e6·max diag moved GARTEUR frequencies by 0.5 %);
- SPCs remove DoFs; DoFs with neither stiffness nor mass are removed (``n_removed``);
- eigenvalues from the shifted pencil (M, K + σM), λ = 1/μ − σ (free–free safe).

Effects (:meth:`Truth.scale` (also torsion GJ alone), :meth:`add_mass`, :meth:`add_mass_at`,
:meth:`ground_spring`, :meth:`release_support`, :meth:`joint`, and frequency-dependent
stiffness :meth:`frequency_law`, :meth:`viscoelastic`, :meth:`standard_linear_solid`) modify
the Truth in place and return it, so they chain. :meth:`Truth.measure` adds noise and,
optionally, uniform modal damping ratios. SI units throughout: m, kg, s, N, Pa, Hz.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import threadpool_limits

from identification import ModalData, Sensors
from jaxfem.io import read_bdf, read_bdf_text

PENALTY = 1e5  # RBE2 penalty stiffness / largest diagonal stiffness of the structural elements
SIGMA = (2 * np.pi * 1.0) ** 2  # eigen shift σ (rad/s)²: K + σM is definite for free–free models
VISCO_RTOL = 1e-9  # fixed-point tolerance on the frequency of each mode with frequency-dependent stiffness
_CARDS = {"GRID", "CBAR", "PBAR", "PBARL", "MAT1", "CROD", "PROD", "CBUSH", "PBUSH", "CELAS2",
          "CONM2", "RBE2", "SPC1", "PARAM"}
_GAUSS = np.polynomial.legendre.leggauss(4)  # exact for the degree-6 products of cubic fields


def _digits(code) -> list[int]:
    """Nastran component code (e.g. 3456) as 0-based DoF indices."""
    return sorted({int(c) - 1 for c in str(code)})


def _skew(r) -> np.ndarray:
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


def _carry(r) -> np.ndarray:
    """6×6 T: motion of the point grid + r of a rigid body moving with the grid's 6 DoFs."""
    t = np.eye(6)
    t[:3, 3:] = -_skew(r)
    return t


def _plane(EI, s, rho_a, rho_i, L):
    """Planar bending stiffness and mass on [v_A, θ_A, v_B, θ_B] (θ = dv/dx for s = 0).

    Homogeneous Timoshenko solution: θ = b0 + b1 x + b2 x², shear strain v' − θ = −2 s b2
    with s = EI/(K G A) (0: Euler–Bernoulli), so v = c + b0 x + b1 x²/2 + b2 (x³/3 − 2 s x).
    Energies ½∫EI θ'² + ½ K G A (v'−θ)² and ½∫ρA v̇² + ρI θ̇² by quadrature.
    """
    def v_row(x):
        return np.array([1.0, x, x**2 / 2, x**3 / 3 - 2 * s * x])

    def t_row(x):
        return np.array([0.0, 1.0, x, x**2])

    inv = np.linalg.inv(np.array([v_row(0.0), t_row(0.0), v_row(L), t_row(L)]))
    k = np.zeros((4, 4))
    k[3, 3] = 4 * s * EI * L  # shear: K G A (2 s b2)² L with K G A = EI / s
    m = np.zeros((4, 4))
    for xi, w in zip(*_GAUSS):
        x, wx = L * (xi + 1) / 2, w * L / 2
        curv = np.array([0.0, 0.0, 1.0, 2 * x])  # dθ/dx per coefficient
        k += wx * EI * np.outer(curv, curv)
        m += wx * (rho_a * np.outer(v_row(x), v_row(x)) + rho_i * np.outer(t_row(x), t_row(x)))
    return inv.T @ k @ inv, inv.T @ m @ inv


def _beam(xa, xb, v, E, G, rho, sec):
    """12×12 stiffness, consistent mass and the torsion (GJ) part of the stiffness of a CBAR
    segment between end points, basic axes.

    Element axes (QRG CBAR): x from A to B, z = x × v, y = z × x; plane 1 (x–y) bends with
    I1 and shear factor K1, plane 2 (x–z) with I2, K2 (θy = −dw/dx); K = 0: no shear strain.
    """
    A, I1, I2, J, K1, K2, nsm = sec
    L = np.linalg.norm(xb - xa)
    ex = (xb - xa) / L
    ez = np.cross(ex, v)
    ez /= np.linalg.norm(ez)
    axes = np.array([ex, np.cross(ez, ex), ez])
    k, m, kt = np.zeros((12, 12)), np.zeros((12, 12)), np.zeros((12, 12))
    bar, bar_m = np.array([[1.0, -1.0], [-1.0, 1.0]]), np.array([[2.0, 1.0], [1.0, 2.0]]) * L / 6
    kt[np.ix_([3, 9], [3, 9])] = G * J / L * bar
    for dofs, stiff, inertia in (([0, 6], E * A / L, rho * A + nsm), ([3, 9], G * J / L, rho * (I1 + I2))):
        k[np.ix_(dofs, dofs)] += stiff * bar
        m[np.ix_(dofs, dofs)] += inertia * bar_m
    for dofs, sign, I, K in (([1, 5, 7, 11], 1.0, I1, K1), ([2, 4, 8, 10], -1.0, I2, K2)):
        s = E * I / (K * G * A) if K > 0 else 0.0
        kp, mp = _plane(E * I, s, rho * A + nsm, rho * I, L)
        d = np.array([1.0, sign, 1.0, sign])  # plane 2: (w, −θy) is the planar (v, θ)
        k[np.ix_(dofs, dofs)] += d[:, None] * kp * d
        m[np.ix_(dofs, dofs)] += d[:, None] * mp * d
    lam = np.kron(np.eye(4), axes)
    return lam.T @ k @ lam, lam.T @ m @ lam, lam.T @ kt @ lam


def _box(card):
    """A, I1, I2, J, K1, K2 of a thin-walled PBARL BOX: DIM1 width (z), DIM2 height (y),
    DIM3 top/bottom wall, DIM4 side wall; J by Bredt on the mid-line, K = web area / A."""
    b, h, t3, t4 = (card[f"DIM{i}"] for i in range(1, 5))
    bi, hi = b - 2 * t4, h - 2 * t3
    area = b * h - bi * hi
    j = 4 * ((b - t4) * (h - t3)) ** 2 / (2 * (b - t4) / t3 + 2 * (h - t3) / t4)
    return (area, (b * h**3 - bi * hi**3) / 12, (h * b**3 - hi * bi**3) / 12, j,
            2 * t4 * (h - t3) / area, 2 * t3 * (b - t4) / area)


@dataclass(frozen=True)
class PowerLaw:
    """Stiffness factor (f / f_ref_hz)^exponent."""

    exponent: float
    f_ref_hz: float

    def __call__(self, f):
        return (f / self.f_ref_hz) ** self.exponent


@dataclass(frozen=True)
class StandardLinearSolid:
    """Stiffness factor 1 + k_ratio x / (1 + x), x = (f / f_c_hz)²: 1 at f = 0, rising
    through f_c_hz and saturating at 1 + k_ratio (a standard linear solid)."""

    k_ratio: float
    f_c_hz: float

    def __call__(self, f):
        x = (f / self.f_c_hz) ** 2
        return 1 + self.k_ratio * x / (1 + x)


@dataclass
class _Element:
    """Matrices on the 6 basic DoFs of each of its grids; ``kt``: the torsion (GJ) part of
    ``k`` (beams and rods); ``law``: a hashable stiffness factor law(f_hz) (frequency-dependent
    stiffness), None for a constant stiffness."""

    eid: int | None
    pid: int | None
    grids: tuple
    k: np.ndarray
    m: np.ndarray | None = None
    law: object | None = None
    kt: np.ndarray | None = None


def _link(eid, pid, xa, xb, ga, gb, point, k6) -> _Element:
    """Springs k6 (basic axes) on the relative motion of two rigid arms meeting at ``point``."""
    g = np.hstack([-_carry(point - xa), _carry(point - xb)])
    return _Element(eid, pid, (ga, gb), g.T @ np.diag(k6) @ g)


class Truth:
    """Independent FE model for generating measured modes (see the module docstring)."""

    def __init__(self, bulk, refine: int = 2, penalty: float = PENALTY):
        """``bulk``: parsed bulk data; ``refine``: beam sub-elements per CBAR; ``penalty``:
        RBE2 penalty stiffness / the largest diagonal element stiffness."""
        if refine < 1:
            raise ValueError(f"refine must be >= 1, got {refine}")
        unknown = sorted(set(bulk.cards) - _CARDS) + sorted(bulk.unknown)
        if unknown:
            raise ValueError(f"Truth does not support the card(s) {', '.join(unknown)}")
        self.penalty, self.n_removed, self.iterations = penalty, 0, []
        self.xyz = {}
        self.spc = {}  # grid -> set of fixed 0-based components
        for c in bulk["GRID"]:
            if c["CP"] != 0:
                raise ValueError(f"GRID {c.id}: CP {c['CP']} not supported (basic coordinates only)")
            self.xyz[c.id] = np.array([c["X1"], c["X2"], c["X3"]], dtype=np.float64)
            if c["PS"]:
                self.spc.setdefault(c.id, set()).update(_digits(c["PS"]))
        self.grid_ids = np.array(sorted(self.xyz))
        for c in bulk["SPC1"]:
            for g in c["G"]:
                self.spc.setdefault(g, set()).update(_digits(c["C"]))
        for c in bulk["PARAM"]:
            if c["N"] != "COUPMASS" or c["V1"] != 1:
                raise ValueError(f"PARAM {c['N']},{c['V1']} not supported (only COUPMASS,1: consistent mass)")
        self.elements: list[_Element] = []
        self.links: dict[int, tuple] = {}  # RBE2 dependent grid -> (eid, master, 0-based components)
        self._read_elements(bulk, refine)

    @classmethod
    def from_bdf_text(cls, text: str, refine: int = 2, **kw) -> Truth:
        return cls(read_bdf_text(text), refine, **kw)

    @classmethod
    def from_bdf(cls, path, refine: int = 2, **kw) -> Truth:
        return cls(read_bdf(Path(path)), refine, **kw)

    # ------------------------------------------------------------------ model
    def _new_grid(self, xyz) -> int:
        g = max(self.xyz) + 1
        self.xyz[g] = np.asarray(xyz, dtype=np.float64)
        return g

    def _read_elements(self, bulk, refine):
        mats = {}
        for c in bulk["MAT1"]:
            E, G, nu = c["E"], c["G"], c["NU"]
            if sum(x is None for x in (E, G, nu)) > 1:
                raise ValueError(f"MAT1 {c.id}: give two of E, G, NU")
            E = 2 * G * (1 + nu) if E is None else E
            G = E / (2 * (1 + nu)) if G is None else G
            mats[c.id] = (E, G, c["RHO"])
        secs = {}
        for c in bulk["PBAR"]:
            if c["I12"] != 0.0:
                raise ValueError(f"PBAR {c.id}: I12 != 0 not supported")
            secs[c.id] = (c["MID"], tuple(c[k] for k in ("A", "I1", "I2", "J", "K1", "K2", "NSM")))
        for c in bulk["PBARL"]:
            if c["TYPE"] != "BOX":
                raise ValueError(f"PBARL {c.id}: section type {c['TYPE']} not supported (BOX only)")
            secs[c.id] = (c["MID"], _box(c) + (c["NSM"],))
        for c in bulk["CBAR"]:
            self._cbar(c, mats, secs, refine)
        props = {c.id: c for c in bulk["PROD"]}
        for c in bulk["CROD"]:
            p = props[c["PID"]]
            E, G, rho = mats[p["MID"]]
            xa, xb = self.xyz[c["G1"]], self.xyz[c["G2"]]
            L, e = np.linalg.norm(xb - xa), (xb - xa) / np.linalg.norm(xb - xa)
            bar, ee = np.array([[1.0, -1.0], [-1.0, 1.0]]), np.outer(e, e)
            kt = np.kron(bar, sla.block_diag(0 * ee, G * p["J"] / L * ee))
            k = np.kron(bar, sla.block_diag(E * p["A"] / L * ee, 0 * ee)) + kt
            m = np.kron(np.array([[2.0, 1.0], [1.0, 2.0]]) * L / 6 * (rho * p["A"] + p["NSM"]),
                        sla.block_diag(np.eye(3), np.zeros((3, 3))))
            self.elements.append(_Element(c.id, c["PID"], (c["G1"], c["G2"]), k, m, kt=kt))
        bush = {c.id: c["K"] for c in bulk["PBUSH"]}
        for c in bulk["CBUSH"]:
            if c["CID"] != 0:
                raise ValueError(f"CBUSH {c.id}: CID {c['CID']} not supported (CID 0 only)")
            xa, xb = self.xyz[c["GA"]], self.xyz[c["GB"]]
            self.elements.append(_link(c.id, c["PID"], xa, xb, c["GA"], c["GB"], xa + c["S"] * (xb - xa),
                                       bush[c["PID"]]))
        for c in bulk["CELAS2"]:
            ends = [(g, comp) for g, comp in ((c["G1"], c["C1"]), (c["G2"], c["C2"])) if g]
            d = np.zeros(6 * len(ends))
            d[[6 * i + comp - 1 for i, (_, comp) in enumerate(ends)]] = [1.0, -1.0][: len(ends)]
            self.elements.append(_Element(c.id, None, tuple(g for g, _ in ends), c["K"] * np.outer(d, d)))
        for c in bulk["CONM2"]:
            x = np.array([c["X1"], c["X2"], c["X3"]]) - (self.xyz[c["G"]] if c["CID"] == -1 else 0.0)
            i11, i21, i22, i31, i32, i33 = (c[k] for k in ("I11", "I21", "I22", "I31", "I32", "I33"))
            inertia = np.array([[i11, -i21, -i31], [-i21, i22, -i32], [-i31, -i32, i33]])
            self._point_mass(c.id, c["G"], c["M"], x, inertia)
        for c in bulk["RBE2"]:
            for g in c["GM"]:
                if set(self.spc.get(g, ())) & set(_digits(c["CM"])):
                    raise ValueError(f"RBE2 {c.id}: dependent grid {g} has SPC'd dependent components")
                self.links[g] = (c.id, c["GN"], _digits(c["CM"]))

    def _cbar(self, c, mats, secs, refine):
        mid, sec = secs[c["PID"]]
        E, G, rho = mats[mid]
        ga, gb = c["GA"], c["GB"]
        wa = np.array([c["W1A"], c["W2A"], c["W3A"]])
        wb = np.array([c["W1B"], c["W2B"], c["W3B"]])
        v = self.xyz[c["G0"]] - self.xyz[ga] if c["G0"] else np.array([c["X1"], c["X2"], c["X3"]])
        a, b = self.xyz[ga] + wa, self.xyz[gb] + wb
        points = [a + (b - a) * i / refine for i in range(refine + 1)]
        grids = [ga] + [self._new_grid(p) for p in points[1:-1]] + [gb]
        for i in range(refine):
            k, m, kt = _beam(points[i], points[i + 1], v, E, G, rho, sec)
            t = sla.block_diag(_carry(wa if i == 0 else 0 * wa), _carry(wb if i == refine - 1 else 0 * wb))
            self.elements.append(_Element(c.id, c["PID"], (grids[i], grids[i + 1]),
                                          t.T @ k @ t, t.T @ m @ t, kt=t.T @ kt @ t))

    def _point_mass(self, eid, grid, mass, offset, inertia):
        t = _carry(offset)
        m = t.T @ sla.block_diag(mass * np.eye(3), inertia) @ t
        self.elements.append(_Element(eid, None, (grid,), np.zeros((6, 6)), m))

    # ---------------------------------------------------------------- effects
    def _select(self, pids, eids) -> list[_Element]:
        chosen = [e for e in self.elements if (pids and e.pid in pids) or (eids and e.eid in eids)]
        if not chosen:
            raise ValueError(f"no element with pid in {pids} or eid in {eids}")
        return chosen

    def scale(self, pids=(), eids=(), stiffness=0.0, mass=0.0, torsion=0.0) -> Truth:
        """Element stiffness (E and G, or spring k) × (1 + stiffness), its mass (density) × (1 + mass);
        ``torsion``: the torsional stiffness GJ alone of beams and rods × (1 + torsion) as well."""
        chosen = self._select(pids, eids)
        if torsion and not any(e.kt is not None for e in chosen):
            raise ValueError(f"no beam or rod with pid in {pids} or eid in {eids}: no torsion to scale")
        for e in chosen:
            e.k = e.k * (1 + stiffness)
            e.m = None if e.m is None else e.m * (1 + mass)
            if e.kt is not None:
                e.kt = e.kt * (1 + stiffness)
                e.k, e.kt = e.k + torsion * e.kt, e.kt * (1 + torsion)
        return self

    def add_mass(self, node, m, offset=(0.0, 0.0, 0.0), inertia=None) -> Truth:
        """Point mass m (kg) rigidly attached at ``offset`` (m) from grid ``node``; ``inertia``
        (3×3, kg·m², about its centre, basic axes) optional."""
        self._point_mass(None, node, m, np.asarray(offset, dtype=np.float64),
                         np.zeros((3, 3)) if inertia is None else np.asarray(inertia, dtype=np.float64))
        return self

    def add_mass_at(self, xyz, m) -> Truth:
        """Point mass m (kg) at the truth grid at ``xyz`` (m, basic), also an internal grid
        of a refined CBAR (e.g. an element's mid-point for ``refine=2``); none within 1e-9 m:
        ValueError."""
        ids = np.array(list(self.xyz))
        dist = np.linalg.norm(np.array(list(self.xyz.values())) - np.asarray(xyz, dtype=np.float64), axis=1)
        if dist.min() > 1e-9:
            raise ValueError(f"no truth grid within 1e-9 m of {tuple(xyz)} (nearest {dist.min():.3g} m away)")
        return self.add_mass(int(ids[np.argmin(dist)]), m)

    def ground_spring(self, node, k, components=(1, 2, 3)) -> Truth:
        """Springs k (N/m or N·m/rad) from the given components (1..6) of ``node`` to ground."""
        d = np.zeros(6)
        d[[c - 1 for c in components]] = k
        self.elements.append(_Element(None, None, (node,), np.diag(d)))
        return self

    def release_support(self, node, k_trans, k_rot) -> Truth:
        """An SPC'd grid made flexible: its fixed translations get k_trans (N/m), rotations k_rot (N·m/rad)."""
        fixed = sorted(self.spc.pop(node, ()))
        if not fixed:
            raise ValueError(f"grid {node} has no SPC")
        self.ground_spring(node, k_trans, [c + 1 for c in fixed if c < 3])
        return self.ground_spring(node, k_rot, [c + 1 for c in fixed if c >= 3])

    def joint(self, node, k_trans, k_rot, pids=None) -> Truth:
        """A rigid connection at ``node`` made flexible: springs k_trans (N/m) on the 3
        translations and k_rot (N·m/rad) on the 3 rotations, basic axes.

        ``pids=None``: ``node`` is an RBE2-dependent grid; its link becomes the springs
        (components the RBE2 left free stay free). ``pids=(keep, released)``: the elements of
        property ``released`` at ``node`` move to a new coincident grid tied by the springs.
        """
        k6 = np.array([k_trans] * 3 + [k_rot] * 3, dtype=np.float64)
        if pids is None:
            if node not in self.links:
                raise ValueError(f"grid {node} is not an RBE2-dependent grid")
            eid, master, comps = self.links.pop(node)
            k6[[c for c in range(6) if c not in comps]] = 0.0
            xd = self.xyz[node]
            self.elements.append(_link(eid, None, self.xyz[master], xd, master, node, xd, k6))
            return self
        keep, released = pids
        if not any(keep == e.pid and node in e.grids for e in self.elements):
            raise ValueError(f"no element of pid {keep} at grid {node}")
        moved = [e for e in self.elements if e.pid == released and node in e.grids]
        if not moved:
            raise ValueError(f"no element of pid {released} at grid {node}")
        new = self._new_grid(self.xyz[node])
        for e in moved:
            e.grids = tuple(new if g == node else g for g in e.grids)
        self.elements.append(_link(None, None, self.xyz[node], self.xyz[new], node, new, self.xyz[node], k6))
        return self

    def frequency_law(self, law, pids=(), eids=()) -> Truth:
        """Stiffness of the selected elements follows k(f) = k0 law(f) (``law``: hashable
        callable of the frequency in Hz, e.g. :class:`PowerLaw`); each mode solves its
        nonlinear eigenproblem by fixed point (:meth:`modes`)."""
        for e in self._select(pids, eids):
            e.law = law
        return self

    def viscoelastic(self, pids=(), eids=(), exponent=0.0, f_ref_hz=1.0) -> Truth:
        """Stiffness of the selected elements follows k(f) = k0 (f / f_ref_hz)^exponent."""
        return self.frequency_law(PowerLaw(float(exponent), float(f_ref_hz)), pids, eids)

    def standard_linear_solid(self, pids=(), eids=(), k_ratio=0.0, f_c_hz=1.0) -> Truth:
        """Stiffness of the selected elements follows k(f) = k0 (1 + r x / (1 + x)),
        x = (f / f_c_hz)², r = ``k_ratio``: rising through f_c_hz, saturating at k0 (1 + r)."""
        return self.frequency_law(StandardLinearSolid(float(k_ratio), float(f_c_hz)), pids, eids)

    # ----------------------------------------------------------------- solve
    def _rigid_map(self, pos, n):
        """Sparse X with u = X q, where q holds d = u_dep − T u_master for each RBE2-dependent
        component (upstream links substituted first), and the indices of those d."""
        def depth(g):
            return 0 if g not in self.links else 1 + depth(self.links[g][1])

        X, d = sp.identity(n, format="csr"), []
        for dep in sorted(self.links, key=depth):
            _, master, comps = self.links[dep]
            t = _carry(self.xyz[dep] - self.xyz[master])[comps]
            rows = np.repeat([6 * pos[dep] + c for c in comps], 6)
            cols = np.tile(6 * pos[master] + np.arange(6), len(comps))
            X = (sp.identity(n) + sp.coo_matrix((t.ravel(), (rows, cols)), shape=(n, n))) @ X
            d += [6 * pos[dep] + c for c in comps]
        return X.tocsr(), np.array(d, dtype=int)

    def _matrices(self):
        """X restricted to the kept coordinates, the dense kept-coordinate K parts
        {law or None: K} (penalty α on the d coordinates in the None part) and M.
        SPC'd DoFs and coordinates with neither stiffness nor mass are removed."""
        pos = {g: i for i, g in enumerate(sorted(self.xyz))}
        n = 6 * len(pos)
        parts, mass = {}, ([], [], [])
        for e in self.elements:
            idx = np.concatenate([6 * pos[g] + np.arange(6) for g in e.grids])
            r, c = np.meshgrid(idx, idx, indexing="ij")
            for target, values in ((parts.setdefault(e.law, ([], [], [])), e.k), (mass, e.m)):
                if values is not None:
                    for lst, a in zip(target, (r, c, values)):
                        lst.append(a.ravel())
        X, d = self._rigid_map(pos, n)

        def transformed(coo):
            A = sp.coo_matrix((np.concatenate(coo[2]), (np.concatenate(coo[0]), np.concatenate(coo[1]))),
                              shape=(n, n))
            return (X.T @ A @ X).tocsr()

        K = {key: transformed(coo) for key, coo in parts.items()}
        M = transformed(mass)
        alpha = self.penalty * max(np.max(np.diag(e.k)) for e in self.elements)
        penalty = sp.coo_matrix((np.full(len(d), alpha), (d, d)), shape=(n, n))
        K[None] = K[None] + penalty if None in K else penalty.tocsr()
        fixed = np.zeros(n, dtype=bool)
        for g, comps in self.spc.items():
            fixed[[6 * pos[g] + c for c in comps]] = True
        empty = (sum(abs(k.diagonal()) for k in K.values()) == 0) & (M.diagonal() == 0) & ~fixed
        self.n_removed = int(empty.sum())
        keep = np.flatnonzero(~fixed & ~empty)
        return X[:, keep], {key: k[keep][:, keep].toarray() for key, k in K.items()}, M[keep][:, keep].toarray()

    @staticmethod
    def _eig(K, M, count):
        """Lowest ``count`` eigenpairs: eigh(M, K + σM) for the largest μ, λ = 1/μ − σ;
        shapes mass-normalised."""
        n = len(K)
        with threadpool_limits(1):  # small dense solves: faster on one thread, no thrashing beside other jobs
            mu, phi = sla.eigh(M, K + SIGMA * M, subset_by_index=[n - count, n - 1])
        return 1 / mu[::-1] - SIGMA, phi[:, ::-1] / np.sqrt(mu[::-1])

    @staticmethod
    def _follow(stiffness, M, lam, phi, f):
        """Cheap fixed-point steps on one mode: at f, of the 3 eigenpairs of (K(f), M) nearest
        λ (sparse shift-invert) the one most like the last shape (MAC); returns f and the
        number of steps (at most 20)."""
        for count in range(1, 21):
            if lam <= 0:
                return f, count - 1
            w, v = spla.eigsh(stiffness(f), k=3, M=M, sigma=0.999 * lam)
            j = np.argmax(np.abs(v.T @ (M @ phi)) / np.sqrt(np.sum(v * (M @ v), axis=0)))
            lam, phi, f_old, f = w[j], v[:, j], f, np.sqrt(max(w[j], 0.0)) / (2 * np.pi)
            if abs(f - f_old) <= VISCO_RTOL * f:
                break
        return f, count

    def modes(self, n: int, skip: int = 0):
        """Frequencies (Hz, (n,)) and mass-normalised shapes ((len(grid_ids), 6, n): T1..R3 in
        basic axes at the original grids ``grid_ids``) of modes skip+1 .. skip+n.

        With frequency-dependent elements each mode i solves f_i = f_i(K(f_i)) by fixed-point
        iteration to ``VISCO_RTOL`` (skip the rigid-body modes): sparse steps following the
        mode (:meth:`_follow`), then dense solves of the lowest skip+i+1 modes until one moves f
        by at most VISCO_RTOL (its mode skip+i+1 is the answer). The step counts of both are
        left in ``self.iterations``.
        """
        X, parts, M = self._matrices()
        fixed = parts.pop(None)
        sparse = (sp.csc_matrix(fixed), {law: sp.csc_matrix(k) for law, k in parts.items()}, sp.csc_matrix(M))

        def stiffness(f, dense=True):
            k0, laws = (fixed, parts) if dense else sparse[:2]
            return k0 + sum(law(f) * k for law, k in laws.items())

        lam, phi = self._eig(fixed + sum(parts.values()), M, skip + n)  # plain model: k = k0
        lam, phi = lam[skip:], phi[:, skip:]
        self.iterations = []
        for i in range(n if parts else 0):
            f, count = self._follow(lambda f: stiffness(f, dense=False), sparse[2], lam[i], phi[:, i],
                                    np.sqrt(max(lam[i], 0.0)) / (2 * np.pi))
            while True:
                lam_i, phi_i = self._eig(stiffness(f), M, skip + i + 1)
                f_new, count = np.sqrt(lam_i[-1]) / (2 * np.pi), count + 1
                if abs(f_new - f) <= VISCO_RTOL * f_new:
                    break
                f = f_new
            lam[i], phi[:, i] = lam_i[-1], phi_i[:, -1]
            self.iterations.append(count)
        pos = {g: i for i, g in enumerate(sorted(self.xyz))}
        shapes = (X @ phi).reshape(-1, 6, n)[[pos[g] for g in self.grid_ids]]
        return np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi), shapes

    def at(self, sensors: Sensors, shapes) -> np.ndarray:
        """Shapes from :meth:`modes` read at the sensors: d · u (or d · θ), (n_sensors, n)."""
        row = {g: i for i, g in enumerate(self.grid_ids)}
        missing = sorted({int(g) for g in sensors.nodes} - set(row))
        if missing:
            raise ValueError(f"sensor grids {missing} are not grids of the model")
        return np.stack([d @ shapes[row[int(g)], 3 * rot: 3 * rot + 3] for g, d, rot
                         in zip(sensors.nodes, sensors.directions, sensors.rotational.astype(int))])

    def measure(self, sensors: Sensors, n_modes: int, noise_freq=0.002, noise_shape=0.01, seed=0,
                skip=0, damping=None, noise_damping=0.0) -> ModalData:
        """Modes skip+1 .. skip+n_modes at the sensors with multiplicative Gaussian noise:
        f (1 + noise_freq N(0,1)), each shape value (1 + noise_shape N(0,1)); largest
        shape value positive. ``damping``: a uniform viscous ratio ζ of every mode, measured
        as |ζ (1 + noise_damping N(0,1))| (drawn after the others: same f and shapes as without)."""
        f, shapes = self.modes(n_modes, skip)
        phi = self.at(sensors, shapes)
        phi = phi * np.sign(phi[np.argmax(np.abs(phi), axis=0), np.arange(n_modes)])
        rng = np.random.default_rng(seed)
        f = f * (1 + noise_freq * rng.standard_normal(f.shape))
        phi = phi * (1 + noise_shape * rng.standard_normal(phi.shape))
        zeta = None if damping is None else np.abs(damping * (1 + noise_damping * rng.standard_normal(f.shape)))
        return ModalData(f, phi, sensors, damping_ratios=zeta)
