"""Stage 3, plan → joint trajectory: IK path, TOPP-RA time law, ruckig moves, the sampled
program."""
