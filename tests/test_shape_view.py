"""The interactive 3-D mode-shape view (updating.report._shape_view): UFF trace lines, the grid and
test-node translations, a self-contained HTML file, ``correlate --report``, and the page in a
real headless browser (Chromium): no console error, the structure on screen."""

import json
import os
import re
import shutil
import subprocess
from types import SimpleNamespace

import numpy as np
import pytest
import pyuff
from typer.testing import CliRunner

import jaxfem
from benchmarks.frames import frame_bdf
from identification import ModalData, Sensors, observation_matrix, read_trace_lines, read_uff, write_uff
from jaxfem.io import read_bdf
from updating import Effect
from updating.report import _shape_view as sv
from updating.cli import app

SENSOR_GRIDS = list(range(5, 21))  # floors 1..4 of the 2 × 2 × 4 frame; grids 1..4 (base) unmeasured
RED, BLUE = np.array([214, 39, 40]) / 255, np.array([31, 119, 180]) / 255  # test and model colours


def _add_trace_lines(path, lines):
    """Append one dataset 82 drawing ``lines`` (node-id pairs, 0 between them: move)."""
    nodes = np.array([n for a, b in lines for n in (a, b, 0)][:-1])
    pyuff.UFF(str(path)).write_sets(pyuff.prepare_82(trace_num=1, n_nodes=len(nodes), color=8, id="frame",
                                                     nodes=nodes, return_full_dict=True), mode="add")


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """A frame, its 'test' (the frame with 25 kg more at grid 14) in a universal file with
    nodes, 8 modes at 16 grids × (X, Y) and trace lines along the members."""
    d = tmp_path_factory.mktemp("shape_view")
    bdf = d / "frame.bdf"
    bdf.write_text(frame_bdf(2, 2, 4, n_groups=8))
    model = jaxfem.build_model(read_bdf(bdf))
    truth = Effect("added_mass", nodes=(14,), values={"m": 25.0}).apply(model)
    sensors = Sensors.from_components(np.repeat(SENSOR_GRIDS, 2), np.tile([1, 2], len(SENSOR_GRIDS)))
    lam, phi = jaxfem.modes(truth, 8)
    C, _ = observation_matrix(truth, sensors)
    test = ModalData(np.asarray(jaxfem.frequencies_hz(lam)), np.asarray(C @ phi), sensors)
    ids = model.node_ids.tolist()
    nodes = {g: model.xyz[ids.index(g)] for g in range(1, 21)}
    lines = [(int(model.node_ids[a]), int(model.node_ids[b])) for a, b in model.segments()[0]
             if model.node_ids[a] in nodes and model.node_ids[b] in nodes]
    uff = d / "test.uff"
    write_uff(uff, nodes=nodes, modes=test)
    _add_trace_lines(uff, lines)
    return SimpleNamespace(dir=d, bdf=bdf, uff=uff, model=model, test=test, lines=lines, nodes=nodes)


def test_read_trace_lines(tmp_path, case):
    uff = tmp_path / "lines.uff"
    _add_trace_lines(uff, [(1, 5), (5, 9), (9, 5), (2, 2), (6, 2)])
    assert read_trace_lines(uff) == [(1, 5), (5, 9), (2, 6)]  # once each, 0 = move, no self-line
    assert sorted(read_trace_lines(case.uff)) == sorted((min(a, b), max(a, b)) for a, b in case.lines)
    plain = tmp_path / "plain.uff"
    write_uff(plain, nodes=case.nodes)
    assert read_trace_lines(plain) == []


def test_read_trace_lines_refuses_a_file_that_is_not_whole(tmp_path, case):
    """The lines go through the same whole-file check as the modes: a -1 missing between
    two datasets is named by its line, not merged by pyuff into one dataset."""
    text = case.uff.read_text().split("\n")
    first = next(i for i, line in enumerate(text) if i > 0 and line.rstrip() == "    -1")  # closes dataset 1
    broken = tmp_path / "broken.uff"
    broken.write_text("\n".join(text[:first] + text[first + 1:]))
    with pytest.raises(ValueError, match=rf"broken.uff: line {first + 2} .* lies outside any dataset"):
        read_trace_lines(broken)


