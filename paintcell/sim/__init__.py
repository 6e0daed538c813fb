"""Simulation of the plan on paint robots: motion → execution → validation → output, the booth,
sweeps and the application (CLI)."""
