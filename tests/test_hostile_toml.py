"""Hostile parameter files (issue 19): every malformed value refused before any
computation, by a ``ValueError`` naming the file, the key and what was expected; targets
that hold nothing of their kind, duplicate columns and under-determined fits refused or
warned about by name. Found by fuzzing; one regression test per finding, and a property
test of the schema (random TOML values in the keys of a valid file)."""

import json
import math
import re
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

import jaxfem
from benchmarks.frames import frame_bdf
from identification import Sensors, write_uff
from jaxfem.io import read_bdf_text
from updating import simulate_test
from updating._parameters import (KINDS, FieldError, Options, Parameter, ParameterSet, identical_columns,
                                  parameterise)
from updating._solve import update
from updating.cli import app

try:
    import hypothesis
    from hypothesis import strategies as st
except ImportError:  # the property test needs the test extra
    hypothesis = None

VALID = '[[parameter]]\nname = "cols"\nkind = "stiffness"\npids = [1]\n'


def _refused(tmp_path, text: str) -> str:
    path = tmp_path / "params.toml"
    path.write_text(text)
    with pytest.raises(ValueError) as err:
        ParameterSet.from_toml(path)
    message = str(err.value)
    assert str(path) in message, message
    return message


@pytest.mark.parametrize(("text", "key", "expected"), [
    # TypeError / exit 1 before
    (VALID.replace("pids = [1]", "pids = 5"), "parameter[1].pids", "array of property ids"),
    (VALID + "bounds = 5\n", "parameter[1].bounds", "two numbers"),
    ("options = 3\n" + VALID, "options", "a table"),
    (VALID + "[options]\nactive_modes = 5\n", "options.active_modes", "array of test mode numbers"),
    ("parameter = [1, 2]\n", "parameter[1]", "expected a table"),
    (VALID + "[options]\nmax_iterations = 2.5\n", "options.max_iterations", "an integer ≥ 1"),
    # refused only after the whole update had run
    (VALID + "bounds = [0.5]\n", "parameter[1].bounds", "two numbers"),
    (VALID + "bounds = [nan, inf]\n", "parameter[1].bounds", "two finite numbers"),
    (VALID + "bounds = [1.0, -0.5]\n", "parameter[1].bounds", "lower < upper (reversed?)"),
    (VALID + "bounds = [-1.0, 0.5]\n", "parameter[1].bounds", "lower > -1"),
    (VALID + "bounds = [-2.0, 0.5]\n", "parameter[1].bounds", "lower > -1"),
    # "invalid literal for int()" without file or key
    (VALID + '[options]\nactive_modes = "1,2"\n', "options.active_modes", "got '1,2'"),
    # pid 1.7 used as pid 1; a bool as pid 1
    (VALID.replace("pids = [1]", "pids = [1.7]"), "parameter[1].pids", "got [1.7]"),
    (VALID.replace("pids = [1]", "pids = [true]"), "parameter[1].pids", "got [True]"),
    (VALID.replace("pids = [1]", "pids = [0]"), "parameter[1].pids", "integers ≥ 1"),
    # regularisation = nan ended in "(a mechanism)"
    (VALID + "[options]\nregularisation = nan\n", "options.regularisation", "finite number ≥ 0"),
    (VALID + "[options]\nregularisation = -1\n", "options.regularisation", "finite number ≥ 0"),
    (VALID + "[options]\ntolerance = inf\n", "options.tolerance", "finite number > 0"),
    (VALID + "[options]\nmin_mac = 1.5\n", "options.min_mac", "≤ 1"),
    (VALID + "[options]\neigenvalue_weight = true\n", "options.eigenvalue_weight", '"auto" or a finite number'),
    (VALID + "[options]\nmax_iterations = 1000000000000\n", "options.max_iterations", "≤ 100000"),
    (VALID + "[options]\nactive_modes = []\n", "options.active_modes", "non-empty"),
    (VALID + "[options]\nactive_modes = [1, 2]\npassive_modes = [2]\n", "options.passive_modes",
     "also in active_modes"),
    (VALID + '[options]\nsolver = "newton"\n', "options.solver", "'gauss-newton'"),
    (VALID.replace('"cols"', "5"), "parameter[1].name", "non-empty string"),
    (VALID.replace('"stiffness"', '"stifness"'), "parameter[1].kind", "one of 'stiffness'"),
    (VALID + VALID, "parameter[2].name", "'cols' is also the name of parameter[1]"),
    ('[[parameter]]\nname = "x"\npids = [1]\n', "parameter[1].kind", "required"),
    (VALID.replace('"stiffness"', '"m"'), "parameter[1].pids", "kind m (CONM2) targets eids or nodes"),
    (VALID + "nodes = [3]\n", "parameter[1].nodes", "only for kinds k and m"),
    ('[parameter]\nname = "x"\nkind = "stiffness"\npids = [1]\n', "parameter", "array of tables"),
    ("", "no [[parameter]]", "declared"),
    ("[[parameter]\n", "Expected", "line 1"),
])
def test_malformed_values_are_refused_naming_file_and_key(tmp_path, text, key, expected):
    message = _refused(tmp_path, text)
    assert f"params.toml: {key}" in message and expected in message, message


