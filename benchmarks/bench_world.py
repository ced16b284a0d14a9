#!/usr/bin/env python3
"""Benchmark: the kinematic world's CPU per received ModelState and per cycle (world stage, fleet scale).

On a ROS master of our own, per fleet size N (``--sizes``, default 1 10 20) and per implementation (the
current ``kinematic_world_node.py``; with ``--reference REV`` also that git revision's node and core, taken
with ``git show`` into a temporary directory, so that both are measured side by side in one run, interleaved):

1. the world node starts (private parameters from anafi_sim/config/kinematic_world.yaml, ground plane on);
2. 2N models are spawned through ``/gazebo/spawn_urdf_model`` as the mirror does (``<drone>`` from
   anafi.urdf and ``<drone>_camera`` from anafi_camera.urdf);
3. idle window (``--idle`` s): no ModelState; the world's CPU [s] / cycles = CPU per cycle;
4. load window (``--duration`` s): this ONE process publishes 2N ModelState at ``--rate`` Hz each on the
   ``/gazebo/set_model_state`` topic (moving poses with a twist, reference frame 'world'); CPU per message =
   (CPU - cycles x CPU per idle cycle) / messages sent in the window;
5. every message must be applied: the world's ``state_updates`` counter (its /diagnostics) equals the
   messages sent, ``rejected`` and ``topic_rejected`` stay 0.

Cycles are counted from ``/gazebo/model_states`` arrivals here (raw, not deserialised), which also give the
achieved cycle rate and the period p99/max; the world's time against the wall clock gives its lateness
(ms of simulated time lost over the window: > 0 when it runs slower than real time). CPU: psutil user+sys
of the world process. Writes benchmarks/results/world.md, world.json and plots/world.png.

Run (inside ``source env.bash``, preferably in a network namespace of your own):
  python benchmarks/bench_world.py [--reference REV] [--sizes 1 10 20] [--duration 15] [--idle 8] [--rounds 2]
(about 30 s per size, implementation and round; the table gives the medians of the rounds)
"""
import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

from anafi_sim import paths
from anafi_sim.processes import Processes, cpu_model, cpu_seconds, node_pid, private_master, wait_for
from anafi_sim.run_files import atomic_path, atomic_write_text, mark_failed, remove_previous

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'benchmarks', 'results', 'world.md')
CORE_IMPORT = 'from anafi_sim.gazebo.kinematic_world import'


def reference_node(rev, directory):
    """Path of revision ``rev``'s world node, its core imported from a copy next to it (git show)."""
    def show(path):
        return subprocess.check_output(['git', '-C', ROOT, 'show', '%s:%s' % (rev, path)],
                                       stderr=subprocess.DEVNULL).decode('utf-8')
    try:       # the node's module (anafi_sim/nodes, run through its main) or, in older revisions, its script
        node = show('anafi_sim/nodes/kinematic_world_node.py') + "\n\nif __name__ == '__main__':\n    main()\n"
    except subprocess.CalledProcessError:
        node = show('anafi_sim/scripts/kinematic_world_node.py')
    if CORE_IMPORT not in node:
        raise RuntimeError('%s: the world node does not import its core as %r' % (rev, CORE_IMPORT))
    with open(os.path.join(directory, 'kinematic_world_reference.py'), 'w') as f:
        f.write(show('anafi_sim/gazebo/kinematic_world.py'))
    path = os.path.join(directory, 'kinematic_world_node_reference.py')
    with open(path, 'w') as f:
        f.write(node.replace(CORE_IMPORT, 'from kinematic_world_reference import'))
    return path


