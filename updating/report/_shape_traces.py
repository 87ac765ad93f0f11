"""The page of :func:`updating.report.shape_view`: the plotly figure (test and model traces
in two 3-D scenes), the script that animates it (pair chooser, play/pause, phase slider,
one camera for both scenes, start from the page's address), the controls and the pair table.
"""

from __future__ import annotations

import html
import json

import numpy as np

_DATA_ID = "jaxfem-shape-data"
_COLOURS = {"test": "#d62728", "model": "#1f77b4", "test0": "#9a9a9a", "model0": "#c4c4c4"}

_CSS = """body{font-family:sans-serif;margin:.6em 1.2em;color:#222}h1{font-size:1.3em;margin:.2em 0}
.controls{display:flex;flex-wrap:wrap;gap:1em;align-items:center;margin:.4em 0}.controls select{max-width:46em}
.note{color:#555;font-size:.85em;margin:.3em 0}table{border-collapse:collapse;font-size:.85em;margin:.6em 0}
th,td{border:1px solid #ccc;padding:.2em .6em}th{background:#f0f0f0}td{text-align:right}"""

# Runs after Plotly.newPlot (plotly's post_script; {plot_id} is replaced by the div's id).
_SCRIPT = r"""
var gd = document.getElementById('{plot_id}');
var D = JSON.parse(document.getElementById('DATA_ID').textContent);
var P = D.phases, phase = Math.round(P / 4), pair = 0, playing = true, timer = null, syncing = false;
function lines(part, u, s) {
  var xyz = part.xyz, seg = part.seg, n = seg.length / 2, out = [[], [], []];
  for (var k = 0; k < n; k++) {
    for (var e = 0; e < 2; e++) {
      var g = 3 * seg[2 * k + e];
      for (var c = 0; c < 3; c++) out[c].push(xyz[g + c] + (u ? s * u[g + c] : 0));
    }
    for (var c2 = 0; c2 < 3; c2++) out[c2].push(null);
  }
  return out;
}
function labels(part) {
  var out = [];
  if (!part.ids) return null;
  for (var k = 0; k < part.seg.length / 2; k++) {
    out.push('node ' + part.ids[part.seg[2 * k]], 'node ' + part.ids[part.seg[2 * k + 1]], '');
  }
  return out;
}
function draw() {
  var s = Math.sin(2 * Math.PI * phase / P), p = D.pairs[pair];
  var t = lines(D.test, p ? p.test : null, s), m = lines(D.model, p ? p.model : null, s);
  document.getElementById('jaxfem-phase').value = phase;
  return Plotly.restyle(gd, {x: [t[0], m[0]], y: [t[1], m[1]], z: [t[2], m[2]]}, [1, 3]);
}
function tick() {
  timer = null;
  if (!playing) return;
  phase = (phase + 1) % P;
  draw().then(function () { if (playing && timer === null) timer = setTimeout(tick, D.frame_ms); });
}
function play(on) {
  playing = on;
  document.getElementById('jaxfem-play').textContent = on ? 'pause' : 'play';
  if (on && timer === null) timer = setTimeout(tick, D.frame_ms);
}
function choose(k) {
  pair = k;
  document.getElementById('jaxfem-pair').value = String(k);
  var p = D.pairs[k];
  return Plotly.relayout(gd, {'title.text': p ? p.title : D.title + ': no paired modes'}).then(draw);
}
function view(how) {
  var overlay = how === 'overlay';
  document.getElementById('jaxfem-view').value = how;
  return Plotly.restyle(gd, {scene: overlay ? 'scene' : 'scene2'}, [2, 3]).then(function () {
    return Plotly.relayout(gd, {'scene.domain.x': overlay ? [0, 1] : [0, 0.5],
                                'annotations[0].text': overlay ? 'test (red) and model (blue)' : 'test',
                                'annotations[0].x': overlay ? 0.5 : 0.25, 'annotations[1].visible': !overlay});
  });
}
var t0 = lines(D.test, null, 0), m0 = lines(D.model, null, 0);
var tl = labels(D.test), ml = labels(D.model);
Plotly.restyle(gd, {x: [t0[0], t0[0], m0[0], m0[0]], y: [t0[1], t0[1], m0[1], m0[1]],
                    z: [t0[2], t0[2], m0[2], m0[2]], text: [tl, tl, ml, ml]}, [0, 1, 2, 3]).then(function () {
  var opts = {};
  location.hash.replace(/^#/, '').split('&').forEach(function (kv) {
    var i = kv.indexOf('='); if (i > 0) opts[kv.slice(0, i)] = decodeURIComponent(kv.slice(i + 1));
  });
  if (opts.phase !== undefined) { phase = ((parseInt(opts.phase, 10) % P) + P) % P; playing = false; }
  var k = Math.min(Math.max(parseInt(opts.pair || '1', 10) - 1, 0), Math.max(D.pairs.length - 1, 0));
  return view(opts.view === 'overlay' ? 'overlay' : 'side').then(function () { return choose(k); });
}).then(function () {
  play(playing);
  document.getElementById('jaxfem-pair').addEventListener('change', function (e) {
    choose(parseInt(e.target.value, 10));
  });
  document.getElementById('jaxfem-play').addEventListener('click', function () { play(!playing); });
  document.getElementById('jaxfem-phase').addEventListener('input', function (e) {
    play(false); phase = parseInt(e.target.value, 10); draw();
  });
  document.getElementById('jaxfem-view').addEventListener('change', function (e) { view(e.target.value); });
  gd.on('plotly_relayout', function (ev) {  // one camera for both scenes
    if (syncing) return;
    var cam = ev['scene.camera'] ? ['scene2.camera', ev['scene.camera']]
            : ev['scene2.camera'] ? ['scene.camera', ev['scene2.camera']] : null;
    if (!cam) return;
    syncing = true;
    var upd = {}; upd[cam[0]] = cam[1];
    Plotly.relayout(gd, upd).then(function () { syncing = false; }, function () { syncing = false; });
  });
});
""".replace("DATA_ID", _DATA_ID)


