"""Correlation of analytical and experimental modes: MAC, COMAC, MSF, orthogonality, pairing.

Mode shapes are columns, ``φ`` of shape ``(n_dof, n_modes)``, over the DoFs both sides
share (the measured ones), real or complex; ``a`` is the analytical model, ``e`` the
test. Inputs of different kinds are cast explicitly to one double-precision dtype
(real, or complex if either is complex), so the functions work under strict dtype
promotion. All are pure JAX and jit/vmap/grad-safe, except :func:`pair_modes`, a
host-side exact assignment for reports and host loops; :func:`pair_modes_masked` is its
fixed-shape, jittable counterpart for Monte-Carlo batches.

Pairing rule (thesis §4.3.3.3, §5.2.4): a test and a model mode may be paired when
``MAC ≥ min_mac`` (0.65 in ch. 4, 0.60 in ch. 5) and ``|Δf| ≤ max_freq_dev`` (0.30),
with Δf of eq. 4.1; pairing uses the shapes, not the order of the frequencies, so it
follows modes that cross (§1.3.3.1).
"""

from __future__ import annotations


import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float, Inexact, Int

MIN_MAC = 0.65  # the pairing rule's MAC threshold (thesis ch. 4; 0.60 in ch. 5)
MAX_FREQ_DEV = 0.30  # and its largest |Δf| (fraction, eq. 4.1)


def _common(*xs) -> tuple[Array, ...]:
    """Cast to one double-precision dtype (explicitly: strict promotion allows no mixing)."""
    xs = tuple(jnp.asarray(x) for x in xs)
    dtype = np.result_type(*(x.dtype for x in xs), np.float64)
    return tuple(x.astype(dtype) for x in xs)


def _sq_norms(phi: Array) -> Float[Array, " m"]:
    """``φᴴφ`` per column, written without ``abs`` (whose complex derivative at 0 is NaN)."""
    return jnp.sum(jnp.real(jnp.conj(phi) * phi), axis=0)


def _safe_div(num: Inexact[Array, "..."], den: Float[Array, "..."]) -> Inexact[Array, "..."]:
    """``num / den`` where ``den > 0``, else 0, with finite gradients at ``den = 0``."""
    pos = den > 0
    return jnp.where(pos, num / jnp.where(pos, den, 1.0).astype(num.dtype), 0.0)


def _safe_rsqrt(den: Float[Array, "..."]) -> Float[Array, "..."]:
    """``1/√den`` where ``den > 0``, else 0, with finite gradients at ``den = 0``."""
    pos = den > 0
    return jnp.where(pos, jax.lax.rsqrt(jnp.where(pos, den, 1.0)), 0.0)


def _shapes(name_a: str, phi_a, name_e: str, phi_e, *, same_modes: bool = False) -> None:
    for name, phi in ((name_a, phi_a), (name_e, phi_e)):
        if jnp.ndim(phi) != 2:
            raise ValueError(f"{name} must be 2-D (n_dof, n_modes), got shape {jnp.shape(phi)}")
    if jnp.shape(phi_a)[0] != jnp.shape(phi_e)[0]:
        raise ValueError(
            f"{name_a} and {name_e} must share the DoFs (rows): got shapes "
            f"{jnp.shape(phi_a)} and {jnp.shape(phi_e)}"
        )
    if same_modes and jnp.shape(phi_a)[1] != jnp.shape(phi_e)[1]:
        raise ValueError(
            f"{name_a} and {name_e} must hold paired columns: got shapes "
            f"{jnp.shape(phi_a)} and {jnp.shape(phi_e)}"
        )


@jax.jit
def mac(
    phi_a: Inexact[ArrayLike, "n_dof n_a"], phi_e: Inexact[ArrayLike, "n_dof n_e"]
) -> Float[Array, "n_a n_e"]:
    """Modal Assurance Criterion, thesis eq. 1.54 (Allemang & Brown 1982).

    ``MAC_rs = |φ_a,rᴴ φ_e,s|² / ((φ_a,rᴴ φ_a,r)(φ_e,sᴴ φ_e,s))``; the Hermitian form makes
    it invariant to a complex scale of either vector. A zero vector gives MAC 0 (and a
    finite gradient).

    **Returns:** the ``(n_a, n_e)`` matrix, values in [0, 1].
    """
    _shapes("phi_a", phi_a, "phi_e", phi_e)
    a, e = _common(phi_a, phi_e)
    cross = jnp.conj(a).T @ e
    num = jnp.real(cross * jnp.conj(cross))
    return _safe_div(num, _sq_norms(a)[:, None] * _sq_norms(e)[None, :])


