"""The stringer-stiffened CFRP panel of thesis §5.3 and its delamination, located by damping.

**The panel** (thesis §5.3.1, §5.3.2, Table 5.4), :func:`panel_bdf`: a base plate of
0.500 × 0.400 m in the x–y plane (z = 0) with two blade stringers 0.040 m high on its
upper side (z from 0 to 0.040), running along x at y = 0.130 and y = 0.270; the stringer
grids along the foot are the plate's grids. All CQUAD4 (with 10 mm elements 50 × 40 =
2,000 in the plate and 2 × 50 × 4 = 400 in the stringers: the thesis' 2,400), clamped
(SPC1 123456) along the short side x = 0, plate and stringer grids. Material as MAT8
after Table 5.4: E1 = E2 = 54 GPa, G12 = 5 GPa, G1Z = G2Z = 2 GPa, ρ = 1,460 kg/m³;
NU12 is not in the table: 0.05 is taken (a balanced woven fabric, whose in-plane
Poisson ratio is small; an assumption of this model). Laminate: PCOMP of 18 fabric
plies (CCC 460), 4.0 mm in all, written as LAM = SYM with 9 plies of 4.0/18 mm at 0°;
the panel then weighs 1.40 kg, as the thesis says ("approximately 1.4 kg"). PARAM
COUPMASS 1 (consistent mass).

The piezoelectric actuator/sensor pair (§5.3.1): 30 mm (x) × 50 mm (y) patches of PIC 151
0.2 mm thick, the actuator on the top surface and the sensor on the bottom, between the
stringers. The thesis gives no co-ordinates; here the patch is centred at x = 0.355,
y = 0.205 (:data:`PIEZO_CENTRE`), so that its edges x = 0.340, 0.370 and y = 0.180, 0.230
are grid lines of the 10 mm mesh (every mesh here puts grid lines on the patch edges and
on the stringers, dividing the spans between them as evenly as the element size allows).
Its elements have their own PCOMP: the 18 CFRP plies with a 0.2 mm PZT ply below and
above (written LAM = SYM: PZT, then 9 CFRP plies). PIC 151 as MAT1 from the PI Ceramic
material data sheet ("Piezo Material Data", PIC151 column): ρ = 7.80 g/cm³ and the
elastic compliance s11^E = 15.0·10⁻¹² m²/N, so E = 1/s11^E = 66.7 GPa; ν = 0.34 (the
value PI Ceramic gives for its PZT materials). Electrodes, glass-fibre covers and
adhesive are left out.

**The delamination** (§5.3.2.1): ``panel_bdf(damage=(x, y, radius))`` puts the base-plate
elements whose centres lie within ``radius`` of (x, y, 0) on their own PCOMP, whose CFRP
plies are a MAT8 with G1Z and G2Z reduced by 90 % (the thesis' delamination model). This
is how the "measured" damaged structure is made: a model of its own with its own
material card, not the damage model of the localisation scan.

**The damage case** (§5.3.5; :func:`run`). On a coarse panel (25 mm elements, 400 CQUAD4,
2,520 DoFs: the dense eigensolver takes about 2 s on two cores) the "measured" healthy and
damaged modes are simulated from modal values directly, not from FRFs (a stepped-sine
sweep of the 2,520-DoF model over 40 Hz – 1.28 kHz would need a complex solve per line).
Damping: Rayleigh, ζ = 0.25 % at the first and the last mode of the band, which gives a
mean of 0.17 % over the selected modes, near the 0.16 % measured on the panel (§5.3.2.1,
footnote 7); in the damaged structure also a hysteretic loss factor :data:`TRUE_LOSS` on
the transverse-shear stiffness of the delaminated elements (their own, reduced, G1Z and
G2Z): friction between the separated plies (§3.3.1). The damaged structure's poles come
from the complex eigenproblem in the basis of its lowest :data:`N_BASIS` real modes (the
non-proportional damping couples the modes), ζ = −Re p/|p|, f = |p|/2π; the healthy ones
are eq. 3.40 (proportional damping: exact). Of the 22 modes in 40 Hz – 1.28 kHz (the
thesis has 20) the :data:`N_MODES` = 14 with the largest resonance peaks at the piezo
sensor are kept (the thesis identified 14): the sensor signal is the bottom-surface
in-plane strain ∂u_x/∂x + ∂u_y/∂y integrated over the patch (eq. 5.2 with ζ_x = ζ_y), the
actuator the same on the top surface, the peak ``|a·φ||s·φ|/(2ζω²)``. Every measured
damping ratio gets Gaussian noise of relative standard deviation ``noise`` (default
:data:`NOISE`), every frequency 10⁻⁵, independently in each state.

The true delamination is centred at :data:`DAMAGE_CENTRE` (between the stringers, the
clamp and the piezo patch, near the impact of §5.3.4.2 at x = 140 mm) with radius
:data:`DAMAGE_RADIUS`: on the 25 mm mesh a 2 × 2 block of elements, about 50 × 50 mm (the
thesis' delamination was about 25 × 44 mm). The scan
(:func:`identification.localise_damage` with ``part="shear"``) runs over the 320 patches
of base-plate elements within :data:`PATCH_RADIUS` of each base-plate element's centre
(:func:`identification.shell_patches`; an element and its four neighbours, a cross: not
the truth's shape), with a damage model deliberately not the truth: an 80 % (not 90 %)
reduction of the transverse-shear stiffness and a loss factor :data:`MODEL_LOSS` on it
(not :data:`TRUE_LOSS`), by the first-order option (healthy modes, modal strain energy:
about 2 s for the 320 patches, where an eigensolution per patch took 397 s). An 80 % shear
softening is far from first order: the shear strain concentrates in the soft patch, and
the first-order deviations come out 5–20 times smaller than an eigensolution's (median
12), mode by mode; C sees only their direction. Measured with seed 0: the first-order scan
locates the patch at element 147 (C = 0.979), the scan by eigensolutions the one at its
neighbour 146 (C = 0.969), both within one element of the true centre, and the two rank
the 320 patches alike (Spearman 0.95; tests/test_cfrp_panel.py checks five of them).

Usage: ``python -m benchmarks.cfrp_panel [--out DIR] [--seed S] [--noise 0.005] [--control]
[--write-package-data]``; writes ``damage_map.png`` and ``damage_summary.json`` into DIR,
and with ``--write-package-data`` the 10 mm panel to ``updating/data/cfrp_panel.bdf``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

PLATE = (0.500, 0.400)  # m, x by y
STRINGER_Y = (0.130, 0.270)  # m
STRINGER_HEIGHT = 0.040  # m
PIEZO_CENTRE = (0.355, 0.205)  # m
PIEZO_SIZE = (0.030, 0.050)  # m, x by y
N_PLIES, LAMINATE_T = 18, 0.004  # CCC 460 fabric plies, total thickness [m]
PZT_T = 0.0002  # m, each of actuator and sensor
# Table 5.4; NU12 assumed (module docstring)
CFRP = {"E1": 54e9, "E2": 54e9, "NU12": 0.05, "G12": 5e9, "G1Z": 2e9, "G2Z": 2e9, "RHO": 1460.0}
PIC151 = {"E": 1.0 / 15.0e-12, "NU": 0.34, "RHO": 7800.0}  # PI Ceramic data sheet (module docstring)
DELAMINATION = 0.9  # reduction of G1Z and G2Z in a delamination (thesis §5.3.2.1)
# property and material ids
PID_PLATE, PID_STRINGER, PID_PIEZO, PID_DAMAGED, PID_DAMAGED_PIEZO = 1, 2, 3, 4, 5
MID_CFRP, MID_DAMAGED, MID_PZT = 1, 2, 3

# the damage case
COARSE = 0.025  # m, element size of the coarse panel
DAMAGE_CENTRE = (0.150, 0.200)  # m
DAMAGE_RADIUS = 0.030  # m: the elements whose centres lie within it are delaminated
PATCH_RADIUS = 0.030  # m: candidate patches
F_BAND = (40.0, 1280.0)  # Hz
N_MODES = 14
ZETA_BAND = 0.0025  # Rayleigh ζ at the first and the last mode of the band (mean 0.17 %)
TRUE_LOSS = 0.3  # loss factor of the delaminated shear stiffness (truth)
MODEL_REDUCTION, MODEL_LOSS = 0.8, 0.2  # the damage model of the scan
NOISE = 0.005  # relative standard deviation of the measured damping ratios
N_BASIS = 80  # real modes in the basis of the damped poles of the truth


def _divisions(breaks, size: float) -> np.ndarray:
    """Grid co-ordinates through every break, each span cut into max(1, round(span/size))
    equal elements."""
    out = [breaks[0]]
    for a, b in zip(breaks[:-1], breaks[1:]):
        n = max(1, int(np.floor((b - a) / size + 0.5)))
        out += list(a + (b - a) * np.arange(1, n + 1) / n)
    return np.array(out)


def _real(x: float) -> str:
    return repr(float(f"{float(x):.12g}"))


def _mat8(mid: int, g_z: float) -> str:
    c = CFRP
    return (f"MAT8,{mid},{_real(c['E1'])},{_real(c['E2'])},{_real(c['NU12'])},{_real(c['G12'])},"
            f"{_real(g_z)},{_real(g_z)},{_real(c['RHO'])}")


def _pcomp(pid: int, mid: int, piezo: bool) -> list[str]:
    """PCOMP, LAM = SYM, bottom half listed: (PZT 0.2 mm,) 9 CFRP plies of 4.0/18 mm at 0°."""
    plies = ([(MID_PZT, PZT_T)] if piezo else []) + [(mid, LAMINATE_T / N_PLIES)] * (N_PLIES // 2)
    lines = [f"PCOMP,{pid},,,,,,,SYM"]
    for k in range(0, len(plies), 2):
        row = [f"{m},{_real(t)},0.,NO" for m, t in plies[k : k + 2]]
        lines.append("," + ",".join(row))
    return lines


def panel_grid(element_size: float = 0.010) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grid co-ordinates of the panel's mesh lines: x (plate and stringers), y (plate),
    z (stringers), in m."""
    if not 0.0 < element_size <= 0.1:
        raise ValueError(f"element_size must be in (0, 0.1] m, got {element_size!r}")
    (px, py), (sx, sy) = PIEZO_CENTRE, PIEZO_SIZE
    xs = _divisions([0.0, px - sx / 2, px + sx / 2, PLATE[0]], element_size)
    ys = _divisions([0.0, STRINGER_Y[0], py - sy / 2, py + sy / 2, STRINGER_Y[1], PLATE[1]], element_size)
    zs = _divisions([0.0, STRINGER_HEIGHT], element_size)
    return xs, ys, zs


