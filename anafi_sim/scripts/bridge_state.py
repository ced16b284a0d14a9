#!/usr/bin/env python3
"""Bridge state node: the real anafi_ros bridge's state topics -> drone/odom for the controllers.

Its code and main(): anafi_sim/nodes/bridge_state.py."""
import sys

from anafi_sim.nodes.bridge_state import main

if __name__ == '__main__':
    sys.exit(main())
