"""jaxfem: differentiable structural dynamics in JAX (model → K, M → modes → responses)."""

from ._assembly import assemble as assemble
from ._build import build_model as build_model
from ._eigen import DEGENERATE_RTOL as DEGENERATE_RTOL
from ._eigen import eigh as eigh
from ._eigen import frequencies_hz as frequencies_hz
from ._eigen import nelson as nelson
from ._matrix import AbstractSymmetricMatrix as AbstractSymmetricMatrix
from ._matrix import DenseMatrix as DenseMatrix
from ._matrix import ElementMatrix as ElementMatrix
from ._model import DofMap as DofMap
from ._model import Model as Model
from ._model import Viscoelastic as Viscoelastic
from ._modes import modes as modes
from ._subspace import Subspace as Subspace
from ._subspace import dense_modes as dense_modes
from ._subspace import ritz_modes as ritz_modes
from ._subspace import shifted_inverse as shifted_inverse
from ._subspace import subspace as subspace
from ._model import correct as correct
from ._model import partition as partition
from ._damping import rayleigh as rayleigh
from ._damping import rayleigh_coefficients as rayleigh_coefficients
from ._damping import rayleigh_ratio as rayleigh_ratio
from ._response import frf_direct as frf_direct
from ._response import frf_modal as frf_modal
