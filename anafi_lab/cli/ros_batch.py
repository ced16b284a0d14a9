#!/usr/bin/env python3
"""Batch of the paper's experiments (Sec. V.B, Tables 3-5, Figs. 2 and 6): every scenario with both controllers.

Stage: benchmark. Runs ``roslaunch anafi_sim experiment.launch`` once per (scenario, controller), one
at a time (``--jobs``), each on its own ROS master (free port) and telemetry port, with its logs in
its own ROS_HOME, and cleans every process of the run up afterwards (by process id). Collects the
evaluator's summaries (e_max, e_mu, e_sigma [m] vs estimate and ground truth), the monitor's run
figures (achieved real-time factor, simulator overruns, MPC solve times, controller CPU), computes
the static waypoints' overshoot and settling from the exported CSV, draws one PNG per run
(anafi_sim.mission.plots) and Fig. 6-style comparisons, and writes ONE Markdown report
(default benchmarks/results/experiments.md, plots under benchmarks/results/plots/) plus the raw
records (experiments.yaml beside the report; ``--from-records`` re-renders a report from it).

    python -m anafi_lab.cli.ros_batch [--controllers mpc,pid] [--scenarios all|NAME,...] [--rtf 2] [--jobs 1]
                       [--mirror true|false] [--pid-mode distributed|single] [--runs-dir DIR]
                       [--report PATH] [--no-plots] [--record true|false] [--retries 1]

Run it inside the project's environment (env.bash: ROS, the workspace, the venv); ``make bench-ros``.
Exit code 0 when every run produced a final summary, 1 otherwise.
"""
import argparse
import datetime
import os
import sys
import time

import yaml

from anafi_sim import paths, processes, run_files
from anafi_lab import paper
from anafi_lab.reports import paper_tables as report
from anafi_sim.mission import step_response
from anafi_sim.mission.trajectory import list_scenarios, load_scenario
from anafi_sim.numeric import fmt



def child_env(ros_home, port):
    """Environment of a run: its master on ``port``, own ROS_HOME; the interpreter's site dir of osqp on
    PYTHONPATH so nodes started through /usr/bin/python3 relay scripts find it too."""
    env = dict(os.environ, ROS_MASTER_URI='http://127.0.0.1:%d' % port, ROS_HOME=ros_home, ROS_HOSTNAME='127.0.0.1')
    env.pop('ROS_IP', None)
    return processes.add_module_paths(env, 'osqp')


def read_yaml(path):
    """A run's result file (None when missing, cut or malformed)."""
    return run_files.read_yaml(path, tolerant=True)


