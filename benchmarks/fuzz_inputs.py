"""Mutation fuzzing of the readers: every mutant must end in a result, a warning or a located error.

Bulk data: the bundled models (``updating/data/*.bdf``, ``tests/data/*.bdf``) through
``read_bdf_text`` and ``build_model``. Universal files: files written here in the layouts
of the exporters (modes with nodes, units and coordinate systems; FRFs) through
``read_uff``. Each mutant is one random edit of one file: a character replaced, a line
deleted, duplicated or swapped with the next, the file cut short, or a field replaced by
a hostile token (1.E400, nan, a 20-digit id, a non-ASCII digit, a BOM, a form feed, a
negative value).

Outcome classes:

- ``ok``: read (and built) with no warning;
- ``warned``: read with a ``UserWarning``;
- ``located``: ``ValueError`` naming the file and where (a line, a card, a dataset);
- ``unlocated``: ``ValueError`` that names neither;
- ``lost``: a universal file read with no error and no warning but with fewer modes,
  nodes or FRFs than the file it came from (silent data loss);
- ``shorter``: the same, for a file cut just after a dataset's closing ``-1``: a whole,
  valid file with fewer datasets, which no reader can tell from the original;
- ``uncaught``: any other exception (a bug).

Sensor lists: the bundled ``*_sensors.csv`` through ``Sensors.read_csv`` (``lost``: a
non-blank row that became neither a sensor nor an error).

``python -m benchmarks.fuzz_inputs --bdf 5000 --uff 1000 --csv 500 --seed 0`` prints the counts per
class and the first examples of ``unlocated``, ``lost`` and ``uncaught``.
"""

from __future__ import annotations

import argparse
import random
import re
import sys
import tempfile
import time
import traceback
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
HOSTILE = ["1.E400", "nan", "-inf", "123456789012345678901", "١٢", "\ufeff", "\f", "\u2028", "-1.", "0.", "", "1.7",
           "THRU", "99999999"]
_WHERE = re.compile(r"line \d+|dataset #\d+|\.bdf:\d+|\.uff|\.csv|card|field", re.IGNORECASE)


def mutate(text: str, rng: random.Random) -> tuple[str, str]:
    """One random edit of ``text``; returns (mutant, what was done)."""
    lines = text.split("\n")
    i = rng.randrange(len(lines))
    kind = rng.choice(["char", "delete", "duplicate", "swap", "cut", "token"])
    if kind == "char" and lines[i]:
        j = rng.randrange(len(lines[i]))
        lines[i] = lines[i][:j] + rng.choice("0123456789.,+-eE*$ \tX") + lines[i][j + 1:]
    elif kind == "delete":
        del lines[i]
    elif kind == "duplicate":
        lines.insert(i, lines[i])
    elif kind == "swap" and i + 1 < len(lines):
        lines[i], lines[i + 1] = lines[i + 1], lines[i]
    elif kind == "cut":
        return "\n".join(lines[:i]), f"cut at line {i + 1}"
    else:
        kind = "token"
        fields = lines[i].split(",") if "," in lines[i] else [lines[i][k:k + 8] for k in range(0, len(lines[i]), 8)]
        if fields:
            j = rng.randrange(len(fields))
            fields[j] = rng.choice(HOSTILE)
            lines[i] = ("," if "," in lines[i] else "").join(fields)
    return "\n".join(lines), f"{kind} at line {i + 1}"


