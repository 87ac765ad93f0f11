"""Identification plots: the stabilisation diagram of :func:`identification._fitting.identify`
and the damage maps of :func:`identification._damage.localise_damage` (thesis eq. 3.45), over
elements (:func:`plot_damage_map`) or over shell patches (:func:`plot_shell_damage_map`).

Drawn on a private Agg canvas (``matplotlib.figure.Figure``, never pyplot: no global
backend or figure registry is touched) and written as PNG. Matplotlib is imported when a
plot is drawn, so that importing :mod:`identification` does not load it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from jaxfem import Model

    from ._damage import DamageScan

_DPI = 120

# (label, marker, colour, filled) per stability class, drawn in this order
_CLASSES = (
    ("new / unstable", "o", "0.65", False),
    ("stable f", ".", "tab:blue", True),
    ("stable f, ζ", "x", "tab:orange", True),
    ("stable f, MAC", "+", "tab:purple", True),
    ("stable f, ζ, MAC", "s", "tab:green", False),
)


def figure(width: float, height: float):
    """A Matplotlib figure of ``width`` × ``height`` inches on its own Agg canvas (no pyplot
    state), constrained layout, at the resolution of every plot here."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def plot_stabilisation(report: Mapping, path: str | Path, title: str = "Stabilisation diagram (pLSCF)") -> Path:
    """Stabilisation diagram: poles by model order against frequency, with the mode indicator.

    **Arguments:** ``report``, the dict returned by :func:`identify` (its
    ``"stabilisation"``, ``"indicator"`` and ``"modes"`` entries; a report read back from
    JSON works too); the PNG ``path``; a title.

    Markers: grey circle a new or unstable pole, dot stable in frequency, cross also in
    damping, plus also in MAC (not damping), green square stable in all three; the poles
    that make up a selected mode are filled, and each selected mode has a dashed line at
    its frequency. The normalised mode indicator Σ|H|² (each FRF scaled to its maximum)
    is drawn in grey on a log scale (right axis). The subtitle gives the stability
    criteria; the report of a failed run (``IdentificationError.report``,
    ``identified: False``) is titled "no mode selected".

    **Returns:** the path written. Raises ``ValueError`` when the report lacks the diagram.
    """
    try:
        diagram = report["stabilisation"]
        f = np.asarray(diagram["frequency_hz"], dtype=np.float64)
        order = np.asarray(diagram["order"], dtype=np.float64)
        sf = np.asarray(diagram["stable_frequency"], dtype=bool)
        sd = np.asarray(diagram["stable_damping"], dtype=bool)
        sv = np.asarray(diagram["stable_mac"], dtype=bool)
    except (KeyError, TypeError) as err:
        raise ValueError(f"the report has no stabilisation diagram ({err}); pass the report of identify") from err
    mode = np.asarray(diagram.get("mode", np.zeros(len(f))), dtype=np.int64)
    fig = figure(9.0, 5.5)
    ax = fig.add_subplot()
    classes = (~sf, sf & ~sd & ~sv, sf & sd & ~sv, sf & ~sd & sv, sf & sd & sv)
    for (label, marker, colour, filled), mask in zip(_CLASSES, classes):
        if not np.any(mask):
            continue
        style = {"color": colour} if filled else {"facecolors": "none", "edgecolors": colour}
        ax.scatter(f[mask], order[mask], s=18, marker=marker, label=label, linewidths=0.9, zorder=3, **style)
    used = mode > 0
    if np.any(used):
        ax.scatter(f[used], order[used], s=18, marker="s", color="tab:green", label="used for a mode", zorder=4)
    for m in report.get("modes", []):
        ax.axvline(m["frequency_hz"], color="tab:green", linestyle="--", linewidth=0.8, zorder=1)
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("model order")
    orders = diagram.get("orders") or order.tolist()
    if len(orders):  # every order of the run, also those without a pole in the band; whole-number ticks
        from matplotlib.ticker import MaxNLocator

        ax.set_ylim(min(orders) - 0.5, max(orders) + 0.5)
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    criteria = diagram.get("criteria", {})
    if criteria:
        title += (f"\nstable: |Δf|/f ≤ {criteria['tol_frequency']:g}, |Δζ|/ζ ≤ {criteria['tol_damping']:g}, "
                  f"MAC ≥ {criteria['min_mac']:g}")
    if report.get("identified") is False:
        title += "; no mode selected"
    ax.set_title(title)
    indicator = report.get("indicator")
    if indicator:
        twin = ax.twinx()
        twin.semilogy(indicator["frequency_hz"], indicator["value"], color="0.45", linewidth=0.8, zorder=0)
        twin.set_ylabel("mode indicator Σ|H|² (normalised)")
        ax.set_zorder(twin.get_zorder() + 1)
        ax.patch.set_visible(False)
        ax.set_xlim(indicator["frequency_hz"][0], indicator["frequency_hz"][-1])
    ax.legend(loc="upper left", fontsize=8, framealpha=0.9)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, format="png")
    return path


