"""Which fitted candidates the diagnosis refines (updating.diagnosis._refine): a place walk
or a spring's directions only for a candidate taking at least CLIMB_SHARE of the best
candidate's cost reduction, as for patches and seams."""

from types import SimpleNamespace

import numpy as np

from updating.diagnosis import _refine


def _candidate(kind, node, cost, components=(1, 2, 3)):
    ref = SimpleNamespace(kind=kind, nodes=(node,), components=components)
    return SimpleNamespace(reference=ref, family="mask", ext=SimpleNamespace(split=False),
                           fit=SimpleNamespace(cost=cost, theta=np.zeros(1)), scan=(0.0,), theta0=np.zeros(1))


def _walk(monkeypatch, spring_cost):
    """A joint at χ² 10 beside a spring at grid 5 (baseline 100); grid 6 fits at 30."""
    joint = _candidate("joint", 1, 10.0)
    spring, there = _candidate("boundary_spring", 5, spring_cost), _candidate("boundary_spring", 6, np.inf)
    monkeypatch.setattr(_refine, "neighbours", lambda aug, g: [6] if g == 5 else [5])
    monkeypatch.setattr(_refine, "scan_start", lambda *a, **k: np.zeros(1))
    fitted_jobs = []

    def fitted(more):
        fitted_jobs.extend(more)
        for c in more:
            c.fit = SimpleNamespace(cost=30.0, theta=np.zeros(1))

    short = [joint, spring]
    moves = _refine.refine_places(fitted, lambda c: None, None, None, None, [spring, there], short,
                                  SimpleNamespace(cost=100.0), np.zeros(0))
    return moves, fitted_jobs, spring, there


def test_a_spring_far_behind_the_best_candidate_is_not_walked(monkeypatch):
    moves, jobs, _, _ = _walk(monkeypatch, 90.0)  # takes 10 of the best's 90: below half
    assert moves == [] and jobs == []


def test_a_spring_near_the_best_candidate_walks_to_the_better_grid(monkeypatch):
    moves, jobs, spring, there = _walk(monkeypatch, 50.0)  # takes 50 of 90: above half (bar 55)
    assert jobs == [there] and moves == [(spring, there)]


def test_directions_only_for_a_spring_near_the_best_candidate():
    joint, spring = _candidate("joint", 1, 10.0), _candidate("boundary_spring", 5, 90.0)
    calls = []
    out = _refine.refine_directions(calls.extend, None, [joint, spring], SimpleNamespace(cost=100.0))
    assert out == [] and calls == []  # aug (None) never read: nothing fitted