class Observer(object):
    """Counts /gazebo/model_states arrivals (raw) and keeps the world's latest /diagnostics values."""

    def __init__(self):
        import rospy
        from diagnostic_msgs.msg import DiagnosticArray
        self.lock = threading.Lock()
        self.arrivals = []
        self.recording = False
        self.world = {}
        self.world_stamp = 0.0
        rospy.Subscriber('/gazebo/model_states', rospy.AnyMsg, self.on_states, queue_size=1000)
        rospy.Subscriber('/diagnostics', DiagnosticArray, self.on_diagnostics, queue_size=10)

    def on_states(self, _msg):
        if self.recording:
            self.arrivals.append(time.monotonic())

    def on_diagnostics(self, msg):
        for status in msg.status:
            if status.name == 'kinematic_world: world':
                with self.lock:
                    self.world = dict((kv.key, kv.value) for kv in status.values)
                    self.world['_wall'] = msg.header.stamp.to_sec()
                    self.world_stamp = time.monotonic()

    def fresh_world(self, timeout=10.0):
        """The world's diagnostics values published after this call."""
        since = time.monotonic()
        if not wait_for(lambda: self.world_stamp > since, timeout, 0.05):
            raise RuntimeError('no /diagnostics from the world for %.0f s' % timeout)
        with self.lock:
            return dict(self.world)


class Source(object):
    """Publishes one ModelState per model at ``rate`` Hz (all from this process), wall-paced."""

    def __init__(self, models, rate):
        import rospy
        from anafi_sim.ros import gazebo_types
        ModelState = gazebo_types.model_state_class()
        # a deep outgoing queue: rospy drops the oldest queued message silently when it is full, and a
        # burst of 2N messages must not be lost before it reaches the world
        self.pub = rospy.Publisher('/gazebo/set_model_state', ModelState, queue_size=max(100, 10 * len(models)),
                                   tcp_nodelay=True)
        self.msgs = []
        for name in models:
            m = ModelState()
            m.model_name = name
            m.reference_frame = 'world'
            self.msgs.append(m)
        self.period = 1.0 / rate
        self.sent = 0
        self.late = 0
        self.running = False

    def start(self):
        self.running = True
        self.thread = threading.Thread(target=self.run)
        self.thread.daemon = True
        self.thread.start()

    def stop(self):
        self.running = False
        self.thread.join()

    def run(self):
        k = 0
        t0 = time.monotonic()
        while self.running:
            t = k * self.period
            for i, m in enumerate(self.msgs):       # drone i on a circle of 2 + i m, 1 rad/s, yawing
                a = t + 0.3 * i
                r = 2.0 + i
                m.pose.position.x, m.pose.position.y, m.pose.position.z = r * np.cos(a), r * np.sin(a), 1.5
                m.pose.orientation.z, m.pose.orientation.w = np.sin(0.5 * a), np.cos(0.5 * a)
                m.twist.linear.x, m.twist.linear.y = -r * np.sin(a), r * np.cos(a)
                m.twist.angular.z = 1.0
                self.pub.publish(m)
                self.sent += 1
            k += 1
            delay = t0 + k * self.period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                self.late += 1


def spawn_models(n):
    """Spawn drones d0..d(n-1) and their cameras; returns the 2n model names."""
    import rospy
    from anafi_sim.gazebo.mirror import model_names, namespaced_model_xml
    from anafi_sim.ros import gazebo_types
    with open(paths.data_path('urdf', 'anafi.urdf')) as f:
        drone_xml = f.read()
    with open(paths.data_path('urdf', 'anafi_camera.urdf')) as f:
        camera_xml = f.read()
    spawn = rospy.ServiceProxy('/gazebo/spawn_urdf_model', gazebo_types.spawn_model_class())
    out = []
    for i in range(n):
        drone = 'd%d' % i
        for name, xml in zip(model_names(drone), (drone_xml, camera_xml)):
            req = gazebo_types.spawn_model_class()._request_class()
            req.model_name, req.model_xml = name, namespaced_model_xml(xml, drone)
            req.robot_namespace, req.reference_frame = '/' + drone, 'world'
            req.initial_pose.position.x, req.initial_pose.position.z = float(i), 1.0
            req.initial_pose.orientation.w = 1.0
            res = spawn(req)
            if not res.success:
                raise RuntimeError('spawn %s: %s' % (name, res.status_message))
            out.append(name)
    return out


def window(observer, pid, seconds):
    """(CPU s of ``pid``, cycles, wall s, arrival times) over ``seconds``."""
    observer.arrivals = []
    observer.recording = True
    cpu0, t0 = cpu_seconds(pid), time.monotonic()
    time.sleep(seconds)
    cpu1, t1 = cpu_seconds(pid), time.monotonic()
    observer.recording = False
    arrivals = [a for a in observer.arrivals if t0 <= a <= t1]
    return cpu1 - cpu0, len(arrivals), t1 - t0, arrivals


