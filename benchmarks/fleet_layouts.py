#!/usr/bin/env python3
"""Benchmark: a fleet flies the same in both process layouts -- per-drone e_mu, per_drone vs shared.

For each layout of ``--layouts`` (per_drone shared), interleaved run by run (per_drone, shared, per_drone,
shared with ``--repeats 2``) so the layouts see the same machine: a private ROS master of its own per run,
``roslaunch anafi_sim fleet.launch fleet:=FLEET evaluate:=true out_dir:=DIR [layout:=L]`` (wall clock, rtf 1:
every drone flies its scenario with its controller, an evaluator per drone), until every drone's evaluator
summary ``DIR/<drone>.yaml`` has state final; a run in which one does not within ``--timeout`` s (or ends
incomplete, ``<drone>.FAILED.yaml``, or whose launch ends first) is FAILED and recorded as such. Per drone
and run: e_max, e_mu, e_sigma [m] against the estimate and against ground truth (the evaluator's summary).

Per drone and reference (truth, estimate): the e_mu of every run per layout, the run-to-run spread within each
layout (max - min), the difference of the layout means, and the verdict "within spread" when
|mean(shared) - mean(per_drone)| <= the larger of the two layouts' spreads (with 2 runs per layout a coarse test:
the spread of two runs is one difference). Beside them the in-process figure: the lab's engine
(anafi_lab.engine.engine.run) flies each drone's scenario (shifted by its offset, anafi_sim.mission.fleet
.drone_scenario) with its controller on virtual time at the fleet's rtf 1; it has no process layout, so its
figure is the same for both layouts by construction (the reference, not a third layout).

Also the machine's facts: date, Python, cores, load average, and per run the CPU of the fleet (launch tree +
master), the machine's busy share and the CPU of other jobs (busy x cores - fleet - this script).

Writes benchmarks/results/fleet_layouts.json (every run's raw figures) and fleet_layouts.md generated from it;
``--no-write``: print only; ``--from-json``: rewrite the .md from the .json.

Run (inside env.bash, in a network namespace of your own; about 4-5 minutes on 2 cores):
    python benchmarks/fleet_layouts.py [--repeats 2] [--layouts per_drone shared] [--fleet circles]
"""
import argparse
import datetime
import json
import math
import os
import platform
import shutil
import sys
import tempfile
import time

import psutil
import yaml

from anafi_sim import processes, run_files

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'benchmarks', 'results', 'fleet_layouts.md')
RESULTS_JSON = os.path.join(ROOT, 'benchmarks', 'results', 'fleet_layouts.json')
LAYOUTS = ('per_drone', 'shared')
REFERENCES = ('truth', 'estimate')   # the evaluator's summary keys: against ground truth, against the estimate
FIGURES = ('e_max', 'e_mu', 'e_sigma')
MASTER_PORTS = (12600, 13100)
#: the in-process engine's name for a fleet file's controller (the PID framework's single mode is 'pid_single')
ENGINE_CONTROLLER = {'mpc': 'mpc', 'pid_single': 'pid_single', 'pid': 'pid', 'preview_mpc': 'preview_mpc'}


def machine_facts():
    """The machine a run measured: date, Python, cores, CPU model, load average at the start."""
    return {'date': datetime.datetime.now().strftime('%Y-%m-%d %H:%M'), 'python': platform.python_version(),
            'cores': os.cpu_count() or 0, 'cpu_model': processes.cpu_model(), 'load_start': list(os.getloadavg())}


def read_summary(path):
    """An evaluator summary file -> its dict, None while it is missing or unreadable."""
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except (IOError, OSError, yaml.YAMLError):
        return None
    return data if isinstance(data, dict) else None


def figures(summary):
    """{reference: {figure: value [m]}} of a final summary."""
    out = {}
    for ref in REFERENCES:
        r = summary.get(ref) or {}
        out[ref] = dict((k, float(r[k])) for k in FIGURES if isinstance(r.get(k), (int, float)))
    return out


