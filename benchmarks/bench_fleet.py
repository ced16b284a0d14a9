#!/usr/bin/env python3
"""Benchmark: a fleet at scale -- CPU per drone, where the time goes, and the largest fleet at RTF 1.

For each N in ``--sizes`` (1 2 4 8): a private ROS master, ``roslaunch anafi_sim fleet.launch drones:=N``
(fleet ``--fleet``, default three_circles: every drone with the MPC flying the circle r = 2 m, v = 1 m/s,
6 m apart; kinematic world, one mirror per drone at 100 Hz, no evaluators), wait until every drone flies its
scenario, ``--settle`` s, then a measurement window of ``--duration`` s of wall time:

- CPU (user + sys, psutil; anafi_sim.processes.TreeCpu / CpuWindow) of every process of the launch tree
  (and of roscore: master + rosout) by role: simulator, telemetry CLI (tlm_data_logger.py), interface,
  mirror, controller, trajectory generator, world, roslaunch; in % of one core, and per drone;
- per drone, from the nodes' own /diagnostics at the window's ends: the simulator's real-time factor
  (sim time advanced / wall time) and overruns, the interface's ground-truth rate (samples published / wall
  time), the mirror's rate (samples sent / wall time) and lag p99;
- the machine's load average and busy share over the window.

A fleet *holds RTF 1* when every drone's RTF >= 0.98 and ground truth >= 97 Hz (the mirror's rates are
reported beside: input received, sent, and decimated -- samples stamped less than 70 % of a period after
the previous one, which receipt-time stamps under load produce).
Writes benchmarks/results/fleet.md and fleet.json (``--no-write``: print only). Machines are shared: the load is recorded
with every figure; compare sizes within one run.

Run (inside env.bash): python benchmarks/bench_fleet.py [--sizes 1 2 4 8] [--duration 30] [--settle 10]
(about 10 minutes on a quiet machine); --from-json rewrites fleet.md from fleet.json.
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

from anafi_sim import processes

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'benchmarks', 'results', 'fleet.md')
RESULTS_JSON = os.path.join(ROOT, 'benchmarks', 'results', 'fleet.json')
MASTER_PORTS = (12000, 12500)
ROLES = (('anafi_sim_node.py', 'simulator'), ('tlm_data_logger.py', 'telemetry CLI'),
         ('interface_node.py', 'interface'), ('gazebo_mirror_node.py', 'mirror'),
         ('controller_node.py', 'controller'), ('pid_', 'controller'),
         ('trajectory_generator.py', 'generator'), ('model_follower.py', 'generator'),
         ('evaluator.py', 'evaluator'), ('kinematic_world_node.py', 'world'), ('fleet_launcher.py', 'roslaunch'),
         ('roslaunch', 'roslaunch'), ('rosmaster', 'master + rosout'), ('rosout', 'master + rosout'))
PER_DRONE = ('simulator', 'telemetry CLI', 'interface', 'mirror', 'controller', 'generator')
SHARED = ('world', 'roslaunch', 'master + rosout')
HOLD = {'rtf': 0.98, 'truth_hz': 97.0}


def role_of(proc, is_root):
    try:
        cmd = ' '.join(proc.cmdline())
    except psutil.Error:
        return 'other'
    for key, role in ROLES:
        if key in cmd:
            return role
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
        self.workdir = workdir
        self.procs = processes.Processes(workdir, grace=30.0)
        uri, self.env = processes.private_master(self.procs, os.path.join(workdir, 'ros_home'),
                                               os.path.join(workdir, 'log'), MASTER_PORTS, join=True)
        self.port = int(uri.rsplit(':', 1)[1])
        self.core = self.procs.started[0][1]
        rospy.init_node('bench_fleet', anonymous=True, disable_signals=True)
        self.diag = Diagnostics()

    def run_size(self, n, args):
        """One fleet of ``n`` drones: the figures of its measurement window."""
        diag = self.diag
        with diag.lock:
            diag.latest.clear()
        name = 'fleet%d' % n
        launch = self.procs.start(name, ['roslaunch', '--port', str(self.port), 'anafi_sim', 'fleet.launch',
                                         'fleet:=%s' % args.fleet, 'drones:=%d' % n, 'evaluate:=false',
                                         'out_dir:=%s' % os.path.join(self.workdir, name)], self.env)
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
        per_role = {}
        for tree in ('launch', 'core'):
            for role, (cpu, count) in window.cpu[tree].items():
                entry = per_role.setdefault(role, [0.0, 0])
                entry[0] += 100.0 * cpu / window.wall
                entry[1] += count
        return {'n': n, 'startup_s': startup, 'wall': window.wall, 'roles': per_role,
                'drones': drone_figures(names, before, after), 'load_before': window.load_before,
                'load_after': window.load_after, 'busy': window.busy,
                'bench_cpu': 100.0 * window.bench_cpu / window.wall}

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


OTHER_JOBS_LIMIT = 30.0   # [% of one core] of other processes during a window: above it, a row measures the machine


def other_jobs(r):
    """CPU [% of one core] of processes outside the fleet during the window: machine busy x cores - fleet - bench."""
    cores = os.cpu_count() or 1
    fleet = sum(v[0] for v in r['roles'].values())
    return max(0.0, r['busy'] * cores - fleet - r.get('bench_cpu', 0.0))


def holds(r):
    figs = [f for f in r['drones'].values()]
    if not figs or any(not f for f in figs):
        return False
    return all(f['rtf'] >= HOLD['rtf'] and f['truth_hz'] >= HOLD['truth_hz'] for f in figs)


def _min(r, key):
    vals = [f[key] for f in r['drones'].values() if f]
    return min(vals) if vals else float('nan')


def _max(r, key):
    vals = [f[key] for f in r['drones'].values() if f]
    return max(vals) if vals else float('nan')


def markdown(results, args):
    lines = ['# A fleet at scale: CPU per drone and the largest fleet at RTF 1', '',
             'Generated by `benchmarks/bench_fleet.py` (%s, Python %s, %d CPU cores, %s). Each size N: '
             '`fleet.launch drones:=N fleet:=%s evaluate:=false` on a private master (kinematic world; per drone '
             'simulated Anafi + interface + mirror at 100 Hz + MPC + trajectory generator; wall clock), '
             '%g s of settling after every drone flies its scenario, then %g s measured. CPU = user + sys '
             '(psutil) of every process of the launch tree and of roscore, by role, in %% of one core. '
             'Per-drone rates from the nodes\' own /diagnostics across the window. *Holds RTF 1*: every drone '
             'RTF >= %.2f and ground truth >= %g Hz. Mirror: input received / sent / decimated (a sample stamped '
             '< 70 %% of a period after the previous one is dropped; the interface stamps at receipt on the wall '
             'clock, so bursts under load are decimated) [Hz, min over the drones].'
             % (datetime.date.today().isoformat(), platform.python_version(), os.cpu_count() or 0,
                processes.cpu_model(), args.fleet, args.settle, args.duration, HOLD['rtf'], HOLD['truth_hz']), '',
             'The machine is shared with other jobs: the machine\'s busy share, the CPU of processes outside '
             'the fleet (busy x cores - fleet - this script) and the load average (1 min, before -> after the '
             'window; the fleet\'s own processes count in it) are next to each row.', '',
             '| N | holds RTF 1 | RTF min | ground truth min [Hz] | mirror in / sent / decimated [Hz] '
             '| mirror lag p99 max [ms] | sim overruns | CPU total [% core] | CPU per drone [% core] '
             '| machine busy [%] | other jobs [% core] | load avg | start-up [s] |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in results:
        total = sum(v[0] for v in r['roles'].values())
        overruns = sum(f.get('overruns', 0) for f in r['drones'].values() if f)
        lines.append('| %d | %s | %.3f | %.1f | %.1f / %.1f / %.1f | %.1f | %d | %.0f | %.1f | %.0f | %.0f '
                     '| %.1f -> %.1f | %.0f |' % (
            r['n'], 'yes' if holds(r) else 'NO', _min(r, 'rtf'), _min(r, 'truth_hz'), _min(r, 'mirror_in_hz'),
            _min(r, 'mirror_hz'), _max(r, 'mirror_decimated_hz'),
            _max(r, 'lag_p99_ms'), overruns, total, total / r['n'], r['busy'], other_jobs(r),
            r['load_before'][0], r['load_after'][0], r['startup_s']))
    lines += ['', '## Where the time goes', '',
              'CPU by role [% of one core]; per drone = the role\'s total / N (the world, roslaunch and the '
              'master are shared by the fleet).', '']
    roles = [ro for ro in PER_DRONE + SHARED + ('other',) if any(ro in r['roles'] for r in results)]
    lines.append('| role | ' + ' | '.join('N = %d total | per drone' % r['n'] for r in results) + ' |')
    lines.append('|---|' + '---|---|' * len(results))
    for role in roles:
        cells = []
        for r in results:
            v = r['roles'].get(role, [0.0, 0])[0]
            cells.append('%.1f | %.1f' % (v, v / r['n']))
        lines.append('| %s | %s |' % (role, ' | '.join(cells)))
    lines.append('| bench (this script) | ' + ' | '.join('%.1f | -' % r['bench_cpu'] for r in results) + ' |')
    if args.core_cost:
        cost, diff = args.core_cost
        before, after = cost['numpy (before)'], cost['plain Python (shipped)']
        lines += ['', '## The cut: the mirror\'s model-state maths', '',
                  'Profiling the mirror core showed numpy call overhead on single 3-vectors (np.cross alone about '
                  'a third of `Mirror.on_ground_truth`). The shipped `anafi_sim/gazebo/mirror.py` does the two '
                  'rotations and the cross product in plain Python (same formulas, same `frames` matrix). Same '
                  'run, interleaved, best of 5 x 3000 samples: numpy %.0f us, plain Python %.0f us per sample '
                  '(x%.1f less; at 100 Hz %.2f -> %.2f %% of a core per drone); largest difference of the '
                  'results %.1e (rounding).' % (before, after, before / after, before / 100.0, after / 100.0, diff)]
    loaded = [r['n'] for r in results if other_jobs(r) > OTHER_JOBS_LIMIT]
    if loaded:
        lines += ['', '## Reading this run', '',
                  'Other jobs used more than %g %% of a core (machine busy minus the fleet and this script) '
                  'for N = %s: the fleet competed with them for the cores, so its processes may have got less '
                  'CPU than they asked for; RTF, rates and "holds" of those rows then measure the machine, not '
                  'the fleet, and CPU per drone is what the drones got, not what they need. Rerun on a quiet '
                  'machine: `python benchmarks/bench_fleet.py`.' % (OTHER_JOBS_LIMIT, ', '.join(str(n) for n in loaded))]
    else:
        lines += ['', 'No other job used more than %g %% of a core during any window (machine busy minus the '
                  'fleet and this script): the figures are the fleet\'s own.' % OTHER_JOBS_LIMIT]
    largest = [r['n'] for r in results if holds(r)]
    mirrored = [r['n'] for r in results if holds(r) and _min(r, 'mirror_hz') >= HOLD['truth_hz']]
    lines += ['', 'Largest fleet holding RTF 1 in this run: %s; with every mirror also at >= %g Hz: %s.'
              % (max(largest) if largest else 'none', HOLD['truth_hz'], max(mirrored) if mirrored else 'none'), '']
    return '\n'.join(lines) + '\n'


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--sizes', type=int, nargs='+', default=[1, 2, 4, 8])
    ap.add_argument('--fleet', default='three_circles')
    ap.add_argument('--duration', type=float, default=30.0, help='s of wall time measured')
    ap.add_argument('--settle', type=float, default=10.0)
    ap.add_argument('--start-timeout', type=float, default=240.0)
    ap.add_argument('--no-write', action='store_true')
    ap.add_argument('--from-json', action='store_true', help='only rewrite fleet.md from fleet.json')
    args = ap.parse_args(argv)
    if args.from_json:
        with open(RESULTS_JSON) as f:
            data = json.load(f)
        for key in ('fleet', 'settle', 'duration'):
            setattr(args, key, data[key])
        args.core_cost = data['core_cost']
        with open(RESULTS, 'w') as f:
            f.write(markdown(data['results'], args))
        print('written %s' % RESULTS)
        return 0
    results = []
    with tempfile.TemporaryDirectory(prefix='bench_fleet_') as workdir:
        bench = Bench(workdir)
        try:
            for n in args.sizes:
                print('N = %d ...' % n, flush=True)
                try:
                    r = bench.run_size(n, args)
                except TimeoutError as error:
                    print('N = %d: %s' % (n, error), flush=True)
                    continue
                results.append(r)
                total = sum(v[0] for v in r['roles'].values())
                print('N = %d: holds RTF 1: %s; RTF min %.3f, ground truth min %.1f Hz, mirror min %.1f Hz; '
                      'CPU %.0f %% (%.1f %% per drone); load %.1f -> %.1f'
                      % (n, holds(r), _min(r, 'rtf'), _min(r, 'truth_hz'), _min(r, 'mirror_hz'), total, total / n,
                         r['load_before'][0], r['load_after'][0]), flush=True)
                for role, (cpu, count) in sorted(r['roles'].items(), key=lambda kv: -kv[1][0]):
                    print('    %-16s %5.1f %% (%d processes)' % (role, cpu, count), flush=True)
        finally:
            bench.close()
    args.core_cost = mirror_core_cost()
    text = markdown(results, args)
    if not args.no_write and results:
        with open(RESULTS_JSON, 'w') as f:
            json.dump({'results': results, 'core_cost': args.core_cost, 'fleet': args.fleet,
                       'settle': args.settle, 'duration': args.duration}, f, indent=1, sort_keys=True)
    print(text)
    if not args.no_write and results:
        with open(RESULTS, 'w') as f:
            f.write(text)
        print('written %s' % RESULTS)
    return 0


if __name__ == '__main__':
    sys.exit(main())
