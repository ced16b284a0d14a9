#!/usr/bin/env python3
"""Stand-in for Sphinx's ``tlm-data-logger [-r RATE] inet:HOST:PORT``: prints the simulated Anafi's telemetry.

RATE is the minimum period in ms between printed samples, on the samples'
timestamps (0 = every sample). Exit 0 when the simulator closes the
connection, 1 when it cannot connect. Logic: anafi_sim.telemetry.server.run_logger.
"""
import os
import sys

from anafi_sim.telemetry.server import run_logger


def main():
    code = run_logger(sys.argv[1:], sys.stdout.buffer, sys.stderr)
    if code != 0:
        # stdout may be a closed pipe: do not let the interpreter's final flush complain.
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except OSError:
            pass
    return code


if __name__ == '__main__':
    sys.exit(main())