def run_fleet(workdir, name, fleet, drones, layout, timeout):
    """One fleet run in ``layout`` on a master of its own: {'drones': {drone: figures}, ...} or {'error': ...}."""
    out_dir = os.path.join(workdir, name)
    procs = processes.Processes(workdir, grace=30.0)
    run = {'layout': layout, 'name': name}
    try:
        uri, env = processes.private_master(procs, os.path.join(workdir, 'ros_home'), os.path.join(workdir, 'log'),
                                            MASTER_PORTS)
        core = procs.started[0][1]
        command = ['roslaunch', '--port', uri.rsplit(':', 1)[1], 'anafi_sim', 'fleet.launch', 'fleet:=%s' % fleet,
                   'evaluate:=true', 'out_dir:=%s' % out_dir]
        if layout != 'per_drone':
            command.append('layout:=%s' % layout)
        me = psutil.Process()
        cpu0, me0, load0, t0 = psutil.cpu_times(), me.cpu_times(), os.getloadavg(), time.time()
        launch = procs.start(name, command, env)
        trees = {'launch': processes.TreeCpu(launch.pid), 'core': processes.TreeCpu(core.pid)}
        for tree in trees.values():
            tree.start_window()
        summaries, error = {}, None
        while True:
            for tree in trees.values():
                tree.poll()
            for d in drones:
                path = os.path.join(out_dir, '%s.yaml' % d)
                s = read_summary(path)
                if s is not None and s.get('state') == 'final':
                    summaries[d] = s
                elif os.path.exists(run_files.failed_name(path)):
                    error = '%s: evaluation ended incomplete (%s)' % (d, run_files.failed_name(path))
            if error or len(summaries) == len(drones):
                break
            if launch.poll() is not None:
                error = 'the launch ended (exit code %s) before every summary was final' % launch.returncode
                break
            if time.time() - t0 > timeout:
                error = 'time-out: %.0f s without a final summary from %s' % (
                    timeout, ', '.join(d for d in drones if d not in summaries))
                break
            time.sleep(1.0)
        wall = time.time() - t0
        cpu = sum(c for tree in trees.values() for c, _ in tree.end_window().values())
        me1 = me.cpu_times()
        run.update({'wall_s': wall, 'fleet_cpu': 100.0 * cpu / wall,
                    'bench_cpu': 100.0 * ((me1.user + me1.system) - (me0.user + me0.system)) / wall,
                    'busy': processes.machine_busy(cpu0, psutil.cpu_times()), 'load_before': list(load0),
                    'load_after': list(os.getloadavg())})
        run['other_jobs'] = max(0.0, run['busy'] * (os.cpu_count() or 1) - run['fleet_cpu'] - run['bench_cpu'])
        run['drones'] = dict((d, figures(s)) for d, s in summaries.items())
        if error:
            run['error'] = error
            run['log_tail'] = procs.log_tail(name, 15)
            run['logs_kept'] = keep_logs(workdir, name)
    except (RuntimeError, OSError) as e:
        run['error'] = str(e)
    finally:
        procs.stop_all()
    return run


def keep_logs(workdir, name):
    """Copy a failed run's logs (roslaunch's output, the nodes' ROS logs, the evaluators' files) out of the
    temporary directory: the kept directory's path."""
    kept = tempfile.mkdtemp(prefix='fleet_layouts_%s_' % name)
    for src in (os.path.join(workdir, name + '.log'), os.path.join(workdir, 'log'), os.path.join(workdir, name)):
        if os.path.isdir(src):
            shutil.copytree(src, os.path.join(kept, os.path.basename(src)))
        elif os.path.exists(src):
            shutil.copy(src, kept)
    return kept


def in_process(fleet_name):
    """{drone: {'controller', 'scenario', reference: figures}} of the lab's engine for every drone of the fleet
    (its scenario shifted by its offset, its controller; virtual time, the fleet's rtf 1)."""
    from anafi_lab.engine import engine
    from anafi_sim.mission.fleet import drone_scenario, load_fleet
    from anafi_sim.mission.trajectory import scenario_from_dict
    out = {}
    for drone in load_fleet(fleet_name).drones:
        data = drone_scenario(drone)
        if data is None or drone.controller not in ENGINE_CONTROLLER:
            out[drone.name] = {'controller': drone.controller, 'error': 'no in-process counterpart'}
            continue
        result = engine.run(scenario_from_dict(data), ENGINE_CONTROLLER[drone.controller],
                            schedule={'ros_rtf': 1.0}, name=drone.name)
        entry = {'controller': drone.controller, 'engine_controller': ENGINE_CONTROLLER[drone.controller],
                 'scenario': data.get('name'), 'offset': list(drone.offset)}
        if result.ok:
            entry.update(figures(result.summary))
        else:
            entry['error'] = result.error
        out[drone.name] = entry
    return out


# ------------------------------------------------------------------------------------ the comparison
def _finite(x):
    return isinstance(x, (int, float)) and math.isfinite(x)