class Run(object):
    """One (scenario, controller) experiment as a roslaunch subprocess."""

    def __init__(self, scenario, controller, args, runs_dir):
        self.scenario, self.controller = scenario, controller
        self.name = '%s_%s' % (scenario, controller)
        self.base = os.path.join(runs_dir, self.name)
        self.files = dict((k, self.base + ext) for k, ext in (
            ('summary', '.yaml'), ('csv', '.csv'), ('bag', '.bag'), ('info', '.run.yaml'), ('log', '.log')))
        for path in self.files.values():
            if os.path.exists(path):
                os.remove(path)
        self.duration = load_scenario(scenario).duration
        self.args = args
        self.port = processes.free_port()
        self.timeout = args.ready_timeout + 60.0 + 3.0 * self.duration / max(args.rtf, 0.1)
        ros_home = os.path.join(runs_dir, 'ros_home', self.name)
        cmd = ['roslaunch', '-p', str(self.port), 'anafi_sim', 'experiment.launch',
               'controller:=' + controller, 'scenario:=' + scenario, 'rtf:=%g' % args.rtf,
               'mirror:=' + args.mirror, 'record:=' + args.record, 'out_dir:=' + runs_dir,
               'run_name:=' + self.name, 'unique:=false', 'plot:=false', 'progress_period:=0',
               'telemetry_port:=%d' % processes.free_port(), 'pid_mode:=' + args.pid_mode,
               'ready_timeout:=%g' % args.ready_timeout] + (['sync:=true'] if args.sync else [])
        self.t0 = time.monotonic()
        self.epoch0 = time.time()
        self.proc = processes.start(cmd, env=child_env(ros_home, self.port), log=self.files['log'])
        self.done_at = None
        self.leftovers = []
        self.wall_s = None
        self.timed_out = False

    def poll(self):
        """True when the run is over (processes cleaned up)."""
        now = time.monotonic()
        finished = self.proc.poll() is not None
        if not finished and self.done_at is None and os.path.exists(self.files['info']):
            self.done_at = now            # the monitor wrote its figures: the run's result is complete
        if not finished and self.done_at is not None:
            bag_closed = self.args.record != 'true' or os.path.exists(self.files['bag'])
            if bag_closed or now - self.done_at > 20.0:
                finished = True           # skip roslaunch's slow sequential shutdown of the rest
        if not finished and now - self.t0 > self.timeout:
            self.timed_out = True
            finished = True
        if not finished:
            return False
        self.leftovers = processes.stop(self.proc, grace=0.5 if self.done_at is not None else 5.0, kill_wait=0.5)
        self.wall_s = time.monotonic() - self.t0
        return True

    def record(self):
        summary = read_yaml(self.files['summary'])
        info = read_yaml(self.files['info'])
        ok = bool(isinstance(summary, dict) and summary.get('state') == 'final' and isinstance(info, dict)
                  and info.get('state') == 'final')
        error = ''
        if not ok:
            if self.timed_out:
                error = 'timed out after %.0f s' % self.timeout
            elif isinstance(info, dict) and info.get('reason'):
                error = info['reason']
            else:
                error = 'no final summary (see %s)' % self.files['log']
        rec = {'scenario': self.scenario, 'controller': self.controller, 'ok': ok, 'error': error,
               'summary': summary if isinstance(summary, dict) else None,
               'info': info if isinstance(info, dict) else None, 'step': None,
               'wall_s': round(self.wall_s, 2), 'files': dict(self.files), 'plot': '',
               'leftover_processes': self.leftovers}
        clock = (info or {}).get('wall_clock') if isinstance(info, dict) else None
        if isinstance(clock, dict) and clock.get('created') and clock.get('final'):
            rec['phases_wall_s'] = {
                'launch_to_monitor': round(clock['created'] - self.epoch0, 2),
                'monitor_to_start': round((clock.get('started') or clock['created']) - clock['created'], 2),
                'start_to_final': round(clock['final'] - (clock.get('started') or clock['created']), 2),
                'final_to_cleaned_up': round(self.epoch0 + self.wall_s - clock['final'], 2)}
        if ok and self.scenario.startswith('static'):
            try:
                from anafi_sim.mission.plots import load, summary_window
                window = summary_window(summary)
                rec['step'] = step_response.as_dict(step_response.step_metrics(load(self.files['csv']), window))
            except (IOError, OSError, ValueError, TypeError) as e:
                rec['error'] = 'step metrics: %s' % e
        return rec


def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--controllers', default=','.join(report.CONTROLLERS),
                    help='comma list of %s (default all)' % ', '.join(report.CONTROLLERS))
    ap.add_argument('--scenarios', default='all',
                    help='all (Tables 3-5 + WP0/WP1), a group (static, straight, circle, vertical) or names')
    ap.add_argument('--rtf', type=float, default=2.0,
                    help='requested real-time factor (default 2: the distributed PID stack saturates 2 cores '
                         'at about 1.7; a higher request only magnifies CPU hiccups in simulated time)')
    ap.add_argument('--jobs', type=int, default=1, help='runs in parallel (default 1; 2 cores: keep 1)')
    ap.add_argument('--mirror', default='true', choices=('true', 'false'))
    ap.add_argument('--sync', action='store_true',
                    help='lockstep (experiment.launch sync:=true): simulation time waits for every control '
                         'period\'s command, so the results do not depend on the machine\'s load; --rtf is then '
                         'a ceiling (the distributed PID graph is not held: use --rtf 0.5 for it)')
    ap.add_argument('--record', default='true', choices=('true', 'false'))
    ap.add_argument('--pid-mode', default='distributed', choices=('distributed', 'single'))
    ap.add_argument('--ready-timeout', type=float, default=90.0, help='s wall for a run to come up')
    ap.add_argument('--retries', type=int, default=1,
                    help='repeat a failed or disturbed run (controller starved: hover commands, command gap) '
                         'up to this many times (default 1)')
    ap.add_argument('--runs-dir', default=None,
                    help='run files (bags, CSV, logs); default ~/.ros/anafi_runs/batch-<date>')
    ap.add_argument('--report', default=os.path.join(paths.checkout(), 'benchmarks', 'results', 'experiments.md'))
    ap.add_argument('--plots-dir', default=None, help='default: plots/ beside the report')
    ap.add_argument('--no-plots', action='store_true')
    ap.add_argument('--from-records', default=None, metavar='YAML',
                    help='no runs: re-render the report (and plots, where the run CSVs still exist) from the '
                         'records YAML a previous batch wrote beside its report')
    args = ap.parse_args(argv)
    controllers = [c.strip() for c in args.controllers.split(',') if c.strip()]
    bad = [c for c in controllers if c not in paper.CONTROLLERS]
    if bad or not controllers:
        ap.error('--controllers: choose from mpc, pid (got %s)' % args.controllers)
    groups = {'all': paper.ALL_SCENARIOS, 'static': paper.STATIC, 'straight': paper.STRAIGHT,
              'circle': paper.CIRCLE_SCENARIOS, 'vertical': paper.VERTICAL_SCENARIOS}
    scenarios = []
    known = set(list_scenarios())
    for item in [s.strip() for s in args.scenarios.split(',') if s.strip()]:
        for s in groups.get(item, (item,)):
            if s not in known:
                ap.error('unknown scenario %s (known: %s)' % (s, ', '.join(sorted(known))))
            if s not in scenarios:
                scenarios.append(s)
    if not scenarios:
        ap.error('--scenarios: nothing selected')
    if args.jobs < 1:
        ap.error('--jobs must be >= 1')
    if args.retries < 0:
        ap.error('--retries must be >= 0')
    if not args.rtf > 0:
        ap.error('--rtf must be > 0')
    args.controller_list, args.scenario_list = controllers, scenarios
    return args


