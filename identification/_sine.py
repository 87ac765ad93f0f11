"""A damped model under sine excitation: damping matrix, receptance, responses, MIF; thesis §3.4.

A damped structure ``Mü + Du̇ + Ku = f̂ e^{iωt}`` (eq. 3.47) under a force with all
components in phase (eq. 3.48) answers with ``û e^{iωt}`` (eq. 3.49), ``û = H(ω) f̂``
(eq. 5.4), ``H(ω) = (K − ω²M + iωD)⁻¹`` (eq. 5.3), D given as a matrix, a stiffness
factor or Rayleigh ``μM + κK`` (eq. 1.29); the Mode Indicator Function (eq. 3.54) is 1000
for a pure normal-mode response and 0 for one in phase with the force. Also the input
checks (K, M, D, DoF indices, counts) shared by :mod:`identification._forces` and
:mod:`identification._phase_resonance`. NumPy in float64/complex128, DoF indices 0-based.
"""

from __future__ import annotations

import operator
from collections.abc import Mapping

import numpy as np
from jaxtyping import Complex, Float


# --------------------------------------------------------------------------- validation


def _real_array(name: str, x, ndim: int | None = None) -> np.ndarray:
    arr = np.asarray(x)
    if np.iscomplexobj(arr):
        raise ValueError(f"{name} must be real, got a complex array")
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name} must be numeric, got dtype {arr.dtype}")
    arr = arr.astype(np.float64)
    if ndim is not None and arr.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} has non-finite entries")
    return arr


def _complex_array(name: str, x, ndim: int) -> np.ndarray:
    arr = np.asarray(x)
    if not (np.issubdtype(arr.dtype, np.number)):
        raise ValueError(f"{name} must be numeric, got dtype {arr.dtype}")
    arr = arr.astype(np.complex128)
    if arr.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    if arr.size == 0:
        raise ValueError(f"{name} is empty (shape {arr.shape})")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} has non-finite entries")
    return arr


def _square(name: str, a, n: int | None = None) -> np.ndarray:
    a = _real_array(name, a, 2)
    if a.shape[0] != a.shape[1] or a.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty square matrix, got shape {a.shape}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name} has shape {a.shape} but K is {n}×{n}")
    return a


