"""Nastran's standard beam-section library (MSC Nastran QRG, PBARL and PBEAML, Figure 1:
group MSCBML0): section properties from the dimensions DIM1..DIMn of each TYPE.

Axes as in the QRG figures: element y up, z to the right; I1 = ∫y² dA (plane 1, about z),
I2 = ∫z² dA, I12 = ∫yz dA, all about the centroid. Each section function takes the
dimensions (a sequence: floats, or a ``jax.numpy`` array) and is plain arithmetic: pure,
jit- and grad-safe (jax arrays in, jax arrays out), and fast on floats. It returns
``(A, I1, I2, I12, J, K1, K2)``.

- A, I1, I2, I12: exact for the drawn shape (rectangles and the parallel-axis theorem;
  HEXA a rectangle and two triangles; ROD and TUBE circles). I12 ≠ 0 for L and Z, and for
  BOX1 and DBOX unless symmetric about one axis.
- J, the rules: ROD, TUBE, TUBE2 the polar moment (exact); BAR Roark's rectangle; open
  thin-walled sections Σ l t³ / 3 over the walls, l the wall's mid-line length (to a free
  edge or to the mid-line of the wall it meets; for I, T, L, CHAN the formulas pyNastran
  quotes from the NX Nastran Element Library Reference); BOX, BOX1 Bredt 4 Aₘ² / ∮ ds/t on the
  mid-lines; DBOX two-cell Bredt; HAT1 Bredt on its cell plus Σ l t³ / 3 of the plate and
  brim strips outside it; HEXA Saint-Venant's approximation A⁴ / (4π² (I1 + I2)) (3 %
  above the exact value of a regular hexagon).
- K1, K2 (shear along y, z): the area of the walls parallel to y (z) over A: open sections
  each wall clear of the walls it meets (that reference's rule for L and CHAN), closed sections
  (BOX, BOX1, DBOX) the walls at full length; solid sections BAR and HEXA 5/6, ROD 0.9,
  TUBE and TUBE2 0.5 (thin-walled circular tube).

Not modelled: the offset of the shear centre from the centroid (the element axis runs
through the centroid) and warping.
"""

from __future__ import annotations

import math

import jax.numpy as jnp

from .io import PBARL_DIMENSIONS

PI = math.pi


def _rects(parts):
    """A, I1, I2, I12 about the centroid of rectangles ``(b along z, h along y, z, y of centre)``."""
    area = sum(b * h for b, h, _, _ in parts)
    zc = sum(b * h * z for b, h, z, _ in parts) / area
    yc = sum(b * h * y for b, h, _, y in parts) / area
    i1 = sum(b * h**3 / 12 + b * h * (y - yc) ** 2 for b, h, _, y in parts)
    i2 = sum(h * b**3 / 12 + b * h * (z - zc) ** 2 for b, h, z, _ in parts)
    i12 = sum(b * h * (y - yc) * (z - zc) for b, h, z, y in parts)
    return area, i1, i2, i12


def _symmetric(parts, j, k1_area, k2_area):
    """Properties of a section symmetric about y or z (I12 = 0), with web areas for K1, K2."""
    area, i1, i2, _ = _rects(parts)
    return area, i1, i2, 0.0, j, k1_area / area, k2_area / area


def rod(d):
    """DIM1 radius."""
    (r,) = d
    i = PI * r**4 / 4
    return PI * r**2, i, i, 0.0, 2 * i, 0.9, 0.9


def tube(d):
    """DIM1 outer, DIM2 inner radius."""
    ro, ri = d
    i = PI * (ro**4 - ri**4) / 4
    return PI * (ro**2 - ri**2), i, i, 0.0, 2 * i, 0.5, 0.5


def tube2(d):
    """DIM1 outer radius, DIM2 wall thickness."""
    ro, t = d
    return tube((ro, ro - t))


def bar(d):
    """DIM1 width (z), DIM2 height (y). J: Roark (7th ed.) table 10.7 case 4,
    J = l s³ [1/3 − 0.21 (s/l)(1 − s⁴ / (12 l⁴))], l the long side, s the short one."""
    b, h = d
    long, short = (b + h + abs(b - h)) / 2, (b + h - abs(b - h)) / 2
    j = long * short**3 * (1 / 3 - 0.21 * short / long * (1 - short**4 / (12 * long**4)))
    return b * h, b * h**3 / 12, h * b**3 / 12, 0.0, j, 5 / 6, 5 / 6