def test_test_translations_from_skew_and_partial_sensors():
    u1, u2 = np.array([0.3, -0.2, 0.9]), np.array([1.0, 2.0, -0.5])
    d = np.array([[1.0, 1.0, 0.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]]) / np.sqrt(2)  # skew, independent
    sensors = Sensors.from_vectors([7, 7, 7, 8, 8, 9], np.vstack([d, [[0, 0, 1.0], [0, 1.0, 0]], [[0, 0, 1.0]]]),
                                   [False] * 5 + [True])
    shapes = np.stack([np.concatenate([d @ u, [u[2], u[1]], [5.0]]) for u in (u1, u2)], axis=1)
    got = sv.measured_translations(sensors, shapes)
    assert set(got) == {7, 8}  # a node with a rotation only is not drawn
    np.testing.assert_allclose(got[7], np.stack([u1, u2], axis=1), atol=1e-12)  # three skew directions: all of u
    np.testing.assert_allclose(got[8], [[0, 0], [u1[1], u2[1]], [u1[2], u2[2]]], atol=1e-12)  # measured parts only
    with pytest.raises(ValueError, match="complex"):
        sv.measured_translations(sensors, shapes * 1j)


def test_grid_translations_agree_with_the_observation_matrix(case):
    """u[g, c] = coef[g, c] · φ[index[g]] reads what a sensor along c at g reads, on
    constrained, free and RBE2-dependent grids alike."""
    model = case.model
    phi = np.random.default_rng(0).standard_normal((model.n_dof, 3))
    u = sv.grid_translations(model, phi)
    rows = [g for g in model.node_ids.tolist() if g > 4]  # observation_matrix refuses the clamped base's zero rows
    sensors = Sensors.from_components(np.repeat(rows, 3), np.tile([1, 2, 3], len(rows)))
    C, _ = observation_matrix(model, sensors)
    np.testing.assert_allclose(u[model.node_index(rows)].reshape(-1, 3), C @ phi, rtol=1e-12, atol=1e-14)
    assert np.allclose(u[model.node_index([1, 2, 3, 4])], 0.0)  # clamped base
    with pytest.raises(ValueError, match="expected"):
        sv.grid_translations(model, phi[:-1])


def _payload(html: str) -> dict:
    return json.loads(re.search(r'<script type="application/json" id="jaxfem-shape-data">(.*?)</script>', html,
                                re.S).group(1).replace("<\\/", "</"))


