"""Readers of model files: Nastran decks (bulk data, INCLUDE files, case control)."""

from ._bdf import read_bdf as read_bdf
from ._bdf import read_bdf_text as read_bdf_text
from ._bulkdata import BulkData as BulkData
from ._bulkdata import BulkDataError as BulkDataError
from ._bulkdata import Card as Card
from ._bulkdata import IdRanges as IdRanges
from ._bulkdata import UnsupportedCardsError as UnsupportedCardsError
from ._cards_variable import PBARL_DIMENSIONS as PBARL_DIMENSIONS
from ._case import CaseControl as CaseControl
from ._case import Subcase as Subcase