def measure(procs, env, observer, node, label, n, args):
    """One world (``node`` script), 2n models: idle and load windows; a result dict."""
    import rospy
    rospy.set_param('/gazebo', _world_params())
    procs.start('world', [sys.executable, node, '__name:=gazebo'], env)
    try:
        if not wait_for(lambda: node_pid('/gazebo') is not None, 30.0, 0.1):
            raise RuntimeError('the world did not start; log:\n%s' % procs.log_tail('world'))
        pid = node_pid('/gazebo')
        rospy.wait_for_service('/gazebo/spawn_urdf_model', timeout=30.0)
        models = spawn_models(n)
        time.sleep(1.0)
        before = observer.fresh_world()
        idle_cpu, idle_cycles, idle_wall, _ = window(observer, pid, args.idle)
        source = Source(models, args.rate)
        wait_for(lambda: source.pub.get_num_connections() > 0, 10.0, 0.05)
        source.start()
        time.sleep(1.0)                              # warm-up
        sent0, w0 = source.sent, observer.fresh_world()
        load_cpu, load_cycles, load_wall, arrivals = window(observer, pid, args.duration)
        sent1 = source.sent
        w1 = observer.fresh_world()
        source.stop()
        time.sleep(0.5)
        after = observer.fresh_world()
        source.pub.unregister()
    finally:
        procs.stop('world', grace=5.0)
    per_cycle = idle_cpu / idle_cycles if idle_cycles else float('nan')
    messages = sent1 - sent0
    per_message = (load_cpu - load_cycles * per_cycle) / messages if messages else float('nan')
    periods = np.diff(arrivals) if len(arrivals) > 1 else np.array([float('nan')])
    applied = int(after['state_updates']) - int(before['state_updates'])
    rejected = int(after['rejected']) - int(before['rejected'])
    world_dt = float(w1['time']) - float(w0['time'])
    return {
        'implementation': label, 'N': n, 'models': 2 * n + 1,
        'idle_cpu_percent': 100.0 * idle_cpu / idle_wall, 'load_cpu_percent': 100.0 * load_cpu / load_wall,
        'cpu_per_cycle_us': 1e6 * per_cycle, 'cpu_per_message_us': 1e6 * per_message,
        'cycle_rate_hz': load_cycles / load_wall, 'idle_cycle_rate_hz': idle_cycles / idle_wall,
        'period_p99_ms': 1e3 * float(np.percentile(periods, 99)), 'period_max_ms': 1e3 * float(np.max(periods)),
        'lateness_ms': _lateness_ms(w0, w1, world_dt), 'messages_per_s': messages / load_wall,
        'sent': source.sent, 'applied': applied, 'rejected': rejected + int(after.get('topic_rejected', 0)),
        'source_late_ticks': source.late, 'overruns': int(after.get('overruns', 0)),
        'all_applied': applied == source.sent and rejected == 0,
    }


def _lateness_ms(w0, w1, world_dt):
    """Simulated ms lost against the wall clock between two diagnostics snapshots (rtf 1)."""
    wall = w1['_wall'] - w0['_wall']
    return 1e3 * (wall - world_dt)


def _world_params():
    import yaml
    with open(paths.config_path('kinematic_world.yaml')) as f:
        return yaml.safe_load(f)


FIGURES = ('idle_cpu_percent', 'load_cpu_percent', 'cpu_per_cycle_us', 'cpu_per_message_us', 'cycle_rate_hz',
           'idle_cycle_rate_hz', 'period_p99_ms', 'lateness_ms', 'messages_per_s')


def summarise(results, labels, sizes):
    """One row per implementation and size: medians of the rounds' figures, worst period, summed counts."""
    out = []
    for n in sizes:
        for label in labels:
            rs = [r for r in results if r['implementation'] == label and r['N'] == n]
            row = {'implementation': label, 'N': n, 'models': rs[0]['models'], 'rounds': len(rs)}
            row.update((key, float(np.median([r[key] for r in rs]))) for key in FIGURES)
            row['period_max_ms'] = max(r['period_max_ms'] for r in rs)
            for key in ('sent', 'applied', 'rejected', 'source_late_ticks', 'overruns'):
                row[key] = sum(r[key] for r in rs)
            row['all_applied'] = all(r['all_applied'] for r in rs)
            out.append(row)
    return out


