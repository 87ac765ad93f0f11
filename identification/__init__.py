"""Measured data: containers, UFF files, FRFs, modal fitting, phase resonance, damage."""

from ._data import FRF_KINDS as FRF_KINDS
from ._data import FRFData as FRFData
from ._data import ModalData as ModalData
from ._data import Sensors as Sensors
from ._data import observation_matrix as observation_matrix
from ._uff import read_uff as read_uff
from ._uff import write_uff as write_uff
