"""Identify modes from FRFs: a 3-DoF spring–mass chain with known M, K and damping.

Synthesises the receptance H(f) = Σ_r φ_r φ_rᵀ / (ω_r² − ω² + 2iζ_r ω_r ω) (modal viscous
damping, thesis ch. 2) at all three masses for a force at mass 3, adds 1 % complex noise,
and identifies the modes with ``identification.identify`` (pLSCF stabilisation diagram,
automatic pole selection, LSFD shapes, real normal modes). Shows identified against exact
frequencies and damping ratios and the MAC of the shapes. Next: write the modes with
``identification.write_uff`` and correlate them with a model (``01_correlate_garteur.py``),
or run ``jaxfem identify FRF.uff`` on measured FRFs.
"""

import numpy as np
import scipy.linalg as sl

from identification import FRFData, Sensors, identify

M = np.diag([2.0, 1.5, 1.0])  # kg
K = np.array([[5e4, -2e4, 0.0], [-2e4, 3.5e4, -1.5e4], [0.0, -1.5e4, 1.5e4]])  # N/m, grounded at mass 1
ZETA = np.array([0.01, 0.015, 0.02])  # modal viscous damping ratios


def main() -> dict:
    lam, phi = sl.eigh(K, M)  # mass-normalised modes
    wn = np.sqrt(lam)
    f_exact = wn / (2 * np.pi)
    f = np.arange(0.0, 60.0, 0.02)  # Hz
    w = 2 * np.pi * f[:, None]
    h = np.einsum("or,r,kr->ko", phi, phi[2], 1 / (wn**2 - w**2 + 2j * ZETA * wn * w))[:, :, None]
    rng = np.random.default_rng(0)
    h = h * (1 + 0.01 * (rng.standard_normal(h.shape) + 1j * rng.standard_normal(h.shape)) / np.sqrt(2))
    frf = FRFData(f, h, Sensors.from_components([1, 2, 3], [3, 3, 3]), Sensors.from_components([3], [3]), "receptance")
    found, report = identify(frf)
    mac = np.abs(np.sum(found.shapes * phi, 0)) ** 2 / (np.sum(found.shapes**2, 0) * np.sum(phi**2, 0))
    print(f"{'mode':>4} {'f exact [Hz]':>12} {'f found [Hz]':>12} {'error [%]':>9} {'ζ exact [%]':>11} "
          f"{'ζ found [%]':>11} {'MAC':>7}")
    for r in range(found.n_modes):
        print(f"{r + 1:>4} {f_exact[r]:>12.4f} {found.frequencies_hz[r]:>12.4f} "
              f"{100 * (found.frequencies_hz[r] / f_exact[r] - 1):>+9.4f} {100 * ZETA[r]:>11.3f} "
              f"{100 * found.damping_ratios[r]:>11.3f} {mac[r]:>7.4f}")
    print(f"synthesis fit error {report['fit']['nmse_percent_worst']:.3f} % (worst FRF)")
    return {"n_modes": found.n_modes, "f_exact_hz": f_exact.tolist(), "f_hz": found.frequencies_hz.tolist(),
            "zeta": found.damping_ratios.tolist(), "min_mac": float(mac.min())}


if __name__ == "__main__":
    main()
