"""Correlate the GARTEUR SM-AG19 model (thesis §4.2) with measured modes.

The model and its 24 sensors ship with jaxfem (``updating/data``). The "measured" modes
are the case ``jaxfem demo`` writes to ``test.uff``: 14 elastic modes of a truth that
differs from the model (fuselage stiffness +6 %, a flexible fin-root joint), with 0.2 %
noise on frequencies and 1 % on shape components (``updating.simulate_test``). Shows:
model modes, pairing by MAC and Δf (thesis eq. 4.1), the table f_test, f_model, Δf %,
MAC and the sensors with the lowest COMAC. Next: ``02_update.py`` (make the model agree by updating parameters).
"""

from importlib import resources

import jax
import jax.numpy as jnp
import numpy as np

import jaxfem
import updating
from identification import Sensors, observation_matrix
from jaxfem.io import read_bdf


def measured(model, sensors, seed=2026):
    """The demo's truth and measurement: 14 elastic modes (3 free-body and 3 suspension
    modes skipped), σ = 1 % on shape components and 0.4 % on eigenvalues (Table 4.7)."""
    truth = jaxfem.correct(model, [model.element_ids(pids=[1])], jnp.array([0.06]))
    ref = updating.at_reference(model, updating.Effect("joint", nodes=(6001,)), [1.0]).values
    truth = updating.Effect("joint", nodes=(6001,), values={**ref, "k_rot": ref["k_rot"] / 300}).apply(truth)
    noise = updating.Noise(relative=0.01, frequency=0.004)
    return updating.simulate_test(truth, sensors, 14, noise, jax.random.key(seed), skip=6)


def main() -> dict:
    jax.config.update("jax_enable_x64", True)
    data = resources.files("updating") / "data"
    with resources.as_file(data / "garteur.bdf") as bdf, resources.as_file(data / "garteur_sensors.csv") as csv:
        model, sensors = jaxfem.build_model(read_bdf(bdf)), Sensors.read_csv(csv)
    test = measured(model, sensors)
    n = updating.n_model_modes(model, test.n_modes)  # 2 × test modes + 6
    lam, phi = jaxfem.modes(model, n)
    f_a, phi_a = np.asarray(jaxfem.frequencies_hz(lam)), np.asarray(observation_matrix(model, sensors)[0] @ phi)
    pairing = updating.pair_modes(f_a, phi_a, test.frequencies_hz, test.shapes)
    print(f"GARTEUR: {model.n_dof} DoFs, {n} model modes; test: {test.n_modes} modes at {len(sensors)} sensors")
    print(f"{'test':>4} {'model':>5} {'f_test [Hz]':>11} {'f_model [Hz]':>12} {'Δf [%]':>7} {'MAC':>6}")
    for t, m, ft, fm, df, c in pairing.table():
        print(f"{t:>4} {m or '–':>5} {ft:>11.3f} " + (f"{fm:>12.3f} {df:>+7.2f} {c:>6.3f}" if m else "unpaired"))
    summary = pairing.summary()
    print("\n".join(pairing.warnings))
    print(f"RMS Δf {summary['rms_freq_dev_pct']:.2f} %, mean MAC {summary['mean_mac']:.3f}")
    co = np.asarray(updating.comac(phi_a[:, pairing.model], test.shapes[:, pairing.test]))
    worst = np.argsort(co)[:5]
    print("lowest COMAC: " + ", ".join(f"{sensors.labels[i]} {co[i]:.3f}" for i in worst))
    return {"n_paired": int(pairing.test.size), "rms_freq_dev_pct": summary["rms_freq_dev_pct"],
            "mean_mac": summary["mean_mac"], "worst_comac_sensor": sensors.labels[worst[0]]}


if __name__ == "__main__":
    main()
