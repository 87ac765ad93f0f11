"""Plots of a Monte-Carlo study in the style of thesis Figs. 4.24–4.32.

Per error category (Table 4.7), against the error magnitude: the correction-factor
deviations Δα (eq. 4.4, Figs. 4.24–4.26), the frequency deviations Δf_n (eq. 4.5,
Figs. 4.27–4.29) and the MAC deviations ΔMAC_n (eq. 4.6, Figs. 4.30–4.32), all in %.
The statistics are those of :meth:`MonteCarloResult.statistics` (failed samples left
out); the failures of every cell are written under each figure. Figures are drawn on
private Agg canvases (:mod:`updating.report._plots`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..studies import CATEGORIES, MonteCarloResult
from ._plots import _figure, _save

# x-axis label per category: what the magnitude is a percentage of (Table 4.7).
_MAGNITUDE = {"relative": "relative error σ [% of each deflection]",
              "absolute": "absolute error a [% of the mode's largest deflection]",
              "frequency": "frequency error σ [% of each frequency]"}
_QUANTITY = {"delta_f": ("freq", "Δf", "frequency deviations Δf (eq. 4.5)"),
             "delta_mac": ("mac", "ΔMAC", "MAC deviations ΔMAC (eq. 4.6)")}


def plot_montecarlo(result: MonteCarloResult, directory: str | Path, name: str | None = None) -> list[Path]:
    """Write ``montecarlo_<category>_{alpha,freq,mac}.png`` for every error category of
    the study: Δα per parameter (mean ± std, RMS dashed; one line per number of modes);
    Δf and ΔMAC as the RMS over modes and samples per number of modes, and mean ± std
    per mode for each number of modes.

    **Arguments:** the result; the output directory; ``name`` of the study in the
    titles (default: the model file's name). **Returns:** the paths written.
    """
    study = result.study
    name = name or study.model.name
    stats = {(s["n_modes"], s["category"], s["magnitude"]): s for s in result.statistics()}
    directory = Path(directory)
    written = []
    present = {k for k, _ in study.cells}
    for category in [c for c in CATEGORIES if c in present]:
        mags = sorted(m for k, m in study.cells if k == category)
        cells = {n: [stats[n, category, m] for m in mags] for n in study.n_modes}
        title = f"{category} errors, {name}"
        written.append(_alpha(cells, mags, result.names, category, title,
                              directory / f"montecarlo_{category}_alpha.png"))
        for key, (suffix, symbol, what) in _QUANTITY.items():
            written.append(_modal(cells, mags, key, symbol, category, f"{what}: {title}",
                                  directory / f"montecarlo_{category}_{suffix}.png"))
    return written


def _grid(n_panels: int, width: float = 4.2, height: float = 3.3):
    cols = min(3, n_panels)
    rows = -(-n_panels // cols)
    fig = _figure(width * cols, height * rows + 0.6)
    return fig, [fig.add_subplot(rows, cols, i + 1) for i in range(n_panels)]


def _footer(fig, cells: dict, mags: list[float]) -> None:
    """The failed (left-out) samples and the fallbacks of every cell, under the figure."""
    first = next(iter(cells.values()))[0]
    failed = "; ".join(f"n = {n}: " + ", ".join(str(sum(c["failed"].values())) for c in row)
                       for n, row in cells.items())
    fallbacks = sum(c["fallback"] for row in cells.values() for c in row)
    kinds = sorted({k for row in cells.values() for c in row for k, v in c["failed"].items() if v})
    fig.supxlabel(f"failed samples (left out) of {first['samples']} per cell at "
                  + ", ".join(f"{100 * m:g}" for m in mags) + f" %: {failed}"
                  + (f" ({', '.join(kinds)})" if kinds else "")
                  + f"; redone with full eigensolves: {fallbacks}", fontsize=8)


def _alpha(cells: dict, mags: list[float], names: list[str], category: str, title: str, path: Path) -> Path:
    """Δα [%] per parameter against the magnitude (Figs. 4.24–4.26)."""
    from matplotlib.lines import Line2D

    fig, axes = _grid(len(names))
    x = 100 * np.asarray(mags)
    for j, (ax, pname) in enumerate(zip(axes, names)):
        ratio = {n: row[0]["delta_alpha_is_ratio"][pname] for n, row in cells.items()}
        for k, (n, row) in enumerate(cells.items()):
            colour = f"C{k}"
            s = {q: 100 * np.array([c["delta_alpha"][pname][q] for c in row], dtype=np.float64)
                 for q in ("mean", "std", "rms")}
            label = f"n = {n} modes" + ("" if ratio[n] else " (difference)")
            ax.errorbar(x, s["mean"], yerr=s["std"], marker="x", capsize=3, color=colour, label=label)
            ax.plot(x, s["rms"], ls="--", color=colour)
            for xi, yi, c in zip(x, s["mean"], row):
                bad = sum(c["failed"].values())
                if bad:
                    ax.annotate(f"{bad} failed", (xi, yi if np.isfinite(yi) else 0.0), fontsize=7, color=colour,
                                textcoords="offset points", xytext=(3, -10))
        kind = ("α(δ)/α(0) − 1" if all(ratio.values())
                else "α(δ) − α(0)" if not any(ratio.values()) else "ratio or difference, see legend")
        ax.set_title(f"{pname}: {kind}", fontsize=9)
        ax.set_xlabel(_MAGNITUDE[category])
        ax.set_ylabel("Δα [%]")
        ax.axhline(0.0, color="grey", lw=0.5)
        if j == 0:
            handles, _ = ax.get_legend_handles_labels()
            handles += [Line2D([], [], color="black", marker="x", label="mean ± std"),
                        Line2D([], [], color="black", ls="--", label="RMS")]
            ax.legend(handles=handles, fontsize=7)
    fig.suptitle(f"Correction-factor deviations Δα (eq. 4.4): {title}")
    _footer(fig, cells, mags)
    return _save(fig, path)


def _modal(cells: dict, mags: list[float], key: str, symbol: str, category: str, title: str, path: Path) -> Path:
    """Δf or ΔMAC [%]: the RMS over modes and samples against the magnitude, one line
    per number of modes; then per number of modes, mean ± std per mode (Figs. 4.27–4.32)."""
    fig, axes = _grid(1 + len(cells))
    x = 100 * np.asarray(mags)
    overall = axes[0]
    for k, (n, row) in enumerate(cells.items()):
        rms = np.array([np.sqrt(np.mean(np.square(c[key]["rms"]))) for c in row], dtype=np.float64)
        overall.plot(x, 100 * rms, marker="x", color=f"C{k}", label=f"n = {n} modes")
    overall.set_title(f"RMS of {symbol} over modes and samples", fontsize=9)
    overall.set_xlabel(_MAGNITUDE[category])
    overall.set_ylabel(f"{symbol} [%]")
    overall.legend(fontsize=7)
    colours = _colours(len(mags))
    for ax, (n, row) in zip(axes[1:], cells.items()):
        modes = np.arange(1, n + 1)
        width = 0.6 / len(mags)
        for i, (m, c) in enumerate(zip(mags, row)):
            offset = (i - (len(mags) - 1) / 2) * width
            ax.errorbar(modes + offset, 100 * np.asarray(c[key]["mean"], dtype=np.float64),
                        yerr=100 * np.asarray(c[key]["std"], dtype=np.float64), ls="none", marker="x",
                        capsize=2, color=colours[i], label=f"δ = {100 * m:g} %")
        ax.axhline(0.0, color="grey", lw=0.5)
        ax.set_xticks(modes)
        ax.set_title(f"n = {n} modes: mean ± std per mode", fontsize=9)
        ax.set_xlabel("mode")
        ax.set_ylabel(f"{symbol} [%]")
        ax.legend(fontsize=7)
    fig.suptitle(title)
    _footer(fig, cells, mags)
    return _save(fig, path)


def _colours(k: int) -> list:
    from matplotlib import colormaps

    return [colormaps["viridis"](v) for v in np.linspace(0.0, 0.85, k)]
