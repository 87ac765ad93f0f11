"""Two-node 3-D beam (Nastran CBAR/CBEAM with PBAR-type properties).

Element DoFs per node, in element axes from :func:`beam_axes`: [u, v, w, θx, θy, θz].
Plane 1 is x–y (deflection v, rotation θz = dv/dx, inertia I1 about element z);
plane 2 is x–z (deflection w, rotation θy = -dw/dx, inertia I2 about element y).
All public functions act on one element and return matrices in basic axes.
"""

import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._rod import rod_mass

_AXIAL = np.array([0, 6])
_TORSION = np.array([3, 9])
_PLANE1 = np.array([1, 5, 7, 11])  # v_A, θz_A, v_B, θz_B
_PLANE2 = np.array([2, 4, 8, 10])  # w_A, θy_A, w_B, θy_B
_FLIP2 = np.array([1.0, -1.0, 1.0, -1.0])  # θy = -dw/dx: plane-2 block = D·(plane-1 form)·D
_BAR = np.array([[1.0, -1.0], [-1.0, 1.0]])
_BAR_MASS = np.array([[2.0, 1.0], [1.0, 2.0]]) / 6.0


def skew(w: Float[ArrayLike, "3"]) -> Float[Array, "3 3"]:
    """Cross-product matrix: ``skew(w) @ a == w × a``."""
    w = jnp.asarray(w)
    zero = jnp.zeros_like(w[0])
    return jnp.array(
        [[zero, -w[2], w[1]], [w[2], zero, -w[0]], [-w[1], w[0], zero]]
    )


def beam_axes(
    xa: Float[ArrayLike, "3"], xb: Float[ArrayLike, "3"], v: Float[ArrayLike, "3"]
) -> Float[Array, "3 3"]:
    """Element axes of a CBAR/CBEAM (MSC Nastran QRG, CBAR: element coordinate system).

    Args:
        xa, xb: end-A and end-B positions in basic axes [m], shape (3,).
        v: orientation vector in basic axes, not parallel to xb - xa, shape (3,).

    Returns:
        (3, 3) rotation whose rows are the element x (A→B), y = z × x and
        z = x × v / |x × v| unit vectors in basic axes.
    """
    x = jnp.asarray(xb) - jnp.asarray(xa)
    x = x / jnp.linalg.norm(x)
    z = jnp.cross(x, jnp.asarray(v))
    z = z / jnp.linalg.norm(z)
    return jnp.stack([x, jnp.cross(z, x), z])


def rigid_offset(
    wa: Float[ArrayLike, "3"], wb: Float[ArrayLike, "3"]
) -> Float[Array, "12 12"]:
    """Rigid-offset transformation ``u_end = T u_grid`` for a two-node element.

    Per node ``[[I, -skew(w)], [0, I]]``: end translation = grid translation + θ × w,
    the rigid-link kinematics of the CBAR/CBUSH offsets (MSC Nastran QRG, CBAR WA/WB).

    Args:
        wa, wb: end position minus grid position for ends A and B, basic axes [m].

    Returns:
        (12, 12) block-diagonal T acting on [grid A 6 DoFs, grid B 6 DoFs].
    """
    eye = jnp.eye(3)
    zero = jnp.zeros((3, 3))

    def node(w):
        return jnp.block([[eye, -skew(w)], [zero, eye]])

    return jsl.block_diag(node(wa), node(wb))


def to_basic(
    axes: Float[ArrayLike, "3 3"], k_local: Float[ArrayLike, "12 12"]
) -> Float[Array, "12 12"]:
    """Rotate a two-node matrix from element to basic axes: ``Λᵀ k Λ`` with ``Λ = I₄ ⊗ axes``.

    Args:
        axes: (3, 3) rows are the element x, y, z unit vectors in basic axes.
        k_local: (12, 12) matrix on the element-axis DoFs of both ends.
    """
    lam = jnp.kron(jnp.eye(4), jnp.asarray(axes))
    return lam.T @ jnp.asarray(k_local) @ lam


def _shear_parameter(E, I, K, G, A, L):
    """Φ = 12 E I / (K G A L²) and the Timoshenko flag K·G·A > 0.

    Φ = 0 (Euler–Bernoulli) where K·G·A == 0 (Nastran: blank K = infinite shear
    stiffness); the inner ``where`` keeps the gradient finite there.
    """
    kga = K * G * A
    shear = kga > 0.0
    phi = jnp.where(shear, 12.0 * E * I / (jnp.where(shear, kga, 1.0) * L**2), 0.0)
    return phi, shear


