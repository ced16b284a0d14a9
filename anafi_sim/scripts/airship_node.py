#!/usr/bin/env python3
"""Airship node: moves the scene's airship along a scripted path in Gazebo (thin node).

Its code and main(): anafi_sim/nodes/airship_node.py."""
import sys

from anafi_sim.nodes.airship_node import main

if __name__ == '__main__':
    sys.exit(main())
