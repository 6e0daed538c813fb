"""Stage 4, joint trajectory → executed trace: the MuJoCo paint cell and its servo execution."""
