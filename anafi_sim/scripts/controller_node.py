#!/usr/bin/env python3
"""One tracking-controller node for every implementation of the controller contract (thin node).

Its code and main(): anafi_sim/nodes/controller_node.py."""
import sys

from anafi_sim.nodes.controller_node import main

if __name__ == '__main__':
    sys.exit(main())