def _indices(name: str, idx, n: int, *, allow_empty: bool = False) -> np.ndarray:
    arr = np.asarray(idx)
    if arr.ndim != 1 or (arr.shape[0] == 0 and not allow_empty):
        raise ValueError(f"{name} must be a non-empty 1-D sequence of DoF indices, got shape {arr.shape}")
    if arr.size and not np.issubdtype(arr.dtype, np.integer):
        raise ValueError(f"{name} must hold integer DoF indices (0-based), got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    bad = arr[(arr < 0) | (arr >= n)]
    if bad.size:
        raise ValueError(f"{name}: DoF index {bad[0]} is out of range 0..{n - 1}")
    if len(np.unique(arr)) != len(arr):
        raise ValueError(f"{name} lists a DoF twice: {arr.tolist()}")
    return arr


def _count(name: str, x) -> int:
    """``x`` as a Python int (bool and floats refused)."""
    try:
        value = operator.index(x)
    except TypeError:
        value = None
    if value is None or x is True or x is False:
        raise ValueError(f"{name} must be an integer, got {x!r}")
    return value


def _system(K, M, damping):
    K = _square("K", K)
    n = K.shape[0]
    M = _square("M", M, n)
    D = damping_matrix(K, M, damping)
    for name, a in (("K", K), ("M", M), ("D", D)):
        if not np.allclose(a, a.T, rtol=1e-10, atol=0.0):
            raise ValueError(f"{name} must be symmetric")
    return K, M, D


def damping_matrix(K, M, damping) -> Float[np.ndarray, "n n"]:
    """Viscous damping matrix D (N·s/m) from a damping specification.

    **Arguments:** ``K`` (N/m), ``M`` (kg) as n×n arrays; ``damping`` one of

    - an n×n array: D itself;
    - a number κ (s): stiffness-proportional ``D = κK`` (thesis §5.4.1 uses κ = 10⁻³ s);
    - a mapping ``{"mu": μ, "kappa": κ}`` (either may be left out): Rayleigh
      ``D = μM + κK``, thesis eq. 1.29.

    **Returns:** D, float64 n×n.
    """
    K = _square("K", K)
    M = _square("M", M, K.shape[0])
    if isinstance(damping, Mapping):
        unknown = set(damping) - {"mu", "kappa"}
        if unknown:
            raise ValueError(f"damping mapping takes keys 'mu' and 'kappa', got {sorted(unknown)}")
        mu = _real_array("damping['mu']", damping.get("mu", 0.0), 0)
        kappa = _real_array("damping['kappa']", damping.get("kappa", 0.0), 0)
        return float(mu) * M + float(kappa) * K  # eq. 1.29
    arr = np.asarray(damping)
    if arr.ndim == 0:
        return float(_real_array("damping", arr, 0)) * K
    return _square("damping matrix D", arr, K.shape[0])


# --------------------------------------------------------------------------- MIF, responses


def mode_indicator(
    u: Complex[np.ndarray, "*batch n"], weights: Float[np.ndarray, " n"] | None = None
) -> Float[np.ndarray, "*batch"]:
    """Mode Indicator Function ×1000, thesis eq. 3.54 with footnote 3.

    ``MIF = 1000 · (1 − Σ_m w_m |Re û_m| |û_m| / Σ_m w_m |û_m|²)``: 1000 for a pure
    normal-mode (quadrature) response, 0 for a response entirely in phase with the force.
    The thesis' eq. 3.54 is unweighted (``weights=None``); passing the DoF masses gives
    the mass-weighted form of the indicator's origin, Breitbach (1973) (thesis ref. [15]).

    **Arguments:** ``u`` complex responses at the n measured DoFs (last axis; leading axes
    are a batch); ``weights`` (n,) non-negative, e.g. the lumped masses.

    **Returns:** MIF in [0, 1000], shape of ``u`` without its last axis.
    """
    u = np.asarray(u)
    if u.ndim == 0 or u.shape[-1] == 0:
        raise ValueError(f"u must have the measured DoFs on its last axis, got shape {u.shape}")
    u = _complex_array("u", u, u.ndim)
    w = np.ones(u.shape[-1]) if weights is None else _real_array("weights", weights, 1)
    if w.shape != (u.shape[-1],):
        raise ValueError(f"weights must have shape ({u.shape[-1]},), got {w.shape}")
    if np.any(w < 0):
        raise ValueError("weights must be non-negative")
    mag = np.abs(u)
    den = np.sum(w * mag**2, axis=-1)
    if np.any(den <= 0):
        raise ValueError("u has no (weighted) response: MIF undefined")
    return 1000.0 * (1.0 - np.sum(w * np.abs(u.real) * mag, axis=-1) / den)  # eq. 3.54


def _receptance(K, M, D, omega: float, cols: np.ndarray) -> np.ndarray:
    """Columns ``cols`` of H(ω) = (K − ω²M + iωD)⁻¹ (eq. 5.3), complex n×len(cols)."""
    n = K.shape[0]
    Z = (K - omega**2 * M) + 1j * omega * D
    rhs = np.zeros((n, len(cols)), dtype=np.complex128)
    rhs[cols, np.arange(len(cols))] = 1.0
    return np.linalg.solve(Z, rhs)


def sine_response(
    K: Float[np.ndarray, "n n"],
    M: Float[np.ndarray, "n n"],
    damping,
    frequencies_hz: Float[np.ndarray, " f"],
    force: Float[np.ndarray, " n"] | Float[np.ndarray, "n c"],
) -> Complex[np.ndarray, "f n"] | Complex[np.ndarray, "f n c"]:
    """Steady-state response to sine excitation over a sweep, thesis eq. 3.47, eq. 3.48, eq. 3.49,
    eq. 5.4.

    ``û(ω) = (K − ω²M + iωD)⁻¹ f̂`` with all force components in phase (eq. 3.48).

    **Arguments:** ``K`` (N/m), ``M`` (kg); ``damping`` as :func:`damping_matrix`;
    ``frequencies_hz`` (f,) ≥ 0; ``force`` (n,) one force vector, or (n, c) one per
    column (e.g. the identity columns of single-point runs), in N.

    **Returns:** complex128 responses (m), shape (f, n) or (f, n, c). Singular (LinAlgError)
    only at an undamped resonance of an undamped model.
    """
    K, M, D = _system(K, M, damping)
    n = K.shape[0]
    f_hz = _real_array("frequencies_hz", frequencies_hz, 1)
    if f_hz.size == 0 or np.any(f_hz < 0):
        raise ValueError("frequencies_hz must be a non-empty 1-D array of non-negative values")
    F = _real_array("force", force)
    if F.ndim not in (1, 2) or F.shape[0] != n:
        raise ValueError(f"force must have shape ({n},) or ({n}, c), got {F.shape}")
    omega = 2.0 * np.pi * f_hz
    Z = (K[None] - omega[:, None, None] ** 2 * M[None]) + 1j * omega[:, None, None] * D[None]
    rhs = np.broadcast_to(F.reshape(n, -1).astype(np.complex128), (len(omega), n, F.reshape(n, -1).shape[1]))
    X = np.linalg.solve(Z, rhs)
    return X[..., 0] if F.ndim == 1 else X
