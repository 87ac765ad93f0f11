"""Compiled functions that are released with their owner.

XLA-CPU maps every compiled kernel into memory pages of its own (a few hundred maps for
one updating step). ``eqx.filter_jit`` and jax keep compiled code for the whole process,
so every update or diagnosis of a new model structure adds maps that are never returned,
and past Linux's ``vm.max_map_count`` (65530) the next compilation crashes the process
(SIGSEGV; a long test run or a notebook that diagnoses a few models). Updating and
diagnosis compile for one model structure at a time: they hold their functions in a
:class:`Compiled` and the code is freed with it.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax


class Compiled:
    """``eqx.filter_jit(fn)`` (arrays traced, everything else static and hashable) whose
    compiled code lives only as long as this object."""

    def __init__(self, fn: Callable):
        self._fn = fn
        self._cache: dict = {}

    def __call__(self, *args):
        dynamic, static = eqx.partition(args, eqx.is_array)
        leaves, treedef = jax.tree.flatten(static)
        key = (treedef, tuple(leaves))
        if key not in self._cache:
            out_static = []

            def run(dyn):
                out = self._fn(*eqx.combine(dyn, static))
                dyn_out, st = eqx.partition(out, eqx.is_array)
                out_static.append(st)
                return dyn_out

            run.__name__ = getattr(self._fn, "__name__", "run")  # names the compilation in JAX's logs
            self._cache[key] = (jax.jit(run), out_static)
        jitted, out_static = self._cache[key]
        dyn_out = jitted(dynamic)
        return eqx.combine(dyn_out, out_static[0])
