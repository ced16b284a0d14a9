#!/usr/bin/env python3
"""Visualisation node: a drone's flown trail, reference, predicted path and waypoint for rviz.

Its code and main(): anafi_sim/nodes/visualisation_node.py."""
import sys

from anafi_sim.nodes.visualisation_node import main

if __name__ == '__main__':
    sys.exit(main())
