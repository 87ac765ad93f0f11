"""Measured data: containers, UFF files, FRFs, modal fitting, phase resonance, damage."""
