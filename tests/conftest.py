"""Strict test configuration: float64, strict dtype promotion, several CPU devices."""

import atexit
import os
import shutil
import tempfile

# Several host devices for the sharding tests; no LLVM optimisation of the compiled code
# and XLA's older fusion emitters (FAST_COMPILE), which compile faster: compilation
# dominates the suite's time (79 % of the non-slow tests' worker-seconds, 2026-11-28;
# 22 % less wall time at -O0; a diagnosis of the 102-DoF frame then compiled in 28 s
# instead of 44 s without the new emitters; results equal to rounding). Under xdist (one
# worker per core) each worker computes on one thread: two workers' thread pools
# oversubscribe the cores (tests/test_diagnose.py on 2 cores: 857 → 738 worker-seconds).
# Must be set before JAX and the BLAS libraries start.
FAST_COMPILE = "--xla_backend_optimization_level=0 --xla_cpu_use_fusion_emitters=false"
ONE_THREAD = {"XLA_FLAGS": "--xla_cpu_multi_thread_eigen=false",
              "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
WORKER = "PYTEST_XDIST_WORKER" in os.environ
os.environ.setdefault("XLA_FLAGS", f"--xla_force_host_platform_device_count=4 {FAST_COMPILE}"
                      + (" " + ONE_THREAD["XLA_FLAGS"] if WORKER else ""))
if WORKER:
    for var, value in ONE_THREAD.items():
        os.environ.setdefault(var, value)
# One persistent compilation cache for the run (this process, its xdist workers and the
# barrel tests' subprocesses inherit it): a program that one test compiled is loaded, not
# compiled again, by the next test that builds the same one (each diagnosis, update and
# study compiles its own functions, see updating._compiled). Removed when the run ends.
if not WORKER and "JAX_COMPILATION_CACHE_DIR" not in os.environ:
    os.environ["JAX_COMPILATION_CACHE_DIR"] = tempfile.mkdtemp(prefix="jaxfem-tests-xla-")
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.1")
    atexit.register(shutil.rmtree, os.environ["JAX_COMPILATION_CACHE_DIR"], ignore_errors=True)

import jax  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

if WORKER:
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)  # NumPy's and SciPy's BLAS, if loaded before this file


def pytest_collection_modifyitems(items):
    """The long end-to-end tests first, the longest (``slow(seconds=…)``, measured) before
    them: under xdist they start at once on every worker and the short tests fill in
    behind them, instead of one long test holding the run's end."""

    def order(item):
        slow = item.get_closest_marker("slow")
        return (0, -slow.kwargs.get("seconds", 0)) if slow else (1, 0)

    items.sort(key=order)


@pytest.fixture
def key():
    return jax.random.key(0)
