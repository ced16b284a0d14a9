#!/usr/bin/env python3
"""Fit the simulated Anafi's parameters to reference logs; write the YAML, a report and a replay figure.

Usage: calibrate_model.py [--logs DIR] [--out YAML] [--fitted YAML] [--report MD] [--context YAML] [--plot PNG]
Defaults (paths of the package's checkout, found through the ROS package path): logs
<checkout>/../shared/reference_logs, out anafi_sim/config/anafi_model.yaml (the fidelity effects as
fit.SHIPPED_EFFECTS says), fitted anafi_sim/config/anafi_model_fitted.yaml (every fitted effect on), report
docs/calibration.md, context benchmarks/results/calibration.yaml (the report's figures: the report renders
again from it without the fits), plot docs/calibration_replay.png. The fits are anafi_lab/calibration/ (fit.py
puts them together), the texts anafi_lab/reports/calibration_report.py and its template
anafi_lab/reports/templates/calibration.md, the figure anafi_lab/calibration/plot.py; this script only wires
them to files (the texts each written atomically).
"""
import argparse
import glob
import os
import sys
import tempfile

import yaml

from anafi_sim import paths
from anafi_lab.calibration import fit, plot
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
                        help='the report\'s figures as YAML ("" to skip)')
    parser.add_argument('--plot', default=os.path.join(root, 'docs', 'calibration_replay.png'),
                        help='PNG figure to write ("" to skip)')
    args = parser.parse_args(argv)
    args.log_files = sorted(glob.glob(os.path.join(args.logs, '*.csv')))
    if not args.log_files:
        parser.error('no *.csv reference logs in %s' % args.logs)
    return args


def write(path, text):
    """Write ``text`` to ``path`` atomically (a temporary file beside it, then renamed)."""
    folder = os.path.dirname(os.path.abspath(path))
    handle, temporary = tempfile.mkstemp(dir=folder, prefix='.' + os.path.basename(path) + '.')
    try:
        with os.fdopen(handle, 'w') as stream:
            stream.write(text)
        os.chmod(temporary, 0o644)
        os.replace(temporary, path)
    except BaseException:
        os.unlink(temporary)
        raise
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
    # the report is rendered from its stored figures, as its test renders it again
    stored = yaml.safe_dump(report.report_context(cal, logs, plot_name=plot_name), default_flow_style=False,
                            sort_keys=False)
    if args.context:
        write(args.context, stored)
    if args.report:
        write(args.report, report.render_report(yaml.safe_load(stored)))
    return 0


if __name__ == '__main__':
    sys.exit(main())
