"""The ``montecarlo`` command: header, progress, JSON, plots, resume and input errors.

A tiny §4.3 study on the embedded tree (model 1 of Table 4.6, 3 modes, 2 samples per
cell) on one device: each device compiles its own copy, and so does every batch size,
so chunks of one sample (the size of the error-free reference update) compile once.
Gauss–Newton with a 1e-6 tolerance converges in 4–5 steps; the default options (LM,
1e-10, 16 steps) cost several times more per sample. The plots' one line per number of
modes and their failure counts are checked on a synthetic result (no updates).
"""

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

import updating.studies as studies
from updating.report import _montecarlo_plots
from updating.studies import _montecarlo
from updating.cli import app

runner = CliRunner()
STUDY = """
[study]
modelling_error = 1
n_modes = [3]
samples = 2
chunk_size = 1
[errors]
relative = [0.01, 0.05]
frequency = [0.01]
[options]
solver = "gauss-newton"
tolerance = 1e-6
max_iterations = 10
"""
N_MODES = (3,)
CELLS = [("relative", 0.01), ("relative", 0.05), ("frequency", 0.01)]
NAMES = ["blades_2_4", "blades_1_3", "pylon_upper"]


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """``(dir, args, first run)``. The CLI calls of this module share one Runner per
    study (as one long-lived process would), so the rerun compiles nothing."""
    d = tmp_path_factory.mktemp("cli_montecarlo")
    (d / "study.toml").write_text(STUDY)
    made, make = {}, _montecarlo.Runner

    def shared(study, devices=None):
        key = (study.digest(), tuple(devices))
        if key not in made:
            made[key] = make(study, devices)
        return made[key]

    args = ["montecarlo", str(d / "study.toml"), "--json", str(d / "mc.json"), "--plots", str(d / "plots"),
            "--devices", "1"]
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(studies, "Runner", shared)
        yield d, args, runner.invoke(app, args)


def _finite_or_none(x, expect_none: bool) -> bool:
    return x is None if expect_none else isinstance(x, float) and math.isfinite(x)


def test_json_holds_the_statistics_of_every_cell(study):
    d, _, result = study
    assert result.exit_code == 0, result.output
    data = json.loads((d / "mc.json").read_text())
    assert data["samples"] == 2 * len(CELLS) * len(N_MODES) and data["parameters"] == NAMES
    assert data["devices"] == 1 and data["study"]["n_modes"] == list(N_MODES)
    stats = data["statistics"]
    assert [(s["n_modes"], s["category"], s["magnitude"]) for s in stats] == [(n, *c) for n in N_MODES for c in CELLS]
    for s in stats:
        assert s["samples"] == 2 and s["succeeded"] + sum(s["failed"].values()) == 2
        none = s["succeeded"] == 0  # a cell without successful samples has no statistics (null)
        assert set(s["delta_alpha"]) == set(NAMES)
        assert all(_finite_or_none(v, none) for a in s["delta_alpha"].values() for v in a.values())
        for key in ("delta_f", "delta_mac"):
            assert all(len(v) == s["n_modes"] and all(_finite_or_none(x, none) for x in v)
                       for v in s[key].values())
    assert sum(sum(s["failed"].values()) for s in stats) == sum(data["failures"].values())
    assert sum(s["fallback"] for s in stats) == data["fallbacks"]
    for n in N_MODES:
        ref = data["reference"][str(n)]
        assert len(ref["alpha"]) == len(NAMES) and len(ref["f_a"]) == n
        assert ref["alpha"][0] == pytest.approx(1 / (1 - 0.17) - 1, abs=1e-3)  # undoes K̃_1 = −17 %


def test_header_progress_plots_and_summary(study):
    d, _, result = study
    assert result.exit_code == 0, result.output
    out, err = result.stdout, result.stderr
    assert "tree.bdf" in out and "49 sensors" in out and "devices: 1 of 4" in out
    assert "= 6, in 6 chunks" in out and "blades_2_4 (stiffness)" in out
    progress = [line for line in err.splitlines() if line.startswith("[montecarlo] chunk")]
    assert len(progress) == 6 and "6/6 samples" in progress[-1] and "samples/s" in progress[-1]
    for name in ("relative", "frequency"):
        for kind in ("alpha", "freq", "mac"):
            png = d / "plots" / f"montecarlo_{name}_{kind}.png"
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    assert not (d / "plots" / "montecarlo_absolute_alpha.png").exists()
    table = [line.split() for line in out.splitlines() if line.split()[:2] in (["3", "relative"], ["3", "frequency"])]
    assert [row[2] for row in table] == ["5", "1"]  # the largest magnitude, %
    assert all(float(v.rstrip("*")) > 0 for v in table[0][3:6])  # std Δα; * marks α(0) = 0 (a difference)
    assert table[0][6:] == ["0", "0"]  # failed, fallbacks


