"""Diagnose the GARTEUR test case: which physical effect is the model missing?

The case of ``jaxfem demo`` (also ``01_correlate_garteur.py``): the nominal model, 14
measured modes and the engineer's parameters (fuselage and wing stiffness). The
diagnosis fits those first (the baseline), localises the remaining error, generates
candidate effects (group stiffness/mass, joints, added masses, springs, frequency-
dependent stiffness), ranks them by Bayesian evidence (posterior probability) and tests
the most probable on held-out modes (4-fold cross-validation). The truth has a flexible
joint at the fin root (RBE2 1029 → 6001): the winner should be ``joint`` at grid 6001.
It fits fewer candidates than ``jaxfem demo``: the 3 best screened, the best of each
kind and the one joint nearest the localised error
(``DiagnoseOptions(shortlist=3, per_kind=1, max_structural=1)``; defaults 4, 3, 4).
Next: add the effect and update again (``updating.add_effect``, ``jaxfem update
--add-effect joint:node=6001``), or ``jaxfem demo`` for all of it with an HTML report.
"""

import importlib.util
from pathlib import Path

import jax

import updating

PARAMETERS = updating.ParameterSet((updating.Parameter("fuselage", "stiffness", pids=(1,)),
                                    updating.Parameter("wings", "stiffness", pids=(11, 12, 13, 21, 22, 23))))
OPTIONS = updating.DiagnoseOptions(shortlist=3, per_kind=1, max_structural=1)


def main() -> dict:
    jax.config.update("jax_enable_x64", True)
    spec = importlib.util.spec_from_file_location("correlate", Path(__file__).with_name("01_correlate_garteur.py"))
    spec.loader.exec_module(correlate := importlib.util.module_from_spec(spec))  # its case()
    model, test = correlate.case()
    diag = updating.diagnose(model, test, PARAMETERS, options=OPTIONS, progress=lambda s: print(f"[diagnose] {s}"))
    b = diag.baseline
    print(f"baseline (parameters fitted): RMS Δf {b.rms_freq_dev_pct:.2f} %, held-out RMS Δf "
          f"{b.heldout_rms_freq_dev_pct:.2f} %, χ²/row {b.chi2_per_row:.1f}")
    print("where it fails (property groups): " + ", ".join(
        f"pid {pid} {score:.2f}" for pid, score, *_ in diag.localisation.groups[:4]))
    print(f"{'rank':>4} {'effect':<36} {'posterior':>9} {'ln B':>9}  declared")
    for e in diag.effects[:5]:  # ln B: log Bayes factor against the baseline
        print(f"{e.rank:>4} {e.effect.kind + ' ' + e.effect.where():<36.36} {e.posterior:>9.3f} "
              f"{e.log_evidence:>9.1f}  {'yes' if e.warranted else 'no'}")
    print(diag.verdict)
    print(f"{diag.candidates_evaluated} candidates screened, {diag.candidates_fitted} fitted, {diag.seconds:.0f} s")
    best = diag.effects[0]
    return {"kind": best.effect.kind, "nodes": list(best.effect.nodes), "warranted": best.warranted,
            "score": best.score, "no_effect_warranted": diag.no_effect_warranted}

if __name__ == "__main__":
    main()
