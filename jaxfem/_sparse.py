"""Sparse storage of element-stacked matrices and sparse direct factorisations (host side).

The sparsity structure of K and M is fixed by the model (NumPy): :func:`pattern` merges
the scatter indices of both :class:`jaxfem.ElementMatrix` into one symmetric CSR
pattern and maps every element-block entry to its slot, so that ``K − σM`` is one
vector operation on the CSR values. Nothing here is an n × n array. The values come from
the traced element blocks of :func:`jaxfem.assemble`; they enter through
``jax.pure_callback`` (:mod:`jaxfem._shift_invert`), which is why this module is NumPy.

Factorisations of ``K − σM``, by library:

- ``"pardiso"``: Intel MKL PARDISO through the optional package ``pypardiso``
  (``pip install "jaxfem[sparse]"``): Cholesky (``mtype`` 2) for σ below the spectrum,
  Bunch–Kaufman LDLᵀ (``mtype`` −2) otherwise (it preconditions an iteration that
  converges to the exact solution, so the rare perturbed pivot costs a sweep, not accuracy).
- ``"superlu"``: SciPy's SuperLU with the MMD ordering of AᵀA + A and symmetric mode,
  needing nothing beyond SciPy; partial pivoting for a shift inside the spectrum.

``"auto"`` takes PARDISO where it is installed and SuperLU otherwise, with a warning.
Factorisations are cached by their matrix values (an exact comparison), so the
eigensolver and its derivative rule share one.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import os
import sys
import threading
import warnings
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

BACKENDS = ("auto", "pardiso", "superlu")


@dataclass(frozen=True, eq=False)  # compared and hashed by identity (a static field of jitted code)
class SparsePattern:
    """Symmetric CSR pattern of n × n matrices assembled from element blocks.

    ``key`` is a digest of the element indices; ``slots[i]`` maps the entries of block array i (flattened) to CSR positions, ``nnz``
    for padding; ``upper`` selects the entries with column ≥ row (PARDISO's half), whose
    CSR structure is ``upper_indptr``, ``upper_indices``.
    """

    key: str
    n: int
    indptr: np.ndarray
    indices: np.ndarray
    slots: tuple[np.ndarray, ...]
    upper: np.ndarray
    upper_indptr: np.ndarray
    upper_indices: np.ndarray

    @property
    def nnz(self) -> int:
        return len(self.indices)

    def values(self, blocks, slots) -> np.ndarray:
        """CSR values of the sum of element blocks, each block array with its ``slots``."""
        out = np.zeros(self.nnz + 1)
        for slot, blk in zip(slots, blocks):
            out += np.bincount(slot, weights=np.asarray(blk, dtype=np.float64).reshape(-1), minlength=self.nnz + 1)
        return out[: self.nnz]

    def matrix(self, data: np.ndarray) -> scipy.sparse.csr_matrix:
        return scipy.sparse.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


def stacked(*mats) -> scipy.sparse.csr_matrix:
    """The CSR matrices one below the other, so that one product gives all."""
    return scipy.sparse.vstack(mats, format="csr")


_POOL = None
_CHUNK = 32  # columns per task of :func:`matmul` (SciPy's CSR × dense is fastest on narrow blocks)


def matmul(a: scipy.sparse.csr_matrix, x: np.ndarray) -> list[np.ndarray]:
    """``a @ x`` of a :func:`stacked` matrix, split back into its n-row blocks; the columns
    in blocks of :data:`_CHUNK` on a thread per core (SciPy's products release the GIL and
    are single-threaded)."""
    global _POOL
    from concurrent.futures import ThreadPoolExecutor

    if _POOL is None:
        _POOL = ThreadPoolExecutor(max(1, min(8, os.cpu_count() or 1)))
    starts = range(0, x.shape[1], _CHUNK)
    parts = list(_POOL.map(lambda i: a @ np.ascontiguousarray(x[:, i:i + _CHUNK]), starts))
    y = np.concatenate(parts, axis=1) if parts else np.zeros((a.shape[0], 0))
    n = a.shape[1]
    return [y[i:i + n] for i in range(0, a.shape[0], n)]


_PATTERNS: dict[str, SparsePattern] = {}
_PATTERN_CACHE = 4
_LOCK = threading.RLock()  # callbacks of several devices (shard_map) may run at once


def _digest(arrays) -> str:
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str(a.shape).encode())
        h.update(a.data)
    return h.hexdigest()


def pattern(indices: tuple[np.ndarray, ...], n: int) -> SparsePattern:
    """The pattern of the element blocks scattered at ``indices`` (each (n_el, w), ``n`` =
    padding), cached by content (the callers keep it alive as long as they need it)."""
    key = _digest(indices) + f":{n}"
    with _LOCK:
        if key not in _PATTERNS:
            _PATTERNS[key] = _pattern(key, indices, n)
            while len(_PATTERNS) > _PATTERN_CACHE:
                _PATTERNS.pop(next(iter(_PATTERNS)))
        return _PATTERNS[key]


def _pattern(key, indices, n) -> SparsePattern:
    pieces, seen = [], {}  # K and M often share index arrays: one code array each
    for idx in indices:
        tag = _digest([idx])
        if tag not in seen:
            idx = np.asarray(idx, dtype=np.int64)
            rows = np.broadcast_to(idx[:, :, None], idx.shape + idx.shape[1:2]).reshape(-1)
            cols = np.broadcast_to(idx[:, None, :], idx.shape[:1] + idx.shape[1:2] + idx.shape[1:2]).reshape(-1)
            seen[tag] = np.where((rows < n) & (cols < n), rows * (n + 1) + cols, -1)
        pieces.append(seen[tag])
    # the diagonal always: K − σM then has a stored entry on every row
    codes = np.unique(np.concatenate([np.concatenate([p[p >= 0] for p in pieces]), np.arange(n) * (n + 2)]))
    rows, cols = np.divmod(codes, n + 1)
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
    found = {}
    for p in pieces:
        if id(p) not in found:
            found[id(p)] = np.where(p >= 0, np.searchsorted(codes, p), len(codes))
    slots = tuple(found[id(p)] for p in pieces)
    upper = np.flatnonzero(cols >= rows)
    upper_indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows[upper], minlength=n), out=upper_indptr[1:])
    return SparsePattern(key, n, indptr, cols.astype(np.int32), slots, upper, upper_indptr.astype(np.int32),
                         cols[upper].astype(np.int32))


class _Factor:
    """A factorisation of ``A = K − σM``: ``solve(b)`` for b (n,) or (n, k)."""

    backend: str
    memory: int  # bytes held by the factor (an estimate)

    def solve(self, b: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class _SuperLU(_Factor):
    backend = "superlu"

    def __init__(self, pat: SparsePattern, data: np.ndarray, definite: bool):
        a = pat.matrix(data).tocsc()
        self._lock = threading.Lock()
        try:
            if definite:
                self._lu = scipy.sparse.linalg.splu(a, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                                    options={"SymmetricMode": True})
            else:
                self._lu = scipy.sparse.linalg.splu(a, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.01)
        except RuntimeError as e:  # "Factor is exactly singular"
            raise _singular(str(e)) from None
        self.memory = 12 * (self._lu.L.nnz + self._lu.U.nnz)
        pivots = self._lu.U.diagonal()
        scale = float(np.abs(a.diagonal()).max(initial=0.0))
        if definite and not (pivots > 1e-13 * scale).all():
            raise _singular(f"smallest pivot {pivots.min():.3g}, largest diagonal {scale:.3g}")

    def solve(self, b):
        with self._lock:
            return self._lu.solve(np.asarray(b, dtype=np.float64))


class _Pardiso(_Factor):
    """MKL PARDISO called through the ctypes function that ``pypardiso`` finds (its wrapper
    copies the index arrays and checks the matrix on every solve; here they are kept). A
    factor holds its own handle, iparm and permutation arrays."""

    backend = "pardiso"

    def __init__(self, pat: SparsePattern, data: np.ndarray, definite: bool):
        self._pardiso, self._pt_ctype, pt_type = _mkl_pardiso()
        self._pt = np.zeros(64, dtype=pt_type)
        self._iparm = np.zeros(64, dtype=np.int32)
        self._perm = np.zeros(0, dtype=np.int32)
        self._mtype = 2 if definite else -2
        self._lock = threading.Lock()
        self._n = pat.n
        self._data = np.ascontiguousarray(data[pat.upper])
        self._ia = pat.upper_indptr.astype(np.int32) + 1  # one-based
        self._ja = pat.upper_indices.astype(np.int32) + 1
        self._iparm[0] = 1  # iparm given here; the others zero = defaults
        self._iparm[1] = 2  # nested dissection ordering (METIS)
        self._iparm[7] = 0  # no iterative refinement: 5× the solve time; the callers' iterations correct
        self._iparm[9] = 13 if definite else 8  # pivot perturbation 1e-13 / 1e-8 (indefinite)
        try:
            self._call(12, np.zeros((pat.n, 1), order="F"))
        except Exception as e:  # PyPardisoError: zero pivot, not positive definite (its memory freed by __del__)
            raise _singular(str(e)) from None
        self.memory = 1024 * int(max(self._iparm[14], self._iparm[15] + self._iparm[16]))

    def _call(self, phase: int, b: np.ndarray) -> np.ndarray:
        import ctypes

        import pypardiso

        x = np.zeros_like(b)
        error = ctypes.c_int32(0)
        i32, f64 = ctypes.POINTER(ctypes.c_int32), ctypes.POINTER(ctypes.c_double)
        self._pardiso(self._pt.ctypes.data_as(ctypes.POINTER(self._pt_ctype)),
                      ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(1)),
                      ctypes.byref(ctypes.c_int32(self._mtype)), ctypes.byref(ctypes.c_int32(phase)),
                      ctypes.byref(ctypes.c_int32(self._n)), self._data.ctypes.data_as(f64),
                      self._ia.ctypes.data_as(i32), self._ja.ctypes.data_as(i32), self._perm.ctypes.data_as(i32),
                      ctypes.byref(ctypes.c_int32(b.shape[1])), self._iparm.ctypes.data_as(i32),
                      ctypes.byref(ctypes.c_int32(0)), b.ctypes.data_as(f64), x.ctypes.data_as(f64),
                      ctypes.byref(error))
        if error.value != 0:
            raise pypardiso.pardiso_wrapper.PyPardisoError(error.value)
        return x

    def solve(self, b):
        b = np.asarray(b, dtype=np.float64)
        with self._lock:  # one PARDISO handle is not reentrant; XLA may run two callbacks at once
            x = self._call(33, np.asfortranarray(b.reshape(b.shape[0], -1)))
        return np.ascontiguousarray(x).reshape(b.shape)

    def __del__(self):
        if getattr(self, "_pt", None) is not None and not sys.is_finalizing():  # MKL may be gone at exit
            try:
                self._call(-1, np.zeros((self._n, 1), order="F"))  # release PARDISO's memory
            except Exception:
                pass


@functools.cache
def _mkl_pardiso():
    """MKL's ``pardiso`` (ctypes, argument types set) and the handle's integer type (ctypes,
    NumPy), found once: ``pypardiso.PyPardisoSolver()`` searches for the library at every
    construction (a recursive glob of the environment: 1.4 s measured)."""
    import pypardiso

    s = pypardiso.PyPardisoSolver()
    return s._mkl_pardiso, *s._pt_type


def _singular(detail: str) -> ValueError:
    return ValueError(
        "K − σM is singular or not positive definite: the structure has a mechanism (DoFs "
        "without stiffness that the shift does not cover, e.g. massless DoFs without stiffness), a "
        f"negative stiffness, or NaN/inf values ({detail})"
    )


_warned = False


def resolve_backend(backend: str, quiet: bool = False) -> str:
    """``"auto"`` → PARDISO if ``pypardiso`` imports, SuperLU otherwise (warned once, unless
    ``quiet``)."""
    global _warned
    if backend not in BACKENDS:
        raise ValueError(f"sparse backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "superlu":
        return backend
    try:
        importlib.import_module("pypardiso")
    except ImportError as err:  # not installed, or its MKL library not found
        if backend == "pardiso":
            raise ImportError(f"backend 'pardiso' needs pypardiso and MKL: pip install 'jaxfem[sparse]' ({err})") from None
        if not (_warned or quiet):
            _warned = True
            warnings.warn(f"pypardiso cannot be used ({err}): the sparse eigensolver factorises with SciPy's "
                          "SuperLU (slower on large models; pip install 'jaxfem[sparse]' for MKL PARDISO)",
                          stacklevel=3)
        return "superlu"
    return "pardiso"


_FACTORS: OrderedDict = OrderedDict()
_FACTOR_MEMORY = 0.25  # fraction of physical memory that cached factors may hold


def _memory_budget() -> float:
    try:
        return _FACTOR_MEMORY * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 4 * 2.0**30


def factor(pat: SparsePattern, backend: str, k_data: np.ndarray, m_data: np.ndarray, sigma: float) -> _Factor:
    """The factorisation of K − σM (CSR values on ``pat``), cached by value."""
    with _LOCK:
        return _factor(pat, backend, k_data, m_data, sigma)


def _factor(pat, backend, k_data, m_data, sigma):
    tag = (pat.key, backend, float(sigma), k_data.shape, float(k_data @ _probe(len(k_data))),
           float(m_data @ _probe(len(m_data))))
    hit = _FACTORS.get(tag)
    if hit is not None and np.array_equal(hit[1], k_data) and np.array_equal(hit[2], m_data):
        _FACTORS.move_to_end(tag)
        return hit[0]
    f = new_factor(pat, backend, k_data - sigma * m_data, definite=sigma < 0)
    budget = _memory_budget()
    while _FACTORS and sum(v[0].memory for v in _FACTORS.values()) + f.memory > budget:
        _FACTORS.popitem(last=False)
    _FACTORS[tag] = (f, k_data.copy(), m_data.copy())
    return f


def clear_factors() -> None:
    """Empty the cache of factorisations kept by :func:`factor` (timings of a fresh factor)."""
    with _LOCK:
        _FACTORS.clear()


def new_factor(pat: SparsePattern, backend: str, data: np.ndarray, *, definite: bool) -> _Factor:
    """A factorisation of the matrix with CSR values ``data`` on ``pat`` (not cached):
    Cholesky if ``definite``, else a symmetric indefinite (PARDISO) or pivoted (SuperLU) one."""
    return (_Pardiso if backend == "pardiso" else _SuperLU)(pat, data, definite)


_PROBES: dict[int, np.ndarray] = {}


def _probe(n: int) -> np.ndarray:
    """A fixed random vector: a fingerprint ``values @ probe`` finds cached factors fast."""
    if n not in _PROBES:
        _PROBES.clear()
        _PROBES[n] = np.random.default_rng(12345).random(n)
    return _PROBES[n]
