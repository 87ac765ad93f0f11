"""The test geometry on the FE model: units check, rigid alignment, test nodes read at their points.

Test nodes have their own numbering and coordinates. :func:`map_test_geometry` gives each
test node a place in the model, as the thesis maps each sensor to the nearest FE node
(§5.2.2), so that the test data keep their own node ids:

- ``"id"``: test node ids are model grid ids (today's test files written from the model);
- ``"nearest"``: a test node is rigidly linked to the model grid closest to its point,
  u = u_g + θ_g × (x − x_g) (the GRID + RBE2 an engineer would add by hand: a sensor on a
  beam's surface sees its torsion);
- ``"interpolate"``: it reads Σ Nᵢ uᵢ over the nearest shell element (its shape
  functions at the projected point, :func:`jaxfem.locate_sensors`), plus Σ Nᵢ θᵢ times
  its offset from the surface;
- ``"auto"``: ``id`` when every test node is a model grid at the same place (or the file
  has no coordinates), else ``nearest``.

Each mapped test node becomes a dependent grid of the model at its point
(:func:`jaxfem.add_interpolated_grid`, no new DoFs), under the test node's id, or,
when that id is a model grid elsewhere, the id plus the power of ten above every model and
test id (test node 1 beside grid 6001 reads as 10001); the measured data are renamed to it. So
every later step (pairing, residuals, effects, FRF prediction) reads the test where it was
measured.

Before mapping, the extent of the test geometry is compared with the model's: a ratio near
10, 100, 1000, 25.4 or 1/0.0254 (or their inverses) means the coordinates are in other
length units than the file says, and the mapping stops with the units that would fit
(``length_units_given`` skips the check). ``align=True`` first moves the test frame onto the
model by a rigid least-squares fit on matched points (iterative closest grid, Kabsch's
rotation, Arun, Huang & Blostein, IEEE PAMI 9, 1987); the rotation turns the measured
directions too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import equinox as eqx
import numpy as np
from scipy.spatial import cKDTree

import jaxfem
from jaxfem import Model, add_interpolated_grid

from ._data import FRFData, ModalData, Sensors
from ._uff_units import LENGTH_UNITS

MAP_METHODS = ("auto", "id", "nearest", "interpolate")
UNIT_FACTORS = (10.0, 100.0, 1000.0, 25.4, 1.0 / 0.0254)  # and inverses: coordinates in other length units
_UNIT_RTOL = 0.3  # an extent ratio within 30 % of a unit factor is suspicious
_SAME_PLACE = 1e-6  # × model size: a test node at a model grid of the same id
MAX_DISTANCE = 0.05  # × model size (bounding-box diagonal): default plausible test-to-model distance ...
MAX_SPACINGS = 1.5  # ... or × the median grid spacing, whichever is larger (a coarse mesh's nearest grid)
_LISTED = 20  # test nodes listed by distance in the printed summary (all are in the JSON)
_ALIGN_ITERATIONS = 100
_ALIGN_TOL = 1e-12  # × model size: the alignment has converged when the RMS changes less


def _size(xyz: np.ndarray) -> float:
    """Bounding-box diagonal [m]."""
    return float(np.linalg.norm(np.ptp(xyz, axis=0))) if len(xyz) > 1 else 0.0


def check_units(test_xyz, model_xyz, length_factor: float = 1.0) -> None:
    """``ValueError`` when the test geometry's extent differs from the model's by a factor
    near 10, 100, 1000, 25.4 or 1/0.0254 (either way): the message says which length unit
    of the file would make them agree. ``length_factor``: the file units per metre used to
    read the test coordinates."""
    t, m = _size(np.asarray(test_xyz)), _size(np.asarray(model_xyz))
    if not (t > 0 and m > 0):
        return
    ratio = t / m
    for factor in UNIT_FACTORS:
        for f in (factor, 1.0 / factor):
            if abs(math.log(ratio / f)) < math.log(1 + _UNIT_RTOL):
                fits = length_factor * f
                unit = [u for u, v in LENGTH_UNITS.items() if math.isclose(v, fits, rel_tol=1e-3)]
                advice = (f"they fit the model if the file's lengths are in {unit[0]} (--test-units {unit[0]})"
                          if unit else f"they fit the model if scaled by 1/{f:.4g}")
                raise ValueError(
                    f"the test geometry spans {t:.4g} m but the model {m:.4g} m ({ratio:.3g}×, near {f:.4g}): "
                    f"{advice}; give --test-units to state the units and go on")


def align(test_xyz, model: Model, iterations: int = _ALIGN_ITERATIONS) -> dict:
    """Rigid motion x ↦ R x + t of the test points onto the model's grids: least squares
    on matched points (each test point with its nearest grid), re-matched until the RMS
    distance stops falling. Returns ``{"rotation": R (3, 3), "translation": t (3,) m,
    "rms_before", "rms_after" (m), "iterations", "angle_deg"}``."""
    x = np.asarray(test_xyz, dtype=np.float64)
    grids = np.asarray(model.xyz)
    tree = cKDTree(grids)
    R, t = np.eye(3), np.zeros(3)
    d, _ = tree.query(x)
    rms_before = rms = float(np.sqrt(np.mean(d**2)))
    tol = _ALIGN_TOL * max(_size(grids), 1.0)
    for it in range(1, iterations + 1):
        moved = x @ R.T + t
        _, nearest = tree.query(moved)
        target = grids[nearest]
        cx, ct = x.mean(axis=0), target.mean(axis=0)
        u, _, vt = np.linalg.svd((x - cx).T @ (target - ct))
        flip = np.diag([1.0, 1.0, np.sign(np.linalg.det(vt.T @ u.T))])
        R = vt.T @ flip @ u.T
        t = ct - R @ cx
        d, _ = tree.query(x @ R.T + t)
        new = float(np.sqrt(np.mean(d**2)))
        if abs(rms - new) <= tol:
            rms = new
            break
        rms = new
    angle = math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(R) - 1) / 2))))
    return {"rotation": R, "translation": t, "rms_before": rms_before, "rms_after": rms, "iterations": it,
            "angle_deg": angle}


@dataclass(frozen=True)
class GeometryMap:
    """Where each test node reads the model.

    ``method``: "id", "nearest" or "interpolate"; ``nodes``: test node ids; ``grids``:
    the model grid id each reads as (its own id, or a new one when the model has that id
    elsewhere); ``xyz`` (n, 3) m: the test points in the model frame; ``reads``: "grid
    12" or "CQUAD4 5 (1 2 3 4)"; ``distance`` (n,) m: to the grid or element surface;
    ``alignment``: the rigid motion applied (:func:`align`) or None; ``note``: why this
    method (for ``auto``).
    """

    method: str
    nodes: np.ndarray
    grids: np.ndarray
    xyz: np.ndarray
    reads: tuple[str, ...]
    distance: np.ndarray
    alignment: dict | None = None
    note: str = ""
    renamed: dict[int, int] = field(default_factory=dict)

    @property
    def worst(self) -> tuple[int, float]:
        """(test node, distance m) of the farthest test node; (0, 0.0) for none."""
        if not len(self.nodes):
            return 0, 0.0
        i = int(np.argmax(self.distance))
        return int(self.nodes[i]), float(self.distance[i])

    def apply(self, data: ModalData | FRFData) -> ModalData | FRFData:
        """``data`` with its sensors on the mapped grids (renamed where needed) and, after an
        alignment, its directions turned into the model frame."""
        def move(sensors: Sensors) -> Sensors:
            nodes = np.array([self.renamed.get(int(g), int(g)) for g in sensors.nodes], dtype=np.int64)
            directions = sensors.directions
            if self.alignment is not None:
                directions = directions @ self.alignment["rotation"].T
            return Sensors.from_vectors(nodes, directions, sensors.rotational)

        if isinstance(data, FRFData):
            return eqx.tree_at(lambda f: (f.outputs, f.inputs), data, (move(data.outputs), move(data.inputs)))
        return eqx.tree_at(lambda m: m.sensors, data, move(data.sensors))

    def lines(self) -> list[str]:
        """The summary a user reads: method, worst distance, alignment, renamed ids, and
        the test nodes by distance, farthest first (at most 20)."""
        node, worst = self.worst
        out = [f"test geometry: {len(self.nodes)} test nodes mapped by {self.method}"
               + (f" ({self.note})" if self.note else "")
               + (f"; worst distance {worst:.3g} m (test node {node})" if len(self.nodes) else "")]
        if self.alignment is not None:
            a = self.alignment
            out.append(f"aligned test frame: rotation {a['angle_deg']:.3f}°, translation "
                       f"{np.array2string(a['translation'], precision=4)} m; RMS distance {a['rms_before']:.3g} → "
                       f"{a['rms_after']:.3g} m ({a['iterations']} iterations)")
        if self.renamed:
            out.append("test nodes whose ids are model grids elsewhere read as new grids: "
                       + ", ".join(f"{a} → {b}" for a, b in sorted(self.renamed.items())))
        if self.method != "id" and len(self.nodes):
            order = np.argsort(-self.distance, kind="stable")
            shown = order if len(order) <= _LISTED else order[:_LISTED]
            out.append(f"{'test node':>10}  {'reads':<28} {'distance [m]':>12}"
                       + ("" if len(shown) == len(order) else f"   ({len(shown)} farthest of {len(order)})"))
            out += [f"{self.nodes[i]:>10}  {self.reads[i]:<28} {self.distance[i]:>12.4g}" for i in shown]
        return out

    def to_json(self) -> dict:
        node, worst = self.worst
        return {
            "method": self.method,
            "note": self.note,
            "worst_distance_m": worst,
            "worst_node": node,
            "nodes": [{"test_node": int(n), "grid": int(g), "reads": r, "distance_m": float(d),
                       "xyz_m": x.tolist()}
                      for n, g, r, d, x in zip(self.nodes, self.grids, self.reads, self.distance, self.xyz)],
            "alignment": None if self.alignment is None else {
                k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in self.alignment.items()},
        }


def map_test_geometry(
    model: Model,
    test_nodes: dict[int, np.ndarray],
    used: set[int] | None = None,
    *,
    method: str = "auto",
    max_distance: float | None = None,
    align_frames: bool = False,
    length_units_given: bool = False,
    length_factor: float = 1.0,
) -> tuple[Model, GeometryMap]:
    """Map test nodes onto ``model`` (module docstring); returns the model with a
    dependent grid per mapped test node and the :class:`GeometryMap` (apply it to the
    test data).

    ``test_nodes``: {test node id: xyz m} from the test file; ``used``: the node ids the
    data refer to (default: all); ``max_distance`` [m]: the largest plausible distance
    from a test node to the model (default: the larger of 5 % of the model's size and
    1.5 median grid spacings); ``length_factor``:
    file units per metre the coordinates were read with (for the units advice).

    ``ValueError`` naming the option to use: test ids not in the model without
    coordinates, coordinates in other units, a test node farther than ``max_distance``.
    """
    if method not in MAP_METHODS:
        raise ValueError(f"--map {method!r}: use one of {', '.join(MAP_METHODS)}")
    if max_distance is not None and not max_distance > 0:
        raise ValueError(f"--max-distance must be positive (m), got {max_distance}")
    ids = np.asarray(model.node_ids)
    grid_xyz = np.asarray(model.xyz)
    size = _size(grid_xyz)
    known = dict(zip(ids.tolist(), range(len(ids))))
    used = set(test_nodes) if used is None else set(used)
    absent = sorted(used - set(test_nodes))
    if absent and (method in ("nearest", "interpolate") or align_frames):
        raise ValueError(f"{'--align' if align_frames else '--map ' + method}: test nodes {absent} have no "
                         "coordinates in the test file (datasets 15/2411)")
    if align_frames and method == "id":
        raise ValueError("--align moves the test geometry onto the model: use it with --map nearest or interpolate")
    nodes = np.array(sorted(used), dtype=np.int64)
    xyz = np.array([test_nodes[g] for g in nodes.tolist()]).reshape(-1, 3) if not absent else np.zeros((0, 3))
    method, note = _choose_method(method, align_frames, absent, nodes, xyz, known, grid_xyz, size)
    if method == "id":
        return model, _map_by_id(nodes, xyz, absent, known, grid_xyz, note)
    if not length_units_given:
        check_units(xyz, grid_xyz, length_factor)
    alignment = None
    if align_frames:
        alignment = align(xyz, model)
        xyz = xyz @ alignment["rotation"].T + alignment["translation"]
    located = jaxfem.locate_sensors(model, xyz, [1] * len(nodes), method, labels=[str(g) for g in nodes.tolist()])
    _check_distances(located, nodes, grid_xyz, size, max_distance)
    model, grids, renamed = _add_test_grids(model, ids, known, nodes, xyz, located)
    reads = tuple(located.where(s) for s in range(len(nodes)))
    return model, GeometryMap(method, nodes, np.asarray(grids, dtype=np.int64), xyz, reads, located.distance,
                              alignment, note, renamed)


def _choose_method(method: str, align_frames: bool, absent: list[int], nodes: np.ndarray, xyz: np.ndarray,
                   known: dict[int, int], grid_xyz: np.ndarray, size: float) -> tuple[str, str]:
    """The mapping method and why it was chosen: ``method`` itself unless it is "auto"."""
    note = ""
    if method == "auto" and align_frames:
        method, note = "nearest", "--align"
    elif method == "auto":
        if absent:
            method, note = "id", "the test file gives no coordinates for some nodes"
        else:
            same = [g in known and np.linalg.norm(grid_xyz[known[g]] - x) <= _SAME_PLACE * max(size, 1e-300)
                    for g, x in zip(nodes.tolist(), xyz)]
            if all(same):
                method, note = "id", "every test node is a model grid at the same place"
            else:
                method = "nearest"
                n_known = sum(g in known for g in nodes.tolist())
                note = (f"{len(nodes) - n_known} of {len(nodes)} test nodes are not model grids" if n_known < len(nodes)
                        else "the test nodes' coordinates differ from the model grids of the same ids")
    return method, note


def _map_by_id(nodes: np.ndarray, xyz: np.ndarray, absent: list[int], known: dict[int, int], grid_xyz: np.ndarray,
               note: str) -> GeometryMap:
    """The :class:`GeometryMap` of test nodes that are model grids of the same ids."""
    missing = sorted(g for g in nodes.tolist() if g not in known)
    if missing:
        hint = ("--map nearest" if not absent else "a test file with node coordinates (datasets 15/2411) and "
                "--map nearest")
        raise ValueError(f"test node(s) {missing} are not model grids: map them by geometry with {hint}")
    rows = [known[g] for g in nodes.tolist()]
    distance = (np.linalg.norm(grid_xyz[rows] - xyz, axis=1) if len(xyz) else np.zeros(len(nodes)))
    return GeometryMap("id", nodes, nodes, grid_xyz[rows], tuple(f"grid {g}" for g in nodes.tolist()),
                       distance, note=note)


def _check_distances(located, nodes: np.ndarray, grid_xyz: np.ndarray, size: float,
                     max_distance: float | None) -> None:
    """``ValueError`` when a located test node is farther than ``max_distance`` (default: from size and spacing)."""
    if max_distance is None:
        spacing = float(np.median(cKDTree(grid_xyz).query(grid_xyz, k=2)[0][:, 1])) if len(grid_xyz) > 1 else 0.0
        limit = max(MAX_DISTANCE * size, MAX_SPACINGS * spacing)
        why = (f" (the larger of {100 * MAX_DISTANCE:.0f} % of its size, {size:.3g} m, and {MAX_SPACINGS:g} median "
               f"grid spacings, {spacing:.3g} m)")
    else:
        limit, why = max_distance, ""
    far = np.flatnonzero(located.distance > limit)
    if len(far):
        w = int(far[np.argmax(located.distance[far])])
        raise ValueError(
            f"{len(far)} test node(s) lie farther than {limit:.3g} m from the model{why}"
            + f"; the worst, test node {nodes[w]}, is {located.distance[w]:.3g} m from {located.where(w)}: check the "
            "test file's units and frame (--test-units, --align) or accept the distances with --max-distance")


def _add_test_grids(model: Model, ids: np.ndarray, known: dict[int, int], nodes: np.ndarray, xyz: np.ndarray,
                    located) -> tuple[Model, list[int], dict[int, int]]:
    """The model with a dependent grid per located test node that is not a model grid at its place; the grid
    of each test node and {test node: its new grid id} for test ids that clash with model grids."""
    offset = 10 ** len(str(max(int(ids.max(initial=0)), int(nodes.max(initial=0)))))  # 1 → 10001 beside grid 6001
    renamed: dict[int, int] = {}
    grids = []
    for s, g in enumerate(nodes.tolist()):
        read = located.grids[s][located.grids[s] >= 0]
        weights = located.shape_functions[s][: len(read)]
        if g in known and len(read) == 1 and read[0] == g:
            grids.append(g)  # the test node is this model grid
            continue
        new = g
        if g in known:
            new = renamed[g] = offset + g
        model, _ = add_interpolated_grid(model, read.tolist(), weights.tolist(), xyz[s], new)
        grids.append(new)
    return model, grids, renamed
