"""The log-factor ladders tried before fitting an effect (its ``scan``), shared by the kinds of
:mod:`updating.diagnosis._effects`."""

import numpy as np

SCAN = (0.0, -1.5, -3.0, -4.5, -6.0, 1.5)  # log-factors tried before fitting a joint, support or mass
SCAN_SEAM = (0.0, -2.0, -4.0, -6.0, -8.0, -10.0, -12.0)  # a seam's: from rigid (reference 100 EA/L) to a detached frame
SCAN_LAW = tuple((0.0, np.log1p(a)) for a in (-0.3, 0.0, 0.15, 0.3, 0.8, 1.5))  # (E0 factor, a − a₀) of a frequency law
