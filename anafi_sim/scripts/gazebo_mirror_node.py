#!/usr/bin/env python3
"""Gazebo mirror node: the Sphinx ground truth drives an Anafi and its camera in Gazebo (thin node).

Its code and main(): anafi_sim/nodes/gazebo_mirror_node.py."""
import sys

from anafi_sim.nodes.gazebo_mirror_node import main

if __name__ == '__main__':
    sys.exit(main())
