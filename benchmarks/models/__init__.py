"""Benchmark finite-element models (GARTEUR SM-AG19, tree structure) and the thesis reference data."""
