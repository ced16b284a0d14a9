#!/usr/bin/env python3
"""Drop-in for the ROS ``pid`` package's ``controller`` node (thin node over anafi_control.pid).

Its code and main(): anafi_sim/nodes/pid_controller.py."""
import sys

from anafi_sim.nodes.pid_controller import main

if __name__ == '__main__':
    sys.exit(main())