def panel_bdf(element_size: float = 0.010, damage: tuple[float, float, float] | None = None, *,
              clamped: bool = True) -> str:
    """Bulk data (free field, SI) of the stringer-stiffened CFRP panel (module docstring).

    **Arguments:** ``element_size`` [m], the target element edge; ``damage``: ``(x, y,
    radius)`` [m] of a delamination (base-plate elements with centres within ``radius``
    get G1Z, G2Z × 0.1), or None; ``clamped``: the SPC1 along x = 0 (False: free, e.g.
    for the mass by a rigid translation).

    Ids: plate grid ``j·(nx + 1) + i + 1`` (i along x, j along y), plate element
    ``j·nx + i + 1``; stringer k (1, 2) grid ``100000·k + 1000·l + i + 1`` at level l ≥ 1
    above the foot, element ``100000·k + 1000·l + i + 1`` between levels l − 1 and l.
    PIDs: 1 plate, 2 stringers, 3 piezo patch, 4 delaminated plate, 5 delaminated piezo
    patch; MIDs: 1 CFRP, 2 delaminated CFRP, 3 PIC 151.
    """
    xs, ys, zs = panel_grid(element_size)
    nx, ny, nz = len(xs) - 1, len(ys) - 1, len(zs) - 1
    (px, py), (sx, sy) = PIEZO_CENTRE, PIEZO_SIZE
    tol = 1e-9
    lines = [
        "$ Stringer-stiffened CFRP panel after thesis sec. 5.3 (Table 5.4), written by",
        f"$ benchmarks/cfrp_panel.py: panel_bdf(element_size={element_size!r}, damage={damage!r}).",
        f"$ {nx} x {ny} plate CQUAD4 + 2 x {nx} x {nz} stringer CQUAD4; clamped at x = 0: {clamped}.",
        "$ SI units: m, kg, s, N, Pa. Base plate 0.500 x 0.400 m at z = 0; blade stringers 0.040 m",
        "$ high on the upper side at y = 0.130, 0.270. PID 1 plate, 2 stringers, 3 piezo patch",
        "$ (30 x 50 mm at x = 0.355, y = 0.205: PZT 0.2 mm top and bottom), 4/5 delaminated plate/patch.",
        "$ MAT8 1: Table 5.4, NU12 = 0.05 assumed (woven fabric); MAT8 2 (with a damage): G1Z, G2Z - 90 %.",
        "$ MAT1 3: PIC 151 (PI Ceramic data sheet: rho 7.80 g/cm3, E = 1/s11E = 66.7 GPa, nu 0.34).",
        "$ PCOMP: 18 plies of 4.0/18 mm at 0 deg (LAM = SYM, 9 listed).",
        "PARAM,COUPMASS,1",
        _mat8(MID_CFRP, CFRP["G1Z"]),
        f"MAT1,{MID_PZT},{_real(PIC151['E'])},,{_real(PIC151['NU'])},{_real(PIC151['RHO'])}",
    ]
    lines += _pcomp(PID_PLATE, MID_CFRP, False) + _pcomp(PID_STRINGER, MID_CFRP, False)
    lines += _pcomp(PID_PIEZO, MID_CFRP, True)
    if damage is not None:
        lines.append(_mat8(MID_DAMAGED, (1.0 - DELAMINATION) * CFRP["G1Z"]))
        lines += _pcomp(PID_DAMAGED, MID_DAMAGED, False) + _pcomp(PID_DAMAGED_PIEZO, MID_DAMAGED, True)

    def plate_gid(i, j):
        return j * (nx + 1) + i + 1

    feet = [int(np.flatnonzero(np.abs(ys - y) < tol)[0]) for y in STRINGER_Y]
    for j, y in enumerate(ys):
        for i, x in enumerate(xs):
            lines.append(f"GRID,{plate_gid(i, j)},,{_real(x)},{_real(y)},0.")
    for k, j in enumerate(feet, 1):
        for level in range(1, nz + 1):
            for i, x in enumerate(xs):
                lines.append(f"GRID,{100000 * k + 1000 * level + i + 1},,{_real(x)},{_real(ys[j])},{_real(zs[level])}")

    n_damaged = 0
    for j in range(ny):
        for i in range(nx):
            cx, cy = 0.5 * (xs[i] + xs[i + 1]), 0.5 * (ys[j] + ys[j + 1])
            piezo = abs(cx - px) < sx / 2 and abs(cy - py) < sy / 2
            pid = PID_PIEZO if piezo else PID_PLATE
            if damage is not None and np.hypot(cx - damage[0], cy - damage[1]) <= damage[2]:
                pid = PID_DAMAGED_PIEZO if piezo else PID_DAMAGED
                n_damaged += 1
            g = (plate_gid(i, j), plate_gid(i + 1, j), plate_gid(i + 1, j + 1), plate_gid(i, j + 1))
            lines.append(f"CQUAD4,{j * nx + i + 1},{pid},{g[0]},{g[1]},{g[2]},{g[3]}")
    if damage is not None and n_damaged == 0:
        raise ValueError(f"damage {damage!r}: no base-plate element centre lies within the radius")
    for k, j in enumerate(feet, 1):
        def gid(i, level, k=k, j=j):
            return plate_gid(i, j) if level == 0 else 100000 * k + 1000 * level + i + 1

        for level in range(1, nz + 1):
            for i in range(nx):
                g = (gid(i, level - 1), gid(i + 1, level - 1), gid(i + 1, level), gid(i, level))
                lines.append(f"CQUAD4,{100000 * k + 1000 * level + i + 1},{PID_STRINGER},{g[0]},{g[1]},{g[2]},{g[3]}")
    if clamped:
        clamp = [plate_gid(0, j) for j in range(ny + 1)]
        clamp += [100000 * k + 1000 * level + 1 for k in (1, 2) for level in range(1, nz + 1)]
        lines += [f"SPC1,1,123456,{g}" for g in clamp]
    return "\n".join(lines) + "\n"


