#!/usr/bin/env python3
"""Experiment monitor node: starts the scenario when everything is up, prints live progress, ends the run.

Its code and main(): anafi_sim/nodes/experiment_monitor.py."""
import sys

from anafi_sim.nodes.experiment_monitor import main

if __name__ == '__main__':
    sys.exit(main())
