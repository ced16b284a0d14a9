"""The mission around the flight: scenarios and waypoints, target following, tracking-error evaluation, reference logs, run monitor, plots, fleets (pure cores)."""
