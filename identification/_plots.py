"""Identification plots: the stabilisation diagram of :func:`identification._fitting.identify`.

Drawn on a private Agg canvas (``matplotlib.figure.Figure``, never pyplot: no global
backend or figure registry is touched) and written as PNG. Matplotlib is imported inside
the function: it is the optional ``plot`` extra (``pip install 'jaxfem[plot]'``).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

_DPI = 120

# (label, marker, colour, filled) per stability class, drawn in this order
_CLASSES = (
    ("new / unstable", "o", "0.65", False),
    ("stable f", ".", "tab:blue", True),
    ("stable f, ζ", "x", "tab:orange", True),
    ("stable f, MAC", "+", "tab:purple", True),
    ("stable f, ζ, MAC", "s", "tab:green", False),
)


def _figure(width: float, height: float):
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError as err:
        raise ImportError("plots need matplotlib: install jaxfem[plot] (pip install 'jaxfem[plot]')") from err
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
    is drawn in grey on a log scale (right axis).

    **Returns:** the path written. Raises ``ImportError`` naming ``jaxfem[plot]`` without
    matplotlib, ``ValueError`` when the report lacks the diagram.
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
    fig = _figure(9.0, 5.5)
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
