"""A generated stiffened fuselage barrel of a requested size, for build, assembly and updating benchmarks.

**The barrel** (:func:`barrel_bdf`): a cylinder of radius :data:`RADIUS` = 1 m along x
(y horizontal, z up), skin CQUAD4 of aluminium (MAT1 E = 70 GPa, ν = 0.33, ρ = 2,700
kg/m³; PSHELL t = 1.6 mm, transverse shear MID3), every grid with its six DoFs, nothing
constrained. Stiffened by :data:`N_STRINGERS` CBAR stringers along grid lines and CBAR
ring frames every :data:`FRAME_PITCH` (nearest station; also at both ends), both sharing
the skin grids (no offsets; the orientation vector is radial). A floor at z = −0.3 R
spans the cylinder horizontally: CQUAD4 sandwich (PSHELL: 1 mm of aluminium faces for
membrane and mass, 12I/T³ = 270.8 for the bending of 0.5 mm faces 9.5 mm apart, NSM 1.5
kg/m² for core and covering) on its own grids, whose edge grids are the skin grids at
the two floor angles (the stringer pattern is laid out so that those are stringer lines),
with CBAR floor cross-beams on the frame stations, each propped by two CROD struts
(tubes) from its outer seat rails down to the nearest lower-lobe skin grid of its frame.
Payload: CONM2 on the four seat-rail grid lines of the floor (y nearest ±0.25 R, ±0.6 R)
at the frame stations (seat tracks pass their loads to the floor beams; tracks are not
modelled), :data:`PAYLOAD` kg per m of barrel in all, at the floor grids
(:data:`PAYLOAD_HEIGHT` = 0: with the CG 0.3 m above the floor the seat masses rocked on
the floor in local modes from about 12 Hz, below every barrel mode). One barrel-section joint: at the
frame station nearest mid-length, every grid of that station (skin ring
and floor) is doubled; the aft side uses the copies, and each coincident pair is joined
by a CBUSH (PBUSH :data:`PID_JOINT`, stiffness per grid = per-length values
:data:`JOINT_K` times the mean element width). Suspension: grounded CELAS1 springs
(PELAS :data:`PID_SUSPENSION`) in x, y, z at four crown-shoulder grids (θ = 90° ± 30°) of
the frames nearest 0.2 L and 0.8 L, stiffness set so that a rigid translation of the
whole mass on the 12 springs has :data:`SUSPENSION_HZ`; K is not singular and the six
suspension modes lie well below the first elastic one. PARAM COUPMASS 1.

**Size.** ``barrel_bdf(n_dof)`` meets the requested number of solved DoFs (6 per grid,
no constraints) within a few per cent (:func:`barrel_layout`): each of the 30 stringer
bays is cut into ``m`` elements (18 bays in the upper lobe, 12 in the lower, as equal as
the floor angles allow), the axial element length is the mean circumferential one (near-
square elements), ``m`` is chosen so that the length comes nearest to :data:`LENGTH`
(log scale), then the number of stations (hence the length) and ±2 floor elements across
the width are chosen to meet ``n_dof``. Smallest barrel: about 1,800 DoFs.

**Property groups** (:func:`parameter_groups`): the skin is 12 PSHELL ids, six axial bays
(equal lengths by station) in each lobe: upper (cabin, above the floor) 101–106, lower
(cargo) 111–116, each with its own MAT1 (id = pid); frames 201, stringers 301 (PBAR),
floor 401 (PSHELL), floor beams 402 (PBAR) and struts 403 (PROD, the floor beams' MAT1),
joint 501 (PBUSH), suspension 601 (PELAS).
``parameter_groups(20)``: ``E`` of each of the 12 skin bays, then :data:`OTHER_GROUPS`:
frame ``E`` and ``nsm`` (clips, insulation and systems carried by the frames), stringer
``E``, floor ``bending`` and ``nsm``, floor beams' and struts' ``stiffness``, joint ``k``, suspension
``k``; fewer groups merge the skin bays (``parameter_groups(10)``: upper and lower lobe).

**Damage / truth models**: ``barrel_bdf(n_dof, damage={"skin U3": -0.3, "joint k": -0.5})``
writes the same mesh with the named groups' values changed by the relative amounts, as
the parameters of :func:`parameter_groups` would (value₀·(1 + α)); keys are the names of
``parameter_groups(20)``.

Usage: ``python -m benchmarks.fuselage --n-dof 100000 [--json OUT] [--modes 20]``: times
the text generation, ``read_bdf_text``, ``build_model`` and ``assemble`` (eager, blocks
ready) at that size in one process; with ``--modes`` also the lowest modes by SciPy's
shift-invert Lanczos.

**Measured** (2-core x86-64, jax 0.10.2, one process per size; peak RSS by
``/usr/bin/time -v``):

| requested | n_dof | CQUAD4 / CBAR | text | read_bdf_text | build_model | assemble (eager) | peak RSS |
|---|---|---|---|---|---|---|---|
| 33,000 | 32,850 | 5,396 / 3,346 | 0.01 s | 0.24 s | 10.3 s | 0.7–0.8 s | 1.5 GB |
| 100,000 | 100,062 | 16,478 / 5,058 | 0.02 s | 0.74 s | 12.5 s | 2.7–2.8 s | 2.0 GB |
| 300,000 | 299,754 | 49,594 / 8,718 | 0.06 s | 1.98 s | 18.8 s | 8.2–8.3 s | 3.9 GB |

``build_model`` is mostly :func:`jaxfem._assembly.finalize_dofs`, whose eager assembly
compiles about 450 small XLA programs (about 8 s, once per process and size) and then
runs them. Modes of the 32,850-DoF barrel: six suspension modes 0.55–2.7 Hz; elastic
from 25.7 Hz: ovalisation and bending (n = 2, 3) to 63 Hz, then these interleaved with
the floor bouncing on the lower frames (floor and keel together, 4 to 14 axial
half-waves, the last alternating frame by frame) from 66 Hz; none of the lowest 24
elastic modes is a skin-panel mode (each moves at least 9 % of the grids, participation
ratio of the translations).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# geometry [m]
RADIUS = 1.0
LENGTH = 6.0  # preferred barrel length; the requested n_dof sets the actual one
FLOOR_Z = -0.3  # floor height, fraction of the radius
N_STRINGERS = 30  # stringer lines, floor edges among them
FRAME_PITCH = 0.5  # m
SEAT_RAILS = (0.6, 0.25, -0.25, -0.6)  # y of the seat rails, fraction of the radius
PAYLOAD = 50.0  # kg per m of barrel, on the seat rails
PAYLOAD_HEIGHT = 0.0  # m above the floor (CONM2 offset)
SUSPENSION_HZ = 1.5  # rigid translation on the 12 suspension springs
JOINT_K = (2.0e9, 2.0e9, 2.0e9, 2.0e5, 2.0e5, 2.0e5)  # per m of joint line: N/m², N·m/rad/m

# materials: (E [Pa], nu, rho [kg/m³])
SKIN_MAT = (70.0e9, 0.33, 2700.0)  # 2024-T3 clad sheet
FRAME_MAT = (72.0e9, 0.33, 2800.0)  # 7075 sections
FLOOR_MAT = (70.0e9, 0.33, 2700.0)
SKIN_T = 0.0016
FLOOR_T, FLOOR_BENDING, FLOOR_NSM = 0.001, 12 * 2 * 0.0005 * 0.00475**2 / 0.001**3, 1.5  # sandwich, see docstring
# PBAR sections: A [m²], I1 (bending in the plane of the axis and the radial/vertical v), I2, J [m⁴], NSM [kg/m]
FRAME_SECTION = (1.76e-4, 1.0e-7, 1.7e-8, 1.5e-10, 0.25)  # Z 60 x 25 x 1.6 mm
STRINGER_SECTION = (6.0e-5, 4.0e-9, 1.5e-9, 3.0e-11, 0.0)  # Z 25 mm
FLOOR_BEAM_SECTION = (5.9e-4, 2.1e-6, 6.3e-8, 1.6e-9, 0.0)  # I 150 x 50 mm, 3 mm flanges, 2 mm web
STRUT_SECTION = (1.34e-4, 2.7e-8)  # PROD A [m²], J [m⁴]: tube 30 x 1.5 mm
STRUT_Y = 0.6  # struts from the seat rails nearest y = ±0.6 R, fraction of the radius

# property ids (= material ids where a property has its own material)
N_BAYS = 6  # axial skin bays per lobe
PID_SKIN_UPPER, PID_SKIN_LOWER = 101, 111  # + bay index 0..5
PID_FRAME, PID_STRINGER, PID_FLOOR, PID_FLOOR_BEAM, PID_STRUT = 201, 301, 401, 402, 403
PID_JOINT, PID_SUSPENSION = 501, 601
MID_FRAME, MID_STRINGER, MID_FLOOR, MID_FLOOR_BEAM = 201, 301, 401, 402
SKIN_PIDS = (tuple(range(PID_SKIN_UPPER, PID_SKIN_UPPER + N_BAYS))
             + tuple(range(PID_SKIN_LOWER, PID_SKIN_LOWER + N_BAYS)))
# (name, kind, pids) of the groups other than the skin
OTHER_GROUPS = (
    ("frames E", "E", (PID_FRAME,)),
    ("frames nsm", "nsm", (PID_FRAME,)),
    ("stringers E", "E", (PID_STRINGER,)),
    ("floor bending", "bending", (PID_FLOOR,)),
    ("floor nsm", "nsm", (PID_FLOOR,)),
    ("floor beams stiffness", "stiffness", (PID_FLOOR_BEAM, PID_STRUT)),
    ("joint k", "k", (PID_JOINT,)),
    ("suspension k", "k", (PID_SUSPENSION,)),
)
# id bases: grid/element = base + 1000·station + index along the station (from 1)
SKIN, FLOOR, JOINT_SKIN, JOINT_FLOOR = 1_000_000, 2_000_000, 3_000_000, 4_000_000
FRAMES, STRINGERS, FLOOR_BEAMS, STRUTS = 5_000_000, 6_000_000, 7_000_000, 7_500_000
BUSHES, SPRINGS, MASSES = 8_000_000, 8_100_000, 9_000_000


@dataclass(frozen=True)
class BarrelLayout:
    """The mesh of a barrel (:func:`barrel_layout`); stations i = 0..na along x.

    ``theta`` (nc,): skin grid angles [rad] from +y towards +z, j = 0 the right floor
    edge, ``n_upper`` the left one; ``floor_y`` (nf + 2,): floor grid y, both edges
    included (the skin grids j = 0 and ``n_upper``); ``frames``: station indices of the
    frames; ``joint``: the station of the barrel-section joint; ``rails``: floor grid
    indices l (1..nf) of the seat rails; ``struts``: (floor grid index l, skin angle index
    j) of the two struts at each frame; ``bay``: skin bay 0..5 of each element column.
    """

    m: int
    theta: np.ndarray
    n_upper: int
    x: np.ndarray
    floor_y: np.ndarray
    frames: tuple[int, ...]
    joint: int
    rails: tuple[int, ...]
    struts: tuple[tuple[int, int], ...]
    bay: np.ndarray

    @property
    def nc(self) -> int:
        return len(self.theta)

    @property
    def na(self) -> int:
        return len(self.x) - 1

    @property
    def nf(self) -> int:
        return len(self.floor_y) - 2

    @property
    def length(self) -> float:
        return float(self.x[-1])

    @property
    def n_grids(self) -> int:
        """Skin and floor grids at every station, and the joint's copies of one station."""
        return (self.na + 2) * (self.nc + self.nf)

    @property
    def n_dof(self) -> int:
        return 6 * self.n_grids

    @property
    def stringers(self) -> np.ndarray:
        """Circumferential grid indices of the stringer lines."""
        return np.arange(0, self.nc, self.m)


