"""The settings of a diagnosis (:func:`updating.diagnose`)."""

from __future__ import annotations

from dataclasses import dataclass

from .. import Noise, Settings
from ._effects import KINDS

NOISE = Noise(frequency=0.002, relative=0.01, damping=0.1)  # Table 4.7 magnitudes; damping 10 %


@dataclass(frozen=True)
class DiagnoseOptions:
    """Settings of :func:`diagnose`.

    ``noise``: the expected measurement noise (:class:`updating.Noise`: relative σ of
    frequencies, of shape components, and of damping ratios — identified damping scatters
    by 5–20 %). ``region``: the localised region holds the
    grids of the groups screening at least this share of the best and the grids scoring at
    least this share of the best (at most ``max_nodes`` grids, and as many about it where
    the place walk may move a mass or spring, and ``max_structural`` joints or supports). Fitted: the ``shortlist`` best
    screened candidates, and of each kind those screening at least ``within`` of the
    kind's best (at most ``per_kind``). ``cross_validate``: the most probable candidates
    cross-validated with ``folds`` folds over the test modes. Every fit is the engine's
    Levenberg–Marquardt loop (:mod:`updating._engine`), converged when no factor changes
    by more than ``tolerance`` relative (|Δ ln factor|), at most ``max_steps`` steps.
    ``eigensolver``: as the updating option (``auto``: the parameters' own).
    ``reduce_above``: on a model of at least this many DoFs, the candidates are screened,
    fitted and cross-validated on reduced models (:mod:`updating.diagnosis._reduced`); the most
    probable ones are evaluated on the full model at their fitted θ, and fitted again
    there where the costs differ (:func:`_on_full_model`); the full model's values are
    the ones reported.
    ``ray``: the shortlisted candidates fitted on Ray workers (``"local"``, ``"auto"`` or
    a cluster address, :func:`updating.diagnosis._ray_fits.fit_candidates_ray`; ``ray_workers`` of them,
    default one per CPU); the hill-climb and the cross-validation stay on the driver.
    ``rounds``: the most effects declared one after another (:func:`updating.diagnose`,
    step 6); ``confirm``: each winner is added and updated with passive modes held out
    before it is declared (withdrawn where a passive mode grows worse beyond noise).
    ``threads``: without Ray, the shortlisted candidates, and the neighbours of each step of
    the hill-climbs, are fitted on this many threads of this process, sharing its compiled
    fit (None: one per CPU, at most ``OMP_NUM_THREADS``; 1: one after another).
    """

    noise: Noise = NOISE
    eigensolver: str = "auto"
    folds: int = 4
    region: float = 0.3
    max_nodes: int = 30
    max_structural: int = 4
    shortlist: int = 4
    per_kind: int = 3
    within: float = 0.5
    cross_validate: int = 2
    max_steps: int = 20
    tolerance: float = 1e-3
    kinds: tuple[str, ...] = KINDS
    reduce_above: int = 2000
    ray: str | None = None
    ray_workers: int | None = None
    threads: int | None = None
    rounds: int = 3
    confirm: bool = True

    @property
    def settings(self) -> Settings:
        return Settings(False, self.tolerance, self.max_steps, self.max_steps, relative=True)
