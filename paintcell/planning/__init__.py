"""Geometry and paint physics: part file → surface → coverage plan. Knows nothing of robots."""
