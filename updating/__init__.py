"""Model updating: correlation, parameters, residuals, solver, diagnosis, reports, CLI."""

from ._correlation import Pairing as Pairing
from ._correlation import automac as automac
from ._correlation import comac as comac
from ._correlation import cross_orthogonality as cross_orthogonality
from ._correlation import frequency_deviation as frequency_deviation
from ._correlation import guyan as guyan
from ._correlation import mac as mac
from ._correlation import modal_scale_factor as modal_scale_factor
from ._correlation import pair_modes as pair_modes
from ._correlation import pair_modes_masked as pair_modes_masked
from ._correlation import serep as serep