def automac(phi: Inexact[ArrayLike, "n_dof n"]) -> Float[Array, "n n"]:
    """Auto-MAC ``mac(φ, φ)`` (thesis Table 5.2): unit diagonal, small off-diagonal for a
    well-resolved set of shapes; large off-diagonal values flag poorly separable modes."""
    return mac(phi, phi)


@jax.jit
def comac(
    phi_a: Inexact[ArrayLike, "n_dof n"], phi_e: Inexact[ArrayLike, "n_dof n"]
) -> Float[Array, " n_dof"]:
    """Co-ordinate MAC per DoF over paired modes (Lieven & Ewins 1988; thesis §1.3.3.2 fn. 5).

    ``COMAC_i = (Σ_r |φ_a,ir φ_e,ir|)² / (Σ_r |φ_a,ir|² Σ_r |φ_e,ir|²)``, with each mode
    first scaled to unit norm so that the arbitrary scale of a mode does not weight it.
    Column r of ``phi_a`` must be the partner of column r of ``phi_e`` (pass paired
    columns). Values near 1 mean the DoF agrees in all modes; the lowest values point to
    the DoFs where model and test disagree.
    """
    _shapes("phi_a", phi_a, "phi_e", phi_e, same_modes=True)
    a, e = _common(phi_a, phi_e)
    a = a * _safe_rsqrt(_sq_norms(a)).astype(a.dtype)
    e = e * _safe_rsqrt(_sq_norms(e)).astype(e.dtype)
    num = jnp.sum(jnp.abs(a) * jnp.abs(e), axis=1) ** 2
    den = jnp.sum(jnp.real(jnp.conj(a) * a), axis=1) * jnp.sum(jnp.real(jnp.conj(e) * e), axis=1)
    return _safe_div(num, den)


def frequency_deviation(
    f_a: Float[ArrayLike, "*b"], f_e: Float[ArrayLike, "*b"]
) -> Float[Array, "*b"]:
    """Relative frequency deviation ``Δf = (f_a − f_e) / f_e``, thesis eq. 4.1.

    A fraction (reports print it in %); broadcasts, so ``frequency_deviation(f_a[:, None],
    f_e[None, :])`` gives the ``(n_a, n_e)`` matrix used for pairing.
    """
    f_a, f_e = _common(f_a, f_e)
    return (f_a - f_e) / f_e


def rms_pct(dev) -> float | None:
    """RMS (%) of the finite relative deviations (None if there are none)."""
    dev = np.asarray(dev, float)
    dev = dev[np.isfinite(dev)]
    return float(100 * np.sqrt(np.mean(dev**2))) if dev.size else None


@jax.jit
def modal_scale_factor(
    phi_a: Inexact[ArrayLike, "n_dof n"], phi_e: Inexact[ArrayLike, "n_dof n"]
) -> Inexact[Array, " n"]:
    """Modal Scale Factor per pair, ``MSF_r = φ_a,rᴴ φ_e,r / φ_a,rᴴ φ_a,r`` (Allemang & Brown 1982).

    The least-squares scale with ``φ_e,r ≈ MSF_r φ_a,r``: it minimises ``‖φ_e,r −
    c φ_a,r‖²``, so ``MSF_r φ_a,r`` is comparable to the test shape component by component
    (eigenvector residuals). Complex if either input is. Paired columns; 0 for a zero
    analytical vector.
    """
    _shapes("phi_a", phi_a, "phi_e", phi_e, same_modes=True)
    a, e = _common(phi_a, phi_e)
    return _safe_div(jnp.sum(jnp.conj(a) * e, axis=0), _sq_norms(a))


