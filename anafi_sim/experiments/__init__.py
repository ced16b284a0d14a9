"""Experiments: scenarios and waypoints, tracking-error evaluation, reference logs, run monitor, batch report, plots."""
