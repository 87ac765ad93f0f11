"""Hostile input (issue 19): every failure a clear message, no data lost silently.

Universal files that are cut short, miss a -1 delimiter, hold an unknown dataset or
binary data that looks like a delimiter; phase-resonance planning on models with
round-off asymmetry and massless rotations; derivatives of frequencies through
rigid-body modes; and the commands' one-line exit-2 messages for bad options and
unwritable outputs.
"""

import json
import re
import struct
import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

import jaxfem
from benchmarks.frames import frame_bdf
from identification import ModalData, Sensors, observation_matrix, read_uff, write_uff
from identification._phase_resonance import appropriate
from jaxfem.io import read_bdf_text
from updating.cli import app

runner = CliRunner()
DELIMITER = "    -1"


# -- universal files -------------------------------------------------------------------


@pytest.fixture
def modes_file(tmp_path):
    """A valid file: units (164), nodes (2411) and four modes (55), as write_uff writes them."""
    rng = np.random.default_rng(0)
    sensors = Sensors.from_components([1, 2, 3], [3, 3, 3])
    modes = ModalData([5.0, 12.0, 20.0, 31.0], rng.normal(size=(3, 4)), sensors)
    path = tmp_path / "modes.uff"
    write_uff(path, nodes={g: np.array([float(g), 0.0, 0.0]) for g in (1, 2, 3)}, modes=modes)
    return path


def _openings(lines: list[str]) -> list[tuple[int, int]]:
    """(1-based line of the opening -1, dataset number) of every dataset of a text file."""
    out, inside = [], False
    for i, line in enumerate(lines):
        if line.rstrip() == DELIMITER:
            if not inside:
                out.append((i + 1, int(lines[i + 1][:6])))
            inside = not inside
    return out


def test_a_good_file_is_read_whole(modes_file):
    data = read_uff(modes_file)
    assert data["modes"].n_modes == 4 and sorted(data["nodes"]) == [1, 2, 3]


def test_a_mangled_line_or_an_overlong_id_names_the_dataset_and_its_line(modes_file):
    """pyuff parses fixed-format lines: a line cut short gives ragged arrays, a 21-digit
    id an integer no array holds; both are named by dataset and line (found by
    benchmarks/fuzz_inputs.py)."""
    lines = modes_file.read_text().split("\n")
    (start, _), = [(line, n) for line, n in _openings(lines) if n == 2411]
    ragged = list(lines)
    ragged[start + 3] = ragged[start + 3][:30]  # the coordinates of the first node cut short
    modes_file.write_text("\n".join(ragged))
    with pytest.raises(ValueError, match=rf"dataset #2 \(type 2411, from line {start}\): its fields have different "
                                         "lengths .*a line of it is malformed"):
        read_uff(modes_file)
    huge = list(lines)
    huge[start + 1] = "123456789012345678901" + huge[start + 1][10:]
    modes_file.write_text("\n".join(huge))
    with pytest.raises(ValueError, match=rf"type 2411, from line {start}\): node_nums .* is not an integer"):
        read_uff(modes_file)


def test_a_truncated_file_names_the_open_dataset_and_its_line(modes_file):
    lines = modes_file.read_text().splitlines(keepends=True)
    line, number = _openings(lines)[-1]  # the last mode
    assert number == 55
    modes_file.write_text("".join(lines[: line + 4]))  # cut inside it
    with pytest.raises(ValueError, match=re.escape(f"dataset 55 that starts at line {line} is not closed by a -1 "
                                                   "line: the file is truncated")):
        read_uff(modes_file)


def test_a_missing_delimiter_names_the_line_outside_any_dataset(modes_file):
    """Without the -1 that closes mode 2, pyuff pairs the delimiters anew: one mode
    vanishes and the rest are shifted. The reader names where the structure breaks."""
    lines = modes_file.read_text().splitlines(keepends=True)
    openings = _openings(lines)
    (start, _), (next_start, _) = openings[3], openings[4]  # the second mode, the third
    del lines[next_start - 2]  # the -1 that closes the second mode
    modes_file.write_text("".join(lines))
    with pytest.raises(ValueError, match=re.escape(f"line {next_start} ('55') lies outside any dataset (after "
                                                   f"dataset 55 that starts at line {start}): a -1 delimiter line "
                                                   "is missing")):
        read_uff(modes_file)


