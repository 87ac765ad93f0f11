"""Diagnosis plots (structure wireframe, effect ranking) and the HTML report."""

import io
import re

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import jaxfem
from benchmarks.frames import frame_bdf
from updating._plots import effect_where, plot_effect_ranking, plot_structure
from updating._report import write_report


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
    from updating._plots import _figure

    figures = {"mac": _figure(3, 3), "structure": plot_structure(model), "effects": plot_effect_ranking([])}
    figures["mac"].add_subplot().plot([0, 1])
    diagnosis = {
        "model": "/a/b/model.bdf", "test": "test.unv", "verdict": "Mass <b>missing</b> at node 7 & more",
        "paired_modes": [{"test": 1, "model": 1, "f_test_hz": 10.0, "f_model_hz": 10.51234,
                          "freq_dev_pct": 5.1234, "mac": 0.98765}],
        "unpaired_test": [3], "baseline": {"rms_freq_dev_pct": 5.1, "mean_mac": 0.9},
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
    tables = re.sub(r'<img src="[^"]*"', "", text)
    assert "14+X" in tables and "4+X" not in tables.replace("14+X", "")  # the 10 lowest COMAC only
    order = [text.index(s) for s in ("Comparison", "Where it fails", "Candidate effects", "More plots")]
    assert order == sorted(order) and "After adding the effect" not in text
