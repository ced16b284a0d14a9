#!/usr/bin/env python3
"""Benchmark: the ground-truth interface (telemetry -> interface stage) -- parser, latency, CPU, vs the paper's way.

Parts (``--parts``, default all):

* ``parser`` (interface_parser.py): lines/s of ``TelemetryParser.feed_line`` on the lines the CLI prints
  (``format_sample`` of a simulated flight, blank line between samples) next to a naive regex parser,
  alternating rounds.
* ``interface`` (interface_ros.py, interface_stream.py): a ``TelemetryServer`` hosted here is fed at
  ``--rate`` Hz by a wall-paced thread with samples stamped with their wall time of generation; our own
  roscore on a free port; the real ``interface_node.py`` with ``~telemetry_command`` = the stand-in CLI
  ``tlm_data_logger.py -r 0`` pointed at that server; we subscribe ``/anafi/ground_truth/drone_data`` and, over
  ``--duration`` s, record header.stamp - generation (generation -> publish) and receipt wall time -
  generation (generation -> ROS message received), the published rate, and the CPU time (user+sys,
  psutil) of the node and its CLI child.
* ``paper``: ``benchmarks/paper_interface.py`` (the paper's 24 ``CLI | grep KEY`` pipelines + a node
  publishing the last values from a 100 Hz timer) runs together with ours on the same server for one
  further window; CPU of each whole process tree (sampled every second, so processes that end still
  count up to their last sample), ratio, latency and torn messages of both.

Sample timestamps: ``format_sample`` prints 9 significant digits, so the timestamp is the wall time minus a
fixed whole-second epoch taken at start (values ~10..300 s: resolution <= 10 us).
Needs the workspace environment (``source env.bash``). Writes benchmarks/results/interface.md
(interface_report.py).

Run: python benchmarks/bench_interface.py [--parts parser,interface,paper] [--duration 30] [--no-write]
"""
import argparse
import os
import signal
import sys

from interface_parser import bench_parser
from interface_report import report

RESULTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'results', 'interface.md')
PARTS = ('parser', 'interface', 'paper')


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--parts', default=','.join(PARTS), help='comma list of %s' % ', '.join(PARTS))
    ap.add_argument('--duration', type=float, default=30.0, help='measurement window per part [s] (>= 30 for the '
                                                                  'committed figures)')
    ap.add_argument('--rate', type=float, default=100.0, help='telemetry and publish rate [Hz]')
    ap.add_argument('--tcp-nodelay', action='store_true',
                    help='subscribe with tcp_nodelay=True (default: the ROS default, False: Nagle on the publisher)')
    ap.add_argument('--no-write', action='store_true', help='print only, do not write %s' % RESULTS)
    args = ap.parse_args(argv)
    args.parts = [p.strip() for p in args.parts.split(',') if p.strip()]
    bad = [p for p in args.parts if p not in PARTS]
    if bad or not args.parts:
        ap.error('unknown part(s) %s; choose from %s' % (bad, ', '.join(PARTS)))
    if not (args.duration > 0 and args.rate > 0):
        ap.error('--duration and --rate must be > 0')

    def log(text):
        sys.stderr.write('[bench_interface] %s\n' % text)
        sys.stderr.flush()

    # Ctrl-C raises KeyboardInterrupt; make SIGTERM do the same so the finally blocks clean up.
    def _terminate(signum, frame):
        raise KeyboardInterrupt('SIGTERM')
    signal.signal(signal.SIGTERM, _terminate)
    parser_res = ros_res = None
    try:
        if 'parser' in args.parts:
            log('parser throughput ...')
            parser_res = bench_parser()
        if 'interface' in args.parts or 'paper' in args.parts:
            from interface_ros import bench_ros     # needs ROS and the generated messages
            ros_res = bench_ros(args.parts, args.duration, args.rate, args.tcp_nodelay, log)
    except KeyboardInterrupt:
        log('interrupted: every process started was stopped; nothing written')
        return 130
    text = report(args, parser_res, ros_res)
    print(text)
    if not args.no_write:
        os.makedirs(os.path.dirname(RESULTS), exist_ok=True)
        with open(RESULTS, 'w') as f:
            f.write(text + '\n')
        log('wrote %s' % RESULTS)
    return 0


if __name__ == '__main__':
    sys.exit(main())
