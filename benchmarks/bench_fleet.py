#!/usr/bin/env python3
"""Benchmark: a fleet at scale -- CPU per drone, where the time goes, and the largest fleet at real time.

For each N in ``--sizes`` (1 2 4 8 10 12), ``--repeats`` times (at least 2 for written results), and each layout of
``--layouts`` (per_drone: a process per role and drone; shared: ``fleet_host.py`` processes hosting one role of
every drone), interleaved run by run so the layouts see the same machine: a private ROS master,
``roslaunch anafi_sim fleet.launch drones:=N`` (``layout:=L`` for a layout other than per_drone; fleet
``--fleet``, default circles: every drone with the MPC flying the circle r = 2 m, v = 1 m/s, 6 m apart;
kinematic world, one mirror per drone at 100 Hz, no evaluators), wait until every drone flies its scenario,
``--settle`` s, then a measurement window of ``--duration`` s of wall time:

- CPU (user + sys, psutil; anafi_sim.processes.TreeCpu / CpuWindow) of every process of the launch tree
  (and of roscore: master + rosout) by role: simulator, telemetry CLI (tlm_data_logger.py), interface,
  mirror, controller, trajectory generator, world, roslaunch, and ``host NAME`` for a shared layout's
  ``fleet_host.py __name:=NAME``; in % of one core, and per drone;
- per drone, from the nodes' own /diagnostics at the window's ends (the same status names in both layouts):
  the simulator's real-time factor (sim time advanced / wall time) and overruns, the interface's ground-truth
  rate (samples published / wall time), the mirror's rates (samples received, sent, decimated / wall time)
  and lag p99;
- the machine's load average and busy share over the window, and the CPU of other jobs.

A fleet *holds real time* when every run of it does: fleet_report.HOLD (every drone's RTF >= 0.98, ground truth
>= 97 Hz and mirror sent >= 97 Hz), the one definition the docs quote. Writes benchmarks/results/fleet.json
(every run's raw figures and the machine's facts) and fleet.md and the generated block of docs/fleet.md from it
(benchmarks/fleet_report.py, templates fleet.md.j2 and fleet_docs.md.j2); ``--no-write``: print only;
``--from-json``: rewrite fleet.md and the docs block from fleet.json.

Run (inside env.bash): python benchmarks/bench_fleet.py [--sizes 1 2 4 8 10 12] [--repeats 2]
[--layouts per_drone shared] [--duration 30] [--settle 10] (about 12 minutes per layout with the defaults).
"""
import argparse
import datetime
import json
import os
import platform
import sys
import tempfile
import threading
import time

import psutil

from anafi_sim import processes, run_files

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fleet_report  # noqa: E402  (beside this script)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'benchmarks', 'results', 'fleet.md')
RESULTS_JSON = os.path.join(ROOT, 'benchmarks', 'results', 'fleet.json')
DOCS = os.path.join(ROOT, 'docs', 'fleet.md')
MASTER_PORTS = (12000, 12500)
#: the processes with the most CPU a run records ([role, % of one core], largest first)
LARGEST_PROCESSES = 5
#: --calibrate-cap: the sizes tried per layout, in order until one does not hold real time
CALIBRATION_SIZES = {'per_drone': [2, 4, 6, 8, 10, 12], 'shared': [4, 8, 12, 16, 20, 24, 28, 32, 40]}


def role_of(proc, is_root):
    try:
        return fleet_report.role_of_cmdline(proc.cmdline())
    except psutil.Error:
        return 'other'


class Diagnostics(object):
    """Latest /diagnostics values per status name, with their receipt wall time."""

    def __init__(self):
        import rospy
        from diagnostic_msgs.msg import DiagnosticArray
        self.lock = threading.Lock()
        self.latest = {}
        rospy.Subscriber('/diagnostics', DiagnosticArray, self.on_array, queue_size=50)

    def on_array(self, msg):
        now = time.time()
        with self.lock:
            for s in msg.status:
                self.latest[s.name] = (now, dict((kv.key, kv.value) for kv in s.values), s.message)

    def snapshot(self):
        with self.lock:
            return dict(self.latest)


def _num(values, key):
    try:
        return float(values[key])
    except (KeyError, ValueError):
        return float('nan')


