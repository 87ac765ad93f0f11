"""Consistent unit systems a deck may be written in, for labels and conversions at the edge.

Nastran data carry no units: any consistent system gives the same frequencies in Hz. The
system only names the units of lengths and masses in outputs and converts test geometry
(read in metres) to the model's length unit. ``metre`` and ``kilogram``: SI value of one
length and one mass unit of the system.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class UnitSystem:
    """A consistent unit system: names of its length, mass, time and force units and the SI
    value of its length [m] and mass [kg] units."""

    name: str
    length: str
    mass: str
    force: str
    metre: float
    kilogram: float

    def describe(self) -> str:
        return (f"{self.name}: lengths in {self.length}, masses in {self.mass}, forces in {self.force}, "
                "time in s; frequencies in Hz")


UNIT_SYSTEMS = {u.name: u for u in (
    UnitSystem("SI", "m", "kg", "N", 1.0, 1.0),
    UnitSystem("mm-t-s", "mm", "t", "N", 1e-3, 1e3),
    UnitSystem("cm-g-s", "cm", "g", "dyn", 1e-2, 1e-3),
    UnitSystem("in-lbf-s", "in", "lbf·s²/in", "lbf", 0.0254, 4.4482216152605 / 0.0254),
    UnitSystem("ft-lbf-s", "ft", "slug", "lbf", 0.3048, 4.4482216152605 / 0.3048),
)}
