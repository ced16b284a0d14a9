#!/usr/bin/env python3
"""Relative-state node of the paper's distributed PID framework (thin node).

Its code and main(): anafi_sim/nodes/pid_relative_state.py."""
import sys

from anafi_sim.nodes.pid_relative_state import main

if __name__ == '__main__':
    sys.exit(main())