def test_an_unknown_dataset_is_named_with_its_line(modes_file):
    text = modes_file.read_text()
    line = _openings(text.splitlines(keepends=True))[2][0]  # the first mode
    modes_file.write_text(text.replace("\n    55", "\n  9999", 1))
    with pytest.warns(UserWarning, match=re.escape(f"datasets not read, ignored: type 9999 (#3) at line {line};")):
        data = read_uff(modes_file)
    assert data["modes"].n_modes == 3


def _frf_file(path, value: float):
    """One binary 58 record (5 lines, uneven axis) of constant ``value``."""
    from identification import FRFData

    f = np.linspace(1.0, 9.0, 5) ** 1.01
    sensors = Sensors.from_components([1], [3])
    write_uff(path, frfs=FRFData(f, np.full((5, 1, 1), value + 0j), sensors, sensors, "receptance"))
    return path


def test_an_undefined_ordinate_type_names_the_dataset(tmp_path):
    """Record 7 of a 58 with ordinate type 7 (one character changed): pyuff parsed no data
    and read_uff raised KeyError 'x' (found by benchmarks/fuzz_inputs.py, seed 29)."""
    from identification import FRFData

    rng = np.random.default_rng(1)
    path = tmp_path / "frf.uff"
    write_uff(path, frfs=FRFData(np.linspace(1.0, 50.0, 40), rng.normal(size=(40, 1, 1)) + 0j,
                                 Sensors.from_components([1], [3]), Sensors.from_components([1], [3]), "accelerance"))
    lines = path.read_text(encoding="latin-1").split("\n")  # a binary 58b: record 7 is in its ASCII header
    (start, _), = [o for o in _openings(lines) if o[1] == 58]
    record7 = start + 7  # 0-based index of record 7: delimiter, number line, records 1-6 before it
    assert lines[record7].split()[:2] == ["6", "40"], lines[record7]
    lines[record7] = lines[record7].replace("         6", "         7", 1)
    path.write_text("\n".join(lines), encoding="latin-1")
    with pytest.raises(ValueError, match=rf"frf.uff: dataset #\d \(type 58, from line {start}\): record 7's "
                                         r"ordinate data type is 7; UFF 58 defines 2, 4 \(real\) and 5, 6"):
        read_uff(path)


def test_a_truncated_binary_dataset_names_its_line(tmp_path):
    path = _frf_file(tmp_path / "frf.uff", 1.0)
    data = path.read_bytes()
    line = data[: data.index(b"    58b")].count(b"\n")  # the -1 line before it
    path.write_bytes(data[:-40])  # 5 lines × (f, Re, Im) doubles = 120 bytes; 33 of them cut
    with pytest.raises(ValueError, match=re.escape(f"dataset 58b that starts at line {line}: its header gives 120 "
                                                   "bytes of binary data, the file holds 87 after the header: the "
                                                   "file is truncated")):
        read_uff(path)


def test_binary_data_that_looks_like_a_delimiter_splits_nothing_silently(tmp_path):
    """A double whose bytes are '    -1' + newline: pyuff cuts the record there; the
    reader skips binary data by its size, sees pyuff's split differ and names the record."""
    (value,) = struct.unpack("<d", DELIMITER.encode() + b"\n@")
    path = _frf_file(tmp_path / "frf.uff", value)
    data = path.read_bytes()
    line = data[: data.index(b"    58b")].count(b"\n")
    with pytest.raises(ValueError, match=re.escape(f"misses #2 (type 58b, line {line})")):
        read_uff(path)
    assert read_uff(_frf_file(tmp_path / "plain.uff", 1.0))["frfs"].values.shape == (5, 1, 1)


# -- phase-resonance planning ----------------------------------------------------------


def _chain() -> tuple[np.ndarray, np.ndarray]:
    k, m = np.array([3e4, 1e4, 2e4, 1.5e4]), np.array([1.0, 2.0, 0.7, 1.5])
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    return K, np.diag(m)


