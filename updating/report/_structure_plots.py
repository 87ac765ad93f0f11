"""3-D drawings of a model: a wireframe coloured by an indicator (:func:`plot_structure`)
and the shells as a surface map, flat where one plane holds them (:func:`plot_surface`).

Each draws on a private Agg canvas (``identification.figure``) or a given axes and
returns the figure (the other plots: :mod:`updating.report._plots`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from identification import figure as _figure


def _values_array(values: dict | None, keys) -> np.ndarray:
    """``values[k]`` per key (NaN where absent or None)."""
    if values is None:
        return np.full(len(keys), np.nan)
    out = [values.get(int(k)) for k in keys]
    return np.array([np.nan if v is None else float(v) for v in out], dtype=np.float64)


def _equal_3d(ax, xyz) -> None:
    """Limits of a 3-D axes around the points ``xyz`` (n, 3), one scale on all three axes
    (a flat direction given 2 % of the largest span), labelled in metres."""
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    span = hi - lo
    pad = np.maximum(span, 0.02 * max(span.max(), 1e-9))
    mid = 0.5 * (lo + hi)
    ax.set_xlim(mid[0] - pad[0] / 2, mid[0] + pad[0] / 2)
    ax.set_ylim(mid[1] - pad[1] / 2, mid[1] + pad[1] / 2)
    ax.set_zlim(mid[2] - pad[2] / 2, mid[2] + pad[2] / 2)
    ax.set_box_aspect(tuple(pad))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")


def _draw_point_elements(ax, model, xyz) -> bool:
    """Grounded springs (triangles) and CONM2 masses (squares) at their grids; whether any."""
    springs = np.asarray(model.springs.nodes).reshape(-1, 2)
    grounded = springs[(springs < 0).any(axis=1)].max(axis=1)
    grounded = grounded[grounded >= 0]
    if grounded.size:
        p = xyz[grounded]
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], marker="v", s=110, facecolors="none", edgecolors="tab:red",
                   linewidths=1.5, depthshade=False, label="spring to ground")
    masses = np.asarray(model.masses.nodes).reshape(-1)
    if masses.size:
        p = xyz[masses]
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], marker="s", s=110, facecolors="none", edgecolors="tab:orange",
                   linewidths=1.5, depthshade=False, label="CONM2")
    return bool(grounded.size or masses.size)


def _draw_node_values(ax, xyz, node_ids, node_values: dict, cmap, label: str, *, colorbar: bool) -> None:
    """Dots sized and coloured by ``node_values`` (the three largest annotated with their
    grid id); a colour bar for them when ``colorbar``."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    nv = _values_array(node_values, node_ids)
    sel = np.flatnonzero(np.isfinite(nv))
    if sel.size:
        v = nv[sel]
        nnorm = Normalize(v.min(), v.max())
        sizes = 15.0 + 165.0 * np.clip(nnorm(v), 0.0, 1.0)
        p = xyz[sel]
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=v, cmap=cmap, norm=nnorm, s=sizes,
                   edgecolors="black", linewidths=0.4, depthshade=False)
        if colorbar:
            ax.get_figure().colorbar(ScalarMappable(nnorm, cmap), ax=ax, label=label, shrink=0.6)
        for i in sel[np.argsort(-v)[:3]]:
            ax.text(*xyz[i], f"   {int(node_ids[i])}", fontsize=8, fontweight="bold", zorder=10)


def plot_structure(
    model,
    element_values: dict[int, float] | None = None,
    node_values: dict[int, float] | None = None,
    *,
    title: str = "",
    label: str = "indicator",
    ax=None,
):
    """3-D wireframe of a :class:`jaxfem.Model`, optionally coloured by an indicator.

    Beams, rods, bushes and two-node springs are lines between their grids, coloured
    by ``element_values[eid]`` (elements without a value: thin, light grey);
    grounded springs are triangles and CONM2 masses squares at their grid. Nodes in
    ``node_values`` (keys: grid ids) are dots sized and coloured by the value, the
    three largest annotated with their grid id. Keys not in the model are ignored.
    **Arguments:** the model; the two dicts (None: plain geometry); a title; the
    colour bar label; ``ax``: an existing 3-D axes (None: a new figure).
    **Returns:** the figure.
    """
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    if ax is None:
        fig = _figure(7.0, 6.0)
        ax = fig.add_subplot(projection="3d")
    elif getattr(ax, "name", None) != "3d":
        raise ValueError("ax must be a 3-D axes (projection='3d')")
    fig = ax.get_figure()
    xyz = np.asarray(model.xyz, dtype=np.float64)
    node_ids = np.asarray(model.node_ids)
    rows, eids = model.segments()
    cmap = colormaps["viridis"]

    ev = _values_array(element_values, eids)
    has = np.isfinite(ev)
    enorm = Normalize(*(np.nanmin(ev[has]), np.nanmax(ev[has])) if has.any() else (0.0, 1.0))
    plain = "0.3" if element_values is None else "0.8"
    colours = [cmap(enorm(v)) if h else plain for v, h in zip(ev, has)]
    widths = np.where(has, 2.2, 0.9 if element_values is None else 0.6)
    lines = Line3DCollection(xyz[rows], colors=colours, linewidths=widths)
    ax.add_collection3d(lines)
    if has.any():
        fig.colorbar(ScalarMappable(enorm, cmap), ax=ax, label=label, shrink=0.6)

    points = _draw_point_elements(ax, model, xyz)
    if node_values:
        _draw_node_values(ax, xyz, node_ids, node_values, cmap, label, colorbar=not has.any())
    elif node_values is None and element_values is None:
        ax.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], s=4, color="black")

    _equal_3d(ax, xyz)
    if points:
        ax.legend(fontsize=7, loc="upper left")
    if title:
        ax.set_title(title)
    return fig


