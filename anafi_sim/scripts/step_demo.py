#!/usr/bin/env python3
"""Foundation demo: step commands to the simulated Anafi, printing what the interface saw.

Its code and main(): anafi_sim/nodes/step_demo.py."""
import sys

from anafi_sim.nodes.step_demo import main

if __name__ == '__main__':
    sys.exit(main())
