"""Assembly of shell K and M and of their tangent: jaxfem against a NumPy element loop.

Square plates of about 1k, 10k and 100k CQUAD4 (32², 100², 316²; isotropic PSHELL,
t = 10 mm aluminium, clamped along x = 0, consistent mass), built from bulk data by
``benchmarks.shell_models.plate``. For each size, in one run:

- model build: ``read_bdf_text`` + ``build_model`` (once; the bulk-data text is made
  beforehand and not timed);
- jaxfem: ``jax.jit`` of values → (K, M) element blocks (``jaxfem.assemble``, blocks
  reduced to the solved DoFs), the model split by ``jaxfem.partition`` and its array
  values passed as arguments (the NumPy structure, connectivity and DoF map, stays
  concrete); trace + compile time (``lower().compile()``) and run time apart (warm-up,
  ``block_until_ready``, median of ``--repeat`` runs);
- the tangent: ``jax.jvp`` of the same function along d(E, G, t) = (E, G, t): the moduli
  and the thickness scaled together by 1 + s (jaxfem keeps a MAT1's G, derived from E and
  ν when blank, as a value of its own, so it is scaled with E), K, M and their tangents in
  one compiled call, compile and run apart;
- NumPy: a Python loop over the elements calling the independent NumPy element
  (``benchmarks/numpy_shell.py``, K and M of one element per call, into preallocated
  element arrays); its tangent by central finite differences (two more loops at
  s = ±1e-5);
- both sides' element blocks scattered by the same function into ``scipy.sparse`` CSR
  matrices (timed apart: the element times above exclude it), and the two K, M (and
  tangents) compared.

NumPy/SciPy run single-threaded (threadpoolctl); jaxfem runs on XLA's own thread pool
(all cores) unless ``--xla-one-thread`` is given. A NumPy loop whose estimate (from a
probe of 200 elements) exceeds ``--numpy-budget`` seconds (nominal + two FD loops) is
timed on an evenly spread subsample of elements and extrapolated linearly; the output
says so. The jaxfem side is assembled in chunks (sub-models over consecutive element
ranges, one compilation each, times summed) when XLA's memory analysis of the compiled
tangent of the whole model asks for more than 40 % of the physical memory (``--chunk -1``,
the default), or always with ``--chunk N`` (at most N elements), or never (``--chunk 0``).
The output says which.

Usage: ``python -m benchmarks.perf_shell_assembly [--sizes 1000 10000 100000] [--repeat 3]
[--chunk -1] [--numpy-budget 120] [--xla-one-thread] [--json OUT]``.
"""

from __future__ import annotations

import os
import sys

if "--xla-one-thread" in sys.argv:  # must precede the jax import
    os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "")
                               + " --xla_cpu_multi_thread_eigen=false").strip()

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import equinox as eqx  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import scipy.sparse as sp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

import jaxfem  # noqa: E402
from benchmarks import numpy_shell  # noqa: E402
from benchmarks.shell_models import plate  # noqa: E402
from jaxfem.io import read_bdf_text  # noqa: E402

E, NU, RHO, T = 7.0e10, 0.3, 2700.0, 0.01
PROPERTIES = f"PSHELL,1,1,{T!r},1,1.0,1,{5 / 6!r}\nMAT1,1,{E!r},,{NU!r},{RHO!r}"
SIDES = {1000: 32, 10000: 100, 100000: 316}
STEP = 1e-5  # central finite-difference step in s
PROBE = 200  # elements timed to estimate the NumPy loops
MEMORY_SHARE = 0.4  # --chunk auto: chunks when the compiled tangent needs more of the memory


def physical_memory() -> float:
    """Bytes of physical memory (nan where unknown)."""
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError):
        return float("nan")


def peak_rss_gib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20


