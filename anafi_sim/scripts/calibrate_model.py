#!/usr/bin/env python3
"""Fit the simulated Anafi's parameters to reference logs; write the YAML, a report and a replay figure.

Usage: calibrate_model.py [--logs DIR] [--out YAML] [--fitted YAML] [--report MD] [--plot PNG]
Defaults (paths of the package's checkout, found through the ROS package path): logs
<checkout>/../shared/reference_logs, out anafi_sim/config/anafi_model.yaml (the fidelity effects as
fit.SHIPPED_EFFECTS says), fitted anafi_sim/config/anafi_model_fitted.yaml (every fitted effect on), report
docs/calibration.md (its "Real flights" section, calibrate_conditions.py's, is kept), plot
docs/calibration_replay.png. The fits are anafi_sim/calibration/fit.py, the texts
report.py, the figure plot.py; this script only wires them to files.
"""
import argparse
import glob
import os
import sys

from anafi_sim import paths
from anafi_sim.calibration import conditions, fit, plot, report
from anafi_sim.experiments.reference_log import read_log


def parse_args(argv):
    root = paths.checkout()
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--logs', default=paths.reference_logs_dir(),
                        help='directory with reference-log CSVs (default: <checkout>/../shared/reference_logs)')
    parser.add_argument('--out', default=os.path.join(root, 'anafi_sim', 'config', 'anafi_model.yaml'),
                        help='model YAML to write (fidelity effects as fit.SHIPPED_EFFECTS says)')
    parser.add_argument('--fitted', default=os.path.join(root, 'anafi_sim', 'config', 'anafi_model_fitted.yaml'),
                        help='model YAML with every fitted fidelity effect on ("" to skip)')
    parser.add_argument('--report', default=os.path.join(root, 'docs', 'calibration.md'),
                        help='Markdown report to write ("" to skip)')
    parser.add_argument('--plot', default=os.path.join(root, 'docs', 'calibration_replay.png'),
                        help='PNG figure to write ("" to skip)')
    args = parser.parse_args(argv)
    args.log_files = sorted(glob.glob(os.path.join(args.logs, '*.csv')))
    if not args.log_files:
        parser.error('no *.csv reference logs in %s' % args.logs)
    return args


def write(path, text):
    with open(path, 'w') as stream:
        stream.write(text)
    print('wrote %s' % path)


def main(argv=None):
    args = parse_args(argv)
    logs = [read_log(path) for path in args.log_files]
    for log in logs:
        for line_no, reason in log.parse_errors:
            print('warning: %s line %d skipped: %s' % (log.name, line_no, reason))
    cal = fit.calibrate(logs)
    for garbage in cal.garbage.values():
        for line in garbage.summary():
            print('garbage: ' + line)
    print(report.format_summary(cal))

    names = [log.name + '.csv' for log in logs]
    write(args.out, report.format_model_yaml(cal, names))
    if args.fitted:
        write(args.fitted, report.format_model_yaml(cal, names, fitted=True))
    plot_name = None
    if args.plot:
        plot.plot_replay(cal, logs, args.plot)
        print('wrote %s (%d bytes)' % (args.plot, os.path.getsize(args.plot)))
        plot_name = os.path.relpath(args.plot, os.path.dirname(os.path.abspath(args.report or args.plot)))
    if args.report:
        # the real flights' section (calibrate_conditions.py) is kept as it is
        kept = conditions.existing_section(open(args.report).read()) if os.path.exists(args.report) else ''
        text = report.format_report(cal, logs, plot_name=plot_name)
        write(args.report, conditions.replace_section(text, kept) if kept else text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