def test_shape_view_is_one_self_contained_file(tmp_path, case):
    model, test = case.model, case.test
    lam, phi = jaxfem.modes(model, 12)
    at = observation_matrix(model, test.sensors)[0] @ np.asarray(phi)
    from identification._correlation import pair_modes

    pairing = pair_modes(np.asarray(jaxfem.frequencies_hz(lam)), at, test.frequencies_hz, test.shapes)
    assert len(pairing.test) >= 6
    out = sv.correlation_view(tmp_path / "sub" / "shapes.html", model=model, phi=phi, test=test, at_sensors=at,
                           pairing=pairing, test_nodes=case.nodes, test_lines=case.lines, title="frame <&> test")
    html = out.read_text(encoding="utf-8")
    # offline: plotly.js inside, no script or stylesheet from elsewhere
    assert not re.search(r"<script[^>]*\bsrc=", html) and not re.search(r"<link[^>]*\bhref=", html)
    assert "Plotly.newPlot" in html and len(html) > 3_000_000  # the embedded plotly.min.js
    assert "frame &lt;&amp;&gt; test" in html
    for j, i, ft, fm, dev, mac in [r for r in pairing.table() if r[1] is not None]:  # every pair, in the title and table
        assert f"test {j}: {ft:.4g} Hz · model {i}: {fm:.4g} Hz · Δf {dev:+.2f} % · MAC {mac:.3f}" in html
        assert f"<td>{ft:.4f}</td><td>{fm:.4f}</td><td>{dev:+.2f}</td><td>{mac:.3f}</td>" in html
    data = _payload(html)
    assert len(data["pairs"]) == len(pairing.test)
    n_t, n_m = len(data["test"]["ids"]), len(data["model"]["xyz"]) // 3
    assert data["test"]["ids"] == sorted(case.nodes) and max(data["test"]["seg"]) < n_t
    assert max(data["model"]["seg"]) < n_m == len(model.node_ids)  # a small model: every grid drawn
    extent = np.ptp(model.xyz, axis=0).max()
    for p in data["pairs"]:  # each shape's largest translation: DEFORMATION × extent
        for side, n in (("test", n_t), ("model", n_m)):
            peak = np.linalg.norm(np.reshape(p[side], (n, 3)), axis=1).max()
            assert abs(peak - sv.DEFORMATION * extent) < 1e-5 * extent
    test_rows = [data["test"]["ids"].index(g) for g in SENSOR_GRIDS]
    first = np.reshape(data["pairs"][0]["test"], (n_t, 3))
    assert np.allclose(first[[0, 1, 2, 3]], 0.0) and np.abs(first[test_rows, 2]).max() == 0.0  # X, Y measured only
    with pytest.raises(ValueError, match="not among the test nodes"):
        sv.shape_view(tmp_path / "bad.html", model=model, model_shapes=np.zeros((len(model.node_ids), 3, 1)),
                   test_nodes=case.nodes, test_shapes={}, pairs=[], test_lines=[(1, 99)])


def _plate(tmp_path, n: int):
    lines = ["MAT1,1,7.0+10,,0.3,2700.", "PSHELL,1,1,0.002,1", "PSHELL,2,1,0.002,1"]
    nid = lambda i, j: 1 + i + (n + 1) * j  # noqa: E731
    lines += [f"GRID,{nid(i, j)},,{i / n},{j / n},0." for j in range(n + 1) for i in range(n + 1)]
    lines += [f"CQUAD4,{1 + i + n * j},{1 + (i >= n // 2)},{nid(i, j)},{nid(i + 1, j)},{nid(i + 1, j + 1)},"
              f"{nid(i, j + 1)}" for j in range(n) for i in range(n)]
    bdf = tmp_path / "plate.bdf"
    bdf.write_text("BEGIN BULK\n" + "\n".join(lines) + "\nENDDATA\n")
    return jaxfem.build_model(read_bdf(bdf))


def test_large_models_draw_feature_edges_first(tmp_path):
    """A 12 × 12 plate of two properties: 312 edges, 48 on the boundary, 12 between the
    properties; capped at 100, every feature edge and an even share of the rest."""
    model = _plate(tmp_path, 12)
    every, total = sv._model_edges(model, 10_000)
    assert total == len(every) == 2 * 12 * 13
    edges, total = sv._model_edges(model, 100)
    assert total == 312 and len(edges) == 100
    xy = np.asarray(model.xyz)[edges][..., :2]
    on_boundary = np.all(np.isclose(xy[..., 0], 0) | np.isclose(xy[..., 0], 1), axis=1) | \
        np.all(np.isclose(xy[..., 1], 0) | np.isclose(xy[..., 1], 1), axis=1)
    between = np.all(np.isclose(xy[..., 0], 0.5), axis=1)
    assert on_boundary.sum() == 48 and between.sum() == 12 and (on_boundary | between)[:60].all()
    assert len({tuple(e) for e in np.sort(edges, axis=1).tolist()}) == 100
    html = sv.shape_view(tmp_path / "plate.html", model=model, model_shapes=np.ones((len(model.node_ids), 3, 1)),
                      test_nodes={1: [0, 0, 0]}, test_shapes={1: np.ones((3, 1))}, pairs=[(0, 0, 10.0, 11.0, 0.9)],
                      max_edges=100).read_text(encoding="utf-8")
    assert "100 of 312 element edges" in html and "Δf +10.00 %" in html


