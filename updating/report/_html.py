"""One self-contained HTML page for a diagnosis: tables, verdict and embedded figures.

No external resource is referenced: the CSS is inline and every figure is a base64
PNG. All text from the diagnosis is HTML-escaped.
"""

from __future__ import annotations

import base64
import datetime
import html
import io
import math
import sys
from pathlib import Path

_CSS = """body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}
h1{margin-bottom:.2em}h2{border-bottom:2px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
.meta{color:#666}.verdict{background:#fff6d5;border-left:6px solid #e0a800;padding:.8em 1em;margin:1em 0}
table{border-collapse:collapse;margin:.6em 0;font-size:.9em}th,td{border:1px solid #ccc;padding:.25em .6em}
th{background:#f0f0f0}td.n{text-align:right;font-variant-numeric:tabular-nums}
img{max-width:100%;display:block;margin:.8em 0}"""

_UNITS = {"_hz": " [Hz]", "_pct": " [%]"}
_HEADERS = {"mac": "MAC [–]", "comac": "COMAC [–]", "freq_dev_pct": "Δf [%]",
            "rms_freq_dev_pct": "RMS Δf [%]", "mean_mac": "mean MAC [–]",
            "heldout_rms_freq_dev_pct_before": "held-out RMS Δf before [%]",
            "heldout_rms_freq_dev_pct_after": "held-out RMS Δf after [%]",
            "heldout_rms_freq_dev_pct": "held-out RMS Δf [%]", "heldout_mean_mac": "held-out mean MAC [–]",
            "chi2_per_row": "χ² per residual row (all, at the stated noise) [–]",
            "chi2_per_row_freq": "χ² per row, frequencies [–]", "chi2_per_row_shape": "χ² per row, shapes [–]",
            "heldout_rms_zeta_dev_pct": "held-out RMS ζ deviation [%]", "posterior": "posterior probability [–]",
            "log_evidence": "ln Bayes factor vs baseline [–]", "log_occam": "ln Occam factor [–]",
            "f_test_hz": "f test [Hz]", "f_model_hz": "f model [Hz]", "zeta_test": "ζ test [–]",
            "zeta_baseline": "ζ uniform damping [–]", "zeta_best": "ζ with the best region [–]",
            "rms_freq_dev_pct_active_before": "RMS Δf active before [%]",
            "rms_freq_dev_pct_active_after": "RMS Δf active after [%]",
            "rms_freq_dev_pct_passive_before": "RMS Δf passive (held out) before [%]",
            "rms_freq_dev_pct_passive_after": "RMS Δf passive (held out) after [%]",
            "mean_mac_passive_before": "mean MAC passive before [–]", "mean_mac_passive_after": "mean MAC passive after [–]"}
_MODE_COLUMNS = ["test", "model", "f_test_hz", "f_model_hz", "freq_dev_pct", "mac"]


def _header(key: str) -> str:
    if key in _HEADERS:
        return _HEADERS[key]
    for suffix, unit in _UNITS.items():
        if key.endswith(suffix):
            return key[: -len(suffix)].replace("_", " ") + unit
    return key.replace("_", " ")