@pytest.mark.parametrize(("text", "key", "near"), [
    (VALID + "bound = [0.0, 1.0]\n", "parameter[1].bound", "'bounds'"),
    (VALID.replace("pids", "pid"), "parameter[1].pid", "'pids'"),
    (VALID + "[options]\nmax_iteration = 3\n", "options.max_iteration", "'max_iterations'"),
    ("[option]\nsolver = 'gauss-newton'\n" + VALID, "option", "'options'"),
])
def test_unknown_keys_are_errors_naming_the_key_and_the_known_ones(tmp_path, text, key, near):
    """A decision: a typo is an error, not a warning, as it was before for whole keys: an
    ignored ``bound`` or ``pid`` would silently change the update."""
    message = _refused(tmp_path, text)
    assert f"params.toml: {key}: unknown key (did you mean {near}?); known keys:" in message, message


def test_not_utf8_names_the_file(tmp_path):
    path = tmp_path / "params.toml"
    path.write_bytes(VALID.encode() + b'# \xff\n')
    with pytest.raises(ValueError, match="params.toml: not UTF-8"):
        ParameterSet.from_toml(path)


def test_a_valid_file_is_read_with_its_types(tmp_path):
    path = tmp_path / "params.toml"
    path.write_text(VALID + "bounds = [-0.5, 1]\n[[parameter]]\nname = \"shakers\"\nkind = \"m\"\nnodes = [8, 12]\n"
                    "[options]\nregularisation = 0\nactive_modes = [1, 2]\npassive_modes = [3]\n"
                    "eigenvalue_weight = 2\nn_model_modes = 12\n")
    pset = ParameterSet.from_toml(path)
    assert pset.parameters[0].bounds == (-0.5, 1.0) and pset.parameters[1].nodes == (8, 12)
    opts = pset.options
    assert opts.regularisation == 0.0 and isinstance(opts.regularisation, float)
    assert opts.active_modes == (1, 2) and opts.passive_modes == (3,) and opts.eigenvalue_weight == 2.0


def test_python_api_runs_the_same_schema():
    """``Parameter`` and ``Options`` built in Python: the same checks (a FieldError, a
    ValueError naming the key); bounds may start at −1 there (an effect's "down to
    nothing"), not in a file."""
    with pytest.raises(FieldError, match=r"parameter 'a': pids: expected .* got \(True,\)"):
        Parameter("a", "stiffness", pids=(True,))
    with pytest.raises(FieldError, match="options: max_iterations: expected an integer"):
        Options(max_iterations=2.5)
    with pytest.raises(FieldError, match="options: regularisation: expected a finite number"):
        Options(regularisation=math.nan)
    assert Parameter("a", "m", eids=np.array([3, 4]), bounds=(-1.0, 10.0)).eids == (3, 4)
    assert Options(passive_modes=[3], regularisation=np.float64(0.5)).passive_modes == (3,)


