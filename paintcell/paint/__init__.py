"""Paint physics: the ESRB bell deposition model, its calibration and the film uniformity
metrics."""
