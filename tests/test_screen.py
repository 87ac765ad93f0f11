"""The screen's linearised evidence of one more column (updating.diagnosis._screen): the
ratio of two linear-Gaussian marginal likelihoods, and a frequency law fitted only where
its coefficient wins over its group's factor alone (updating.diagnosis._candidates.shortlist)."""

from types import SimpleNamespace

import numpy as np

from updating.diagnosis._candidates import shortlist
from updating.diagnosis._screen import Screen


def _gauss(r, cov):
    _, logdet = np.linalg.slogdet(cov)
    return -0.5 * (r @ np.linalg.solve(cov, r) + logdet + len(r) * np.log(2 * np.pi))


def _projected(a, cols):
    q, _ = np.linalg.qr(cols)
    return a - q @ (q.T @ a)


def test_added_log_evidence_is_the_ratio_of_the_marginal_likelihoods():
    rng = np.random.default_rng(3)
    n_e, n_s = 6, 4
    row_mode = np.concatenate([np.arange(n_e), np.tile(np.arange(n_e), n_s)])
    mac = np.where(np.arange(n_e) < 3, 0.99, 0.5)  # modes 4–6 mispaired: their shape rows leave the linear set
    J_b, g, extra = rng.normal(size=(30, 1)), rng.normal(size=(30, 1)), rng.normal(size=(30, 1))
    sigma2, sd = 0.04, 0.7
    for amplitude in (0.0, 0.05, 0.5):  # no signal, a weak and a strong one
        r = 0.2 * rng.normal(size=30) + amplitude * extra[:, 0]
        screen = Screen(r, SimpleNamespace(mac=mac), J_b, row_mode, np.ones(n_e), 1.0)
        want = []
        for rows in (np.ones(30, bool), screen.linear()):
            cols = np.concatenate([J_b, g], axis=1)[rows]
            rp, jp = _projected(r[rows], cols), _projected(extra[rows, 0], cols)
            # on an orthonormal basis q of the complement of the fitted columns' span, the
            # residual is N(0, σ²I) without the column and N(0, σ²I + sd² j jᵀ) with it
            q = np.linalg.svd(_projected(np.eye(rows.sum()), cols))[0][:, :rows.sum() - 2]
            want.append(_gauss(q.T @ rp, sigma2 * np.eye(q.shape[1]) + sd ** 2 * np.outer(q.T @ jp, q.T @ jp))
                        - _gauss(q.T @ rp, sigma2 * np.eye(q.shape[1])))
        assert screen.linear().sum() < 30
        np.testing.assert_allclose(screen.added_log_evidence(g, extra, sd, sigma2), max(want), rtol=1e-9, atol=1e-9)


class _Cand(SimpleNamespace):
    __hash__ = object.__hash__


def _cand(kind, screen, nested=float("inf")):
    return _Cand(reference=SimpleNamespace(kind=kind), screen=screen, nested=nested)


def test_a_law_no_better_than_its_groups_factor_is_not_fitted():
    """A law screening best is still left out where its coefficient's linearised evidence
    over its own group's factor is not positive (it nests that factor: it cannot win)."""
    law = "frequency_dependent_stiffness"
    mass, flat, sloped = _cand("added_mass", 0.5), _cand(law, 0.6, nested=-0.3), _cand(law, 0.55, nested=12.0)
    short = shortlist([mass, flat, sloped], 3, 2, ("added_mass", law), 0.5)
    assert flat not in short and sloped in short and mass in short
