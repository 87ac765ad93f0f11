"""Strict test configuration: float64, strict dtype promotion, several CPU devices."""

import os

# Several host devices for the sharding tests; no LLVM optimisation of the compiled code:
# compilation dominates the suite's time (measured 22 % less wall time at -O0, results
# equal to rounding). Must be set before JAX starts its backend.
os.environ.setdefault("XLA_FLAGS", "--xla_force_host_platform_device_count=4 --xla_backend_optimization_level=0")

import jax  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")


@pytest.fixture
def key():
    return jax.random.key(0)


def pytest_collection_modifyitems(items):
    """The modules holding slow tests first (each kept whole, so that its module fixtures
    are made once): pytest-xdist hands tests out in this order, and a long test started
    last runs alone while the other worker idles."""
    slow = {item.module for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: item.module not in slow)
