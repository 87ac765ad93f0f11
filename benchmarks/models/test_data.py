"""Reference data from the thesis for the benchmark models in this folder.

``GARTEUR_TABLE_4_3``: GARTEUR SM-AG19 modal data, thesis Table 4.3 (analytical frequencies of the
thesis' initial MATFEM model, measured GVT frequencies, deviation Δf = (f_a − f_e)/f_e as printed,
MAC of the paired modes in percent). The source text lost three mode numbers in conversion
("S", "9", "6" printed for 5, 6, 9); the sequence 1..14 and the text (Δf_4 = −2.60 %,
Δf_9 = +2.91 %) fix them. The text quotes the last measured frequency as 151.32 Hz, the table
as 151.3 Hz; the table value is kept.

``TREE_TABLE_4_6``: artificial stiffness modelling errors of the tree-structure simulation study,
thesis Table 4.6, with the property ids of ``tree.bdf`` they act on. ``alpha`` is the value to
give :func:`jaxfem.correct` (eq. 3.1, ``K = K0 + α K_group``) to build the erroneous model,
``factor = 1 + alpha`` the resulting stiffness multiplier of the group, and
``alpha_exact_correction = 1/factor − 1`` the correction factor an updating run started from the
erroneous model must converge to.

``GARTEUR_TABLE_4_4``: the two updating parameter sets of thesis Table 4.4 with their updated
correction values p_k [%] and the property ids / CONM2 ids of ``garteur.bdf`` they map to (see
README.md). Values marked ``None`` are illegible in the source (digits lost in conversion).
"""

GARTEUR_TABLE_4_3 = [
    {"mode": 1, "description": "1st Symmetric Wing Bending", "f_analytical_hz": 6.253, "f_measured_hz": 6.376, "delta_f_percent": -1.93, "mac_percent": 99.96},
    {"mode": 2, "description": "Fuselage Rotation", "f_analytical_hz": 16.34, "f_measured_hz": 16.10, "delta_f_percent": +1.47, "mac_percent": 97.46},
    {"mode": 3, "description": "1st Anti-Symmetric Wing Torsion", "f_analytical_hz": 32.59, "f_measured_hz": 33.13, "delta_f_percent": -1.63, "mac_percent": 76.40},
    {"mode": 4, "description": "1st Symmetric Wing Torsion", "f_analytical_hz": 32.66, "f_measured_hz": 33.53, "delta_f_percent": -2.60, "mac_percent": 83.20},
    {"mode": 5, "description": "1st Anti-Symmetric Wing Bending", "f_analytical_hz": 36.56, "f_measured_hz": 35.65, "delta_f_percent": +2.57, "mac_percent": 93.25},
    {"mode": 6, "description": "2nd Symmetric Wing Bending", "f_analytical_hz": 48.95, "f_measured_hz": 48.38, "delta_f_percent": +1.17, "mac_percent": 99.51},
    {"mode": 7, "description": "1st Anti-Symmetric In-Plane Bending", "f_analytical_hz": 49.88, "f_measured_hz": 49.43, "delta_f_percent": +0.89, "mac_percent": 97.60},
    {"mode": 8, "description": "1st Symmetric In-Plane Bending", "f_analytical_hz": 56.36, "f_measured_hz": 55.08, "delta_f_percent": +2.33, "mac_percent": 99.38},
    {"mode": 9, "description": "2nd Anti-Symmetric Wing Bending", "f_analytical_hz": 64.87, "f_measured_hz": 63.04, "delta_f_percent": +2.91, "mac_percent": 96.20},
    {"mode": 10, "description": "Tail Torsion", "f_analytical_hz": 66.13, "f_measured_hz": 66.50, "delta_f_percent": -0.56, "mac_percent": 99.93},
    {"mode": 11, "description": "Lateral Fuselage Bending", "f_analytical_hz": 100.7, "f_measured_hz": 102.9, "delta_f_percent": -2.11, "mac_percent": 99.81},
    {"mode": 12, "description": "2nd Tail Bending", "f_analytical_hz": 127.9, "f_measured_hz": 130.5, "delta_f_percent": -2.01, "mac_percent": 98.83},
    {"mode": 13, "description": "3rd Symmetric Wing Bending", "f_analytical_hz": 143.6, "f_measured_hz": 141.4, "delta_f_percent": +1.56, "mac_percent": 97.44},
    {"mode": 14, "description": "3rd Anti-Symmetric Wing Bending", "f_analytical_hz": 155.5, "f_measured_hz": 151.3, "delta_f_percent": +2.79, "mac_percent": 94.59},
]

# Thesis Table 4.2: measured rigid-body (suspension) modes of the GARTEUR GVT.
GARTEUR_TABLE_4_2 = [
    {"mode": "RBM 1", "description": "Roll", "f_measured_hz": 0.52, "mif": 966},
    {"mode": "RBM 2", "description": "Pitch", "f_measured_hz": 0.62, "mif": 934},
    {"mode": "RBM 3", "description": "Heave", "f_measured_hz": 1.84, "mif": 965},
]