def plot_damage_map(
    model: Model,
    scan: DamageScan,
    path: str | Path,
    *,
    true_elements: Sequence[int] = (),
    title: str = "Correlation of damage-induced damping deviations, eq. 3.45",
) -> Path:
    """Map of C over the structure (cf. thesis Figure 5.28) and C per candidate, as a PNG.

    Top: elements with stiffness as lines between their grids, coloured by C of the
    candidates containing them (grey: not a candidate); the located damage outlined in
    black, ``true_elements`` (when known) in red. A model in a plane (or on a line) is
    drawn in that plane, any other in 3-D. Bottom: C per candidate, labelled by its
    first element id. The figure lives on its own Agg canvas (no pyplot state).

    **Returns:** the path written.
    """
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    xyz = np.asarray(model.xyz, dtype=np.float64)
    rows, eids = model.segments()
    values = scan.element_values()
    c = np.array([values.get(int(e), np.nan) for e in eids])
    used, spread, dims, flat = _drawing_axes(xyz, rows)

    fig = figure(8.0, 7.0)
    line = flat and not np.all(spread[dims] > 1e-9 * max(float(spread.max()), 1e-300))
    grid = fig.add_gridspec(2, 1, height_ratios=(1, 2) if line else (3, 2))
    ax = fig.add_subplot(grid[0]) if flat else fig.add_subplot(grid[0], projection="3d")
    cmap = colormaps["viridis"]
    has = np.isfinite(c)
    norm = Normalize(0.0, max(float(np.nanmax(c)) if has.any() else 1.0, 1e-12))
    seg = xyz[rows][:, :, dims] if flat else xyz[rows]
    collection = LineCollection if flat else Line3DCollection

    def draw(mask, **style):
        if mask.any():
            lc = collection(seg[mask], **style)
            ax.add_collection(lc) if flat else ax.add_collection3d(lc)

    truth = np.isin(eids, np.asarray(true_elements, dtype=np.int64))
    located = np.isin(eids, np.asarray(scan.best_group, dtype=np.int64))
    draw(truth, colors="tab:red", linewidths=14.0, label="true damage")
    draw(located, colors="k", linewidths=9.0, label=f"located (C = {scan.correlation[scan.best]:.3f})")
    draw(np.ones(len(eids), bool), colors=[cmap(norm(v)) if ok else "0.8" for v, ok in zip(c, has)],
         linewidths=np.where(has, 5.0, 1.0))
    fig.colorbar(ScalarMappable(norm, cmap), ax=ax, label="C", shrink=0.8)
    names = "xyz"
    if flat:
        ax.set_xlabel(f"{names[dims[0]]} (m)")
        ax.set_ylabel(f"{names[dims[1]]} (m)")
        ax.autoscale()
        if not line:
            ax.set_aspect("equal", adjustable="datalim")
        ax.margins(0.05)
    else:
        lo, hi = used.min(axis=0), used.max(axis=0)
        ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), zlim=(lo[2], hi[2]), xlabel="x (m)", ylabel="y (m)",
               zlabel="z (m)")
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title, fontsize=10)

    _candidate_bars(fig.add_subplot(grid[1]), scan, true_elements)
    return _save(fig, path)


