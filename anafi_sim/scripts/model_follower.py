#!/usr/bin/env python3
"""Model follower node: a Gazebo model's pose (e.g. the airship) -> the drone's waypoint with velocity.

Its code and main(): anafi_sim/nodes/model_follower.py."""
import sys

from anafi_sim.nodes.model_follower import main

if __name__ == '__main__':
    sys.exit(main())