def build(size: int):
    side = SIDES.get(size, int(round(np.sqrt(size))))
    text = plate(1.0, 1.0, side, side, PROPERTIES, bc="cfff")
    t = time.perf_counter()
    model = jaxfem.build_model(read_bdf_text(text, name=f"plate_{side}x{side}"))
    seconds = time.perf_counter() - t
    assert len(model.quads.ids) == side * side and not len(model.trias.ids) and not model.lumped
    return model, seconds


# ---------------------------------------------------------------------------------------
# Sparse scatter, the same for both sides


def to_csr(blocks: np.ndarray, indices: np.ndarray, n: int) -> sp.csr_matrix:
    """Σ_e P_eᵀ A_e P_e as CSR: blocks (n_el, w, w) at indices (n_el, w); index n is dropped."""
    w = indices.shape[1]
    rows = np.broadcast_to(indices[:, :, None], (len(indices), w, w))
    cols = np.broadcast_to(indices[:, None, :], (len(indices), w, w))
    keep = (rows < n) & (cols < n)
    return sp.csr_matrix((blocks[keep], (rows[keep], cols[keep])), shape=(n, n))


def grid_dof_indices(model) -> np.ndarray:
    """Solved DoF of each grid component (nnode, 6), n_dof where removed. The DoF map must
    be a selection (SPCs only, no RBE2), which it is for these plates."""
    index, coef, n = model.dofs.index, model.dofs.coef, model.n_dof
    out = np.full(coef.shape[:2], n, dtype=np.int64)
    rows = np.arange(len(index))
    for c in range(6):
        nonzero = coef[:, c, :] != 0.0
        assert np.all(nonzero.sum(axis=1) <= 1), "DoF map is not a selection"
        j = np.argmax(nonzero, axis=1)
        hit = nonzero[rows, j]
        assert np.all(coef[rows[hit], c, j[hit]] == 1.0), "DoF map is not a selection"
        out[hit, c] = index[rows[hit], j[hit]]
    return out


def max_rel_diff(a: sp.spmatrix, b: sp.spmatrix) -> float:
    return float(abs(a - b).max() / abs(b).max())


# ---------------------------------------------------------------------------------------
# jaxfem


