#!/usr/bin/env python3
"""Fit the simulated Anafi's parameters to reference logs; write the YAML, a report and a replay figure.

Usage: calibrate_model.py [--logs DIR] [--update | --dir DIR] [--out YAML] [--fitted YAML] [--report MD]
                          [--context YAML] [--plot PNG]
Logs: the paper's reference logs shipped with the package (anafi_sim/data/reference_logs, ``paths.reference_logs_dir``).
Where the files go:
- by default (``make calibrate``) into a new run folder ``<checkout>/run/calibrate-<date>-<time>-<pid>/``
  (``--dir DIR``: a new run folder below DIR; ``run/latest`` links to the newest): anafi_model.yaml,
  anafi_model_fitted.yaml, calibration.md, calibration.yaml, calibration_replay.png; each is then compared with
  its committed file ("same" / "differs"); nothing tracked is touched;
- with ``--update`` (``UPDATE=1 make calibrate``) over the committed files: out anafi_sim/config/anafi_model.yaml
  (the fidelity effects as fit.SHIPPED_EFFECTS says), fitted anafi_sim/config/anafi_model_fitted.yaml (every
  fitted effect on), report docs/calibration.md, context benchmarks/results/calibration.yaml (the figures of the
  report and of both model YAMLs: the texts are rendered from it, and render again from it without the fits),
  plot docs/calibration_replay.png;
- ``--out`` / ``--fitted`` / ``--report`` / ``--context`` / ``--plot`` name one file each ("" skips it).
The report's "Real flights" section (calibrate_conditions.py's) is kept from the report being replaced, else from
the committed docs/calibration.md. The fits are anafi_lab/calibration/ (fit.py puts them together), the texts
anafi_lab/reports/calibration_report.py with its templates anafi_lab/reports/templates/calibration.md and
anafi_model.yaml, the figure anafi_lab/reports/calibration_plot.py; this script only wires them to files (the texts
each written atomically).
"""
import argparse
import filecmp
import glob
import os
import sys

import yaml

from anafi_sim import paths, run_files
from anafi_lab.calibration import fit
from anafi_lab.reports import calibration_plot as plot
from anafi_lab.reports import calibration_report as report, conditions_report
from anafi_sim.mission.reference_log import read_log

#: (option, committed path below the checkout, file name in a run folder): the files a calibration writes
OUTPUTS = (('out', ('anafi_sim', 'config', 'anafi_model.yaml'), 'anafi_model.yaml'),
           ('fitted', ('anafi_sim', 'config', 'anafi_model_fitted.yaml'), 'anafi_model_fitted.yaml'),
           ('report', ('docs', 'calibration.md'), 'calibration.md'),
           ('context', ('benchmarks', 'results', 'calibration.yaml'), 'calibration.yaml'),
           ('plot', ('docs', 'calibration_replay.png'), 'calibration_replay.png'))


def committed(option):
    """The committed file of an output option (e.g. 'out': <checkout>/anafi_sim/config/anafi_model.yaml)."""
    return os.path.join(paths.checkout(), *dict((o, c) for o, c, _ in OUTPUTS)[option])


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--logs', default=paths.reference_logs_dir(),
                        help='directory with reference-log CSVs (default: the shipped ones, %s)' % report.LOGS_LABEL)
    where = parser.add_mutually_exclusive_group()
    where.add_argument('--update', action='store_true',
                       help='write over the committed files (model YAMLs, docs/calibration.md, its figure and '
                            'benchmarks/results/calibration.yaml); UPDATE=1 make calibrate')
    where.add_argument('--dir', default=None,
                       help='a new run folder is made below DIR (default: <checkout>/run)')
    parser.add_argument('--out', default=None,
                        help='model YAML to write (fidelity effects as fit.SHIPPED_EFFECTS says)')
    parser.add_argument('--fitted', default=None,
                        help='model YAML with every fitted fidelity effect on ("" to skip)')
    parser.add_argument('--report', default=None, help='Markdown report to write ("" to skip)')
    parser.add_argument('--context', default=None, help='the figures of the report and the model YAMLs ("" to skip)')
    parser.add_argument('--plot', default=None, help='PNG figure to write ("" to skip)')
    args = parser.parse_args(argv)
    args.log_files = sorted(glob.glob(os.path.join(args.logs, '*.csv')))
    if not args.log_files:
        parser.error('no *.csv reference logs in %s' % args.logs)
    args.logs_label = (report.LOGS_LABEL if os.path.realpath(args.logs) == os.path.realpath(paths.reference_logs_dir())
                       else args.logs)
    args.run_dir = None
    unset = [option for option, _, _ in OUTPUTS if getattr(args, option) is None]
    if unset and not args.update:
        args.run_dir = run_files.new_run_dir(args.dir or os.path.join(paths.checkout(), 'run'), 'calibrate')
    for option, _, name in OUTPUTS:
        if getattr(args, option) is None:
            setattr(args, option, committed(option) if args.update else os.path.join(args.run_dir, name))
    return args


def write(path, text):
    """Write ``text`` to ``path`` atomically and say so."""
    run_files.atomic_write_text(path, text)
    print('wrote %s' % path)


def compare_with_committed(args):
    """Lines saying, for each file written into the run folder, whether it equals its committed file."""
    lines = []
    for option, _, _ in OUTPUTS:
        path, original = getattr(args, option), committed(option)
        if not path or os.path.dirname(os.path.abspath(path)) != args.run_dir or not os.path.isfile(path):
            continue
        same = os.path.isfile(original) and filecmp.cmp(path, original, shallow=False)
        lines.append('%s %s' % ('same as   ' if same else 'DIFFERS from', os.path.relpath(original, paths.checkout())))
    return lines


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
    stored = yaml.safe_dump(report.stored_context(cal, logs, plot_name=plot_name, logs_label=args.logs_label),
                            default_flow_style=False, sort_keys=False)
    if args.context:
        write(args.context, stored)
    stored = yaml.safe_load(stored)
    write(args.out, report.render_model_yaml(stored['model']))
    if args.fitted:
        write(args.fitted, report.render_model_yaml(stored['model_fitted']))
    if args.report:
        # the real flights' section (calibrate_conditions.py) is kept as it is
        source = args.report if os.path.exists(args.report) else committed('report')
        kept = conditions_report.existing_section(open(source).read()) if os.path.exists(source) else ''
        text = report.render_report(stored['report'])
        write(args.report, conditions_report.replace_section(text, kept) if kept else text)
    if args.run_dir:
        print('run folder %s (the committed files are left as they are; UPDATE=1 make calibrate or --update '
              'rewrites them):' % args.run_dir)
        for line in compare_with_committed(args):
            print('  ' + line)
    return 0


if __name__ == '__main__':
    sys.exit(main())
