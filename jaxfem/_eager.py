"""Eager calls of jaxfem's entry points compiled whole.

Called outside ``jit``, JAX runs a function one operation at a time and compiles every
operation for every new shape: assembling a shell model and solving its modes compiled
some 400 small programs (measured: 19 s of a 26 s test). :func:`compiled_when_eager`
compiles the whole call instead, once per model structure and array shapes, and keeps
the last :data:`KEPT` of them per function (compiled code is mapped memory, see
``updating._compiled``). Under a transformation (``jit``, ``grad``, ``vmap``) the
function is traced in place as before.
"""

from __future__ import annotations

import functools
from collections import OrderedDict
from collections.abc import Callable

import equinox as eqx
import jax

from ._model import Opaque

KEPT = 8  # compiled calls kept per function
FAST_COMPILE = {"xla_backend_optimization_level": 0, "xla_cpu_use_fusion_emitters": False}
"""XLA options for programs run a few times per model: compiled faster, each run slower
(an updating step 1.7×, an assembly of 33k DoFs 1.8×); the test suite compiles everything so."""


def _is_jax(x) -> bool:
    return isinstance(x, jax.Array)


def jit_over(fn: Callable, static, name: str | None = None, compiler_options: dict | None = None) -> Callable:
    """``jax.jit`` of ``fn(*args, **kwargs)`` over the dynamic part of its arguments,
    ``static`` (the rest of ``(args, kwargs)``, as from ``eqx.partition``) bound: the
    returned function maps the dynamic part to ``fn``'s result, whose JAX arrays come out
    of the compiled call and whose other values are those of the trace; ``compiler_options``:
    XLA's (as :data:`FAST_COMPILE`)."""
    out_static = []

    def run(dyn):
        a, kw = eqx.combine(dyn, static)
        dyn_out, st = eqx.partition(fn(*a, **kw), _is_jax)
        out_static.append(st)
        return dyn_out

    run.__name__ = name or getattr(fn, "__name__", "run")  # names the compilation in JAX's logs
    jitted = jax.jit(run, compiler_options=compiler_options)
    return lambda dyn: eqx.combine(jitted(dyn), out_static[0])


def compiled_when_eager(fn: Callable | None = None, *, compiler_options: dict | None = None) -> Callable:
    """``fn`` whose eager calls run compiled (:func:`jit_over`): JAX arrays among the
    arguments are traced, everything else (NumPy structure, Python numbers and strings)
    is static, hashed by content (:class:`~jaxfem._model.Opaque`). As
    ``@compiled_when_eager(compiler_options=...)``, compiled with those XLA options."""
    if fn is None:
        return functools.partial(compiled_when_eager, compiler_options=compiler_options)
    cache: OrderedDict = OrderedDict()

    @functools.wraps(fn)
    def call(*args, **kwargs):
        dynamic, static = eqx.partition((args, kwargs), _is_jax)
        leaves = jax.tree.leaves(dynamic)
        if any(isinstance(x, jax.core.Tracer) for x in leaves):
            return fn(*args, **kwargs)
        key = (Opaque(static), tuple((x.shape, x.dtype) for x in leaves))
        if key in cache:
            cache.move_to_end(key)
        else:
            cache[key] = jit_over(fn, static, compiler_options=compiler_options)
            while len(cache) > KEPT:
                cache.popitem(last=False)
        return cache[key](dynamic)

    return call
