"""An EC 135-size updating case: the 33,000-DoF stiffened barrel, 10 parameter groups, `jaxfem update` from the command line.

Thesis §5.2.2: the EC 135 model has about 33,000 DoFs. Here the generated barrel of
``benchmarks/fuselage.py`` at that size plays the model, and a barrel with the values
of :data:`TRUTH` changed plays the structure (same mesh: the case tests the updating,
not the modelling). "Measured": its lowest :data:`N_MODES` modes (six suspension modes,
then the elastic ones) in y and z at :data:`N_GRIDS` skin grids, with Table 4.7-size
errors drawn once (:data:`NOISE`: 1 % relative on each shape component, 0.1 % of each
mode's peak uniform, 1 % on each eigenvalue λ, i.e. 0.5 % on frequency). The parameters
are ``fuselage.parameter_groups(10)``: skin E (upper and lower lobe), frame E and NSM,
stringer E, floor bending and NSM, floor-beam stiffness, joint k and suspension k.

The files are written to ``--out`` and ``jaxfem update`` runs on them as an engineer
would run it (the sparse eigensolver is chosen automatically at this size); the script
prints the command's wall time and the recovered against the true factors.

Usage: ``python -m benchmarks.fuselage_update [--n-dof 33000] [--out DIR] [--json OUT]``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

N_MODES = 20
N_GRIDS = 100
NOISE = {"relative": 0.01, "absolute": 0.001, "frequency": 0.01}
# true factors α of the parameters of fuselage.parameter_groups(10), by group name
TRUTH = {"skin upper": -0.08, "skin lower": 0.05, "frames E": 0.10, "frames nsm": 0.0, "stringers E": -0.05,
         "floor bending": 0.0, "floor nsm": 0.30, "floor beams stiffness": 0.0, "joint k": -0.5,
         "suspension k": 0.2}


def _damage() -> dict[str, float]:
    """TRUTH in the names ``barrel_bdf(damage=...)`` takes (the 20-group names)."""
    out = {}
    for name, a in TRUTH.items():
        if name.startswith("skin "):
            lobe = "U" if name.endswith("upper") else "L"
            out.update({f"skin {lobe}{i}": a for i in range(1, 7)})
        else:
            out[name] = a
    return {k: v for k, v in out.items() if v}


def write_case(out: Path, n_dof: int, seed: int = 0) -> dict:
    """Model, measured modes and parameter file in ``out``; returns the file paths."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jaxfem
    from benchmarks import fuselage
    from identification import Sensors, write_uff
    from jaxfem.io import read_bdf_text
    from updating import Noise, simulate_test

    out.mkdir(parents=True, exist_ok=True)
    model_text = fuselage.barrel_bdf(n_dof)
    (out / "barrel.bdf").write_text(model_text)
    truth = jaxfem.build_model(read_bdf_text(fuselage.barrel_bdf(n_dof, damage=_damage()), name="truth"))
    ids = np.asarray(truth.node_ids)
    skin = ids[(ids >= fuselage.SKIN) & (ids < fuselage.FLOOR)]
    grids = np.random.default_rng(seed).choice(skin, N_GRIDS, replace=False)
    sensors = Sensors.from_components(np.repeat(np.sort(grids), 2), np.tile([2, 3], N_GRIDS))
    test = simulate_test(truth, sensors, N_MODES, Noise(**NOISE), jax.random.key(seed), solver="sparse")
    xyz = {int(g): np.asarray(truth.xyz)[np.flatnonzero(ids == g)[0]] for g in np.sort(grids)}
    write_uff(out / "test.uff", nodes=xyz, modes=test)
    fuselage.write_parameters(out / "params.toml", 10, {"max_iterations": 20, "tolerance": 1e-3})
    return {"model": out / "barrel.bdf", "test": out / "test.uff", "params": out / "params.toml"}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n-dof", type=int, default=33000)
    parser.add_argument("--out", type=Path, default=Path("fuselage-update"))
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    t = time.perf_counter()
    files = write_case(args.out, args.n_dof)
    prepared = time.perf_counter() - t
    result_json = args.out / "update.json"
    cmd = [sys.executable, "-c", "from updating.cli import app; app()", "update", str(files["model"]), str(files["test"]),
           "--params", str(files["params"]), "--json", str(result_json)]
    t = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t
    print(done.stdout[-4000:])
    if done.returncode:
        print(done.stderr[-4000:], file=sys.stderr)
        raise SystemExit(done.returncode)
    res = json.loads(result_json.read_text())
    alpha = {p["name"]: p["alpha"] for p in res["parameters"]}
    rows = [{"parameter": k, "true": TRUTH[k], "updated": float(alpha[k]), "error": float(alpha[k]) - TRUTH[k]}
            for k in TRUTH]
    summary = {"n_dof": args.n_dof, "case_preparation_s": prepared, "update_wall_s": wall,
               "converged": res.get("converged"), "iterations": res.get("iterations"), "factors": rows}
    for r in rows:
        print(f"{r['parameter']:>22}  true {r['true']:+.3f}  updated {r['updated']:+.4f}  error {r['error']:+.4f}")
    print(f"jaxfem update: {wall:.0f} s wall ({summary['iterations']} iterations, converged {summary['converged']})")
    if args.json:
        args.json.write_text(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