# --- checks against the model --------------------------------------------------------

PELAS = "CELAS1,5000,77,6,1\nPELAS,77,1.e5\nENDDATA\n"


@pytest.fixture(scope="module")
def frame():
    """The 2×2×2 frame: CBAR eids 1.., PBAR/PBARL pids 1–6, PBUSH 7, PROD 8, a PELAS 77
    spring at grid 6, CONM2 masses at grids 8, 12 (and a sensor grid)."""
    return jaxfem.build_model(read_bdf_text(frame_bdf(2, 2, 2, n_groups=6).replace("ENDDATA\n", PELAS), name="frame"))


@pytest.mark.parametrize(("parameter", "message"), [
    (Parameter("m_bar", "m", eids=(1,)), "'m_bar': eids [1] are not CONM2 masses: nothing for kind m"),
    (Parameter("m_grid", "m", nodes=(8, 5)), "'m_grid': nodes [5] carry no CONM2 mass: nothing for kind m"),
    (Parameter("i1_rod", "I1", pids=(8,)), "'i1_rod': pids [8] are not PBAR/PBARL/PBEAM properties: nothing for kind I1"),
    (Parameter("a_bush", "A", pids=(7,)), "'a_bush': pids [7] are not PBAR/PBARL/PBEAM/PROD properties"),
    (Parameter("e_spring", "E", pids=(77,)), "'e_spring': pids [77] use no MAT1 material (kind E"),
    (Parameter("k_bar", "k", eids=(1,)), "'k_bar': eids [1] are not springs or bushes (CELAS, CBUSH): nothing for kind k"),
    (Parameter("k_pbar", "k", pids=(1,)), "'k_pbar': pids [1] are not PELAS or PBUSH properties"),
    (Parameter("k_grid", "k", nodes=(5,)), "'k_grid': nodes [5] have no spring or bush attached"),
    (Parameter("k_conm2", "stiffness", eids=(22,)), "'k_conm2': eids [22] are CONM2 masses (no stiffness)"),
    (Parameter("m_spring", "mass", pids=(77,)), "'m_spring': pids [77] are used by no element with a mass matrix"),
    (Parameter("m_spring_eid", "mass", eids=(5000,)), "'m_spring_eid': eids [5000] are springs or bushes (no mass)"),
])
def test_parameters_that_target_nothing_are_refused(frame, parameter, message):
    """Before: α stayed 0 and the update reported "converged"."""
    with pytest.raises(ValueError, match="parameter " + re.escape(message)):
        parameterise(frame, [parameter])


def test_parameters_that_target_something_are_kept(frame):
    params = [Parameter("g1", "stiffness", pids=(1,)), Parameter("g1_mass", "mass", pids=(1,)),
              Parameter("spring", "k", pids=(77,)), Parameter("bush", "k", nodes=(900000,)),
              Parameter("masses", "m", nodes=(8, 12)), Parameter("rod", "A", pids=(8,)),
              Parameter("e2", "E", pids=(2,)), Parameter("i1", "I1", pids=(1,))]
    assert len(parameterise(frame, params)[1].parameters) == len(params)


@pytest.mark.parametrize("pair", [
    lambda m: (Parameter("g1", "stiffness", pids=(1,)),  # pid 1, and its elements by eid
               Parameter("first_bars", "stiffness", eids=tuple(m.element_ids(pids=[1]).tolist()))),
    lambda m: (Parameter("e12", "E", pids=(1, 2)), Parameter("e21", "E", pids=(2, 1))),
    lambda m: (Parameter("bush", "k", pids=(7,)), Parameter("bush_eid", "k", eids=tuple(m.bushes.ids.tolist()))),
])
def test_two_parameters_on_the_same_targets_are_named(frame, pair):
    a, b = pair(frame)
    assert identical_columns(frame, [a, Parameter("g2", "stiffness", pids=(2,))]) is None
    assert identical_columns(frame, [a, b]) == (
        f"parameters {a.name!r} and {b.name!r} (kind {a.kind}) scale the same targets: identical Jacobian "
        "columns, only their combined effect is identifiable")