def comparison(data):
    """Per drone and reference: e_mu per run and layout, spreads, means, difference, verdict."""
    out = {}
    ok_runs = [r for r in data['runs'] if not r.get('error')]
    for d in data['drones']:
        for ref in REFERENCES:
            per = {}
            for layout in data['layouts']:
                values = [r['drones'][d][ref]['e_mu'] for r in ok_runs
                          if r['layout'] == layout and _finite(r['drones'].get(d, {}).get(ref, {}).get('e_mu'))]
                per[layout] = {'e_mu': values, 'mean': sum(values) / len(values) if values else None,
                               'spread': max(values) - min(values) if len(values) >= 2 else None}
            entry = {'layouts': per}
            if all(len(per.get(l, {}).get('e_mu', [])) >= 2 for l in LAYOUTS):
                diff = per['shared']['mean'] - per['per_drone']['mean']
                bound = max(per['shared']['spread'], per['per_drone']['spread'])
                entry.update({'difference': diff, 'bound': bound,
                              'verdict': 'within spread' if abs(diff) <= bound else 'outside spread'})
            else:
                entry['verdict'] = 'not measured (fewer than 2 successful runs in a layout)'
            out['%s/%s' % (d, ref)] = entry
    return out


def fmt(x, digits=3):
    return ('%.*f' % (digits, x)) if _finite(x) else '-'


def markdown(data):
    """fleet_layouts.md from fleet_layouts.json's content."""
    m = data['machine']
    cmp_ = comparison(data)
    lines = ['# Fleet layouts: the same results per drone (per_drone vs shared)', '',
             'Generated by `benchmarks/fleet_layouts.py` from `fleet_layouts.json`; do not edit. Fleet `%s` '
             '(`roslaunch anafi_sim fleet.launch fleet:=%s evaluate:=true`, wall clock, rtf 1), each layout %d '
             'times, interleaved (%s), each run on a private ROS master until every evaluator summary is final '
             '(time-out %.0f s: the run is FAILED).' % (data['fleet'], data['fleet'], data['repeats'],
                                                        ', '.join(r['layout'] for r in data['runs']),
                                                        data['timeout']),
             '',
             'Machine: %s, Python %s, %d cores (%s), load average at the start %s.'
             % (m['date'], m['python'], m['cores'], m['cpu_model'], ' / '.join('%.2f' % x for x in m['load_start'])),
             '', '## Runs', '',
             '| run | layout | result | wall [s] | fleet CPU [% core] | other jobs [% core] '
             '| load 1 min before -> after |',
             '|---|---|---|---|---|---|---|']
    for i, r in enumerate(data['runs']):
        lines.append('| %d | %s | %s | %s | %s | %s | %s |' % (
            i + 1, r['layout'], ('FAILED: %s' % r['error']) if r.get('error') else 'every summary final',
            fmt(r.get('wall_s'), 0), fmt(r.get('fleet_cpu'), 0), fmt(r.get('other_jobs'), 0),
            ('%.2f -> %.2f' % (r['load_before'][0], r['load_after'][0])) if r.get('load_before') else '-'))
    lines += ['', '## e_mu per drone [m]', '',
              'Spread: max - min of a layout\'s runs. Verdict "within spread": |mean(shared) - mean(per_drone)| <= '
              'the larger of the two spreads. With %d run(s) per layout this is a coarse test: the spread of two runs '
              'is a single difference, so a small spread makes the bound tight and a large one loose; it shows a '
              'layout changing the flight by more than the run-to-run noise, not a subtle shift.'
              % data['repeats'], '',
              'In-process: the lab\'s engine (`anafi_lab/engine/engine.py`) flying the drone\'s scenario (shifted by '
              'its offset) with its controller on virtual time (rtf 1). The engine has no process layout: its '
              'figure is the same for both layouts by construction, shown as the reference, not as a measurement '
              'of either layout.', '',
              '| drone | against | controller | per_drone runs | shared runs | spread per_drone | spread shared '
              '| mean shared - mean per_drone | verdict | in-process |',
              '|---|---|---|---|---|---|---|---|---|---|']
    for d in data['drones']:
        ip = data.get('in_process', {}).get(d, {})
        for ref in REFERENCES:
            c = cmp_['%s/%s' % (d, ref)]
            lay = c['layouts']
            lines.append('| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |' % (
                d, 'ground truth' if ref == 'truth' else 'estimate', ip.get('controller', '-'),
                ', '.join(fmt(v, 4) for v in lay.get('per_drone', {}).get('e_mu', [])) or '-',
                ', '.join(fmt(v, 4) for v in lay.get('shared', {}).get('e_mu', [])) or '-',
                fmt(lay.get('per_drone', {}).get('spread'), 4), fmt(lay.get('shared', {}).get('spread'), 4),
                fmt(c.get('difference'), 4), c['verdict'],
                fmt(ip.get(ref, {}).get('e_mu'), 4) if not ip.get('error') else ip['error']))
    lines += ['', '## e_max / e_sigma per run [m] (against ground truth)', '',
              '| run | layout | ' + ' | '.join('%s e_max | %s e_sigma' % (d, d) for d in data['drones']) + ' |',
              '|---|---|' + '---|---|' * len(data['drones'])]
    for i, r in enumerate(data['runs']):
        cells = []
        for d in data['drones']:
            f = r.get('drones', {}).get(d, {}).get('truth', {})
            cells += [fmt(f.get('e_max'), 4), fmt(f.get('e_sigma'), 4)]
        lines.append('| %d | %s | %s |' % (i + 1, r['layout'], ' | '.join(cells)))
    lines += ['', '## Rerun', '',
              'Inside env.bash, in a network namespace of your own (`ip netns exec NAME bash -c ...`), about 4-5 '
              'minutes:', '',
              '    python benchmarks/fleet_layouts.py --repeats %d --layouts %s --fleet %s'
              % (data['repeats'], ' '.join(data['layouts']), data['fleet']), '',
              '`--from-json` rewrites this file from fleet_layouts.json.', '']
    return '\n'.join(lines)


