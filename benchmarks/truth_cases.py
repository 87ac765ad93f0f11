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
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from importlib import resources

import numpy as np

from benchmarks.frames import frame_bdf
from benchmarks.truth import Truth
from identification import ModalData, Sensors

NOISE_F, NOISE_S = 0.002, 0.01


@dataclass(frozen=True)
class Case:
    """``hidden`` adds the effect to a :class:`Truth`; ``kind`` and ``place`` (the grids
    or pids it is found at) are what the diagnosis must rank first; None: a control."""

    name: str
    model: str  # "garteur" | "frame"
    hidden: Callable[[Truth], Truth]
    kind: str | None = None
    place: tuple[int, ...] = ()
    description: str = ""


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
    """Bulk data text, the sensors, the number of modes and of rigid-body modes skipped."""
    if case.model == "garteur":
        sensors = Sensors.read_csv(resources.files("updating") / "data" / "garteur_sensors.csv")
        return _garteur_text(), sensors, 14, 6
    grids = list(range(5, 21))
    return frame_bdf(2, 2, 4, n_groups=8), Sensors.from_components(np.repeat(grids, 2), np.tile([1, 2], 16)), 12, 0


def measure(case: Case, seed: int = 1) -> ModalData:
    """The case's measured modes: its truth with the hidden effect. GARTEUR's truth has two
    beam elements per CBAR; the frame's one (its 1 m members with one element each are
    0.66 % off a refined mesh in modes 9–12: a model-form error no single effect
    explains, and the frame has no engineer's parameters to absorb it)."""
    text, sensors, n, skip = nominal(case)
    truth = Truth.from_bdf_text(text, refine=2 if case.model == "garteur" else 1)
    if case.model == "garteur":
        truth.scale(pids=(1,), stiffness=0.06)
    return case.hidden(truth).measure(sensors, n, NOISE_F, NOISE_S, seed=seed, skip=skip)


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
