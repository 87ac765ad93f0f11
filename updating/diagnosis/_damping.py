"""Which region's loss factor the measured modal damping asks for: the ``damping`` effect.

The model's modal viscous ratios are Rayleigh's (eq. 3.40) plus its element loss factors
and a candidate region R with loss factor η, to first order in the damping on the real
modes (modal strain energy, :func:`jaxfem.element_strain_energies`):

    ζ_n = μ/(2ω_n) + κω_n/2 + ½ η_n^model + ½ η F_Rn,   F_Rn = Σ_{e∈R} φ_nᵀK_eφ_n / λ_n

F_Rn is the share of mode n's strain energy in R. The prediction is linear in (μ, κ, η),
so a region's fit is a weighted least-squares problem in three numbers, and its Laplace
evidence (:func:`updating.diagnosis._evidence.log_evidence`) is exact. Every region is therefore
fitted, not a shortlist: each property group, and the elements within each radius of
the ladder :data:`~updating.diagnosis._patch_effects.RADII` (× the element size) of every grid. The
measured ratios (e.g. :func:`identification.identify` from FRFs) are paired with the
model's modes by MAC and frequency; each has the standard deviation ``noise`` × ζ.

The decision is the structural diagnosis' (:func:`updating.diagnosis._evidence.evidence`): the
most probable region is declared when it is decisively more probable than Rayleigh
damping alone (ln Bayes factor ≥ ln 20), lowers χ² beyond noise and lowers the
held-out χ² of the damping ratios (modes held out in folds, each predicted by a fit on
the others) beyond noise. Priors: η half-normal (σ :data:`~updating.diagnosis._patch_effects.ETA_SD`),
μ and κ broad normals. Where even the best region leaves χ²/row above 1, σ² is scaled by
it (``noise_scale``). The posterior is over Rayleigh alone and the ``n_report`` most
probable regions (neighbouring patches share it where the data cannot tell them apart).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

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
    damping_verdict,
)
from ._effects import ETA_SD, RADII, LocalDamping
from ._evidence import DECISIVE, log_evidence, lowered
from ._fit import fold_masks
from ._topology import shell_size

BASE_SD = 1.0  # prior σ of Rayleigh's two terms, each as its largest ratio over the modes: broad
PRIOR_BASE = np.full(2, BASE_SD)  # prior σ of (μ, κ), Rayleigh alone
PRIOR_REGION = np.array([BASE_SD, BASE_SD, ETA_SD])  # and of η, with a region
MIN_MODES = 4  # measured damping ratios a diagnosis needs (three numbers are fitted)


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


def _fit(A: np.ndarray, y: np.ndarray, sd: np.ndarray) -> dict:
    """MAP of ``y ≈ A θ`` (rows already divided by their σ) under the prior N(0, sd²):
    θ, the data cost ‖y − Aθ‖² and the Jacobian, as :func:`log_evidence` takes them."""
    H = A.T @ A + np.diag(1.0 / sd ** 2)
    theta = np.linalg.solve(H, A.T @ y)
    return {"theta": theta, "cost": float(np.sum((y - A @ theta) ** 2)), "jac": A}


def _heldout(A: np.ndarray, y: np.ndarray, sd: np.ndarray, masks: list[np.ndarray]) -> np.ndarray:
    """Each mode's residual when fitted on the folds without it (``masks[1:]``: the
    training modes of each fold)."""
    r = np.full(len(y), np.nan)
    for train in masks[1:]:
        theta = _fit(A[train], y[train], sd)["theta"]
        r[~train] = (y - A @ theta)[~train]
    return r


@dataclass(frozen=True)
class _Rows:
    """The measured ratios paired with the model's modes, as the fits take them: test
    modes ``rows`` and model modes ``idx``; ``share`` F_en (elements × paired modes);
    the measured ζ ``y_raw``, the row weights ``w`` = 1/σ, the weighted ζ less the model's
    own loss ``y`` and Rayleigh's two weighted columns ``B``."""

    rows: np.ndarray
    idx: np.ndarray
    share: np.ndarray
    y_raw: np.ndarray
    w: np.ndarray
    y: np.ndarray
    B: np.ndarray

    def predicted(self, A: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """ζ of a fit, per mode."""
        return self.y_raw - (self.y - A @ theta) / self.w


@dataclass(frozen=True)
class _RegionFit:
    """A region's fit: its weighted column, the MAP fit, its ln Z (with η's half-normal
    prior) and the posterior σ of (μ, κ, η)."""

    region: LocalDamping
    col: np.ndarray
    fit: dict
    log_evidence: float
    sd: np.ndarray


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
    base_cols = np.stack([0.5 / omega, 0.5 * omega], axis=1)
    base_cols /= np.abs(base_cols).max(axis=0)
    return _Rows(rows, idx, share, y_raw, w, y, base_cols * w[:, None])


def _fit_regions(model: Model, r: _Rows, cands: list[LocalDamping], n_report: int,
                 say: Callable[[str], None]) -> tuple[dict, float, float, list[_RegionFit]]:
    """Rayleigh alone's fit and every region's (those asking for η > 0); σ²'s scale; the
    ln Z of Rayleigh alone and the ``n_report`` most probable regions, best first."""
    col_of = {int(e): i for i, e in enumerate(stiffness_ids(model))}
    say(f"damping: fitting {len(cands)} regions (property groups; patches about every grid)")
    base = _fit(r.B, r.y, PRIOR_BASE)
    fitted = []
    for c in cands:
        col = 0.5 * r.share[[col_of[e] for e in c.eids]].sum(axis=0) * r.w
        res = _fit(np.column_stack([r.B, col]), r.y, PRIOR_REGION)
        if res["theta"][2] <= 0:  # asks for negative damping
            continue
        fitted.append((c, col, res))
    n = len(r.y)
    scale = max(1.0, min([base["cost"] / n] + [res["cost"] / n for _, _, res in fitted]))
    lz_b = log_evidence(base["theta"], base["cost"], base["jac"], np.zeros(2), PRIOR_BASE, scale)[0]
    scored = []
    for c, col, res in fitted:
        lz, _, sd = log_evidence(res["theta"], res["cost"], res["jac"], np.zeros(3), PRIOR_REGION, scale)
        scored.append(_RegionFit(c, col, res, lz + np.log(2.0), sd))  # + ln 2: the half-normal prior of η
    scored.sort(key=lambda t: -t.log_evidence)
    return base, lz_b, scale, scored[:n_report]


def _ranked(r: _Rows, base: dict, lz_b: float, scale: float, top: list[_RegionFit], noise: float,
            folds: int) -> tuple[DampingBaseline, tuple[DampingRegion, ...]]:
    """Rayleigh alone and the regions with their posterior (over those and Rayleigh alone),
    held-out error and checks; the first region is warranted where it passes them all."""
    n = len(r.y)
    masks = fold_masks(n, folds)
    r_b = _heldout(r.B, r.y, PRIOR_BASE, masks)
    lz = np.array([lz_b] + [t.log_evidence for t in top])
    post = np.exp(lz - lz.max())
    post /= post.sum()
    rms = lambda res: float(100 * noise * np.sqrt(np.mean(res ** 2)))  # noqa: E731  % of the measured ratio
    out = []
    for k, t in enumerate(top):
        r_c = _heldout(np.column_stack([r.B, t.col]), r.y, PRIOR_REGION, masks)
        effect = t.region.updated([t.fit["theta"][2]])
        checks = DampingChecks(
            decisive_over_baseline=bool(t.log_evidence - lz_b >= DECISIVE),
            chi2_lowered=bool(t.fit["cost"] < base["cost"] - 2 * np.sqrt(2 * n) * scale),
            heldout_lowered=bool(lowered(np.sum(r_b ** 2) / scale, np.sum(r_c ** 2) / scale, n)))
        out.append(DampingRegion(
            effect, k + 1, float(t.sd[2]), float(post[k + 1]), float(t.log_evidence - lz_b), float(t.fit["cost"] / n),
            effect.advice(t.sd[2]), rms(r_b), rms(r_c), tuple(effect.plausibility(0.0)), checks,
            warranted=k == 0 and checks.passed))
    return DampingBaseline(float(base["cost"] / n), rms(r_b), float(post[0])), tuple(out)


def _modes(test: ModalData, zeta_e: np.ndarray, r: _Rows, base: dict, top: list[_RegionFit]) -> tuple[DampingMode, ...]:
    """The per-mode table: measured ζ, Rayleigh alone's and the first-ranked region's."""
    z_best = r.predicted(np.column_stack([r.B, top[0].col]), top[0].fit["theta"]) if top else np.full(len(r.y), np.nan)
    return tuple(DampingMode(int(j) + 1, float(test.frequencies_hz[j]), float(zeta_e[j]), int(i) + 1, float(zb), float(zt))
                 for j, i, zb, zt in zip(r.rows, r.idx, r.predicted(r.B, base["theta"]), z_best))


def diagnose_damping(model: Model, test: ModalData, *, noise: Noise = Noise(damping=0.1), folds: int = 4,
                     min_mac: float = MIN_MAC, max_freq_dev: float = MAX_FREQ_DEV, n_report: int = 10,
                     progress: ProgressFn | None = None) -> DampingDiagnosis:
    """The region whose loss factor explains the measured modal damping (module
    docstring), or that Rayleigh damping (and the model's own loss factors) already do.

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
    cands = regions(model)
    base, lz_b, scale, top = _fit_regions(model, r, cands, n_report, say)
    baseline, ranked = _ranked(r, base, lz_b, scale, top, sigma, folds)
    effect = ranked[0].effect if ranked and ranked[0].warranted else None
    outcome = "effect" if effect is not None else "none_needed"
    text = damping_verdict(outcome, ranked, baseline, 100 * sigma)
    say(f"damping: {text}")
    return DampingDiagnosis(outcome, _modes(test, zeta_e, r, base, top), baseline, 100 * sigma, float(scale),
                            len(cands), ranked, effect, text)
