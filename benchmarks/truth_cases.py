"""Hidden-effect cases whose "measurements" come from an independent FE code.

Each case takes a nominal jaxfem model and makes its truth with :mod:`benchmarks.truth`
(refined Timoshenko beams, RBE2 links as penalty springs, its own joints, springs,
masses and power-law visco-elastic stiffness), adds one hidden effect and a parameter
error the engineer's parameters can fix, and measures modes with noise (0.2 % on
frequencies, 1 % on shape components). The diagnosis never sees the truth's model family.

- GARTEUR SM-AG19 (updating/data/garteur.bdf): 14 elastic modes at the 24 sensors of
  garteur_sensors.csv; engineer's parameters: fuselage and wing stiffness; fuselage
  stiffness +6 % in every truth.
- The beam frame ``frame_bdf(2, 2, 4, n_groups=8)`` (clamped): 12 modes at 32 sensors
  (x and y at grids 5–20); no engineer's parameters. Its truth differs in the element
  formulation (rotary inertia of every beam, the BOX shear factor), not in the mesh.

:data:`HARD_CASES` (GARTEUR; judged by :func:`found_hard`): two effects at once, a
stiffness change outside the effect library (torsion alone), a mass between grids, sparse
sensors, stated high noise, uniform damping ratios, a saturating stiffness law.
:func:`measure_hard` gives what a diagnosis of one needs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources

import numpy as np

from benchmarks.frames import frame_bdf
from benchmarks.truth import Truth
from identification import ModalData, Sensors

NOISE_F, NOISE_S, NOISE_D = 0.002, 0.01, 0.1  # σ on frequencies, shape components, damping ratios
OUTSIDE = ("unexplained", "unconfirmed", "partial", "cannot_localise")  # honest outcomes where no library effect fits
_GROUP_KINDS = ("stiffness", "mass", "frequency_dependent_stiffness")  # placed by pids, the others by grids

Place = tuple[str, tuple[int, ...]]  # (effect kind, its grids or pids)


@dataclass(frozen=True)
class Case:
    """``hidden`` adds the effect to a :class:`Truth`; ``kind`` and ``place`` (the grids
    or pids it is found at) are what the diagnosis must rank first; None: a control.

    For :func:`found_hard`: ``outcome`` "effect" (one of ``accept``, or every one of
    ``effects``, declared), "outside" (an outcome of :data:`OUTSIDE`), "none_needed" or
    "any"; ``sensors``: grids of triaxial sensors replacing the model's sensor list;
    ``noise``: σ of the measurement (frequencies, shape components, damping ratios);
    ``damping``: a uniform damping ratio of every measured mode (None: none measured),
    whose diagnosis must be "none_needed"."""

    name: str
    model: str  # "garteur" | "frame"
    hidden: Callable[[Truth], Truth]
    kind: str | None = None
    place: tuple[int, ...] = ()
    description: str = ""
    accept: tuple[Place, ...] = ()  # alternatives: any one declared (or tied) will do
    effects: tuple[Place, ...] = ()  # effects at once: each declared (or tied)
    outcome: str = "effect"
    sensors: tuple[int, ...] = ()
    noise: tuple[float, float, float] = (NOISE_F, NOISE_S, NOISE_D)
    damping: float | None = None


def _garteur_text() -> str:
    return (resources.files("updating") / "data" / "garteur.bdf").read_text()


# joint references of the jaxfem model (updating.diagnosis._topology.joint_reference), rounded: the
# truth's joints are these springs made softer
_FIN_K = (3.0e8, 2.4e4)  # k_trans N/m, k_rot N·m/rad at RBE2 1029 → 6001, ≈ its reference / 500
_WING_K = (1.0e9, 5.0e4)  # the wing–fuselage RBE2 1013 → 2000, 2001, 3001


def _wing_joint(t: Truth) -> Truth:
    for node in (2000, 2001, 3001):
        t.joint(node, *_WING_K)
    return t


CASES = (
    Case("garteur-added-mass", "garteur", lambda t: t.add_mass(2010, 0.15, offset=(0.0, 0.0, 0.01)),
         "added_mass", (2010,), "0.15 kg at wing grid 2010 (1 cm above it)"),
    Case("garteur-fin-joint", "garteur", lambda t: t.joint(6001, *_FIN_K), "joint", (6001,),
         "fin root RBE2 1029 → 6001 as springs, k_rot = 2.4e4 N·m/rad"),
    Case("garteur-wing-joint", "garteur", _wing_joint, "joint", (2000, 2001, 3001),
         "wing–fuselage RBE2 1013 → 2000, 2001, 3001 as springs, k_rot = 5e4 N·m/rad"),
    Case("garteur-ground-spring", "garteur", lambda t: t.ground_spring(1020, 5.0e4),
         "boundary_spring", (1020,), "50 kN/m to ground at fuselage grid 1020"),
    Case("garteur-viscoelastic", "garteur", lambda t: t.viscoelastic(pids=(62,), exponent=1.2, f_ref_hz=40.0),
         "frequency_dependent_stiffness", (62,), "tape pid 62: k ∝ (f / 40 Hz)^1.2"),
    Case("garteur-stiffness", "garteur", lambda t: t.scale(pids=(42,), stiffness=-0.25),
         "stiffness", (42,), "tailplane pid 42 stiffness −25 %"),
    Case("garteur-control", "garteur", lambda t: t, description="no hidden effect"),
    Case("frame-joint", "frame", lambda t: t.joint(12, 2.0e8, 1.0e6, pids=(3, 5)), "joint", (12,),
         "grid 12 between pids 3 and 5 as springs, k_rot = 1e6 N·m/rad"),
    Case("frame-support", "frame", lambda t: t.release_support(2, 1.0e9, 2.0e6), "boundary_spring", (2,),
         "clamped base grid 2 released: 1e9 N/m, 2e6 N·m/rad"),
    Case("frame-added-mass", "frame", lambda t: t.add_mass(14, 6.0), "added_mass", (14,), "6 kg at grid 14"),
    Case("frame-control", "frame", lambda t: t, description="no hidden effect"),
)


def nominal(case: Case):
    """Bulk data text, the sensors (the case's triaxial ones, if any), the number of modes
    and of rigid-body modes skipped."""
    if case.model == "garteur":
        text, n, skip = _garteur_text(), 14, 6
        sensors = Sensors.read_csv(resources.files("updating") / "data" / "garteur_sensors.csv")
    else:
        grids = list(range(5, 21))
        text, n, skip = frame_bdf(2, 2, 4, n_groups=8), 12, 0
        sensors = Sensors.from_components(np.repeat(grids, 2), np.tile([1, 2], 16))
    if case.sensors:
        sensors = Sensors.from_components(np.repeat(case.sensors, 3), np.tile([1, 2, 3], len(case.sensors)))
    return text, sensors, n, skip


def measure(case: Case, seed: int = 1) -> ModalData:
    """The case's measured modes: its truth with the hidden effect, the case's noise (and
    damping ratios). GARTEUR's truth has two beam elements per CBAR; the frame's one (its
    1 m members with one element each are 0.66 % off a refined mesh in modes 9–12: a
    model-form error no single effect explains, and the frame has no engineer's
    parameters to absorb it)."""
    text, sensors, n, skip = nominal(case)
    truth = Truth.from_bdf_text(text, refine=2 if case.model == "garteur" else 1)
    if case.model == "garteur":
        truth.scale(pids=(1,), stiffness=0.06)
    noise_f, noise_s, noise_d = case.noise
    return case.hidden(truth).measure(sensors, n, noise_f, noise_s, seed=seed, skip=skip, damping=case.damping,
                                      noise_damping=noise_d)


def parameters(case: Case):
    """The engineer's parameters of the case (None: none)."""
    from updating.diagnosis._demo import PARAMETERS

    return PARAMETERS if case.model == "garteur" else None


def found(report: dict, case: Case) -> bool:
    """The diagnosis declared the hidden effect at its place (or listed the place as a tie:
    the sensors cannot tell it apart); a control: declared nothing."""
    if case.kind is None:
        return report["outcome"] != "effect"
    if report["outcome"] != "effect":
        return False
    places = [report["effects"][0]] + list(report["ties"])
    key = "pids" if case.kind in ("stiffness", "mass", "frequency_dependent_stiffness") else "nodes"
    return any(e["kind"] == case.kind and set(e[key]) == set(case.place) for e in places)


# ------------------------------------------------------------------ hard cases
_TAIL_TIP = 7001  # tailplane tip (y = +0.2, z = 0.38; the other tip is 7009)
_NOSE = 1001  # fuselage front end (x = +0.6)
_MID_311 = (0.0, -0.5, 0.0805)  # middle of right-wing CBAR 311 (grids 3010, 3011): a truth grid for refine=2
_SPARSE = (4001, 4005, 5001, 5005, 9003, 9007, 7001, 7009)  # wing-tip drums, mid-wing LE, tailplane tips


def _joint_and_mass(t: Truth) -> Truth:
    return _wing_joint(t).add_mass(_TAIL_TIP, 0.25)


HARD_CASES = (
    Case("garteur-joint-and-mass", "garteur", _joint_and_mass,
         description=f"wing–fuselage joint as garteur-wing-joint and 0.25 kg at tailplane tip {_TAIL_TIP}",
         effects=(("joint", (2000, 2001, 3001)), ("added_mass", (_TAIL_TIP,)))),
    Case("garteur-wing-torsion", "garteur", lambda t: t.scale(pids=(11, 12, 13), torsion=-0.15),
         description="left wing pids 11-13: torsion constant J −15 % (bending and mass unchanged)",
         outcome="outside"),
    Case("garteur-mass-mid-element", "garteur", lambda t: t.add_mass_at(_MID_311, 0.15),
         description="0.15 kg at the middle of right-wing CBAR 311 (grids 3010-3011, y = −0.5)",
         accept=(("added_mass", (3010,)), ("added_mass", (3011,)), ("added_mass", (3010, 3011)))),
    Case("garteur-sparse-nose-spring", "garteur", lambda t: t.ground_spring(_NOSE, 3.0e3, components=(3,)),
         description=f"3 kN/m vertical to ground at nose grid {_NOSE}; 8 triaxial sensors, none on the fuselage",
         accept=(("boundary_spring", (_NOSE,)),), sensors=_SPARSE),
    Case("garteur-noisy-mass", "garteur", lambda t: t.add_mass(5005, 0.15),
         description="0.15 kg at right wing-tip drum grid 5005 (rear end); 1 % frequency, 3 % shape noise",
         accept=(("added_mass", (5005,)),), noise=(0.01, 0.03, NOISE_D)),
    Case("garteur-uniform-damping", "garteur", lambda t: t, outcome="any", damping=0.005,
         description="no hidden structural effect; damping ratio 0.5 % in every mode, 10 % noise"),
    Case("garteur-saturating-tape", "garteur",
         lambda t: t.standard_linear_solid(pids=(62,), k_ratio=4.0, f_c_hz=40.0),
         description="tape pid 62: standard linear solid k(f) = k0 (1 + 4 x / (1 + x)), x = (f / 40 Hz)²",
         accept=(("frequency_dependent_stiffness", (62,)), ("stiffness", (62,)))),
)


def measure_hard(case: Case, seed: int = 1):
    """Bulk data text, the measured modes, the engineer's parameters and the stated noise
    (:class:`updating.Noise`, for ``DiagnoseOptions(noise=...)``) of a case."""
    from updating import Noise

    noise_f, noise_s, noise_d = case.noise
    return (nominal(case)[0], measure(case, seed), parameters(case),
            Noise(frequency=noise_f, relative=noise_s, damping=noise_d))


def _is(item: dict, kind: str, place: tuple[int, ...]) -> bool:
    key = "pids" if kind in _GROUP_KINDS else "nodes"
    return item["kind"] == kind and set(item.get(key) or ()) == set(place)


def found_hard(report: dict, case: Case) -> bool:
    """The report's answer is acceptable for the case (:class:`Case`): the effects declared
    (``declared``, else the first of ``effects``) and the ``ties`` hold one of ``accept``,
    or every one of ``effects``, with outcome "effect"; "outside": an outcome of
    :data:`OUTSIDE`; with damping measured, the damping part's outcome is "none_needed"."""
    if case.damping is not None and (report.get("damping") or {}).get("outcome") != "none_needed":
        return False
    outcome = report["outcome"]
    if case.outcome != "effect":
        return {"any": True, "none_needed": outcome == "none_needed", "outside": outcome in OUTSIDE}[case.outcome]
    if outcome != "effect":
        return False
    listed = list(report.get("declared") or report["effects"][:1]) + list(report["ties"])
    if case.effects:
        return all(any(_is(e, k, p) for e in listed) for k, p in case.effects)
    accept = case.accept or ((case.kind, case.place),)
    return any(_is(e, k, p) for e in listed for k, p in accept)
