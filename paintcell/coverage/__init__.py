"""Stage 2, surface → coverage plan: start curve, offsets, index widths, per-pass speed QP and
Algorithm 1 (per patch)."""