def test_test_geometry_follows_the_map(tmp_path):
    """Measured nodes where the map put them (renamed ids back to the test's), the others
    moved by its rigid alignment; left out, with their lines, when the coordinates do not
    land on the mapped ones."""
    raw = {1: [0.0, 0, 0], 2: [1.0, 0, 0], 3: [1.0, 1, 0], 4: [0.0, 1, 0]}
    uff = tmp_path / "t.uff"
    write_uff(uff, nodes={k: np.array(v) for k, v in raw.items()})
    _add_trace_lines(uff, [(1, 2), (2, 3), (3, 4), (4, 1)])
    c, s = np.cos(0.3), np.sin(0.3)
    R, t = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]), np.array([0.5, -0.2, 1.0])
    moved = {k: R @ np.array(v) + t for k, v in raw.items()}
    gmap = SimpleNamespace(nodes=np.array([1, 2, 3]), xyz=np.array([moved[k] for k in (1, 2, 3)]),
                           renamed={3: 1003}, alignment={"rotation": R, "translation": t})
    content = read_uff(uff, length_units="m")
    nodes, lines, names = sv.measured_geometry(content, gmap)
    assert sorted(nodes) == [1, 2, 3, 4] and names == {1: 1, 2: 2, 1003: 3}
    np.testing.assert_allclose(nodes[4], moved[4], atol=1e-12)
    assert lines == [(1, 2), (2, 3), (3, 4), (1, 4)]
    in_mm = SimpleNamespace(nodes=np.array([1, 2, 3]), xyz=1000 * np.array([raw[k] for k in (1, 2, 3)]),
                            renamed={}, alignment=None)
    nodes, lines, _ = sv.measured_geometry(content, in_mm)
    assert sorted(nodes) == [1, 2, 3] and lines == [(1, 2), (2, 3)]
    assert sv.measured_geometry(None, None) == ({}, [], {})


@pytest.fixture(scope="module")
def correlated(case):
    """``jaxfem correlate --report`` on the case."""
    report = case.dir / "report"
    result = CliRunner().invoke(app, ["correlate", str(case.bdf), str(case.uff), "--json",
                                      str(case.dir / "corr.json"), "--report", str(report)])
    return result, report / "shapes.html"


def test_correlate_report_writes_the_view(case, correlated):
    result, view = correlated
    assert result.exit_code == 0, result.output
    assert f"wrote {view}" in result.output and view.is_file()
    html = view.read_text(encoding="utf-8")
    paired = json.loads((case.dir / "corr.json").read_text())["paired_modes"]
    assert len(paired) >= 6 and len(_payload(html)["pairs"]) == len(paired)
    for p in paired:
        assert f"Δf {p['freq_dev_pct']:+.2f} % · MAC {p['mac']:.3f}" in html
    assert f"trace lines: {len(case.lines)} from UFF dataset 82" in html
    assert _payload(html)["test"]["ids"] == list(range(1, 21))  # the unmeasured base drawn too


def test_diagnosis_report_links_the_views(tmp_path, case):
    """``diagnose --report``: shapes.html (initial model) and shapes_after.html (with the
    effect) next to report.html, linked from it."""
    from updating.diagnosis import DiagnoseOptions
    from updating.report._html import write_report
    from updating.cli._diagnose import _shape_views

    after = Effect("added_mass", nodes=(14,), values={"m": 25.0}).apply(case.model)
    views = _shape_views(SimpleNamespace(model=case.model), SimpleNamespace(after=SimpleNamespace(model=after)),
                         case.test, None, None, DiagnoseOptions(), tmp_path)
    assert list(views.values()) == ["shapes.html", "shapes_after.html"]
    assert all((tmp_path / name).is_file() for name in views.values())
    assert "Δf +0.00 % · MAC 1.000" in (tmp_path / "shapes_after.html").read_text(encoding="utf-8")  # the truth
    html = write_report({"model": "frame.bdf"}, {}, tmp_path / "report.html", links=views).read_text(encoding="utf-8")
    assert '<a href="shapes.html">test vs the initial model (' in html and '<a href="shapes_after.html">' in html


