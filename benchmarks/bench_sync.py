#!/usr/bin/env python3
"""Lockstep ROS runs (experiment.launch sync:=true): load independence and agreement with the in-process engine
-> benchmarks/results/sync.yaml and the "Lockstep" section of benchmarks/results/engine.md.

Stage: benchmark (not a timed test). For each controller, the same scenario (default the rostest's 10 s circle,
test/ros/experiment_short.yaml) runs through ROS in lockstep once on the machine as it is ("idle": no load
added by this script) and once with ``--hogs`` busy-loop processes (one per core by default) started here and
stopped by id afterwards ("busy"); then once in-process with the lockstep's schedule
(``experiment.py run --sync-schedule``, ``anafi_lab.engine.runs.SYNC_SCHEDULE``). Reported: e_mu vs
estimate and vs truth, busy / idle and ROS / in-process ratios, wall time, the simulator's lockstep figures
(periods waited, timeouts; read from the run's /diagnostics in its bag) and the load average.

    python benchmarks/bench_sync.py [--controllers mpc,pid] [--scenario-file PATH] [--rtf 0.5] [--hogs 2]
                                    [--repeat 1] [--render-only]

The runs themselves are ``anafi_lab.engine.lockstep`` (also used by test/ros/test_sync.py).
"""
import argparse
import datetime
import os
import platform
import re
import sys
import tempfile
import time

import yaml

from anafi_lab.engine.lockstep import e_mu, lockstep_figures, run_inprocess, run_sync  # noqa: F401
from anafi_sim.run_files import read_yaml
from anafi_sim.numeric import fmt

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'benchmarks', 'results')
FIGURES = os.path.join(RESULTS, 'sync.yaml')
ENGINE_MD = os.path.join(RESULTS, 'engine.md')
SHORT_SCENARIO = os.path.join(ROOT, 'test', 'ros', 'experiment_short.yaml')
SECTION_BEGIN = '<!-- bench_sync: begin -->'
SECTION_END = '<!-- bench_sync: end -->'
HOG = 'while True:\n    pass\n'


def start_hogs(n):
    from anafi_sim import processes
    return [processes.start([sys.executable, '-c', HOG]) for _ in range(n)]


def stop_hogs(hogs):
    """Stop the busy loops; the CPU seconds they got [s] (None without psutil)."""
    from anafi_sim import processes
    cpu = 0.0
    for proc in hogs:
        try:
            times = processes.psutil.Process(proc.pid).cpu_times()
            cpu += times.user + times.system
        except (AttributeError, processes.psutil.Error if processes.psutil else OSError):
            cpu = None
        processes.stop(proc, grace=1.0)
    return round(cpu, 1) if cpu is not None and hogs else None


