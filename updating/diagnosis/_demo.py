"""The embedded demonstration case: the GARTEUR SM-AG19 benchmark model (thesis §4.2) and
"measured" modes simulated from a truth the diagnosis does not see.

The truth differs from the nominal model by a hidden effect — the fin-to-fuselage
connection (RBE2 from grid 1029 to 6001) is a flexible joint — and by a parameter error
the engineer's parameters can fix (fuselage bending stiffness +6 %). Measurement: the
first 14 elastic modes at the 24 sensors of ``garteur_sensors.csv`` with the Table 4.7
errors of :func:`updating.simulate_test`: σ = 0.4 % on each eigenvalue (0.2 % on the
frequencies) and 1 % relative on each shape component; written as a universal file.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import jax
import jax.numpy as jnp

import jaxfem
from identification import Sensors, write_uff
from jaxfem.io import read_bdf

from .. import Noise, Options, Parameter, ParameterSet, simulate_test
from ._effects import Effect
from ._topology import joint_reference

HIDDEN = "a flexible joint at the fin root (RBE2 1029 → 6001, k_rot = 1/300 of its reference)"
PARAMETERS = ParameterSet((Parameter("fuselage", "stiffness", pids=(1,)),
                           Parameter("wings", "stiffness", pids=(11, 12, 13, 21, 22, 23))), Options())


def demo_case(directory: Path, seed: int = 2026) -> tuple[Path, Path]:
    """Write ``garteur.bdf`` (nominal) and ``test.uff`` (simulated measurement) into
    ``directory``; returns their paths."""
    directory.mkdir(parents=True, exist_ok=True)
    data = resources.files("updating") / "data"
    model_path = directory / "garteur.bdf"
    model_path.write_text((data / "garteur.bdf").read_text())
    sensors = Sensors.read_csv(data / "garteur_sensors.csv")
    model = jaxfem.build_model(read_bdf(model_path))
    truth = jaxfem.correct(model, [model.element_ids(pids=[1])], jnp.array([0.06]))
    ref = joint_reference(model, (6001,), [501])
    truth = Effect("joint", nodes=(6001,), values={"k_trans": ref["k_trans"], "k_rot": ref["k_rot"] / 300}).apply(truth)
    measured = simulate_test(truth, sensors, 14, Noise(frequency=0.002, relative=0.01), jax.random.key(seed), skip=6)
    nodes = {int(n): model.xyz[i] for i, n in enumerate(model.node_ids)}
    test_path = directory / "test.uff"
    write_uff(test_path, nodes=nodes, modes=measured)
    return model_path, test_path
