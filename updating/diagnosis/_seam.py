"""A seam or fastener line made flexible (:class:`Seam`) and the lines of grids a beam group
shares with a shell group; the kinds by name: :mod:`updating.diagnosis._effects`."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from jaxfem import Model

from ._abstract_effect import (
    AbstractEffect,
    ids_field,
    label_field,
    spread,
    value_field,
)
from ._element_effects import AbstractAddedElements, _release, _rigid_note
from ._scans import SCAN_SEAM
from ._topology import elements_at, joint_reference

SEAM_GRIDS = 5  # grids per seam candidate: a seam line is offered in runs of this many
SEAM_LENGTHS = (3, 5, 8, 13, 21, 34)  # seam ladder, in grids: a fitted seam is refined along its line and in length
SEAM_SCREEN = (13, 34)  # longer runs screened beside each run of SEAM_GRIDS (Seam.longer): a loose stretch
# whose short pieces do not fit on their own (the 33k barrel's 31 grids: its first 5 fit at a local minimum)


class Seam(AbstractAddedElements):
    """A seam or fastener line made flexible: the grids that a beam group (a frame, a
    stringer; ``pids[1]``) shares with a shell group (the skin; ``pids[0]``, which keeps
    them) along a line, each released into springs of a stiffness per unit length × the
    grid's share of the line (half the distance to each neighbour on it). Values:
    ``k_trans`` (N/m per m of seam) on translations, ``k_rot`` (N·m/rad per m) on rotations."""

    nodes: tuple[int, ...] = ids_field()
    pids: tuple[int, ...] = ids_field()
    label: str = label_field()
    k_trans: float | None = value_field()
    k_rot: float | None = value_field()

    kind = "seam"
    value_names = ("k_trans", "k_rot")
    scales = "k"
    scan = tuple((t, t) for t in SCAN_SEAM)
    prior_sd = (3.0, 3.0)

    def __check_init__(self):
        self._check_nodes()
        if len(self.pids) != 2:
            raise ValueError(f"seam at grids {list(self.nodes)}: name the shell group and the beam group, "
                             "e.g. seam:node=1001-1005;pids=101,201 (the beams are released)")

    @classmethod
    def candidates(cls, model: Model) -> list[Seam]:
        """Every line of grids a beam group shares with a shell group, in runs of
        :data:`SEAM_GRIDS` along the beams."""
        return [cls(pids=pids, nodes=line[:1]).run(line, k, SEAM_GRIDS)
                for pids, lines in _seam_lines(model).items() for line in lines
                for k in range(0, len(line), SEAM_GRIDS)]

    def line(self, model: Model, lines: dict | None = None) -> tuple[int, ...]:
        """The whole line this seam lies on (grids in order along it); ``lines``: the
        model's seam lines (:func:`_seam_lines`), if at hand."""
        for line in (_seam_lines(model) if lines is None else lines).get(tuple(self.pids), []):
            if self.nodes[0] in line:
                return line
        raise ValueError(f"seam at grids {list(self.nodes)}: no line of pid {self.pids[1]} on pid {self.pids[0]} "
                         "runs through them")

    def run(self, line: tuple[int, ...], start: int, n: int) -> Seam:
        """This seam (its values) on ``n`` grids of ``line`` from index ``start``."""
        nodes = tuple(line[start:start + n])
        return replace(self, nodes=nodes,
                       label=f"grids {nodes[0]}–{nodes[-1]} of pid {self.pids[1]} on pid {self.pids[0]}")

    def longer(self, line: tuple[int, ...]) -> list[Seam]:
        """Runs of each length of :data:`SEAM_SCREEN` shorter than ``line`` that overlap
        this one or lie next to it, half a length apart (clipped to the line): the
        stretches about it that screening offers."""
        start, n = line.index(self.nodes[0]), len(self.nodes)
        runs = [(int(np.clip(s, 0, len(line) - m)), m) for m in SEAM_SCREEN if m < len(line)
                for s in range(start - m, start + n + 1, max(1, m // 2))]
        return [self.run(line, s, m) for s, m in dict.fromkeys(runs)]

    def neighbours(self, line: tuple[int, ...], coarse: bool = False) -> list[Seam]:
        """The seams next to this one on its ``line``: one grid along it either way and
        each end one grid out or in; ``coarse``: half its length along either way, each
        end a quarter of its length out or in, both ends so (about the same centre), and
        the next length of :data:`SEAM_LENGTHS` up and down about the same centre. (On the
        33k barrel a run of 21 grids centred on the 31 loose ones fitted better than
        every run one grid longer or shorter at either end, and worse than the 31.)"""
        start, n = line.index(self.nodes[0]), len(self.nodes)
        along, d = (max(1, n // 2), max(1, n // 4)) if coarse else (1, 1)
        runs = [(start - along, n), (start + along, n),  # along the line
                (start - d, n + d), (start, n + d), (start + d, n - d), (start, n - d)]  # an end out or in
        if coarse:  # both ends out or in; the ladder, about the same centre
            runs += [(start - d, n + 2 * d), (start + d, n - 2 * d)]
            step = int(np.argmin(np.abs(np.asarray(SEAM_LENGTHS) - n)))
            runs += [(start + n // 2 - SEAM_LENGTHS[i] // 2, SEAM_LENGTHS[i]) for i in (step - 1, step + 1)
                     if 0 <= i < len(SEAM_LENGTHS)]
        runs = [(int(np.clip(s, 0, len(line) - m)), m) for s, m in runs if 2 <= m <= len(line)]
        return [self.run(line, s, m) for s, m in dict.fromkeys(runs) if (s, m) != (start, n)]

    def springs(self, before: Model, after: Model) -> dict[int, tuple[tuple[int, ...], tuple[int, ...]]]:
        """The springs :meth:`add_to` added (``before`` → ``after``) at each grid:
        (on translations, on rotations)."""
        trans, rot = self._halves(before, after)
        b = after.bushes
        at = {int(e): {int(after.node_ids[r]) for r in row} for e, row in zip(b.ids, np.asarray(b.nodes))}
        return {g: (tuple(e for e in trans if g in at[e]), tuple(e for e in rot if g in at[e])) for g in self.nodes}

    def shares(self, model: Model) -> np.ndarray:
        """Each grid's length of seam (m): half the distance to each neighbour on the line."""
        b, xyz = model.beams, np.asarray(model.xyz)
        rows = set(model.node_index(list(self.nodes)).tolist())
        shell = {int(r) for blk in (model.quads, model.trias) for p, row in zip(blk.pids, blk.nodes)
                 if int(p) == self.pids[0] for r in row if r >= 0}
        ends = np.asarray(b.nodes)[np.asarray(b.pids) == self.pids[1]][:, :2]
        out = []
        for r in model.node_index(list(self.nodes)):
            near = [j if i == r else i for i, j in ends if r in (i, j) and {i, j} <= shell | rows]
            out.append(0.5 * sum(np.linalg.norm(xyz[n] - xyz[r]) for n in near))
        return np.asarray(out)

    def add_to(self, model: Model) -> Model:
        return _release(model, self.nodes, self.pids, self._need("k_trans"), self._need("k_rot"), self.shares(model))

    def at_reference(self, model: Model, f_test_hz) -> Seam:
        """A joint's reference (:func:`~updating.diagnosis._topology.joint_reference` of the beams)
        per unit of the mean share: slightly softer than rigid."""
        side = [e for n in self.nodes for e, p in elements_at(model, n).items() if p == self.pids[1]]
        share = float(np.mean(self.shares(model)))
        if share <= 0:
            raise ValueError(f"seam at grids {list(self.nodes)}: no beam of pid {self.pids[1]} runs along "
                             f"them on the shells of pid {self.pids[0]}")
        return replace(self, **{k: v / share for k, v in joint_reference(model, self.nodes, side).items()})

    def plausibility(self, total_mass: float, reference: AbstractEffect | None = None) -> list[str]:
        return _rigid_note(self, reference)

    def advice(self, sd) -> str:
        s = np.broadcast_to(np.asarray(sd, float), (2,))
        return (f"make the seam at {self.where()} flexible: k_rot = {spread(self.k_rot, s[1], 'N·m/rad per m')}, "
                f"k_trans = {spread(self.k_trans, s[0], 'N/m per m')}")


def _seam_lines(model: Model) -> dict[tuple[int, int], list[tuple[int, ...]]]:
    """The lines of grids each beam group shares with each shell group, by (shell pid,
    beam pid): each line's grids in order along it (:func:`_chains`)."""
    shells = [(model.quads.pids, model.quads.nodes), (model.trias.pids, model.trias.nodes)]
    shell_rows = {int(p): set() for pids, _ in shells for p in pids}
    for pids, nodes in shells:
        for p, row in zip(pids, nodes):
            shell_rows[int(p)].update(int(r) for r in row if r >= 0)
    b, out = model.beams, {}
    for bp in sorted({int(p) for p in b.pids}):
        ends = np.asarray(b.nodes)[np.asarray(b.pids) == bp][:, :2]
        for sp, rows in sorted(shell_rows.items()):
            edges = [(int(i), int(j)) for i, j in ends if int(i) in rows and int(j) in rows]
            lines = [tuple(int(model.node_ids[r]) for r in line) for line in _chains(edges)]
            if lines:
                out[sp, bp] = lines
    return out


def _chains(edges: list[tuple[int, int]]) -> list[list[int]]:
    """The connected lines of ``edges`` (grid rows), each in order along the line (a ring
    from its lowest row)."""
    nbr: dict[int, list[int]] = {}
    for i, j in edges:
        nbr.setdefault(i, []).append(j)
        nbr.setdefault(j, []).append(i)
    seen, out = set(), []
    for start in sorted(nbr, key=lambda r: (len(nbr[r]) != 1, r)):  # line ends first
        if start in seen:
            continue
        line, prev, cur = [], None, start
        while cur is not None and cur not in seen:
            seen.add(cur)
            line.append(cur)
            nxt = [n for n in nbr[cur] if n != prev and n not in seen]
            prev, cur = cur, (nxt[0] if nxt else None)
        out.append(line)
    return out
