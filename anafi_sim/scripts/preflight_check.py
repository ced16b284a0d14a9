#!/usr/bin/env python3
"""Pre-flight check node: 'start' to the trajectory generator once the state is fresh, the drone flies and the
first waypoint is within reach; an abort topic ends the launch.

Its code and main(): anafi_sim/nodes/preflight_check.py."""
import sys

from anafi_sim.nodes.preflight_check import main

if __name__ == '__main__':
    sys.exit(main())