def _classify(run) -> tuple[str, str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            lost = run()
        except ValueError as err:
            message = str(err)
            return ("located" if _WHERE.search(message) else "unlocated"), message
        except Exception as err:  # noqa: BLE001 - the point is to catch what should not happen
            return "uncaught", "".join(traceback.format_exception_only(type(err), err)).strip()
    if lost:
        return ("warned" if caught else "lost"), lost
    return ("warned", str(caught[0].message)) if caught else ("ok", "")


def _bdf_sources() -> list[tuple[str, str]]:
    files = sorted((ROOT / "updating" / "data").glob("*.bdf")) + sorted((ROOT / "tests" / "data").glob("*.bdf"))
    return [(f.name, f.read_text()) for f in files if f.stat().st_size < 2_000_000]


def _uff_sources(folder: Path) -> list[tuple[str, str, tuple[int, int, int]]]:
    """Universal files written here (ASCII): modes with nodes, units and systems; FRFs."""
    import pyuff

    from identification import FRFData, ModalData, Sensors, read_uff, write_uff

    rng = np.random.default_rng(0)
    nodes = {g: rng.uniform(-1, 1, 3) for g in range(1, 9)}
    sensors = Sensors.from_components([g for g in nodes for _ in range(3)], [1, 2, 3] * len(nodes))
    modes = ModalData(np.array([5.0, 12.0, 20.0, 31.0]), rng.normal(size=(len(sensors), 4)), sensors,
                      damping_ratios=[0.01, 0.02, 0.01, 0.03])
    out = []
    path = folder / "modes.uff"
    write_uff(path, nodes=nodes, modes=modes, units={"length": 1000.0, "force": 1.0})
    axes = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    system = {"type": 2420, "Part_UID": 1, "Part_Name": "fuzz", "CS_sys_labels": [7], "CS_types": [0],
              "CS_colors": [8], "CS_names": ["CS7"], "CS_matrices": [np.vstack([axes, [10.0, 0.0, 0.0]])]}
    pyuff.UFF(str(path)).write_sets([system], mode="add")
    f = np.linspace(1.0, 50.0, 40)
    frfs = FRFData(f, rng.normal(size=(40, 2, 1)) + 1j * rng.normal(size=(40, 2, 1)),
                   Sensors.from_components([1, 2], [3, 3]), Sensors.from_components([1], [3]), "accelerance")
    frf_path = folder / "frfs.uff"
    write_uff(frf_path, frfs=frfs)
    for p in (path, frf_path):
        data = read_uff(p)
        counts = (0 if data["modes"] is None else data["modes"].n_modes, len(data["nodes"]),
                  0 if data["frfs"] is None else data["frfs"].values.shape[1] * data["frfs"].values.shape[2])
        out.append((p.name, p.read_text(errors="surrogateescape"), counts))
    return out


def fuzz_bdf(n: int, rng: random.Random) -> tuple[Counter, dict]:
    import jaxfem
    from jaxfem.io import read_bdf_text

    sources = _bdf_sources()
    counts, examples = Counter(), {}
    for _ in range(n):
        name, text = rng.choice(sources)
        mutant, what = mutate(text, rng)

        def run():
            jaxfem.build_model(read_bdf_text(mutant, name=name))

        outcome, message = _classify(run)
        counts[outcome] += 1
        examples.setdefault(outcome, []).append(f"{name}, {what}: {message[:300]}")
    return counts, examples


def fuzz_uff(n: int, rng: random.Random) -> tuple[Counter, dict]:
    from identification import read_uff

    counts, examples = Counter(), {}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        sources = _uff_sources(folder)
        for k in range(n):
            name, text, (n_modes, n_nodes, n_frfs) = rng.choice(sources)
            mutant, what = mutate(text, rng)
            path = folder / f"mutant_{k}.uff"
            path.write_text(mutant, errors="surrogateescape")

            def run():
                data = read_uff(path)
                got = (0 if data["modes"] is None else data["modes"].n_modes, len(data["nodes"]),
                       0 if data["frfs"] is None else data["frfs"].values.shape[1] * data["frfs"].values.shape[2])
                if any(g < e for g, e in zip(got, (n_modes, n_nodes, n_frfs))):
                    return f"modes, nodes, FRFs {got} of {(n_modes, n_nodes, n_frfs)}"
                return None

            outcome, message = _classify(run)
            last = [line for line in mutant.split("\n") if line.strip()][-1:] or [""]
            if outcome == "lost" and what.startswith("cut") and last[0].rstrip().endswith("    -1"):
                outcome = "shorter"
            path.unlink()
            counts[outcome] += 1
            examples.setdefault(outcome, []).append(f"{name}, {what}: {message[:300]}")
    return counts, examples


def fuzz_csv(n: int, rng: random.Random) -> tuple[Counter, dict]:
    """The bundled sensor lists through ``Sensors.read_csv``: every non-blank row after the
    header must become a sensor or an error (``lost`` otherwise)."""
    from identification import Sensors

    files = sorted((ROOT / "updating" / "data").glob("*_sensors.csv"))
    sources = [(f.name, f.read_text()) for f in files]
    counts, examples = Counter(), {}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "sensors.csv"
        for _ in range(n):
            name, text = rng.choice(sources)
            mutant, what = mutate(text, rng)
            path.write_text(mutant, errors="surrogateescape")

            def run():
                rows = [line for line in mutant.splitlines()[1:] if line.strip()]
                got = len(Sensors.read_csv(path))
                return f"{got} sensors of {len(rows)} rows" if got < len(rows) else None

            outcome, message = _classify(run)
            counts[outcome] += 1
            examples.setdefault(outcome, []).append(f"{name}, {what}: {message[:300]}")
    return counts, examples


def _print(title: str, counts: Counter, examples: dict, seconds: float) -> int:
    total = sum(counts.values())
    print(f"{title}: {total} mutants in {seconds:.0f} s")
    for outcome in ("ok", "warned", "located", "unlocated", "shorter", "lost", "uncaught"):
        print(f"  {outcome:<10} {counts.get(outcome, 0):>6}")
    for outcome in ("unlocated", "lost", "uncaught"):
        for line in examples.get(outcome, [])[:5]:
            print(f"    {outcome}: {line}")
    return counts.get("uncaught", 0) + counts.get("lost", 0)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bdf", type=int, default=1000, help="bulk-data mutants")
    parser.add_argument("--uff", type=int, default=500, help="universal-file mutants")
    parser.add_argument("--csv", type=int, default=200, help="sensor-list mutants")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    import jax

    jax.config.update("jax_enable_x64", True)
    rng = random.Random(args.seed)
    bad = 0
    for title, n, run in (("bulk data", args.bdf, fuzz_bdf), ("universal files", args.uff, fuzz_uff),
                          ("sensor lists", args.csv, fuzz_csv)):
        if n:
            start = time.perf_counter()
            counts, examples = run(n, rng)
            bad += _print(title, counts, examples, time.perf_counter() - start)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
