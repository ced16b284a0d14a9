#!/usr/bin/env python3
"""Evaluate recorded flights: e_max, e_mu, e_sigma of e = |waypoint - drone position| per file.

Its code and main(): anafi_sim/nodes/evaluate_log.py."""
import sys

from anafi_sim.nodes.evaluate_log import main

if __name__ == '__main__':
    sys.exit(main())