def package_path() -> Path:
    """``updating/data/cfrp_panel.bdf``: the 10 mm panel shipped as package data."""
    return Path(__file__).resolve().parents[1] / "updating" / "data" / "cfrp_panel.bdf"


def write_package_data(path: Path | None = None) -> Path:
    """Write the 10 mm healthy panel (the thesis' 2,400 CQUAD4) to ``path`` (default
    :func:`package_path`)."""
    path = package_path() if path is None else Path(path)
    path.write_text(
        "$ Package data of jaxfem: the CFRP panel of thesis sec. 5.3, regenerate with\n"
        "$ python -m benchmarks.cfrp_panel --write-package-data\n" + panel_bdf(0.010), encoding="utf-8")
    return path


# ----------------------------------------------------------------------------- damage case


def build(element_size: float = COARSE, damage: tuple[float, float, float] | None = None):
    """The panel as a :class:`jaxfem.Model` (clamped)."""
    import jaxfem
    from jaxfem.io import read_bdf_text

    name = "cfrp_panel" if damage is None else "cfrp_panel_damaged"
    return jaxfem.build_model(read_bdf_text(panel_bdf(element_size, damage), name=name))


def _dof(model, node: int, component: int) -> int:
    hit = np.flatnonzero((model.dofs.labels[:, 0] == node) & (model.dofs.labels[:, 1] == component))
    if len(hit) != 1:
        raise ValueError(f"({node}, {component}) is not a solved DoF")
    return int(hit[0])


