#!/usr/bin/env python3
"""Command node of the paper's distributed PID framework (thin node).

Its code and main(): anafi_sim/nodes/pid_command.py."""
import sys

from anafi_sim.nodes.pid_command import main

if __name__ == '__main__':
    sys.exit(main())
