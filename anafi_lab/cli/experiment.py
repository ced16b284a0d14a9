#!/usr/bin/env python3
"""Experiments from the command line: one run, the paper's batch, or a sweep; in-process (default) or ROS.

    experiment.py run --controller pid|mpc|pid_single|pkg.mod:Class --scenario NAME|PATH [--seed S]
                      [--wind X,Y[,Z]] [--gust STD] [--gust-vertical STD] [--gust-tau S]
                      [--conditions NAME|PATH] [--param KEY=VALUE ...] [--schedule KEY=VALUE ...] [--sync-schedule]
                      [--state-source estimate|truth]
                      [--engine inprocess|ros [--sync] [--rtf R]] [--no-plot] [--format png|svg|pdf] [--dpi N]
                      --out DIR
        -> DIR/<scenario>_<controller>[_<conditions>].yaml (the evaluator's summary), .csv (reference log), the
           figure (.png, --format svg / pdf, --dpi; a failed run's title says FAILED); one
           'RESULT ...' line on stdout, then one line per file written (exit 0 when the summary is final).
           --engine ros: in a new folder DIR/<scenario>_<controller>-<date>-<time>-<pid> per run (DIR/latest links to it).
    experiment.py batch [--engine inprocess|ros [--sync] [--rtf R]] [--workers N] [--scheduler ADDRESS] [--conditions C]
                        [--scenarios ...] [--controllers mpc,pid,preview_mpc] [--runs-dir DIR] [--no-plots] --out DIR
        -> DIR/experiments.yaml (the ROS batch's schema) and DIR/report.md (the paper's tables), plots.
    experiment.py sweep NAME|SPEC.yaml [--workers N] [--scheduler ADDRESS] [--conditions C] [--no-plot] --out DIR
        -> DIR/runs.csv (every run's metrics), DIR/summary.md, DIR/e_mu.png. NAME: a spec of
           anafi_lab/sweeps/ (e.g. wind_circles); a relative path missing here is looked up in the package.

``--conditions NAME|PATH``: a flight-conditions profile (anafi_sim/config/conditions/, e.g. real_flights: the
wind, gusts and firmware wind handling of the paper's outdoor flights) under the run's settings; ``--wind`` and
the gust options override its wind. For a sweep it overrides the spec's ``conditions:``. Without it: sim.yaml
(no wind), as Sphinx flew.

The in-process engine (anafi_lab.engine.engine) needs no ROS master: the same cores as the nodes on
virtual time, bit-for-bit deterministic for a seed. ``--engine ros`` runs the real graph instead
(experiment.launch through anafi_lab/cli/ros_batch.py: needs a ROS environment, takes the seed and wind of
sim.yaml; ``--sync``: in lockstep, experiment.launch sync:=true, so that its results do not depend on the
machine's load). Workers: processes on this machine (concurrent.futures); ``--scheduler`` sends the same tasks to a
Dask distributed scheduler (python3-distributed; the workers need this package importable). Progress: a
tqdm bar on a terminal (with its ETA), one line per finished run otherwise (on stderr: elapsed, ETA).
"""
import argparse
import os
import shutil
import subprocess
import sys

import yaml

from anafi_sim import paths, run_files
from anafi_sim.run_files import FIGURE_DPI, FIGURE_FORMATS
from anafi_lab import paper
from anafi_lab.reports import paper_tables as report
from anafi_control import registry
from anafi_lab.engine.engine import make_schedule, wind_settings
from anafi_lab.engine.runs import SYNC_SCHEDULE, make_task, result_line, run_task, task_name
from anafi_lab.reports.batch_report import batch
from anafi_lab.engine.sweep import GROUPS, load_spec, unflatten
from anafi_lab.reports.sweep_report import run_sweep
from anafi_sim.mission.trajectory import list_scenarios
from anafi_sim.sim.conditions_profile import conditions_label, load_conditions


#: the batch's controllers by engine (the ROS batch runs the paper's two); README's run counts come from these
BATCH_CONTROLLERS = {'inprocess': ','.join(paper.KNOWN_CONTROLLERS), 'ros': ','.join(paper.CONTROLLERS)}


def _key_values(items, what):
    """['a=1', 'loop.Kp=2'] -> nested dict with YAML-parsed values."""
    pairs = []
    for item in items or []:
        key, sep, text = item.partition('=')
        if not sep or not key:
            raise ValueError('%s must be KEY=VALUE, got %r' % (what, item))
        pairs.append((key, yaml.safe_load(text)))
    return unflatten(pairs)