def test_cli_names_the_file_of_a_parameter_that_targets_nothing(frame, tmp_path):
    bdf = tmp_path / "frame.bdf"
    bdf.write_text(frame_bdf(2, 2, 2, n_groups=6).replace("ENDDATA\n", PELAS))
    free = frame.node_ids[(frame.node_ids > 4) & (frame.node_ids < 900000)]
    test = simulate_test(frame, Sensors.from_components(np.repeat(free, 2), np.tile([1, 2], len(free))), 4)
    write_uff(tmp_path / "test.uff", nodes={int(g): np.asarray(x) for g, x in zip(frame.node_ids, frame.xyz)},
              modes=test)
    params = tmp_path / "params.toml"
    params.write_text(VALID + '[[parameter]]\nname = "m_bar"\nkind = "m"\neids = [1]\n')
    result = CliRunner().invoke(app, ["update", str(bdf), str(tmp_path / "test.uff"), "--params", str(params),
                                      "--json", str(tmp_path / "out.json")])
    assert result.exit_code == 2, result.output
    assert "params.toml" in result.stderr and "'m_bar'" in result.stderr and "kind m" in result.stderr
    assert "Traceback" not in result.output and not (tmp_path / "out.json").exists()


# --- under-determination ---------------------------------------------------------------

@pytest.fixture(scope="module")
def measured(frame):
    free = frame.node_ids[(frame.node_ids > 4) & (frame.node_ids < 900000)]
    return simulate_test(frame, Sensors.from_components(np.repeat(free, 2), np.tile([1, 2], len(free))), 4)


SIX = tuple(Parameter(f"g{p}", "stiffness", pids=(p,)) for p in range(1, 7))


def test_more_parameters_than_rows_warns_and_says_so_in_the_result(frame, measured):
    """Before: 6 parameters fitted to 1 residual row reported plain "converged"."""
    opts = Options(residual="eigenvalue", active_modes=(1,), max_iterations=3)
    with pytest.warns(UserWarning, match=r"6 parameters but 1 residual row \(1 active test mode × 1 row, "
                                         r"residual = 'eigenvalue'\): the fit is under-determined"):
        res = update(frame, measured, ParameterSet(SIX, opts))
    assert len(res.warnings) == 1 and "'converged' does not mean identified" in res.warnings[0]
    assert json.loads(json.dumps(res.to_json()))["warnings"] == list(res.warnings)


def test_more_parameters_than_rows_is_refused_for_plain_gauss_newton(frame, measured):
    opts = Options(residual="eigenvalue", active_modes=(1,), solver="gauss-newton")
    with pytest.raises(ValueError, match=r"6 parameters but 1 residual row .* Gauss–Newton has no unique step; "
                                         r"use fewer parameters .* set options.regularisation > 0"):
        update(frame, measured, ParameterSet(SIX, opts))


DUPLICATE = (Parameter("g1", "stiffness", pids=(1,)), Parameter("g1_again", "stiffness", pids=(1,)),
             Parameter("g2", "stiffness", pids=(2,)))


def test_two_parameters_on_the_same_targets_are_refused_for_plain_gauss_newton(frame, measured):
    """Before: "(a mechanism)" and a traceback (identical columns, singular JᵀJ)."""
    with pytest.raises(ValueError, match=r"parameters 'g1' and 'g1_again' \(kind stiffness\) scale the same "
                                         r"targets: .* Gauss–Newton has no unique step; keep one of each pair"):
        update(frame, measured, ParameterSet(DUPLICATE, Options(solver="gauss-newton")))


