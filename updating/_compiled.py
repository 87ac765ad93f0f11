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

from jaxfem import jit_over


class Compiled:
    """``eqx.filter_jit(fn)`` (arrays traced, everything else static and hashable) whose
    compiled code lives only as long as this object; ``compiler_options``: XLA's
    (:data:`jaxfem.FAST_COMPILE` for a program run a few times)."""

    def __init__(self, fn: Callable, compiler_options: dict | None = None):
        self._fn, self._options = fn, compiler_options
        self._cache: dict = {}

    def __call__(self, *args):
        dynamic, static = eqx.partition(args, eqx.is_array)
        leaves, treedef = jax.tree.flatten(static)
        key = (treedef, tuple(leaves))
        if key not in self._cache:
            self._cache[key] = jit_over(self._fn, (static, {}), compiler_options=self._options)
        return self._cache[key]((dynamic, {}))
