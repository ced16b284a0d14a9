#!/usr/bin/env python3
"""Fit the simulated Anafi's parameters to reference logs; write the YAML, a report and a replay figure.

Usage: calibrate_model.py [--logs DIR] [--out YAML] [--fitted YAML] [--report MD] [--context YAML] [--plot PNG]
Defaults (paths of the package's checkout, found through the ROS package path): logs
<checkout>/../shared/reference_logs, out anafi_sim/config/anafi_model.yaml (the fidelity effects as
fit.SHIPPED_EFFECTS says), fitted anafi_sim/config/anafi_model_fitted.yaml (every fitted effect on), report
docs/calibration.md (its "Real flights" section, calibrate_conditions.py's, is kept), context benchmarks/results/calibration.yaml (the figures of the report and of both model
YAMLs: the texts are rendered from it, and render again from it without the fits), plot
docs/calibration_replay.png. The fits are anafi_lab/calibration/ (fit.py puts them together), the texts
anafi_lab/reports/calibration_report.py with its templates anafi_lab/reports/templates/calibration.md and
anafi_model.yaml, the figure anafi_lab/calibration/plot.py; this script only wires them to files (the texts
each written atomically).
"""
import argparse
import glob
import os
import sys

import yaml

from anafi_sim import paths, run_files
from anafi_lab.calibration import conditions, fit, plot
from anafi_lab.reports import calibration_report as report
from anafi_sim.mission.reference_log import read_log


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
    parser.add_argument('--context', default=os.path.join(root, 'benchmarks', 'results', 'calibration.yaml'),
                        help='the figures of the report and the model YAMLs ("" to skip)')
    parser.add_argument('--plot', default=os.path.join(root, 'docs', 'calibration_replay.png'),
                        help='PNG figure to write ("" to skip)')
    args = parser.parse_args(argv)
    args.log_files = sorted(glob.glob(os.path.join(args.logs, '*.csv')))
    if not args.log_files:
        parser.error('no *.csv reference logs in %s' % args.logs)
    return args


def write(path, text):
    """Write ``text`` to ``path`` atomically and say so."""
    run_files.atomic_write_text(path, text)
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

    plot_name = None
    if args.plot:
        plot.plot_replay(cal, logs, args.plot)
        print('wrote %s (%d bytes)' % (args.plot, os.path.getsize(args.plot)))
        plot_name = os.path.relpath(args.plot, os.path.dirname(os.path.abspath(args.report or args.plot)))
    # every text is rendered from the stored figures, as the unit test renders them again
    stored = yaml.safe_dump(report.stored_context(cal, logs, plot_name=plot_name), default_flow_style=False,
                            sort_keys=False)
    if args.context:
        write(args.context, stored)
    stored = yaml.safe_load(stored)
    write(args.out, report.render_model_yaml(stored['model']))
    if args.fitted:
        write(args.fitted, report.render_model_yaml(stored['model_fitted']))
    if args.report:
        # the real flights' section (calibrate_conditions.py) is kept as it is
        kept = conditions.existing_section(open(args.report).read()) if os.path.exists(args.report) else ''
        text = report.render_report(stored['report'])
        write(args.report, conditions.replace_section(text, kept) if kept else text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