def test_round_off_asymmetry_is_symmetrised_and_a_real_one_named():
    K, M = _chain()
    noise = 1e-12 * np.max(np.abs(K)) * np.random.default_rng(1).normal(size=K.shape)  # also on the zeros
    exact = appropriate(K, M, 1e-3, [0, 2], n_modes=2)
    rounded = appropriate(K + noise, M, 1e-3, [0, 2], n_modes=2)
    for a, b in zip(exact, rounded):
        np.testing.assert_allclose(a.force, b.force, rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(a.mif, b.mif, rtol=1e-8)
    K[0, 3] = 1.0  # 1 N/m on one side only
    with pytest.raises(ValueError, match=re.escape("K must be symmetric: K[0, 3] = 1 but K[3, 0] = 0")):
        appropriate(K, M, 1e-3, [0])


W, H = 0.02, 0.001
STRIP = "\n".join(  # a lumped-mass cantilever: its rotations have no mass
    [f"GRID,{i + 1},,{0.1 * i:.3f},0.,0." for i in range(11)]
    + [f"CBAR,{i + 1},1,{i + 1},{i + 2},0.,0.,1." for i in range(10)]
    + [f"PBAR,1,1,{W * H:.6e},{W * H**3 / 12:.6e},{H * W**3 / 12:.6e},{W * H**3 / 3:.6e}",
       "MAT1,1,70.E9,,0.33,2700.", "SPC1,1,123456,1"]) + "\n"


def test_appropriate_condenses_massless_rotations(tmp_path):
    bdf = tmp_path / "strip.bdf"
    bdf.write_text(STRIP)
    args = ["appropriate", str(bdf), "--candidates", "11:3,6:3", "--exciters", "1", "--modes", "3",
            "--json", str(tmp_path / "a.json")]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    model = jaxfem.build_model(read_bdf_text(STRIP), spc_set=1)
    expected = np.asarray(jaxfem.frequencies_hz(jaxfem.modes(model, 3)[0]))
    found = [m["natural_frequency_hz"] for m in json.loads((tmp_path / "a.json").read_text())["modes"]]
    np.testing.assert_allclose(found, expected, rtol=1e-7)
    res = runner.invoke(app, args[:3] + ["11:3,6:5"] + args[4:] + ["--method", "lewis_wrisley"])
    assert res.exit_code == 2 and "candidates 6:5 have no mass" in res.output, res.output


# -- derivatives -----------------------------------------------------------------------


@pytest.mark.parametrize("lam", [0.0, -1e-12])
def test_frequency_derivative_is_finite_at_rigid_body_modes(lam):
    assert jax.grad(jaxfem.frequencies_hz)(lam) == 0.0
    np.testing.assert_allclose(jax.grad(jaxfem.frequencies_hz)(4.0), 1 / (8 * np.pi), rtol=1e-14)


def test_gradient_through_a_free_model_is_finite():
    M = jnp.eye(2)

    def total(k):
        K = k * jnp.array([[1.0, -1.0], [-1.0, 1.0]])
        return jnp.sum(jaxfem.frequencies_hz(jaxfem.eigh(K, M)[0]))

    g = jax.grad(total)(1e4)
    np.testing.assert_allclose(g, np.sqrt(2) / (4 * np.pi * np.sqrt(1e4)), rtol=1e-8)  # f = √(2k)/2π


def test_split_under_grad_says_what_to_use():
    K, M = jnp.diag(jnp.array([1.0, 1.0, 2.0])), jnp.eye(3)

    def total(t):
        return jnp.sum(jaxfem.eigh(t * K, M, 2, degenerate="split")[0])

    assert jax.jacfwd(total)(1.0) == pytest.approx(2.0)
    with pytest.raises(NotImplementedError, match=r"forward mode only .* use degenerate='mean'"):
        jax.grad(total)(1.0)


# -- the commands ----------------------------------------------------------------------


@pytest.fixture(scope="module")
def frame(tmp_path_factory):
    """``(dir, model.bdf, test.uff)``: the 2×2×2 frame and four of its own modes."""
    d = tmp_path_factory.mktemp("hostile")
    bdf = d / "frame.bdf"
    bdf.write_text(frame_bdf(2, 2, 2, n_groups=2))
    model = jaxfem.build_model(read_bdf_text(bdf.read_text()))
    lam, phi = jaxfem.eigh(*jaxfem.assemble(model), 4)
    nodes = np.asarray(model.node_ids[4:])
    sensors = Sensors.from_components(np.repeat(nodes, 2), np.tile([1, 2], nodes.size))
    C, _ = observation_matrix(model, sensors)
    test = ModalData(np.asarray(jaxfem.frequencies_hz(lam)), C @ np.asarray(phi), sensors)
    write_uff(d / "test.uff", nodes={int(g): np.asarray(x) for g, x in zip(model.node_ids, model.xyz)}, modes=test)
    return d, bdf, d / "test.uff"


def _one_line_error(res, *named: str) -> None:
    assert res.exit_code == 2, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    errors = [line for line in res.output.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1, res.output
    for text in named:
        assert text in errors[0], errors[0]


@pytest.mark.parametrize("option, value, message", [
    ("--min-mac", "2", "--min-mac 2: must be in (0, 1]"),
    ("--max-freq-dev", "-1", "--max-freq-dev -1: must be a non-negative fraction"),
    ("-n", "0", "-n 0: must be a positive number of model modes"),
    ("-n", "-3", "-n -3: must be a positive number of model modes"),
    ("--max-automac", "nan", "--max-automac nan: must be in (0, 1]"),
])
def test_correlate_refuses_bad_options_before_solving(frame, option, value, message):
    d, bdf, uff = frame
    res = runner.invoke(app, ["correlate", str(bdf), str(uff), "--json", str(d / "c.json"), option, value])
    _one_line_error(res, message)
    assert "DoFs" not in res.output  # refused before the model was read


def test_correlate_on_a_file_missing_a_delimiter_exits_2(frame, tmp_path):
    d, bdf, uff = frame
    lines = uff.read_text().splitlines(keepends=True)
    start = _openings(lines)[3][0]
    cut = tmp_path / "cut.uff"
    cut.write_text("".join(lines[: start - 2] + lines[start - 1:]))  # the -1 closing the first mode
    res = runner.invoke(app, ["correlate", str(bdf), str(cut), "--json", str(tmp_path / "c.json")])
    _one_line_error(res, str(cut), "lies outside any dataset (after dataset 55 that starts at line")


def test_unwritable_outputs_exit_2_naming_the_path(frame, tmp_path):
    d, bdf, uff = frame
    blocker = tmp_path / "file.txt"
    blocker.write_text("")
    res = runner.invoke(app, ["correlate", str(bdf), str(uff), "--json", str(tmp_path / "c.json"),
                              "--plots", str(blocker / "plots")])
    _one_line_error(res, f"cannot write plots to {blocker / 'plots'}")


def test_identify_names_an_unwritable_uff(tmp_path, capsys):
    """pyuff answers a bad path with a bare Exception; ``--uff`` opens the file first."""
    import typer

    from updating.cli._identify import _write_modes

    blocker = tmp_path / "file.txt"
    blocker.write_text("")
    modes = ModalData([5.0], [[1.0]], Sensors.from_components([1], [3]))
    with pytest.raises(typer.Exit) as exit_:
        _write_modes(blocker / "modes.uff", modes)
    assert exit_.value.exit_code == 2
    assert f"error: cannot write {blocker / 'modes.uff'}:" in capsys.readouterr().err
    _write_modes(tmp_path / "new" / "modes.uff", modes)
    assert read_uff(tmp_path / "new" / "modes.uff")["modes"].n_modes == 1


MC_STUDY = """
[study]
modelling_error = 1
n_modes = [3]
samples = 1
chunk_size = 1
[errors]
relative = [0.01]
"""


def test_montecarlo_names_a_chunk_it_cannot_read(tmp_path):
    """A chunk that cannot be read is refused with its directory named, before any update
    runs (a folder in its place here: a truncated .npz also leaves NumPy's file open)."""
    (tmp_path / "s.toml").write_text(MC_STUDY)
    (tmp_path / "mc.chunks" / "chunks" / "n03_0000000.npz").mkdir(parents=True)
    res = runner.invoke(app, ["montecarlo", str(tmp_path / "s.toml"), "--json", str(tmp_path / "mc.json"),
                              "--devices", "1"])
    _one_line_error(res, f"chunks in {tmp_path / 'mc.chunks'}: [Errno 21] Is a directory")


@pytest.mark.parametrize("extra, message", [
    (["--candidates", "5"], "--candidates '5': expected GRID:COMPONENT"),
    (["--candidates", ","], "--candidates ',': expected GRID:COMPONENT"),
    (["--candidates", "5:1", "--kappa", "-1"], "--kappa -1: must be finite and non-negative"),
    (["--candidates", "5:1", "--exciters", "0"], "--exciters 0: must be at least 1"),
])
def test_appropriate_bad_options_exit_2(frame, extra, message):
    d, bdf, _ = frame
    args = ["appropriate", str(bdf), "--json", str(d / "a.json")] + extra
    if "--exciters" not in extra:
        args += ["--exciters", "1"]
    _one_line_error(runner.invoke(app, args), message)


# -- universal files, property-based ---------------------------------------------------

try:
    from hypothesis import given, settings
    from hypothesis import strategies as st
except ImportError:  # pragma: no cover - hypothesis is in the test extra
    given = None

if given is not None:
    _PROPERTY = dict(max_examples=100, deadline=None, database=None)

    @st.composite
    def _modal_files(draw):
        n_nodes = draw(st.integers(1, 5))
        n_modes = draw(st.integers(1, 4))
        ids = draw(st.lists(st.integers(1, 99_999_999), min_size=n_nodes, max_size=n_nodes, unique=True))
        xyz = draw(st.lists(st.tuples(*[st.floats(-100, 100, allow_nan=False)] * 3), min_size=n_nodes,
                            max_size=n_nodes))
        freqs = sorted(draw(st.lists(st.floats(0.1, 1e4), min_size=n_modes, max_size=n_modes, unique=True)))
        shapes = draw(st.lists(st.floats(0.01, 100) | st.floats(-100, -0.01), min_size=n_nodes * n_modes,
                               max_size=n_nodes * n_modes))
        units = draw(st.sampled_from(["SI", {"length": 1000.0, "force": 1.0}]))
        return ids, np.array(xyz), np.array(freqs), np.array(shapes).reshape(n_nodes, n_modes), units

    @settings(**_PROPERTY)
    @given(case=_modal_files())
    def test_written_modes_read_back(tmp_path_factory, case):
        ids, xyz, freqs, shapes, units = case
        path = tmp_path_factory.mktemp("prop") / "m.uff"
        modes = ModalData(freqs, shapes, Sensors.from_components(ids, [3] * len(ids)))
        write_uff(path, nodes=dict(zip(ids, xyz)), modes=modes, units=units)
        back = read_uff(path)
        np.testing.assert_allclose(back["modes"].frequencies_hz, freqs, rtol=1e-5)
        order = [back["modes"].sensors.labels.index(f"{g}+Z") for g in ids]
        np.testing.assert_allclose(back["modes"].shapes[order], shapes, rtol=1e-5)
        for g, x in zip(ids, xyz):
            np.testing.assert_allclose(back["nodes"][g], x, rtol=1e-12, atol=1e-12)

    @settings(**_PROPERTY)
    @given(case=_modal_files(), line=st.integers(0, 10_000), column=st.integers(0, 80),
           char=st.sampled_from(list("0123456789.+-eE ") + ["\x00", "X", "-1"]))
    def test_a_mutated_file_is_read_or_refused_with_its_place(tmp_path_factory, case, line, column, char):
        """One character changed: the file is read (perhaps with a warning) or refused with
        a ValueError naming the file and the dataset or line; never another exception."""
        ids, xyz, freqs, shapes, units = case
        path = tmp_path_factory.mktemp("mut") / "m.uff"
        write_uff(path, nodes=dict(zip(ids, xyz)), modes=ModalData(freqs, shapes, Sensors.from_components(
            ids, [3] * len(ids))), units=units)
        lines = path.read_text().split("\n")
        i = line % len(lines)
        lines[i] = lines[i][:column] + char + lines[i][column + 1:]
        path.write_text("\n".join(lines))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            try:
                read_uff(path)
            except ValueError as err:
                assert str(path) in str(err) and re.search(r"dataset|line", str(err)), str(err)


def test_the_fuzz_harness_finds_nothing_uncaught_or_lost_in_a_short_run(capsys):
    """A short run of ``benchmarks/fuzz_inputs.py`` (the acceptance run has ≥ 5,000
    mutants per reader): every mutant ends in a result, a warning or a located error."""
    from benchmarks.fuzz_inputs import main

    assert main(["--bdf", "30", "--uff", "60", "--csv", "60", "--seed", "7"]) == 0
    out = capsys.readouterr().out
    for title, n in (("bulk data", 30), ("universal files", 60), ("sensor lists", 60)):
        assert f"{title}: {n} mutants" in out, out
    for outcome in ("unlocated", "lost", "uncaught"):
        assert re.findall(rf"^  {outcome}\s+(\d+)$", out, re.MULTILINE) == ["0", "0", "0"], out