def box1(d):
    """DIM1 width, DIM2 height, DIM3 top, DIM4 bottom, DIM5 left (−z), DIM6 right wall thickness."""
    b, h, t3, t4, t5, t6 = d
    w = b - t5 - t6
    zm = (t5 - t6) / 2
    area, i1, i2, i12 = _rects([(t5, h, (t5 - b) / 2, 0.0), (t6, h, (b - t6) / 2, 0.0),
                                (w, t3, zm, (h - t3) / 2), (w, t4, zm, (t4 - h) / 2)])
    bm, hm = b - (t5 + t6) / 2, h - (t3 + t4) / 2
    j = 4 * (bm * hm) ** 2 / (bm / t3 + bm / t4 + hm / t5 + hm / t6)
    return area, i1, i2, i12, j, (t5 + t6) * h / area, (t3 + t4) * b / area


def box(d):
    """DIM1 width, DIM2 height, DIM3 top and bottom, DIM4 side wall thickness."""
    b, h, t, s = d
    area, i1, i2, _, j, k1, k2 = box1((b, h, t, t, s, s))
    return area, i1, i2, 0.0, j, k1, k2


def i_section(d):
    """DIM1 height, DIM2 bottom and DIM3 top flange width, DIM4 web, DIM5 bottom and DIM6
    top flange thickness."""
    h, a, b, tw, ta, tb = d
    hw = h - ta - tb
    parts = [(a, ta, 0.0, ta / 2), (tw, hw, 0.0, ta + hw / 2), (b, tb, 0.0, h - tb / 2)]
    j = (a * ta**3 + b * tb**3 + (h - (ta + tb) / 2) * tw**3) / 3
    return _symmetric(parts, j, tw * hw, (a - tw) * ta + (b - tw) * tb)


def i1(d):
    """DIM1 both flange outstands together, DIM2 web thickness, DIM3 web height between the
    flanges, DIM4 height."""
    f, tw, hw, h = d
    tf = (h - hw) / 2
    return i_section((h, f + tw, f + tw, tw, tf, tf))


def chan(d):
    """DIM1 width, DIM2 height, DIM3 web (at −z), DIM4 flange thickness."""
    b, h, tw, tf = d
    hw = h - 2 * tf
    parts = [(tw, hw, tw / 2, 0.0), (b, tf, b / 2, (h - tf) / 2), (b, tf, b / 2, (tf - h) / 2)]
    j = (2 * (b - tw / 2) * tf**3 + (h - tf) * tw**3) / 3
    return _symmetric(parts, j, tw * hw, 2 * (b - tw) * tf)


def chan1(d):
    """DIM1 flange outstand, DIM2 web thickness, DIM3 web height between the flanges, DIM4 height."""
    f, tw, hw, h = d
    return chan((f + tw, h, tw, (h - hw) / 2))


def chan2(d):
    """U open upwards: DIM1 leg thickness, DIM2 base thickness, DIM3 height, DIM4 width."""
    tl, tb, h, b = d
    hl = h - tb
    parts = [(b, tb, 0.0, tb / 2), (tl, hl, (tl - b) / 2, (h + tb) / 2), (tl, hl, (b - tl) / 2, (h + tb) / 2)]
    j = ((b - tl) * tb**3 + 2 * (h - tb / 2) * tl**3) / 3
    return _symmetric(parts, j, 2 * tl * hl, (b - 2 * tl) * tb)


def t_section(d):
    """Flange on top: DIM1 flange width, DIM2 height, DIM3 flange, DIM4 web thickness
    (also T2, the same shape upside down)."""
    b, h, tf, tw = d
    parts = [(b, tf, 0.0, h - tf / 2), (tw, h - tf, 0.0, (h - tf) / 2)]
    j = (b * tf**3 + (h - tf / 2) * tw**3) / 3
    return _symmetric(parts, j, tw * (h - tf), (b - tw) * tf)


def t1_section(d):
    """The T turned a quarter (its flange upright): DIM1 flange height, DIM2 web length beside
    it, DIM3 flange, DIM4 web thickness."""
    h, f, tv, th = d
    area, i_1, i_2, _, j, k1, k2 = t_section((h, f + tv, tv, th))
    return area, i_2, i_1, 0.0, j, k2, k1


