"""Correlate the GARTEUR SM-AG19 model (thesis §4.2) with measured modes.

The files are those ``jaxfem demo`` writes (``updating.demo_case``): the nominal model
``garteur.bdf`` and ``test.uff``, 14 elastic modes at 24 sensors "measured" on a truth
that differs from the model (fuselage stiffness +6 %, a flexible fin-root joint), with
0.2 % noise on frequencies and 1 % on shape components (``updating.simulate_test``).
Shows, in one call (``updating.correlate``): model modes, pairing by MAC and Δf (thesis
eq. 4.1), the table f_test, f_model, Δf %, MAC and the sensors with the lowest COMAC.
Next: ``02_update.py`` (make the model agree by updating parameters).
"""

import tempfile
from pathlib import Path

import jax

import jaxfem
import updating
from identification import read_uff
from jaxfem.io import read_bdf


def case(directory=None):
    """The files of ``jaxfem demo`` (``updating.demo_case``): the nominal model ``garteur.bdf``
    and ``test.uff``, 14 elastic modes "measured" on a truth with the fuselage stiffness
    +6 % and a flexible fin-root joint, σ = 1 % on shape components and 0.4 % on the
    eigenvalues (Table 4.7). Read back as an engineer reads a model and a modal survey."""
    model_path, test_path = updating.demo_case(Path(directory or tempfile.mkdtemp(prefix="jaxfem-demo-")))
    return jaxfem.build_model(read_bdf(model_path)), read_uff(test_path)["modes"]


def main() -> dict:
    jax.config.update("jax_enable_x64", True)
    model, test = case()
    # model modes (twice the test modes, at least 6 spare: updating.n_model_modes) read at the
    # sensors, paired by MAC and Δf (eq. 4.1), AutoMAC, COMAC, spatial aliasing
    res = updating.correlate(model, test)
    print(f"GARTEUR: {model.n_dof} DoFs, {res.n_model_modes} model modes; "
          f"test: {test.n_modes} modes at {len(res.sensors)} sensors")
    print(f"{'test':>4} {'model':>5} {'f_test [Hz]':>11} {'f_model [Hz]':>12} {'Δf [%]':>7} {'MAC':>6}")
    for t, m, ft, fm, df, c in res.pairing.table():
        print(f"{t:>4} {m or '–':>5} {ft:>11.3f} " + (f"{fm:>12.3f} {df:>+7.2f} {c:>6.3f}" if m else "unpaired"))
    print("\n".join(res.warnings))
    print(f"RMS Δf {res.rms_freq_dev_pct:.2f} %, mean MAC {res.mean_mac:.3f}")
    worst = res.comac_ranking[:5]
    print("lowest COMAC: " + ", ".join(f"{sensor} {value:.3f}" for sensor, value in worst))
    return {"n_paired": res.n_paired, "rms_freq_dev_pct": res.rms_freq_dev_pct, "mean_mac": res.mean_mac,
            "worst_comac_sensor": worst[0][0]}


if __name__ == "__main__":
    main()