def _trapezoid(s: np.ndarray) -> np.ndarray:
    """Trapezoid weights of sorted abscissae (exact for a piecewise-linear integrand)."""
    w = np.zeros(len(s))
    d = np.diff(s)
    w[:-1] += d / 2
    w[1:] += d / 2
    return w


def piezo_vectors(model) -> tuple[np.ndarray, np.ndarray]:
    """(actuator, sensor): row vectors on the solved DoFs giving ∫(∂u_x/∂x + ∂u_y/∂y) dA
    over the piezo patch on its top (actuator) and bottom (sensor) surface, thesis eq. 5.2
    with ζ_x = ζ_y = 1 (m² of strain × area). Surface displacements of the shell:
    ``u_x(z) = u + zθ_y``, ``u_y(z) = v − zθ_x``; by the divergence theorem the area
    integral is a line integral of the edge displacements (trapezoid rule on the edge
    grids, exact for the bilinear CQUAD4)."""
    (px, py), (sx, sy) = PIEZO_CENTRE, PIEZO_SIZE
    x0, x1, y0, y1 = px - sx / 2, px + sx / 2, py - sy / 2, py + sy / 2
    xyz, ids = np.asarray(model.xyz), np.asarray(model.node_ids)
    tol = 1e-9
    on_plate = np.abs(xyz[:, 2]) < tol
    z_surface = LAMINATE_T / 2 + PZT_T
    out = []
    for z in (z_surface, -z_surface):
        b = np.zeros(model.n_dof)
        for axis, (lo, hi), (a, c) in ((0, (x0, x1), (y0, y1)), (1, (y0, y1), (x0, x1))):
            along = 1 - axis
            for edge, sign in ((hi, 1.0), (lo, -1.0)):
                rows = np.flatnonzero(on_plate & (np.abs(xyz[:, axis] - edge) < tol)
                                      & (xyz[:, along] > a - tol) & (xyz[:, along] < c + tol))
                rows = rows[np.argsort(xyz[rows, along])]
                for row, w in zip(rows, _trapezoid(xyz[rows, along])):
                    if axis == 0:  # u_x = u + z θy
                        b[_dof(model, ids[row], 1)] += sign * w
                        b[_dof(model, ids[row], 5)] += sign * w * z
                    else:  # u_y = v − z θx
                        b[_dof(model, ids[row], 2)] += sign * w
                        b[_dof(model, ids[row], 4)] -= sign * w * z
        out.append(b)
    return out[0], out[1]