def fmt_table(results):
    rows = ['| implementation | N | models | CPU/message [us] | CPU/cycle [us] | idle CPU [% core] | '
            'load CPU [% core] | cycle rate [Hz] | period p99 / max [ms] | lateness [ms] | sent | applied |',
            '|---|---|---|---|---|---|---|---|---|---|---|---|']
    for r in results:
        rows.append('| %s | %d | %d | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f / %.1f | %.0f | %d | %d%s |' % (
            r['implementation'], r['N'], r['models'], r['cpu_per_message_us'], r['cpu_per_cycle_us'],
            r['idle_cpu_percent'], r['load_cpu_percent'], r['cycle_rate_hz'], r['period_p99_ms'],
            r['period_max_ms'], r['lateness_ms'], r['sent'], r['applied'],
            '' if r['all_applied'] else ' (NOT ALL)'))
    return rows


def ratios(results, reference):
    """[(N, reference/current CPU per message, per cycle, load CPU)] for sizes measured with both."""
    out = []
    for r in results:
        if r['implementation'] != 'current':
            continue
        for q in results:
            if q['implementation'] == reference and q['N'] == r['N']:
                out.append((r['N'], q['cpu_per_message_us'] / r['cpu_per_message_us'],
                            q['cpu_per_cycle_us'] / r['cpu_per_cycle_us'],
                            q['load_cpu_percent'] / r['load_cpu_percent']))
    return out


def plot(path, results, labels):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
    for label in labels:
        rs = sorted((r for r in results if r['implementation'] == label), key=lambda r: r['N'])
        ns = [r['N'] for r in rs]
        for ax, key in zip(axes, ('cpu_per_message_us', 'cpu_per_cycle_us', 'load_cpu_percent')):
            ax.plot(ns, [r[key] for r in rs], 'o-', label=label)
    for ax, title in zip(axes, ('CPU per ModelState [us]', 'CPU per cycle [us]',
                                'world CPU under load [% of a core]')):
        ax.set_title(title, fontsize=10)
        ax.set_xlabel('drones N (2N models)')
        ax.grid(True, alpha=0.3)
        ax.set_ylim(bottom=0)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    with atomic_path(path, '.png') as tmp:
        fig.savefig(tmp, dpi=90)
    plt.close(fig)