def make_plots(records, plots_dir, report_dir):
    """Per-run PNGs and Fig. 6-style comparisons; returns (plots, comparisons) as (label, relative path)."""
    from anafi_sim.mission import plots
    out, comparisons = [], []
    for rec in records:
        name = '%s_%s' % (rec['scenario'], rec['controller'])
        csv = (rec.get('files') or {}).get('csv')
        if not csv or not os.path.exists(csv):
            if rec.get('plot') and os.path.exists(os.path.join(report_dir, rec['plot'])):
                out.append((name, rec['plot']))        # re-rendering without the run files: keep the PNG
            continue
        path = os.path.join(plots_dir, name + '.png')
        try:
            plots.plot_run(csv, path, summary=rec.get('summary'), title='%s, %s' % (
                rec['scenario'], paper.LABELS.get(rec['controller'], rec['controller'])))
        except (IOError, OSError, ValueError) as e:
            print('plot %s failed: %s' % (name, e))
            continue
        rec['plot'] = os.path.relpath(path, report_dir)
        out.append((name, rec['plot']))
    static = [(r['scenario'], r['controller'], r) for r in records if r['scenario'] in paper.STATIC and r['ok']
              and os.path.exists((r.get('files') or {}).get('csv') or '')]
    if static:
        runs = []
        for scenario, controller, rec in sorted(static, key=lambda x: (x[0], x[1] != 'pid')):
            window = plots.summary_window(rec['summary'])
            runs.append(('%s %s' % (paper.LABELS[controller], 'WP0' if scenario.endswith('0') else 'WP1'),
                         rec['files']['csv'], window[0] if window else 0.0))
        path = os.path.join(plots_dir, 'static_waypoints.png')
        try:
            plots.plot_comparison(runs, path, title='Static waypoints WP0 / WP1 from hover (cf. Fig. 6); '
                                                    't = 0 at the step')
            comparisons.append((report.STATIC_COMPARISON,
                                os.path.relpath(path, report_dir)))
        except (IOError, OSError, ValueError) as e:
            print('comparison plot failed: %s' % e)
    elif os.path.exists(os.path.join(plots_dir, 'static_waypoints.png')):
        comparisons.append((report.STATIC_COMPARISON,
                            os.path.relpath(os.path.join(plots_dir, 'static_waypoints.png'), report_dir)))
    return out, comparisons


def write_report(args, records, meta):
    """Plots, the Markdown report and the records YAML beside it; returns the report path."""
    report_path = os.path.abspath(args.report)
    report_dir = os.path.dirname(report_path)
    plots_dir = os.path.abspath(args.plots_dir or os.path.join(report_dir, 'plots'))
    if not os.path.isdir(report_dir):
        os.makedirs(report_dir)
    plots, comparisons = ([], []) if args.no_plots else make_plots(records, plots_dir, report_dir)
    with open(report_path, 'w') as f:
        f.write(report.render(records, meta, plots=plots, comparison_plots=comparisons))
    raw = os.path.splitext(report_path)[0] + '.yaml'
    with open(raw, 'w') as f:
        yaml.safe_dump({'meta': meta, 'records': records}, f, default_flow_style=False, sort_keys=False)
    return report_path