@jax.jit
def cross_orthogonality(
    phi_a: Inexact[ArrayLike, "n_dof n_a"],
    phi_e: Inexact[ArrayLike, "n_dof n_e"],
    M_red: Float[ArrayLike, "n_dof n_dof"],
) -> Inexact[Array, "n_a n_e"]:
    """Cross-orthogonality ``φ̂_aᴴ M_red φ̂_e`` (thesis eq. 1.44, eq. 1.54 with a mass metric).

    Each mode is first scaled to unit generalised mass on ``M_red``, ``φ̂ = φ / √(φᴴ M_red
    φ)``, so that exact modes give the identity (up to the sign of each mode). ``M_red``
    is the mass matrix reduced to the measured DoFs (:func:`guyan`, :func:`serep`).
    """
    _shapes("phi_a", phi_a, "phi_e", phi_e)
    m = jnp.asarray(M_red)
    n = jnp.shape(phi_a)[0]
    if m.shape != (n, n):
        raise ValueError(f"M_red must be {n}×{n} (the shapes' DoFs), got shape {m.shape}")
    a, e, m = _common(phi_a, phi_e, m)
    ma, me = m @ a, m @ e
    ga = jnp.sum(jnp.real(jnp.conj(a) * ma), axis=0)
    ge = jnp.sum(jnp.real(jnp.conj(e) * me), axis=0)
    return (jnp.conj(a).T @ me) * _safe_rsqrt(ga[:, None] * ge[None, :]).astype(a.dtype)




@jax.jit
def _candidates(f_a, phi_a, f_e, phi_e, min_mac, max_freq_dev):
    """MAC, Δf and admissibility matrices ``(n_a, n_e)``; shapes checked at trace time."""
    _shapes("phi_a", phi_a, "phi_e", phi_e)
    for name, f, phi in (("f_a", f_a, phi_a), ("f_e", f_e, phi_e)):
        if jnp.shape(f) != (jnp.shape(phi)[1],):
            raise ValueError(f"{name} must have shape ({jnp.shape(phi)[1]},), got {jnp.shape(f)}")
    m = mac(phi_a, phi_e)
    f_a, f_e = _common(f_a, f_e)
    dev = frequency_deviation(f_a[:, None], f_e[None, :])
    return m, dev, (m >= min_mac) & (jnp.abs(dev) <= max_freq_dev)


