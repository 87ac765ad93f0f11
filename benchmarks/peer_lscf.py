"""Peer check of the modal fitting: our pLSCF + LSFD against sdypy-EMA's LSCF on the same FRFs.

sdypy-EMA (https://github.com/sdypy/sdypy-EMA) is NOT a jaxfem dependency: install it by
hand for this script (``pip install sdypy-EMA``). Without it only our results are shown,
with a line saying so.

Data (one input, as sdypy-EMA's LSCF is single-reference): receptances of

- ``chain5``: a 5-DoF spring–mass chain, modes 7.9–50.8 Hz, ζ = 1–2 %, input at DoF 5;
- ``pair``: two oscillators coupled so their modes are 1.00 % apart (ζ = 1 %: one peak)
  plus two more DoFs, input at DoF 1 (which does not see the other two modes);

exact modal superposition with complex Gaussian noise of 1 % of |H| (seed fixed).

- ours: :func:`identification._fitting.identify`, orders 2–40, fully automatic
  (stabilisation, clustering of stable poles, LSFD with residuals);
- sdypy-EMA: ``Model(..., pol_order_high=20)`` (its orders 2, 4, … 40), ``get_poles()``
  (LSCF), at order 40 the pole nearest each TRUE frequency (it needs frequencies to pick
  from, and is handed the exact ones; its own ``select_closest_poles`` misses modes, see
  :func:`run_sdypy`), and ``get_constants()`` (LSFD with residuals).

Reported per mode: frequency and damping errors against the exact values, MAC against
the exact mode shape, and the wall time of each full identification (best of
``--repeat`` after a warm-up; both are NumPy on the host, BLAS held to one thread
unless OPENBLAS_NUM_THREADS / OMP_NUM_THREADS are set, so a shared machine times
alike). Our time covers 39 model orders, sdypy-EMA's its 20. Usage:
``python -m benchmarks.peer_lscf [--repeat 3] [--json OUT]`` (from the repository root).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
import warnings

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # before NumPy loads its BLAS

import numpy as np
import scipy
import scipy.linalg as sl
from scipy.optimize import brentq

from identification import FRFData, Sensors
from identification._fitting import identify


def _modes(M, K, zeta):
    lam, phi = sl.eigh(K, M)
    return np.sqrt(lam) / (2 * np.pi), phi, np.broadcast_to(np.asarray(zeta, dtype=np.float64), lam.shape).copy()


def _stiffness(n, springs):
    K = np.zeros((n, n))
    for i, j, k in springs:
        idx = [i] if j is None else [i, j]
        K[np.ix_(idx, idx)] += k * (np.eye(1) if j is None else np.array([[1.0, -1.0], [-1.0, 1.0]]))
    return K


def chain5():
    M = np.diag([1.0, 1.2, 0.9, 1.1, 1.0])
    K = _stiffness(5, [(0, None, 4e4), (0, 1, 3e4), (1, 2, 3e4), (2, 3, 2.5e4), (3, 4, 2e4)])
    return M, K, [0.01, 0.012, 0.015, 0.01, 0.02], np.arange(0.0, 120.0, 0.05), 4, 5


def pair():
    def build(kc):
        springs = [(0, None, 1.2e4), (1, None, 1e4), (0, 1, kc), (2, None, 3e4), (1, 2, 2e3), (3, None, 5e4),
                   (2, 3, 5e3)]
        return np.diag([1.0, 1.0, 0.5, 0.8]), _stiffness(4, springs)

    kc = brentq(lambda kc: np.divide(*_modes(*build(kc), 0.01)[0][[1, 0]]) - 1.01, 0.0, 2000.0)
    M, K = build(kc)
    return M, K, [0.01, 0.01, 0.015, 0.01], np.arange(0.0, 80.0, 0.02), 0, 2  # only the pair is seen at DoF 1


def simulate(case, noise=0.01, seed=0):
    M, K, zeta, f, drive, n_seen = case()
    fn, phi, zeta = _modes(M, K, zeta)
    w, wn = 2 * np.pi * f, 2 * np.pi * fn
    den = wn[None, :] ** 2 - w[:, None] ** 2 + 2j * zeta[None, :] * wn[None, :] * w[:, None]
    h = np.einsum("or,r,kr->ko", phi, phi[drive], 1 / den)[:, :, None]
    rng = np.random.default_rng(seed)
    h = h * (1 + noise * (rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape)) / np.sqrt(2))
    n = len(M)
    frfs = FRFData(f, h, Sensors.from_components(np.arange(1, n + 1), [3] * n),
                   Sensors.from_components([drive + 1], [3]), "receptance")
    return frfs, fn[:n_seen], zeta[:n_seen], phi[:, :n_seen], drive


def _mac(a, b):
    return float(np.abs(np.vdot(a, b)) ** 2 / (np.vdot(a, a).real * np.vdot(b, b).real))


def _best(fn, repeat):
    fn()  # warm-up
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return out, min(times)


def run_ours(frfs):
    modes, _ = identify(frfs)
    return modes.frequencies_hz, modes.damping_ratios, np.asarray(modes.shapes)


def run_sdypy(frfs, approx_hz):
    """sdypy-EMA LSCF poles at its highest order, the one nearest each given frequency, then its LSFD.

    (Its ``select_closest_poles`` picks no pole for 3 of the 5 chain modes even on
    noise-free data — its stability test at 0.1 % — so the choice is made here.)
    """
    from sdypy import EMA

    model = EMA.Model(frf=np.asarray(frfs.values)[:, :, 0].T, freq=frfs.frequencies_hz,
                      lower=float(frfs.frequencies_hz[1]), upper=float(frfs.frequencies_hz[-1]),
                      pol_order_high=20, frf_form="receptance")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model.get_poles(method="lscf", show_progress=False)
        last = len(model.all_poles) - 1
        freq = np.asarray(model.pole_freq[last])
        picks = [int(np.argmin(np.abs(freq - f))) for f in approx_hz]
        model.pole_ind = np.array([[last, k] for k in picks])
        model.get_constants(method="lsfd")
    return freq[picks], np.asarray(model.pole_xi[last])[picks], np.asarray(model.A)


def _match(f_true, f_found):
    """Index of the identified mode nearest each true one (None when none within 2 %)."""
    out = []
    for f in f_true:
        k = int(np.argmin(np.abs(np.asarray(f_found) - f))) if len(f_found) else None
        out.append(k if k is not None and abs(f_found[k] / f - 1) < 0.02 else None)
    return out


def compare(name, frfs, fn, zeta, phi, repeat, have_sdypy):
    rows, timing = [], {}
    results = {"ours": _best(lambda: run_ours(frfs), repeat)}
    if have_sdypy:
        results["sdypy-EMA"] = _best(lambda: run_sdypy(frfs, fn), repeat)
    for method, ((f, z, shapes), seconds) in results.items():
        timing[method] = seconds
        for r, k in enumerate(_match(fn, f)):
            row = {"case": name, "method": method, "mode": r + 1, "f_true_hz": float(fn[r]),
                   "zeta_true": float(zeta[r])}
            if k is None:
                row.update(f_hz=None, df_percent=None, zeta=None, dzeta_percent=None, mac=None)
            else:
                row.update(f_hz=float(f[k]), df_percent=float(100 * (f[k] / fn[r] - 1)), zeta=float(z[k]),
                           dzeta_percent=float(100 * (z[k] / zeta[r] - 1)), mac=_mac(shapes[:, k], phi[:, r]))
            rows.append(row)
    return rows, timing


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", metavar="OUT")
    args = parser.parse_args(argv)
    try:
        import sdypy.EMA  # noqa: F401

        have_sdypy, version = True, _version("sdypy-EMA")
    except ImportError:
        have_sdypy, version = False, None
        print("sdypy-EMA is not installed: it is not a jaxfem dependency; `pip install sdypy-EMA` to compare. "
              "Only our results are shown.\n")
    machine = {"platform": platform.platform(), "processor": platform.processor(), "python": platform.python_version(),
               "cpus": os.cpu_count(), "blas_threads": os.environ["OPENBLAS_NUM_THREADS"], "numpy": np.__version__,
               "scipy": scipy.__version__, "sdypy-EMA": version}
    rows, timings = [], {}
    for name, case in (("chain5", chain5), ("pair", pair)):
        frfs, fn, zeta, phi, _ = simulate(case)
        case_rows, timing = compare(name, frfs, fn, zeta, phi, args.repeat, have_sdypy)
        rows += case_rows
        timings[name] = timing
    print(f"machine: {machine}")
    print(f"{'case':7} {'mode':>4} {'method':10} {'f_true Hz':>10} {'f Hz':>10} {'Δf %':>9} {'ζ_true':>7} "
          f"{'ζ':>8} {'Δζ %':>8} {'MAC':>8}")
    for r in rows:
        if r["f_hz"] is None:
            print(f"{r['case']:7} {r['mode']:>4} {r['method']:10} {r['f_true_hz']:10.4f} {'missed':>10}")
            continue
        print(f"{r['case']:7} {r['mode']:>4} {r['method']:10} {r['f_true_hz']:10.4f} {r['f_hz']:10.4f} "
              f"{r['df_percent']:9.4f} {r['zeta_true']:7.4f} {r['zeta']:8.5f} {r['dzeta_percent']:8.3f} "
              f"{r['mac']:8.5f}")
    print(f"\nwall time per full identification, s (best of {args.repeat} after a warm-up):")
    for name, timing in timings.items():
        line = ", ".join(f"{m} {t:.3f}" for m, t in timing.items())
        ratio = f"  (ours / sdypy-EMA = {timing['ours'] / timing['sdypy-EMA']:.2f})" if "sdypy-EMA" in timing else ""
        print(f"  {name}: {line}{ratio}")
    if args.json:
        with open(args.json, "w") as out:
            json.dump({"machine": machine, "rows": rows, "seconds": timings}, out, indent=2)


def _version(name):
    from importlib.metadata import version

    return version(name)


if __name__ == "__main__":
    main()