def drone_figures(names, before, after):
    """Per drone: RTF, overruns, ground-truth Hz, mirror Hz, mirror lag p99 [ms] between two snapshots."""
    out = {}
    for n in names:
        keys = {'sim': 'anafi_sim: simulated Anafi (%s)' % n, 'gt': '/%s/interface: ground truth interface' % n,
                'mirror': '/%s/gazebo_mirror: gazebo mirror' % n}
        fig = {}
        if all(keys[k] in before and keys[k] in after for k in keys):
            (t0, s0, _), (t1, s1, _) = before[keys['sim']], after[keys['sim']]
            fig['rtf'] = (_num(s1, 'sim time [s]') - _num(s0, 'sim time [s]')) / (t1 - t0)
            fig['overruns'] = _num(s1, 'overruns (steps late by > 1 period)') - \
                _num(s0, 'overruns (steps late by > 1 period)')
            (t0, g0, _), (t1, g1, _) = before[keys['gt']], after[keys['gt']]
            fig['truth_hz'] = (_num(g1, 'samples published') - _num(g0, 'samples published')) / (t1 - t0)
            (t0, m0, _), (t1, m1, _) = before[keys['mirror']], after[keys['mirror']]
            fig['mirror_hz'] = (_num(m1, 'samples sent') - _num(m0, 'samples sent')) / (t1 - t0)
            fig['mirror_in_hz'] = (_num(m1, 'samples received') - _num(m0, 'samples received')) / (t1 - t0)
            fig['mirror_decimated_hz'] = (_num(m1, 'samples decimated') - _num(m0, 'samples decimated')) / (t1 - t0)
            fig['lag_p99_ms'] = _num(m1, 'lag p99 [ms]')
        out[n] = fig
    return out


class Bench(object):
    """One private master for every size (rospy joins it once); one fleet.launch per size."""

    def __init__(self, workdir):
        import rospy
        import shutil
        from anafi_sim import launch_check
        self.workdir = workdir
        user_cache = launch_check.cap_cache_path()     # this machine's figures: the fleets split their hosts by them
        if os.path.isfile(user_cache):
            target = os.path.join(workdir, 'ros_home', *launch_check.CAP_CACHE)
            os.makedirs(os.path.dirname(target), exist_ok=True)
            shutil.copyfile(user_cache, target)
        self.split = launch_check.machine_drones_per_host()
        self.procs = processes.Processes(workdir, grace=30.0)
        uri, self.env = processes.private_master(self.procs, os.path.join(workdir, 'ros_home'),
                                               os.path.join(workdir, 'log'), MASTER_PORTS, join=True)
        self.port = int(uri.rsplit(':', 1)[1])
        self.core = self.procs.started[0][1]
        rospy.init_node('bench_fleet', anonymous=True, disable_signals=True)
        self.diag = Diagnostics()

    def run_size(self, n, args, layout='per_drone', repeat=0):
        """One fleet of ``n`` drones in ``layout``: the figures of its measurement window."""
        diag = self.diag
        with diag.lock:
            diag.latest.clear()
        name = 'fleet%d_%s_%d' % (n, layout, repeat)
        command = ['roslaunch', '--port', str(self.port), 'anafi_sim', 'fleet.launch', 'fleet:=%s' % args.fleet,
                   'drones:=%d' % n, 'evaluate:=false', 'out_dir:=%s' % os.path.join(self.workdir, name),
                   'max_drones:=%d' % n]     # measured beyond the fleet cap too: the cap comes from these runs
        if layout != 'per_drone':
            command.append('layout:=%s' % layout)
        launch = self.procs.start(name, command, self.env)
        try:
            names = ['anafi%d' % (i + 1) for i in range(n)]
            t_start = time.time()

            def flying():
                snap = diag.snapshot()
                gens = [snap.get('trajectory_generator: /%s/trajectory_generator' % d) for d in names]
                return all(g is not None and g[2] == 'running' for g in gens)
            processes.require(lambda: launch.poll() is None and flying(), args.start_timeout,
                            'all %d drones flying their scenario' % n, lambda: self.procs.log_tail(name, 30))
            startup = time.time() - t_start
            time.sleep(args.settle)
            before = diag.snapshot()
            window = processes.CpuWindow({'launch': processes.TreeCpu(launch.pid, role_of),
                                        'core': processes.TreeCpu(self.core.pid, role_of)}, args.duration).run()
            time.sleep(1.5)   # the diagnostics after the window
            after = diag.snapshot()
        finally:
            self.procs.stop(name)
        procs = sorted(((role, 100.0 * cpu / window.wall) for tree in ('launch', 'core')
                        for role, cpu in window.trees[tree].processes()), key=lambda item: -item[1])
        per_role = {}
        for tree in ('launch', 'core'):
            for role, (cpu, count) in window.cpu[tree].items():
                entry = per_role.setdefault(role, [0.0, 0])
                entry[0] += 100.0 * cpu / window.wall
                entry[1] += count
        run = {'layout': layout, 'n': n, 'repeat': repeat, 'startup_s': startup, 'wall': window.wall,
               'roles': per_role, 'drones': drone_figures(names, before, after), 'load_before': window.load_before,
               'load_after': window.load_after, 'busy': window.busy,
               'bench_cpu': 100.0 * window.bench_cpu / window.wall,
               'largest_processes': [[role, cpu] for role, cpu in procs[:LARGEST_PROCESSES]]}
        if layout == 'shared':
            run['drones_per_host'] = self.split[0]
            run['processes'] = [[role, cpu] for role, cpu in procs]
        run['other_jobs'] = fleet_report.other_jobs(dict(run), os.cpu_count() or 1)
        return run

    def close(self):
        self.procs.stop_all()


