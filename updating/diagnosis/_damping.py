"""Which region's loss factor the measured modal damping asks for: the ``damping`` effect.

The model's modal viscous ratios are Rayleigh's (eq. 3.40), its own element loss factors,
a uniform loss factor η0 on every element with stiffness and a candidate region R with
loss factor η, to first order in the damping on the real modes (modal strain energy,
:func:`jaxfem.element_strain_energies`):

    ζ_n = μ/(2ω_n) + κω_n/2 + ½ η_n^model + ½ η0 F_n + ½ η F_Rn,   F_Rn = Σ_{e∈R} φ_nᵀK_eφ_n / λ_n

F_Rn is the share of mode n's strain energy in R, F_n = Σ_e F_en that in all elements (1
where elements hold all the stiffness). The **null model** is uniform damping, (μ, κ, η0):
Rayleigh cannot make a constant ζ, a uniform loss factor does (ζ_n = η0/2), so a region
is never declared for damping that is simply uniform. A candidate adds η on top (four
numbers). The prediction is linear, so every fit is a weighted least-squares problem
and every region is fitted, not a shortlist: each property group (short of all the
elements: that is η0), each element, and the elements within each radius of the ladder
:data:`~updating.diagnosis._patch_effects.RADII` (× the element size) of every grid. The
measured ratios (e.g. :func:`identification.identify` from FRFs) are paired with the
model's modes by MAC and frequency; each has the standard deviation ``noise`` × ζ.

Priors: μ and κ broad normals (:data:`BASE_SD`), η0 and η half-normal with σ
:data:`~updating.diagnosis._patch_effects.ETA_SD` (a loss factor is ≥ 0). θ is the MAP
within η0, η ≥ 0; ln Z is exact for the linear model under these priors: the Gaussian
evidence (:func:`updating.diagnosis._evidence.log_evidence`) + ln 2 per half-normal
factor + ln P(η0, η ≥ 0) under the Gaussian posterior (→ ln 2 per factor where it lies
well inside η > 0).

Every decision is at the **stated** noise (σ² never rescaled). A region is declared
when it is the most probable (posterior ≥ 0.5 over the null model and the ``n_report``
most probable regions), decisively more probable than the null model (ln Bayes factor
≥ ln 20), lowers χ² beyond noise (by 2√(2n)), lowers the held-out χ² of the ratios
(modes held out in folds, each predicted by a fit on the others) beyond noise, **and**
brings it to the noise level: held-out χ² ≤ n + 2√(2n) (2σ of a χ² of n rows). Else the
null model explains the ratios where its χ² ≤ n + 2√(2n) (``none_needed``), and
otherwise nothing does (``unexplained``: the ratios scatter beyond the stated noise or
need physics outside the candidates). ``noise_scale``, the χ²/row of the retained model
(the declared region's fit, else the null model's), estimates (actual/stated noise)²:
reported, never used in a decision.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from itertools import combinations

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import log_ndtr

import jaxfem
from identification import (
    MAX_FREQ_DEV,
    MIN_MAC,
    ModalData,
    observation_matrix,
    pair_modes,
)
from jaxfem import STIFFNESS_BLOCKS, Model, element_strain_energies, stiffness_ids

from .. import Noise, ProgressFn, n_model_modes, progress_lines
from ._damping_result import (
    DampingBaseline,
    DampingChecks,
    DampingDiagnosis,
    DampingMode,
    DampingRegion,
    UniformDamping,
    damping_verdict,
)
from ._effects import ETA_SD, RADII, LocalDamping
from ._evidence import DECISIVE, log_evidence, lowered
from ._fit import fold_masks
from ._topology import shell_size

BASE_SD = 1.0  # prior σ of Rayleigh's two terms, each as its largest ratio over the modes: broad
PRIOR_NULL = np.array([BASE_SD, BASE_SD, ETA_SD])  # prior σ of (μ, κ, η0), the null model
PRIOR_REGION = np.array([BASE_SD, BASE_SD, ETA_SD, ETA_SD])  # and of η, with a region
HALF_NULL, HALF_REGION = (2,), (2, 3)  # the loss factors: half-normal priors, ≥ 0
MIN_MODES = 4  # measured damping ratios a diagnosis needs (the priors bound the fourth number)
_GRID = np.concatenate([[0.0], np.geomspace(1e-9, 1.0, 1000)])  # of the orthant integral, × its length


def _elements(model: Model) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Stiffness element ids (order of :func:`jaxfem.stiffness_ids`),
    their property ids and grid rows (ground: none)."""
    pids, rows = [], []
    for name in STIFFNESS_BLOCKS:
        block = getattr(model, name)
        pids.append(np.asarray(block.pids, np.int64))
        rows += [r[r >= 0] for r in np.asarray(block.nodes)]
    return stiffness_ids(model), np.concatenate(pids), rows


