#!/usr/bin/env python3
"""Live tracking-error evaluator node: e = |waypoint - drone position| over the measured segment.

Its code and main(): anafi_sim/nodes/evaluator.py."""
import sys

from anafi_sim.nodes.evaluator import main

if __name__ == '__main__':
    sys.exit(main())