def measure(args):
    out = tempfile.mkdtemp(prefix='bench_sync_')
    rows = []
    for controller in args.controllers:
        ref = run_inprocess(controller, os.path.join(out, 'inprocess'), args.scenario_file)
        plan = [(m, k, load) for m in args.modes for k in range(args.repeat) for load in ('idle', 'busy')]
        for mode, k, load in plan:
            hogs = start_hogs(args.hogs) if load == 'busy' else []
            hog_cpu = None
            try:
                time.sleep(1.0 if hogs else 0.0)
                load_avg = os.getloadavg()[0]
                run = run_sync(controller, os.path.join(out, '%s_%s_%s_%d' % (controller, mode, load, k)),
                               args.scenario_file, args.rtf, sync=mode == 'lockstep')
            finally:
                hog_cpu = stop_hogs(hogs)
            info = run['info'] or {}
            ls = run['lockstep']
            row = {'controller': controller, 'mode': mode, 'load': load, 'repeat': k, 'hogs': len(hogs),
                   'hogs_cpu_s': hog_cpu,
                   'load_average_1min': round(load_avg, 1),
                   'state': (run['summary'] or {}).get('state'),
                   'e_mu_estimate': e_mu(run['summary']), 'e_mu_truth': e_mu(run['summary'], 'truth'),
                   'inprocess_e_mu_estimate': e_mu(ref), 'inprocess_e_mu_truth': e_mu(ref, 'truth'),
                   'scenario_wall_s': info.get('scenario_wall_s'), 'achieved_rtf': info.get('achieved_rtf'),
                   'hover_commands': info.get('hover_commands'),
                   'periods_waited': _int(ls.get('lockstep periods waited')),
                   'timeouts': _int(ls.get('lockstep timeouts (period went on without a command)')),
                   'wait_max_s': _float(ls.get('lockstep wait max [s wall]'))}
            rows.append(row)
            print('%-4s %-8s %-4s e_mu %s (truth %s), in-process %s; %s s wall, lockstep %s periods, %s timeouts, '
                  'load %.1f' % (controller, mode, load, row['e_mu_estimate'], row['e_mu_truth'],
                                 row['inprocess_e_mu_estimate'], row['scenario_wall_s'], row['periods_waited'],
                                 row['timeouts'], load_avg))
    return {'meta': {'date': datetime.datetime.now().strftime('%Y-%m-%d %H:%M'), 'machine': '%s, %d CPUs, Python %s'
                     % (platform.machine(), os.cpu_count() or 0, platform.python_version()),
                     'scenario_file': os.path.relpath(args.scenario_file, ROOT), 'rtf': args.rtf,
                     'hogs': args.hogs, 'command': 'python benchmarks/bench_sync.py ' + ' '.join(args.argv)},
            'rows': rows}


def _int(text):
    return int(text) if text is not None and re.match(r'^\d+$', str(text)) else None


def _float(text):
    try:
        return float(text)
    except (TypeError, ValueError):
        return None


def _fmt(v, n=3):
    """A float with ``n`` decimals, anything else (counts, labels) as it is; '-' when missing."""
    return fmt(v, n) if v is None or isinstance(v, float) else str(v)


def _ratio(a, b):
    return a / b if a is not None and b else None


def section(figures):
    """The Markdown section of engine.md (between the bench_sync markers)."""
    meta, rows = figures['meta'], figures['rows']
    lines = [SECTION_BEGIN, '## Lockstep ROS runs (`experiment.launch sync:=true`): load independence', '',
             'Generated by `benchmarks/bench_sync.py` (%s, %s): `%s`. Scenario `%s`, rtf %g (a ceiling: the simulator '
             'also waits for every 10 Hz command), no mirror, bag recorded. "busy" = %d busy-loop processes started by '
             'the benchmark for the run (one per core); "idle" = the machine as it was (other work on it: see the '
             'load average). In-process = `experiment.py run --engine inprocess --sync-schedule` (same scenario, '
             'seed 0). Lockstep figures: the simulator\'s /diagnostics in the run\'s bag.'
             % (meta['date'], meta['machine'], meta['command'], meta['scenario_file'], meta['rtf'], meta['hogs']), '',
             '| controller | mode | load | load avg | busy loops\' CPU [s] | e_mu vs estimate [m] | vs truth [m] '
             '| in-process [m] '
             '| ROS / in-process | scenario wall [s] | periods waited | timeouts | longest wait [s] |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        lines.append('| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |' % (
            r['controller'], r.get('mode', 'lockstep'), r['load'], _fmt(r['load_average_1min'], 1),
            _fmt(r.get('hogs_cpu_s'), 1),
            _fmt(r['e_mu_estimate'], 4),
            _fmt(r['e_mu_truth'], 4), _fmt(r['inprocess_e_mu_estimate'], 4),
            _fmt(_ratio(r['e_mu_estimate'], r['inprocess_e_mu_estimate'])), _fmt(r['scenario_wall_s'], 1),
            _fmt(r['periods_waited']), _fmt(r['timeouts']), _fmt(r['wait_max_s'])))
    lines.append('')
    failed = [r for r in rows if r['e_mu_estimate'] is None]
    if failed:
        lines += ['Rows without e_mu: the run did not finish (%s; its launch log tells why, e.g. roslaunch could not '
                  'reach its own new master on an overloaded machine).'
                  % ', '.join('%s %s %s' % (r['controller'], r.get('mode', 'lockstep'), r['load']) for r in failed), '']
    groups = []
    for r in rows:
        key = (r['controller'], r.get('mode', 'lockstep'))
        if key not in groups:
            groups.append(key)
    for controller, mode in groups:
        mine = [r for r in rows if (r['controller'], r.get('mode', 'lockstep')) == (controller, mode)]
        idle = [r['e_mu_estimate'] for r in mine if r['load'] == 'idle' and r['e_mu_estimate'] is not None]
        busy = [r['e_mu_estimate'] for r in mine if r['load'] == 'busy' and r['e_mu_estimate'] is not None]
        walls = dict((load, [r['scenario_wall_s'] for r in mine if r['load'] == load and r['scenario_wall_s']])
                     for load in ('idle', 'busy'))
        if idle and busy:
            spread = (max(idle + busy) - min(idle + busy)) / min(idle + busy)
            lines.append('- **%s, %s**: busy / idle e_mu %.4f (largest spread over the %d runs: %.2f %%%s); '
                         'wall time of the scenario idle %s s, busy %s s.' % (
                             controller, 'sync:=true' if mode == 'lockstep' else 'sync:=false (for comparison)',
                             (sum(busy) / len(busy)) / (sum(idle) / len(idle)), len(idle + busy), 100.0 * spread,
                             ', target < 2 %' if mode == 'lockstep' else '',
                             ', '.join('%.1f' % w for w in walls['idle']),
                             ', '.join('%.1f' % w for w in walls['busy'])))
    lines += ['', 'How the lockstep works and what it does not hold: docs/experiments.md (Lockstep ROS runs) and '
              '`anafi_sim/sim/clock.py` (`Lockstep`, `StartHold`).', SECTION_END, '']
    return '\n'.join(lines)