def _floor_angle() -> float:
    return math.asin(FLOOR_Z)  # right floor edge, below +y


def _angles(m: int) -> tuple[np.ndarray, int]:
    """Skin grid angles: upper arc from the right floor edge over the crown to the left one in
    n_u·m equal steps, lower arc back in n_l·m; n_u + n_l = N_STRINGERS."""
    a = _floor_angle()
    upper = math.pi - 2.0 * a  # rad
    n_u = round(N_STRINGERS * upper / (2.0 * math.pi))
    n_l = N_STRINGERS - n_u
    up = a + upper * np.arange(n_u * m) / (n_u * m)
    low = (math.pi - a) + (2.0 * math.pi - upper) * np.arange(n_l * m) / (n_l * m)
    return np.concatenate([up, low]), n_u * m


def _candidate(m: int, n_dof: int, nf_shift: int) -> tuple[int, int] | None:
    """(na, nf) nearest to ``n_dof`` for m elements per stringer bay and the floor cut into
    round(width / a) + nf_shift elements; None when too short or no floor grid."""
    nc = N_STRINGERS * m
    a = 2.0 * math.pi * RADIUS / nc
    width = 2.0 * RADIUS * math.cos(_floor_angle())
    nf = round(width / a) + nf_shift - 1
    if nf < 3:
        return None
    na = round(n_dof / (6.0 * (nc + nf))) - 2
    if na < N_BAYS:
        return None
    return na, nf