def write(results, rounds, args, facts, labels):
    base = os.path.splitext(RESULTS)[0]
    figure = os.path.join(os.path.dirname(RESULTS), 'plots', 'world.png')
    remove_previous([RESULTS, base + '.json', figure])
    plot(figure, results, labels)
    rat = ratios(results, labels[0]) if len(labels) > 1 else []
    lines = ['# Kinematic world: CPU per ModelState and per cycle', '',
             'Generated by `benchmarks/bench_world.py` on %s (%s, %d cores, Python %s); load average (1 min) '
             'at the start / end: %.2f / %.2f.' % (facts['date'], facts['cpu'], facts['cores'], facts['python'],
                                                  facts['load'][0], facts['load'][1]), '',
             'Per size N: the world node with 2N models spawned through `/gazebo/spawn_urdf_model` (drone + '
             'camera URDF, as the mirror does) plus the ground plane; %.0f s idle (CPU per cycle = CPU / '
             'cycles), then %.0f s with ONE process publishing 2N ModelState at %.0f Hz each on '
             '`/gazebo/set_model_state` (CPU per message = (CPU - cycles x CPU per idle cycle) / messages). '
             'Cycles counted from `/gazebo/model_states` arrivals; lateness = simulated ms lost against the '
             'wall clock over the load window (world time in its /diagnostics); applied = the world\'s '
             '`state_updates` counter, which must equal the messages sent (no drop, no rejection). CPU: '
             'user+sys of the world process (psutil). Implementations: %s, interleaved; %d rounds, the table '
             'gives their medians (period max: the worst; sent / applied: summed).'
             % (args.idle, args.duration, args.rate, ', '.join('`%s`' % l for l in labels), args.rounds), '']
    lines += fmt_table(results) + ['']
    if not all(r['all_applied'] for r in results):
        lines += ['NOT ALL: the world applied fewer ModelState than were sent; rospy keeps the subscriber\'s '
                  '`queue_size` messages of one read and drops older ones silently.', '']
    if rat:
        lines += ['Ratios %s / current (> 1: the current world is cheaper):' % labels[0], '',
                  '| N | CPU per message | CPU per cycle | CPU under load |', '|---|---|---|---|']
        lines += ['| %d | %.2f | %.2f | %.2f |' % r for r in rat] + ['']
    lines += ['![world CPU](plots/world.png)', '',
              'Rerun: `source env.bash; python benchmarks/bench_world.py%s --sizes %s --idle %g --duration %g '
              '--rounds %d` (in a network namespace of your own; about %.0f s).'
              % (' --reference %s' % args.reference if args.reference else '', ' '.join(str(n) for n in args.sizes),
                 args.idle, args.duration, args.rounds, len(rounds) * (args.idle + args.duration + 8)), '']
    atomic_write_text(RESULTS, '\n'.join(lines))
    atomic_write_text(base + '.json', json.dumps({'facts': facts, 'args': vars(args), 'summary': results,
                                                  'rounds': rounds},
                                                 indent=1, sort_keys=True))
    return [RESULTS, base + '.json', figure]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--sizes', type=int, nargs='+', default=[1, 10, 20])
    ap.add_argument('--duration', type=float, default=15.0, help='s of load window')
    ap.add_argument('--idle', type=float, default=8.0, help='s of idle window')
    ap.add_argument('--rate', type=float, default=100.0, help='Hz of ModelState per model')
    ap.add_argument('--rounds', type=int, default=2, help='measurements per size and implementation')
    ap.add_argument('--reference', default='', help='git revision whose world is measured side by side')
    ap.add_argument('--no-write', action='store_true')
    args = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix='bench_world_')
    procs = Processes(tmp)
    nodes = [('current', paths.data_path('scripts', 'kinematic_world_node.py'))]
    if args.reference:
        rev = subprocess.check_output(['git', '-C', ROOT, 'rev-parse', '--short', args.reference]).decode().strip()
        nodes.insert(0, ('reference %s' % rev, reference_node(args.reference, tmp)))
    labels = [label for label, _ in nodes]
    facts = {'date': time.strftime('%Y-%m-%d %H:%M'), 'cpu': cpu_model(), 'cores': os.cpu_count() or 0,
             'python': platform.python_version(), 'load': [os.getloadavg()[0], None]}
    results = []
    ok = False
    try:
        _, env = private_master(procs, os.path.join(tmp, 'ros_home'), join=True)
        import rospy
        rospy.init_node('bench_world', disable_signals=True)
        observer = Observer()
        for k in range(args.rounds):
            for n in args.sizes:
                for label, node in nodes:
                    r = measure(procs, env, observer, node, label, n, args)
                    r['round'] = k + 1
                    results.append(r)
                    print('round %d, %s N=%d: %.1f us/message, %.1f us/cycle, load %.1f %% core, %.1f Hz, '
                          'applied %d/%d' % (k + 1, label, n, r['cpu_per_message_us'], r['cpu_per_cycle_us'],
                                             r['load_cpu_percent'], r['cycle_rate_hz'], r['applied'], r['sent']))
                    sys.stdout.flush()
        facts['load'][1] = os.getloadavg()[0]
        summary = summarise(results, labels, args.sizes)
        measured = all(r['cycle_rate_hz'] > 0 and np.isfinite(r['cpu_per_message_us']) for r in results)
        ok = measured and all(r['all_applied'] for r in summary if r['implementation'] == 'current')
        print('\n'.join(fmt_table(summary)))
        if not args.no_write:
            written = write(summary, results, args, facts, labels)
            if not ok:
                print('FAILED: %s; results marked FAILED' % ('the current world did not apply every message'
                                                             if measured else 'no cycles or no CPU figure'))
                mark_failed(written)
            else:
                print('wrote %s' % ', '.join(written))
    except Exception:
        print('roscore log:\n%s\nworld log:\n%s' % (procs.log_tail('roscore'), procs.log_tail('world')))
        raise
    finally:
        procs.stop_all()
        shutil.rmtree(tmp, ignore_errors=True)
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