def _shear_stiffness(model, elements) -> np.ndarray:
    """Dense transverse-shear stiffness of the given shell elements of ``model`` (its own
    material), for the truth's hysteretic loss: the model with A = B = D = 0 (membrane and
    bending factors 0), every other element's stiffness off."""
    import equinox as eqx
    import jax.numpy as jnp

    import jaxfem

    sec = model.shell_sections
    zero = jnp.zeros_like(sec.membrane)
    shear = eqx.tree_at(lambda m: (m.shell_sections.membrane, m.shell_sections.bending), model, (zero, zero))
    mask = jnp.asarray(np.isin(model.quads.ids, np.asarray(elements, np.int64)), dtype=jnp.float64)
    shear = eqx.tree_at(lambda m: m.quads.k_scale, shear, model.quads.k_scale * mask)
    return np.asarray(jaxfem.assemble(shear)[0].todense())


def damped_poles(lam, phi, k_loss, mu: float, kappa: float) -> tuple[np.ndarray, np.ndarray]:
    """Natural frequencies |p|/2π (Hz) and ratios −Re p/|p| of the structure with Rayleigh
    damping μM + κK and the hysteretic loss i·K_loss, from the complex eigenproblem in the
    basis of the real modes (λ, φ mass-normalised): one pole per mode, paired by its
    largest modal co-ordinate."""
    import scipy.linalg as sl

    lam = np.asarray(lam)
    n = len(lam)
    kc = np.diag(lam) + 1j * (phi.T @ k_loss @ phi)
    c = np.diag(mu + kappa * lam)
    a = np.block([[np.zeros((n, n)), np.eye(n)], [-kc, -c]])
    p, v = sl.eig(a)
    up = p.imag > 0
    p, v = p[up], v[:n, up]
    owner = np.argmax(np.abs(v), axis=0)
    if len(set(owner.tolist())) != n:
        raise RuntimeError("damped poles could not be paired one to one with the real modes")
    order = np.argsort(owner)
    p = p[order]
    return np.abs(p) / (2.0 * np.pi), -p.real / np.abs(p)