def median_run(fn, args, repeat):
    jax.block_until_ready(fn(*args))  # warm-up
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def chunks(model, chunk: int):
    """The model itself, or sub-models over consecutive element ranges of ≤ chunk quads."""
    n = len(model.quads.ids)
    if not chunk or n <= chunk:
        return [model]
    parts = np.array_split(np.arange(n), -(-n // chunk))
    return [eqx.tree_at(lambda m: m.quads, model, jax.tree.map(lambda a, p=p: a[p[0]:p[-1] + 1], model.quads))
            for p in parts]


def compile_part(part) -> dict:
    """Jitted values → (K, M) blocks and its jvp for one (sub-)model, compiled, timed."""
    values, structure = jaxfem.partition(part)
    indices = {}

    def blocks(values):
        K, M = jaxfem.assemble(eqx.combine(values, structure))
        indices["K"], indices["M"] = K.indices, M.indices  # NumPy, fixed at trace time
        return K.blocks, M.blocks

    def tangent(values, direction):
        return jax.jvp(blocks, (values,), (direction,))

    # d/ds at s = 0 of the moduli and the thickness scaled by 1 + s: E, G (a MAT1 keeps its
    # G, derived from E and ν when blank, as a value of its own) and t
    direction = jax.tree.map(jnp.zeros_like, values)
    direction = eqx.tree_at(lambda v: (v.materials.E, v.materials.G, v.shell_sections.t), direction,
                            (values.materials.E, values.materials.G, values.shell_sections.t))
    t = time.perf_counter()
    assembly = jax.jit(blocks).lower(values).compile()
    compile_s = time.perf_counter() - t
    t = time.perf_counter()
    tangent_c = jax.jit(tangent).lower(values, direction).compile()
    tangent_compile_s = time.perf_counter() - t
    stats = tangent_c.memory_analysis()
    need = None if stats is None else stats.temp_size_in_bytes + stats.output_size_in_bytes
    return {"values": values, "direction": direction, "assembly": assembly, "tangent": tangent_c,
            "indices": indices, "compile_s": compile_s, "tangent_compile_s": tangent_compile_s,
            "tangent_bytes": need}


def jaxfem_side(model, repeat: int, chunk: int) -> dict:
    """Compile and run times of the (K, M) blocks and of their jvp, and the blocks.

    ``chunk`` > 0: sub-models of at most that many elements; 0: the whole model; < 0
    (auto): the whole model unless its compiled tangent needs more than
    :data:`MEMORY_SHARE` of the physical memory (XLA's memory analysis, temporaries and
    outputs), then as many equal chunks as make each fit."""
    out = {"compile_s": 0.0, "run_s": 0.0, "tangent_compile_s": 0.0, "tangent_run_s": 0.0, "chunk_reason": ""}
    n_el = len(model.quads.ids)
    first = None
    if chunk < 0:
        first = compile_part(model)
        need, limit = first["tangent_bytes"], MEMORY_SHARE * physical_memory()
        out["tangent_gib"] = None if need is None else need / 2**30
        chunk = 0
        if need is not None and need > limit:
            chunk = -(-n_el // int(np.ceil(need / limit)))
            out["chunk_reason"] = (f"the compiled tangent of the whole model needs {need / 2**30:.1f} GiB "
                                   f"> {MEMORY_SHARE:.0%} of {physical_memory() / 2**30:.1f} GiB "
                                   f"(its compilation, {first['compile_s'] + first['tangent_compile_s']:.1f} s, "
                                   "not counted)")
            first = None
    parts = chunks(model, chunk)
    names = ("K", "M", "dK", "dM")
    blocks = {k: [] for k in names}
    idx = {k: [] for k in names}
    for i, part in enumerate(parts):
        c = first if (i == 0 and first is not None) else compile_part(part)
        out["compile_s"] += c["compile_s"]
        out["tangent_compile_s"] += c["tangent_compile_s"]
        out["run_s"] += median_run(c["assembly"], (c["values"],), repeat)
        out["tangent_run_s"] += median_run(c["tangent"], (c["values"], c["direction"]), repeat)
        (kb, mb), (dkb, dmb) = c["tangent"](c["values"], c["direction"])
        for k, bs, ix in (("K", kb, "K"), ("M", mb, "M"), ("dK", dkb, "K"), ("dM", dmb, "M")):
            blocks[k] += [np.asarray(b) for b in bs]
            idx[k] += list(c["indices"][ix])
        del c, kb, mb, dkb, dmb
    out["chunks"] = len(parts)
    out["blocks"] = {k: (np.concatenate(blocks[k]), np.concatenate(idx[k])) for k in names}
    return out


# ---------------------------------------------------------------------------------------
# NumPy


def numpy_loop(xyz, ratios, section, k6rot, elements):
    """K and M blocks (grid DoFs) of the given elements, one NumPy element call each."""
    ke = np.empty((len(elements), 24, 24))
    me = np.empty((len(elements), 24, 24))
    for i, e in enumerate(elements):
        ke[i], me[i] = numpy_shell.cquad4(xyz[e], section, k6rot, ratios[e])
    return ke, me


def numpy_side(model, budget: float) -> dict:
    n_el = len(model.quads.ids)
    xyz = np.asarray(model.xyz)[model.quads.nodes]  # (n_el, 4, 3)
    ratios = np.asarray(model.quads.t_ratio)
    k6rot = model.k6rot

    def section(s):
        return numpy_shell.pshell(E * (1 + s), NU, T * (1 + s), RHO)

    probe = np.arange(min(PROBE, n_el))
    t = time.perf_counter()
    numpy_loop(xyz, ratios, section(0.0), k6rot, probe)
    per_element = (time.perf_counter() - t) / len(probe)
    estimate = 3 * per_element * n_el
    if estimate <= budget:
        elements = np.arange(n_el)
    else:
        n_sub = int(np.clip(budget / (3 * per_element), 2 * PROBE, n_el))
        elements = np.unique(np.linspace(0, n_el - 1, n_sub).round().astype(np.int64))
    scale = n_el / len(elements)

    t = time.perf_counter()
    ke, me = numpy_loop(xyz, ratios, section(0.0), k6rot, elements)
    loop_s = time.perf_counter() - t
    t = time.perf_counter()
    kp, mp = numpy_loop(xyz, ratios, section(STEP), k6rot, elements)
    km, mm = numpy_loop(xyz, ratios, section(-STEP), k6rot, elements)
    dk, dm = (kp - km) / (2 * STEP), (mp - mm) / (2 * STEP)
    del kp, km, mp, mm
    fd_s = time.perf_counter() - t
    grid = grid_dof_indices(model)
    idx = grid[model.quads.nodes[elements]].reshape(len(elements), 24)
    return {"elements": elements, "sampled": len(elements) < n_el, "per_element_probe_s": per_element,
            "loop_s": loop_s * scale, "fd_tangent_s": fd_s * scale, "loop_measured_s": loop_s,
            "blocks": {"K": (ke, idx), "M": (me, idx), "dK": (dk, idx), "dM": (dm, idx)}}


# ---------------------------------------------------------------------------------------


def scatter_time(blocks: dict, names, n: int) -> tuple[float, dict]:
    t = time.perf_counter()
    mats = {k: to_csr(*blocks[k], n) for k in names}
    return time.perf_counter() - t, mats


def run_size(size: int, repeat: int, chunk: int, budget: float) -> dict:
    model, build_s = build(size)
    n_el, n = len(model.quads.ids), model.n_dof
    row = {"elements": n_el, "n_dof": n, "build_s": build_s}
    jx = jaxfem_side(model, repeat, chunk)
    row.update({k: v for k, v in jx.items() if k != "blocks"})
    with threadpool_limits(1):
        nps = numpy_side(model, budget)
        row.update({k: nps[k] for k in ("sampled", "loop_s", "fd_tangent_s", "loop_measured_s",
                                        "per_element_probe_s")})
        row["numpy_elements_timed"] = len(nps["elements"])
        # the same scatter for both sides: K + M, and the tangents
        row["csr_jaxfem_s"], mats_j = scatter_time(jx["blocks"], ("K", "M"), n)
        row["csr_tangent_jaxfem_s"], tan_j = scatter_time(jx["blocks"], ("dK", "dM"), n)
        mats_j.update(tan_j)
        if not nps["sampled"]:
            row["csr_numpy_s"], mats_n = scatter_time(nps["blocks"], ("K", "M"), n)
            row["csr_tangent_numpy_s"], tan_n = scatter_time(nps["blocks"], ("dK", "dM"), n)
            mats_n.update(tan_n)
        else:  # compare on the timed elements only
            sub = nps["elements"]
            mats_j = {k: to_csr(b[sub], i[sub], n) for k, (b, i) in jx["blocks"].items()}
            mats_n = {k: to_csr(*nps["blocks"][k], n) for k in mats_j}
    row["agreement"] = {k: max_rel_diff(mats_n[k], mats_j[k]) for k in ("K", "M", "dK", "dM")}
    row["peak_rss_gib"] = peak_rss_gib()
    return row


def machine() -> dict:
    return {"cpu": platform.processor() or platform.machine(), "cpu_count": os.cpu_count(),
            "cpus_usable": len(os.sched_getaffinity(0)), "memory_gib": round(physical_memory() / 2**30, 1),
            "jax": jax.__version__, "devices": [str(d) for d in jax.devices()],
            "xla_flags": os.environ.get("XLA_FLAGS", "")}


def report(rows, info, args):
    print(f"machine: {info['cpu']}, {info['cpu_count']} CPUs ({info['cpus_usable']} usable), "
          f"{info['memory_gib']} GiB; jax {info['jax']}, devices {info['devices']}")
    threads = "one thread (--xla-one-thread)" if args.xla_one_thread else "XLA's default thread pool"
    print(f"jaxfem on {threads}; NumPy/SciPy pinned to one BLAS thread (threadpoolctl); "
          f"run times: median of {args.repeat} after a warm-up\n")
    head = (f"{'elements':>9} {'DoFs':>8} {'build':>7} {'K+M run':>8} {'compile':>8} {'tangent':>8} "
            f"{'t.comp.':>8} {'NumPy K+M':>10} {'NumPy FD':>9} {'ratio':>6} {'ratio t.':>8} {'CSR K+M':>8}")
    print("times in seconds; 'tangent' = one jvp call (K, M and dK, dM); 'NumPy FD' = two more loops;")
    print("ratio = NumPy loop / jaxfem run (element blocks only, CSR scatter excluded, shown apart)")
    print(head)
    for r in rows:
        mark = "*" if r["sampled"] else " "
        print(f"{r['elements']:>9} {r['n_dof']:>8} {r['build_s']:>7.1f} {r['run_s']:>8.3f} {r['compile_s']:>8.1f} "
              f"{r['tangent_run_s']:>8.3f} {r['tangent_compile_s']:>8.1f} {r['loop_s']:>9.2f}{mark} "
              f"{r['fd_tangent_s']:>8.2f}{mark} {r['loop_s'] / r['run_s']:>6.1f} "
              f"{(r['loop_s'] + r['fd_tangent_s']) / r['tangent_run_s']:>8.1f} {r['csr_jaxfem_s']:>8.3f}")
    print()
    for r in rows:
        notes = [f"peak RSS {r['peak_rss_gib']:.1f} GiB (process so far)"]
        if r["chunks"] > 1:
            why = f", because {r['chunk_reason']}" if r["chunk_reason"] else ""
            notes.append(f"jaxfem in {r['chunks']} chunks (one compilation each, times summed){why}")
        if r.get("tangent_gib") is not None:
            notes.append(f"compiled tangent of the whole model: {r['tangent_gib']:.2f} GiB (XLA temporaries + outputs)")
        if r["sampled"]:
            notes.append(f"* NumPy extrapolated from {r['numpy_elements_timed']} of {r['elements']} elements "
                         f"(measured {r['loop_measured_s']:.1f} s for K+M; NumPy CSR scatter not timed: "
                         "the same function on blocks of the same size as jaxfem's; compared on those elements)")
        else:
            notes.append(f"CSR scatter NumPy K+M {r['csr_numpy_s']:.3f} s")
        notes.append(f"CSR scatter tangents {r['csr_tangent_jaxfem_s']:.3f} s")
        a = r["agreement"]
        notes.append("NumPy vs jaxfem (max rel.): " + ", ".join(f"{k} {v:.1e}" for k, v in a.items()))
        print(f"  {r['elements']} elements: " + "; ".join(notes))


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", type=int, default=[1000, 10000, 100000])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--chunk", type=int, default=-1,
                        help="jaxfem elements per chunk (0: none; -1, the default: only if memory is short)")
    parser.add_argument("--numpy-budget", type=float, default=120.0,
                        help="seconds for the three NumPy loops above which they are sampled")
    parser.add_argument("--xla-one-thread", action="store_true", help="XLA CPU on one thread")
    parser.add_argument("--json")
    args = parser.parse_args()
    info = machine()
    rows = []
    for size in args.sizes:
        rows.append(run_size(size, args.repeat, args.chunk, args.numpy_budget))
        print(f"[done {rows[-1]['elements']} elements]", flush=True)
    print()
    report(rows, info, args)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"machine": info, "sizes": rows}, f, indent=2)


if __name__ == "__main__":
    main()