def barrel_layout(n_dof: int) -> BarrelLayout:
    """The mesh of the barrel with about ``n_dof`` solved DoFs (module docstring, *Size*).

    **Raises:** ``ValueError`` when ``n_dof`` is below the smallest barrel (6 stations of
    one element per stringer bay) or so large that a station holds more than 999 grids.
    """
    n_dof = int(n_dof)
    best = None
    for m in range(1, 34):
        options = [(c, s) for s in (0, -1, 1, -2, 2) if (c := _candidate(m, n_dof, s)) is not None]
        if not options:
            continue
        na, nf = min(options, key=lambda o: (abs(6 * (o[0][0] + 2) * (N_STRINGERS * m + o[0][1]) - n_dof),
                                             abs(o[1])))[0]
        length = na * 2.0 * math.pi * RADIUS / (N_STRINGERS * m)
        score = abs(math.log(length / LENGTH))
        if best is None or score < best[0]:
            best = (score, m, na, nf)
    if best is None:
        raise ValueError(f"n_dof = {n_dof} is below the smallest barrel (about 1,800 DoFs)")
    _, m, na, nf = best
    theta, n_upper = _angles(m)
    if len(theta) > 999 or nf > 999:
        raise ValueError(f"n_dof = {n_dof} is too large for the id scheme (at most 999 grids per station)")
    a = 2.0 * math.pi * RADIUS / len(theta)
    x = a * np.arange(na + 1)
    y_edge = RADIUS * math.cos(_floor_angle())
    floor_y = y_edge - 2.0 * y_edge * np.arange(nf + 2) / (nf + 1)
    step = max(1, round(FRAME_PITCH / a))
    frames = tuple(sorted(set(range(0, na, step)) | {na}))
    inner = [f for f in frames if 0 < f < na] or [na // 2]
    joint = min(inner, key=lambda f: (abs(f - na / 2), f))
    rails = tuple(sorted({int(np.argmin(np.abs(floor_y[1:-1] - r * RADIUS))) + 1 for r in SEAT_RAILS}))
    struts = []
    for y in (STRUT_Y * RADIUS, -STRUT_Y * RADIUS):
        l = min(rails, key=lambda r: abs(floor_y[r] - y))
        below = math.atan2(-math.sqrt(RADIUS**2 - floor_y[l] ** 2), floor_y[l])  # skin point below the rail
        j = int(np.argmin(np.abs(np.angle(np.exp(1j * (theta - below))))))
        struts.append((l, j))
    bay = np.minimum((N_BAYS * (np.arange(na) + 0.5) / na).astype(np.int64), N_BAYS - 1)
    return BarrelLayout(m=m, theta=theta, n_upper=n_upper, x=x, floor_y=floor_y, frames=frames, joint=joint,
                        rails=rails, struts=tuple(struts), bay=bay)


# ---------------------------------------------------------------------------------------
# Masses by hand (the suspension stiffness and the tests)


def _chords(layout: BarrelLayout) -> np.ndarray:
    """Length of each skin element edge around the ring (j to j + 1), m."""
    d = np.diff(np.append(layout.theta, layout.theta[0] + 2.0 * math.pi))
    return 2.0 * RADIUS * np.sin(0.5 * d)


def masses(layout: BarrelLayout, damage: dict[str, float] | None = None) -> dict[str, float]:
    """Mass [kg] of each part of the barrel, summed by hand: skin ρtA (flat elements), floor
    (ρT + NSM)·area, frames, stringers, floor beams and struts (ρA + NSM)·length, payload
    CONM2."""
    f = _factors(damage)
    perimeter = float(np.sum(_chords(layout)))
    width = float(layout.floor_y[0] - layout.floor_y[-1])
    n_frames, length = len(layout.frames), layout.length
    return {
        "skin": SKIN_MAT[2] * SKIN_T * perimeter * length,
        "floor": (FLOOR_MAT[2] * FLOOR_T + FLOOR_NSM * f["floor nsm"]) * width * length,
        "frames": (FRAME_MAT[2] * FRAME_SECTION[0] + FRAME_SECTION[4] * f["frames nsm"]) * perimeter * n_frames,
        "stringers": FRAME_MAT[2] * STRINGER_SECTION[0] * length * len(layout.stringers),
        "floor beams": FRAME_MAT[2] * FLOOR_BEAM_SECTION[0] * width * n_frames,
        "struts": FRAME_MAT[2] * STRUT_SECTION[0] * n_frames * sum(
            math.hypot(layout.floor_y[l] - RADIUS * math.cos(layout.theta[j]), FLOOR_Z * RADIUS
                       - RADIUS * math.sin(layout.theta[j])) for l, j in layout.struts),
        "payload": PAYLOAD * length,
    }


# ---------------------------------------------------------------------------------------
# Bulk data


def _real(x: float) -> str:
    """Shortest repr at 12 significant digits, always with a decimal point (1e-07 -> 1.e-07)."""
    text = repr(float(f"{float(x):.12g}"))
    mantissa, e, exponent = text.partition("e")
    return text if "." in mantissa else f"{mantissa}.{e}{exponent}"


def _skin_groups() -> list[tuple[str, tuple[int, ...]]]:
    return ([(f"skin U{b + 1}", (PID_SKIN_UPPER + b,)) for b in range(N_BAYS)]
            + [(f"skin L{b + 1}", (PID_SKIN_LOWER + b,)) for b in range(N_BAYS)])


def _groups() -> dict[str, tuple[str, tuple[int, ...]]]:
    """name -> (kind, pids) of the 20 groups: the 12 skin bays (E), then OTHER_GROUPS."""
    out = {name: ("E", pids) for name, pids in _skin_groups()}
    out.update({name: (kind, pids) for name, kind, pids in OTHER_GROUPS})
    return out


def _factors(damage: dict[str, float] | None) -> dict[str, float]:
    """1 + α of every group of parameter_groups(20); unknown names or α <= −1 refused."""
    groups = _groups()
    out = dict.fromkeys(groups, 1.0)
    for name, alpha in (damage or {}).items():
        if name not in groups:
            raise ValueError(f"damage: unknown group {name!r}; the groups are {list(groups)}")
        if not float(alpha) > -1.0:
            raise ValueError(f"damage: {name!r} = {alpha!r}, the relative change must be > -1")
        out[name] = 1.0 + float(alpha)
    return out


def _mat1(mid: int, mat: tuple[float, float, float], e_factor: float = 1.0, g_factor: float = 1.0) -> str:
    """MAT1 with E, G = E/(2(1 + ν)) and ν all written, so that a factor on E leaves G (as
    the parameter kind ``E`` does)."""
    e, nu, rho = mat
    return f"MAT1,{mid},{_real(e * e_factor)},{_real(e / (2.0 * (1.0 + nu)) * g_factor)},{_real(nu)},{_real(rho)}"


def _pbar(pid: int, mid: int, section: tuple, nsm_factor: float = 1.0) -> str:
    a, i1, i2, j, nsm = section
    return f"PBAR,{pid},{mid},{_real(a)},{_real(i1)},{_real(i2)},{_real(j)},{_real(nsm * nsm_factor)}"


def suspension_stiffness(layout: BarrelLayout) -> float:
    """Stiffness [N/m] of each of the 12 suspension springs: a rigid translation of the
    nominal barrel on them at :data:`SUSPENSION_HZ`."""
    return sum(masses(layout).values()) * (2.0 * math.pi * SUSPENSION_HZ) ** 2 / 4.0


def suspension_grids(layout: BarrelLayout) -> list[int]:
    """The four suspended grids: θ = 90° ± 30° at the frames nearest 0.2 L and 0.8 L."""
    stations = [min(layout.frames, key=lambda f: abs(layout.x[f] - s * layout.length)) for s in (0.2, 0.8)]
    ring = [int(np.argmin(np.abs(np.angle(np.exp(1j * (layout.theta - math.radians(t))))))) for t in (60.0, 120.0)]
    return [SKIN + 1000 * i + j + 1 for i in stations for j in ring]


def payload_eids(layout: BarrelLayout) -> list[int]:
    """CONM2 ids of the payload (for a parameter of kind ``m``)."""
    return [MASSES + 1000 * i + l for i in layout.frames for l in layout.rails]


def barrel_bdf(n_dof: int, *, damage: dict[str, float] | None = None) -> str:
    """Bulk data (free field, SI) of the stiffened barrel with about ``n_dof`` solved DoFs.

    **Arguments:** ``n_dof``: the requested number of solved DoFs (met within a few per
    cent, :func:`barrel_layout`); ``damage``: ``{group name: α}``, the named groups of
    ``parameter_groups(20)`` written with value₀·(1 + α) (skin and frame E, NSM, floor
    12I/T³, floor beams' and struts' E and G together, PBUSH and PELAS K), or None. G is written with E
    (E/(2(1 + ν))) and stays when E changes, as the parameter kind ``E`` leaves it.

    **Returns:** the text; ids in the module's id scheme: skin grid ``1,000,000 + 1000 i
    + j + 1`` (station i, angle index j), floor grid ``2,000,000 + 1000 i + l`` (l = 1..nf
    across from +y), their joint copies ``3,000,000 + j + 1`` and ``4,000,000 + l``;
    elements on the same scheme from 1,000,000 (skin), 2,000,000 (floor), 5,000,000
    (frames), 6,000,000 (stringers), 7,000,000 (floor beams), 7,500,000 (struts), 8,000,000 (joint CBUSH),
    8,100,000 (suspension CELAS1), 9,000,000 (payload CONM2).
    """
    layout = barrel_layout(n_dof)
    f = _factors(damage)
    nc, na, nf, lo = layout.nc, layout.na, layout.nf, layout.n_upper
    theta, x, fy = layout.theta, layout.x, layout.floor_y
    zf = FLOOR_Z * RADIUS
    a = float(x[1] - x[0])
    lines = [
        f"$ Stiffened fuselage barrel written by benchmarks/fuselage.py: barrel_bdf({n_dof}, damage={damage!r}).",
        f"$ R = {RADIUS} m, L = {layout.length:.4f} m, {nc} x {na} skin CQUAD4, floor {nf + 1} x {na} CQUAD4 at "
        f"z = {zf} m; {N_STRINGERS} stringers, {len(layout.frames)} frames; joint at x = {x[layout.joint]:.4f} m.",
        f"$ {layout.n_grids} grids, {layout.n_dof} DoFs, nothing constrained (suspension springs). SI units.",
        "PARAM,COUPMASS,1",
    ]
    for name, pids in _skin_groups():
        (pid,) = pids
        lines.append(_mat1(pid, SKIN_MAT, f[name]))
        lines.append(f"PSHELL,{pid},{pid},{_real(SKIN_T)},{pid},,{pid}")
    lines += [
        _mat1(MID_FRAME, FRAME_MAT, f["frames E"]),
        _pbar(PID_FRAME, MID_FRAME, FRAME_SECTION, f["frames nsm"]),
        _mat1(MID_STRINGER, FRAME_MAT, f["stringers E"]),
        _pbar(PID_STRINGER, MID_STRINGER, STRINGER_SECTION),
        _mat1(MID_FLOOR, FLOOR_MAT),
        f"PSHELL,{PID_FLOOR},{MID_FLOOR},{_real(FLOOR_T)},{MID_FLOOR},{_real(FLOOR_BENDING * f['floor bending'])},"
        f"{MID_FLOOR},,{_real(FLOOR_NSM * f['floor nsm'])}",
        _mat1(MID_FLOOR_BEAM, FRAME_MAT, f["floor beams stiffness"], f["floor beams stiffness"]),
        _pbar(PID_FLOOR_BEAM, MID_FLOOR_BEAM, FLOOR_BEAM_SECTION),
        f"PROD,{PID_STRUT},{MID_FLOOR_BEAM},{_real(STRUT_SECTION[0])},{_real(STRUT_SECTION[1])}",
        f"PBUSH,{PID_JOINT},K," + ",".join(_real(k * a * f["joint k"]) for k in JOINT_K),
        f"PELAS,{PID_SUSPENSION},{_real(suspension_stiffness(layout) * f['suspension k'])}",
    ]

    ys, zs = RADIUS * np.cos(theta), RADIUS * np.sin(theta)
    cy, cz = [_real(v) for v in ys], [_real(v) for v in zs]
    fys, zfs = [_real(v) for v in fy], _real(zf)
    for i in range(na + 1):
        xi = _real(x[i])
        lines += [f"GRID,{SKIN + 1000 * i + j + 1},,{xi},{cy[j]},{cz[j]}" for j in range(nc)]
        lines += [f"GRID,{FLOOR + 1000 * i + l},,{xi},{fys[l]},{zfs}" for l in range(1, nf + 1)]
    xj = _real(x[layout.joint])
    lines += [f"GRID,{JOINT_SKIN + j + 1},,{xj},{cy[j]},{cz[j]}" for j in range(nc)]
    lines += [f"GRID,{JOINT_FLOOR + l},,{xj},{fys[l]},{zfs}" for l in range(1, nf + 1)]

    def skin(i: int, j: int, aft: bool) -> int:
        """Skin grid at station i, angle index j; at the joint the aft elements use the copies."""
        j %= nc
        return JOINT_SKIN + j + 1 if aft and i == layout.joint else SKIN + 1000 * i + j + 1

    def floor(i: int, l: int, aft: bool) -> int:
        if l == 0:
            return skin(i, 0, aft)
        if l == nf + 1:
            return skin(i, lo, aft)
        return JOINT_FLOOR + l if aft and i == layout.joint else FLOOR + 1000 * i + l

    for i in range(na):
        aft = i >= layout.joint  # element column i spans stations i, i + 1
        b = int(layout.bay[i])
        for j in range(nc):
            pid = (PID_SKIN_UPPER if j < lo else PID_SKIN_LOWER) + b
            g = (skin(i, j, aft), skin(i + 1, j, aft), skin(i + 1, j + 1, aft), skin(i, j + 1, aft))
            lines.append(f"CQUAD4,{SKIN + 1000 * i + j + 1},{pid},{g[0]},{g[1]},{g[2]},{g[3]}")
        for l in range(nf + 1):
            g = (floor(i, l, aft), floor(i, l + 1, aft), floor(i + 1, l + 1, aft), floor(i + 1, l, aft))
            lines.append(f"CQUAD4,{FLOOR + 1000 * i + l + 1},{PID_FLOOR},{g[0]},{g[1]},{g[2]},{g[3]}")
        for s, j in enumerate(layout.stringers, 1):
            lines.append(f"CBAR,{STRINGERS + 1000 * i + s},{PID_STRINGER},{skin(i, j, aft)},{skin(i + 1, j, aft)},"
                         f"0.,{cy[j]},{cz[j]}")
    for i in layout.frames:  # on the forward grids at the joint
        for j in range(nc):
            lines.append(f"CBAR,{FRAMES + 1000 * i + j + 1},{PID_FRAME},{skin(i, j, False)},{skin(i, j + 1, False)},"
                         f"0.,{cy[j]},{cz[j]}")
        for l in range(nf + 1):
            lines.append(f"CBAR,{FLOOR_BEAMS + 1000 * i + l + 1},{PID_FLOOR_BEAM},{floor(i, l, False)},"
                         f"{floor(i, l + 1, False)},0.,0.,1.")
        lines += [f"CROD,{STRUTS + 1000 * i + k},{PID_STRUT},{floor(i, l, False)},{skin(i, j, False)}"
                  for k, (l, j) in enumerate(layout.struts, 1)]
    pairs = [(skin(layout.joint, j, False), skin(layout.joint, j, True)) for j in range(nc)]
    pairs += [(floor(layout.joint, l, False), floor(layout.joint, l, True)) for l in range(1, nf + 1)]
    lines += [f"CBUSH,{BUSHES + k},{PID_JOINT},{ga},{gb}" for k, (ga, gb) in enumerate(pairs, 1)]
    for k, g in enumerate(suspension_grids(layout)):
        lines += [f"CELAS1,{SPRINGS + 3 * k + c},{PID_SUSPENSION},{g},{c}" for c in (1, 2, 3)]
    count = len(layout.frames) * len(layout.rails)
    m = _real(PAYLOAD * layout.length / count)
    for i in layout.frames:
        lines += [f"CONM2,{MASSES + 1000 * i + l},{FLOOR + 1000 * i + l},,{m},0.,0.,{_real(PAYLOAD_HEIGHT)}"
                  for l in layout.rails]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------
# Updating parameters


def parameter_groups(n: int = 20) -> list:
    """``n`` updating parameters (9 <= n <= 20), :class:`updating.Parameter`, of the barrel.

    The last eight are :data:`OTHER_GROUPS` (frame E and NSM, stringer E, floor bending and
    NSM, floor beams' and struts' stiffness, joint k, suspension k); the first ``n − 8`` are ``E`` of the
    skin: with an even count, each lobe's six axial bays in (n − 8)/2 runs of neighbouring
    bays (``n = 20``: every bay, ``skin U1`` … ``skin L6``; ``n = 10``: ``skin upper``,
    ``skin lower``), with an odd count both lobes together in n − 8 runs. The targets are
    property ids only, valid on every barrel :func:`barrel_bdf` writes.
    """
    from updating import Parameter

    n_other = len(OTHER_GROUPS)
    if not n_other + 1 <= n <= n_other + 2 * N_BAYS:
        raise ValueError(f"n must lie in [{n_other + 1}, {n_other + 2 * N_BAYS}], got {n}")
    k = n - n_other
    bays = np.arange(N_BAYS)
    skin = []
    if k % 2 == 0:
        runs = np.array_split(bays, k // 2)
        for lobe, base, label in (("upper", PID_SKIN_UPPER, "U"), ("lower", PID_SKIN_LOWER, "L")):
            for run in runs:
                name = (f"skin {lobe}" if len(runs) == 1 else f"skin {label}{run[0] + 1}" if len(run) == 1
                        else f"skin {label}{run[0] + 1}-{run[-1] + 1}")
                skin.append((name, tuple(int(base + b) for b in run)))
    else:
        runs = np.array_split(bays, k)
        for run in runs:
            name = "skin" if k == 1 else f"skin bays {run[0] + 1}-{run[-1] + 1}" if len(run) > 1 \
                else f"skin bay {run[0] + 1}"
            skin.append((name, tuple(int(p + b) for b in run for p in (PID_SKIN_UPPER, PID_SKIN_LOWER))))
    params = [Parameter(name, "E", pids=pids, bounds=(-0.3, 0.3)) for name, pids in skin]
    bounds = {"k": (-0.9, 9.0), "nsm": (-0.5, 1.0)}
    params += [Parameter(name, kind, pids=pids, bounds=bounds.get(kind, (-0.3, 0.3)))
               for name, kind, pids in OTHER_GROUPS]
    return params


def parameters_toml(n: int = 20, options: dict | None = None) -> str:
    """A parameter file (docs/parameters.md) of ``parameter_groups(n)`` for ``jaxfem update``
    and ``jaxfem diagnose --params``, with an optional ``[options]`` table (numbers, strings,
    booleans and lists of numbers)."""

    def value(v) -> str:
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(u) for u in v) + "]"
        return repr(v)

    out = []
    for p in parameter_groups(n):
        out += ["[[parameter]]", f"name = {json.dumps(p.name)}", f'kind = "{p.kind}"',
                f"pids = {value(list(p.pids))}", f"bounds = {value(list(p.bounds))}", ""]
    if options:
        out += ["[options]"] + [f"{k} = {value(v)}" for k, v in options.items()] + [""]
    return "\n".join(out)


def write_parameters(path: str | Path, n: int = 20, options: dict | None = None) -> Path:
    """Write :func:`parameters_toml` to ``path``; returns the path."""
    path = Path(path)
    path.write_text(parameters_toml(n, options), encoding="utf-8")
    return path


# ---------------------------------------------------------------------------------------
# Timing


def _sparse(a, n: int):
    import scipy.sparse as sp

    rows, cols, vals = [], [], []
    for blk, idx in zip(a.blocks, a.indices):
        idx = np.asarray(idx)
        r, c = np.broadcast_arrays(idx[:, :, None], idx[:, None, :])
        keep = (r < n) & (c < n)
        rows.append(r[keep])
        cols.append(c[keep])
        vals.append(np.asarray(blk)[keep])
    return sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsc()


def run(n_dof: int, n_modes: int = 0) -> dict:
    """Time generation, parsing, building and assembly of one barrel (one process, one size)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxfem
    from jaxfem.io import read_bdf_text

    out: dict = {"requested_n_dof": n_dof, "machine": f"{platform.machine()}, {platform.processor() or '?'}, "
                 f"{__import__('os').cpu_count()} cores, jax {jax.__version__}"}
    t = time.perf_counter()
    text = barrel_bdf(n_dof)
    out["generate_s"] = time.perf_counter() - t
    out["text_mb"] = len(text) / 1e6
    t = time.perf_counter()
    bulk = read_bdf_text(text, name="barrel")
    out["read_s"] = time.perf_counter() - t
    t = time.perf_counter()
    model = jaxfem.build_model(bulk)
    out["build_s"] = time.perf_counter() - t
    out["n_dof"] = model.n_dof
    out["n_quads"], out["n_beams"] = len(model.quads.ids), len(model.beams.ids)
    for label in ("assemble_first_s", "assemble_second_s"):
        t = time.perf_counter()
        K, M = jaxfem.assemble(model)
        jax.block_until_ready((K.blocks, M.blocks))
        out[label] = time.perf_counter() - t
    if n_modes:
        import scipy.sparse.linalg as spla

        t = time.perf_counter()
        k, mm = _sparse(K, model.n_dof), _sparse(M, model.n_dof)
        lam = spla.eigsh(k, n_modes, mm, sigma=-1.0, which="LM", return_eigenvectors=False)
        out["modes_s"] = time.perf_counter() - t
        out["frequencies_hz"] = (np.sqrt(np.abs(np.sort(lam))) / (2 * math.pi)).round(3).tolist()
    return out


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n-dof", type=int, default=33000)
    parser.add_argument("--modes", type=int, default=0, help="also the lowest modes (SciPy shift-invert)")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    out = run(args.n_dof, args.modes)
    print(json.dumps(out, indent=1))
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
