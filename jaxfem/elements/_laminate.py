"""Shell section stiffness and inertia: PSHELL roles and classical lamination theory.

The section relates membrane forces N, moments M and transverse shear forces Q to the
mid-surface strains ε, curvatures κ and shear strains γ (Reddy 2004, *Mechanics of
Laminated Composite Plates and Shells*, (3.3.17) and (3.4.26)):

``[N; M] = [[A, B], [B, D]] [ε; κ]``, ``Q = S γ``, with engineering shear strains.

A lamina of material axes at angle θ from the element x axis has ``Q̄ = T_εᵀ Q T_ε`` and
``Q̄_s = Rᵀ Q_s R`` (Reddy 2004, (2.3.17)). For a PCOMP of plies k between z_k and z_{k+1}
(z from Z0 up): ``A = Σ Q̄_k Δz``, ``B = ½ Σ Q̄_k Δz²``, ``D = ⅓ Σ Q̄_k Δz³`` (Reddy
(3.3.17)), ``S = 5/6 Σ Q̄_s,k Δz`` (the shear correction of a homogeneous section). A PSHELL
(MSC QRG, PSHELL) has ``A = T·G1``, ``D = (12I/T³)·T³/12·G2``, ``B = T²·G4``,
``S = (TS/T)·T·G3`` with Gi the matrices of MIDi. The inertia per unit area is
``I0 = ∫ρ dz + NSM``, ``I1 = ∫ρ z dz``, ``I2 = ∫ρ z² dz`` (PSHELL: the density of MID1,
or MID2 without MID1; I2 = ρT³/12).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .. import MAT2, MAT8, Materials, ShellSections  # exported before jaxfem imports this package

SHEAR_CORRECTION = 5.0 / 6.0


class Laminate(eqx.Module):
    """Section matrices of one shell element (element axes), see the module docstring.

    A [N/m], B [N], D [N·m], S [N/m]; I0 [kg/m²], I1 [kg/m], I2 [kg]; ``rigid`` is 1.0
    where the section has no transverse-shear flexibility (the element then takes a
    shear stiffness far above its bending stiffness, see :func:`jaxfem.elements.shell_stiffness`).
    """

    A: Float[Array, "3 3"]
    B: Float[Array, "3 3"]
    D: Float[Array, "3 3"]
    S: Float[Array, "2 2"]
    I0: Float[Array, ""]
    I1: Float[Array, ""]
    I2: Float[Array, ""]
    rigid: Float[Array, ""]


def material_matrices(kind, E, G, nu, E2, G1z, G2z, Q) -> tuple[Float[Array, "3 3"], Float[Array, "2 2"]]:
    """Plane-stress matrix Q (3 × 3, engineering shear) and transverse-shear matrix (2 × 2)
    of one material row of :class:`jaxfem.Materials` in its own axes [Pa].

    MAT1: ``E/(1−ν²)·[[1, ν], [ν, 1]]`` and Q66 = G; shear G·I. MAT8: ν21 = ν12·E2/E1,
    ``Q11 = E1/(1−ν12ν21)``, ``Q22 = E2/(1−ν12ν21)``, ``Q12 = ν12·Q22``, Q66 = G12
    (Reddy 2004, (2.3.9)); shear diag(G1Z, G2Z). MAT2: Q as given; shear its upper 2 × 2.
    """
    is8, is2 = kind == MAT8, kind == MAT2
    E = jnp.where(is2, 1.0, E)  # MAT2 rows carry no E: keep the unused branch finite
    e2 = jnp.where(is8, E2, E)
    nu21 = nu * e2 / E
    d = 1.0 - nu * nu21
    q11, q22 = E / d, e2 / d
    iso = jnp.array([[q11, nu * q22, 0.0], [nu * q22, q22, 0.0], [0.0, 0.0, G]])
    shear = jnp.where(is8, jnp.diag(jnp.stack([G1z, G2z])), G * jnp.eye(2))
    return jnp.where(is2, Q, iso), jnp.where(is2, Q[:2, :2], shear)


def rotate(q: Float[Array, "3 3"], qs: Float[Array, "2 2"], theta) -> tuple[Float[Array, "3 3"], Float[Array, "2 2"]]:
    """``Q̄ = T_εᵀ Q T_ε``, ``Q̄_s = Rᵀ Q_s R`` for material axis 1 at ``theta`` [rad] from x."""
    c, s = jnp.cos(theta), jnp.sin(theta)
    t = jnp.array([[c * c, s * s, c * s], [s * s, c * c, -c * s], [-2 * c * s, 2 * c * s, c * c - s * s]])
    r = jnp.array([[c, s], [-s, c]])
    return t.T @ q @ t, r.T @ qs @ r


def _materials(mats: Materials, rows):
    """Material matrices and densities for an array of material rows (any shape)."""
    safe = np.maximum(rows, 0)
    fields = (mats.E, mats.G, mats.nu, mats.E2, mats.G1z, mats.G2z)
    q, qs = jnp.vectorize(material_matrices, signature="(),(),(),(),(),(),(),(3,3)->(3,3),(2,2)")(
        jnp.asarray(mats.kind[safe]), *(f[safe] for f in fields), mats.Q[safe]
    )
    return q, qs, mats.rho[safe]


def laminates(sections: ShellSections, mats: Materials, rows: np.ndarray, theta: Float[Array, " n"],
              zoffs: Float[Array, " n"], parts: Float[Array, "n 3"] | None = None,
              nsm: Float[Array, " n"] | None = None) -> Laminate:
    """Section matrices of n elements (stacked :class:`Laminate`): ``rows`` are their rows in
    ``sections``, ``theta`` their material angles [rad], ``zoffs`` their offsets [m];
    ``parts`` element factors on membrane, bending and shear (times the section's),
    ``nsm`` element non-structural mass [kg/m²] added to the section's.

    The updating factors scale A, D and S (B by √(membrane·bending)); the offset z₀ then
    moves the reference plane: ``B ← B + z₀A``, ``D ← D + 2z₀B + z₀²A``, ``I1 ← I1 + z₀I0``,
    ``I2 ← I2 + 2z₀I1 + z₀²I0`` (Reddy 2004, (3.3.17) with z shifted).
    """
    sec = jax.tree.map(lambda a: a[rows], sections)
    if parts is not None:
        sec = eqx.tree_at(lambda s: (s.membrane, s.bending, s.shear), sec,
                          (sec.membrane * parts[:, 0], sec.bending * parts[:, 1], sec.shear * parts[:, 2]))
    if nsm is not None:
        sec = eqx.tree_at(lambda s: s.nsm, sec, sec.nsm + nsm)
    composite = jnp.asarray(sec.composite)

    # PSHELL: one matrix per role MID1..MID4 (a blank role contributes nothing).
    roles = np.asarray(sec.materials)
    q, qs, rho = _materials(mats, roles)  # (n, 4, ...)
    given = jnp.asarray(roles >= 0, dtype=jnp.float64)
    t = sec.t
    rot = jax.vmap(rotate, in_axes=(0, 0, 0))
    q1, qs3 = rot(q[:, 0] * given[:, 0, None, None], qs[:, 2] * given[:, 2, None, None], theta)
    q2, _ = rot(q[:, 1] * given[:, 1, None, None], qs[:, 1], theta)
    q4, _ = rot(q[:, 3] * given[:, 3, None, None], qs[:, 3], theta)
    t1, t2, t3 = t[:, None, None], t[:, None, None] ** 2, t[:, None, None] ** 3
    a_p = q1 * t1
    d_p = q2 * (sec.bending_ratio[:, None, None] * t3 / 12.0)
    b_p = q4 * t2
    s_p = qs3 * (sec.shear_ratio[:, None, None] * t1)
    rho_p = jnp.where(given[:, 0] > 0, rho[:, 0], rho[:, 1] * given[:, 1])
    i0_p, i1_p, i2_p = rho_p * t, jnp.zeros_like(t), rho_p * t**3 / 12.0

    # PCOMP: plies from z0 up.
    qk, qsk, rhok = _materials(mats, np.asarray(sec.ply_material))  # (n, P, ...)
    ply = jnp.asarray(np.asarray(sec.ply_material) >= 0, dtype=jnp.float64) * sec.ply_t
    z = sec.z0[:, None] + jnp.concatenate([jnp.zeros_like(ply[:, :1]), jnp.cumsum(ply, axis=1)], axis=1)
    dz = [(z[:, 1:] ** p - z[:, :-1] ** p) / p for p in (1, 2, 3)]
    qbar, qsbar = jax.vmap(jax.vmap(rotate))(qk, qsk, theta[:, None] + sec.ply_theta)
    a_c, b_c, d_c = (jnp.einsum("np,npij->nij", w, qbar) for w in dz)
    s_c = SHEAR_CORRECTION * jnp.einsum("np,npij->nij", dz[0], qsbar)
    i0_c, i1_c, i2_c = (jnp.sum(rhok * w, axis=1) for w in dz)

    def pick(c, p):
        return jnp.where(composite.reshape((-1,) + (1,) * (c.ndim - 1)), c, p)

    fm, fb, fs = sec.membrane[:, None, None], sec.bending[:, None, None], sec.shear[:, None, None]
    a = pick(a_c, a_p) * fm
    b = pick(b_c, b_p) * jnp.sqrt(fm * fb)
    d = pick(d_c, d_p) * fb
    s = pick(s_c, s_p) * fs
    i0 = pick(i0_c, i0_p) + sec.nsm
    i1, i2 = pick(i1_c, i1_p), pick(i2_c, i2_p)
    z0 = zoffs[:, None, None]
    return Laminate(
        A=a, B=b + z0 * a, D=d + 2.0 * z0 * b + z0**2 * a, S=s,
        I0=i0, I1=i1 + zoffs * i0, I2=i2 + 2.0 * zoffs * i1 + zoffs**2 * i0,
        rigid=jnp.asarray(sec.shear_rigid, dtype=jnp.float64),
    )
