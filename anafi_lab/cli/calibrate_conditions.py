#!/usr/bin/env python3
"""Identify the firmware's wind handling and the flight conditions from real-flight logs; write the profile.

Usage: calibrate_conditions.py [--logs DIR] [--profile YAML] [--report MD] [--fidelity MD] [--store YAML]
                               [--render-only] [--seeds N] [--workers N]
Defaults (paths of the package's checkout): logs anafi_sim/data/reference_logs/real (shipped), profile
anafi_sim/config/conditions/real_flights.yaml, report docs/calibration.md (its "Real flights" section is
replaced; calibrate_model.py keeps it when it rewrites the file), fidelity docs/fidelity.md (its real-flights
replay section, kept by anafi_lab/cli/measure_fidelity.py). The method is
anafi_lab/calibration/conditions.py; this script only wires it to files.
"""
import argparse
import glob
import os
import sys
import time

from anafi_sim import paths
from anafi_lab.calibration import conditions as cond
from anafi_lab.cli.calibrate_model import write
from anafi_lab.reports import conditions_report
from anafi_sim.mission.reference_log import read_log
from anafi_sim.sim.drone_model import load_model_params

COMMAND = 'anafi_lab/cli/calibrate_conditions.py'


def parse_args(argv):
    root = paths.checkout()
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--logs', default=paths.reference_logs_dir('real'),
                        help='directory with the real-flight log CSVs (default: the shipped ones, '
                             'anafi_sim/data/reference_logs/real)')
    parser.add_argument('--profile', default=os.path.join(root, 'anafi_sim', 'config', 'conditions',
                                                          'real_flights.yaml'),
                        help='conditions profile YAML to write ("" to skip)')
    parser.add_argument('--report', default=os.path.join(root, 'docs', 'calibration.md'),
                        help='Markdown file whose conditions section is replaced ("" to skip)')
    parser.add_argument('--fidelity', default=os.path.join(root, 'docs', 'fidelity.md'),
                        help='Markdown file whose real-flights replay section is replaced ("" to skip)')
    parser.add_argument('--store', default=os.path.join(root, 'benchmarks', 'results', 'real_flights.yaml'),
                        help='the closed-loop replays\' figures (YAML) to write, or to read with --render-only')
    parser.add_argument('--findings', default=os.path.join(root, 'benchmarks', 'results', 'conditions_findings.yaml'),
                        help='the figures of earlier checks the calibration section quotes (YAML)')
    parser.add_argument('--render-only', action='store_true',
                        help='no replays: the figures of --store (the identification is recomputed: seconds)')
    parser.add_argument('--seeds', type=int, default=3, help='gust seeds per closed-loop replay (default 3)')
    parser.add_argument('--workers', type=int, default=os.cpu_count() or 1, help='worker processes')
    args = parser.parse_args(argv)
    args.log_files = sorted(glob.glob(os.path.join(args.logs, '*.csv')))
    if not args.log_files:
        parser.error('no *.csv logs in %s' % args.logs)
    if args.seeds < 1:
        parser.error('--seeds must be >= 1')
    return args



def main(argv=None):
    args = parse_args(argv)
    t0 = time.time()
    model = load_model_params()
    logs = [read_log(path) for path in args.log_files]
    contributions = dict((log.name, cond.firmware_contribution(log, model)) for log in logs)
    handling = cond.fit_wind_handling(contributions)
    print('wind handling: K = %.3f +- %.3f (%d samples)' % (handling.gain, handling.gain_stderr, handling.samples))
    conds = [cond.estimate_conditions(log, model, contributions[log.name]) for log in logs]
    combined = cond.combine(conds)
    print('conditions: wind (%.2f, %.2f) m/s, gust <= %.2f m/s (%.2f s), noise %.4f m / %.4f m/s' % (
        combined['wind_x'], combined['wind_y'], combined['gust_std_horizontal'], combined['gust_time_constant'],
        combined['position_noise'], combined['velocity_noise']))
    wind = (combined['wind_x'], combined['wind_y'])
    settings_list = [cond.profile_settings(wind, gust, combined['gust_time_constant'], handling.gain, tau)
                     for tau in cond.TAU_W_GRID for gust in cond.GUST_GRID]
    off_index = len(settings_list)
    settings_list.append(cond.profile_settings(wind, cond.GUST_GRID[1], combined['gust_time_constant'], 0.0,
                                               cond.TAU_W_GRID[1]))
    seeds = list(range(args.seeds))
    references = dict((log.name, cond.log_figures(log)) for log in logs)
    if args.render_only:
        import yaml
        with open(args.store) as stream:
            stored = yaml.safe_load(stream)
        if [dict(s) for s in settings_list] != stored['settings'] or seeds != stored['seeds']:
            raise SystemExit('%s was made with other settings or seeds: rerun without --render-only' % args.store)
        grid = cond.grid_from_store(stored)
    else:
        grid = cond.replay_grid(logs, settings_list, seeds, workers=args.workers)
        write(args.store, cond.store_text(settings_list, seeds, grid, COMMAND))
    scores = [cond.score(grid, i, references)[0] for i in range(off_index)]
    chosen = min(range(off_index), key=lambda i: scores[i])
    print('chosen: %s (score %.3f)' % (dict(settings_list[chosen]), scores[chosen]))
    if args.profile:
        write(args.profile, cond.profile_text(settings_list[chosen], combined, handling, COMMAND))
    if args.report:
        section = conditions_report.calibration_section(logs, handling, conds, combined, grid, settings_list,
                                                        chosen, references, seeds, off_index, COMMAND,
                                                        conditions_report.load_findings(args.findings))
        text = open(args.report).read() if os.path.exists(args.report) else ''
        write(args.report, conditions_report.replace_section(text, section))
    if args.fidelity:
        section = conditions_report.fidelity_section(logs, grid, chosen, references, seeds, COMMAND)
        text = open(args.fidelity).read() if os.path.exists(args.fidelity) else ''
        write(args.fidelity, conditions_report.replace_section(text, section, conditions_report.FIDELITY_BEGIN,
                                                               conditions_report.FIDELITY_END))
    print('wall %.0f s' % (time.time() - t0))
    return 0


if __name__ == '__main__':
    sys.exit(main())