def write(data):
    run_files.atomic_write_text(RESULTS_JSON, json.dumps(data, indent=1, sort_keys=True) + '\n')
    run_files.atomic_write_text(RESULTS, markdown(data))
    print('written %s and %s' % (RESULTS_JSON, RESULTS))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--repeats', type=int, default=2, help='runs per layout (>= 2 for written results)')
    ap.add_argument('--layouts', choices=LAYOUTS, nargs='+', default=list(LAYOUTS))
    ap.add_argument('--fleet', default='circles')
    ap.add_argument('--timeout', type=float, default=100.0, help='s per run until every summary is final (a run takes ~40 s)')
    ap.add_argument('--no-in-process', action='store_true', help='skip the in-process reference')
    ap.add_argument('--no-write', action='store_true')
    ap.add_argument('--from-json', action='store_true', help='only rewrite fleet_layouts.md from the .json')
    args = ap.parse_args(argv)
    if args.from_json:
        with open(RESULTS_JSON) as f:
            data = json.load(f)
        run_files.atomic_write_text(RESULTS, markdown(data))
        print('written %s' % RESULTS)
        return 0
    if len(set(args.layouts)) != len(args.layouts):
        ap.error('--layouts: each layout once')
    if args.repeats < 1 or (args.repeats < 2 and not args.no_write):
        ap.error('--repeats: at least 2 for written results (1 only with --no-write)')
    if not args.no_write and set(args.layouts) != set(LAYOUTS):
        ap.error('written results need both layouts (--no-write to try one)')
    from anafi_sim.mission.fleet import load_fleet
    drones = [d.name for d in load_fleet(args.fleet).drones]
    data = {'format': 1, 'fleet': args.fleet, 'repeats': args.repeats, 'layouts': list(args.layouts),
            'timeout': args.timeout, 'drones': drones, 'machine': machine_facts(), 'runs': []}
    with tempfile.TemporaryDirectory(prefix='fleet_layouts_') as workdir:
        for repeat in range(args.repeats):
            for layout in args.layouts:
                name = '%s_%d' % (layout, repeat + 1)
                print('%s ...' % name, flush=True)
                r = run_fleet(workdir, name, args.fleet, drones, layout, args.timeout)
                r['repeat'] = repeat
                data['runs'].append(r)
                print('%s: %s after %s s; e_mu vs truth %s; other jobs %s %% core' % (
                    name, ('FAILED: ' + r['error']) if r.get('error') else 'ok', fmt(r.get('wall_s'), 0),
                    ', '.join('%s %s' % (d, fmt(f.get('truth', {}).get('e_mu'), 4))
                              for d, f in sorted(r.get('drones', {}).items())),
                    fmt(r.get('other_jobs'), 0)), flush=True)
                if r.get('error'):
                    print('%s\nlogs kept in %s' % (r.get('log_tail', ''), r.get('logs_kept')), flush=True)
    if not args.no_in_process:
        print('in-process reference ...', flush=True)
        data['in_process'] = in_process(args.fleet)
    print(markdown(data))
    failed = [r for r in data['runs'] if r.get('error')]
    if not args.no_write:
        write(data)
    if failed:
        print('FAILED: %d run(s) (see above)' % len(failed), flush=True)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
