"""Sensors given by coordinates: the observation of a model's DoFs at measured points.

A test article is instrumented at points (x, y, z) that need not coincide with the grids
of the FE model. :func:`locate_sensors` maps each point to the model once, in NumPy, and
returns a :class:`SensorMap` whose :meth:`SensorMap.observe` applies the observation
matrix C (n_sensors × n_dof, held sparse as indices and weights) to mode shapes inside
``jit``/``grad``: φ_sensors = C φ.

Two mappings (the design's "grid, nearest grid, or interpolation"):

- ``nearest``: each sensor reads the grid closest to its point (thesis §5.2.2 maps each
  sensor to the nearest FE node); ties go to the lowest grid id.
- ``interpolate``: the point is projected onto the nearest shell element (CQUAD4: the
  bilinear map of the flat projected element inverted by Newton iterations; CTRIA3: area
  coordinates) and the sensor reads Σ N_i(ξ, η) u_i over the element's grids, the
  element's own shape functions (rotations are interpolated by the same N_i, as in the
  MITC shells). A model without shells, or a point farther than ``max_distance`` from
  every shell element, falls back to ``nearest`` with a ``UserWarning`` naming the sensor.

Grid components go through the model's :class:`~jaxfem.DofMap`
(``u[g, c] = coef[g, c] @ u_solved[index[g]]``), so constrained grids read zero in their
held components and RBE2/RBE3/MPC-dependent grids read their combination of independent
DoFs.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float, Inexact, Int

from ._model import Model, check_float64
from .elements import QUAD_CORNERS, quad_shape, shell_frame

METHODS = ("nearest", "interpolate")
_AXES = "XYZ"
_UNIT_TOL = 1e-6  # |‖d‖ − 1| allowed for a direction given as a vector
_TIE_RTOL = 1e-9  # distances equal to this relative tolerance are ties
_TIE_ATOL = 1e-12  # ... or to this fraction of the model's extent
_NEWTON_ITERS = 50
_NEWTON_TOL = 1e-13  # on the natural coordinates
_INSIDE_TOL = 1e-10  # natural / area coordinates this far outside still count as inside
_SNAP = 1e-12  # shape-function values below this are dropped (a point on a grid reads it alone)


class SensorMap(eqx.Module):
    """Where each sensor reads the model: the observation matrix and how it was found.

    Fields (NumPy; structure, never differentiated):

    - ``indices``, ``weights`` (n_sensors, k): row s of C is Σ_j weights[s, j] at column
      indices[s, j] (padding: weight 0).
    - ``labels``: sensor names; ``xyz`` (n_sensors, 3): the points [m], basic axes;
      ``directions`` (n_sensors, 3): unit measured directions in basic axes;
      ``rotational``: True where the sensor reads rotations (components 4..6).
    - ``grids`` (n_sensors, w): grid ids read (−1 pads); ``shape_functions`` (n_sensors, w):
      their weights N_i (1 for a nearest grid).
    - ``elements``: the shell element interpolated (−1 where a grid was read directly);
      ``element_types``: ``"CQUAD4"``, ``"CTRIA3"`` or ``""``.
    - ``distance`` [m]: from the point to the grid (nearest) or to the element surface
      (interpolate: the normal distance for a point over the element).
    """

    indices: Int[np.ndarray, "ns k"]
    weights: Float[np.ndarray, "ns k"]
    labels: tuple[str, ...]
    xyz: Float[np.ndarray, "ns 3"]
    directions: Float[np.ndarray, "ns 3"]
    rotational: Bool[np.ndarray, " ns"]
    grids: Int[np.ndarray, "ns w"]
    shape_functions: Float[np.ndarray, "ns w"]
    elements: Int[np.ndarray, " ns"]
    element_types: tuple[str, ...]
    distance: Float[np.ndarray, " ns"]
    n_dof: int = eqx.field(static=True)
    method: str = eqx.field(static=True)

    def __len__(self) -> int:
        return len(self.labels)

    def observe(self, phi: Inexact[ArrayLike, "n_dof *m"]) -> Inexact[Array, "ns *m"]:
        """Sensor responses ``C φ`` of shapes ``phi`` (n_dof,) or (n_dof, m), real or complex;
        jittable and differentiable in ``phi``."""
        phi = jnp.asarray(phi)
        check_float64("phi", phi)
        if phi.ndim not in (1, 2) or phi.shape[0] != self.n_dof:
            raise ValueError(f"phi has shape {phi.shape}, expected ({self.n_dof},) or ({self.n_dof}, m)")
        w = jnp.asarray(self.weights, dtype=phi.dtype)
        gathered = phi[jnp.asarray(self.indices)]  # (ns, k, *m)
        return jnp.einsum("sk,sk...->s...", w, gathered)

    @property
    def matrix(self) -> Float[np.ndarray, "ns n_dof"]:
        """The observation matrix C as a dense NumPy float64 array (n_sensors, n_dof)."""
        C = np.zeros((len(self), self.n_dof))
        np.add.at(C, (np.arange(len(self))[:, None], self.indices), self.weights)
        return C

    @property
    def worst_distance(self) -> float:
        """The largest sensor-to-model distance [m] (0 for no sensors)."""
        return float(self.distance.max()) if len(self) else 0.0

    def where(self, s: int) -> str:
        """What sensor ``s`` reads: ``grid G`` or ``CQUAD4 E (g1 g2 g3 g4)``."""
        g = self.grids[s][self.grids[s] >= 0]
        if self.elements[s] >= 0:
            return f"{self.element_types[s]} {self.elements[s]} ({' '.join(str(x) for x in g)})"
        return f"grid {g[0]}"

    def report(self) -> str:
        """A table: sensor, direction, x, y, z [m], grid or element read, distance [m];
        then the worst distance and its sensor."""
        rows = [
            (self.labels[s], _direction_label(self.directions[s], self.rotational[s]),
             *(f"{v:.6g}" for v in self.xyz[s]), self.where(s), f"{self.distance[s]:.3e}")
            for s in range(len(self))
        ]
        head = ("sensor", "direction", "x [m]", "y [m]", "z [m]", "grid/element", "distance [m]")
        widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
        right = {2, 3, 4, 6}

        def line(r):
            return "  ".join(c.rjust(w) if i in right else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths)))

        out = [line(head), line(tuple("-" * w for w in widths)), *(line(r) for r in rows)]
        if len(self):
            s = int(np.argmax(self.distance))
            out.append(f"worst distance: {self.distance[s]:.3e} m (sensor {self.labels[s]})")
        return "\n".join(line.rstrip() for line in out)


def _direction_label(d: np.ndarray, rotational: bool) -> str:
    r = "R" if rotational else ""
    axis = np.flatnonzero(np.abs(d) > 1.0 - 1e-12)
    if len(axis) == 1:
        return f"{'+' if d[axis[0]] > 0 else '-'}{r}{_AXES[axis[0]]}"
    return f"{r}({d[0]:.3f},{d[1]:.3f},{d[2]:.3f})"


def _directions(directions, n: int, rotational=None) -> tuple[np.ndarray, np.ndarray]:
    """Per sensor a Nastran component ±1..6 or a unit vector (a rotation where
    ``rotational``) → (unit vectors (n, 3), rotational (n,))."""
    if isinstance(directions, (str, bytes)) or not isinstance(directions, (Sequence, np.ndarray)) or (
        isinstance(directions, np.ndarray) and directions.ndim not in (1, 2)
    ):
        raise ValueError(
            "directions must give one entry per sensor: a component 1..6 or a unit vector (3,) in basic axes"
        )
    items = list(directions)
    if len(items) != n:
        raise ValueError(f"{n} sensor points but {len(items)} directions")
    if rotational is not None and len(rotational) != n:
        raise ValueError(f"{n} sensors but {len(rotational)} rotational flags")
    vec = np.zeros((n, 3))
    rot = np.zeros(n, dtype=bool)
    for i, item in enumerate(items):
        arr = np.asarray(item)
        if arr.ndim == 0 and (arr.dtype.kind in "iu" or (arr.dtype.kind == "f" and float(arr).is_integer())):
            code = int(arr)
            if not 1 <= abs(code) <= 6:
                raise ValueError(f"sensor {i}: direction component {code} is not 1..6 (or −1..−6)")
            vec[i, (abs(code) - 1) % 3] = np.sign(code)
            rot[i] = abs(code) > 3
        elif arr.shape == (3,) and arr.dtype.kind in "iuf":
            d = arr.astype(np.float64)
            norm = np.linalg.norm(d)
            if not np.isfinite(norm) or abs(norm - 1.0) > _UNIT_TOL:
                what = "is zero" if norm == 0.0 else f"has length {norm:.6g}, not 1"
                raise ValueError(f"sensor {i}: direction {d.tolist()} {what} (give a unit vector in basic axes)")
            vec[i] = d / norm
            rot[i] = rotational is not None and bool(rotational[i])
        else:
            raise ValueError(
                f"sensor {i}: direction {item!r} is neither a component 1..6 nor a unit vector of shape (3,)"
            )
    return vec, rot


def _nearest_grid(model: Model, p: np.ndarray, atol: float) -> tuple[int, float]:
    """Row of the grid closest to p (lowest id among ties) and its distance."""
    d = np.linalg.norm(np.asarray(model.xyz) - p, axis=1)
    ties = np.flatnonzero(d <= d.min() * (1.0 + _TIE_RTOL) + atol)
    row = int(ties[np.argmin(np.asarray(model.node_ids)[ties])])
    return row, float(d[row])


# ---------------------------------------------------------------------------------------
# Projection on shell elements (all elements of one shape at once, for one point)

def _frames(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centroid (ne, 3) and rows x, y, n (ne, 3, 3) of the flat projected elements, from
    :func:`jaxfem.elements.shell_frame`."""
    return X.mean(axis=1), np.asarray(_shell_frames(jnp.asarray(X)))