class Pairing(eqx.Module):
    """One-to-one pairing of test and model modes (host-side NumPy result).

    Indices are 0-based; reports (``table``, ``warnings``) number modes from 1.

    **Fields:**
    - ``test``, ``model``: indices of the paired modes, sorted by test mode.
    - ``mac``, ``freq_dev``: MAC and Δf (fraction, eq. 4.1) of each pair.
    - ``unpaired_test``, ``unpaired_model``: modes left without a partner (model modes
      among those passed in).
    - ``f_test``, ``f_model``: all frequencies considered (Hz).
    - ``warnings``: one line per unpaired test mode with the reason.
    - ``min_mac``, ``max_freq_dev``: the thresholds used.
    """

    test: Int[np.ndarray, " p"]
    model: Int[np.ndarray, " p"]
    mac: Float[np.ndarray, " p"]
    freq_dev: Float[np.ndarray, " p"]
    unpaired_test: Int[np.ndarray, " ut"]
    unpaired_model: Int[np.ndarray, " um"]
    f_test: Float[np.ndarray, " n_e"]
    f_model: Float[np.ndarray, " n_a"]
    warnings: tuple[str, ...] = eqx.field(static=True)
    min_mac: float = eqx.field(static=True)
    max_freq_dev: float = eqx.field(static=True)

    def __check_init__(self):
        p = self.test.shape[0]
        if not all(x.shape == (p,) for x in (self.model, self.mac, self.freq_dev)):
            raise ValueError("test, model, mac and freq_dev must have one entry per pair")
        if p + self.unpaired_test.size != self.f_test.size:
            raise ValueError("every test mode must be paired or listed as unpaired")
        if p + self.unpaired_model.size != self.f_model.size:
            raise ValueError("every model mode must be paired or listed as unpaired")

    def table(self) -> list[tuple[int, int | None, float, float | None, float | None, float | None]]:
        """Rows ``(test mode no., model mode no., f_test Hz, f_model Hz, Δf %, MAC)`` for
        every test mode in order, numbered from 1; an unpaired test mode has ``None`` in
        the model columns (its reason is in ``warnings``). MAC as a fraction."""
        pairs = dict(zip(self.test.tolist(), range(self.test.size)))
        rows = []
        for j, f in enumerate(self.f_test.tolist()):
            if j in pairs:
                k = pairs[j]
                i = int(self.model[k])
                rows.append(
                    (j + 1, i + 1, f, float(self.f_model[i]), 100.0 * float(self.freq_dev[k]), float(self.mac[k]))
                )
            else:
                rows.append((j + 1, None, f, None, None, None))
        return rows

    def per_test(self) -> tuple[Float[np.ndarray, " n_e"], Float[np.ndarray, " n_e"]]:
        """Δf (%) and MAC of every test mode in order, NaN where unpaired."""
        dev, mac = np.full(self.f_test.size, np.nan), np.full(self.f_test.size, np.nan)
        idx = np.asarray(self.test, dtype=np.int64)
        dev[idx] = 100.0 * np.asarray(self.freq_dev, dtype=np.float64)
        mac[idx] = np.asarray(self.mac, dtype=np.float64)
        return dev, mac

    def summary(self) -> dict:
        """JSON-ready: paired modes (numbered from 1, Δf in %), unpaired modes on both
        sides, warnings, RMS Δf (%) and mean MAC over the pairs (None without pairs)."""
        rows = [{"test": t, "model": m, "f_test_hz": ft, "f_model_hz": fm, "freq_dev_pct": d, "mac": c}
                for t, m, ft, fm, d, c in self.table() if m is not None]
        dev = 100.0 * np.asarray(self.freq_dev, dtype=np.float64)
        return {
            "paired_modes": rows,
            "unpaired_test": [int(j) + 1 for j in self.unpaired_test],
            "unpaired_model": [int(i) + 1 for i in self.unpaired_model],
            "warnings": list(self.warnings),
            "rms_freq_dev_pct": float(np.sqrt(np.mean(dev**2))) if dev.size else None,
            "mean_mac": float(np.mean(self.mac)) if dev.size else None,
        }

    def to_json(self) -> dict:
        """JSON-ready: the thresholds ``min_mac`` and ``max_freq_dev`` and :meth:`summary`."""
        return {"min_mac": self.min_mac, "max_freq_dev": self.max_freq_dev, **self.summary()}


def _check_thresholds(min_mac, max_freq_dev) -> tuple[float, float]:
    min_mac, max_freq_dev = float(min_mac), float(max_freq_dev)
    if not 0.0 < min_mac <= 1.0:
        raise ValueError(f"min_mac must be in (0, 1], got {min_mac}")
    if not max_freq_dev >= 0.0:
        raise ValueError(f"max_freq_dev must be non-negative, got {max_freq_dev}")
    return min_mac, max_freq_dev


def _unpaired_reason(j, m, dev, ok, f_e, model_of_test, min_mac, max_freq_dev) -> str:
    head = f"test mode {j + 1} ({f_e[j]:.1f} Hz): "
    if m.shape[0] == 0:
        return head + "no model modes to pair with"
    adm = np.flatnonzero(ok[:, j])
    if adm.size:  # every admissible candidate went to a test mode it fits better
        i = adm[np.argmax(m[adm, j])]
        k = model_of_test[i]
        return (
            head + f"admissible model candidate {i + 1} (MAC {m[i, j]:.2f}) is paired with "
            f"test mode {k + 1} (MAC {m[i, k]:.2f})"
        )
    i = int(np.argmax(m[:, j]))
    reasons = []
    if m[i, j] < min_mac:
        reasons.append(f"MAC {m[i, j]:.2f} < {min_mac:.2f}")
    else:
        reasons.append(f"MAC {m[i, j]:.2f}")
    if not abs(dev[i, j]) <= max_freq_dev:
        reasons.append(f"Δf {100 * dev[i, j]:+.1f} % outside ±{100 * max_freq_dev:.0f} %")
    return head + f"best model candidate {i + 1} " + ", ".join(reasons)