def splice(text, figures):
    """``text`` (engine.md) with the bench_sync section replaced, or appended when missing."""
    new = section(figures)
    if SECTION_BEGIN in text and SECTION_END in text:
        head, rest = text.split(SECTION_BEGIN, 1)
        tail = rest.split(SECTION_END, 1)[1].lstrip('\n')
        return head + new + tail
    return text.rstrip('\n') + '\n\n' + new


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--controllers', default='mpc,pid')
    ap.add_argument('--scenario-file', default=SHORT_SCENARIO)
    ap.add_argument('--rtf', type=float, default=0.5, help='requested real-time factor (default 0.5)')
    ap.add_argument('--hogs', type=int, default=os.cpu_count() or 2, help='busy-loop processes (default: CPUs)')
    ap.add_argument('--repeat', type=int, default=1, help='idle + busy pairs per controller and mode')
    ap.add_argument('--modes', default='lockstep', help='lockstep (sync:=true) and / or free (sync:=false)')
    ap.add_argument('--render-only', action='store_true', help='no runs: re-render the section from sync.yaml')
    args = ap.parse_args(argv)
    args.argv = argv
    args.controllers = [c.strip() for c in args.controllers.split(',') if c.strip()]
    args.modes = [m.strip() for m in args.modes.split(',') if m.strip()]
    if not args.modes or set(args.modes) - {'lockstep', 'free'}:
        ap.error('--modes: lockstep and / or free')
    args.scenario_file = os.path.abspath(args.scenario_file)
    if args.render_only:
        figures = read_yaml(FIGURES)
    else:
        figures = measure(args)
        with open(FIGURES, 'w') as f:
            yaml.safe_dump(figures, f, default_flow_style=False, sort_keys=False)
    with open(ENGINE_MD) as f:
        text = f.read()
    with open(ENGINE_MD, 'w') as f:
        f.write(splice(text, figures))
    print('written: %s, %s' % (FIGURES, ENGINE_MD))
    return 0


if __name__ == '__main__':
    sys.exit(main())