def simulate(element_size: float = COARSE, damage=(*DAMAGE_CENTRE, DAMAGE_RADIUS), *, loss: float = TRUE_LOSS,
             zeta_band: float = ZETA_BAND, n_modes: int = N_MODES) -> dict:
    """Noise-free "measured" modes of the healthy and the damaged panel (module docstring).

    **Returns:** a dict with the healthy ``model``, ``mode_indices`` (the selected model
    modes), ``healthy_hz``, ``healthy_zeta``, ``damaged_hz``, ``damaged_zeta``,
    ``band_hz`` (all model frequencies in the band), ``mu``, ``kappa``, ``true_elements``
    (the delaminated element ids), ``peaks`` (the sensor's resonance peaks of the
    selected modes, relative to the largest in the band) and ``damaged_shapes`` (the
    damaged structure's real modes paired with the selected ones, solved DoFs).
    """
    import jax.numpy as jnp

    import jaxfem

    model = build(element_size)
    damaged = build(element_size, damage)
    true_elements = np.asarray(damaged.quads.ids)[np.isin(damaged.quads.pids, (PID_DAMAGED, PID_DAMAGED_PIEZO))]
    k_h, m = jaxfem.assemble(model)
    n_basis = min(N_BASIS, model.n_dof)
    lam_h, phi_h = (np.asarray(a) for a in jaxfem.eigh(k_h, m, n_basis))
    f_all = np.sqrt(lam_h) / (2.0 * np.pi)
    band = np.flatnonzero((f_all >= F_BAND[0]) & (f_all <= F_BAND[1]))
    if len(band) < n_modes:
        raise ValueError(f"only {len(band)} modes in {F_BAND} Hz, {n_modes} asked")
    w_band = np.sqrt(lam_h[band])
    mu, kappa = (float(v) for v in jaxfem.rayleigh_coefficients(w_band[0], w_band[-1], zeta_band, zeta_band))
    zeta_h = 0.5 * (mu / np.sqrt(lam_h) + kappa * np.sqrt(lam_h))  # eq. 3.40: proportional, exact
    actuator, sensor = piezo_vectors(model)
    peak = np.abs((actuator @ phi_h[:, band]) * (sensor @ phi_h[:, band])) / (2 * zeta_h[band] * lam_h[band])
    chosen = np.sort(band[np.argsort(-peak)[:n_modes]])

    k_d, _ = jaxfem.assemble(damaged)
    lam_d, phi_d = (np.asarray(a) for a in jaxfem.eigh(k_d, m, n_basis))
    k_loss = loss * _shear_stiffness(damaged, true_elements)
    f_d, z_d = damped_poles(lam_d, phi_d, k_loss, mu, kappa)
    overlap = np.abs(np.asarray(m.matmul(jnp.asarray(phi_h[:, chosen]))).T @ phi_d)  # (selected, basis)
    pair = np.argmax(overlap, axis=1)
    return {
        "model": model,
        "mode_indices": chosen,
        "healthy_hz": f_all[chosen],
        "healthy_zeta": zeta_h[chosen],
        "damaged_hz": f_d[pair],
        "damaged_zeta": z_d[pair],
        "band_hz": f_all[band],
        "mu": mu,
        "kappa": kappa,
        "true_elements": true_elements,
        "peaks": peak[np.searchsorted(band, chosen)] / peak.max(),
        "pairing_overlap": overlap[np.arange(len(chosen)), pair],
        "damaged_shapes": phi_d[:, pair],
    }


def measure(sim: dict, noise: float, seed: int, *, control: bool = False) -> tuple[tuple, tuple]:
    """Noisy measured modes ``((f_h, ζ_h), (f_d, ζ_d))``: relative Gaussian noise ``noise``
    on every damping ratio, 10⁻⁵ on every frequency, independent per state. ``control``:
    the "damaged" state is the healthy structure measured again (only noise)."""
    rng = np.random.default_rng(seed)

    def noisy(f, z):
        e = rng.standard_normal((2, len(f)))
        return f * (1.0 + 1e-5 * e[0]), z * (1.0 + noise * e[1])

    healthy = noisy(sim["healthy_hz"], sim["healthy_zeta"])
    if control:
        damaged = noisy(sim["healthy_hz"], sim["healthy_zeta"])
    else:
        damaged = noisy(sim["damaged_hz"], sim["damaged_zeta"])
    return healthy, damaged


