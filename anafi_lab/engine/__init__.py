"""The in-process engine: one experiment on virtual time, many runs, sweeps and the ROS batch."""
