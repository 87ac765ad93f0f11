"""Element matrices (one element per call; vmap over elements), basic axes, 6 DoFs per grid."""

from ._beam import beam_axes as beam_axes
from ._beam import beam_lumped_torsion as beam_lumped_torsion
from ._beam import beam_mass as beam_mass
from ._beam import beam_stiffness as beam_stiffness
from ._beam import rigid_offset as rigid_offset
from ._bush import bush_stiffness as bush_stiffness
from ._mass import conm2_mass as conm2_mass
from ._rod import rod_mass as rod_mass
from ._rod import rod_stiffness as rod_stiffness
from ._laminate import Laminate as Laminate
from ._laminate import laminates as laminates
from ._shell import QUAD_CORNERS as QUAD_CORNERS
from ._shell import quad_shape as quad_shape
from ._shell import shell_frame as shell_frame
from ._shell import shell_mass as shell_mass
from ._shell import shell_stiffness as shell_stiffness
