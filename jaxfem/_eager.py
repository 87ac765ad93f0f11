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


def _is_jax(x) -> bool:
    return isinstance(x, jax.Array)


def compiled_when_eager(fn: Callable) -> Callable:
    """``fn`` whose eager calls run compiled: JAX arrays among the arguments are traced,
    everything else (NumPy structure, Python numbers and strings) is static, hashed by
    content; NumPy arrays and other non-JAX values in the result are returned as traced."""
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
            out_static = []

            def run(dyn):
                a, kw = eqx.combine(dyn, static)
                out = fn(*a, **kw)
                dyn_out, st = eqx.partition(out, _is_jax)
                out_static.append(st)
                return dyn_out

            run.__name__ = fn.__name__
            cache[key] = (jax.jit(run), out_static)
            while len(cache) > KEPT:
                cache.popitem(last=False)
        jitted, out_static = cache[key]
        return eqx.combine(jitted(dynamic), out_static[0])

    return call