def _wind(args):
    wind = {}
    if args.wind:
        values = [float(v) for v in args.wind.split(',')]
        if len(values) not in (2, 3):
            raise ValueError('--wind X,Y[,Z] [m/s], got %r' % args.wind)
        wind.update(zip(('wind_x', 'wind_y', 'wind_z'), values))
    for key, value in (('gust_std_horizontal', args.gust), ('gust_std_vertical', args.gust_vertical),
                       ('gust_time_constant', args.gust_tau)):
        if value is not None:
            wind[key] = value
    wind_settings(wind)
    return wind or None


def _ros_batch(out_dir, scenarios, controllers, runs_dir, extra=()):
    cmd = [sys.executable, '-m', 'anafi_lab.cli.ros_batch', '--controllers', ','.join(controllers), '--scenarios',
           ','.join(scenarios), '--runs-dir', runs_dir, '--report', os.path.join(out_dir, 'experiments.md')]
    cmd += list(extra)
    return subprocess.call(cmd)


def _in_process_only(args):
    if args.sync:
        raise ValueError('--sync is for --engine ros (lockstep ROS runs); the in-process engine runs on virtual '
                         'time anyway (--sync-schedule gives it the lockstep\'s schedule)')


def cmd_run(args):
    wind = _wind(args)
    params = _key_values(args.param, '--param')
    schedule = _key_values(args.schedule, '--schedule')
    if args.sync_schedule:
        schedule = dict(SYNC_SCHEDULE, **schedule)
    make_schedule(schedule)
    os.makedirs(args.out, exist_ok=True)
    from anafi_sim.mission import plots
    plots.check_dpi(args.dpi)
    task = make_task(args.scenario, args.controller, seed=args.seed, wind=wind, params=params or None,
                     schedule=schedule or None, state_source=args.state_source, name=args.name,
                     out_dir=args.out, plot=not args.no_plot, conditions=args.conditions, plot_format=args.format,
                     plot_dpi=args.dpi)
    if args.conditions and not args.name:       # a windy run's name says so (files, title)
        task['name'] = '%s_%s' % (task_name(task), conditions_label(args.conditions))
    load_conditions(args.conditions)
    name = task_name(task)
    if args.engine == 'ros':
        if args.controller not in paper.CONTROLLERS or wind or params or schedule or args.seed is not None \
                or args.state_source != 'estimate' or args.name or args.conditions:
            raise ValueError('--engine ros runs experiment.launch as it is: controller mpc or pid, the seed and wind '
                             'of sim.yaml, no --param / --schedule / --state-source / --name / --conditions '
                             '(roslaunch anafi_sim experiment.launch conditions:=NAME runs the graph in them)')
        args.out = run_files.new_run_dir(args.out, name)    # its own folder: concurrent runs never share files
        print('run folder %s (%s)' % (args.out, os.path.join(os.path.dirname(args.out), run_files.LATEST)))
        rc = _ros_batch(args.out, [args.scenario], [args.controller], args.out,
                        ['--no-plots', '--retries', '0', '--report', os.path.join(args.out, 'ros_batch.md'),
                         '--rtf', str(args.rtf)] + (['--sync'] if args.sync else []))
        summary_path = os.path.join(args.out, name + '.yaml')
        summary = yaml.safe_load(open(summary_path)) if os.path.isfile(summary_path) else None
        run_info = os.path.join(args.out, name + '.run.yaml')
        monitor = (yaml.safe_load(open(run_info)) if os.path.isfile(run_info) else None) or {}
        record = {'scenario': args.scenario, 'controller': args.controller,
                  'ok': rc == 0 and isinstance(summary, dict) and summary.get('state') == 'final',
                  'error': '' if rc == 0 else 'ROS run failed (exit %d), see %s' % (rc, args.out),
                  'summary': summary, 'info': {'sim_s': monitor.get('scenario_sim_s'),
                                               'wall_s': monitor.get('scenario_wall_s'),
                                               'achieved_rtf': monitor.get('achieved_rtf')}}
        csv_path = os.path.join(args.out, name + '.csv')
        if not args.no_plot and os.path.isfile(csv_path):
            plots.plot_run(csv_path, os.path.join(args.out, name + '.' + args.format), summary=summary, title=name,
                           dpi=args.dpi, failed=None if record['ok'] else record['error'] or True)
        record['files'] = dict((key, os.path.join(args.out, name + ext)) for key, ext in (
            ('summary', '.yaml'), ('csv', '.csv'), ('plot', '.' + args.format), ('bag', '.bag'),
            ('info', '.run.yaml')))
    else:
        _in_process_only(args)
        record = run_task(task)
    print(result_line(record, name))
    for key, path in sorted((record.get('files') or {}).items()):
        if path and os.path.isfile(path):
            print('  %-8s %s' % (key + ':', os.path.abspath(path)))
    return 0 if record['ok'] else 1