def test_rerun_resumes_from_the_chunks(study):
    d, args, first = study
    assert first.exit_code == 0, first.output
    before = json.loads((d / "mc.json").read_text())
    assert sorted(p.name for p in (d / "mc.chunks" / "chunks").iterdir()) == [f"n03_{j:07d}.npz" for j in range(6)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "6 of 6 chunks found (6 samples); nothing to compute" in result.stdout
    assert "[montecarlo] chunk" not in result.stderr
    assert json.loads((d / "mc.json").read_text())["statistics"] == before["statistics"]


def test_ray_option_reaches_montecarlo_ray(study, monkeypatch):
    """``--ray local`` hands the study to ``updating.montecarlo_ray`` without an address
    (start a cluster here), ``--ray ADDRESS`` with it; a cluster that cannot be reached
    exits 2 naming the address. (The Ray run itself is tested in test_ray.py; here it is
    replaced by the in-process study, which must give the same statistics.)"""
    d, _, first = study
    assert first.exit_code == 0, first.output
    seen = []

    def fake(study_, *, address, out, progress, runner):
        seen.append(address)
        if address is not None:
            raise ConnectionError(f"could not reach {address}")
        return _montecarlo.montecarlo(study_, out=out, progress=progress, runner=runner)

    monkeypatch.setattr(studies, "montecarlo_ray", fake)
    base = ["montecarlo", str(d / "study.toml"), "--json", str(d / "ray.json"), "--devices", "1"]
    ok = runner.invoke(app, base + ["--ray", "local"])
    assert ok.exit_code == 0, ok.output
    assert json.loads((d / "ray.json").read_text())["statistics"] == \
        json.loads((d / "mc.json").read_text())["statistics"]
    bad = runner.invoke(app, base + ["--ray", "ray://head:10001"])
    assert bad.exit_code == 2 and "--ray ray://head:10001: could not reach ray://head:10001" in bad.stderr
    assert seen == [None, "ray://head:10001"]


@pytest.mark.parametrize("text, named", [
    ("[study\nsamples = 2\n", "Expected ']'"),
    ("[study]\nmodeling_error = 1\n", "modeling_error"),
    ("[errors]\nthermal = [0.1]\n", "thermal"),
    ("[errors]\nrelative = [5]\n", "fractions"),
    ("[study]\nmodelling_error = 4\n", "Table 4.6"),
])
def test_malformed_study_exits_2_naming_file_and_problem(tmp_path, text, named):
    (tmp_path / "bad.toml").write_text(text)
    result = runner.invoke(app, ["montecarlo", str(tmp_path / "bad.toml"), "--json", str(tmp_path / "x.json")])
    assert result.exit_code == 2, result.output
    assert "bad.toml" in result.stderr and named in result.stderr and "Traceback" not in result.output
    assert len(result.stderr.strip().splitlines()) == 1 and not (tmp_path / "x.chunks").exists()


def test_more_devices_than_there_are_exits_2(tmp_path):
    (tmp_path / "s.toml").write_text(STUDY)
    result = runner.invoke(app, ["montecarlo", str(tmp_path / "s.toml"), "--json", str(tmp_path / "x.json"),
                                 "--devices", "99"])
    assert result.exit_code == 2 and "--devices 99: only" in result.stderr


def test_plots_draw_one_line_per_number_of_modes_and_count_failures(tmp_path, monkeypatch):
    study = _montecarlo.default_study(1, n_modes=(2, 5), samples=3,
                                      errors=(("absolute", (0.001, 0.01)),))
    rng = np.random.default_rng(0)

    def record(n, rows, noise):
        f_e = np.tile(np.linspace(10.0, 50.0, n), (rows, 1))
        return {"alpha": np.array([0.2, 0.0, 0.0]) + noise * rng.normal(size=(rows, 3)), "f_e": f_e,
                "f_a": f_e * (1 + noise * rng.normal(size=(rows, n))), "mac": 0.99 - noise * rng.random((rows, n)),
                "iterations": np.full(rows, 5), "status": np.zeros(rows, np.int64), "fallback": np.zeros(rows, bool),
                "refreshes": np.zeros(rows, np.int64)}

    samples = {n: record(n, 6, 0.01) for n in study.n_modes}
    samples[2]["status"][:3] = 1  # the first cell of n = 2 failed entirely: no statistics
    samples[5]["status"][4] = 3
    result = _montecarlo.MonteCarloResult(study, study.parameters.names, samples,
                                          {n: record(n, 1, 0.0) for n in study.n_modes}, 1.0)
    figures, save = [], _montecarlo_plots._save
    monkeypatch.setattr(_montecarlo_plots, "_save", lambda fig, path: figures.append(fig) or save(fig, path))
    paths = _montecarlo_plots.plot_montecarlo(result, tmp_path, name="synthetic.toml")
    assert [p.name for p in paths] == [f"montecarlo_absolute_{k}.png" for k in ("alpha", "freq", "mac")]
    assert all(p.stat().st_size > 10_000 for p in paths)
    alpha, freq, mac = figures
    assert [t.get_text() for t in alpha.axes[0].get_legend().get_texts()] == [
        "n = 2 modes", "n = 5 modes", "mean ± std", "RMS"]
    assert "absolute errors, synthetic.toml" in alpha.get_suptitle()
    assert alpha.axes[0].get_xlabel() == "absolute error a [% of the mode's largest deflection]"
    assert {a.get_ylabel() for a in alpha.axes} == {"Δα [%]"}
    for fig, symbol in ((freq, "Δf"), (mac, "ΔMAC")):
        assert len(fig.axes) == 3 and fig.axes[0].get_ylabel() == f"{symbol} [%]"
        assert [t.get_text() for t in fig.axes[0].get_legend().get_texts()] == ["n = 2 modes", "n = 5 modes"]
        assert len(fig.axes[2].get_xticks()) == 5  # the n = 5 panel: one tick per mode
    for fig in figures:
        footer = fig.get_supxlabel()
        assert "of 3 per cell at 0.1, 1 %: n = 2: 3, 0; n = 5: 0, 1 (non-finite, not converged)" in footer
    assert any(t.get_text() == "3 failed" for t in alpha.axes[0].texts)
