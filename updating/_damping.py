"""Which region's loss factor the measured modal damping asks for: the ``damping`` effect.

The model's modal viscous ratios are Rayleigh's (eq. 3.40) plus its element loss factors
and a candidate region R with loss factor η, to first order in the damping on the real
modes (modal strain energy, :mod:`jaxfem._structural_damping`):

    ζ_n = μ/(2ω_n) + κω_n/2 + ½ η_n^model + ½ η F_Rn,   F_Rn = Σ_{e∈R} φ_nᵀK_eφ_n / λ_n

F_Rn is the share of mode n's strain energy in R. The prediction is linear in (μ, κ, η),
so a region's fit is a weighted least-squares problem in three numbers, and its Laplace
evidence (:func:`updating._evidence.log_evidence`) is exact. Every region is therefore
fitted, not a shortlist: each property group, and the elements within each radius of
the ladder :data:`~updating._effects.RADII` (× the element size) of every grid. The
measured ratios (e.g. :func:`identification.identify` from FRFs) are paired with the
model's modes by MAC and frequency; each has the standard deviation ``noise`` × ζ.

The decision is the structural diagnosis' (:func:`updating._evidence.evidence`): the
most probable region is declared when it is decisively more probable than Rayleigh
damping alone (ln Bayes factor ≥ ln 20), lowers χ² beyond noise and lowers the
held-out χ² of the damping ratios (modes held out in folds, each predicted by a fit on
the others) beyond noise. Priors: η half-normal (σ :data:`~updating._effects.ETA_SD`),
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
from identification import ModalData, observation_matrix
from jaxfem import STIFFNESS_BLOCKS, Model
from jaxfem._structural_damping import element_strain_energies, stiffness_ids

from ._correlation import pair_modes
from ._effects import ETA_SD, RADII, LocalDamping
from ._evidence import DECISIVE, _lowered, fold_masks, log_evidence
from ._topology import shell_size

BASE_SD = 1.0  # prior σ of Rayleigh's two terms, each as its largest ratio over the modes: broad
MIN_MODES = 4  # measured damping ratios a diagnosis needs (three numbers are fitted)


@dataclass
class DampingDiagnosis:
    """``report`` (JSON-ready: ``outcome`` "effect" or "none_needed", ``modes`` (measured
    ζ, Rayleigh's fit ``zeta_baseline``, the first-ranked region's ``zeta_best``),
    ``baseline``, ``effects`` best first, ``verdict``) and the declared ``effect`` (or None)."""

    report: dict
    effect: LocalDamping | None


def _elements(model: Model) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Stiffness element ids (order of :func:`~jaxfem._structural_damping.stiffness_ids`),
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


def diagnose_damping(model: Model, test: ModalData, *, noise: float = 0.1, folds: int = 4,
                     min_mac: float = 0.65, max_freq_dev: float = 0.30, n_report: int = 10,
                     progress: Callable[[str], None] | None = None) -> DampingDiagnosis:
    """The region whose loss factor explains the measured modal damping (module
    docstring), or that Rayleigh damping (and the model's own loss factors) already do.

    **Arguments:** the model (updated, if it has been); ``test`` with damping ratios
    (ζ ≤ 0: unknown, left out; at least :data:`MIN_MODES`); ``noise``: the relative
    standard deviation of the measured ratios (identified damping scatters by 5–20 %);
    ``folds`` of modes for the held-out test; the pairing thresholds; ``n_report``:
    regions listed.

    **Returns:** :class:`DampingDiagnosis`.
    """
    say = progress or (lambda line: None)
    if not noise > 0:
        raise ValueError(f"noise must be a positive relative standard deviation, got {noise}")
    zeta_e = np.asarray(test.damping_ratios, np.float64)
    known = np.flatnonzero(zeta_e > 0)
    if len(known) < MIN_MODES:
        raise ValueError(f"diagnose_damping needs measured damping ratios of at least {MIN_MODES} modes, got "
                         f"{len(known)} (ζ ≤ 0 is read as unknown)")
    say(f"damping: modes of the model and pairing ({len(known)} measured ratios)")
    f_e = np.asarray(test.frequencies_hz)[known]
    n_free = model.n_dof - len(model.dofs.massless)
    lam, phi = jaxfem.modes(model, int(min(n_free, 2 * len(known) + 6)))
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
    B = base_cols * w[:, None]
    cands = regions(model)
    ids = stiffness_ids(model)
    col_of = {int(e): i for i, e in enumerate(ids)}
    say(f"damping: fitting {len(cands)} regions (property groups; patches about every grid)")
    prior_b = np.full(2, BASE_SD)
    prior_c = np.array([BASE_SD, BASE_SD, ETA_SD])
    base = _fit(B, y, prior_b)
    fitted = []
    for c in cands:
        col = 0.5 * share[[col_of[e] for e in c.eids]].sum(axis=0) * w
        res = _fit(np.column_stack([B, col]), y, prior_c)
        if res["theta"][2] <= 0:  # asks for negative damping
            continue
        fitted.append((c, col, res))
    n = len(y)
    scale = max(1.0, min([base["cost"] / n] + [r["cost"] / n for _, _, r in fitted]))
    lz_b = log_evidence(base, np.zeros(2), prior_b, scale)[0]
    scored = []
    for c, col, res in fitted:
        lz, _, sd = log_evidence(res, np.zeros(3), prior_c, scale)
        scored.append((lz + np.log(2.0), c, col, res, sd))  # + ln 2: the half-normal prior of η
    scored.sort(key=lambda t: -t[0])
    top = scored[:n_report]

    masks = fold_masks(n, folds)
    r_b = _heldout(B, y, prior_b, masks)
    lz = np.array([lz_b] + [t[0] for t in top])
    post = np.exp(lz - lz.max())
    post /= post.sum()
    rms = lambda r: float(100 * noise * np.sqrt(np.mean(r ** 2)))  # noqa: E731  % of the measured ratio
    effects = []
    for k, (lz_c, c, col, res, sd) in enumerate(top):
        r_c = _heldout(np.column_stack([B, col]), y, prior_c, masks)
        effect = c.updated([res["theta"][2]])
        checks = {
            "decisive_over_baseline": bool(lz_c - lz_b >= DECISIVE),
            "chi2_lowered": bool(res["cost"] < base["cost"] - 2 * np.sqrt(2 * n) * scale),
            "heldout_lowered": bool(_lowered(np.sum(r_b ** 2) / scale, np.sum(r_c ** 2) / scale, n)),
        }
        effects.append({**effect.to_json(), "rank": k + 1, "eta": effect.eta, "eta_sd": float(sd[2]),
                        "posterior": float(post[k + 1]), "log_evidence": float(lz_c - lz_b),
                        "chi2_per_row": float(res["cost"] / n), "advice": effect.advice(sd[2]),
                        "heldout_rms_zeta_dev_pct_before": rms(r_b), "heldout_rms_zeta_dev_pct_after": rms(r_c),
                        "plausibility": effect.plausibility(0.0), "checks": checks, "warranted": False})
    best = None
    if effects and all(effects[0]["checks"].values()):
        effects[0]["warranted"] = True
        best = top[0][1].updated([top[0][3]["theta"][2]])
    predicted = lambda A, theta: y_raw - (y - A @ theta) / w  # noqa: E731  ζ of a fit, per mode
    z_best = predicted(np.column_stack([B, top[0][2]]), top[0][3]["theta"]) if top else np.full(n, np.nan)
    report = {
        "outcome": "effect" if best is not None else "none_needed",
        "modes": [{"test_mode": int(j) + 1, "f_test_hz": float(test.frequencies_hz[j]), "zeta_test": float(zeta_e[j]),
                   "model_mode": int(i) + 1, "zeta_baseline": float(zb), "zeta_best": float(zt)}
                  for j, i, zb, zt in zip(rows, idx, predicted(B, base["theta"]), z_best)],
        "baseline": {"chi2_per_row": float(base["cost"] / n), "heldout_rms_zeta_dev_pct": rms(r_b),
                     "posterior": float(post[0])},
        "noise_pct": 100 * noise, "noise_scale": float(scale), "regions_fitted": len(cands), "effects": effects,
    }
    report["verdict"] = damping_verdict(report)
    say(f"damping: {report['verdict']}")
    return DampingDiagnosis(report, best)


def damping_verdict(report: dict) -> str:
    """One sentence: the loss factor to add and where, with what it does to the held-out
    damping error; or that Rayleigh damping explains the measured damping."""
    b = report["baseline"]
    if report["outcome"] == "effect":
        e = report["effects"][0]
        return (f"{e['advice'][0].upper()}{e['advice'][1:]}: held-out damping error "
                f"{e['heldout_rms_zeta_dev_pct_before']:.1f} % → {e['heldout_rms_zeta_dev_pct_after']:.1f} % "
                f"(posterior probability {e['posterior']:.2f}).")
    return (f"No local loss factor is warranted: Rayleigh damping leaves χ² per row {b['chi2_per_row']:.2f} at "
            f"{report['noise_pct']:.0f} % noise on the ratios (held-out error {b['heldout_rms_zeta_dev_pct']:.1f} %).")