def regions(model: Model) -> list[LocalDamping]:
    """The candidate regions: each property group of elements with stiffness, each such
    element, and about
    every grid of them the elements whose centres lie within each radius of the ladder
    (:data:`RADII` × the shell size, or the median two-grid element length without shells),
    and at least those attached to the grid; regions of the same elements once."""
    ids, pids, rows = _elements(model)
    xyz = np.asarray(model.xyz)
    out, seen = [], set()

    def add(members: np.ndarray, **kw) -> None:
        key = frozenset(ids[members].tolist())
        if key and key not in seen:
            seen.add(key)
            out.append(LocalDamping(eids=tuple(sorted(key)), **kw))

    for p in np.unique(pids):
        at = np.flatnonzero(pids == p)
        add(at, label=f"the {len(at)} elements of pid {p}")
    for i, e in enumerate(ids):
        add(np.array([i]), label=f"element {e}")
    centres = np.stack([xyz[r].mean(axis=0) for r in rows])
    size = shell_size(model) or float(np.median([np.linalg.norm(xyz[r[1]] - xyz[r[0]]) for r in rows if len(r) == 2]))
    attached: dict[int, list[int]] = {}
    for i, r in enumerate(rows):
        for g in r.tolist():
            attached.setdefault(g, []).append(i)
    tree = cKDTree(centres)
    for g in sorted(attached):
        for f in RADII:
            members = np.union1d(tree.query_ball_point(xyz[g], f * size * (1 + 1e-9)), attached[g]).astype(np.int64)
            add(members, nodes=(int(model.node_ids[g]),), radius=f * size,
                label=f"the {len(members)} elements within {1000 * f * size:.0f} mm of grid {int(model.node_ids[g])}")
    return out


def at_noise(chi2: float, n: int) -> bool:
    """A χ² of ``n`` rows at the noise level: within 2σ of a χ² of n rows, χ² ≤ n + 2√(2n)."""
    return bool(chi2 <= n + 2 * np.sqrt(2 * n))


def _log_orthant(m: np.ndarray, cov: np.ndarray) -> float:
    """ln P(θ ≥ 0) for θ ~ N(m, cov), one or two numbers. Two: P(X ≤ h, Y ≤ k) of the
    standard pair with correlation ρ, ∫_{−∞}^h φ(x) Φ((k − ρx)/√(1 − ρ²)) dx by the
    trapezoid rule in logs on a geometric grid below h (tails included)."""
    s = np.sqrt(np.diag(cov))
    h = np.asarray(m) / s
    if len(h) == 1:
        return float(log_ndtr(h[0]))
    rho = min(max(cov[0, 1] / (s[0] * s[1]), -1 + 1e-12), 1 - 1e-12)
    t = _GRID * (max(h[0], 0.0) + 12.0)
    x = h[0] - t
    f = -0.5 * x ** 2 - 0.5 * np.log(2 * np.pi) + log_ndtr((h[1] - rho * x) / np.sqrt(1 - rho ** 2))
    g = np.logaddexp(f[1:], f[:-1]) + np.log(0.5 * np.diff(t))
    top = g.max()
    return float(top + np.log(np.sum(np.exp(g - top))))


