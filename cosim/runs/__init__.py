"""Runs: one run end to end (runner), in a supervised child (supervisor), many runs
(campaign), their output folders, result files, plots, replays and comparisons."""