def _numpy_twist_states(mirror_module, frames, np, position, q, lin_b, ang_b, offset):
    """The mirror's two model states computed as before the cut (numpy per 3-vector, np.cross): the reference."""
    q = frames.normalize_quaternion(q)
    rot = frames.quaternion_matrix(q)
    lin = tuple(float(v) for v in rot.dot(np.asarray(lin_b, dtype=float)))
    ang = tuple(float(v) for v in rot.dot(np.asarray(ang_b, dtype=float)))
    roll, pitch, yaw = frames.quaternion_to_euler(*q)
    cam_p, cam_q = mirror_module.camera_pose(position, roll, pitch, yaw, 0.0, 0.0, offset)
    rot = frames.quaternion_matrix(q)
    lin_b2 = tuple(float(v) for v in rot.dot(np.asarray(lin_b, dtype=float)))
    ang_w = rot.dot(np.asarray(ang_b, dtype=float))
    lever = frames.quaternion_matrix(q).dot(np.asarray(offset, dtype=float))
    cam_lin = np.asarray(lin_b2) + np.cross(ang_w, lever)
    return (lin, ang), (cam_p, cam_q, tuple(float(v) for v in cam_lin))


def mirror_core_cost(samples=3000, rounds=5):
    """CPU [us] per ground-truth sample of the mirror core's model-state maths: the numpy reference (before the
    cut) and the shipped plain-Python one (anafi_sim.gazebo.mirror), interleaved; and their largest difference."""
    import numpy as np
    from anafi_control import frames
    from anafi_sim.gazebo import mirror
    args = ((1.0, 2.0, 3.0), (0.0, 0.05, 0.1, 0.99), (0.4, -0.2, 0.3), (0.05, -0.02, 0.3))
    offset = (0.1, 0.0, 0.0)

    def shipped():
        q = frames.normalize_quaternion(args[1])
        d = mirror.drone_model_state('a', args[0], q, args[2], args[3])
        c = mirror.camera_model_state('a_camera', args[0], q, args[2], args[3], 0.0, 0.0, offset)
        return d, c

    def reference():
        return _numpy_twist_states(mirror, frames, np, args[0], args[1], args[2], args[3], offset)
    times = {'numpy (before)': [], 'plain Python (shipped)': []}
    for _ in range(rounds):
        for name, fn in (('numpy (before)', reference), ('plain Python (shipped)', shipped)):
            t0 = time.process_time()
            for _ in range(samples):
                fn()
            times[name].append(1e6 * (time.process_time() - t0) / samples)
    (d, c), ((lin, ang), (cp, cq, clin)) = shipped(), reference()
    diff = max(abs(a - b) for a, b in zip(d.linear + d.angular + c.position + c.linear, lin + ang + cp + clin))
    return dict((k, min(v)) for k, v in times.items()), diff