def pair_modes(
    f_a: Float[ArrayLike, " n_a"],
    phi_a: Inexact[ArrayLike, "n_dof n_a"],
    f_e: Float[ArrayLike, " n_e"],
    phi_e: Inexact[ArrayLike, "n_dof n_e"],
    *,
    min_mac: float = MIN_MAC,
    max_freq_dev: float = MAX_FREQ_DEV,
) -> Pairing:
    """Pair test and model modes one-to-one, maximising the total MAC (thesis §4.3.3.3).

    Candidates are admissible when ``MAC ≥ min_mac`` (eq. 1.54) and ``|Δf| ≤
    max_freq_dev`` (eq. 4.1); among them the assignment with the largest total MAC is
    found exactly (Hungarian method, ``scipy.optimize.linear_sum_assignment`` on −MAC
    with inadmissible entries set to 0, then dropped; equal MACs, as at one sensor, go to
    the nearest frequencies). Based on shapes, not frequency order, so it follows
    crossing modes. Host-side (not jittable); see
    :func:`pair_modes_masked` inside jit/vmap.

    **Arguments:** model frequencies (Hz) and shapes ``f_a, phi_a``; test frequencies and
    shapes ``f_e, phi_e``, on the same DoFs; thresholds (ch. 4: 0.65, 0.30; ch. 5: 0.60).

    **Returns:** a :class:`Pairing`; every unpaired test mode gets a line in ``warnings``.
    """
    try:
        from scipy.optimize import linear_sum_assignment
    except ImportError as err:  # pragma: no cover - scipy is a test/bench extra
        raise ImportError("pair_modes needs scipy: pip install scipy") from err
    min_mac, max_freq_dev = _check_thresholds(min_mac, max_freq_dev)
    m, dev, ok = (np.asarray(x) for x in _candidates(f_a, phi_a, f_e, phi_e, min_mac, max_freq_dev))
    f_a, f_e = np.asarray(f_a, np.float64), np.asarray(f_e, np.float64)
    # equal MACs (one sensor: every MAC is 1) go to the smallest total |Δf|
    rows, cols = linear_sum_assignment(np.where(ok, -m + 1e-9 * np.abs(dev), 0.0))
    keep = ok[rows, cols]
    order = np.argsort(cols[keep])
    model, test = rows[keep][order], cols[keep][order]
    model_of_test = dict(zip(model.tolist(), test.tolist()))
    unpaired_test = np.setdiff1d(np.arange(f_e.size), test)
    return Pairing(
        test=test,
        model=model,
        mac=m[model, test],
        freq_dev=dev[model, test],
        unpaired_test=unpaired_test,
        unpaired_model=np.setdiff1d(np.arange(f_a.size), model),
        f_test=f_e,
        f_model=f_a,
        warnings=tuple(
            _unpaired_reason(j, m, dev, ok, f_e, model_of_test, min_mac, max_freq_dev)
            for j in unpaired_test.tolist()
        ),
        min_mac=min_mac,
        max_freq_dev=max_freq_dev,
    )