_FLAT_COS = float(np.cos(np.radians(10.0)))  # a shell is in the plane when its normal is within 10° of the plane's
_FLAT_SHARE = 0.6  # a 2-D map when one plane holds this share of the shell area
_FLAT_OFFSET = 0.02  # ... within this distance of the plane, relative to the largest span of the shells
_AXIS_COS = float(np.cos(np.radians(2.0)))  # a plane within 2° of a coordinate plane is drawn in x, y or z


def _shell_normals(xyz: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit normals (n, 3) and areas (n,) of shells from their corner rows (n, 4), −1
    padding a triangle (a quad's normal from its diagonals)."""
    p = xyz[np.where(corners >= 0, corners, corners[:, :1])]
    quad = (corners[:, 3] >= 0)[:, None]
    n = np.cross(np.where(quad, p[:, 2] - p[:, 0], p[:, 1] - p[:, 0]),
                 np.where(quad, p[:, 3] - p[:, 1], p[:, 2] - p[:, 0]))
    length = np.linalg.norm(n, axis=1)
    return n / np.maximum(length, 1e-300)[:, None], 0.5 * length


def _dominant_plane(xyz: np.ndarray, corners: np.ndarray, centres: np.ndarray):
    """``(unit normal, in-plane mask per shell)`` of the plane that holds at least
    ``_FLAT_SHARE`` of the shell area (normals within 10° of its normal, centres within 2 %
    of the shells' span of it), e.g. the plate of a stiffened panel; None when none does
    (a curved skin, a box)."""
    normals, area = _shell_normals(xyz, corners)
    if not area.sum() > 0:
        return None
    n = np.linalg.eigh((normals * area[:, None]).T @ normals)[1][:, -1]  # the area-weighted mean direction
    parallel = np.abs(normals @ n) >= _FLAT_COS
    if not parallel.any():
        return None
    offset = centres @ n
    o, a = offset[parallel], area[parallel]
    order = np.argsort(o)
    cum = np.cumsum(a[order])
    level = o[order][np.searchsorted(cum, 0.5 * cum[-1])]  # area-weighted median offset
    tol = _FLAT_OFFSET * max(float(np.ptp(centres, axis=0).max()), float(np.sqrt(area.max())))
    inside = parallel & (np.abs(offset - level) <= tol)
    return (n, inside) if area[inside].sum() >= _FLAT_SHARE * area.sum() else None


def _plane_axes(n: np.ndarray) -> tuple[np.ndarray, tuple[str, str]]:
    """Orthonormal in-plane axes (3, 2) of a plane with unit normal ``n`` and their names:
    the two other coordinate axes when ``n`` is within 2° of one, else u (the flattest
    coordinate axis projected on the plane) and v = n × u."""
    k = int(np.argmax(np.abs(n)))
    if abs(n[k]) >= _AXIS_COS:
        dims = [d for d in range(3) if d != k]
        return np.eye(3)[:, dims], ("xyz"[dims[0]], "xyz"[dims[1]])
    u = np.eye(3)[int(np.argmin(np.abs(n)))]
    u = u - (u @ n) * n
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    return np.stack([u, v], axis=1), tuple(f"{s} along ({', '.join(f'{c:.2f}' for c in w)})"
                                           for s, w in (("u", u), ("v", v)))


def _free_edges(corners: np.ndarray) -> np.ndarray:
    """Outline of a set of shells given by corner rows (n, 4), −1 padding: the edges that
    belong to one of them only, as grid rows (s, 2)."""
    count: dict[tuple[int, int], int] = {}
    for c in corners:
        c = c[c >= 0]
        for a, b in zip(c, np.roll(c, -1)):
            key = (int(min(a, b)), int(max(a, b)))
            count[key] = count.get(key, 0) + 1
    return np.array([k for k, m in count.items() if m == 1], dtype=np.int64).reshape(-1, 2)


def plot_surface(
    model,
    element_values: dict[int, float] | None,
    *,
    sensors=None,
    patch: dict | None = None,
    title: str = "",
    label: str = "element indicator",
    ax=None,
):
    """Colour map of a per-element indicator on the shells of a :class:`jaxfem.Model`,
    with the sensors and a patch (e.g. the delamination an effect places).

    Shells (CQUAD4, CTRIA3) are filled by ``element_values[eid]`` on the viridis scale
    (shells without a value: light grey), beams, rods, bushes and springs are thin grey
    lines. When one plane holds most of the shell area (a flat panel; its stiffeners may
    stand out of it) the map is 2-D, seen along the plane's normal: shells out of the
    plane are drawn as outlines coloured by their value (grey without), stringers seen
    edge-on as lines. Otherwise (a curved skin, a barrel) the shells are a 3-D surface on
    one scale in x, y and z.

    **Arguments:**

    - ``model``: a model with shell elements.
    - ``element_values``: element id → value (None: plain geometry); keys not in the
      model are ignored.
    - ``sensors``: grid ids with sensors (repeats are drawn once; ids not in the model
      ignored), drawn as small black dots.
    - ``patch``: an effect as in the diagnosis JSON, ``{"kind": ..., "eids": [...],
      "nodes": [centre grid], "radius_m": ...}`` (``nodes`` and ``radius_m`` optional):
      the outline of its elements in red (its line elements thick red), its centre grid
      marked with an x and, in 2-D, a dashed circle of ``radius_m`` about it; the legend
      names the kind and the radius in mm.
    - ``title``, ``label``: the title and the colour bar's label.
    - ``ax``: an existing axes (None: a new figure): a 3-D axes (``projection='3d'``)
      gets the 3-D drawing, a 2-D one the 2-D map (the shells must then lie in a plane).

    **Returns:** the figure (its own Agg canvas, no pyplot state). Raises ``ValueError``
    for a model without shells or a 2-D ``ax`` for shells not in a plane.
    """
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable

    from identification import shell_centres

    ids, centres, corners = shell_centres(model)
    if not len(ids):
        raise ValueError("the model has no shell elements (CQUAD4, CTRIA3): draw it with plot_structure")
    xyz = np.asarray(model.xyz, dtype=np.float64)
    row_of = {int(n): i for i, n in enumerate(np.asarray(model.node_ids))}
    rows, eids = model.segments()
    lines = ~np.isin(eids, ids)  # segments() also gives the shells' edges
    rows, eids = rows[lines], eids[lines]

    cmap = colormaps["viridis"]
    has, norm, faces, edges = _shell_colours(_values_array(element_values, ids), cmap)
    s_rows = np.array(sorted({row_of[int(g)] for g in (sensors if sensors is not None else ()) if int(g) in row_of}),
                      dtype=np.int64)
    marks = _patch_marks(patch, ids, eids, row_of)

    plane = _dominant_plane(xyz, corners, centres)
    if ax is None:
        fig = _figure(8.0, 6.0)
        ax = fig.add_subplot() if plane is not None else fig.add_subplot(projection="3d")
    elif getattr(ax, "name", None) == "3d":
        plane = None
    elif plane is None:
        raise ValueError("the shells are not in one plane: pass a 3-D axes (projection='3d') or ax=None")
    fig = ax.get_figure()

    if plane is not None:
        _draw_plane_map(ax, plane, xyz, corners, faces, edges, rows, marks, s_rows)
    else:
        _draw_surface_3d(ax, xyz, corners, faces, rows, marks, s_rows)
    if has.any():
        fig.colorbar(ScalarMappable(norm, cmap), ax=ax, label=label, shrink=0.8)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    if title:
        ax.set_title(title, fontsize=10)
    return fig


class _PatchMarks(NamedTuple):
    """A patch as :func:`plot_surface` draws it."""

    shells: np.ndarray  # mask over the shells
    lines: np.ndarray  # mask over the line segments
    centre_id: int | None  # the centre grid's id
    centre: int | None  # ... and its row
    radius: float | None  # metres; None: no circle
    label: str  # the legend entry of the outline


def _shell_colours(values: np.ndarray, cmap):
    """``(has value, norm, face colours, edge colours)`` of the shells (no value: grey)."""
    from matplotlib.colors import Normalize, to_rgba

    has = np.isfinite(values)
    norm = Normalize(*(np.nanmin(values[has]), np.nanmax(values[has])) if has.any() else (0.0, 1.0))
    faces = cmap(norm(np.where(has, values, 0.0)))
    faces[~has] = to_rgba("0.85")
    edges = faces.copy()
    edges[~has] = to_rgba("0.45")
    return has, norm, faces, edges


def _patch_marks(patch: dict | None, ids, eids, row_of: dict) -> _PatchMarks:
    """The shells, line segments, centre grid, radius and legend label of a patch."""
    patch = dict(patch or {})
    p_eids = np.asarray(patch.get("eids") or [], dtype=np.int64)
    centre_id = next((int(g) for g in patch.get("nodes") or [] if int(g) in row_of), None)
    radius = patch.get("radius_m")
    radius = float(radius) if radius is not None and np.isfinite(float(radius)) and float(radius) > 0 else None
    return _PatchMarks(np.isin(ids, p_eids), np.isin(eids, p_eids), centre_id,
                       None if centre_id is None else row_of[centre_id], radius,
                       str(patch.get("kind") or "patch") + (f", radius {1000.0 * radius:.3g} mm" if radius else ""))


def _draw_plane_map(ax, plane, xyz, corners, faces, edges, rows, marks: _PatchMarks, s_rows) -> None:
    """The 2-D map seen along the plane's normal: shells in the plane filled, the others
    as coloured outlines, line elements, the patch and the sensors."""
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.patches import Circle

    from identification import boundary

    basis, names = _plane_axes(plane[0])
    xy = xyz @ basis
    polys = [xy[c[c >= 0]] for c in corners]
    inside = np.flatnonzero(plane[1])
    others = np.flatnonzero(~plane[1])
    ax.add_collection(PolyCollection([polys[i] for i in inside], facecolors=faces[inside], edgecolors="0.55",
                                     linewidths=0.25, zorder=1))
    if others.size:
        ax.add_collection(PolyCollection([polys[i] for i in others], facecolors="none", edgecolors=edges[others],
                                         linewidths=1.5, zorder=2))
    if len(rows):
        ax.add_collection(LineCollection(xy[rows], colors="0.4", linewidths=0.8, zorder=2))
    outline = np.concatenate([boundary([polys[i] for i in np.flatnonzero(marks.shells)]), xy[rows[marks.lines]]])
    if len(outline):
        ax.add_collection(LineCollection(outline, colors="tab:red", linewidths=2.5, zorder=4, label=marks.label))
    if marks.centre is not None:
        ax.plot(*xy[marks.centre], marker="x", color="tab:red", markersize=10, mew=2.2, linestyle="none", zorder=5,
                label=f"centre: grid {marks.centre_id}")
        if marks.radius:
            ax.add_patch(Circle(xy[marks.centre], marks.radius, fill=False, edgecolor="tab:red", linestyle="--",
                                linewidth=1.2, zorder=4))
    if s_rows.size:
        ax.scatter(xy[s_rows, 0], xy[s_rows, 1], s=14, color="black", zorder=6, label=f"sensors ({s_rows.size} grids)")
    ax.set_xlabel(f"{names[0]} [m]")
    ax.set_ylabel(f"{names[1]} [m]")
    ax.autoscale()
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.03)


def _draw_surface_3d(ax, xyz, corners, faces, rows, marks: _PatchMarks, s_rows) -> None:
    """The shells as a 3-D surface on one scale in x, y and z, with line elements, the
    patch and the sensors in front."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    ax.computed_zorder = False  # the patch, its centre and the sensors stay visible in front of the skin
    ax.add_collection3d(Poly3DCollection([xyz[c[c >= 0]] for c in corners], facecolors=faces,
                                         edgecolors=(0.0, 0.0, 0.0, 0.25), linewidths=0.2, zorder=1))
    if len(rows):
        ax.add_collection3d(Line3DCollection(xyz[rows], colors="0.4", linewidths=0.6, zorder=2))
    outline = np.concatenate([xyz[_free_edges(corners[marks.shells])], xyz[rows[marks.lines]]]).reshape(-1, 2, 3)
    if len(outline):
        ax.add_collection3d(Line3DCollection(outline, colors="tab:red", linewidths=2.5, zorder=4, label=marks.label))
    if marks.centre is not None:
        ax.plot(*xyz[marks.centre][:, None], marker="x", color="tab:red", markersize=10, mew=2.2, linestyle="none",
                zorder=5, label=f"centre: grid {marks.centre_id}")
    if s_rows.size:
        p = xyz[s_rows]
        ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=10, color="black", depthshade=False, zorder=6,
                   label=f"sensors ({s_rows.size} grids)")
    _equal_3d(ax, xyz)