def _bending_stiffness(EI, L, phi):
    """Planar bending stiffness on [v_A, θ_A, v_B, θ_B] with θ = dv/dx.

    Shear-deformable beam, Przemieniecki (1968), *Theory of Matrix Structural
    Analysis*, ch. 5 (same matrix as the interdependent-interpolation element of
    Friedman & Kosmatka 1993, Comput. Struct. 47(3)); Φ = 0 gives the
    Euler–Bernoulli matrix 2EI/L³[[6, 3L, -6, 3L], ...].
    """
    a = 12.0
    b = 6.0 * L
    c = (4.0 + phi) * L**2
    d = (2.0 - phi) * L**2
    k = jnp.array([[a, b, -a, b], [b, c, -b, d], [-a, -b, a, -b], [b, d, -b, c]])
    return EI / (L**3 * (1.0 + phi)) * k


def _bending_mass(mass_per_length, rho_i, L, phi):
    """Planar consistent bending mass on [v_A, θ_A, v_B, θ_B] with θ = dv/dx.

    Friedman & Kosmatka (1993), "An improved two-node Timoshenko beam finite
    element", Comput. Struct. 47(3) 473–481: mass matrix from the interdependent
    cubic/quadratic shape functions = translational part (m' L / (1+Φ)²) +
    rotary part (ρI / (L (1+Φ)²)). Φ = 0 with ρI = 0 gives the cubic Hermite
    (Euler–Bernoulli) consistent mass m'L/420·[[156, 22L, 54, -13L], ...].
    """
    p = phi
    t11 = 13.0 / 35.0 + 7.0 * p / 10.0 + p**2 / 3.0
    t12 = (11.0 / 210.0 + 11.0 * p / 120.0 + p**2 / 24.0) * L
    t13 = 9.0 / 70.0 + 3.0 * p / 10.0 + p**2 / 6.0
    t14 = (13.0 / 420.0 + 3.0 * p / 40.0 + p**2 / 24.0) * L
    t22 = (1.0 / 105.0 + p / 60.0 + p**2 / 120.0) * L**2
    t24 = (1.0 / 140.0 + p / 60.0 + p**2 / 120.0) * L**2
    trans = jnp.array(
        [
            [t11, t12, t13, -t14],
            [t12, t22, t14, -t24],
            [t13, t14, t11, -t12],
            [-t14, -t24, -t12, t22],
        ]
    )
    r11 = 6.0 / 5.0
    r12 = (1.0 / 10.0 - p / 2.0) * L
    r22 = (2.0 / 15.0 + p / 6.0 + p**2 / 3.0) * L**2
    r24 = (-1.0 / 30.0 - p / 6.0 + p**2 / 6.0) * L**2
    rot = jnp.array(
        [
            [r11, r12, -r11, r12],
            [r12, r22, -r12, r24],
            [-r11, -r12, r11, -r12],
            [r12, r24, -r12, r22],
        ]
    )
    scale = 1.0 / (1.0 + p) ** 2
    return scale * (mass_per_length * L * trans + rho_i / L * rot)


def _assemble_local(axial, torsion, plane1, plane2):
    """Place 2×2 axial/torsion and 4×4 plane-1/plane-2 blocks into a 12×12 local matrix."""
    out = jnp.zeros((12, 12))
    out = out.at[np.ix_(_AXIAL, _AXIAL)].set(axial)
    out = out.at[np.ix_(_TORSION, _TORSION)].set(torsion)
    out = out.at[np.ix_(_PLANE1, _PLANE1)].set(plane1)
    return out.at[np.ix_(_PLANE2, _PLANE2)].set(_FLIP2[:, None] * plane2 * _FLIP2)


