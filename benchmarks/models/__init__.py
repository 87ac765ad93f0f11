"""Benchmark finite-element models (GARTEUR SM-AG19, tree structure) and the thesis reference data.

The bulk-data and sensor files ship with the package (``updating/data``: the demo and the
default Monte-Carlo study use them); ``MODELS`` is their folder.
"""

from importlib import resources
from pathlib import Path

MODELS = Path(str(resources.files("updating") / "data"))
