"""The place of a fitted candidate refined by hill-climbing (:func:`updating.diagnose`, step 3):
an added mass or spring walks from grid to grid, a patch moves its centre and radius, a
seam walks along its line and in length — each while a neighbour fits better; springs to
ground at a free grid are tried on each translation alone."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from jaxfem import Model

from ._candidates import (
    Candidate,
    neighbours,
    patch_candidate,
    patch_neighbours,
    seam_neighbours,
    seam_onward,
    with_masks,
)
from ._effects import AbstractPatch, BoundarySpring, Seam
from ._fit import Fit, Fits, scan_start, threaded
from ._topology import total_mass

POINT_WALK = ("added_mass", "boundary_spring")  # the kinds the place walk moves from grid to grid
CLIMB_SHARE = 0.5  # a patch kind or a seam is refined when it takes this share of the best candidate's cost reduction


def _climb(best: Candidate, fitted_neighbours, onward=None) -> list[tuple[Candidate, Candidate]]:
    """Move from ``best`` to its best-fitting neighbour while that fits better;
    ``fitted_neighbours(c)``: the neighbours of ``c`` to compare, fitted; ``onward(a, b)``:
    the move a → b made once more, fitted (None where it cannot be), tried first after
    each move (a seam growing grid by grid takes one fit a step, not six). The moves made."""
    moves = []
    while True:
        ahead = onward(*moves[-1]) if moves and onward is not None else None
        if ahead is not None and ahead.fit.cost < best.fit.cost:
            moves.append((best, ahead))
            best = ahead
            continue
        step = min(fitted_neighbours(best), key=lambda c: c.fit.cost, default=best)
        if step.fit.cost >= best.fit.cost:
            return moves
        moves.append((best, step))
        best = step


def refine_places(fitted, solver, fits: Fits, problem, aug: Model, cands: list[Candidate], short: list[Candidate],
                   base: Fit, theta_b: np.ndarray) -> list[tuple[Candidate, Candidate]]:
    """Hill-climb over the grids: the best fitted added mass (spring to ground), where it
    takes at least :data:`CLIMB_SHARE` of the best candidate's cost reduction, is fitted
    (``fitted(candidates)``, each from its θ₀) at the neighbouring grids of the region, and moves
    while one fits better (the linearised screen hardly separates neighbours; a spring far
    behind a flexible joint walked six grids, 17 s of a 117 s diagnosis). Fitted
    candidates join ``short``; returns the moves made."""
    at_grid = {(c.reference.kind, c.reference.nodes): c for c in cands if c.family == "mask"
               and c.reference.kind in POINT_WALK and not c.ext.split}

    def fitted_neighbours(best: Candidate) -> list[Candidate]:
        kind = best.reference.kind
        new = [at_grid[kind, (g,)] for g in neighbours(aug, best.reference.nodes[0])
               if (kind, (g,)) in at_grid and at_grid[kind, (g,)] not in short]
        for c in new:
            c.theta0 = scan_start(fits, problem, c.ext, theta_b, c.scan, solver(c))
        fitted(new)
        short.extend(new)
        return new

    moves, bar = [], _climb_bar(short, base)
    for kind in POINT_WALK:
        tried = [c for c in short if c.reference.kind == kind and (kind, c.reference.nodes) in at_grid]
        best = min(tried, key=lambda c: c.fit.cost, default=None)
        if best is not None and best.fit.cost < bar:
            moves += _climb(best, fitted_neighbours)
    return moves


def refine_directions(fitted, aug: Model, short: list[Candidate], base: Fit) -> list[Candidate]:
    """The best-fitting springs to ground at a free grid also fitted on each translation
    alone (one of its three dormant springs woken, from the three's fitted log-factor): the
    evidence chooses between them — a vertical support at a nose is not springs in all
    three translations. Only a spring taking :data:`CLIMB_SHARE` of the best candidate's cost
    reduction. Fits join ``short``; returns them."""
    free = [c for c in short if c.reference.kind == BoundarySpring.kind and c.family == "mask" and not c.ext.split
            and c.reference.components == (1, 2, 3) and np.isfinite(c.fit.cost)]
    best = min(free, key=lambda c: c.fit.cost, default=None)
    if best is None or best.fit.cost >= _climb_bar(short, base):
        return []
    node = best.reference.nodes[0]
    row = int(aug.node_index([node])[0])
    s = aug.springs
    dormant = (s.nodes[:, 0] == row) & (s.nodes[:, 1] < 0) & (np.asarray(s.k_scale) == 0)
    new = []
    for comp in (1, 2, 3):
        hit = s.ids[dormant & (s.components[:, 0] == comp)]
        if len(hit) == 1:
            ref = replace(best.reference, components=(comp,), label=f"node {node}, {'xyz'[comp - 1]} only")
            new.append(Candidate(ref, ref.dormant_extension(aug, [int(hit[0])]),
                                 theta0=best.fit.theta[len(best.fit.theta) - 1:]))
    fitted(new)
    short.extend(new)
    return new


def refine_patches(fitted, model: Model, aug: Model, short: list[Candidate], base: Fit,
                    f_e) -> list[tuple[Candidate, Candidate]]:
    """Hill-climb of the two best patch kinds (kind and part) that fit better than the
    baseline and take at least half the cost reduction of the best candidate of any kind
    (a patch far behind a mass or a joint is not refined: on the 33k barrel each climb
    costs tens of fits): the best fitted patch is fitted about each neighbouring shell grid
    and with the next radius up and down the ladder, and moves while one fits better
    (centre refined between neighbours, radius chosen by the data). Fits join ``short``."""
    def key(e):
        return e.kind, getattr(e, "part", ""), e.nodes, round(e.radius, 9)

    mass = total_mass(model)
    done = {key(c.reference): c for c in short if isinstance(c.reference, AbstractPatch)}

    def fitted_neighbours(best: Candidate) -> list[Candidate]:
        near = patch_neighbours(model, best, f_e)
        new = {key(p): patch_candidate(p, model, None, f_e, mass) for p in near if key(p) not in done}
        with_masks(list(new.values()), aug)
        theta = best.fit.theta
        for c in new.values():
            c.theta0 = theta[len(theta) - len(c.theta0):]
        fitted(list(new.values()))
        done.update(new)
        short.extend(new.values())
        return [done[key(p)] for p in near]

    bar = _climb_bar(short, base)
    best_of: dict = {}
    for c in done.values():
        k = key(c.reference)[:2]
        if c.fit.cost < bar and (k not in best_of or c.fit.cost < best_of[k].fit.cost):
            best_of[k] = c
    return [m for best in sorted(best_of.values(), key=lambda c: c.fit.cost)[:2]
            for m in _climb(best, fitted_neighbours)]


def refine_seams(fitted, aug: Model, short: list[Candidate], base: Fit) -> list[tuple[Candidate, Candidate]]:
    """Hill-climb of the best fitted seam that takes at least half the cost reduction of
    the best candidate (as a patch, :func:`refine_patches`) on its released line
    (:meth:`~updating.diagnosis._seam.Seam.neighbours`): first in coarse moves (half its length
    along, each end or both a quarter of it out or in, the length ladder), then in fine ones (one
    grid along, each end out or in), the last move made once more first, the neighbours
    fitted, moving while one fits better. Fits join ``short``."""
    def key(c: Candidate):
        return c.reference.pids, c.reference.nodes

    done = {key(c): c for c in short if c.reference.kind == Seam.kind and c.released is not None}

    def known(near: list[Candidate]) -> list[Candidate]:
        new = {key(c): c for c in near if key(c) not in done}
        fitted(list(new.values()))
        done.update(new)
        short.extend(new.values())
        return [done[key(c)] for c in near]

    def fitted_neighbours(best: Candidate, coarse: bool) -> list[Candidate]:
        return known(seam_neighbours(aug, best, coarse))

    def onward(a: Candidate, b: Candidate) -> Candidate | None:
        ahead = seam_onward(aug, a, b)
        return None if ahead is None else known([ahead])[0]

    bar = _climb_bar(short, base)
    best = min((c for c in done.values() if c.fit.cost < bar), key=lambda c: c.fit.cost, default=None)
    if best is None:
        return []
    moves = _climb(best, lambda c: fitted_neighbours(c, coarse=True), onward)
    return moves + _climb(moves[-1][1] if moves else best, lambda c: fitted_neighbours(c, coarse=False), onward)


def _climb_bar(short: list[Candidate], base: Fit) -> float:
    """The cost a candidate must fit below to be refined: :data:`CLIMB_SHARE` of the best
    candidate's cost reduction."""
    best = min((c.fit.cost for c in short if np.isfinite(c.fit.cost)), default=base.cost)
    return base.cost - CLIMB_SHARE * (base.cost - best)
