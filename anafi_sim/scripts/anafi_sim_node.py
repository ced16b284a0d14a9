#!/usr/bin/env python3
"""The simulated Anafi: stand-in for Sphinx + firmware + the anafi_ros bridge (thin ROS node).

Its code and main(): anafi_sim/nodes/anafi_sim_node.py."""
import sys

from anafi_sim.nodes.anafi_sim_node import main

if __name__ == '__main__':
    sys.exit(main())
