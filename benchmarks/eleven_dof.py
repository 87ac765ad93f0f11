"""The eleven-DoF force-appropriation study of thesis §5.4.1 (Tables 5.6–5.10).

A chain of 11 masses (Table 5.6): mass 6 is tied to ground by k6 = 18000 N/m, each other
mass i to its neighbour on the side of mass 6 by k_i (symmetric about mass 6); viscous
damping D = 10⁻³ s · K; the responses (eq. 5.3, eq. 5.4) are evaluated at the undamped natural
frequencies. For the exciter sets "2,4", "2,10", "4,6", "2,4,8,10" the four methods give
the MIF tables of the thesis: Lewis & Wrisley (Table 5.7), Asher (5.8), Hunt et al.
(5.9) and the thesis' method of §3.4 (5.10); they are compared entry by entry with the
thesis values transcribed below ("-" in the thesis: None).

Usage: ``python benchmarks/eleven_dof.py [--json OUT] [--close-pair-fit]``.

``--close-pair-fit`` evaluates modes 1 and 2 (1.7109 Hz and 1.8170 Hz, 0.1 Hz apart)
at f₁ − 1.36·10⁻⁴ Hz and f₂ − 3.94·10⁻⁴ Hz instead of the exact natural frequencies. The
thesis does not state its evaluation frequencies; these two offsets were fitted to the
eight Table 5.10 entries of modes 1–2 (one offset per mode, minimising the largest
difference) and then reproduce them within 2.3 points, and Table 5.7's within 5.4
points. With so little damping (ζ ≈ 0.55 %) the MIF of these two modes moves by tens of
points for 10⁻⁴ Hz; the higher modes are insensitive to such offsets.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from identification._phase_resonance import appropriate

MASSES_HALF = (1.0, 6.0, 1.0, 0.6, 1.0)  # DoFs 1..5 (= 11..7), Table 5.6
SPRINGS_HALF = (2421.4, 2989.4, 3690.6, 4556.3, 5625.0)  # N/m, DoFs 1..5 (= 11..7)
MASS_6, SPRING_6 = 1.0, 18000.0
KAPPA = 1e-3  # s, D = κK (§5.4.1)
SETS = ("2,4", "2,10", "4,6", "2,4,8,10")
METHOD_KEYS = {"thesis_method": "thesis", "lewis_wrisley": "lewis_wrisley", "asher": "asher", "hunt": "hunt"}
TABLE_NUMBERS = {"lewis_wrisley": "5.7", "asher": "5.8", "hunt": "5.9", "thesis_method": "5.10"}
TOLERANCE = 15.0  # MIF points
CLOSE_PAIR_OFFSETS_HZ = (-1.36e-4, -3.94e-4)  # fitted to Table 5.10, modes 1 and 2 (see above)

_ = None
THESIS_TABLES = {
    "lewis_wrisley": {  # Table 5.7
        "2,4": [919, 899, 782, 580, 612, 701, 468, 577, 820, 730, 46],
        "2,10": [980, 961, 143, 577, 926, 884, 813, 724, 140, 129, 1],
        "4,6": [933, 886, 809, 467, 486, 695, 871, 549, 829, 725, 918],
        "2,4,8,10": [980, 961, 916, 952, 859, 964, 821, 675, 921, 884, 66],
    },
    "asher": {  # Table 5.8
        "2,4": [6, 26, _, _, _, 709, _, _, _, _, _],
        "2,10": [_, _, _, _, 717, 884, _, _, _, _, _],
        "4,6": [929, 908, 852, _, 536, _, _, _, 826, _, 924],
        "2,4,8,10": [967, _, 752, _, 493, 907, 165, _, _, _, _],
    },
    "hunt": {  # Table 5.9
        "2,4": [914, 913, 676, 580, 599, 690, 110, 553, 820, 730, 46],
        "2,10": [941, 911, 143, 577, 926, 884, 813, 724, 140, 129, 1],
        "4,6": [920, 904, 919, 531, 521, 856, 510, 403, 823, 721, 924],
        "2,4,8,10": [965, 951, 961, 907, 852, 929, 124, 634, 921, 884, 66],
    },
    "thesis_method": {  # Table 5.10
        "2,4": [976, 955, 788, 733, 705, 711, 631, 641, 821, 731, 46],
        "2,10": [985, 960, 143, 577, 926, 884, 813, 724, 140, 131, 1],
        "4,6": [984, 959, 920, 769, 664, 858, 904, 558, 844, 731, 925],
        "2,4,8,10": [987, 964, 987, 964, 927, 969, 827, 841, 930, 889, 66],
    },
}


def eleven_dof_model() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K (N/m), M (kg), D = κK (N·s/m) of the eleven-DoF system (Table 5.6)."""
    m = np.array([*MASSES_HALF, MASS_6, *MASSES_HALF[::-1]])
    k = np.array([*SPRINGS_HALF, SPRING_6, *SPRINGS_HALF[::-1]])
    K = np.zeros((11, 11))
    for i in range(11):
        if i == 5:
            K[5, 5] += k[5]  # mass 6 to ground
            continue
        j = i + 1 if i < 5 else i - 1  # neighbour on the side of mass 6
        K[np.ix_([i, j], [i, j])] += k[i] * np.array([[1.0, -1.0], [-1.0, 1.0]])
    return K, np.diag(m), KAPPA * K