def beam_stiffness(
    xa: Float[ArrayLike, "3"],
    xb: Float[ArrayLike, "3"],
    v: Float[ArrayLike, "3"],
    E: Float[ArrayLike, ""],
    G: Float[ArrayLike, ""],
    A: Float[ArrayLike, ""],
    I1: Float[ArrayLike, ""],
    I2: Float[ArrayLike, ""],
    J: Float[ArrayLike, ""],
    K1: Float[ArrayLike, ""],
    K2: Float[ArrayLike, ""],
) -> Float[Array, "12 12"]:
    """Stiffness of a 3-D two-node beam between end points, in basic axes.

    Axial EA/L, torsion GJ/L, bending per plane with Φᵢ = 12 E Iᵢ / (Kᵢ G A L²)
    (Timoshenko, Przemieniecki 1968, ch. 5) when Kᵢ G A > 0, Euler–Bernoulli
    (Φᵢ = 0) when Kᵢ == 0.

    Args:
        xa, xb: end positions (rigid offsets already applied) in basic axes [m].
        v: orientation vector in basic axes.
        E, G: Young's and shear moduli [Pa].
        A: area [m²]; I1, I2: area moments for planes 1 and 2 [m⁴]; J: torsion constant [m⁴].
        K1, K2: shear area factors for planes 1 (shear along y) and 2 (along z) [-].

    Returns:
        (12, 12) symmetric stiffness [N/m, N/rad, N·m/rad] on the end DoFs.
    """
    axes = beam_axes(xa, xb, v)
    L = jnp.linalg.norm(jnp.asarray(xb) - jnp.asarray(xa))
    phi1, _ = _shear_parameter(E, I1, K1, G, A, L)
    phi2, _ = _shear_parameter(E, I2, K2, G, A, L)
    k = _assemble_local(
        E * A / L * _BAR,
        G * J / L * _BAR,
        _bending_stiffness(E * I1, L, phi1),
        _bending_stiffness(E * I2, L, phi2),
    )
    return to_basic(axes, k)


def beam_mass(
    xa: Float[ArrayLike, "3"],
    xb: Float[ArrayLike, "3"],
    v: Float[ArrayLike, "3"],
    rho: Float[ArrayLike, ""],
    A: Float[ArrayLike, ""],
    nsm: Float[ArrayLike, ""],
    I1: Float[ArrayLike, ""],
    I2: Float[ArrayLike, ""],
    K1: Float[ArrayLike, ""],
    K2: Float[ArrayLike, ""],
    E: Float[ArrayLike, ""],
    G: Float[ArrayLike, ""],
    lumped: bool,
) -> Float[Array, "12 12"]:
    """Mass of a 3-D two-node beam between end points, in basic axes.

    Consistent (``lumped=False``): axial m'L/6·[[2,1],[1,2]], torsion
    ρ(I1+I2)L/6·[[2,1],[1,2]], bending per plane with the interdependent-
    interpolation mass of Friedman & Kosmatka (1993) including rotary inertia ρIᵢ
    when Kᵢ G A > 0, and the cubic Hermite mass without rotary inertia when
    Kᵢ == 0 (Nastran CBAR). Lumped (``lumped=True``): m'L/2 on each translation
    of each end, no rotational inertia (Nastran COUPMASS=-1).

    Args:
        xa, xb: end positions in basic axes [m]; v: orientation vector.
        rho: density [kg/m³]; A: area [m²]; nsm: non-structural mass [kg/m].
        I1, I2: area moments for planes 1 and 2 [m⁴].
        K1, K2: shear area factors [-]; E, G: moduli [Pa] (for Φᵢ).
        lumped: static Python bool selecting the lumped matrix.

    Returns:
        (12, 12) symmetric mass [kg, kg·m, kg·m²] on the end DoFs.
    """
    if lumped:
        return rod_mass(xa, xb, rho, A, nsm, True)
    axes = beam_axes(xa, xb, v)
    L = jnp.linalg.norm(jnp.asarray(xb) - jnp.asarray(xa))
    m_len = rho * A + nsm
    phi1, shear1 = _shear_parameter(E, I1, K1, G, A, L)
    phi2, shear2 = _shear_parameter(E, I2, K2, G, A, L)
    m = _assemble_local(
        m_len * L * _BAR_MASS,
        rho * (I1 + I2) * L * _BAR_MASS,
        _bending_mass(m_len, jnp.where(shear1, rho * I1, 0.0), L, phi1),
        _bending_mass(m_len, jnp.where(shear2, rho * I2, 0.0), L, phi2),
    )
    return to_basic(axes, m)


def beam_lumped_torsion(
    xa: Float[ArrayLike, "3"], xb: Float[ArrayLike, "3"], rho: Float[ArrayLike, ""], I1: Float[ArrayLike, ""],
    I2: Float[ArrayLike, ""],
) -> Float[Array, "12 12"]:
    """Lumped torsional inertia of a CBEAM, ρ(I1 + I2)L/2 about the axis at each end, in
    basic axes (Nastran's lumped CBEAM mass has it, the CBAR's has not)."""
    e = jnp.asarray(xb) - jnp.asarray(xa)
    L = jnp.linalg.norm(e)
    block = rho * (I1 + I2) * L / 2.0 * jnp.outer(e, e) / L**2
    out = jnp.zeros((12, 12))
    return out.at[3:6, 3:6].set(block).at[9:12, 9:12].set(block)