def aliasing(
    phi_a: Inexact[ArrayLike, "n_dof n_a"],
    phi_e: Inexact[ArrayLike, "n_dof n_e"],
    f_a: Float[ArrayLike, " n_a"] | None = None,
    f_e: Float[ArrayLike, " n_e"] | None = None,
    *,
    min_mac: float = MIN_MAC,
    max_automac: float = 0.9,
    max_freq_dev: float = MAX_FREQ_DEV,
) -> list[str]:
    """Signs of spatial aliasing, one line each (host-side): pairs of test modes whose
    AutoMAC (eq. 1.54 of the test shapes with each other) exceeds ``max_automac`` — the
    sensors cannot tell them apart — and test modes with MAC ≥ ``min_mac`` against two or
    more model modes, whose pairing then rests on the frequency window. With frequencies
    (Hz), only model modes within twice the pairing window ``max_freq_dev`` of the test
    mode count (a look-alike ten times higher cannot be mistaken for it). Modes numbered
    from 1."""
    if not 0.0 < max_automac <= 1.0:
        raise ValueError(f"max_automac must be in (0, 1], got {max_automac}")
    auto = np.asarray(automac(phi_e))
    lines = []
    for i, j in zip(*np.nonzero(np.triu(auto > max_automac, k=1))):
        lines.append(f"test modes {i + 1} and {j + 1} have AutoMAC {auto[i, j]:.2f} > {max_automac:.2f}: the "
                     "sensors do not tell them apart (spatial aliasing; add sensors or directions)")
    m = np.asarray(mac(phi_a, phi_e))  # (n_a, n_e)
    near = np.ones_like(m, dtype=bool)
    if f_a is not None and f_e is not None:
        f_a, f_e = np.asarray(f_a, np.float64), np.asarray(f_e, np.float64)
        near = np.abs(f_a[:, None] - f_e[None, :]) <= 2 * max_freq_dev * f_e[None, :]
    for j in range(m.shape[1]):
        hits = np.flatnonzero((m[:, j] >= min_mac) & near[:, j])
        if len(hits) > 1:
            hits = hits[np.argsort(-m[hits, j], kind="stable")]
            named = ", ".join(f"{k + 1}" + ("" if f_a is None else f" ({np.asarray(f_a)[k]:.4g} Hz)")
                              + f" MAC {m[k, j]:.2f}" for k in hits)
            lines.append(f"test mode {j + 1} has MAC ≥ {min_mac:.2f} with {len(hits)} model modes ({named}): its "
                         "pairing rests on the frequency window")
    return lines


def pair_modes_masked(
    f_a: Float[ArrayLike, " n_a"],
    phi_a: Inexact[ArrayLike, "n_dof n_a"],
    f_e: Float[ArrayLike, " n_e"],
    phi_e: Inexact[ArrayLike, "n_dof n_e"],
    *,
    min_mac: float | Float[ArrayLike, ""] = MIN_MAC,
    max_freq_dev: float | Float[ArrayLike, ""] = MAX_FREQ_DEV,
) -> tuple[Int[Array, " n_e"], Bool[Array, " n_e"]]:
    """Fixed-shape, jittable and vmappable mode pairing (same admissibility as :func:`pair_modes`).

    Greedy assignment in descending MAC: ``min(n_a, n_e)`` steps of a
    ``jax.lax.fori_loop``, each taking the largest admissible MAC among the remaining
    rows (model) and columns (test), then masking that row and column. Greedy equals the
    Hungarian assignment of :func:`pair_modes` when each test mode has one dominant
    candidate (its best admissible model mode prefers it in return, as for well-separated
    shapes); with competing candidates it may trade total MAC for the single best pair.
    The thresholds may be traced; under ``jax.vmap`` bind them with
    ``functools.partial`` (vmap maps keyword arguments too).

    **Returns:** ``(model_index, paired)``: for each test mode the index of its model mode
    (−1 where unpaired, int32) and the mask ``model_index ≥ 0``.
    """
    m, _, ok = _candidates(f_a, phi_a, f_e, phi_e, min_mac, max_freq_dev)
    index = _greedy(m, ok)
    return index, index >= 0


@jax.jit
def _greedy(m: Float[Array, "n_a n_e"], ok: Bool[Array, "n_a n_e"]) -> Int[Array, " n_e"]:
    n_a, n_e = m.shape
    if min(n_a, n_e) == 0:
        return jnp.full(n_e, -1, jnp.int32)
    rows, cols = jnp.arange(n_a), jnp.arange(n_e)

    def step(_, state):
        avail, index = state
        k = jnp.argmax(jnp.where(avail, m, -jnp.inf))
        i, j = k // n_e, k % n_e
        hit = avail[i, j]
        index = index.at[j].set(jnp.where(hit, i.astype(jnp.int32), index[j]))
        taken = (rows == i)[:, None] | (cols == j)[None, :]
        return avail & ~(hit & taken), index

    init = (ok, jnp.full(n_e, -1, jnp.int32))
    return jax.lax.fori_loop(0, min(n_a, n_e), step, init)[1]