def _map(A: np.ndarray, y: np.ndarray, sd: np.ndarray, half: tuple[int, ...]) -> np.ndarray:
    """MAP θ of ``y ≈ A θ`` (rows already divided by their σ) under the prior N(0, sd²)
    restricted to θ[half] ≥ 0: the unconstrained optimum where it is feasible, else the
    best optimum on a face θ[fixed] = 0 whose other loss factors are ≥ 0."""
    H, b, p = A.T @ A + np.diag(1.0 / sd ** 2), A.T @ y, len(sd)
    best, objective = np.zeros(p), np.inf
    for k in range(len(half) + 1):
        for fixed in combinations(half, k):
            free = np.setdiff1d(np.arange(p), fixed)
            theta = np.zeros(p)
            theta[free] = np.linalg.solve(H[np.ix_(free, free)], b[free])
            obj = np.sum((y - A @ theta) ** 2) + np.sum((theta / sd) ** 2)
            if (theta[list(half)] >= 0).all() and obj < objective:
                best, objective = theta, obj
        if k == 0 and objective < np.inf:
            break
    return best


def _fit(A: np.ndarray, y: np.ndarray, sd: np.ndarray, half: tuple[int, ...]) -> dict:
    """The MAP fit (:func:`_map`): θ, its data cost ‖y − Aθ‖²; ln Z, exact for the linear
    model (module docstring), and the posterior σ of θ."""
    theta = _map(A, y, sd, half)
    H = A.T @ A + np.diag(1.0 / sd ** 2)
    free = np.linalg.solve(H, A.T @ y)  # the Gaussian posterior's mean, no bounds
    lz, _, post_sd = log_evidence(free, float(np.sum((y - A @ free) ** 2)), A, np.zeros(len(sd)), sd, 1.0)
    h = list(half)
    lz += len(h) * np.log(2.0) + _log_orthant(free[h], np.linalg.inv(H)[np.ix_(h, h)])
    return {"theta": theta, "cost": float(np.sum((y - A @ theta) ** 2)), "log_z": float(lz), "sd": post_sd}


def _heldout(A: np.ndarray, y: np.ndarray, sd: np.ndarray, half: tuple[int, ...],
             masks: list[np.ndarray]) -> np.ndarray:
    """Each mode's residual when fitted on the folds without it (``masks[1:]``: the
    training modes of each fold, :func:`~updating.diagnosis._fit.fold_masks`)."""
    r = np.full(len(y), np.nan)
    for train in masks[1:]:
        theta = _map(A[train], y[train], sd, half)
        r[~train] = (y - A @ theta)[~train]
    return r