# Thesis Table 4.6 -> tree.bdf property ids: 1-4 blades 1-4, 11 pylon base -> lower joint,
# 12 pylon between the lower and upper blade planes, 21/22 upper/lower joint blocks.
TREE_TABLE_4_6 = [
    {"model": 1, "error": "K1", "location": "Compound Blades No. 2 & 4", "pids": [2, 4],
     "stiffness_modification_percent": -17.0, "alpha": -0.17, "factor": 0.83,
     "alpha_exact_correction": 1.0 / 0.83 - 1.0},
    {"model": 2, "error": "K2", "location": "Compound Blades No. 2 & 4", "pids": [2, 4],
     "stiffness_modification_percent": -7.0, "alpha": -0.07, "factor": 0.93,
     "alpha_exact_correction": 1.0 / 0.93 - 1.0},
    {"model": 3, "error": "K3", "location": "Pylon (between upper & lower Blade Plane)", "pids": [12],
     "stiffness_modification_percent": +10.0, "alpha": +0.10, "factor": 1.10,
     "alpha_exact_correction": 1.0 / 1.10 - 1.0},
]

# Thesis Table 4.4 -> garteur.bdf. "pids": PBAR/PBUSH property ids; "conm2": CONM2 element ids;
# "quantity": section value scaled (I1 = Imin, I2 = Imax, J = Itor) or "m" (mass correction).
# Wing "sections" 1/2/3 are this model's root / mid-span / outboard thirds (thesis Fig. 4.6 gives
# the strain-based sections only graphically).
_LEFT_WING, _RIGHT_WING = [11, 12, 13], [21, 22, 23]
GARTEUR_TABLE_4_4 = {
    1: [
        {"no": 1, "location": "Wings", "parameter": "Imax", "quantity": "I2", "pids": _LEFT_WING + _RIGHT_WING, "p_percent": -3.29},
        {"no": 2, "location": "Wings, Sections 1", "parameter": "Imin", "quantity": "I1", "pids": [11, 21], "p_percent": +4.30},
        {"no": 3, "location": "Wings, Sections 2", "parameter": "Imin", "quantity": "I1", "pids": [12, 22], "p_percent": +12.2},
        {"no": 4, "location": "Right Wing, Sections 3", "parameter": "Imin", "quantity": "I1", "pids": [23], "p_percent": -7.53},
        {"no": 5, "location": "Left Wing, Sections 3", "parameter": "Imin", "quantity": "I1", "pids": [13], "p_percent": -7.54},
        {"no": 6, "location": "Right Wing", "parameter": "Itor", "quantity": "J", "pids": _RIGHT_WING, "p_percent": +3.15},
        {"no": 7, "location": "Left Wing", "parameter": "Itor", "quantity": "J", "pids": _LEFT_WING, "p_percent": +3.18},
        {"no": 8, "location": "Tail & Tailplane", "parameter": "Itor ~ m", "quantity": "J+m", "pids": [41, 42], "p_percent": +9.21},
        {"no": 9, "location": "Fuselage", "parameter": "m", "quantity": "m", "pids": [1], "p_percent": -2.76},
        {"no": 10, "location": "Right Wing", "parameter": "m", "quantity": "m", "pids": _RIGHT_WING, "p_percent": +6.70},
        {"no": 11, "location": "Left Wing", "parameter": "m", "quantity": "m", "pids": _LEFT_WING, "p_percent": +8.72},
        {"no": 12, "location": "Shaker @ Right Wing", "parameter": "m", "quantity": "m", "conm2": [804], "p_percent": -2.74},
        {"no": 13, "location": "Shaker @ Left Wing", "parameter": "m", "quantity": "m", "conm2": [805], "p_percent": +1.85},
    ],
    2: [
        {"no": 1, "location": "Wings", "parameter": "Imax", "quantity": "I2", "pids": _LEFT_WING + _RIGHT_WING, "p_percent": -3.45},
        {"no": 2, "location": "Wings", "parameter": "Imin", "quantity": "I1", "pids": _LEFT_WING + _RIGHT_WING, "p_percent": None},  # "+?.82"
        {"no": 3, "location": "Right Wing", "parameter": "Itor", "quantity": "J", "pids": _RIGHT_WING, "p_percent": +3.61},
        {"no": 4, "location": "Left Wing", "parameter": "Itor", "quantity": "J", "pids": _LEFT_WING, "p_percent": +2.81},
        {"no": 5, "location": "Tail", "parameter": "Imin", "quantity": "I1", "pids": [41, 42], "p_percent": -5.41},
        {"no": 6, "location": "Right Wing", "parameter": "m", "quantity": "m", "pids": _RIGHT_WING, "p_percent": +2.65},
        {"no": 7, "location": "Left Wing", "parameter": "m", "quantity": "m", "pids": _LEFT_WING, "p_percent": +3.25},
        {"no": 8, "location": "Tail", "parameter": "m", "quantity": "m", "pids": [41, 42], "p_percent": -0.15},
    ],
}
