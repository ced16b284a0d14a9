#!/usr/bin/env python3
"""The paper's "Interface": Sphinx ground-truth telemetry -> ROS (thin node).

Its code and main(): anafi_sim/nodes/interface_node.py."""
import sys

from anafi_sim.nodes.interface_node import main

if __name__ == '__main__':
    sys.exit(main())