def _selection(text, groups, known, what):
    out = []
    for item in [s.strip() for s in text.split(',') if s.strip()]:
        for name in groups.get(item, (item,)):
            if name not in known:
                raise ValueError('unknown %s %s (known: %s)' % (what, name, ', '.join(sorted(known))))
            if name not in out:
                out.append(name)
    if not out:
        raise ValueError('no %s selected' % what)
    return out


def command_line(argv=None):
    """This command as the reports quote it: paths below the checkout relative to it."""
    root = paths.checkout() + os.sep
    return 'anafi_lab/cli/experiment.py ' + ' '.join(a.replace(root, '') for a in (argv or sys.argv[1:]))


def cmd_batch(args):
    scenarios = _selection(args.scenarios, GROUPS, set(list_scenarios()), 'scenario')
    controllers = _selection(args.controllers or BATCH_CONTROLLERS[args.engine], {}, set(paper.KNOWN_CONTROLLERS),
                             'controller')
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    command = command_line()
    if args.engine == 'ros':
        if args.conditions:
            raise ValueError('--conditions is for the in-process batch (roslaunch anafi_sim experiment.launch '
                             'conditions:=NAME runs the graph in them)')
        runs_dir = os.path.abspath(args.runs_dir or os.path.join(out, 'runs'))
        extra = ['--rtf', str(args.rtf)] + (['--no-plots'] if args.no_plots else []) + (
            ['--sync'] if args.sync else [])
        rc = _ros_batch(out, scenarios, controllers, runs_dir, extra)
        md = os.path.join(out, 'experiments.md')
        if os.path.isfile(md):
            shutil.move(md, os.path.join(out, 'report.md'))
        print('ROS batch: %s, %s' % (os.path.join(out, 'experiments.yaml'), os.path.join(out, 'report.md')))
        return rc
    _in_process_only(args)
    load_conditions(args.conditions)
    records, meta, report_path = batch(out, scenarios, controllers, workers=args.workers, scheduler=args.scheduler,
                                       runs_dir=args.runs_dir, plots=not args.no_plots, command=command,
                                       conditions=args.conditions)
    ok = sum(1 for r in records if r['ok'])
    print('batch done: %d of %d runs ok, %.1f s wall for %.0f s of simulated time; %s, %s' % (
        ok, len(records), meta['wall_s'], meta['sim_s'], os.path.join(out, 'experiments.yaml'), report_path))
    _, wins, compared = report.beats_summary(records)
    print('MPC better than PID (e_mu vs estimate) in %d of %d scenarios' % (wins, compared))
    return 0 if ok == len(records) else 1


def cmd_sweep(args):
    spec = load_spec(args.spec)
    if args.conditions:
        spec['conditions'] = args.conditions
    command = command_line()
    table, out_paths, meta = run_sweep(spec, args.out, workers=args.workers, scheduler=args.scheduler,
                                       command=command, plot=not args.no_plot)
    ok = sum(1 for r in table if r['ok'])
    print('sweep %s: %d of %d runs ok, %.1f s wall; %s' % (spec.get('name'), ok, len(table), meta['wall_s'],
                                                           ', '.join(out_paths.values())))
    return 0 if ok == len(table) else 1