def l_section(d):
    """Legs up and to +z from the corner: DIM1 width, DIM2 height, DIM3 thickness of the
    horizontal leg, DIM4 of the vertical one."""
    b, h, th, tv = d
    area, i_1, i_2, i12 = _rects([(tv, h, tv / 2, h / 2), (b - tv, th, (b + tv) / 2, th / 2)])
    j = ((b - tv / 2) * th**3 + (h - th / 2) * tv**3) / 3
    return area, i_1, i_2, i12, j, (h - th) * tv / area, (b - tv) * th / area


def z_section(d):
    """Top flange to −z, bottom flange to +z: DIM1 flange outstand, DIM2 web thickness, DIM3
    web height between the flanges, DIM4 height."""
    f, tw, hw, h = d
    tf = (h - hw) / 2
    area, i_1, i_2, i12 = _rects([(tw, h, 0.0, 0.0), (f, tf, -(tw + f) / 2, (h - tf) / 2),
                                  (f, tf, (tw + f) / 2, (tf - h) / 2)])
    j = (2 * (f + tw / 2) * tf**3 + (h - tf) * tw**3) / 3
    return area, i_1, i_2, i12, j, tw * hw / area, 2 * f * tf / area


def h_section(d):
    """Two upright flanges joined by a horizontal web: DIM1 web length between the flanges,
    DIM2 both flange thicknesses together, DIM3 flange height, DIM4 web thickness."""
    w, t2, h, tw = d
    tf = t2 / 2
    parts = [(tf, h, -(w + tf) / 2, 0.0), (tf, h, (w + tf) / 2, 0.0), (w, tw, 0.0, 0.0)]
    j = (2 * h * tf**3 + (w + tf) * tw**3) / 3
    return _symmetric(parts, j, t2 * h, w * tw)


def cross(d):
    """DIM1 both arms together, DIM2 thickness of the upright, DIM3 its height, DIM4 arm thickness."""
    w, tv, h, ta = d
    arm = (tv + w / 2) / 2
    parts = [(tv, h, 0.0, 0.0), (w / 2, ta, -arm, 0.0), (w / 2, ta, arm, 0.0)]
    j = (h * tv**3 + (w + tv) * ta**3) / 3
    return _symmetric(parts, j, tv * (h - ta), w * ta)


def hexa(d):
    """DIM1 length of each pointed end, DIM2 width, DIM3 height: a rectangle and two triangles."""
    tip, w, h = d
    core = w - 2 * tip
    area = (core + tip) * h
    i_1 = core * h**3 / 12 + tip * h**3 / 24
    zt = core / 2 + tip / 3  # centroid of a triangle
    i_2 = h * core**3 / 12 + 2 * (h * tip**3 / 36 + tip * h / 2 * zt**2)
    return area, i_1, i_2, 0.0, area**4 / (4 * PI**2 * (i_1 + i_2)), 5 / 6, 5 / 6


def hat(d):
    """Open downwards, one thickness: DIM1 height, DIM2 thickness, DIM3 crown width, DIM4
    width of each brim."""
    h, t, w, f = d
    web = (w - t) / 2
    parts = [(w, t, 0.0, h - t / 2), (t, h - t, -web, (h - t) / 2), (t, h - t, web, (h - t) / 2),
             (f, t, -(w + f) / 2, t / 2), (f, t, (w + f) / 2, t / 2)]
    j = t**3 * (w - t + 2 * (h - t) + 2 * (f + t / 2)) / 3
    return _symmetric(parts, j, 2 * t * (h - 2 * t), (w - 2 * t + 2 * f) * t)


def hat1(d):
    """A hat on a base plate: DIM1 plate width, DIM2 height, DIM3 crown width, DIM4 hat and
    DIM5 plate thickness."""
    w, h, wc, t, tp = d
    f, hw, web = (w - wc) / 2, h - tp - t, (wc - t) / 2
    parts = [(w, tp, 0.0, tp / 2), (f, t, -(wc + f) / 2, tp + t / 2), (f, t, (wc + f) / 2, tp + t / 2),
             (t, hw, -web, tp + hw / 2), (t, hw, web, tp + hw / 2), (wc, t, 0.0, h - t / 2)]
    bm, hm = wc - t, h - (t + tp) / 2
    j = 4 * (bm * hm) ** 2 / (bm / t + bm / tp + 2 * hm / t) + 2 * f * (t + tp) ** 3 / 3
    return _symmetric(parts, j, 2 * t * hw, w * tp + 2 * f * t + (wc - 2 * t) * t)


