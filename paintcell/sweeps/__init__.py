"""Robustness sweeps over real tolerances on Dask."""