def rerender(args):
    data = read_yaml(args.from_records)
    if not isinstance(data, dict) or not isinstance(data.get('records'), list):
        print('%s: no records' % args.from_records)
        return 1
    records = data['records']
    for r in records:
        r.setdefault('files', {})
    path = write_report(args, records, data.get('meta') or {})
    print('report re-rendered: %s' % path)
    return 0


def main(argv=None):
    args = parse_args(argv)
    if args.from_records:
        return rerender(args)
    stamp = datetime.datetime.now().strftime('%Y%m%d-%H%M%S')
    runs_dir = os.path.abspath(args.runs_dir or os.path.join(os.path.expanduser('~'), '.ros', 'anafi_runs',
                                                              'batch-' + stamp))
    if not os.path.isdir(runs_dir):
        os.makedirs(runs_dir)
    todo = [(s, c, 1, []) for s in args.scenario_list for c in args.controller_list]
    print('%d runs (%s x %s), rtf %g, runs in %s' % (len(todo), len(args.scenario_list),
                                                    ','.join(args.controller_list), args.rtf, runs_dir))
    load = processes.load_average()      # the machine's load before the batch
    t_start = time.monotonic()
    records, active = [], []
    try:
        while todo or active:
            while todo and len(active) < args.jobs:
                scenario, controller, attempt, earlier = todo.pop(0)
                run = Run(scenario, controller, args, runs_dir)
                run.attempt, run.earlier = attempt, earlier
                active.append(run)
                print('[%6.0f s] start %s%s' % (time.monotonic() - t_start, run.name,
                                               ' (attempt %d)' % attempt if attempt > 1 else ''), flush=True)
            for run in list(active):
                if run.poll():
                    active.remove(run)
                    rec = run.record()
                    rec['attempts'] = run.attempt
                    rec['earlier_attempts'] = run.earlier
                    problem = rec['error'] if not rec['ok'] else str((rec.get('info') or {}).get('disturbed') or '')
                    if problem and run.attempt <= args.retries:
                        print('[%6.0f s] %-22s %s: %s -> again' % (time.monotonic() - t_start, run.name,
                                                                  'FAILED' if not rec['ok'] else 'disturbed',
                                                                  problem), flush=True)
                        todo.insert(0, (run.scenario, run.controller, run.attempt + 1,
                                        run.earlier + [problem]))
                        continue
                    records.append(rec)
                    est = (rec.get('summary') or {}).get('estimate') or {}
                    info = rec.get('info') or {}
                    print('[%6.0f s] %-22s %s  e_mu %s e_max %s m  (%.0f s wall, rtf %s)%s' % (
                        time.monotonic() - t_start, run.name, 'ok    ' if rec['ok'] else 'FAILED',
                        fmt(est.get('e_mu')), fmt(est.get('e_max')), run.wall_s,
                        fmt(info.get('achieved_rtf')),
                        '' if rec['ok'] else '  ' + rec['error']), flush=True)
                    if run.leftovers:
                        print('  WARNING: processes %s did not stop' % run.leftovers)
            time.sleep(0.5)
    except KeyboardInterrupt:
        print('interrupted: stopping the active runs')
        for run in active:
            processes.stop(run.proc)
        raise
    wall = time.monotonic() - t_start
    cmd = 'anafi_lab/cli/ros_batch.py' + (' ' + ' '.join(argv if argv is not None else sys.argv[1:])).rstrip()
    meta = {'command': cmd.strip(), 'date': datetime.datetime.now().strftime('%Y-%m-%d %H:%M'),
            'machine': processes.machine(load), 'rtf': '%g' % args.rtf, 'wall_s': round(wall, 1),
            'mirror': args.mirror, 'pid_mode': args.pid_mode, 'sync': bool(args.sync)}
    report_path = write_report(args, records, meta)
    ok = sum(1 for r in records if r['ok'])
    print('batch done: %d of %d runs ok, %.0f s wall (%.1f min); report %s' % (ok, len(records), wall, wall / 60.0,
                                                                            report_path))
    _, wins, compared = report.beats_summary(records)
    print('MPC better than PID (e_mu vs estimate) in %d of %d scenarios' % (wins, compared))
    return 0 if ok == len(records) else 1


if __name__ == '__main__':
    sys.exit(main())