def _page(title: str, note: str, data: dict, rows: list[tuple]) -> str:
    """The HTML: controls, the plotly figure (JavaScript embedded) and the pair table."""
    import plotly.graph_objects as go
    import plotly.io as pio

    c = _COLOURS
    axis = [{"title": {"text": f"{a} [m]"}, "range": r, "autorange": False} for a, r in zip("xyz", data["range"])]
    sides = np.array([r[1] - r[0] for r in data["range"]])
    aspect = dict(zip("xyz", (sides / sides.max()).tolist()))
    scene = {"xaxis": axis[0], "yaxis": axis[1], "zaxis": axis[2], "aspectmode": "manual", "aspectratio": aspect}
    model_mode = "lines+markers" if data["model"]["markers"] else "lines"
    hover = "%{text}<extra></extra>"
    traces = [
        go.Scatter3d(name="test, undeformed", mode="lines+markers", scene="scene",
                     line={"color": c["test0"], "width": 2}, marker={"color": c["test0"], "size": 2},
                     hovertemplate=hover),
        go.Scatter3d(name="test", mode="lines+markers", scene="scene", line={"color": c["test"], "width": 5},
                     marker={"color": c["test"], "size": 4}, hovertemplate=hover),
        go.Scatter3d(name="model, undeformed", mode="lines", scene="scene2", line={"color": c["model0"], "width": 1},
                     hoverinfo="skip"),
        go.Scatter3d(name="model", mode=model_mode, scene="scene2", line={"color": c["model"], "width": 3},
                     marker={"color": c["model"], "size": 2},
                     **({"hovertemplate": hover} if data["model"]["markers"] else {"hoverinfo": "skip"})),
    ]
    label = {"xref": "paper", "yref": "paper", "y": 1.0, "showarrow": False, "font": {"size": 14}}
    layout = go.Layout(
        title={"text": data["title"]}, uirevision="keep", showlegend=True,
        legend={"orientation": "h", "y": -0.02}, margin={"l": 0, "r": 0, "t": 50, "b": 30},
        scene={**scene, "domain": {"x": [0.0, 0.5], "y": [0.0, 0.95]}},
        scene2={**scene, "domain": {"x": [0.5, 1.0], "y": [0.0, 0.95]}},
        annotations=[{**label, "x": 0.25, "text": "test"}, {**label, "x": 0.75, "text": "model"}],
    )
    figure = pio.to_html(go.Figure(traces, layout), include_plotlyjs=True, full_html=False, div_id="jaxfem-shapes",
                         post_script=_SCRIPT, default_height="76vh", config={"displaylogo": False, "responsive": True})
    options = "".join(f'<option value="{k}">{html.escape(p["label"])}</option>' for k, p in enumerate(data["pairs"]))
    head = "".join(f"<th>{h}</th>" for h in ("pair", "test", "model", "f_test [Hz]", "f_model [Hz]", "Δf [%]", "MAC"))
    body = "".join(f"<tr><td>{k}</td><td>{j}</td><td>{i}</td><td>{ft:.4f}</td><td>{fm:.4f}</td><td>{d:+.2f}</td>"
                   f"<td>{m:.3f}</td></tr>" for k, j, i, ft, fm, d, m in rows)
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    return (
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>\n"
        f"<h1>{html.escape(title)}</h1>\n<div class=\"controls\">"
        f"<label>pair <select id=\"jaxfem-pair\">{options}</select></label>"
        "<button id=\"jaxfem-play\" type=\"button\">pause</button>"
        f"<label>phase <input id=\"jaxfem-phase\" type=\"range\" min=\"0\" max=\"{data['phases'] - 1}\" value=\"0\"></label>"
        "<label>view <select id=\"jaxfem-view\"><option value=\"side\">side by side</option>"
        "<option value=\"overlay\">overlaid</option></select></label></div>\n"
        f"<p class=\"note\">{html.escape(note)}</p>\n"
        f"<script type=\"application/json\" id=\"{_DATA_ID}\">{payload}</script>\n{figure}\n"
        f"<table><tr>{head}</tr>{body}</table>\n</body></html>\n"
    )