def modal_change(noise_f: float = 1e-4, noise_s: float = 0.01, seed: int = 0, *, control: bool = False,
                 n_modes: int = N_MODES, element_size: float = COARSE):
    """The delamination as an engineer would measure it with a scanning vibrometer, for
    :func:`updating.diagnose` on the change between two states (``--reference``).

    Truth: the panel meshed at half the model's ``element_size`` (12.5 mm for the default
    :data:`COARSE`; mesh alone moves the frequencies by 0.2–4 %), healthy and with the
    delamination of :data:`DAMAGE_CENTRE`, :data:`DAMAGE_RADIUS` (its own PCOMP, G1Z and G2Z −90 %). Test:
    out-of-plane (component 3) at every grid of the coarse model's base plate off the clamp
    that is a grid of the truth too; the ``n_modes`` modes in :data:`F_BAND` with the
    largest piezo sensor peaks of the healthy truth (as :func:`simulate`); relative noise
    ``noise_f`` on frequencies and ``noise_s`` on shape components, independent per state
    (``control``: the healthy truth measured twice).

    **Returns:** ``(model, reference, test, true_elements)``: the coarse healthy model, the
    healthy and the damaged :class:`identification.ModalData` (grid ids of the model), and
    the model's base-plate elements whose centres lie within :data:`DAMAGE_RADIUS` of the
    centre.
    """
    import jaxfem
    from identification import ModalData, Sensors, observation_matrix
    from identification._patches import shell_centres

    model = build(element_size)
    truth = [build(element_size / 2), build(element_size / 2, (*DAMAGE_CENTRE, DAMAGE_RADIUS))]
    xyz, ids = np.asarray(model.xyz), np.asarray(model.node_ids)
    t_xyz = np.asarray(truth[0].xyz)
    plate = np.flatnonzero((np.abs(xyz[:, 2]) < 1e-9) & (xyz[:, 0] > 1e-9))
    dist = np.linalg.norm(xyz[plate, None, :] - t_xyz[None, :, :], axis=2)
    same = dist.min(axis=1) < 1e-3 * element_size
    grids, t_grids = ids[plate[same]], np.asarray(truth[0].node_ids)[dist[same].argmin(axis=1)]
    components = np.full(len(grids), 3)
    rng = np.random.default_rng(seed)
    states, chosen = [], None
    for i, t in enumerate(truth[:1] * 2 if control else truth):
        lam, phi = jaxfem.modes(t, 40)
        f = np.asarray(jaxfem.frequencies_hz(lam))
        if chosen is None:
            band = np.flatnonzero((f >= F_BAND[0]) & (f <= F_BAND[1]))
            actuator, sensor = piezo_vectors(t)
            peak = np.abs((actuator @ np.asarray(phi)[:, band]) * (sensor @ np.asarray(phi)[:, band])) / np.asarray(lam)[band]
            chosen = np.sort(band[np.argsort(-peak)[:n_modes]])
            picked = chosen
        else:  # the damaged modes nearest in shape to the chosen healthy ones
            shapes0 = states[0][1] / np.linalg.norm(states[0][1], axis=0)
            C, _ = observation_matrix(t, Sensors.from_components(t_grids, components))
            cand = np.asarray(C @ phi)
            cand = cand / np.linalg.norm(cand, axis=0)
            picked = np.abs(shapes0.T @ cand).argmax(axis=1)
        C, _ = observation_matrix(t, Sensors.from_components(t_grids, components))
        shapes = np.asarray(C @ phi)[:, picked]
        f = f[picked] * (1 + noise_f * rng.standard_normal(len(picked)))
        states.append((f, shapes * (1 + noise_s * rng.standard_normal(shapes.shape))))
    sensors = Sensors.from_components(grids, components)
    e_ids, centres, _ = shell_centres(model)
    on_plate = np.abs(centres[:, 2]) < 1e-9
    true = e_ids[on_plate & (np.hypot(centres[:, 0] - DAMAGE_CENTRE[0], centres[:, 1] - DAMAGE_CENTRE[1])
                             <= DAMAGE_RADIUS)]
    return model, ModalData(*states[0], sensors), ModalData(*states[1], sensors), true


def scan(sim: dict, healthy, damaged, *, first_order: bool = True, candidates=None):
    """The localisation (module docstring): ``(DamageScan, ShellPatches)``; ``candidates``
    restricts the scan to those patch indices (the patches returned are then the subset)."""
    from identification import ShellPatches, localise_damage, shell_patches

    patches = shell_patches(sim["model"], PATCH_RADIUS, pids=(PID_PLATE, PID_PIEZO))
    if candidates is not None:
        keep = np.asarray(candidates, dtype=np.int64)
        patches = ShellPatches(tuple(patches.groups[i] for i in keep), patches.centres[keep], patches.anchors[keep],
                               patches.at, patches.radius)
    result = localise_damage(sim["model"], healthy, damaged, stiffness_reduction=MODEL_REDUCTION,
                             loss_factor=MODEL_LOSS, candidates=patches.groups, mode_indices=sim["mode_indices"],
                             part="shear", first_order=first_order)
    return result, patches