def dbox(d):
    """Two cells side by side: DIM1 width, DIM2 height, DIM3 left cell width to the middle of
    the middle wall; wall thicknesses DIM4 left, DIM5 middle, DIM6 right, DIM7 and DIM8 top
    and bottom of the left cell, DIM9 and DIM10 of the right one."""
    w, h, c, t4, t5, t6, t7, t8, t9, t10 = d
    wl, wr = c - t5 / 2 - t4, w - c - t5 / 2 - t6
    zl, zr = t4 + wl / 2, c + t5 / 2 + wr / 2
    area, i_1, i_2, i12 = _rects([(t4, h, t4 / 2, h / 2), (t5, h, c, h / 2), (t6, h, w - t6 / 2, h / 2),
                                  (wl, t7, zl, h - t7 / 2), (wl, t8, zl, t8 / 2),
                                  (wr, t9, zr, h - t9 / 2), (wr, t10, zr, t10 / 2)])
    b1, h1, b2, h2 = c - t4 / 2, h - (t7 + t8) / 2, w - c - t6 / 2, h - (t9 + t10) / 2
    a1, a2, hs = b1 * h1, b2 * h2, (h1 + h2) / 2
    d11 = b1 / t7 + b1 / t8 + h1 / t4 + hs / t5
    d22 = b2 / t9 + b2 / t10 + h2 / t6 + hs / t5
    d12 = hs / t5  # the shared wall: Gθ 2Aᵢ = qᵢ ∮ᵢ ds/t − qⱼ ∫ shared ds/t, T = 2 Σ Aᵢ qᵢ
    j = 4 * (a1**2 * d22 + 2 * a1 * a2 * d12 + a2**2 * d11) / (d11 * d22 - d12**2)
    k2 = (t7 + t8) * c + (t9 + t10) * (w - c)
    return area, i_1, i_2, i12, j, (t4 + t5 + t6) * h / area, k2 / area


SECTIONS = {
    "ROD": rod, "TUBE": tube, "TUBE2": tube2, "BAR": bar, "BOX": box, "BOX1": box1, "I": i_section, "I1": i1,
    "T": t_section, "T1": t1_section, "T2": t_section, "L": l_section, "CHAN": chan, "CHAN1": chan1, "CHAN2": chan2,
    "H": h_section, "Z": z_section, "HAT": hat, "HAT1": hat1, "CROSS": cross, "HEXA": hexa, "DBOX": dbox,
}
DIMENSIONS = PBARL_DIMENSIONS  # DIMs per type: the reader's table (MSC QRG, PBARL)
TYPES = tuple(DIMENSIONS)  # the type code of BeamSections.section_type is the index here

