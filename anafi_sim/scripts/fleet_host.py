#!/usr/bin/env python3
"""Fleet host node: every drone's instance of some nodes in one process (the shared layout of a fleet).

Its code and main(): anafi_sim/nodes/fleet_host.py."""
import sys

from anafi_sim.nodes.fleet_host import main

if __name__ == '__main__':
    sys.exit(main())
