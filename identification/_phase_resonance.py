"""Phase resonance testing: force appropriation over the modes of a model, exciter search.

Thesis §2.1.2 and §3.4. A damped structure ``Mü + Du̇ + Ku = f̂ e^{iωt}`` (eq. 3.47)
answers a sine excitation with ``û = H(ω) f̂``, ``H(ω) = (K − ω²M + iωD)⁻¹`` (eq. 3.48,
eq. 3.49, eq. 5.3, eq. 5.4). It vibrates in a pure normal mode when the real part of û
vanishes: the force balances the damping forces (eq. 3.52) at an undamped natural
frequency (eq. 3.53); the Mode Indicator Function (MIF, eq. 3.54) measures how close it is.
Force appropriation picks the force components at a few exciters that come closest:

- ``"thesis"``: the method of §3.4.2 — superpose single-point responses at all measured
  DoFs, minimise the real-part response relative to the total (eq. 3.55, eq. 3.56,
  eq. 3.57, eq. 3.58, eq. 3.59, eq. 3.60, eq. 3.61);
- ``"lewis_wrisley"``: force ∝ mass × deflection at the exciters (Lewis & Wrisley 1950);
- ``"asher"``: null vector of the real part of the admittance matrix at the exciters, at a
  frequency where its determinant vanishes (Asher 1958);
- ``"hunt"``: eigenproblem of eq. 3.58 on the exciter responses, weighted by the reduced mass
  matrix (Hunt, Vold, Peterson & Williams 1984).

This module runs the simulated test of §5.4.1 (:func:`appropriate`,
:func:`exciter_search`, :func:`appropriation_report`); the MIF, the damping matrix and
the sine responses are in :mod:`identification._sine`, the force kernels of the four
methods in :mod:`identification._forces`.

Everything here is NumPy/SciPy in float64/complex128 (no JAX tracing): the methods are
test-planning tools, not differentiated. DoF indices are 0-based; mode numbers 1-based
as in the thesis tables; frequencies in Hz at the user boundary, rad/s inside.

References: Lewis, R.C., Wrisley, D.L. (1950), "A system for the excitation of pure
natural modes of complex structures", J. Aeronaut. Sci. 17(11), 705–722. Asher, G.W.
(1958), "A method of normal mode excitation utilizing admittance measurements", Proc.
National Specialists' Meeting on Dynamics and Aeroelasticity, IAS, 69–76. Hunt, D.L.,
Vold, H., Peterson, E.L., Williams, R. (1984), "Optimal selection of excitation methods
for enhanced modal testing", AIAA paper 84-1068.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import equinox as eqx
import numpy as np
import scipy.linalg as sl
from jaxtyping import Float, Int
from scipy.optimize import brentq

from jaxfem import static_condensation

from ._forces import _gram_eig, force_asher, force_hunt, force_lewis_wrisley, force_thesis
from ._sine import (
    _count,
    _indices,
    _real_array,
    _receptance,
    _square,
    _system,
    damping_matrix,
    mode_indicator,
    sine_response,
)

# the appropriation study, and the names tests and docs/thesis.md import from here (before
# the split into _sine and _forces they were defined here)
__all__ = ["METHODS", "REDUCED_MASS", "Appropriation", "appropriate", "appropriation_report", "exciter_search",
           "damping_matrix", "force_asher", "force_hunt", "force_lewis_wrisley", "force_thesis", "mode_indicator",
           "sine_response", "_gram_eig", "_receptance"]

METHODS = ("thesis", "lewis_wrisley", "asher", "hunt")
REDUCED_MASS = ("diagonal", "guyan")
_ASHER_GRID = 81  # frequency samples per mode in the search for det Re(H_ee) = 0
_SYMMETRY_RTOL = 1e-10  # |A − Aᵀ| up to this × max|A| is assembly round-off: A is symmetrised


# --------------------------------------------------------------------------- model level


class Appropriation(eqx.Module):
    """Force appropriated to one mode by one method, and the MIF it is predicted to give.

    **Fields:** ``method``; ``mode`` (1-based); ``exciters`` (0-based DoF indices);
    ``frequency_hz`` at which the force is applied (NaN where none was found);
    ``force`` (C,) components at the exciters, unit norm, or None where the method finds
    no force vector; ``mif`` predicted at the measured DoFs (eq. 3.54 ×1000) or None.
    """

    method: str
    mode: int
    exciters: tuple[int, ...]
    frequency_hz: float
    force: Float[np.ndarray, " c"] | None
    mif: float | None

    @property
    def found(self) -> bool:
        return self.force is not None


def _symmetrised(name: str, a: np.ndarray) -> np.ndarray:
    """``(A + Aᵀ)/2``, or ``ValueError`` naming the worst entry when A is not symmetric to
    within round-off (``_SYMMETRY_RTOL`` × max|A|: a relative test on each entry fails on
    entries that should be 0)."""
    gap = np.abs(a - a.T)
    worst = np.unravel_index(np.argmax(gap), gap.shape)
    if gap[worst] > _SYMMETRY_RTOL * np.max(np.abs(a)):
        i, j = (int(x) for x in worst)
        raise ValueError(f"{name} must be symmetric: {name}[{i}, {j}] = {a[i, j]:.6g} but {name}[{j}, {i}] = "
                         f"{a[j, i]:.6g} (beyond round-off, {_SYMMETRY_RTOL:g} × max|{name}|)")
    return 0.5 * (a + a.T)


def _symmetric_system(K, M, damping):
    """K, M, D as :func:`_system`, each symmetrised when its asymmetry is round-off."""
    K = _symmetrised("K", _square("K", K))
    M = _symmetrised("M", _square("M", M, K.shape[0]))
    if np.ndim(damping) == 2:
        damping = _symmetrised("damping matrix D", _square("damping matrix D", damping, K.shape[0]))
    return _system(K, M, damping)


def _modes(K, M, n_modes: int | None):
    """Undamped modes, mass-normalised (eq. 3.14; eq. 3.53 at resonance). Massless DoFs
    (zero rows of M: the rotations of a lumped-mass model) are condensed statically
    (:func:`jaxfem.static_condensation`), ``K* = K_aa − K_ab K_bb⁻¹ K_ba``,
    ``φ_b = −K_bb⁻¹ K_ba φ_a``, as :func:`jaxfem.eigh` does; there are as many modes as
    DoFs with mass."""
    b = np.flatnonzero(~np.any(M, axis=1))
    a = np.setdiff1d(np.arange(K.shape[0]), b)
    if not len(a):
        raise ValueError("M is zero: the model has no mass")
    try:
        x = -static_condensation(K, a)[b]  # K_bb⁻¹ K_ba
    except np.linalg.LinAlgError:
        raise ValueError(f"the stiffness of the {len(b)} massless DoFs (zero rows of M) is singular: a mechanism "
                         "(e.g. a rotation no element resists)") from None
    k_star = K[np.ix_(a, a)] - K[np.ix_(a, b)] @ x
    try:
        lam, phi_a = sl.eigh(0.5 * (k_star + k_star.T), M[np.ix_(a, a)])
    except np.linalg.LinAlgError:
        raise ValueError("M must be positive definite on the DoFs with mass (its non-zero rows); it is singular or "
                         "indefinite there") from None
    phi = np.zeros((K.shape[0], len(a)))
    phi[a], phi[b] = phi_a, -x @ phi_a
    if np.any(lam <= 0):
        raise ValueError("K must be positive definite (rigid-body modes cannot be appropriated)")
    m = len(lam) if n_modes is None else _count("n_modes", n_modes)
    if not 1 <= m <= len(lam):
        raise ValueError(f"n_modes must be in 1..{len(lam)}, got {n_modes}")
    return lam[:m], phi[:, :m]


def _frequencies(frequencies_hz, lam) -> np.ndarray:
    if frequencies_hz is None:
        return np.sqrt(lam)
    f = _real_array("frequencies_hz", frequencies_hz, 1)
    if f.shape != lam.shape or np.any(f <= 0) or np.any(np.diff(f) < 0):
        raise ValueError(
            f"frequencies_hz must hold {len(lam)} positive, ascending values (one per mode), got {f.tolist()}"
        )
    return 2.0 * np.pi * f


def _reduced_mass(K, M, exciters: np.ndarray, kind: str) -> np.ndarray:
    """Mass model reduced to the exciters: diagonal entries, or Guyan condensation
    ``Tᵀ M T`` (:func:`jaxfem.static_condensation`)."""
    if kind == "diagonal":
        return np.diag(M)[exciters]
    try:
        T = static_condensation(K, exciters)
    except np.linalg.LinAlgError:
        raise ValueError("Guyan reduction needs K restricted to the other DoFs to be regular") from None
    return T.T @ M @ T


def _check_method(method: str, reduced_mass: str):
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if reduced_mass not in REDUCED_MASS:
        raise ValueError(f"reduced_mass must be one of {REDUCED_MASS}, got {reduced_mass!r}")


def _asher_window(omega, phi, D, r: int, band: float) -> tuple[float, float]:
    """Search window around ω_r: ±band × the half-power half-width ζ_rω_r = φ_rᵀDφ_r/2
    (mass-normalised φ_r), kept between the midpoints to the neighbouring frequencies."""
    half = band * 0.5 * float(phi[:, r] @ D @ phi[:, r])
    lo, hi = omega[r] - half, omega[r] + half
    if r > 0:
        lo = max(lo, 0.5 * (omega[r - 1] + omega[r]))
    if r < len(omega) - 1:
        hi = min(hi, 0.5 * (omega[r] + omega[r + 1]))
    return max(lo, 1e-3 * omega[r]), hi


class _Solver:
    """Receptance columns of one system, cached per frequency."""

    def __init__(self, K, M, D, cols):
        self.K, self.M, self.D, self.cols = K, M, D, np.asarray(cols)
        self._cache: dict[float, np.ndarray] = {}

    def __call__(self, omega: float, cache: bool = True) -> np.ndarray:
        key = float(omega)
        if key in self._cache:
            return self._cache[key]
        H = _receptance(self.K, self.M, self.D, key, self.cols)
        if cache:
            self._cache[key] = H
        return H

    def clear(self):
        self._cache.clear()


def _asher_root(solver: _Solver, pos: np.ndarray, lo: float, hi: float, target: float) -> float | None:
    """Zero of det Re(H_ee(ω)) in [lo, hi] closest to ``target`` (None if no sign change)."""
    block = np.ix_(solver.cols[pos], pos)  # H_ee within the cached columns

    def det(om, cache=False):
        return float(np.linalg.det(solver(om, cache)[block].real))

    grid = np.linspace(lo, hi, _ASHER_GRID)
    vals = np.array([det(om, True) for om in grid])
    flips = np.flatnonzero(np.sign(vals[1:]) * np.sign(vals[:-1]) <= 0)
    roots = []
    for i in flips:
        if vals[i] == 0.0:
            roots.append(grid[i])
        elif vals[i + 1] == 0.0:
            roots.append(grid[i + 1])
        else:
            roots.append(brentq(det, grid[i], grid[i + 1], xtol=1e-12 * target, rtol=1e-14))
    return None if not roots else float(min(roots, key=lambda z: abs(z - target)))


def _one(method, solver, sensors, exc_pos, masses, omega, phi, D, r, asher_band):
    """(frequency in rad/s, force or None, MIF or None) for mode r with exciters cols[exc_pos]."""
    ex = solver.cols[exc_pos]
    if method == "asher":
        lo, hi = _asher_window(omega, phi, D, r, asher_band)
        root = _asher_root(solver, exc_pos, lo, hi, omega[r])
        if root is None:
            return math.nan, None, None
        om = root
    else:
        om = omega[r]
    Hc = solver(om, method != "asher")[:, exc_pos]  # all DoFs × exciters
    H_ee = Hc[ex]
    if method == "thesis":
        f = force_thesis(Hc[sensors])
    elif method == "lewis_wrisley":
        f = force_lewis_wrisley(H_ee, masses)
    elif method == "hunt":
        f = force_hunt(H_ee, masses)
    else:
        f = force_asher(H_ee)[0]
    if f is None:
        return om, None, None
    return om, f, float(mode_indicator(Hc[sensors] @ f))


def _prepare(K, M, damping, exciters_or_candidates, name, method, reduced_mass, n_modes, frequencies_hz, sensors,
             asher_band):
    _check_method(method, reduced_mass)
    if not asher_band > 0:
        raise ValueError(f"asher_band must be positive, got {asher_band}")
    K, M, D = _symmetric_system(K, M, damping)
    if not np.any(D):
        raise ValueError("force appropriation needs a damped model (D = 0: the response is singular at resonance)")
    n = K.shape[0]
    cols = _indices(name, exciters_or_candidates, n)
    sens = np.arange(n) if sensors is None else _indices("sensors", sensors, n)
    lam, phi = _modes(K, M, n_modes)
    omega = _frequencies(frequencies_hz, lam)
    return K, M, D, cols, sens, lam, phi, omega


def appropriate(
    K: Float[np.ndarray, "n n"],
    M: Float[np.ndarray, "n n"],
    damping,
    exciters: Int[np.ndarray, " c"] | Sequence[int],
    *,
    method: str = "thesis",
    n_modes: int | None = None,
    frequencies_hz: Float[np.ndarray, " m"] | None = None,
    sensors: Int[np.ndarray, " s"] | Sequence[int] | None = None,
    reduced_mass: str = "diagonal",
    asher_band: float = 1.0,
) -> list[Appropriation]:
    """Appropriated force and predicted MIF for each of the first modes of a damped model.

    The simulated test of thesis §5.4.1: responses ``H(ω)F`` (eq. 5.3, eq. 5.4) at the
    resonance frequencies, the force from ``method`` (see the module docstring), the MIF
    (eq. 3.54) of the resulting response at the ``sensors``.

    **Arguments:**
    - ``K`` (N/m), ``M`` (kg): symmetric n×n, K positive definite; ``damping`` as
      :func:`damping_matrix`.
    - ``exciters``: 0-based DoF indices of the C exciters.
    - ``method``: ``"thesis"``, ``"lewis_wrisley"``, ``"asher"`` or ``"hunt"``.
    - ``n_modes``: how many modes (lowest first); all if None.
    - ``frequencies_hz``: frequency per mode at which to apply the force; default the
      undamped natural frequencies of (K, M). Asher's method searches its own frequency
      (the zero of det Re(H_ee) nearest to this one).
    - ``sensors``: 0-based measured DoFs (MIF and the thesis method); all if None.
    - ``reduced_mass``: mass model at the exciters for Lewis & Wrisley and Hunt:
      ``"diagonal"`` (the diagonal entries of M, lumped masses) or ``"guyan"``.
    - ``asher_band``: Asher's search window, in half-power half-widths ζ_rω_r around each
      frequency (kept between the neighbouring natural frequencies).

    **Returns:** one :class:`Appropriation` per mode; ``force`` None where the method finds
    none (Asher: no zero of the determinant in the window; thesis method: dependent runs).
    """
    exciters = np.asarray(exciters)
    table = _ranked(K, M, damping, exciters, "exciters", exciters.size, method, n_modes, frequencies_hz, sensors,
                    reduced_mass, asher_band)
    return [rows[0] for rows in table]


def exciter_search(
    K: Float[np.ndarray, "n n"],
    M: Float[np.ndarray, "n n"],
    damping,
    candidates: Int[np.ndarray, " C"] | Sequence[int],
    n_exciters: int,
    *,
    method: str = "thesis",
    n_modes: int | None = None,
    frequencies_hz: Float[np.ndarray, " m"] | None = None,
    sensors: Int[np.ndarray, " s"] | Sequence[int] | None = None,
    reduced_mass: str = "diagonal",
    asher_band: float = 1.0,
) -> list[list[Appropriation]]:
    """All subsets of ``n_exciters`` out of the candidate positions, ranked per mode by
    predicted MIF (thesis §3.4.2 last paragraph; Table 5.11).

    Arguments as :func:`appropriate`; ``candidates`` are 0-based DoF indices, ``n_exciters``
    in 1..len(candidates).

    **Returns:** per mode, the list of all ``C(len(candidates), n_exciters)``
    :class:`Appropriation` s, best MIF first (subsets without a force vector last,
    in combination order).
    """
    return _ranked(K, M, damping, candidates, "candidates", n_exciters, method, n_modes, frequencies_hz, sensors,
                   reduced_mass, asher_band)


def _ranked(K, M, damping, candidates, name, n_exciters, method, n_modes, frequencies_hz, sensors, reduced_mass,
            asher_band, labels=None) -> list[list[Appropriation]]:
    """Every subset of ``n_exciters`` candidates appropriated for each mode, best MIF first
    (one subset when ``n_exciters`` is the number of candidates: :func:`appropriate`);
    ``labels`` name the DoFs in messages (default: 0-based indices)."""
    K, M, D, cand, sens, lam, phi, omega = _prepare(
        K, M, damping, candidates, name, method, reduced_mass, n_modes, frequencies_hz, sensors, asher_band
    )
    n_exciters = _count("n_exciters", n_exciters)
    if not 1 <= n_exciters <= len(cand):
        raise ValueError(f"n_exciters must be in 1..{len(cand)} (the number of candidates), got {n_exciters}")
    solver = _Solver(K, M, D, cand)
    full_mass = _reduced_mass(K, M, cand, "diagonal") if reduced_mass == "diagonal" else None
    if full_mass is not None and method in ("lewis_wrisley", "hunt") and np.any(full_mass <= 0):
        named = [f"{labels[c]}" if labels is not None else f"DoF {c} (0-based)" for c in cand[full_mass <= 0]]
        raise ValueError(f"{name} {', '.join(named)} have no mass (M_ii = 0: a rotation of a lumped-mass model?), "
                         f"and the {method} method weights the force by the mass at each exciter: choose DoFs "
                         "with mass, the thesis or asher method, or reduced_mass='guyan'")
    table = []
    for r in range(len(lam)):
        solver.clear()  # keep one mode's frequencies only
        rows = []
        for subset in itertools.combinations(range(len(cand)), n_exciters):
            pos = np.asarray(subset)
            ex = cand[pos]
            masses = full_mass[pos] if full_mass is not None else _reduced_mass(K, M, ex, reduced_mass)
            om, f, mif = _one(method, solver, sens, pos, masses, omega, phi, D, r, asher_band)
            rows.append(Appropriation(method, r + 1, tuple(int(e) for e in ex), om / (2.0 * np.pi), f, mif))
        rows.sort(key=lambda a: -a.mif if a.mif is not None else math.inf)
        table.append(rows)
    return table


def appropriation_report(
    K: Float[np.ndarray, "n n"],
    M: Float[np.ndarray, "n n"],
    damping,
    candidates: Int[np.ndarray, " C"] | Sequence[int],
    n_exciters: int,
    n_modes: int | None = None,
    *,
    method: str = "thesis",
    frequencies_hz: Float[np.ndarray, " m"] | None = None,
    sensors: Int[np.ndarray, " s"] | Sequence[int] | None = None,
    labels: Sequence[str] | None = None,
    top: int = 5,
    reduced_mass: str = "diagonal",
) -> dict:
    """JSON-ready exciter-placement report (for ``jaxfem appropriate``; cf. thesis Table 5.11).

    Per mode: the natural frequency, the single-point MIF of each candidate (the sweep
    runs), and the ``top`` exciter subsets of size ``n_exciters`` ranked by predicted MIF,
    with their force components (unit norm) and evaluation frequency.

    **Arguments:** as :func:`exciter_search`; ``labels`` one string per DoF of K (default
    the 1-based DoF numbers, as in the thesis); ``top`` ≥ 1 subsets listed per mode.

    **Returns:** a dict of plain Python values; ``"exciters"`` are 0-based DoF indices,
    ``force``/``mif`` are None where a subset has no force vector.
    """
    if _count("top", top) < 1:
        raise ValueError(f"top must be a positive integer, got {top!r}")
    K, M, D = _symmetric_system(K, M, damping)
    n = K.shape[0]
    if labels is None:
        labels = [str(i + 1) for i in range(n)]
    elif len(labels) != n:
        raise ValueError(f"labels must name all {n} DoFs of K, got {len(labels)}")
    labels = [str(x) for x in labels]
    ranked = _ranked(K, M, D, candidates, "candidates", n_exciters, method, n_modes, frequencies_hz, sensors,
                     reduced_mass, 1.0, labels)
    cand = _indices("candidates", candidates, n)
    sens = np.arange(n) if sensors is None else _indices("sensors", sensors, n)
    lam, _ = _modes(K, M, n_modes)
    omega = _frequencies(frequencies_hz, lam)

    def row(a: Appropriation) -> dict:
        return {
            "exciters": list(a.exciters),
            "labels": [labels[e] for e in a.exciters],
            "frequency_hz": None if math.isnan(a.frequency_hz) else a.frequency_hz,
            "force": None if a.force is None else [float(x) for x in a.force],
            "mif": a.mif,
        }

    modes = []
    for r, rows in enumerate(ranked):
        single = mode_indicator(_receptance(K, M, D, omega[r], cand)[sens].T)  # one run per candidate
        modes.append({
            "mode": r + 1,
            "natural_frequency_hz": float(np.sqrt(lam[r]) / (2.0 * np.pi)),
            "single_point_mif": {labels[c]: float(v) for c, v in zip(cand, single)},
            "best": row(rows[0]) if rows[0].found else None,
            "ranking": [row(a) for a in rows[:top]],
        })
    return {
        "method": method,
        "n_exciters": int(n_exciters),
        "candidates": [int(c) for c in cand],
        "candidate_labels": [labels[c] for c in cand],
        "sensors": [int(s) for s in sens],
        "n_subsets": math.comb(len(cand), int(n_exciters)),
        "mif": "1000*(1 - sum|Re u||u| / sum|u|^2) at the sensors, thesis eq. 3.54",
        "modes": modes,
    }