def _drawing_axes(xyz: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """The grids drawn, their spread per axis, the axes to draw and whether the model is flat (in a
    plane or on a line: drawn in 2-D over two axes) for :func:`plot_damage_map`."""
    used = xyz[np.unique(rows)] if len(rows) else xyz
    spread = np.ptp(used, axis=0)
    dims = np.flatnonzero(spread > 1e-9 * max(float(spread.max()), 1e-300))
    flat = len(dims) <= 2
    if flat:
        dims = np.array([0, 1]) if len(dims) == 0 else dims
        dims = np.array([dims[0], (dims[0] + 1) % 3]) if len(dims) == 1 else dims
    return used, spread, dims, flat


def _candidate_bars(bars, scan: DamageScan, true_elements: Sequence[int]) -> None:
    """C per candidate on ``bars``, labelled by its first element id: located black, true damage red."""
    k = np.arange(len(scan.groups))
    true_set = {int(e) for e in true_elements}
    colours = ["k" if i == scan.best else "tab:red" if set(g) & true_set else "tab:blue"
               for i, g in enumerate(scan.groups)]
    bars.bar(k, scan.correlation, color=colours)
    step = max(1, len(k) // 30)
    bars.set_xticks(k[::step], [str(g[0]) for g in scan.groups[::step]], fontsize=7)
    bars.set(xlabel="candidate (first element id)", ylabel="C", ylim=(0.0, 1.05))
    bars.set_title("black: located; red: true damage", fontsize=8)


def _save(fig, path: str | Path) -> Path:
    """Write ``fig`` as a PNG at ``path`` (creating its folder); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, format="png")
    return path


def boundary(polygons: Sequence[np.ndarray]) -> np.ndarray:
    """Outline of a union of polygons (each (k, 2)): the edges that belong to one polygon
    only, as segments (s, 2, 2)."""
    count: dict[tuple, int] = {}
    edges: dict[tuple, np.ndarray] = {}
    for poly in polygons:
        for a, b in zip(poly, np.roll(poly, -1, axis=0)):
            key = tuple(sorted((tuple(np.round(a, 12)), tuple(np.round(b, 12)))))
            count[key] = count.get(key, 0) + 1
            edges[key] = np.array([a, b])
    return np.array([edges[k] for k, n in count.items() if n == 1]).reshape(-1, 2, 2)



def plot_shell_damage_map(
    model: Model,
    scan: DamageScan,
    patches,
    path: str | Path,
    *,
    true_elements: Sequence[int] = (),
    title: str = "Correlation of damage-induced damping deviations, eq. 3.45",
) -> Path:
    """Surface map of C over the shell patches (cf. thesis Figure 5.28), as a PNG.

    **Arguments:** the model; the :class:`DamageScan` of a scan over ``patches`` (a
    :class:`identification.ShellPatches`, in the same order as ``scan.groups``); the PNG
    ``path``; ``true_elements`` (when known) outlined in red; a title.

    Top: the patches' region seen along its normal (the two axes of largest spread of the
    element centres), each element filled with the C of the patch centred on it
    (``at="elements"``; ``at="grids"``: the mean C of its corner grids) on a fixed 0–1
    colour scale; the located patch outlined in black with its centre marked, other shells (e.g. stringers seen
    edge-on) drawn grey. Bottom: per mode the measured deviations Δη_e (eq. 3.43) and the
    located candidate's Δη_a (eq. 3.44) scaled by its least-squares factor (C does not
    depend on the scale). The figure lives on its own Agg canvas (no pyplot state).

    **Returns:** the path written.
    """
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.colors import Normalize

    from ._patches import shell_centres

    if len(patches.groups) != len(scan.groups) or any(
            tuple(a) != tuple(b) for a, b in zip(patches.groups, scan.groups)):
        raise ValueError("patches and scan differ: pass the patches whose groups were the scan's candidates")
    ids, centres, corners = shell_centres(model)
    region = np.isin(ids, np.unique(np.concatenate([np.asarray(g, np.int64) for g in patches.groups])))
    spread = np.ptp(centres[region], axis=0)
    dims = np.sort(np.argsort(-spread)[:2])
    xyz = np.asarray(model.xyz, dtype=np.float64)
    polys = [xyz[c[c >= 0]][:, dims] for c in corners]
    values = _shell_values(model, scan, patches, ids, corners)

    fig = figure(8.0, 8.0)
    grid = fig.add_gridspec(2, 1, height_ratios=(3, 2))
    ax = fig.add_subplot(grid[0])
    cmap = colormaps["viridis"]
    norm = Normalize(0.0, 1.0)  # C is in [0, 1]: one scale for every map (a control looks dark)
    inside = region & np.isfinite(values)
    ax.add_collection(PolyCollection([polys[i] for i in np.flatnonzero(inside)],
                                     facecolors=[cmap(norm(v)) for v in values[inside]],
                                     edgecolors="0.85", linewidths=0.3))
    others = np.flatnonzero(~inside)
    if len(others):
        ax.add_collection(PolyCollection([polys[i] for i in others], facecolors="0.9", edgecolors="0.45",
                                         linewidths=1.5))
    by_id = dict(zip(ids.tolist(), polys))
    truth = [by_id[int(e)] for e in true_elements if int(e) in by_id]
    if truth:
        ax.add_collection(LineCollection(boundary(truth), colors="tab:red", linewidths=2.5, label="true damage"))
    best = scan.best
    ax.add_collection(LineCollection(boundary([by_id[e] for e in scan.best_group]), colors="k", linewidths=1.8,
                                     linestyles="--", label=f"located (C = {scan.correlation[best]:.3f})"))
    centre = np.asarray(patches.centres)[best][dims]
    ax.plot(*centre, marker="x", color="k", markersize=9, mew=2)
    fig.colorbar(ScalarMappable(norm, cmap), ax=ax, label="C of the patch centred here", shrink=0.8)
    names = "xyz"
    ax.set(xlabel=f"{names[dims[0]]} (m)", ylabel=f"{names[dims[1]]} (m)")
    ax.autoscale()
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.03)
    ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    ax.set_title(title, fontsize=10)

    _deviation_bars(fig.add_subplot(grid[1]), scan)
    return _save(fig, path)


def _shell_values(model: Model, scan: DamageScan, patches, ids: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """C per shell element: of the patch centred on it (``at="elements"``) or the mean over its corner
    grids (``at="grids"``); NaN where no patch gives one."""
    c_of = dict(zip(np.asarray(patches.anchors).tolist(), scan.correlation.tolist()))
    if patches.at == "elements":
        return np.array([c_of.get(int(e), np.nan) for e in ids])
    node_ids = np.asarray(model.node_ids)
    return np.array([np.nanmean([c_of.get(int(node_ids[n]), np.nan) for n in c[c >= 0]])
                     if any(int(node_ids[n]) in c_of for n in c[c >= 0]) else np.nan for c in corners])


def _deviation_bars(bars, scan: DamageScan) -> None:
    """Per mode on ``bars``: the measured Δη_e (eq. 3.43) and the located candidate's Δη_a (eq. 3.44)
    scaled by its least-squares factor."""
    e, a = scan.measured, scan.predicted[scan.best]
    scale = float(a @ e) / float(a @ a) if float(a @ a) > 0 else 0.0
    k = np.arange(len(e))
    bars.bar(k - 0.2, 100 * e, width=0.4, color="tab:red", label="measured Δη_e")
    bars.bar(k + 0.2, 100 * scale * a, width=0.4, color="k", label=f"located, Δη_a × {scale:.3g}")
    bars.axhline(0.0, color="0.5", linewidth=0.6)
    bars.set_xticks(k, [f"{f:.0f}" for f in scan.model_hz], rotation=60, fontsize=7)
    bars.set(xlabel="mode (model frequency, Hz)", ylabel="damping deviation (%)")
    bars.legend(fontsize=8)
