"""Test and model mode shapes moving side by side: one interactive, self-contained HTML file.

:func:`shape_view` draws the test wireframe (sensor nodes as markers, and the trace lines
of UFF dataset 82 where the file has them; markers only where it has none: lines guessed
from proximity could join parts that are not joined) and the FE model (its element
edges: beams, rods, bushes and springs as lines, CQUAD4/CTRIA3 by their edges), and for
each paired mode animates both shapes, ``x(t) = x₀ + a·u·sin(2πk/n)`` with n =
:data:`PHASES` frames a cycle, in two 3-D scenes side by side (one camera) or overlaid in
one, with a pair chooser, play/pause and a phase slider; f_test, f_model, Δf and MAC in
the title. Each shape is scaled on its own so that its largest translation ``a`` is
:data:`DEFORMATION` of the structure's extent (the largest side of the bounding box of
grids and test nodes). plotly's JavaScript is embedded (``include_plotlyjs=True``): the
file opens offline and loads nothing from elsewhere. The page's address may choose the
start: ``shapes.html#pair=2&view=overlay&phase=6`` (a phase stops the animation).

Large models: at most :data:`MAX_EDGES` element edges are drawn, beams, rods and
springs first, then the shells' feature edges (free edges and edges between properties),
then an evenly spaced share of the remaining shell edges; grids are drawn as markers only
up to :data:`MAX_GRID_MARKERS` grids.

:func:`correlation_view` prepares the arrays from a correlation (mode vectors over the
solved DoFs, measured shapes at the sensors, a :class:`Pairing`); :func:`measured_geometry`
gives the test nodes and trace lines in the model's frame.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
from jaxtyping import ArrayLike, Float

from jaxfem import Model

from ._shape_traces import _page

DEFORMATION = 0.10  # largest translation of each drawn shape, as a fraction of the structure's extent
MAX_EDGES = 20_000  # model element edges drawn at most (feature edges first)
MAX_GRID_MARKERS = 2_000  # model grids drawn as markers up to this many grids
PHASES = 24  # animation frames per cycle
FRAME_MS = 60  # time per frame

def grid_translations(model: Model, phi: Float[ArrayLike, "ndof m"]) -> Float[np.ndarray, "nnode 3 m"]:
    """Translations of every grid in mode vectors over the solved DoFs.

    ``u[g, c] = coef[g, c] · φ[index[g]]`` (:class:`jaxfem.DofMap`), so constrained
    components read zero and an RBE2/RBE3/MPC-dependent grid moves with the DoFs it
    depends on. **Arguments:** the model and ``φ`` (n_dof, m) (or one vector (n_dof,)).
    **Returns:** (n_grid, 3, m), components T1 T2 T3 in basic axes.
    """
    phi = np.asarray(phi)
    if phi.ndim == 1:
        phi = phi[:, None]
    if phi.ndim != 2 or phi.shape[0] != model.n_dof:
        raise ValueError(f"mode vectors have shape {phi.shape}; expected ({model.n_dof}, m) for this model")
    if np.iscomplexobj(phi):
        raise ValueError("mode vectors are complex; give real normal modes")
    from scipy.sparse import csr_matrix

    index, coef = np.asarray(model.dofs.index), np.asarray(model.dofs.coef)[:, :3]
    n = len(index)
    # sparse (3 n_grid, n_dof): a dense gather would be n_grid × width × m, and one RBE3 widens every grid
    g, c, k = np.nonzero((coef != 0.0) & (index < model.n_dof)[:, None, :])
    T = csr_matrix((coef[g, c, k], (3 * g + c, index[g, k])), shape=(3 * n, model.n_dof))
    return np.asarray(T @ phi.astype(np.float64)).reshape(n, 3, phi.shape[1])


def measured_translations(sensors, shapes: Float[ArrayLike, "n m"]) -> dict[int, np.ndarray]:
    """Translations of the measured nodes from shapes at sensors.

    A node's translational sensors read ``D u = y`` (rows of D: their unit directions,
    skew ones included); ``u = D⁺ y``, the least-squares solution of least length: with
    three independent directions the full translation, with fewer the measured
    components only (nothing along directions not measured). Rotational sensors are
    not drawn. **Arguments:** :class:`identification.Sensors` and real shapes
    (n_sensors, m). **Returns:** {node id: (3, m)}.
    """
    shapes = np.asarray(shapes)
    if np.iscomplexobj(shapes):
        raise ValueError("test shapes are complex; give real normal modes (ModalData.real())")
    nodes, directions = np.asarray(sensors.nodes), np.asarray(sensors.directions)
    rotational = np.asarray(sensors.rotational, dtype=bool)
    if shapes.ndim != 2 or shapes.shape[0] != len(nodes):
        raise ValueError(f"test shapes have shape {shapes.shape}; expected ({len(nodes)}, m), one row per sensor")
    out = {}
    for node in np.unique(nodes[~rotational]).tolist():
        rows = np.flatnonzero((nodes == node) & ~rotational)
        out[int(node)] = np.linalg.pinv(directions[rows]) @ shapes[rows].astype(np.float64)
    return out


def measured_geometry(content: dict | None = None, gmap=None
                      ) -> tuple[dict[int, np.ndarray], list[tuple[int, int]], dict[int, int]]:
    """The test nodes and trace lines to draw, in the model's frame.

    **Arguments:** what :func:`identification.read_uff` read from the universal file
    (``nodes``: datasets 15/2411, ``lines``: 82) and the
    :class:`identification.GeometryMap` that put the measured nodes on the model (None:
    the file's coordinates are the model's). **Returns:** ``(nodes, lines, names)``:
    {test node id: xyz m}, trace lines between them (node-id pairs), and {sensor node id
    in the mapped data: test node id}. The measured nodes are placed where the map put
    them; the others (trace-line corners without sensors) are moved by the map's rigid
    alignment, and left out, with their lines, when the file's coordinates of the
    measured nodes do not land on the mapped ones (another unit): no node is drawn where
    it was neither measured nor mapped.
    """
    content = content or {}
    raw = {int(k): np.asarray(v, np.float64) for k, v in content.get("nodes", {}).items()}
    lines = list(content.get("lines", []))
    if gmap is None:
        nodes, names = raw, {}
    else:
        measured = [int(n) for n in np.asarray(gmap.nodes).tolist()]
        mapped = np.asarray(gmap.xyz, np.float64).reshape(-1, 3)
        nodes = dict(zip(measured, mapped))
        names = {int(gmap.renamed.get(n, n)): n for n in measured}
        a = gmap.alignment
        moved = {n: (x @ np.asarray(a["rotation"]).T + np.asarray(a["translation"]) if a is not None else x)
                 for n, x in raw.items()}
        known = [k for k, n in enumerate(measured) if n in moved]
        size = float(np.ptp(mapped, axis=0).max()) if len(mapped) else 0.0
        if known and np.allclose([moved[measured[k]] for k in known], mapped[known], rtol=0.0, atol=1e-6 * size):
            nodes = {**moved, **nodes}
    return nodes, [(p, q) for p, q in lines if p in nodes and q in nodes], names


def correlation_view(
    path: str | os.PathLike,
    *,
    model: Model,
    phi: Float[ArrayLike, "ndof n_a"],
    test,
    at_sensors: Float[ArrayLike, "ns n_a"],
    pairing,
    test_nodes: Mapping[int, ArrayLike] | None = None,
    test_lines: Sequence[tuple[int, int]] = (),
    names: Mapping[int, int] | None = None,
    title: str = "test and model mode shapes",
) -> Path:
    """:func:`shape_view` of a correlation.

    **Arguments:** the model and its mode vectors ``phi`` over the solved DoFs; the
    measured modes (:class:`identification.ModalData`, real) and the model modes at the
    same sensors ``at_sensors`` (C φ); the :class:`Pairing` of the two (indices into the
    columns of ``phi`` and the test modes); the test nodes {id: xyz m} and trace lines
    (:func:`measured_geometry`); ``names``: {sensor node id: test node id} where they differ.
    A measured node missing from ``test_nodes`` is drawn at the model grid of its sensor
    id. Each model shape's sign is chosen so that it moves with its test shape at the
    sensors (``φ_eᵀ C φ_a ≥ 0``). **Returns:** the path written.
    """
    phi, at_sensors = np.asarray(phi), np.asarray(at_sensors)
    shapes_e = np.asarray(test.shapes)
    names = {int(k): int(v) for k, v in (names or {}).items()}
    by_sensor = measured_translations(test.sensors, shapes_e)
    nodes = {int(k): np.asarray(v, np.float64) for k, v in (test_nodes or {}).items()}
    missing = [n for n in by_sensor if names.get(n, n) not in nodes]
    for n, row in zip(missing, model.node_index(missing) if missing else ()):  # ValueError: ids that are no grid
        nodes[names.get(n, n)] = np.asarray(model.xyz)[row]
    test_shapes = {names.get(n, n): u for n, u in by_sensor.items()}
    pairs, columns = [], {}
    for j, i, mac in zip(pairing.test.tolist(), pairing.model.tolist(), np.asarray(pairing.mac).tolist()):
        sign = -1.0 if float(shapes_e[:, j] @ at_sensors[:, i]) < 0 else 1.0
        columns[i] = sign * phi[:, i]
        pairs.append((j, i, float(pairing.f_test[j]), float(pairing.f_model[i]), mac))
    grids = dict(zip(columns, np.moveaxis(grid_translations(model, np.stack(list(columns.values()), axis=1)), 2, 0))
                 ) if columns else {}
    return shape_view(path, model=model, model_shapes=grids.__getitem__, test_nodes=nodes, test_shapes=test_shapes,
                      pairs=pairs, test_lines=test_lines, title=title,
                      note="Model shapes signed to move with the test at the sensors (φ_eᵀ C φ_a ≥ 0).")


def shape_view(
    path: str | os.PathLike,
    *,
    model: Model,
    model_shapes: Float[ArrayLike, "nnode 3 m"] | Callable[[int], Float[ArrayLike, "nnode 3"]],
    test_nodes: Mapping[int, ArrayLike],
    test_shapes: Mapping[int, Float[ArrayLike, "3 n_e"]],
    pairs: Sequence[tuple[int, int, float, float, float]],
    test_lines: Sequence[tuple[int, int]] = (),
    title: str = "test and model mode shapes",
    note: str = "",
    deformation: float = DEFORMATION,
    max_edges: int = MAX_EDGES,
) -> Path:
    """Write the interactive 3-D view of paired test and model mode shapes (module docstring).

    **Arguments:**

    - ``path``: the HTML file to write (its directory is made).
    - ``model``: the FE model; its grids and element edges are drawn.
    - ``model_shapes``: translations of every grid (n_grid, 3, m) per model mode, basic
      axes (:func:`grid_translations`), or a function of the model mode index giving
      (n_grid, 3).
    - ``test_nodes``: {node id: xyz (3,) m}, every test node (measured or not).
    - ``test_shapes``: {node id: (3, n_e)} translations of the measured nodes per test
      mode (:func:`measured_translations`); nodes not listed stand still.
    - ``pairs``: ``(test mode, model mode, f_test Hz, f_model Hz, MAC)`` per pair, mode
      indices from 0 (shown from 1); the model shapes already signed to move with the test.
    - ``test_lines``: node-id pairs of the test wireframe (UFF dataset 82).
    - ``title``, ``note``: the page's title and a sentence added to its explanation.
    - ``deformation``: largest drawn translation of each shape over the extent.
    - ``max_edges``: element edges drawn at most.

    **Returns:** the path written. ``ValueError`` naming the item for shapes of the wrong
    size, complex or non-finite values, and nodes, lines or mode indices that do not exist.
    """
    node_ids = np.asarray(model.node_ids)
    xyz = np.asarray(model.xyz, np.float64)
    n_grid = len(node_ids)
    if not deformation > 0:
        raise ValueError(f"deformation must be positive, got {deformation}")
    shape_of, n_model = _model_shape_source(model_shapes, n_grid)
    ids, t_xyz, row_of = _test_node_rows(test_nodes)
    t_shapes, n_test = _test_shape_arrays(test_shapes, row_of)
    _check_lines_and_pairs(test_lines, pairs, row_of, n_test, n_model)

    edges, n_edges = _model_edges(model, max_edges)
    markers = n_grid <= MAX_GRID_MARKERS
    if markers:  # grids on no drawn edge (a lumped mass, an RBE's master) as zero-length segments
        alone = np.setdiff1d(np.arange(n_grid), edges.ravel())
        edges = np.concatenate([edges, np.stack([alone, alone], axis=1)])
    drawn = np.unique(edges)
    compact = np.searchsorted(drawn, edges)

    t_seg = [(row_of[int(a)], row_of[int(b)]) for a, b in test_lines]
    on_line = {r for s in t_seg for r in s}
    t_seg += [(r, r) for r in range(len(ids)) if r not in on_line]

    both = np.concatenate([xyz, t_xyz]) if len(t_xyz) else xyz
    lo, hi = both.min(axis=0), both.max(axis=0)
    extent = float((hi - lo).max()) or 1.0
    amp = deformation * extent
    digits = int(6 - np.floor(np.log10(extent)))
    margin = 1.1 * amp
    view_pairs, rows = _view_pairs(pairs, shape_of, n_grid, t_shapes, row_of, len(ids), drawn, amp, digits)

    explanation = _explanation(deformation, extent, len(test_lines), n_edges, max_edges, note)
    data = {
        "title": title, "phases": PHASES, "frame_ms": FRAME_MS,
        "range": [[float(lo[c] - margin), float(hi[c] + margin)] for c in range(3)],
        "test": {"ids": ids, "xyz": np.round(t_xyz, digits).ravel().tolist(),
                 "seg": [r for s in t_seg for r in s]},
        "model": {"ids": node_ids[drawn].tolist() if markers else None,
                  "xyz": np.round(xyz[drawn], digits).ravel().tolist(),
                  "seg": compact.ravel().tolist(), "markers": markers},
        "pairs": view_pairs,
    }
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(_page(title, explanation, data, rows), encoding="utf-8")
    return path


def _model_shape_source(model_shapes, n_grid: int) -> tuple[Callable[[int], ArrayLike], int | None]:
    """The model shape of a mode index, and how many modes there are (None: a function's)."""
    if callable(model_shapes):
        return model_shapes, None
    array = np.asarray(model_shapes)
    if array.ndim != 3 or array.shape[:2] != (n_grid, 3):
        raise ValueError(f"model_shapes has shape {array.shape}; expected ({n_grid}, 3, m) for this model")
    return (lambda i: array[:, :, i]), array.shape[2]


def _test_node_rows(test_nodes: Mapping[int, ArrayLike]) -> tuple[list[int], np.ndarray, dict[int, int]]:
    """The test node ids sorted, their coordinates (n, 3) (finite) and {id: row}."""
    ids = sorted(int(n) for n in test_nodes)
    t_xyz = np.array([np.asarray(test_nodes[n], np.float64).reshape(3) for n in ids]).reshape(-1, 3)
    if not np.isfinite(t_xyz).all():
        raise ValueError(f"test node {ids[int(np.flatnonzero(~np.isfinite(t_xyz).all(axis=1))[0])]} has "
                         "coordinates that are not finite")
    return ids, t_xyz, {n: k for k, n in enumerate(ids)}


def _test_shape_arrays(test_shapes: Mapping, row_of: dict[int, int]) -> tuple[dict[int, np.ndarray], int]:
    """The test shapes as {node id: (3, n_e)} arrays, checked, and n_e (0 without)."""
    unknown = sorted(int(n) for n in test_shapes if int(n) not in row_of)
    if unknown:
        raise ValueError(f"test shapes at node(s) {unknown} that are not among the test nodes")
    t_shapes = {int(n): np.asarray(v) for n, v in test_shapes.items()}
    widths = {v.shape[1] for v in t_shapes.values() if v.ndim == 2 and v.shape[0] == 3}
    bad = [n for n, v in t_shapes.items() if v.ndim != 2 or v.shape[0] != 3 or np.iscomplexobj(v)
           or not np.isfinite(v).all()]
    if bad or len(widths) > 1:
        raise ValueError("test shapes must be real, finite (3, n_e) arrays of one n_e; node "
                         f"{(bad or list(t_shapes))[0]} has {t_shapes[(bad or list(t_shapes))[0]].shape}")
    return t_shapes, widths.pop() if widths else 0


def _check_lines_and_pairs(test_lines, pairs, row_of: dict[int, int], n_test: int, n_model: int | None) -> None:
    """``ValueError`` for a trace line to an unknown node or a pair of modes that do not exist."""
    bad_lines = [ln for ln in test_lines if int(ln[0]) not in row_of or int(ln[1]) not in row_of]
    if bad_lines:
        raise ValueError(f"test trace line {tuple(bad_lines[0])} joins a node that is not among the test nodes")
    for k, (j, i, *_rest) in enumerate(pairs):
        if not 0 <= int(j) < n_test or (n_model is not None and not 0 <= int(i) < n_model) or int(i) < 0:
            raise ValueError(f"pair {k + 1}: test mode {int(j) + 1} or model mode {int(i) + 1} does not exist "
                             f"({n_test} test modes{'' if n_model is None else f', {n_model} model modes'})")


def _scaled(u: np.ndarray, amp: float, digits: int, rows=slice(None)) -> list[float]:
    """u[rows] scaled so that the largest translation of all of u is ``amp``, rounded."""
    peak = float(np.linalg.norm(u, axis=1).max()) if len(u) else 0.0
    u = u[rows] * (amp / peak) if peak > 0 else np.zeros_like(u[rows])
    return np.round(u, digits).ravel().tolist()


def _view_pairs(pairs, shape_of, n_grid: int, t_shapes: dict[int, np.ndarray], row_of: dict[int, int],
                n_nodes: int, drawn: np.ndarray, amp: float, digits: int) -> tuple[list[dict], list[tuple]]:
    """Per pair, the page's entry (label, title, scaled test and model shapes) and the table row."""
    rows = []
    view_pairs = []
    for k, (j, i, ft, fm, mac) in enumerate(pairs):
        j, i, ft, fm, mac = int(j), int(i), float(ft), float(fm), float(mac)
        u_m = np.asarray(shape_of(i))
        if u_m.shape != (n_grid, 3) or np.iscomplexobj(u_m) or not np.isfinite(u_m).all():
            raise ValueError(f"model mode {i + 1}: shape {u_m.shape}, expected real, finite ({n_grid}, 3)")
        u_t = np.zeros((n_nodes, 3))
        for n, v in t_shapes.items():
            u_t[row_of[n]] = v[:, j]
        dev = 100.0 * (fm - ft) / ft if ft else float("nan")
        text = (f"test {j + 1}: {ft:.4g} Hz · model {i + 1}: {fm:.4g} Hz · Δf {dev:+.2f} % · MAC {mac:.3f}")
        view_pairs.append({"label": f"{k + 1}: {text}", "title": f"pair {k + 1}/{len(pairs)}: {text}",
                           "test": _scaled(u_t, amp, digits), "model": _scaled(u_m, amp, digits, drawn)})
        rows.append((k + 1, j + 1, i + 1, ft, fm, dev, mac))
    return view_pairs, rows


def _explanation(deformation: float, extent: float, n_lines: int, n_edges: int, max_edges: int, note: str) -> str:
    """The sentence under the title: scale, colours, what is drawn, and ``note``."""
    shown = f"{min(n_edges, max_edges):,} of {n_edges:,}"
    return (
        f"Deflection: each shape scaled to a largest translation of {100 * deformation:g} % of the structure's "
        f"extent (L = {extent:.4g} m), u(t) = u·sin(ωt). Test in red (nodes; trace lines: "
        + (f"{n_lines} from UFF dataset 82" if n_lines else "none given (UFF dataset 82)")
        + f"), model in blue ({shown} element edges"
        + (f", the first {max_edges:,} by priority: line elements, shell feature edges, an even share of the rest"
           if n_edges > max_edges else "")
        + "), undeformed in grey. " + note).strip()


def _model_edges(model: Model, max_edges: int) -> tuple[np.ndarray, int]:
    """Element edges to draw, (k, 2) grid rows, and how many there are in all.

    Priority: two-grid elements (beams, rods, bushes, springs between two grids), then the
    shells' feature edges (on one element only, or between elements of different
    properties), then the other shell edges; a class that does not fit in what is left of
    ``max_edges`` is thinned to an evenly spaced subset."""
    lines = [np.asarray(b.nodes)[:, :2] for b in (model.beams, model.rods, model.bushes, model.springs)]
    lines = np.concatenate(lines).astype(np.int64).reshape(-1, 2)
    lines = lines[(lines >= 0).all(axis=1) & (lines[:, 0] != lines[:, 1])]
    shell, pids = [np.zeros((0, 2), np.int64)], [np.zeros(0, np.int64)]
    for block in (model.quads, model.trias):
        nodes = np.asarray(block.nodes, np.int64)
        nn = nodes.shape[1]
        for a in range(nn):
            shell.append(nodes[:, [a, (a + 1) % nn]])
            pids.append(np.asarray(block.pids, np.int64))
    shell, pids = np.concatenate(shell), np.concatenate(pids)
    lines = _unique_edges(lines)[0]
    uniq, inverse, counts = _unique_edges(shell)
    low = np.full(len(uniq), np.iinfo(np.int64).max)
    high = np.full(len(uniq), np.iinfo(np.int64).min)
    np.minimum.at(low, inverse, pids)
    np.maximum.at(high, inverse, pids)
    feature = (counts == 1) | (low != high)
    groups = [lines, uniq[feature], uniq[~feature]]
    chosen, budget = [], max_edges
    for g in groups:
        if len(g) > budget:
            g = g[np.unique(np.linspace(0, len(g) - 1, budget).round().astype(np.int64))] if budget else g[:0]
        chosen.append(g)
        budget -= len(g)
    return np.concatenate(chosen).reshape(-1, 2), sum(len(g) for g in groups)


def _unique_edges(edges: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Undirected edges once each (smaller row first), the inverse map and the counts."""
    edges = np.sort(edges.reshape(-1, 2), axis=1)
    if not len(edges):
        return edges, np.zeros(0, np.int64), np.zeros(0, np.int64)
    uniq, inverse, counts = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    return uniq, inverse.reshape(-1), counts
