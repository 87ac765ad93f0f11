"""Eager calls of the entry points run compiled, once per model structure
(jaxfem._eager); structures are compared by content (jaxfem._model.Opaque)."""

import equinox as eqx
import jax
import jax.monitoring
import jax.numpy as jnp
import numpy as np
import pytest

import jaxfem
from benchmarks.frames import frame_bdf
from jaxfem._eager import FAST_COMPILE, KEPT, compiled_when_eager
from jaxfem._model import Opaque
from jaxfem.io import read_bdf_text

COMPILES: list[str] = []  # programs compiled, or loaded from the suite's compilation cache (tests/conftest.py)
jax.monitoring.register_event_duration_secs_listener(
    lambda event, secs, **kw: COMPILES.append(event)
    if event.endswith(("backend_compile_duration", "cache_retrieval_time_sec")) else None)


def _compiles(fn) -> int:
    start = len(COMPILES)
    jax.block_until_ready(jax.tree.leaves(fn()))
    return len(COMPILES) - start


def _frame(nz: int) -> jaxfem.Model:
    return jaxfem.build_model(read_bdf_text(frame_bdf(2, 2, nz, n_groups=2)))


@pytest.fixture(scope="module")
def frames():
    return _frame(2), _frame(2), _frame(3)


def test_structures_compare_by_content(frames):
    (_, a), (_, b), (_, c) = (jaxfem.partition(m) for m in frames)
    assert Opaque(a) == Opaque(b) and hash(Opaque(a)) == hash(Opaque(b))
    assert Opaque(a) != Opaque(c)
    moved = jax.tree.map(np.copy, a)
    moved.xyz[0, 0] += 1e-9  # one coordinate moved by a nanometre: another structure
    assert Opaque(moved) != Opaque(a)


def test_an_equal_structure_compiles_once_and_equals_the_traced_call(frames):
    one, same, other = frames
    lam, phi = jaxfem.modes(one, 4)
    assert _compiles(lambda: jaxfem.modes(same, 4)) == 0  # another model object, equal structure
    assert _compiles(lambda: jaxfem.modes(other, 4)) == 1  # one program, not one per operation
    values, structure = jaxfem.partition(one)
    lam_t, phi_t = jax.jit(lambda v: jaxfem.modes(eqx.combine(v, structure), 4))(values)  # traced in place
    np.testing.assert_allclose(lam, lam_t, rtol=1e-12)
    np.testing.assert_allclose(np.abs(phi), np.abs(phi_t), atol=1e-10 * np.abs(phi).max())
    K, M = jaxfem.assemble(one)
    assert all(isinstance(i, np.ndarray) for i in K.indices + M.indices)  # structure stays NumPy
    assert K.values()[0].dtype == jnp.float64


def test_derivatives_trace_through_the_eager_entry_point(frames):
    model = frames[0]
    f = lambda s: jaxfem.modes(jaxfem.correct(model, [model.element_ids().tolist()], s), 2)[0]  # noqa: E731
    d = jax.jacfwd(f)(jnp.array([0.1]))[:, 0]
    np.testing.assert_allclose(d, f(jnp.array([0.0])), rtol=1e-9)  # λ ∝ (1 + α): dλ/dα = λ(0)


def test_only_the_last_calls_are_kept():
    @compiled_when_eager
    def double(x):
        return 2 * x

    x = [jnp.ones(n) for n in range(1, KEPT + 2)]  # KEPT + 1 shapes
    assert [_compiles(lambda a=a: double(a)) for a in x] == [1] * len(x)
    assert _compiles(lambda: double(x[-1])) == 0
    assert _compiles(lambda: double(x[0])) == 1  # the oldest was released


def test_compiler_options_reach_xla_and_change_no_number(frames):
    """``compiled_when_eager(compiler_options=FAST_COMPILE)`` (the diagnosis' programs run a
    few times) gives the default compilation's modes; an option XLA does not know is refused,
    so the options are passed on."""
    fast = compiled_when_eager(compiler_options=FAST_COMPILE)(lambda m: jaxfem.modes(m, 4))
    lam, phi = fast(frames[0])
    lam_d, phi_d = jaxfem.modes(frames[0], 4)
    assert lam.dtype == jnp.float64
    np.testing.assert_allclose(lam, lam_d, rtol=1e-11)
    np.testing.assert_allclose(phi, phi_d, atol=1e-9 * float(np.abs(phi_d).max()))
    wrong = compiled_when_eager(compiler_options={"xla_no_such_option": 1})(lambda x: 2 * x)
    with pytest.raises(Exception, match="xla_no_such_option"):
        wrong(jnp.ones(3))
