"""Rigid elements whose independent DoFs may sit on several grids: RBAR, RBE1, RROD.

A rigid body's motion is q = [u; θ] of a reference point (basic axes); the global (CD)
component c of grid g moves as row c of A_g = R6_gᵀ G(x_g − x_ref), G the rigid-body
map u_g = u + θ × r, θ_g = θ (MSC QRG, RBAR, RBE1). Six
independent components give q = A_I⁻¹ u_I, and each dependent one u_d = A_d A_I⁻¹ u_I.
An RROD holds the distance of its grids: (u_B − u_A)·e = 0 along the unit axis e, solved
for its one dependent component.
"""

from __future__ import annotations

import numpy as np

from ._grids import _Grids
from .io import Card

_SINGULAR_RTOL = 1e-10


def _cross_rows(r: np.ndarray) -> np.ndarray:
    """S with (θ × r)_c = Σ_j S[c, j] θ_j, i.e. S[c] = r × e_c."""
    return np.array([[0.0, r[2], -r[1]], [-r[2], 0.0, r[0]], [r[1], -r[0], 0.0]])


def _rigid(r: np.ndarray) -> np.ndarray:
    """G (6 × 6): basic motion [u; θ] of a point at offset r from a reference point moving
    rigidly with [u_ref; θ_ref]: u = u_ref + θ_ref × r, θ = θ_ref."""
    g = np.eye(6)
    g[:3, 3:] = _cross_rows(r)
    return g


def _six(r: np.ndarray) -> np.ndarray:
    """diag(R, R): a grid's axes R (columns in basic) on its translations and rotations."""
    out = np.zeros((6, 6))
    out[:3, :3] = out[3:, 3:] = r
    return out


def _row(grids: _Grids, g: int, c: int, x_ref: np.ndarray) -> np.ndarray:
    """Row c (1..6, global components of grid g) of A_g = R6_gᵀ G(x_g − x_ref)."""
    row = grids.row[g]
    return (_six(grids.axes(row)).T @ _rigid(grids.xyz[row] - x_ref))[c - 1]


def rigid_terms(card: Card, grids: _Grids, independent: list[tuple[int, int, str]],
                dependent: list[tuple[int, int, str]]) -> list[tuple[int, int, str, list]]:
    """``[(g, c, key, terms)]`` for each dependent (grid, component, field): terms
    ``((grid, component), coefficient, field)`` on the six independent components."""
    x_ref = grids.xyz[grids.row[independent[0][0]]]
    a_i = np.array([_row(grids, g, c, x_ref) for g, c, _ in independent])
    scale = np.array([1.0] * 3 + [max(np.max(np.abs(a_i[:, :3])), 1.0)] * 3)
    s = np.linalg.svd(a_i / scale, compute_uv=False)
    if len(independent) != 6 or s[-1] <= _SINGULAR_RTOL * s[0]:
        listed = ", ".join(f"{g}/{c}" for g, c, _ in independent)
        raise card.error(independent[0][2], f"the independent components ({listed}) must be six that determine "
                                            "a rigid-body motion (three translations and three rotations)")
    solve = np.linalg.inv(a_i)
    out = []
    for g, c, key in dependent:
        coef = _row(grids, g, c, x_ref) @ solve
        terms = [((h, e), float(a), k) for (h, e, k), a in zip(independent, coef) if abs(a) > 1e-14]
        out.append((g, c, key, terms))
    return out


def _digits(code) -> list[int]:
    return [int(d) for d in str(code)] if code else []


def rbar(card: Card, grids: _Grids) -> list[tuple[int, int, str, list]]:
    """RBAR: CNA/CNB independent, CMA/CMB dependent (both blank: every other component of
    GA and GB), MSC QRG RBAR."""
    ga, gb = card["GA"], card["GB"]
    grids(card, "GA"), grids(card, "GB")
    ind = [(ga, c, "CNA") for c in _digits(card["CNA"])] + [(gb, c, "CNB") for c in _digits(card["CNB"])]
    if card["CMA"] or card["CMB"]:
        dep = [(ga, c, "CMA") for c in _digits(card["CMA"])] + [(gb, c, "CMB") for c in _digits(card["CMB"])]
    else:
        dep = [(g, c, key) for g, key in ((ga, "CNA"), (gb, "CNB")) for c in range(1, 7)
               if (g, c) not in {(h, e) for h, e, _ in ind}]
    if not ind:
        raise card.error("CNA", "RBAR needs independent components (CNA, CNB)")
    return rigid_terms(card, grids, ind, dep)


def rbe1(card: Card, grids: _Grids) -> list[tuple[int, int, str, list]]:
    """RBE1: the GNi/CNi components independent (six in all), the GMi/CMi dependent."""
    ind = [(g, c, f"GN{k}") for k, (g, code) in enumerate(zip(card["GN"], card["CN"]), 1) for c in _digits(code)]
    dep = [(g, c, f"GM{k}") for k, (g, code) in enumerate(zip(card["GM"], card["CM"]), 1) for c in _digits(code)]
    for g, _, key in ind + dep:
        grids(card, key, g)
    return rigid_terms(card, grids, ind, dep)


def rrod(card: Card, grids: _Grids) -> list[tuple[int, int, str, list]]:
    """RROD: (u_B − u_A)·e = 0 solved for the dependent translation CMA of GA or CMB of GB
    (both blank: the component of GB most nearly along the rod)."""
    a, b = grids(card, "GA"), grids(card, "GB")
    e = grids.xyz[b] - grids.xyz[a]
    if np.linalg.norm(e) == 0.0:
        raise card.error("GB", "zero length: GA and GB coincide")
    e = e / np.linalg.norm(e)
    along = {g: e @ grids.axes(row) for g, row in ((card["GA"], a), (card["GB"], b))}  # e·(axis j)
    sign = {card["GA"]: -1.0, card["GB"]: 1.0}
    if card["CMA"] and card["CMB"]:
        raise card.error("CMB", "only one of CMA and CMB may be given")
    if card["CMA"] or card["CMB"]:
        g, key = (card["GA"], "CMA") if card["CMA"] else (card["GB"], "CMB")
        c = int(card[key])
    else:
        g, key, c = card["GB"], "GB", int(np.argmax(np.abs(along[card["GB"]]))) + 1
    if c not in (1, 2, 3):
        raise card.error(key, f"the dependent component must be a translation 1, 2 or 3, got {c}")
    pivot = sign[g] * along[g][c - 1]
    if abs(pivot) <= 1e-8:
        raise card.error(key, f"component {c} of grid {g} is normal to the rod: it cannot hold its length")
    terms = [((h, j + 1), float(-sign[h] * along[h][j] / pivot), key)
             for h in (card["GA"], card["GB"]) for j in range(3)
             if (h, j + 1) != (g, c) and abs(along[h][j]) > 1e-14]
    return [(g, c, key, terms)]
