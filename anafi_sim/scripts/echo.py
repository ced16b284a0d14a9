#!/usr/bin/env python3
"""``rostopic echo`` for topics whose message package is not installed here (e.g. ``drone/rpyt``).

Its code and main(): anafi_sim/nodes/echo.py."""
import sys

from anafi_sim.nodes.echo import main

if __name__ == '__main__':
    sys.exit(main(sys.argv))
