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
