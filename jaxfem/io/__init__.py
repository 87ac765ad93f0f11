"""Readers of model files: Nastran bulk data."""

from ._bdf import BulkData as BulkData
from ._bdf import BulkDataError as BulkDataError
from ._bdf import Card as Card
from ._bdf import read_bdf as read_bdf
from ._bdf import read_bdf_text as read_bdf_text