def _fmt(value) -> str:
    """Text of one cell: floats to 4 significant digits, lists joined, dicts as k=v."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, dict):
        return ", ".join(f"{k}={_fmt(v)}" for k, v in value.items())
    if isinstance(value, (list, tuple)):
        return ", ".join(_fmt(v) for v in value)
    if hasattr(value, "item") and getattr(value, "ndim", 1) == 0:  # NumPy / JAX scalar
        value = value.item()
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _table(rows, columns=None) -> str:
    """An HTML table of dicts; ``columns``: keys to show (None: every key, first-seen order)."""
    rows = list(rows)
    if columns is None:
        columns = list(dict.fromkeys(k for r in rows for k in r))
    head = "".join(f"<th>{html.escape(_header(c))}</th>" for c in columns)
    body = []
    for r in rows:
        cells = []
        for c in columns:
            v = r.get(c)
            cls = ' class="n"' if isinstance(v, (int, float)) and not isinstance(v, bool) else ""
            cells.append(f"<td{cls}>{html.escape(_fmt(v))}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def _scalars(d: dict) -> str:
    """Two-column table of the scalar entries of ``d``."""
    rows = [{"quantity": _header(k), "value": v} for k, v in d.items()
            if isinstance(v, (int, float, str, bool)) or (hasattr(v, "ndim") and v.ndim == 0)]
    return _table(rows, ["quantity", "value"]) if rows else ""


def _png(fig) -> str:
    """``<img>`` with the figure as base64 PNG; a pyplot-managed figure is then closed."""
    if isinstance(fig, (str, Path)):
        data = Path(fig).read_bytes()
    else:
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
        data = buffer.getvalue()
        if "matplotlib.pyplot" in sys.modules:
            sys.modules["matplotlib.pyplot"].close(fig)
    return f'<img src="data:image/png;base64,{base64.b64encode(data).decode("ascii")}" alt="">'


def write_report(diagnosis: dict, figures: dict, path, links: dict | None = None) -> Path:
    """Write the diagnosis as one self-contained HTML file.

    **Arguments:** ``diagnosis``: dict with any of ``model``, ``test``, ``verdict``,
    ``paired_modes``, ``unpaired_test``, ``unpaired_model``, ``baseline``,
    ``sensors``, ``localisation`` (``groups``, ``nodes``), ``effects``,
    ``outcome``, ``damping``, ``after``; ``figures``: name → matplotlib figure (or PNG
    path); names ``mac``, ``freq_dev``, ``localisation_surface`` (the indicator on the
    shells), ``localisation_groups``, ``localisation_nodes``, ``effects``, ``damping``,
    ``freq_dev_after``, ``mac_after``, ``convergence`` go to their section, others under
    "More plots". Sections without data are left out. ``links``: link text → file name
    of pages written next to the report (the 3-D mode-shape views), listed after the
    comparison.
    **Returns:** the path written.
    """
    d, figs, out = diagnosis, dict(figures), []

    def figs_of(*names):
        return [_png(figs.pop(n)) for n in names if n in figs]

    def section(title, parts):
        parts = [p for p in parts if p]
        if parts:
            out.append(f"<h2>{html.escape(title)}</h2>" + "\n".join(parts))

    out.extend(_heading(d))
    section("Comparison", [*_comparison(d), *figs_of("mac", "freq_dev")])
    section("Mode shapes in 3-D", [_shape_links(links)])
    section("Where it fails", [*_failures(d),
                               *figs_of("localisation_surface", "localisation_groups", "localisation_nodes")])
    section("Candidate effects", [*_candidates(d), *figs_of("effects")])
    section("Damping: a local loss factor", [*_damping(d), *figs_of("damping")])
    after = d.get("after") or {}
    section("After adding the effect", [
        _table(after["paired_modes"], _MODE_COLUMNS) if after.get("paired_modes") else "",
        _scalars(after), *figs_of("freq_dev_after", "mac_after", "convergence")])
    section("More plots", [f"<h3>{html.escape(name)}</h3>" + _png(fig) for name, fig in figs.items()])

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>jaxfem diagnosis</title>"
                    f"<style>{_CSS}</style></head><body>\n" + "\n".join(out) + "\n</body></html>\n",
                    encoding="utf-8")
    return path


def _heading(d: dict) -> list[str]:
    """The title with the model, test and date, and the verdict."""
    meta = [f"{label}: {Path(str(d[key])).name}" for key, label in (("model", "model"), ("test", "test"))
            if d.get(key)]
    meta.append(datetime.datetime.now().strftime("%Y-%m-%d %H:%M"))
    out = ["<h1>jaxfem diagnosis</h1>" + f'<p class="meta">{html.escape(" · ".join(meta))}</p>']
    if d.get("verdict"):
        out.append(f'<div class="verdict">{html.escape(str(d["verdict"]))}</div>')
    return out


def _id_list(d: dict, key: str, text: str) -> str:
    """A paragraph listing ``d[key]`` ('' without)."""
    return f"<p>{html.escape(text)}: {html.escape(_fmt(list(d[key])))}</p>" if d.get(key) else ""


def _comparison(d: dict) -> list[str]:
    """Paired modes, unpaired ones and the baseline."""
    return [
        _table(d["paired_modes"], _MODE_COLUMNS) if d.get("paired_modes") else "",
        _id_list(d, "unpaired_test", "Unpaired test modes"), _id_list(d, "unpaired_model", "Unpaired model modes"),
        "<h3>Baseline</h3>" + _scalars(d["baseline"]) if d.get("baseline") else ""]


def _shape_links(links: dict | None) -> str:
    """The list of links to the 3-D mode-shape views ('' without)."""
    return ("<ul>" + "".join(f'<li><a href="{html.escape(href)}">{html.escape(text)}</a></li>'
                             for text, href in links.items()) + "</ul><p>Test and model shapes of each pair animated "
            "side by side (interactive, one self-contained page each).</p>" if links else "")


def _failures(d: dict) -> list[str]:
    """The sensors of lowest COMAC and the first property groups and nodes of the localisation."""
    sensors = sorted(d.get("sensors") or [], key=lambda s: _num(s.get("comac")))[:10]
    loc = d.get("localisation") or {}
    return [
        "<h3>Sensors with the lowest COMAC</h3>" + _table(sensors, ["label", "comac"]) if sensors else "",
        "<h3>Property groups</h3>" + _table(loc["groups"][:10]) if loc.get("groups") else "",
        "<h3>Nodes</h3>" + _table(loc["nodes"][:10]) if loc.get("nodes") else ""]


def _candidates(d: dict) -> list[str]:
    """The table of candidate effects, its legend and the outcome."""
    effects = [{**e, "notes": "; ".join(map(str, e.get("plausibility") or []))} for e in d.get("effects") or []]
    outcome = {"effect": "<p>The declared effects pass every test (decisive over the baseline, χ², held-out "
                         "frequencies and shapes lowered beyond noise, no held-out or passive mode worse); what "
                         "remains is noise.</p>",
               "partial": "<p><b>Partially explained</b>: modes remain off beyond noise and no further candidate "
                          "passes.</p>",
               "none_needed": "<p><b>No extra effect is warranted</b>: the baseline explains the data to the "
                              "stated noise.</p>",
               "unconfirmed": "<p><b>A candidate fits to noise but is not confirmed</b> by the held-out modes.</p>",
               "cannot_localise": "<p><b>The sensors cannot localise the effect</b>: equally good places.</p>",
               "unexplained": "<p><b>No effect in the library explains the data.</b></p>"}.get(d.get("outcome"), "")
    declared = [{**e, "values": e.get("parameters")} for e in d.get("declared") or []]
    if declared:
        outcome += "<h3>Declared effects, in order</h3>" + _table(declared, [
            "round", "kind", "where", "values", "heldout_rms_freq_dev_pct_before", "heldout_rms_freq_dev_pct_after",
            "rms_freq_dev_pct_passive_before", "rms_freq_dev_pct_passive_after"])
    if d.get("withdrawn"):
        w = d["withdrawn"]
        outcome += f"<p>Withdrawn: {html.escape(str(w.get('kind')))} at {html.escape(str(w.get('where')))}: {html.escape(str(w.get('reason')))}</p>"
    return [
        _table(effects, ["rank", "kind", "where", "parameters", "posterior", "log_evidence", "log_occam",
                         "chi2_per_row", "heldout_rms_freq_dev_pct_before", "heldout_rms_freq_dev_pct_after",
                         "heldout_mean_mac_after", "score", "delta_aic", "warranted", "notes"]) if effects else "",
        "<p>posterior: probability among the fitted candidates and the baseline (Laplace evidence, equal "
        "prior odds); log_evidence: ln Bayes factor against the baseline; log_occam: the price of the "
        "parameters' freedom; score: % of the cross-validated residual removed; delta_aic: ΔAIC.</p>"
        if effects else "",
        outcome]


def _damping(d: dict) -> list[str]:
    """The damping verdict, the per-mode and per-region tables and their legend."""
    damping = d.get("damping") or {}
    return [
        f'<div class="verdict">{html.escape(str(damping["verdict"]))}</div>' if damping else "",
        "<h3>Per mode</h3>" + _table(damping["modes"], ["test_mode", "f_test_hz", "zeta_test", "zeta_baseline",
                                                      "zeta_best", "model_mode"]) if damping else "",
        "<h3>Regions</h3>" + _table(damping["effects"], ["rank", "where", "eta", "eta_sd", "posterior",
                                                         "log_evidence", "chi2_per_row",
                                                         "heldout_rms_zeta_dev_pct_before",
                                                         "heldout_rms_zeta_dev_pct_after", "warranted"])
        if damping.get("effects") else "",
        "<p>ζ: viscous damping ratio; zeta_baseline: uniform damping (Rayleigh, eq. 3.40, and a constant loss factor η0) fitted; zeta_best: with "
        "the first-ranked region's loss factor η (modal strain energy); held-out: each mode predicted by a fit "
        "on the other folds, % of the measured ratio.</p>" if damping else ""]


def _num(value) -> float:
    """Sort key: a number, missing values last."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        return math.inf
    return math.inf if math.isnan(v) else v