@dataclass(frozen=True)
class _Rows:
    """The measured ratios paired with the model's modes, as the fits take them: test
    modes ``rows`` and model modes ``idx``; ``share`` F_en (elements × paired modes);
    the measured ζ ``y_raw``, the row weights ``w`` = 1/σ, the weighted ζ less the model's
    own loss ``y``, the null model's three weighted columns ``B`` (Rayleigh's two, each
    divided by ``norm``, and η0's)."""

    rows: np.ndarray
    idx: np.ndarray
    share: np.ndarray
    y_raw: np.ndarray
    w: np.ndarray
    y: np.ndarray
    B: np.ndarray
    norm: np.ndarray

    def predicted(self, A: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """ζ of a fit, per mode."""
        return self.y_raw - (self.y - A @ theta) / self.w

    def uniform(self, fit: dict) -> UniformDamping:
        """The uniform part (μ [1/s], κ [s], η0 ± σ) of a fit."""
        theta, sd = fit["theta"], fit["sd"]
        return UniformDamping(float(theta[0] / self.norm[0]), float(theta[1] / self.norm[1]), float(theta[2]),
                              float(sd[2]))


@dataclass(frozen=True)
class _RegionFit:
    """A region's fit: its weighted column and the MAP fit (:func:`_fit`)."""

    region: LocalDamping
    col: np.ndarray
    fit: dict


def _paired_rows(model: Model, test: ModalData, noise: float, zeta_e: np.ndarray, known: np.ndarray,
                 min_mac: float, max_freq_dev: float, say: Callable[[str], None]) -> _Rows:
    """Pair the measured ratios ``zeta_e[known]`` with the model's modes; each mode's strain
    energy per element; the weighted rows of the fits."""
    say(f"damping: modes of the model and pairing ({len(known)} measured ratios)")
    f_e = np.asarray(test.frequencies_hz)[known]
    lam, phi = jaxfem.modes(model, n_model_modes(model, len(known)))
    lam, phi = np.asarray(lam), np.asarray(phi)
    C, _ = observation_matrix(model, test.sensors)
    pairing = pair_modes(np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi), np.asarray(C) @ phi, f_e,
                         np.asarray(test.shapes)[:, known], min_mac=min_mac, max_freq_dev=max_freq_dev)
    idx, rows = pairing.model, known[pairing.test]
    if len(rows) < MIN_MODES:
        raise ValueError(f"diagnose_damping: only {len(rows)} measured modes with damping pair with the model's")
    lam_p, phi_p = lam[idx], phi[:, idx]
    omega = np.sqrt(lam_p)
    say(f"damping: strain energy of every element in {len(idx)} modes")
    share = np.asarray(element_strain_energies(model, phi_p)) / lam_p  # F_en
    own = 0.5 * np.asarray(jaxfem.modal_loss_factors(model, lam_p, phi_p))

    y_raw = zeta_e[rows]
    w = 1.0 / (noise * y_raw)
    y = (y_raw - own) * w
    rayleigh = np.stack([0.5 / omega, 0.5 * omega], axis=1)  # eq. 3.40
    norm = np.abs(rayleigh).max(axis=0)
    cols = np.column_stack([rayleigh / norm, 0.5 * share.sum(axis=0)])  # μ, κ (scaled) and η0
    return _Rows(rows, idx, share, y_raw, w, y, cols * w[:, None], norm)


def _fit_regions(model: Model, r: _Rows, cands: list[LocalDamping], n_report: int,
                 say: Callable[[str], None]) -> tuple[dict, list[_RegionFit]]:
    """The null model's fit and the ``n_report`` most probable regions of those asking for
    η > 0, best first."""
    col_of = {int(e): i for i, e in enumerate(stiffness_ids(model))}
    say(f"damping: fitting {len(cands)} regions (property groups; patches about every grid)")
    null = _fit(r.B, r.y, PRIOR_NULL, HALF_NULL)
    scored = []
    for c in cands:
        col = 0.5 * r.share[[col_of[e] for e in c.eids]].sum(axis=0) * r.w
        res = _fit(np.column_stack([r.B, col]), r.y, PRIOR_REGION, HALF_REGION)
        if res["theta"][3] > 0:  # else it asks for no local loss factor (or a negative one)
            scored.append(_RegionFit(c, col, res))
    scored.sort(key=lambda t: -t.fit["log_z"])
    return null, scored[:n_report]


def _ranked(r: _Rows, null: dict, top: list[_RegionFit], noise: float,
            folds: int) -> tuple[DampingBaseline, tuple[DampingRegion, ...]]:
    """The null model and the regions with their posterior (over those and the null model),
    held-out error and checks, all at the stated noise; the first region is warranted
    where it passes them all."""
    n = len(r.y)
    masks = fold_masks(n, folds)
    r_b = _heldout(r.B, r.y, PRIOR_NULL, HALF_NULL, masks)
    held_b = float(np.sum(r_b ** 2))
    lz = np.array([null["log_z"]] + [t.fit["log_z"] for t in top])
    post = np.exp(lz - lz.max())
    post /= post.sum()
    rms = lambda res: float(100 * noise * np.sqrt(np.mean(res ** 2)))  # noqa: E731  % of the measured ratio
    out = []
    for k, t in enumerate(top):
        r_c = _heldout(np.column_stack([r.B, t.col]), r.y, PRIOR_REGION, HALF_REGION, masks)
        held_c, sd = float(np.sum(r_c ** 2)), t.fit["sd"]
        effect = t.region.updated([t.fit["theta"][3]])
        checks = DampingChecks(
            most_probable=bool(post[k + 1] >= 0.5),
            decisive_over_baseline=bool(t.fit["log_z"] - null["log_z"] >= DECISIVE),
            chi2_lowered=bool(t.fit["cost"] < null["cost"] - 2 * np.sqrt(2 * n)),
            heldout_lowered=bool(lowered(held_b, held_c, n)),
            heldout_at_noise=at_noise(held_c, n))
        out.append(DampingRegion(
            effect, k + 1, float(sd[3]), float(post[k + 1]), float(t.fit["log_z"] - null["log_z"]),
            float(t.fit["cost"] / n), held_c / n, effect.advice(sd[3]), rms(r_b), rms(r_c), r.uniform(t.fit),
            tuple(effect.plausibility(0.0)), checks, warranted=k == 0 and checks.passed))
    baseline = DampingBaseline(float(null["cost"] / n), held_b / n, rms(r_b), float(post[0]), r.uniform(null),
                               at_noise(null["cost"], n))
    return baseline, tuple(out)


