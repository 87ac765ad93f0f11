"""Correlation and updating plots: MAC matrix, frequency deviations, convergence.

Each function draws one figure on a private Agg canvas (``identification.figure``:
never pyplot, so no global backend or figure registry is touched), writes it as a PNG
and returns the path. Frequency deviations are percentages, Δf = 100 (f_model − f_test) / f_test (thesis eq. 4.1); NaN marks an unpaired mode.
The 3-D drawings of a model: :mod:`updating.report._structure_plots`.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from identification import figure as _figure


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
    stated σ), uniform damping (Rayleigh and a constant loss factor) fitted, and with the first-ranked region's loss
    factor (``damping``: the report of :func:`updating.diagnose_damping`). **Returns:** the path."""
    rows = damping["modes"]
    f = np.array([r["f_test_hz"] for r in rows])
    z = 100 * np.array([r["zeta_test"] for r in rows])
    fig = _figure(7.0, 4.0)
    ax = fig.add_subplot()
    ax.errorbar(f, z, yerr=z * damping["noise_pct"] / 100, fmt="o", color="black", capsize=3, label="measured (±σ)")
    ax.plot(f, 100 * np.array([r["zeta_baseline"] for r in rows]), "s--", color="tab:orange", label="uniform damping (Rayleigh + η0)")
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