def parser():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    sub = ap.add_subparsers(dest='command')
    sub.required = True

    run = sub.add_parser('run', help='one experiment')
    run.add_argument('--controller', default='mpc',
                     help='%s, or package.module:Class (a contract.Controller)' % ', '.join(registry.names()))
    run.add_argument('--scenario', required=True, help='a scenario name (anafi_sim/config/scenarios) or a YAML path')
    run.add_argument('--seed', type=int, default=None, help='wind-gust seed (default: sim.yaml, 0)')
    run.add_argument('--wind', default=None, help='constant wind X,Y[,Z] [m/s], world ENU')
    run.add_argument('--gust', type=float, default=None, help='horizontal gust std [m/s]')
    run.add_argument('--gust-vertical', type=float, default=None, help='vertical gust std [m/s]')
    run.add_argument('--gust-tau', type=float, default=None, help='gust time constant [s]')
    run.add_argument('--conditions', default=None, metavar='NAME|PATH',
                     help='flight-conditions profile (anafi_sim/config/conditions, e.g. real_flights); default none')
    run.add_argument('--param', action='append', metavar='KEY=VALUE',
                     help='controller parameter (mpc: mpc.yaml keys, e.g. r=0.1; pid: LOOP.PARAM, e.g. x_outer.Kp=1)')
    run.add_argument('--schedule', action='append', metavar='KEY=VALUE',
                     help='engine schedule override (anafi_lab.engine.engine.DEFAULT_SCHEDULE)')
    run.add_argument('--sync-schedule', action='store_true',
                     help='the schedule of a ROS run with experiment.launch sync:=true (runs.SYNC_SCHEDULE; '
                          '--schedule wins)')
    run.add_argument('--state-source', default='estimate', choices=('estimate', 'truth'))
    run.add_argument('--name', default=None, help='run name (default SCENARIO_CONTROLLER)')
    run.add_argument('--engine', default='inprocess', choices=('inprocess', 'ros'))
    run.add_argument('--sync', action='store_true',
                     help='--engine ros: lockstep (experiment.launch sync:=true), results independent of the load')
    run.add_argument('--rtf', type=float, default=2.0, help='--engine ros: requested real-time factor')
    run.add_argument('--no-plot', action='store_true')
    run.add_argument('--format', default=FIGURE_FORMATS[0], choices=FIGURE_FORMATS,
                     help='the run\'s figure: png (default), svg or pdf')
    run.add_argument('--dpi', type=float, default=FIGURE_DPI, help='the figure\'s dots per inch (default %(default)s)')
    run.add_argument('--out', required=True, help='output folder')
    run.set_defaults(func=cmd_run)

    bat = sub.add_parser('batch', help='the paper\'s batch: every scenario with both controllers')
    bat.add_argument('--engine', default='inprocess', choices=('inprocess', 'ros'))
    bat.add_argument('--workers', type=int, default=None, help='processes (default: the CPU count)')
    bat.add_argument('--scheduler', default=None, help='Dask distributed scheduler address (tcp://host:8786)')
    bat.add_argument('--scenarios', default='all', help='all, a group (static, straight, circle, vertical) or names')
    bat.add_argument('--controllers', default=None,
                     help='comma list (default %s in-process; %s with --engine ros)'
                          % (BATCH_CONTROLLERS['inprocess'], BATCH_CONTROLLERS['ros']))
    bat.add_argument('--runs-dir', default=None, help='per-run summaries and CSVs (default OUT/runs)')
    bat.add_argument('--conditions', default=None, metavar='NAME|PATH', help='flight-conditions profile')
    bat.add_argument('--no-plots', action='store_true')
    bat.add_argument('--rtf', type=float, default=2.0, help='--engine ros: requested real-time factor')
    bat.add_argument('--sync', action='store_true',
                     help='--engine ros: lockstep (experiment.launch sync:=true), results independent of the load')
    bat.add_argument('--out', required=True)
    bat.set_defaults(func=cmd_batch)

    swp = sub.add_parser('sweep', help='a grid or list of runs from a YAML spec')
    swp.add_argument('spec', help='sweep spec: a name in anafi_lab/sweeps (e.g. wind_circles) or a path')
    swp.add_argument('--workers', type=int, default=1, help='processes (default 1)')
    swp.add_argument('--scheduler', default=None, help='Dask distributed scheduler address')
    swp.add_argument('--conditions', default=None, metavar='NAME|PATH',
                     help='flight-conditions profile (overrides the spec\'s conditions:)')
    swp.add_argument('--no-plot', action='store_true')
    swp.add_argument('--out', required=True)
    swp.set_defaults(func=cmd_sweep)
    return ap


def main(argv=None):
    ap = parser()
    args = ap.parse_args(argv)
    if getattr(args, 'workers', None) is not None and args.workers < 1:
        ap.error('--workers must be >= 1')
    try:
        return args.func(args)
    except (ValueError, RuntimeError, IOError, OSError) as error:
        sys.stderr.write('experiment.py: %s\n' % error)
        return 2


if __name__ == '__main__':
    sys.exit(main())