def _modes(test: ModalData, zeta_e: np.ndarray, r: _Rows, null: dict, top: list[_RegionFit]) -> tuple[DampingMode, ...]:
    """The per-mode table: measured ζ, the null model's and the first-ranked region's."""
    z_best = r.predicted(np.column_stack([r.B, top[0].col]), top[0].fit["theta"]) if top else np.full(len(r.y), np.nan)
    return tuple(DampingMode(int(j) + 1, float(test.frequencies_hz[j]), float(zeta_e[j]), int(i) + 1, float(zb), float(zt))
                 for j, i, zb, zt in zip(r.rows, r.idx, r.predicted(r.B, null["theta"]), z_best))


def diagnose_damping(model: Model, test: ModalData, *, noise: Noise = Noise(damping=0.1), folds: int = 4,
                     min_mac: float = MIN_MAC, max_freq_dev: float = MAX_FREQ_DEV, n_report: int = 10,
                     progress: ProgressFn | None = None) -> DampingDiagnosis:
    """The region whose loss factor explains the measured modal damping beyond uniform
    damping (module docstring), or that uniform damping (Rayleigh, a loss factor η0 and
    the model's own loss factors) already does, or that neither does.

    **Arguments:** the model (updated, if it has been); ``test`` with damping ratios
    (ζ ≤ 0: unknown, left out; at least :data:`MIN_MODES`); ``noise.damping``: the
    relative standard deviation of the measured ratios (identified damping scatters by 5–20 %);
    ``folds`` of modes for the held-out test; the pairing thresholds; ``n_report``:
    regions listed.

    **Returns:** :class:`DampingDiagnosis`.
    """
    say = progress_lines(progress)
    if not noise.damping > 0:
        raise ValueError(f"noise.damping must be a positive relative standard deviation, got {noise.damping}")
    sigma = float(noise.damping)
    zeta_e = np.asarray(test.damping_ratios, np.float64)
    known = np.flatnonzero(zeta_e > 0)
    if len(known) < MIN_MODES:
        raise ValueError(f"diagnose_damping needs measured damping ratios of at least {MIN_MODES} modes, got "
                         f"{len(known)} (ζ ≤ 0 is read as unknown)")
    r = _paired_rows(model, test, sigma, zeta_e, known, min_mac, max_freq_dev, say)
    cands = [c for c in regions(model) if len(c.eids) < r.share.shape[0]]  # all the elements: that is η0
    null, top = _fit_regions(model, r, cands, n_report, say)
    baseline, ranked = _ranked(r, null, top, sigma, folds)
    effect = ranked[0].effect if ranked and ranked[0].warranted else None
    outcome = "effect" if effect is not None else "none_needed" if baseline.at_noise else "unexplained"
    scale = ranked[0].chi2_per_row if effect is not None else baseline.chi2_per_row
    text = damping_verdict(outcome, ranked, baseline, 100 * sigma, scale)
    say(f"damping: {text}")
    return DampingDiagnosis(outcome, _modes(test, zeta_e, r, null, top), baseline, 100 * sigma, scale,
                            len(cands), ranked, effect, text)
