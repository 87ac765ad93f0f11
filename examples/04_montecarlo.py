"""A tiny Monte-Carlo study of experimental errors (thesis §4.3) on the embedded tree.

The tree model (Table 4.5, 49 measured DoFs) with modelling error 1 of Table 4.6 (blades
2 and 4 17 % too soft) is updated against "measured" modes: the first 5, with 1 % and
5 % relative errors on every shape component (Table 4.7), 8 samples each. Each sample
runs the complete update of the three substructure stiffness factors; the statistics
are eq. 4.4: Δα = α(δ)/α(0) − 1 against the error-free update. The thesis runs 100
samples of 2, 5, 10 and 20 modes for all categories: ``jaxfem montecarlo study.toml``
(``docs/montecarlo.md``) with ``--devices`` or ``--ray`` for that size.
"""

import jax
import numpy as np

import updating


def main() -> dict:
    jax.config.update("jax_enable_x64", True)
    study = updating.default_study(1, n_modes=(5,), samples=8, errors=(("relative", (0.01, 0.05)),))
    result = updating.montecarlo(study)
    print(f"tree, modelling error 1 (blades 2 & 4 −17 %): {len(study.cells) * study.samples} samples "
          f"in {result.seconds:.1f} s, failures {sum(result.failures.values())}, fallbacks {result.fallbacks}")
    alpha0 = result.reference[5]["alpha"][0]
    print("error-free update: " + ", ".join(f"{n} α = {a:+.4f}" for n, a in zip(result.names, alpha0)))
    head = "".join(f"{n + ' Δα mean/std':>28}" for n in result.names)
    print(f"{'modes':>5} {'category':>9} {'δ [%]':>6} {'ok':>3}{head}")
    delta = {}
    for s in result.statistics():
        cells = "".join(f"{d['mean']:>+15.5f} {d['std']:>12.5f}" for d in s["delta_alpha"].values())
        print(f"{s['n_modes']:>5} {s['category']:>9} {100 * s['magnitude']:>6.1f} {s['succeeded']:>3}{cells}")
        delta[s["magnitude"]] = {n: (d["mean"], d["std"]) for n, d in s["delta_alpha"].items()}
    kind = {n: "ratio α(δ)/α(0) − 1" if r else "difference α(δ) − α(0), as α(0) ≈ 0"
            for n, r in s["delta_alpha_is_ratio"].items()}
    print("Δα: " + "; ".join(f"{n} {k}" for n, k in kind.items()))
    return {"alpha_reference": np.asarray(alpha0).tolist(), "delta_alpha": delta,
            "failures": sum(result.failures.values())}


if __name__ == "__main__":
    main()
