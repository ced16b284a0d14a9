#!/usr/bin/env python3
"""Checks launch arguments before any node starts: ``check_launch_args.py [--launch FILE] NAME=VALUE ...``.

Called by the launch files from ``<param command=...>`` while roslaunch reads them: one line per bad or unknown
argument and exit 2 (roslaunch ends), else prints ``ok``. Its code and main(): anafi_sim/nodes/check_launch_args.py.
"""
import sys

from anafi_sim.nodes.check_launch_args import main

if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