# -- in a real browser -------------------------------------------------------------------

CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-quic",
                  "--no-first-run", "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--host-resolver-rules=MAP * ~NOTFOUND",  # no network: a fetch would fail
                  "--enable-logging=stderr", "--v=0", "--window-size=1200,800", "--virtual-time-budget=5000"]
# console.error marked (chromium logs every console level alike), and any resource that fails to load
CATCH_ERRORS = ("<script>(function(){var e=console.error;console.error=function(){"
                "e.apply(console,['JAXFEM-CONSOLE-ERROR'].concat([].slice.call(arguments)));};"
                "window.addEventListener('error',function(ev){var t=ev.target;"
                "if(t&&t!==window)console.error('failed to load',t.src||t.href);},true);})();</script>")


def _chromium() -> str | None:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None and os.environ.get("JAXFEM_REQUIRE_BROWSER") == "1":
        pytest.fail("JAXFEM_REQUIRE_BROWSER=1 but no chromium on PATH (apt-get install chromium)")
    return found


def _browse(chromium: str, page, url_hash: str, profile, *args) -> subprocess.CompletedProcess:
    return subprocess.run([chromium, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args,
                           page.as_uri() + url_hash], capture_output=True, text=True, timeout=120)


def _console_errors(log: str) -> list[str]:
    return [line for line in log.splitlines() if ":CONSOLE" in line and any(
        mark in line for mark in ("Uncaught", "JAXFEM-CONSOLE-ERROR", "Failed to load", "net::ERR", "WebGL is not"))]


def test_view_in_a_headless_browser(tmp_path, correlated):
    """The page runs without a console error (animating, overlaid, for 5 s of virtual time)
    and, stopped at the largest deflection side by side, shows the test wireframe in red on
    the left and the model in blue on the right."""
    chromium = _chromium()
    if chromium is None:
        pytest.skip("no chromium on PATH (apt-get install chromium; JAXFEM_REQUIRE_BROWSER=1 makes this a failure)")
    result, view = correlated
    assert result.exit_code == 0, result.output
    page = tmp_path / "shapes.html"
    page.write_text(view.read_text(encoding="utf-8").replace("<head>", "<head>" + CATCH_ERRORS, 1), encoding="utf-8")

    dom = _browse(chromium, page, "#view=overlay&pair=2", tmp_path / "profile1", "--dump-dom")
    assert dom.returncode == 0, dom.stderr[-3000:]
    assert _console_errors(dom.stderr) == []
    assert re.search(r'class="gtitle"[^>]*>pair 2/\d+: test 2: ', dom.stdout), "the script did not set the title"

    png = tmp_path / "shapes.png"
    shot = _browse(chromium, page, "#phase=6", tmp_path / "profile2", f"--screenshot={png}")
    assert shot.returncode == 0 and png.is_file(), shot.stderr[-3000:]
    assert _console_errors(shot.stderr) == []
    import matplotlib.image

    rgb = matplotlib.image.imread(png)[..., :3]
    height, width = rgb.shape[:2]
    for colour, side in ((RED, "left"), (BLUE, "right")):
        ys, xs = np.nonzero(np.abs(rgb - colour).max(axis=2) < 0.1)
        assert len(xs) > 500, f"{side}: {len(xs)} pixels of the shape's colour"
        assert (np.median(xs) < width / 2) == (side == "left")  # the legend's samples aside
        assert np.ptp(ys) > 0.2 * height  # the whole frame, not a dot
