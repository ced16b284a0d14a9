#!/usr/bin/env python3
"""Evaluate recorded flights: e_max, e_mu, e_sigma of e = |waypoint - drone position| per file.

Stage: (recorded waypoint, estimate, ground truth) -> tracking-error summary,
offline. Same core as the live evaluator (anafi_sim.mission.evaluation).

    evaluate_log.py FILE... [--window T0 T1] [--drone NAME] [--yaml OUT] [--csv-dir DIR]
                    [--receive-time] [--min-altitude M] [--fail-on-garbage]

FILE: a CSV in the column format of anafi_sim/data/reference_logs (e.g. the
paper's logs or an export of a real flight) or a rosbag (*.bag) with
<drone>/position_control/waypoint (anafi_sim/Waypoint), <drone>/drone/odom
and optionally <drone>/ground_truth/odom (nav_msgs/Odometry) and
<drone>/trajectory/begin|end (std_msgs/Header: the measured window; else
the whole bag). Prints per file the errors against the drone's estimate
(the paper's metric) and against ground truth [m], and the garbage samples
that were excluded. --window: seconds since the first evaluated sample.
--yaml: all summaries into one YAML file; --csv-dir: each bag's evaluated
rows as a reference-log CSV. Exit code 0; 1 when a file could not be
evaluated; 3 with --fail-on-garbage when some file has garbage.
"""
import argparse
import math
import os

import yaml

from anafi_sim.mission.evaluation import evaluate_bag, evaluate_csv
from anafi_sim.mission.reference_log import write_log


def evaluate_file(path, args):
    """Evaluation of one file (CSV or bag) according to the command-line options."""
    name = os.path.splitext(os.path.basename(path))[0]
    if path.endswith('.bag'):
        try:
            import rosbag
        except ImportError:
            raise ValueError('rosbag (python3-rosbag) is needed to read %s' % path)
        try:
            with rosbag.Bag(path) as bag:
                return evaluate_bag(bag, drone=args.drone, name=name, window=args.window,
                                    use_header_stamp=not args.receive_time, min_altitude=args.min_altitude)
        except rosbag.ROSBagException as e:
            raise ValueError('%s: not a readable bag: %s' % (path, e))
    result = evaluate_csv(path, window=args.window, min_altitude=args.min_altitude)
    return result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('files', nargs='+', metavar='FILE', help='reference-log CSV or rosbag files')
    parser.add_argument('--window', nargs=2, type=float, metavar=('T0', 'T1'),
                        help='evaluate only T0..T1 s after the first sample (overrides begin/end signals)')
    parser.add_argument('--drone', default=None, help='drone namespace in bags (default: the only one)')
    parser.add_argument('--yaml', default=None, metavar='OUT', help='write all summaries to this YAML file')
    parser.add_argument('--csv-dir', default=None, metavar='DIR',
                        help="write each bag's evaluated rows as a reference-log CSV into DIR")
    parser.add_argument('--receive-time', action='store_true',
                        help='align by bag receive time instead of header stamps')
    parser.add_argument('--min-altitude', type=float, default=-1.0, metavar='M',
                        help='positions below M metres are excluded as not flying (default -1)')
    parser.add_argument('--fail-on-garbage', action='store_true', help='exit 3 when a file has garbage samples')
    args = parser.parse_args(argv)
    if args.window and not (math.isfinite(args.window[0]) and args.window[1] >= args.window[0]):
        parser.error('--window needs T0 <= T1')
    summaries = []
    failed = garbage = False
    for path in args.files:
        try:
            result = evaluate_file(path, args)
        except (IOError, OSError, ValueError) as e:
            print('%s: ERROR %s' % (path, e))
            failed = True
            continue
        print('\n'.join(result.lines()))
        garbage = garbage or result.has_garbage
        d = result.as_dict()
        d['file'] = path
        summaries.append(d)
        if args.csv_dir and path.endswith('.bag'):
            if not os.path.isdir(args.csv_dir):
                os.makedirs(args.csv_dir)
            out = os.path.join(args.csv_dir, os.path.splitext(os.path.basename(path))[0] + '.csv')
            write_log(out, result.log)
            print('  rows written to %s' % out)
    if args.yaml:
        with open(args.yaml, 'w') as f:
            yaml.safe_dump([dict(s) for s in summaries], f, default_flow_style=False, sort_keys=False)
    if failed:
        return 1
    if garbage and args.fail_on_garbage:
        return 3
    return 0