def run(seed: int = 0, noise: float = NOISE, out: Path | None = None, *, control: bool = False,
        sim: dict | None = None) -> dict:
    """The whole damage case; returns the summary (and writes the map and the JSON when
    ``out`` is given). ``control``: healthy against healthy (only noise); ``sim``: the
    result of :func:`simulate`, when already at hand."""
    from identification import plot_shell_damage_map

    t0 = time.perf_counter()
    sim = simulate() if sim is None else sim
    t1 = time.perf_counter()
    healthy, damaged = measure(sim, noise, seed, control=control)
    result, patches = scan(sim, healthy, damaged)
    t2 = time.perf_counter()
    true_centre = np.array([*DAMAGE_CENTRE, 0.0])
    best = result.best
    distance = np.linalg.norm(patches.centres - true_centre, axis=1)
    near = distance <= COARSE
    model = sim["model"]
    summary = {
        "structure": f"CFRP panel after thesis sec. 5.3, element size {COARSE} m: {len(model.quads.ids)} CQUAD4, "
                     f"{model.n_dof} DoFs",
        "band_hz": list(F_BAND),
        "model_hz_in_band": sim["band_hz"].tolist(),
        "mode_indices": sim["mode_indices"].tolist(),
        "sensor_peaks_relative": sim["peaks"].tolist(),
        "measured_from": "modal values (no FRFs): healthy by eq. 3.40, damaged by the complex eigenproblem in "
                         f"{N_BASIS} real modes; relative noise on damping {noise}, on frequency 1e-5",
        "noise_damping_rel": noise,
        "seed": seed,
        "control": control,
        "rayleigh_true": {"mu": sim["mu"], "kappa": sim["kappa"], "zeta_at_band_ends": ZETA_BAND},
        "rayleigh_fitted": {"mu": result.mu, "kappa": result.kappa},
        "true_damage": {"centre_m": list(DAMAGE_CENTRE), "radius_m": DAMAGE_RADIUS,
                        "elements": sim["true_elements"].tolist(), "shear_reduction": DELAMINATION,
                        "loss_factor_on_damaged_shear": TRUE_LOSS},
        "model_damage": {"part": "shear", "stiffness_reduction": MODEL_REDUCTION, "loss_factor": MODEL_LOSS,
                         "patch_radius_m": PATCH_RADIUS, "first_order": True},
        "healthy_hz": healthy[0].tolist(),
        "damaged_hz": damaged[0].tolist(),
        "healthy_zeta": healthy[1].tolist(),
        "damaged_zeta": damaged[1].tolist(),
        "measured_deviation": result.measured.tolist(),
        "n_candidates": len(patches.groups),
        "located_patch_anchor_element": int(patches.anchors[best]),
        "located_patch_elements": list(result.best_group),
        "located_centre_m": patches.centres[best].tolist(),
        "distance_to_true_centre_m": float(distance[best]),
        "C_located": float(result.correlation[best]),
        "C_median": float(np.median(result.correlation)),
        "C_best_within_one_element_of_truth": float(result.correlation[near].max()),
        "ranking": [[int(patches.anchors[i]), float(result.correlation[i])]
                    for i in np.argsort(-result.correlation)[:8]],
        "seconds_simulation": t1 - t0,
        "seconds_scan": t2 - t1,
    }
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        what = "control (healthy vs healthy)" if control else f"true delamination (red), noise {noise:g}"
        plot_shell_damage_map(model, result, patches, out / "damage_map.png", true_elements=sim["true_elements"],
                              title=f"CFRP panel, C over {len(patches.groups)} patches, eq. 3.45: {what}")
        (out / "damage_summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=None, help="directory for damage_map.png, damage_summary.json")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--noise", type=float, default=NOISE, help="relative noise on the measured damping")
    parser.add_argument("--control", action="store_true", help="healthy against healthy (only noise)")
    parser.add_argument("--write-package-data", action="store_true",
                        help="also write the 10 mm panel to updating/data/cfrp_panel.bdf")
    args = parser.parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", True)
    if args.write_package_data:
        print(f"wrote {write_package_data()}")
    s = run(seed=args.seed, noise=args.noise, out=args.out, control=args.control)
    print(f"{s['structure']}; {len(s['model_hz_in_band'])} modes in {F_BAND[0]:g}-{F_BAND[1]:g} Hz, "
          f"{len(s['mode_indices'])} used")
    print(f"located patch at {np.round(s['located_centre_m'], 4).tolist()} m, "
          f"{1000 * s['distance_to_true_centre_m']:.1f} mm from the true centre; C = {s['C_located']:.3f} "
          f"(median {s['C_median']:.3f}); simulation {s['seconds_simulation']:.0f} s, scan {s['seconds_scan']:.0f} s")
    for anchor, c in s["ranking"][:5]:
        print(f"  patch at element {anchor:5d}  C = {c:.4f}")


if __name__ == "__main__":
    main()
