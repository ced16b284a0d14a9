#!/usr/bin/env python3
"""Trajectory generator node: a scenario (anafi_sim/config/scenarios/*.yaml) -> the paper's waypoint.

Its code and main(): anafi_sim/nodes/trajectory_generator.py."""
import sys

from anafi_sim.nodes.trajectory_generator import main

if __name__ == '__main__':
    sys.exit(main())