def machine_facts():
    """The machine a run measured: date, Python, cores, CPU model, load average at the start."""
    return {'date': datetime.datetime.now().strftime('%Y-%m-%d %H:%M'), 'python': platform.python_version(),
            'cores': os.cpu_count() or 0, 'cpu_model': processes.cpu_model(), 'load_start': os.getloadavg()}


def write(data):
    """fleet.json, fleet.md and the generated block of docs/fleet.md (each atomically) from ``data``."""
    run_files.atomic_write_text(RESULTS_JSON, json.dumps(data, indent=1, sort_keys=True) + '\n')
    print('written %s' % RESULTS_JSON)
    rewrite(data)


def rewrite(data):
    """fleet.md and the generated block of docs/fleet.md from ``data`` (fleet.json's content)."""
    run_files.atomic_write_text(RESULTS, fleet_report.markdown(data))
    with open(DOCS) as f:
        text = f.read()
    run_files.atomic_write_text(DOCS, fleet_report.replace_docs_block(text, data))
    print('written %s and the generated block of %s' % (RESULTS, DOCS))


def report_run(r):
    f = fleet_report.run_figures(r)
    print('%s N = %d run %d: holds real time: %s; RTF min %s, ground truth min %s Hz, mirror sent min %s Hz; '
          'CPU %s %% (%s %% per drone); load %.1f -> %.1f; other jobs %s %% core'
          % (r['layout'], r['n'], r['repeat'] + 1, f['holds'], fleet_report.fmt(f['rtf_min'], 3),
             fleet_report.fmt(f['truth_min']), fleet_report.fmt(f['mirror_min']), fleet_report.fmt(f['cpu_total'], 0),
             fleet_report.fmt(f['cpu_per_drone']), r['load_before'][0], r['load_after'][0],
             fleet_report.fmt(r['other_jobs'], 0)), flush=True)
    for role, (cpu, count) in sorted(r['roles'].items(), key=lambda kv: -kv[1][0]):
        print('    %-24s %5.1f %% (%d processes)' % (role, cpu, count), flush=True)
    print('    largest processes: %s' % ', '.join('%s %.1f %%' % (role, cpu) for role, cpu in
                                                   r.get('largest_processes', [])), flush=True)
    if r.get('drones_per_host'):
        print('    hosts split by: %s' % ', '.join('%s %d drones' % kv for kv in sorted(r['drones_per_host'].items())),
              flush=True)


