"""Stage 6, results → files people read: results folders, plots, renders, the HTML report and RAPID
programs."""