def test_two_parameters_on_the_same_targets_warn_with_levenberg_marquardt(frame, measured):
    with pytest.warns(UserWarning, match="'g1' and 'g1_again' .* 'converged' does not mean identified"):
        res = update(frame, measured, ParameterSet(DUPLICATE, Options(max_iterations=2)))
    assert len(res.warnings) == 1 and "g1_again" in res.to_json()["warnings"][0]


def test_enough_rows_no_warning(frame, measured):
    opts = Options(residual="combined", max_iterations=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = update(frame, measured, ParameterSet(SIX[:2], opts))
    assert res.warnings == () and res.to_json()["warnings"] == []


# --- property test of the schema -------------------------------------------------------

GOOD = {
    "parameter": [{"name": "cols", "kind": "stiffness", "pids": [1, 2], "bounds": [-0.5, 0.5]},
                  {"name": "shakers", "kind": "m", "nodes": [14]}],
    "options": {"active_modes": [1, 2, 3], "passive_modes": [4], "residual": "combined", "eigenvalue_weight": "auto",
                "regularisation": 0.0, "solver": "gauss-newton", "max_iterations": 10, "tolerance": 1e-3,
                "min_mac": 0.6, "max_freq_dev": 0.3, "n_model_modes": 12, "eigensolver": "auto"},
}
PARAMETER_KEYS = ("name", "kind", "pids", "eids", "nodes", "bounds")


def _toml(value) -> str:
    """``value`` as a TOML inline value (arrays and inline tables nest)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):  # a basic string: quote, backslash and control characters escaped
        return '"' + "".join(f"\\u{ord(c):04x}" if ord(c) < 0x20 or ord(c) == 0x7F or c in '"\\' else c
                             for c in value) + '"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return "{" + ", ".join(f"{_toml(k)} = {_toml(v)}" for k, v in value.items()) + "}"


def _write_with(path, good: dict, place: tuple, value):
    """``good`` as a TOML file with ``value`` at ``place`` (a path of keys and indices)."""
    data = json.loads(json.dumps(good))
    *parents, last = place
    target = data
    for key in parents:
        target = target[key]
    target[last] = value
    path.write_text("".join(f"{k} = {_toml(v)}\n" for k, v in data.items()))
    return path


def _values(words: list[str], keys: list[str]):
    """Random TOML values: integers (int64 and small), floats (nan, inf), bools, short
    strings, ``words``, and arrays and inline tables (keys from ``keys``) of them."""
    scalars = st.one_of(st.integers(-(2 ** 63), 2 ** 63 - 1), st.integers(-3, 30), st.floats(), st.booleans(),
                        st.text(st.characters(exclude_categories=("Cs",)), max_size=6), st.sampled_from(words))
    return st.recursive(scalars, lambda inner: st.one_of(
        st.lists(inner, max_size=3), st.dictionaries(st.sampled_from(keys), inner, max_size=2)), max_leaves=6)


@pytest.mark.skipif(hypothesis is None, reason="needs hypothesis (pip install jaxfem[test])")
def test_schema_property_valid_or_value_error_naming_the_key(tmp_path_factory):
    """A random TOML value in any key of a valid file: either a valid ParameterSet or a
    ValueError naming the file and the key; never another exception."""
    folder = tmp_path_factory.mktemp("hostile")
    values = _values(list(KINDS) + ["auto", "combined", "gauss-newton", "dense"], ["a", "pids", "name"])
    places = ([("parameter",), ("options",)] + [("parameter", i, k) for i in range(2) for k in PARAMETER_KEYS]
              + [("options", k) for k in GOOD["options"]])

    @hypothesis.settings(max_examples=200, deadline=None, database=None,
                         suppress_health_check=[hypothesis.HealthCheck.too_slow])
    @hypothesis.given(place=st.sampled_from(places), value=values)
    def check(place, value):
        path = _write_with(folder / "fuzz.toml", GOOD, place, value)
        try:
            pset = ParameterSet.from_toml(path)
        except ValueError as err:
            message = str(err)
            assert str(path) in message, message
            assert place[-1] in message, (place, message)
            assert ("options" if place[0] == "options" else "parameter") in message, (place, message)
        else:
            assert isinstance(pset, ParameterSet) and len(pset.parameters) == 2

    check()


GOOD_STUDY = {"study": {"model": "tree", "sensors": "tree", "error_pids": [2, 4], "error_alpha": -0.17,
                        "n_modes": [2, 5], "samples": 3, "seed": 0, "chunk_size": 4, "eigensolver": "subspace",
                        "lockstep": 1},
              "errors": {"relative": [0.01, 0.05], "frequency": [0.02]}}


@pytest.mark.parametrize("text, message", [
    ("[study]\nsamples = 2.5", "study.samples: expected an integer ≥ 1, got 2.5"),  # was truncated to 2
    ("[study]\nerror_pids = 5", "study.error_pids: expected a non-empty array of property ids"),  # was TypeError text
    ("[study]\nmodel = 5", "study.model: expected a non-empty string, got 5"),  # was an uncaught TypeError
    ("errors = [1]", "errors: expected a table [errors], got [1]"),  # was an uncaught AttributeError
    ("[errors]\nrelative = [1.5]", "errors.relative: expected a non-empty array of fractions in [0, 1)"),
    ("[errors]\nthermal = [0.1]", "errors.thermal: unknown error category; known: relative, absolute, frequency"),
    ('[study]\nmodelling_error = "a"', "study.modelling_error: expected a model of Table 4.6: 1, 2, 3, got 'a'"),
    ("[study]\nmodelling_error = 1\nerror_pids = [3]", "study.modelling_error: give modelling_error or "
                                                       "error_pids/error_alpha, not both"),
    ("[study]\nsampels = 3", "study.sampels: unknown key (did you mean 'samples'?)"),
    ("[study]\nlockstep = true", "study.lockstep: expected an integer ≥ 1, got True"),
    ("[options]\nmax_iterations = 2.5", "options.max_iterations: expected an integer ≥ 1"),
])
def test_a_monte_carlo_study_file_is_checked_naming_file_and_key(tmp_path, text, message):
    from updating.studies._study import Study

    path = tmp_path / "study.toml"
    path.write_text(text + "\n")
    with pytest.raises(ValueError) as err:
        Study.from_toml(path)
    assert str(err.value) == f"{path}: {message}" or str(err.value).startswith(f"{path}: {message}"), str(err.value)
    result = CliRunner().invoke(app, ["montecarlo", str(path), "--json", str(tmp_path / "mc.json")])
    assert result.exit_code == 2 and message in result.output and "Traceback" not in result.output, result.output


@pytest.mark.skipif(hypothesis is None, reason="needs hypothesis (pip install jaxfem[test])")
def test_study_schema_property_valid_or_value_error_naming_the_key(tmp_path_factory):
    """A random TOML value in any key of a valid Monte-Carlo study: a Study or a ValueError
    naming the file and the key; never another exception."""
    from updating.studies._study import Study

    folder = tmp_path_factory.mktemp("study")
    values = _values(["tree", "sparse", "relative"], ["relative", "samples"])
    places = [("study",), ("errors",)] + [(table, k) for table in GOOD_STUDY for k in GOOD_STUDY[table]]

    @hypothesis.settings(max_examples=150, deadline=None, database=None,
                         suppress_health_check=[hypothesis.HealthCheck.too_slow])
    @hypothesis.given(place=st.sampled_from(places), value=values)
    def check(place, value):
        path = _write_with(folder / "fuzz.toml", GOOD_STUDY, place, value)
        try:
            study = Study.from_toml(path)
        except ValueError as err:
            message = str(err)
            assert str(path) in message and place[-1] in message, (place, message)
        else:
            assert isinstance(study, Study) and study.samples >= 1

    check()
