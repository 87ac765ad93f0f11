"""Correlation and updating plots: MAC matrix, frequency deviations, convergence.

Each function draws one figure on a private Agg canvas (``identification._plots._figure``:
never pyplot, so no global backend or figure registry is touched), writes it as a PNG
and returns the path. Frequency deviations are percentages, Δf = 100 (f_model − f_test) / f_test (thesis eq. 4.1); NaN marks an unpaired mode.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from identification._plots import _figure


def _save(fig, path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, format="png")
    return path


def plot_mac(
    mac_matrix,
    test_labels: Sequence[str],
    model_labels: Sequence[str],
    path: str | Path,
    title: str = "MAC",
) -> Path:
    """Heat map of a MAC matrix (thesis eq. 1.54), the value printed in each cell.

    **Arguments:** ``mac_matrix`` of shape ``(n_test, n_model)`` (rows: test modes,
    columns: model modes), values in [0, 1]; labels for the rows and columns; the PNG
    path; a title. **Returns:** the path written.
    """
    m = np.asarray(mac_matrix, dtype=np.float64)
    if m.ndim != 2 or m.shape != (len(test_labels), len(model_labels)):
        raise ValueError(
            f"mac_matrix has shape {m.shape}, expected ({len(test_labels)}, {len(model_labels)}) "
            "(test labels × model labels)"
        )
    n_e, n_a = m.shape
    fig = _figure(max(4.0, 1.2 + 0.55 * n_a), max(3.0, 1.2 + 0.45 * n_e))
    ax = fig.add_subplot()
    image = ax.imshow(m, vmin=0.0, vmax=1.0, cmap="viridis", aspect="auto")
    fig.colorbar(image, ax=ax, label="MAC [–]")
    small = max(n_e, n_a) > 14
    for i in range(n_e):
        for j in range(n_a):
            v = m[i, j]
            ax.text(j, i, "–" if not np.isfinite(v) else f"{v:.2f}", ha="center", va="center",
                    fontsize=6 if small else 8, color="black" if v > 0.6 else "white")
    ax.set_xticks(range(n_a), [str(s) for s in model_labels], rotation=90 if small else 0)
    ax.set_yticks(range(n_e), [str(s) for s in test_labels])
    ax.set_xlabel("model mode [no. (f Hz)]")
    ax.set_ylabel("test mode [no. (f Hz)]")
    ax.set_title(title)
    return _save(fig, path)


def plot_freq_dev(
    before,
    after,
    labels: Sequence[str],
    path: str | Path,
    active=None,
) -> Path:
    """Grouped bar chart of Δf [%] per test mode, before and after updating.

    **Arguments:** ``before`` (and ``after``, or None for a single series) Δf in % per
    test mode (NaN where unpaired: no bar, "n/p" written at the axis); ``labels`` per
    test mode; the PNG path; ``active``: bool per test mode (None: all active). Passive
    modes (held out of the fit) are drawn hatched and lighter. **Returns:** the path.
    """
    series = [("before", np.asarray(before, dtype=np.float64))]
    if after is not None:
        series.append(("after", np.asarray(after, dtype=np.float64)))
    n = len(labels)
    for name, values in series:
        if values.shape != (n,):
            raise ValueError(f"{name} has shape {values.shape}, expected ({n},) (one value per label)")
    act = np.ones(n, dtype=bool) if active is None else np.asarray(active, dtype=bool)
    if act.shape != (n,):
        raise ValueError(f"active has shape {act.shape}, expected ({n},)")
    from matplotlib.patches import Patch

    colours = {"before": "tab:orange", "after": "tab:blue"} if len(series) > 1 else {"before": "tab:blue"}
    fig = _figure(max(5.0, 1.5 + 0.6 * n * len(series)), 3.8)
    ax = fig.add_subplot()
    width = 0.8 / len(series)
    x = np.arange(n)
    for k, (name, values) in enumerate(series):
        pos = x + (k - (len(series) - 1) / 2) * width
        shown = np.where(np.isfinite(values), values, 0.0)
        for i in range(n):
            ax.bar(pos[i], shown[i], width, color=colours[name], alpha=1.0 if act[i] else 0.45,
                   hatch=None if act[i] else "//", edgecolor="black", linewidth=0.5)
            if not np.isfinite(values[i]):
                ax.text(pos[i], 0.0, "n/p", ha="center", va="bottom", fontsize=7, rotation=90)
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.set_xticks(x, [str(s).replace(" (", "\n(") for s in labels])
    ax.set_xlabel("test mode [no. (f Hz)]")
    ax.set_ylabel("Δf = (f_model − f_test) / f_test [%]")
    handles = [Patch(facecolor=colours[name], edgecolor="black", label=name if len(series) > 1 else "Δf")
               for name, _ in series]
    if not act.all():
        handles += [Patch(facecolor="white", edgecolor="black", label="active (fitted)"),
                    Patch(facecolor="white", edgecolor="black", hatch="//", label="passive (held out)")]
    ax.legend(handles=handles, fontsize=8)
    ax.set_title("Frequency deviation" + (" before / after updating" if len(series) > 1 else ""))
    ax.grid(axis="y", alpha=0.3)
    return _save(fig, path)


def plot_convergence(history, names: Sequence[str], path: str | Path, active=None) -> Path:
    """Two panels: the factors α per parameter, and Δf [%] per test mode, vs iteration.

    **Arguments:** ``history``: the iterates of an update, objects with ``iteration``,
    ``alpha`` (one per name) and ``freq_dev`` (fraction per test mode, NaN if
    unpaired) such as :class:`updating._solve.Iteration`; the parameter names; the
    PNG path; ``active``: bool per test mode (passive modes dashed; None: all active).
    **Returns:** the path.
    """
    if not len(history):
        raise ValueError("history is empty")
    it = np.array([h.iteration for h in history])
    alpha = np.array([np.asarray(h.alpha, dtype=np.float64) for h in history])
    dev = 100.0 * np.array([np.asarray(h.freq_dev, dtype=np.float64) for h in history])
    if alpha.shape[1] != len(names):
        raise ValueError(f"{alpha.shape[1]} parameters in the history but {len(names)} names")
    act = np.ones(dev.shape[1], dtype=bool) if active is None else np.asarray(active, dtype=bool)
    if act.shape != (dev.shape[1],):
        raise ValueError(f"active has shape {act.shape}, expected ({dev.shape[1]},)")
    fig = _figure(9.0, 3.8)
    ax1, ax2 = fig.subplots(1, 2)
    for k, name in enumerate(names):
        ax1.plot(it, alpha[:, k], marker="o", markersize=3, label=name)
    ax1.set_xlabel("iteration [–]")
    ax1.set_ylabel("correction factor α [–] (value = value₀ (1 + α))")
    ax1.set_title("Parameters")
    ax1.legend(fontsize=7)
    ax1.grid(alpha=0.3)
    for j in range(dev.shape[1]):
        ax2.plot(it, dev[:, j], marker="o", markersize=3, linestyle="-" if act[j] else "--",
                 label=f"test {j + 1}" + ("" if act[j] else " (passive)"))
    ax2.axhline(0.0, color="black", linewidth=0.8)
    ax2.set_xlabel("iteration [–]")
    ax2.set_ylabel("Δf [%]")
    ax2.set_title("Frequency deviation per test mode")
    ax2.legend(fontsize=7, ncol=2 if dev.shape[1] > 8 else 1)
    ax2.grid(alpha=0.3)
    for ax in (ax1, ax2):
        ax.xaxis.get_major_locator().set_params(integer=True)
    return _save(fig, path)


def plot_damping(damping: dict, path: str | Path) -> Path:
    """Modal damping ratio ζ [%] per mode against its test frequency: measured (with its
    stated σ), Rayleigh damping alone fitted, and with the first-ranked region's loss
    factor (``damping``: the report of :func:`updating.diagnose_damping`). **Returns:** the path."""
    rows = damping["modes"]
    f = np.array([r["f_test_hz"] for r in rows])
    z = 100 * np.array([r["zeta_test"] for r in rows])
    fig = _figure(7.0, 4.0)
    ax = fig.add_subplot()
    ax.errorbar(f, z, yerr=z * damping["noise_pct"] / 100, fmt="o", color="black", capsize=3, label="measured (±σ)")
    ax.plot(f, 100 * np.array([r["zeta_baseline"] for r in rows]), "s--", color="tab:orange", label="Rayleigh alone")
    if damping["effects"] and rows[0].get("zeta_best") is not None:
        top = damping["effects"][0]
        ax.plot(f, 100 * np.array([r["zeta_best"] for r in rows]), "^-", color="tab:blue",
                label=f"+ η = {top['eta']:.3g} on {top['where']}"[:60] + ("" if top["warranted"] else " (not declared)"))
    ax.set_xlabel("test frequency [Hz]")
    ax.set_ylabel("damping ratio ζ [%]")
    ax.set_title("Modal damping: measured and predicted")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def plot_frf_overlay(freqs_hz, measured, curves: dict, label: str, path: str | Path, unit: str) -> Path:
    """Magnitude of one measured FRF with model predictions (e.g. before/after updating)."""
    fig = _figure(7.0, 4.0)
    ax = fig.add_subplot(1, 1, 1)
    ax.semilogy(freqs_hz, np.abs(measured), color="black", lw=1.6, label="measured")
    for name, values in curves.items():
        ax.semilogy(freqs_hz, np.abs(values), lw=1.1, label=name)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"|H| [{unit}]")
    ax.set_title(f"FRF {label}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    return _save(fig, path)


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

    if node_values:
        nv = _values_array(node_values, node_ids)
        sel = np.flatnonzero(np.isfinite(nv))
        if sel.size:
            v = nv[sel]
            nnorm = Normalize(v.min(), v.max())
            sizes = 15.0 + 165.0 * np.clip(nnorm(v), 0.0, 1.0)
            p = xyz[sel]
            ax.scatter(p[:, 0], p[:, 1], p[:, 2], c=v, cmap=cmap, norm=nnorm, s=sizes,
                       edgecolors="black", linewidths=0.4, depthshade=False)
            if not has.any():
                fig.colorbar(ScalarMappable(nnorm, cmap), ax=ax, label=label, shrink=0.6)
            for i in sel[np.argsort(-v)[:3]]:
                ax.text(*xyz[i], f"   {int(node_ids[i])}", fontsize=8, fontweight="bold", zorder=10)
    elif node_values is None and element_values is None:
        ax.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], s=4, color="black")

    _equal_3d(ax, xyz)
    if grounded.size or masses.size:
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
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.colors import Normalize, to_rgba
    from matplotlib.patches import Circle
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    from identification._patches import shell_centres
    from identification._plots import _boundary

    ids, centres, corners = shell_centres(model)
    if not len(ids):
        raise ValueError("the model has no shell elements (CQUAD4, CTRIA3): draw it with plot_structure")
    xyz = np.asarray(model.xyz, dtype=np.float64)
    row_of = {int(n): i for i, n in enumerate(np.asarray(model.node_ids))}
    rows, eids = model.segments()
    lines = ~np.isin(eids, ids)  # segments() also gives the shells' edges
    rows, eids = rows[lines], eids[lines]

    cmap = colormaps["viridis"]
    values = _values_array(element_values, ids)
    has = np.isfinite(values)
    norm = Normalize(*(np.nanmin(values[has]), np.nanmax(values[has])) if has.any() else (0.0, 1.0))
    faces = cmap(norm(np.where(has, values, 0.0)))
    faces[~has] = to_rgba("0.85")
    edges = faces.copy()
    edges[~has] = to_rgba("0.45")

    s_rows = np.array(sorted({row_of[int(g)] for g in (sensors if sensors is not None else ()) if int(g) in row_of}),
                      dtype=np.int64)
    patch = dict(patch or {})
    p_eids = np.asarray(patch.get("eids") or [], dtype=np.int64)
    p_shells, p_lines = np.isin(ids, p_eids), np.isin(eids, p_eids)
    centre_id = next((int(g) for g in patch.get("nodes") or [] if int(g) in row_of), None)
    centre = None if centre_id is None else row_of[centre_id]
    radius = patch.get("radius_m")
    radius = float(radius) if radius is not None and np.isfinite(float(radius)) and float(radius) > 0 else None
    p_label = str(patch.get("kind") or "patch") + (f", radius {1000.0 * radius:.3g} mm" if radius else "")

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
        outline = np.concatenate([_boundary([polys[i] for i in np.flatnonzero(p_shells)]), xy[rows[p_lines]]])
        if len(outline):
            ax.add_collection(LineCollection(outline, colors="tab:red", linewidths=2.5, zorder=4, label=p_label))
        if centre is not None:
            ax.plot(*xy[centre], marker="x", color="tab:red", markersize=10, mew=2.2, linestyle="none", zorder=5,
                    label=f"centre: grid {centre_id}")
            if radius:
                ax.add_patch(Circle(xy[centre], radius, fill=False, edgecolor="tab:red", linestyle="--",
                                    linewidth=1.2, zorder=4))
        if s_rows.size:
            ax.scatter(xy[s_rows, 0], xy[s_rows, 1], s=14, color="black", zorder=6, label=f"sensors ({s_rows.size} grids)")
        ax.set_xlabel(f"{names[0]} [m]")
        ax.set_ylabel(f"{names[1]} [m]")
        ax.autoscale()
        ax.set_aspect("equal", adjustable="datalim")
        ax.margins(0.03)
    else:
        ax.computed_zorder = False  # the patch, its centre and the sensors stay visible in front of the skin
        ax.add_collection3d(Poly3DCollection([xyz[c[c >= 0]] for c in corners], facecolors=faces,
                                             edgecolors=(0.0, 0.0, 0.0, 0.25), linewidths=0.2, zorder=1))
        if len(rows):
            ax.add_collection3d(Line3DCollection(xyz[rows], colors="0.4", linewidths=0.6, zorder=2))
        outline = np.concatenate([xyz[_free_edges(corners[p_shells])], xyz[rows[p_lines]]]).reshape(-1, 2, 3)
        if len(outline):
            ax.add_collection3d(Line3DCollection(outline, colors="tab:red", linewidths=2.5, zorder=4, label=p_label))
        if centre is not None:
            ax.plot(*xyz[centre][:, None], marker="x", color="tab:red", markersize=10, mew=2.2, linestyle="none",
                    zorder=5, label=f"centre: grid {centre_id}")
        if s_rows.size:
            p = xyz[s_rows]
            ax.scatter(p[:, 0], p[:, 1], p[:, 2], s=10, color="black", depthshade=False, zorder=6,
                       label=f"sensors ({s_rows.size} grids)")
        _equal_3d(ax, xyz)
    if has.any():
        fig.colorbar(ScalarMappable(norm, cmap), ax=ax, label=label, shrink=0.8)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    if title:
        ax.set_title(title, fontsize=10)
    return fig


def _runs(values) -> str:
    """``[201, 202, 203, 207]`` → ``"201-203, 207"``."""
    v = sorted(int(x) for x in values)
    parts, start = [], 0
    for i in range(1, len(v) + 1):
        if i == len(v) or v[i] != v[i - 1] + 1:
            parts.append(str(v[start]) if i - start == 1 else
                         f"{v[start]}, {v[i - 1]}" if i - start == 2 else f"{v[start]}-{v[i - 1]}")
            start = i
    return ", ".join(parts)


def effect_where(effect: dict) -> str:
    """``"pid 41"``, ``"node 1029"``, ``"eids 201-205"``: the non-empty id lists of an effect."""
    out = []
    for key, one in (("pids", "pid"), ("eids", "eid"), ("nodes", "node")):
        ids = list(effect.get(key) or [])
        if ids:
            out.append(f"{one if len(ids) == 1 else key} {_runs(ids)}")
    return " ".join(out)


def _finite(value) -> bool:
    return value is not None and np.isfinite(float(value))


def plot_effect_ranking(effects: list[dict]):
    """Held-out RMS Δf [%] before / after each candidate effect, best at the top.

    **Arguments:** ``effects``: dicts with ``kind``, ``pids``/``eids``/``nodes``,
    ``posterior``, ``heldout_rms_freq_dev_pct_before`` and ``..._after`` (a missing key
    skips that bar), best first or ordered by ``rank``; at most 12 are drawn.
    **Returns:** the figure.
    """
    if effects and all("rank" in e for e in effects):
        effects = sorted(effects, key=lambda e: e["rank"])
    effects = list(effects)[:12]
    fig = _figure(7.5, 1.4 + 0.45 * max(len(effects), 1))
    ax = fig.add_subplot()
    if not effects:
        ax.text(0.5, 0.5, "no candidate effects", ha="center", va="center", transform=ax.transAxes)
        ax.set_axis_off()
        return fig
    y = np.arange(len(effects))[::-1].astype(np.float64)
    h = 0.38
    series = (("before", "tab:orange", +h / 2), ("after", "tab:blue", -h / 2))
    top = 0.0
    for name, colour, dy in series:
        key = f"heldout_rms_freq_dev_pct_{name}"
        first = True
        for yi, e in zip(y, effects):
            if _finite(e.get(key)):
                ax.barh(yi + dy, float(e[key]), h, color=colour, edgecolor="black", linewidth=0.5,
                        label=name if first else None)
                top, first = max(top, float(e[key])), False
    for yi, e in zip(y, effects):
        if _finite(e.get("posterior")):
            ax.text(0.99, yi, f"posterior {float(e['posterior']):.2g}", ha="right", va="center", fontsize=8,
                    transform=ax.get_yaxis_transform())
    ax.set_xlim(0.0, 1.3 * top if top > 0 else 1.0)
    ax.set_yticks(y, [f"{e.get('kind', '?')} {effect_where(e)}".strip() for e in effects])
    ax.set_xlabel("held-out RMS Δf [%]")
    ax.set_title("Candidate effects")
    ax.grid(axis="x", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        fig.legend(loc="outside lower center", ncols=2, fontsize=8)
    return fig
