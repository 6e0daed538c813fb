"""The application: scenarios, the pipeline that chains the stages, and the `paintcell` command
line."""