# What makes the drawn shape: (field to blame, message with {d} = the dimensions, test on them).
LIMITS = {
    "TUBE": ("DIM2", "inner radius {d[1]} must be smaller than outer radius {d[0]}", lambda d: d[1] < d[0]),
    "TUBE2": ("DIM2", "wall thickness {d[1]} must be smaller than the outer radius {d[0]}", lambda d: d[1] < d[0]),
    "BOX": ("DIM3", "walls too thick for the box: need 2·DIM4 < DIM1 and 2·DIM3 < DIM2, got {d}",
            lambda d: 2 * d[3] < d[0] and 2 * d[2] < d[1]),
    "BOX1": ("DIM3", "walls too thick for the box: need DIM5 + DIM6 < DIM1 and DIM3 + DIM4 < DIM2, got {d}",
             lambda d: d[4] + d[5] < d[0] and d[2] + d[3] < d[1]),
    "I": ("DIM5", "need DIM5 + DIM6 < DIM1 and DIM4 < DIM2, DIM3, got {d}",
          lambda d: d[4] + d[5] < d[0] and d[3] < min(d[1], d[2])),
    "I1": ("DIM3", "need DIM3 < DIM4, got {d}", lambda d: d[2] < d[3]),
    "CHAN": ("DIM4", "need 2·DIM4 < DIM2 and DIM3 < DIM1, got {d}", lambda d: 2 * d[3] < d[1] and d[2] < d[0]),
    "CHAN1": ("DIM3", "need DIM3 < DIM4, got {d}", lambda d: d[2] < d[3]),
    "CHAN2": ("DIM1", "need 2·DIM1 < DIM4 and DIM2 < DIM3, got {d}", lambda d: 2 * d[0] < d[3] and d[1] < d[2]),
    "T": ("DIM3", "need DIM3 < DIM2 and DIM4 < DIM1, got {d}", lambda d: d[2] < d[1] and d[3] < d[0]),
    "T1": ("DIM4", "need DIM4 < DIM1, got {d}", lambda d: d[3] < d[0]),
    "T2": ("DIM3", "need DIM3 < DIM2 and DIM4 < DIM1, got {d}", lambda d: d[2] < d[1] and d[3] < d[0]),
    "L": ("DIM3", "need DIM3 < DIM2 and DIM4 < DIM1, got {d}", lambda d: d[2] < d[1] and d[3] < d[0]),
    "Z": ("DIM3", "need DIM3 < DIM4, got {d}", lambda d: d[2] < d[3]),
    "H": ("DIM4", "need DIM4 < DIM3, got {d}", lambda d: d[3] < d[2]),
    "CROSS": ("DIM4", "need DIM4 < DIM3, got {d}", lambda d: d[3] < d[2]),
    "HEXA": ("DIM1", "need 2·DIM1 < DIM2, got {d}", lambda d: 2 * d[0] < d[1]),
    "HAT": ("DIM2", "need 2·DIM2 < DIM1 and 2·DIM2 < DIM3, got {d}", lambda d: 2 * d[1] < min(d[0], d[2])),
    "HAT1": ("DIM4", "need DIM4 + DIM5 < DIM2 and 2·DIM4 < DIM3 < DIM1, got {d}",
             lambda d: d[3] + d[4] < d[1] and 2 * d[3] < d[2] < d[0]),
    "DBOX": ("DIM3", ("need DIM4 + DIM5/2 < DIM3 < DIM1 − DIM5/2 − DIM6, DIM7 + DIM8 < DIM2 and "
                      "DIM9 + DIM10 < DIM2, got {d}"),
             lambda d: d[3] + d[4] / 2 < d[2] < d[0] - d[4] / 2 - d[5] and d[6] + d[7] < d[1] and d[8] + d[9] < d[1]),
}


def section(name: str, dims):
    """``(A, I1, I2, I12, J, K1, K2)`` of a section TYPE ``name`` with dimensions ``dims``."""
    return SECTIONS[name](dims)


def principal(i_1, i_2, i12, k1, k2):
    """``(θ, I1', I2', K1', K2')``: the section in its principal axes, turned by θ about x.

    y' = y cos θ + z sin θ, z' = −y sin θ + z cos θ give I1' = c² I1 + 2sc I12 + s² I2,
    I2' = s² I1 − 2sc I12 + c² I2 and I12' = ½ (I2 − I1) sin 2θ + I12 cos 2θ, zero at
    tan 2θ = 2 I12 / (I1 − I2); the root with |θ| ≤ π/4 (θ = 0 when I12 = 0). The shear
    factors are turned as the diagonal of diag(K1, K2) (their coupling dropped:
    K1' = c² K1 + s² K2, K2' = s² K1 + c² K2). Pure jax.numpy, differentiable (the root
    at I12 = I1 − I2 = 0 is guarded).
    """
    d = i_1 - i_2
    sign = jnp.where(d < 0.0, -1.0, 1.0)
    flat = (i12 == 0.0) & (d == 0.0)
    theta = 0.5 * jnp.arctan2(jnp.where(flat, 0.0, 2.0 * i12 * sign), jnp.where(flat, 1.0, d * sign))
    c, s = jnp.cos(theta), jnp.sin(theta)
    return (theta, c**2 * i_1 + 2 * s * c * i12 + s**2 * i_2, s**2 * i_1 - 2 * s * c * i12 + c**2 * i_2,
            c**2 * k1 + s**2 * k2, s**2 * k1 + c**2 * k2)


def turn(v, x, theta):
    """``v`` turned by ``theta`` about the unit vector ``x`` (Rodrigues):
    v cos θ + (x × v) sin θ + x (x·v)(1 − cos θ); rows of ``v``, ``x`` and ``theta`` broadcast."""
    c, s = jnp.cos(theta)[..., None], jnp.sin(theta)[..., None]
    return v * c + jnp.cross(x, v) * s + x * jnp.sum(x * v, axis=-1, keepdims=True) * (1 - c)
