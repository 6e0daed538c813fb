"""Stage 1, part file → surface: read, repair, remesh and measure the part (units, pieces, regions,
curvature)."""