_shell_frames = jax.jit(jax.vmap(shell_frame))  # called once per sensor: compiled once per element shape


def _natural(x2: np.ndarray, p2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Natural coordinates of p2 (ne, 2) in flat elements with corners x2 (ne, nn, 2):
    (ξ, η) of the bilinear map by Newton iterations (quad), or area coordinates (r, s)
    (tria); and whether the point lies in the element."""
    ne, nn = x2.shape[:2]
    if nn == 3:
        J = np.stack([x2[:, 1] - x2[:, 0], x2[:, 2] - x2[:, 0]], axis=2)  # columns ∂x/∂r, ∂x/∂s
        rs = np.linalg.solve(J, (p2 - x2[:, 0])[..., None])[..., 0]
        L = np.concatenate([1.0 - rs.sum(axis=1, keepdims=True), rs], axis=1)
        return rs, np.all(L >= -_INSIDE_TOL, axis=1)
    q = np.zeros((ne, 2))
    converged = np.zeros(ne, dtype=bool)
    for _ in range(_NEWTON_ITERS):
        N, dn = quad_shape(q[:, 0], q[:, 1])
        dxi, deta = dn[:, 0], dn[:, 1]
        r = np.einsum("ek,ekd->ed", N, x2) - p2
        J = np.stack([np.einsum("ek,ekd->ed", dxi, x2), np.einsum("ek,ekd->ed", deta, x2)], axis=2)
        with np.errstate(all="ignore"):
            step = np.linalg.solve(J, r[..., None])[..., 0]
        finite = np.isfinite(step).all(axis=1)
        step = np.where(finite[:, None], step, 0.0)
        q = np.clip(q - step, -10.0, 10.0)  # keep far points from running away
        converged = finite & (np.max(np.abs(step), axis=1) < _NEWTON_TOL)
        if converged.all():
            break
    inside = converged & np.all(np.abs(q) <= 1.0 + _INSIDE_TOL, axis=1)
    return q, inside


def _edge_natural(nn: int, a: int, t: np.ndarray) -> np.ndarray:
    """Natural coordinates of the point at fraction t along the side from corner a to a+1."""
    if nn == 4:
        c0, c1 = QUAD_CORNERS[a], QUAD_CORNERS[(a + 1) % 4]
    else:
        corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
        c0, c1 = corners[a], corners[(a + 1) % 3]
    return c0 + t[:, None] * (c1 - c0)


def _shape(nn: int, q: np.ndarray) -> np.ndarray:
    """Shape functions (ne, nn) at natural coordinates q (ne, 2)."""
    if nn == 4:
        return quad_shape(q[:, 0], q[:, 1])[0]
    return np.stack([1.0 - q[:, 0] - q[:, 1], q[:, 0], q[:, 1]], axis=1)


def _project(X: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape functions at the point of each element (ne, nn) nearest to p on the flat
    projected element, and the distance [m] from p to that point of the element surface
    Σ N_i X_i (ne,): the normal distance when p lies over the element."""
    ne, nn = X.shape[:2]
    c, T = _frames(X)
    x2 = np.einsum("eij,ekj->eki", T[:, :2], X - c[:, None, :])  # corners in the element plane
    p2 = np.einsum("eij,ej->ei", T[:, :2], p - c)
    q, inside = _natural(x2, p2)
    if not inside.all():  # nearest point on the boundary of the flat element
        best = np.full(ne, np.inf)
        q_edge = np.zeros((ne, 2))
        for a in range(nn):
            e0, e1 = x2[:, a], x2[:, (a + 1) % nn]
            v = e1 - e0
            t = np.clip(np.sum((p2 - e0) * v, axis=1) / np.sum(v * v, axis=1), 0.0, 1.0)
            d = np.linalg.norm(e0 + t[:, None] * v - p2, axis=1)
            closer = d < best
            best = np.where(closer, d, best)
            q_edge = np.where(closer[:, None], _edge_natural(nn, a, t), q_edge)
        q = np.where(inside[:, None], q, q_edge)
    N = _shape(nn, q)
    N = np.where(np.abs(N) < _SNAP, 0.0, N)
    N /= N.sum(axis=1, keepdims=True)
    surface = np.einsum("ek,ekd->ed", N, X)
    return N, np.linalg.norm(p - surface, axis=1)


def _element_size(X: np.ndarray) -> float:
    """Longest side of an element (nn, 3) [m]."""
    return float(max(np.linalg.norm(X[(a + 1) % len(X)] - X[a]) for a in range(len(X))))


class _Shells:
    """One block of shell elements with the bounding sphere of each (centroid, radius)."""

    def __init__(self, name: str, block, node_xyz: np.ndarray):
        self.name = name
        self.ids = np.asarray(block.ids)
        self.nodes = np.asarray(block.nodes)
        self.X = node_xyz[self.nodes]  # (ne, nn, 3)
        self.centre = self.X.mean(axis=1)
        self.radius = np.linalg.norm(self.X - self.centre[:, None, :], axis=2).max(axis=1)


def _nearest_element(shells: list[_Shells], p: np.ndarray, atol: float):
    """The shell element nearest to p (lowest id among ties): (distance, id, type, grid rows,
    shape functions). Only elements whose bounding sphere may hold a nearer point than the
    farthest point of the nearest sphere are projected."""
    to_centre = [np.linalg.norm(b.centre - p, axis=1) for b in shells]
    upper = min(float((d + b.radius).min()) for d, b in zip(to_centre, shells))
    candidates = []
    for d, b in zip(to_centre, shells):
        keep = np.flatnonzero(d - b.radius <= upper + atol)
        if len(keep):
            N, dist = _project(b.X[keep], p)
            candidates += [(float(dist[k]), int(b.ids[e]), b.name, b.nodes[e], N[k]) for k, e in enumerate(keep)]
    dmin = min(c[0] for c in candidates)
    return min((c for c in candidates if c[0] <= dmin * (1.0 + _TIE_RTOL) + atol), key=lambda c: c[1])


# ---------------------------------------------------------------------------------------


def _row(model: Model, rows: np.ndarray, N: np.ndarray, d: np.ndarray, rotational: bool) -> dict[int, float]:
    """Σ_i N_i Σ_c d_c coef[g_i, c] at the solved DoFs index[g_i] → {solved DoF: weight}."""
    comp = np.arange(3) + (3 if rotational else 0)
    coef = np.asarray(model.dofs.coef)[rows][:, comp]  # (nn, 3, w)
    weights = np.einsum("i,c,icw->iw", N, d, coef).ravel()
    index = np.asarray(model.dofs.index)[rows].ravel()
    out: dict[int, float] = {}
    for j, w in zip(index.tolist(), weights.tolist()):
        if j < model.n_dof and w != 0.0:
            out[j] = out.get(j, 0.0) + w
    return out


def locate_sensors(
    model: Model,
    xyz: Float[ArrayLike, "ns 3"],
    directions: Sequence[int | Sequence[float]] | np.ndarray,
    method: str = "nearest",
    *,
    rotational: Sequence[bool] | None = None,
    labels: Sequence[str] | None = None,
    max_distance: float | None = None,
) -> SensorMap:
    """Map sensors given by coordinates to the model's DoFs: the observation matrix.

    **Arguments:**

    - ``model``: the FE model (grids in m, basic axes).
    - ``xyz`` (n_sensors, 3): the sensor points [m], basic axes.
    - ``directions``: per sensor a Nastran component 1..6 (T1 T2 T3 R1 R2 R3; −1..−6
      measure along the negative axis) or a unit vector in basic axes (a translation);
      a sensor reads the projection ``d · u`` of its grid's translation (or rotation).
    - ``method``: ``"nearest"`` (the nearest grid, lowest id among ties) or
      ``"interpolate"`` (Σ N_i(ξ, η) u_i over the nearest CQUAD4/CTRIA3, the point
      projected on the flat element: Newton iterations on the bilinear map, area
      coordinates on triangles; the element surface is the grid surface, offsets ZOFFS
      are not applied).
    - ``rotational``: per sensor, whether a unit-vector direction measures a rotation
      (default: translations).
    - ``labels``: sensor names for the report (default ``"1"``, ``"2"``, …).
    - ``max_distance`` [m] (``interpolate``): a point farther than this from every shell
      element falls back to ``nearest`` with a ``UserWarning``; default: the longest side
      of the nearest element.

    **Returns:** a :class:`SensorMap`; ``SensorMap.observe(phi)`` gives ``C φ``.

    A sensor on a support reads the held components as zero (its row may be zero).
    ``ValueError`` for wrong shapes, a zero or non-unit direction, a component outside
    1..6, an unknown method or non-finite coordinates.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}: use one of {METHODS}")
    pts = np.asarray(xyz, dtype=np.float64)
    if pts.ndim == 1 and pts.shape == (3,):
        raise ValueError("xyz has shape (3,); give the sensor points as an (n_sensors, 3) array")
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"xyz has shape {pts.shape}, expected (n_sensors, 3)")
    bad = np.flatnonzero(~np.isfinite(pts).all(axis=1))
    if len(bad):
        raise ValueError(f"sensor {int(bad[0])}: coordinates {pts[bad[0]].tolist()} are not finite")
    n = len(pts)
    vec, rot = _directions(directions, n, rotational)
    labels = tuple(str(i + 1) for i in range(n)) if labels is None else tuple(str(s) for s in labels)
    if len(labels) != n:
        raise ValueError(f"{n} sensor points but {len(labels)} labels")
    if max_distance is not None and not max_distance > 0.0:
        raise ValueError(f"max_distance must be positive [m], got {max_distance}")

    blocks = [(name, block) for name, block in (("CQUAD4", model.quads), ("CTRIA3", model.trias))
              if len(block.ids)]
    node_xyz = np.asarray(model.xyz)
    grid_rows: list[np.ndarray] = []
    shape: list[np.ndarray] = []
    elements = np.full(n, -1, dtype=np.int64)
    types = [""] * n
    distance = np.zeros(n)
    fallback: list[str] = []
    tie_atol = _TIE_ATOL * (1.0 + float(np.ptp(node_xyz, axis=0).max())) if len(node_xyz) else 0.0
    shells = [_Shells(name, block, node_xyz) for name, block in blocks] if method == "interpolate" else []
    for s, p in enumerate(pts):
        found = None
        if method == "interpolate" and blocks:
            found = _nearest_element(shells, p, tie_atol)
            limit = _element_size(node_xyz[found[3]]) if max_distance is None else max_distance
            if found[0] > limit:
                fallback.append(f"{labels[s]} ({found[0]:.3g} m from {found[2]} {found[1]})")
                found = None
        elif method == "interpolate":
            fallback.append(labels[s])
        if found is None:
            row, distance[s] = _nearest_grid(model, p, tie_atol)
            grid_rows.append(np.array([row]))
            shape.append(np.ones(1))
        else:
            distance[s] = found[0] if found[0] > tie_atol else 0.0  # rounding on the surface reads 0
            elements[s], types[s] = found[1], found[2]
            keep = found[4] != 0.0
            grid_rows.append(found[3][keep])
            shape.append(found[4][keep])
    if fallback:
        why = "the model has no shell elements" if not blocks else "too far from every shell element"
        warnings.warn(
            f"interpolate: sensor(s) {', '.join(fallback)} read the nearest grid instead ({why})", stacklevel=2
        )

    return _sensor_map(model, grid_rows, shape, vec, rot, labels, pts, elements, tuple(types), distance, method)


def sensors_at_grids(
    model: Model,
    grids: Sequence[int],
    directions: Sequence[int | Sequence[float]] | np.ndarray,
    *,
    rotational: Sequence[bool] | None = None,
    labels: Sequence[str] | None = None,
) -> SensorMap:
    """Sensors placed at model grids by id (distance 0): the :class:`SensorMap` of
    :func:`locate_sensors` for test DoFs labelled with the model's grid ids.

    ``directions`` as in :func:`locate_sensors`; ``rotational`` marks unit-vector
    directions that measure rotations (default: translations). ``ValueError`` naming grid
    ids that are not in the model.
    """
    rows = model.node_index(grids)
    n = len(rows)
    vec, rot = _directions(directions, n, rotational)
    labels = tuple(str(g) for g in grids) if labels is None else tuple(str(x) for x in labels)
    return _sensor_map(model, [np.array([r]) for r in rows], [np.ones(1)] * n, vec, rot, labels,
                       np.asarray(model.xyz)[rows].reshape(n, 3), np.full(n, -1, dtype=np.int64), ("",) * n,
                       np.zeros(n), "grid")


def _sensor_map(model, grid_rows, shape, vec, rot, labels, pts, elements, types, distance, method) -> SensorMap:
    """The SensorMap of sensors reading Σ N_i u(grid_rows_i) along their directions."""
    n = len(grid_rows)
    node_ids = np.asarray(model.node_ids)
    rows = [_row(model, g, N, vec[s], rot[s]) for s, (g, N) in enumerate(zip(grid_rows, shape))]
    k = max([1, *(len(r) for r in rows)])
    indices = np.zeros((n, k), dtype=np.int64)
    weights = np.zeros((n, k))
    for s, r in enumerate(rows):
        indices[s, : len(r)] = list(r.keys())
        weights[s, : len(r)] = list(r.values())
    w = max([1, *(len(g) for g in grid_rows)])
    grids = np.full((n, w), -1, dtype=np.int64)
    shape_functions = np.zeros((n, w))
    for s, (g, N) in enumerate(zip(grid_rows, shape)):
        grids[s, : len(g)] = node_ids[g]
        shape_functions[s, : len(N)] = N
    return SensorMap(
        indices=indices,
        weights=weights,
        labels=labels,
        xyz=pts,
        directions=vec,
        rotational=rot,
        grids=grids,
        shape_functions=shape_functions,
        elements=elements,
        element_types=types,
        distance=distance,
        n_dof=model.n_dof,
        method=method,
    )
