#!/usr/bin/env python3
"""rosbag record with its output directory created first (rosbag refuses a missing directory).

Its code and main(): anafi_sim/nodes/record_bag.py."""
import sys

from anafi_sim.nodes.record_bag import main

if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