def calibrate(args, layouts, bench_runs):
    """The fleet cap of this machine: per layout, the sizes of ``args.sizes`` (default CALIBRATION_SIZES) one run
    each, in order until one does not hold real time; the cap's figures (fleet_report.cap_cpu_per_drone,
    cap_failing_per_core) written into the cap cache (launch_check.cap_cache_path(), or --cap-cache) under this
    machine's CPU model and cores, unless --no-write. ``bench_runs(n, layout)``: one run's figures."""
    from anafi_sim import launch_check
    cores = launch_check.available_cores()
    model = launch_check.cpu_model()
    data = {'format': 2, 'fleet': args.fleet, 'settle': args.settle, 'duration': args.duration, 'repeats': 1,
            'sizes': [], 'layouts': layouts, 'machine': dict(machine_facts(), cores=cores, cpu_model=model),
            'hold': dict(fleet_report.HOLD), 'runs': []}
    figures = {}
    for layout in layouts:
        sizes = args.sizes or CALIBRATION_SIZES[layout]
        for n in sizes:
            print('calibrating the %s layout: N = %d ...' % (layout, n), flush=True)
            try:
                r = bench_runs(n, layout)
            except TimeoutError as error:
                r = {'layout': layout, 'n': n, 'repeat': 0, 'error': str(error)}
                print('%s N = %d: %s' % (layout, n, error), flush=True)
            else:
                report_run(r)
            data['runs'].append(r)
            data['sizes'] = sorted(set(data['sizes'] + [n]))
            if not fleet_report.run_holds(r):
                break
        cpu = fleet_report.cap_cpu_per_drone(data, layout)
        if cpu is None:
            print('%s: no size held real time here (smallest tried %d): no cap written for it (the conservative '
                  'default stays; try smaller --sizes)' % (layout, sizes[0]), flush=True)
            continue
        mine = [r for r in data['runs'] if r['layout'] == layout]
        others = [fleet_report.other_jobs(r, cores) for r in mine]
        figures[layout] = {
            'cpu_per_drone': cpu, 'failing_per_core': fleet_report.cap_failing_per_core(data, layout),
            'largest_holding': [h for h in fleet_report.headline(data) if h['layout'] == layout][0]['n'],
            'sizes': [r['n'] for r in mine], 'duration_s': args.duration,
            'other_jobs_max_pct_core': round(max([o for o in others if o is not None] or [0.0]), 1),
            'load_1min_max': round(max(max(r.get('load_before', [0])[0], r.get('load_after', [0])[0])
                                       for r in mine), 2)}
        hosts = fleet_report.host_cpu_per_drone(data) if layout == 'shared' else None
        if hosts and all(k in hosts for k in launch_check.REFERENCE_HOST_CPU_PER_DRONE):
            figures[layout]['host_cpu_per_drone'] = dict((k, hosts[k])
                                                         for k in launch_check.REFERENCE_HOST_CPU_PER_DRONE)
            print('shared layout: the hosts\' CPU per drone %s: split by %s drones (%g core per host at most)' % (
                figures[layout]['host_cpu_per_drone'],
                launch_check.drones_per_host(figures[layout]['host_cpu_per_drone']), launch_check.HOST_CORE_BUDGET),
                flush=True)
    caps = dict((layout, launch_check.fleet_cap(cores, layout, launch_check.CapFigures(
        dict((k, v['cpu_per_drone']) for k, v in figures.items()),
        dict((k, v['failing_per_core']) for k, v in figures.items()), model, cores, '', ''))) for layout in figures)
    for layout, figs in figures.items():
        print('%s layout on %s, %d cores: %.3f core per drone, %s drones per core failing: fleet cap %d'
              % (layout, model, cores, figs['cpu_per_drone'], figs['failing_per_core'], caps[layout]), flush=True)
        if figs['other_jobs_max_pct_core'] > fleet_report.OTHER_JOBS_LIMIT:
            print('  (other jobs used up to %.0f %% of a core meanwhile: the machine was busy, the cap is what the '
                  'fleet got then; rerun on a quiet machine)' % figs['other_jobs_max_pct_core'], flush=True)
    if figures and not args.no_write:
        from anafi_sim import run_files
        path = args.cap_cache or launch_check.cap_cache_path()
        document = launch_check.cap_cache_with(run_files.read_yaml(path, default=None, tolerant=True), model, cores,
                                               data['machine']['date'], figures,
                                               python=data['machine']['python'], command=' '.join(sys.argv))
        run_files.write_yaml(path, document)
        print('written %s (%s): fleet.launch refuses above these caps now' % (
            path, launch_check.machine_key(model, cores)), flush=True)
    return data


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--sizes', type=int, nargs='+', default=None, help='default 1 2 4 8 10 12')
    ap.add_argument('--repeats', type=int, default=2, help='runs per size and layout (>= 2 for written results)')
    which = ap.add_mutually_exclusive_group()
    which.add_argument('--layout', choices=fleet_report.LAYOUTS, help='one layout (default per_drone)')
    which.add_argument('--layouts', choices=fleet_report.LAYOUTS, nargs='+',
                       help='several layouts side by side, interleaved run by run')
    ap.add_argument('--fleet', default='circles')
    ap.add_argument('--duration', type=float, default=None, help='s of wall time measured (30; --calibrate-cap 20)')
    ap.add_argument('--settle', type=float, default=None, help='s (10; --calibrate-cap 5)')
    ap.add_argument('--start-timeout', type=float, default=240.0)
    ap.add_argument('--max-size', action='append', default=[], metavar='LAYOUT=N',
                    help='run that layout only up to N drones (e.g. per_drone=10: larger ones never start in time)')
    ap.add_argument('--no-write', action='store_true')
    ap.add_argument('--processes-page', default='', metavar='PATH',
                    help='also write the per-process CPU of the shared layout\'s runs (every host process, the '
                         'split, the machine and its load) to PATH (e.g. benchmarks/results/fleet_processes.md), '
                         'with --no-write too')
    ap.add_argument('--calibrate-cap', action='store_true',
                    help='measure this machine\'s fleet cap (one run per size, sizes in order until one does not '
                         'hold; default sizes per layout %s, default layouts both) and write it into the cap cache '
                         '(~/.ros/anafi_sim/fleet_cap.yaml) instead of the results page' % CALIBRATION_SIZES)
    ap.add_argument('--cap-cache', default='', metavar='PATH', help='--calibrate-cap: the cache file to write')
    ap.add_argument('--from-json', action='store_true',
                    help='only rewrite fleet.md and the block of docs/fleet.md from fleet.json')
    args = ap.parse_args(argv)
    if args.from_json:
        rewrite(fleet_report.load(RESULTS_JSON))
        return 0
    if args.duration is None:
        args.duration = 20.0 if args.calibrate_cap else 30.0
    if args.settle is None:
        args.settle = 5.0 if args.calibrate_cap else 10.0
    if args.calibrate_cap:
        from anafi_sim import launch_check
        # the user's cache, taken before the private master points this process's ROS_HOME at the bench's folder
        args.cap_cache = args.cap_cache or launch_check.cap_cache_path()
        layouts = args.layouts or ([args.layout] if args.layout else list(fleet_report.LAYOUTS))
        with tempfile.TemporaryDirectory(prefix='bench_fleet_') as workdir:
            bench = Bench(workdir)
            try:
                calibrate(args, layouts, lambda n, layout: bench.run_size(n, args, layout, 0))
            finally:
                bench.close()
        return 0
    if args.sizes is None:
        args.sizes = [1, 2, 4, 8, 10, 12]
    layouts = args.layouts or [args.layout or 'per_drone']
    max_size = {}
    for item in args.max_size:
        layout, _, n = item.partition('=')
        if layout not in fleet_report.LAYOUTS or not n.isdigit():
            ap.error('--max-size: LAYOUT=N, got %r' % item)
        max_size[layout] = int(n)
    if len(set(layouts)) != len(layouts):
        ap.error('--layouts: each layout once')
    if args.repeats < 1 or (args.repeats < 2 and not args.no_write):
        ap.error('--repeats: at least 2 for written results (1 only with --no-write)')
    data = {'format': 2, 'fleet': args.fleet, 'settle': args.settle, 'duration': args.duration,
            'repeats': args.repeats, 'sizes': list(args.sizes), 'layouts': layouts, 'machine': machine_facts(),
            'hold': dict(fleet_report.HOLD), 'runs': []}
    failed = 0
    with tempfile.TemporaryDirectory(prefix='bench_fleet_') as workdir:
        bench = Bench(workdir)
        try:
            for n in args.sizes:
                for repeat in range(args.repeats):
                    for layout in layouts:
                        if n > max_size.get(layout, n):
                            continue
                        print('%s N = %d run %d ...' % (layout, n, repeat + 1), flush=True)
                        try:
                            r = bench.run_size(n, args, layout, repeat)
                        except TimeoutError as error:
                            print('%s N = %d run %d: %s' % (layout, n, repeat + 1, error), flush=True)
                            data['runs'].append({'layout': layout, 'n': n, 'repeat': repeat, 'error': str(error)})
                            failed += 1
                            continue
                        data['runs'].append(r)
                        report_run(r)
        finally:
            bench.close()
    data['core_cost'] = mirror_core_cost()
    print(fleet_report.markdown(data))
    if not args.no_write and data['runs']:
        write(data)
    if args.processes_page and data['runs']:
        data['command'] = 'python benchmarks/bench_fleet.py ' + ' '.join(argv if argv is not None else sys.argv[1:])
        run_files.atomic_write_text(args.processes_page, fleet_report.processes_markdown(data))
        print('written %s' % args.processes_page)
    if failed:
        print('FAILED: %d run(s) never had every drone flying (see above)' % failed, flush=True)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
