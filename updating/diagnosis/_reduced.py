"""The Ritz basis of the diagnosis' reduced fits (:class:`updating._eigensolvers.Reduced`).

A diagnosis fits tens of candidates, each a change of one model in a few parameters. On a
large model every step of every fit would solve the full eigenproblem. The modes of the
changed model are sought in the span of

- the baseline's q lowest modes;
- along the engineer's parameters (groups, global): the static responses to the forces
  each parameter's change exerts on the paired modes, ``(K − σM)⁻¹ (∂_i K − λ_j ∂_i M) φ_j``
  (the first-order modal expansion with its static correction, eq. 3.23 with eq. 3.28);
- along a candidate's parameters (a local change): the static responses to unit loads at
  every DoF the change touches, ``(K − σM)⁻¹ e_d`` (attachment modes), and one step of
  inverse iteration on them, ``(K − σM)⁻¹ M (K − σM)⁻¹ e_d``. A change ΔK of any size
  on those DoFs changes the static flexibility only in their span (Woodbury), so these
  hold a joint released or a patch delaminated, not only a small step. Springs that hold
  a connection stiff (a released joint, seam or support) take the loads their change
  exerts instead, ``(K − σM)⁻¹ ∂K e_d``, which span the same range ΔK has at any scale
  (k e^θ): for unit loads the motion across the connection is the difference of two
  nearly equal columns, which the M-orthonormalisation drops (a seam softened e⁻¹²
  left the reduced eigenvalues unchanged); both sets together widened the bases and ran
  the 33k diagnosis past 10 minutes. A candidate
  touching more than ``ATTACH_MAX`` DoFs (a whole group; twice as many for held springs,
  whose change load is one column from either end) gets the first-order columns.

The basis is M-orthonormalised. The reduced eigenvalues are Rayleigh quotients, so their
error is of second order in the shapes' error. The baseline's part is made once.

A fit step then costs what the elements θ changes cost: with a ``pool`` of element ids
(the diagnosis' region, :attr:`Bases.pool`) that holds every element a candidate
changes, only the pool is assembled and projected at each θ, the rest once
(:class:`~updating._eigensolvers.Reduced`). Without engineer's parameters, a candidate
whose K and M are linear in each factor e^θᵢ (a group's factor, woken masses or springs,
springs holding a connection, a patch's part of its shells' stiffness; checked at one
step, :meth:`Bases._linear`) changes them along one projected matrix per parameter: no
assembly at any θ. A candidate changing anything else (a material, a group beside the engineer's
parameters) assembles the whole model at each θ.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import scipy.sparse

import jaxfem
from jaxfem import ELEMENT_BLOCKS

from .. import Compiled, Problem, Reduced, pair
from ._element_sensitivity import _modes
from ._fit import EXTENSION_PARAMS, with_extension

ATTACH_MAX = 400  # DoFs a candidate may touch for attachment columns; more: first-order columns
WIDTHS = (96, 2.0, 32)  # a basis is padded to the next width of 96, then ×2 (one compiled fit per width)
LINEAR_STEP = (0.7, -0.9)  # the step along the candidate's parameters at which Bases._linear checks K(θ) and M(θ)
LINEAR_RTOL = 1e-10  # their largest departure from the linear forms, relative to their largest entry
MASS_FLOOR = 1e-10  # basis directions of M-norm² below this share of the largest are dropped


def _loads(theta, problem: Problem, tangents, phi, lam):
    """``(∂K − λ_j ∂M) φ_j`` along each row of ``tangents``: (n, tangents × modes)."""

    def one(d):
        dK, dM = _derivative(theta, problem, d)
        return dK.matmul(phi) - dM.matmul(phi) * lam

    out = jax.lax.map(one, tangents)
    return jnp.moveaxis(out, 0, 1).reshape(phi.shape[0], -1)


def _assembled(theta, problem: Problem, pool):
    """K(θ), M(θ), element-stacked, of the elements ``pool`` (all when None)."""
    model = problem.model(theta)
    return jaxfem.assemble(model if pool is None else model.restricted(pool))


def _derivative(theta, problem: Problem, d, pool=None):
    """∂K, ∂M along the direction ``d``, element-stacked, of the elements ``pool`` (all when None)."""
    (K, M), (dK, dM) = jax.jvp(lambda t: _assembled(t, problem, pool), (theta,), (d,))
    return K.with_values(dK.values()), M.with_values(dM.values())


def _touched(theta, problem: Problem, tangents, pool):
    """Per DoF, Σ |∂K| + |∂M| over the rows along ``tangents``: nonzero where they touch
    (the elements ``pool`` assembled, all when None)."""

    def one(d):
        derivative = _derivative(theta, problem, d, pool)
        ones = jnp.ones((derivative[0].n, 1))
        return sum(A.with_values(jax.tree.map(jnp.abs, A.values())).matmul(ones)[:, 0] for A in derivative)

    return jnp.sum(jax.lax.map(one, tangents), axis=0)


def _changes(theta, problem: Problem, d):
    """Along the direction ``d``: per element block, Σ |∂| of each element's data; and Σ |∂|
    of everything else in the model (materials, sections, a law)."""
    m, dm = eqx.filter_jvp(problem.model, (theta,), (d,))

    def size(x):
        return jnp.sum(jnp.abs(x).reshape(x.shape[0], -1), axis=1) if x.size else jnp.zeros(x.shape[0])

    blocks = {n: sum((size(x) for x in jax.tree.leaves(getattr(dm, n))), jnp.zeros(len(getattr(m, n).ids)))
              for n in ELEMENT_BLOCKS}
    rest = eqx.tree_at(lambda m: tuple(getattr(m, n) for n in ELEMENT_BLOCKS), dm,
                       replace=(None,) * len(ELEMENT_BLOCKS))
    return blocks, sum((jnp.sum(jnp.abs(x)) for x in jax.tree.leaves(rest)), jnp.zeros(()))


class Bases:
    """The baseline's modes, its factorisation of K − σM and its static corrections along
    the engineer's parameters, at θ_b; :meth:`reduced` adds a candidate's columns.

    ``problem`` carries an extension of one parameter at 0 (the diagnosis' ``none``), θ_b
    the engineer's log-factors and that 0. ``pool``: element ids (sorted) assembled at each
    step of a candidate that changes only these (module docstring; at first none, which
    serves the baseline without parameters); None: the whole model at each step.
    ``modes``: the baseline's (:func:`~updating.diagnosis._element_sensitivity._modes`)."""

    def __init__(self, problem: Problem, theta_b):
        # the matrices are compiled once for all candidates (their masks are arrays), their
        # products taken on the host (a compiled product would compile anew at every basis width)
        self._loads, self._touched, self._matrices = Compiled(_loads), Compiled(_touched), Compiled(_assembled)
        self._changes, self._derivative = Compiled(_changes), Compiled(_derivative)
        self._problem, self._theta = problem, jnp.asarray(theta_b, dtype=jnp.float64)
        theta = self._theta
        self.modes = _modes(problem, theta, problem.model(theta))  # also the baseline's screen's
        _, lam, Phi, self._solve, _ = self.modes
        q = problem.n_model
        lam, Phi = lam[:q], Phi[:, :q]
        index, paired = (np.asarray(a) for a in pair(jnp.asarray(lam), problem.C @ jnp.asarray(Phi), problem))
        j = np.unique(index[paired])
        self.phi, self.lam = Phi[:, j], lam[j]
        self.theta_b = np.asarray(theta[:-1])
        self.n_b = len(self.theta_b)
        common = [Phi] + ([self._corrections(problem, theta, np.eye(len(theta))[: self.n_b])] if self.n_b else [])
        self.common = np.concatenate(common, axis=1)
        self._full = tuple(A.tocsr() for A in self._matrices(theta, problem, None))
        self.pool = ()  # the baseline without parameters changes no element

    def _corrections(self, problem: Problem, theta, tangents) -> np.ndarray:
        loads = self._loads(theta, problem, jnp.asarray(tangents), jnp.asarray(self.phi), jnp.asarray(self.lam))
        return np.asarray(self._solve(np.asarray(loads)))

    @property
    def pool(self) -> tuple[int, ...] | None:
        """Element ids assembled at each step of the candidates they serve (class docstring)."""
        return self._pool

    @pool.setter
    def pool(self, eids: tuple[int, ...] | None):
        """Set the pool; the rest of K and M (constant for the candidates it serves) is
        assembled once, at θ_b."""
        self._pool = eids
        if eids is not None:
            part = self._matrices(self._theta, self._problem, eids)
            self._rest = tuple(a - b.tocsr() for a, b in zip(self._full, part))

    def _changed(self, theta, problem: Problem, n: int) -> np.ndarray | None:
        """Ids of the elements whose data change with any of the first ``n`` parameters (the
        engineer's and the candidate's); None when anything else of the model changes too."""
        ids = []
        for d in np.eye(len(theta))[:n]:
            blocks, rest = self._changes(theta, problem, jnp.asarray(d))
            if float(rest) != 0.0:
                return None
            ids += [np.asarray(getattr(problem.structure.value, n).ids)[np.asarray(v) != 0] for n, v in blocks.items()]
        return np.unique(np.concatenate(ids)) if ids else np.zeros(0, np.int64)

    @staticmethod
    def _linear(at, moved, slopes, step) -> bool:
        """Whether the element matrices ``moved`` (K, M at θ + ``step``) are those at θ
        (``at``) changed linearly in each factor e^θᵢ along the derivatives ``slopes``
        (one (∂K, ∂M) per parameter, None along the padding): K(θ + s) = K(θ) + Σᵢ
        (e^sᵢ − 1) ∂ᵢK(θ), as where each parameter scales its own elements or their part
        of a shell's stiffness (:class:`Reduced`'s ``linear``)."""
        factors = np.expm1(step)
        for i in (0, 1):
            for j, (a, b) in enumerate(zip(at[i].values(), moved[i].values())):
                guess = np.asarray(a) + sum(f * np.asarray(d[i].values()[j]) for f, d in zip(factors, slopes)
                                            if d is not None)
                if np.max(np.abs(np.asarray(b) - guess), initial=0.0) > LINEAR_RTOL * np.max(np.abs(b), initial=0.0):
                    return False
        return True

    @staticmethod
    def _change_loads(slopes, touched: np.ndarray, n: int) -> scipy.sparse.csc_matrix:
        """``∂K e_d`` and ``∂M e_d`` along each parameter (``slopes``: its (∂K, ∂M), None
        along the padding), for each touched DoF d (their columns; ``n`` DoFs): the
        loads a change exerts across its own elements (a spring's k (e_a − e_b)). Their
        static responses hold the motion across a connection released and held stiff (a
        joint, a seam), which the unit loads' responses hold only as the difference of two
        nearly equal columns, below :data:`MASS_FLOOR`. Taken from the sparse derivative
        (a product with unit columns, in JAX, took 7 of a 33k seam's 10 s basis)."""
        cols = [A.tocsc()[:, touched] for d in slopes if d is not None for A in d]
        loads = scipy.sparse.hstack(cols, format="csc") if cols else scipy.sparse.csc_matrix((n, 0))
        loads.eliminate_zeros()
        return loads[:, np.flatnonzero(np.diff(loads.indptr))]

    def reduced(self, problem: Problem, ext, theta_c, held: bool = False) -> Reduced:
        """The :class:`Reduced` eigensolver of one candidate (``ext``, its θ at ``theta_c``):
        the baseline's columns and the candidate's (module docstring); it assembles only
        the :attr:`pool` when that holds every element the parameters change. ``held``: the
        candidate scales springs that hold a connection stiff (a released joint, seam or
        support): its attachment columns are the responses to its change loads
        (:meth:`_change_loads`), not to unit loads."""
        p = with_extension(problem, ext)
        theta_c = np.atleast_1d(np.asarray(theta_c, float))
        # padded as the fits are (EXTENSION_PARAMS): one compiled function for every kind
        n = self.n_b + len(theta_c)
        theta = jnp.asarray(np.concatenate([self.theta_b, theta_c, np.zeros(EXTENSION_PARAMS - len(theta_c))]))
        tangents = jnp.asarray(np.eye(len(theta))[self.n_b:] * (np.arange(EXTENSION_PARAMS) < len(theta_c))[:, None])
        changed = self._changed(theta, p, n) if self.pool is not None else None
        pool = self.pool if changed is not None and np.isin(changed, self.pool).all() else None
        group = self.n_b == 0 and ext.scales_only()  # a group's factor alone: linear by construction
        # ∂K, ∂M along each parameter (None along the padding), of the pool (all when None)
        slopes = [self._derivative(theta, p, d, pool) if bool(d.any()) else None for d in tangents] \
            if pool is not None or held or group else None
        if pool is not None:  # K and M at θ: the rest, and the pool assembled
            part = self._matrices(theta, p, pool)
            step = np.resize(LINEAR_STEP, len(tangents)) * np.asarray(tangents).any(axis=1)
            linear = self.n_b == 0 and self._linear(
                part, self._matrices(theta + jnp.asarray(step) @ tangents, p, pool), slopes, step)
            at = tuple(a + b.tocsr() for a, b in zip(self._rest, part))
        else:  # a group's factor at θ = 0 changes nothing
            linear = group
            at = self._full if linear else tuple(A.tocsr() for A in self._matrices(theta, p, None))
        host = [None if d is None else tuple(A.tocsr() for A in d) for d in slopes] if held or linear else None
        touched = np.flatnonzero(np.asarray(self._touched(theta, p, tangents, pool)))
        M = at[1]
        if len(touched) <= ATTACH_MAX * (2 if held else 1):  # a held spring's load is one column from either end
            if held:
                loads = _distinct(self._change_loads(host, touched, len(self.phi))).toarray()
            else:
                loads = np.zeros((len(self.phi), len(touched)))
                loads[touched, np.arange(len(touched))] = 1.0
            static = np.asarray(self._solve(loads))
            dynamic = np.asarray(self._solve(M @ static))
            own = np.concatenate([static, dynamic], axis=1)
        else:
            own = self._corrections(p, theta, tangents)
        V = np.concatenate([self.common, own], axis=1)
        V = _orthonormal(V, V.T @ (M @ V))
        columns, r = V.shape[1], _width(V.shape[1])
        V, padding = np.pad(V, ((0, 0), (0, r - columns))), jnp.arange(r) >= columns
        head = (jnp.asarray(V), padding, jnp.asarray(np.asarray(problem.C) @ V))
        project = lambda matrices: tuple(jnp.asarray(_project(A, V)) for A in matrices)  # noqa: E731
        if linear:  # Vᵀ ∂ᵢK V and Vᵀ ∂ᵢM V along each parameter (zero along the padding)
            zero = scipy.sparse.csr_matrix(at[0].shape)
            host = [(zero, zero) if d is None else d for d in host]
            return Reduced(*head, project(at), linear=tuple(jnp.stack(project(d[i] for d in host)) for i in (0, 1)),
                           centre=theta[self.n_b:])
        if pool is None:
            return Reduced(*head)
        return Reduced(*head, project(self._rest), pool)


def _project(A: scipy.sparse.csr_matrix, V: np.ndarray) -> np.ndarray:
    """``Vᵀ A V`` over the rows of A that hold entries (a candidate's derivative touches a
    few hundred of 33,000: the n × r² product took seconds)."""
    rows = np.flatnonzero(np.diff(A.indptr))
    return V[rows].T @ (A[rows] @ V)


def _width(columns: int) -> int:
    """The padded width of a basis of ``columns`` (:data:`WIDTHS`: 96, 192, 384, 768, ...)."""
    r, growth, multiple = WIDTHS
    while r < columns:
        r = -(-int(r * growth) // multiple) * multiple
    return r


def _distinct(loads: scipy.sparse.csc_matrix) -> scipy.sparse.csc_matrix:
    """The columns of ``loads`` (nonzero ones) that differ beyond sign and scale: a
    spring's change load k (e_a − e_b) comes from either of its ends."""
    loads, seen, keep = loads.sorted_indices(), set(), []
    for j in range(loads.shape[1]):
        rows, values = (a[loads.indptr[j]:loads.indptr[j + 1]] for a in (loads.indices, loads.data))
        key = (rows.tobytes(), np.round(values / values[np.argmax(np.abs(values))], 12).tobytes())
        if key not in seen:
            seen.add(key)
            keep.append(j)
    return loads[:, keep]


def _orthonormal(V: np.ndarray, G: np.ndarray) -> np.ndarray:
    """V M-orthonormalised from its Gram matrix G = Vᵀ M V, each column first scaled to a
    unit M-norm; directions of M-norm² below ``MASS_FLOOR`` then (a column repeated, a
    load that vanishes) dropped."""
    d = np.sqrt(np.maximum(np.diag(G), 0.0))
    d = np.where(d > 0, d, 1.0)
    w, U = np.linalg.eigh(0.5 * (G + G.T) / np.outer(d, d))
    keep = w > MASS_FLOOR * w.max()
    return (V / d) @ (U[:, keep] / np.sqrt(w[keep]))
