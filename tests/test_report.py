"""Diagnosis plots (structure wireframe, indicator on the shells, effect ranking) and the
HTML report."""

import io
import re

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import jaxfem
from benchmarks.frames import frame_bdf
from identification._patches import shell_centres
from updating.report._plots import effect_where, plot_effect_ranking
from updating.report._structure_plots import plot_structure, plot_surface
from updating.report._html import write_report


@pytest.fixture(scope="module")
def model():
    return jaxfem.build_model(jaxfem.io.read_bdf_text(frame_bdf(2, 2, 2, n_groups=4)))


def _segments(fig) -> int:
    """Line segments drawn in the 3-D axes (projected on drawing, so draw first)."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    fig.savefig(io.BytesIO(), format="png")
    ax = fig.axes[0]
    return sum(len(c.get_segments()) for c in ax.collections if isinstance(c, Line3DCollection))


def _n_lines(model) -> int:
    springs = np.asarray(model.springs.nodes).reshape(-1, 2)
    n_two_node_springs = int((springs >= 0).all(axis=1).sum())
    return len(model.beams.ids) + len(model.rods.ids) + len(model.bushes.ids) + n_two_node_springs


def test_plot_structure_plain(model):
    from matplotlib.figure import Figure

    fig = plot_structure(model)
    assert isinstance(fig, Figure)
    assert _segments(fig) == _n_lines(model) == 18  # 16 beams, 1 rod, 1 bush; the spring is grounded
    assert len(fig.axes) == 1  # no colour bar without values
    assert fig.axes[0].get_xlabel() == "x [m]"


def test_plot_structure_values(model):
    eids = [int(e) for e in model.beams.ids[:5]]
    nodes = [int(n) for n in model.node_ids[:6]]
    fig = plot_structure(model, {e: float(i) for i, e in enumerate(eids)},
                         {n: float(i + 1) for i, n in enumerate(nodes)}, title="t", label="energy [–]")
    assert _segments(fig) == _n_lines(model)
    assert any(a.get_ylabel() == "energy [–]" for a in fig.axes[1:])  # the colour bar
    texts = {t.get_text().strip() for t in fig.axes[0].texts}
    assert texts == {str(n) for n in nodes[-3:]}  # the three largest nodes annotated


def test_plot_effect_ranking():
    effects = [{"rank": 2, "kind": "mass", "nodes": [1029], "score": 0.4,
                "heldout_rms_freq_dev_pct_before": 3.0, "heldout_rms_freq_dev_pct_after": 2.0},
               {"rank": 1, "kind": "stiffness", "pids": [41], "score": 0.8,
                "heldout_rms_freq_dev_pct_before": 3.0, "heldout_rms_freq_dev_pct_after": 1.0},
               {"rank": 3, "kind": "joint", "eids": [201, 202, 203, 204, 205], "score": 0.1,
                "heldout_rms_freq_dev_pct_before": 3.0}]
    fig = plot_effect_ranking(effects)
    ax = fig.axes[0]
    assert len(ax.patches) == 5  # the third effect has no "after"
    rows = sorted(zip(ax.get_yticks(), (t.get_text() for t in ax.get_yticklabels())), reverse=True)
    assert [label for _, label in rows] == ["stiffness pid 41", "mass node 1029", "joint eids 201-205"]
    assert ax.get_xlabel() == "held-out RMS Δf [%]"
    assert effect_where({"pids": [1, 2], "nodes": []}) == "pids 1, 2"


def test_write_report(tmp_path, model):
    from updating.report._plots import _figure

    figures = {"mac": _figure(3, 3), "structure": plot_structure(model), "effects": plot_effect_ranking([])}
    figures["mac"].add_subplot().plot([0, 1])
    diagnosis = {
        "model": "/a/b/model.bdf", "test": "test.unv", "verdict": "Mass <b>missing</b> at node 7 & more",
        "paired_modes": [{"test": 1, "model": 1, "f_test_hz": 10.0, "f_model_hz": 10.51234,
                          "freq_dev_pct": 5.1234, "mac": 0.98765}],
        "unpaired_test": [3], "baseline": {"rms_freq_dev_pct": 5.1, "mean_mac": 0.9, "heldout_rms_freq_dev_pct": 4.2,
                                           "chi2_per_row_shape": 3.3},
        "sensors": [{"label": f"{i}+X", "comac": 1.0 - 0.01 * i} for i in range(15)],
        "localisation": {"groups": [{"pid": 41, "score": 1.0}], "nodes": []},
        "effects": [{"rank": 1, "kind": "mass", "nodes": [7], "parameters": {"m": 0.5}, "score": 0.9,
                     "plausible": True, "plausibility": ["small", "local"]}],
        "no_effect_warranted": False,
    }
    out = write_report(diagnosis, figures, tmp_path / "sub" / "report.html")
    assert list(tmp_path.rglob("*")) == [tmp_path / "sub", out]
    text = out.read_text(encoding="utf-8")
    assert text.count('<img src="data:image/png;base64,') == len(figures)
    assert "Mass &lt;b&gt;missing&lt;/b&gt; at node 7 &amp; more" in text
    assert "<b>missing" not in text
    assert "http" not in text
    assert "model.bdf" in text and "/a/b" not in text
    assert "10.51" in text and "10.51234" not in text and "m=0.5" in text and "small; local" in text
    # the baseline labelled for engineers, not by its JSON keys
    assert "held-out RMS Δf [%]" in text and "χ² per row, shapes [–]" in text
    assert "heldout rms" not in text and "chi2 per row" not in text
    tables = re.sub(r'<img src="[^"]*"', "", text)
    assert "14+X" in tables and "4+X" not in tables.replace("14+X", "")  # the 10 lowest COMAC only
    order = [text.index(s) for s in ("Comparison", "Where it fails", "Candidate effects", "More plots")]
    assert order == sorted(order) and "After adding the effect" not in text


# ----------------------------------------------------------------------------- indicator on shells


@pytest.fixture(scope="module")
def panel():
    from benchmarks.cfrp_panel import build

    return build()  # clamped CFRP plate (z = 0) with two blade stringers standing on it


def _panel_case(panel):
    """A fake indicator (largest at (0.3, 0.2) on the plate) and a rectangular patch of
    plate elements around it, centred on the plate grid nearest to that point."""
    ids, centres, _ = shell_centres(panel)
    values = {int(e): -float(np.linalg.norm(c - [0.3, 0.2, 0.0])) for e, c in zip(ids, centres)}
    plate = np.abs(centres[:, 2]) < 1e-9
    block = plate & (np.abs(centres[:, 0] - 0.3) < 0.04) & (np.abs(centres[:, 1] - 0.2) < 0.03)
    xyz = np.asarray(panel.xyz)
    row = int(np.argmin(np.linalg.norm(xyz - [0.3, 0.2, 0.0], axis=1)))
    patch = {"kind": "delamination", "eids": [int(e) for e in ids[block]], "nodes": [int(panel.node_ids[row])],
             "radius_m": 0.04, "where": "eids ..."}
    return values, patch, plate, block, xyz[row]


def test_plot_surface_flat_panel(panel):
    from matplotlib import colormaps
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.patches import Circle

    values, patch, plate, block, centre = _panel_case(panel)
    sensors = [int(g) for g in panel.node_ids[::40]]
    fig = plot_surface(panel, values, sensors=sensors + sensors[:3] + [999_999], patch=patch, label="energy [–]")
    ax = fig.axes[0]
    assert ax.name == "rectilinear" and (ax.get_xlabel(), ax.get_ylabel()) == ("x [m]", "y [m]")  # seen along z
    assert [a.get_ylabel() for a in fig.axes[1:]] == ["energy [–]"]  # the colour bar
    polys = [c for c in ax.collections if isinstance(c, PolyCollection)]
    assert [len(c.get_paths()) for c in polys] == [plate.sum(), (~plate).sum()]  # plate filled, stringers edge-on
    ids = shell_centres(panel)[0][plate]
    top = int(np.argmax([values[int(e)] for e in ids]))
    assert np.allclose(polys[0].get_facecolors()[top], colormaps["viridis"](1.0))
    outline = [c for c in ax.collections if isinstance(c, LineCollection) and c.get_label().startswith("delamination")]
    assert len(outline) == 1 and outline[0].get_label() == "delamination, radius 40 mm"
    segments = np.array(outline[0].get_segments())  # the rectangle's border only, no inner edge
    corners = np.asarray(panel.xyz)[np.asarray(panel.quads.nodes)[np.isin(panel.quads.ids, patch["eids"])]][..., :2]
    lo, hi = corners.reshape(-1, 2).min(axis=0), corners.reshape(-1, 2).max(axis=0)
    assert len(patch["eids"]) >= 4
    assert np.isclose(np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1).sum(), 2 * (hi - lo).sum())
    on_border = np.isclose(segments, lo).any(axis=-1) | np.isclose(segments, hi).any(axis=-1)
    assert on_border.all()
    circles = [p for p in ax.patches if isinstance(p, Circle)]
    assert len(circles) == 1 and circles[0].get_radius() == 0.04 and np.allclose(circles[0].center, centre[:2])
    marks = [line for line in ax.lines if line.get_marker() == "x"]
    assert len(marks) == 1 and np.allclose(marks[0].get_xydata(), [centre[:2]])
    dots = [c for c in ax.collections if c.get_label().startswith("sensors")]
    assert len(dots) == 1 and len(dots[0].get_offsets()) == len(set(sensors))  # repeats once, unknown id left out
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend[0] == "delamination, radius 40 mm" and f"sensors ({len(set(sensors))} grids)" in legend


def _rolled(panel):
    """The panel rolled into a closed tube about the y axis (x runs round it, the stringers
    stand out radially as two ring frames): a curved shell model at no build cost."""
    import equinox as eqx

    x, y, z = np.asarray(panel.xyz).T
    theta, r = 2 * np.pi * x / x.max(), x.max() / (2 * np.pi) + z
    return eqx.tree_at(lambda m: m.xyz, panel, np.stack([y, r * np.cos(theta), r * np.sin(theta)], axis=1))


def test_plot_surface_curved(panel):
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    from updating.report._plots import _figure

    tube = _rolled(panel)
    ids, centres, _ = shell_centres(tube)
    values = {int(e): float(c[2]) for e, c in zip(ids, centres)}
    quads = np.asarray(tube.quads.nodes)  # two quads sharing an edge: their outline has 6 edges
    second = next(i for i in range(1, len(quads)) if len(set(quads[i]) & set(quads[0])) == 2)
    patch = {"kind": "delamination", "eids": [int(tube.quads.ids[0]), int(tube.quads.ids[second])],
             "nodes": [int(tube.node_ids[quads[0, 0]])]}
    fig = plot_surface(tube, values, sensors=[int(g) for g in tube.node_ids[::10]], patch=patch, title="tube")
    fig.savefig(io.BytesIO(), format="png")  # 3-D collections are projected on drawing
    ax = fig.axes[0]
    assert ax.name == "3d" and ax.get_title() == "tube"
    faces = [c for c in ax.collections if isinstance(c, Poly3DCollection)]
    n_shells = len(tube.quads.ids) + len(tube.trias.ids)
    assert len(faces) == 1 and len(faces[0].get_paths()) == n_shells == 400
    outline = [c for c in ax.collections if isinstance(c, Line3DCollection)]
    assert [c.get_label() for c in outline] == ["delamination"]  # no radius given; no line elements
    assert len(outline[0].get_segments()) == 6
    assert [a.get_ylabel() for a in fig.axes[1:]] == ["element indicator"]
    spans = np.ptp(np.asarray(tube.xyz), axis=0)
    assert np.allclose(np.asarray(ax.get_box_aspect()) / ax.get_box_aspect()[0], spans / spans[0])  # equal scale
    with pytest.raises(ValueError, match="not in one plane"):
        plot_surface(tube, values, ax=_figure(3, 3).add_subplot())


def test_plot_surface_needs_shells(model):
    with pytest.raises(ValueError, match="no shell elements"):
        plot_surface(model, {})


def test_surface_figure_of_the_diagnosis(panel, model):
    from types import SimpleNamespace

    from matplotlib.collections import LineCollection

    from updating.cli._diagnose import _surface_figure

    values, patch, _, _, _ = _panel_case(panel)
    diag = SimpleNamespace(element_scores=values)
    test = SimpleNamespace(sensors=SimpleNamespace(nodes=np.array([1, 1, 2, 3])))
    effects = [patch, {"kind": "added_mass", "nodes": [5], "eids": []}]
    fig = _surface_figure({"effects": effects}, diag, panel, test)
    ax = fig.axes[0]
    assert any(isinstance(c, LineCollection) and c.get_label() == "delamination, radius 40 mm" for c in ax.collections)
    assert len(next(c for c in ax.collections if c.get_label().startswith("sensors")).get_offsets()) == 3
    fig = _surface_figure({"effects": effects[::-1]}, diag, panel, test)  # the first effect names no elements
    assert not [t.get_text() for t in fig.axes[0].get_legend().get_texts() if "mass" in t.get_text()]
    assert not any(c.get_label().startswith(("delamination", "added_mass")) for c in fig.axes[0].collections)
    assert _surface_figure({"effects": effects}, SimpleNamespace(element_scores={}), model, test) is None  # no shells


def _png_widths(html_text: str) -> list[int]:
    """Pixel widths of the embedded PNG images, in page order (from the IHDR chunk)."""
    import base64

    return [int.from_bytes(base64.b64decode(b)[16:20], "big")
            for b in re.findall(r'data:image/png;base64,([A-Za-z0-9+/=]+)', html_text)]


def test_write_report_places_the_surface_map(tmp_path, panel):
    from updating.report._plots import _figure

    values, patch, _, _, _ = _panel_case(panel)
    groups = _figure(2, 2)  # small: told apart from the 8 x 6 in map by its width
    groups.add_subplot().plot([0, 1])
    text = write_report({"localisation": {"groups": [{"pid": 1, "score": 1.0}]}, "effects": [patch]},
                        {"localisation_groups": groups, "localisation_surface": plot_surface(panel, values, patch=patch)},
                        tmp_path / "report.html").read_text(encoding="utf-8")
    where, effects = text.index("<h2>Where it fails</h2>"), text.index("<h2>Candidate effects</h2>")
    assert _png_widths(text[:where]) == [] and _png_widths(text[effects:]) == []
    widths = _png_widths(text[where:effects])  # the map first, then the wireframe
    assert len(widths) == 2 and widths[0] > 600 > 300 > widths[1]
    assert "More plots" not in text