def natural_frequencies_hz() -> np.ndarray:
    import scipy.linalg as sl

    K, M, _D = eleven_dof_model()
    return np.sqrt(sl.eigh(K, M, eigvals_only=True)) / (2.0 * np.pi)


def exciters(key: str) -> list[int]:
    """0-based DoF indices of a thesis exciter set such as "2,4,8,10"."""
    return [int(s) - 1 for s in key.split(",")]


def eleven_dof_tables(close_pair_fit: bool = False) -> dict[str, dict[str, list[float | None]]]:
    """The four MIF tables: ``{method key: {exciter set: [11 MIFs or None]}}``."""
    K, M, D = eleven_dof_model()
    f = natural_frequencies_hz()
    if close_pair_fit:
        f[:2] += np.asarray(CLOSE_PAIR_OFFSETS_HZ)
    tables = {}
    for key, method in METHOD_KEYS.items():
        tables[key] = {
            s: [a.mif for a in appropriate(K, M, D, exciters(s), method=method, frequencies_hz=f)] for s in SETS
        }
    return tables


def compare(tables: dict) -> dict:
    """Entry-by-entry differences (ours − thesis) and the count within ±TOLERANCE.

    An entry agrees when both values exist and differ by at most TOLERANCE, or when
    neither method finds a force vector; ``presence`` counts entries where both sides
    agree on whether a force vector exists.
    """
    out = {}
    for key, ours in tables.items():
        ref = THESIS_TABLES[key]
        diff, within, presence, total = {}, 0, 0, 0
        for s in SETS:
            row = []
            for a, b in zip(ours[s], ref[s]):
                total += 1
                presence += (a is None) == (b is None)
                if a is None or b is None:
                    row.append(None)
                    within += a is None and b is None
                else:
                    row.append(a - b)
                    within += abs(a - b) <= TOLERANCE
            diff[s] = row
        out[key] = {"table": TABLE_NUMBERS[key], "differences": diff, "within": within, "total": total,
                    "fraction_within": within / total, "presence_agrees": presence}
    return out


def _fmt(x) -> str:
    return "   -" if x is None else f"{x:4.0f}"


def print_tables(tables: dict, comparison: dict) -> None:
    for key in ("lewis_wrisley", "asher", "hunt", "thesis_method"):
        c = comparison[key]
        print(f"\nTable {c['table']} ({key}): ours | thesis | difference   "
              f"[{c['within']}/{c['total']} within ±{TOLERANCE:.0f}]")
        print(f"{'mode':>9}: " + " ".join(f"{i:4d}" for i in range(1, 12)))
        for s in SETS:
            print(f"{s:>9}: " + " ".join(_fmt(x) for x in tables[key][s]))
            print(f"{'thesis':>9}: " + " ".join(_fmt(x) for x in THESIS_TABLES[key][s]))
            print(f"{'diff':>9}: " + " ".join(_fmt(x) for x in c["differences"][s]))


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", metavar="OUT", help="write tables, thesis values and differences to OUT")
    parser.add_argument("--close-pair-fit", action="store_true",
                        help="evaluate modes 1-2 at the fitted frequency offsets (see module docstring)")
    args = parser.parse_args(argv)
    tables = eleven_dof_tables(args.close_pair_fit)
    comparison = compare(tables)
    print("Eleven-DoF system, thesis §5.4.1; natural frequencies (Hz):",
          " ".join(f"{x:.4f}" for x in natural_frequencies_hz()))
    print_tables(tables, comparison)
    report = {
        "tables": tables,
        "thesis": THESIS_TABLES,
        "comparison": comparison,
        "tolerance": TOLERANCE,
        "close_pair_fit": bool(args.close_pair_fit),
        "natural_frequencies_hz": natural_frequencies_hz().tolist(),
    }
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(report, fh, indent=1)
    return report


if __name__ == "__main__":
    main()
