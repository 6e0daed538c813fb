"""Stage 5, executed trace → film maps and metrics: the executed film, the loss of uniformity and
the verdict."""
