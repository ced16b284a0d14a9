#!/usr/bin/env python3
"""Kinematic world node: our stand-in for Gazebo's ROS API (thin node over anafi_sim.gazebo.kinematic_world).

Its code and main(): anafi_sim/nodes/kinematic_world_node.py."""
import sys

from anafi_sim.nodes.kinematic_world_node import main

if __name__ == '__main__':
    sys.exit(main())
