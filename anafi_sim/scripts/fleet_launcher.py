#!/usr/bin/env python3
"""Fleet launcher node: a fleet file -> one launch file with every drone's includes -> roslaunch it (thin node).

Its code and main(): anafi_sim/nodes/fleet_launcher.py."""
import sys

from anafi_sim.nodes.fleet_launcher import main

if __name__ == '__main__':
    sys.exit(main())
