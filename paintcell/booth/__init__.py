"""Several robots, rail axes and a moving conveyor: the booth as one run."""
