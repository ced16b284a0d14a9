#!/usr/bin/env python3
"""Benchmark: the Gazebo mirror (mirror stage) -- topic stream vs the paper's per-cycle service call.

One run, our own roscore on a free port, one kinematic world (the stand-in for Gazebo) running at
``--world-rate`` Hz without ground plane, and a synthetic ground truth published here at ``--rate`` Hz on
``/bench/ground_truth/odom`` (+ gimbal angles on ``/bench/ground_truth/drone_data``), stamped with the wall time
of publication. Sample number k is encoded in the pose (x = k * 1 mm, zero twist, so the world does not
extrapolate it). The real ``gazebo_mirror_node.py`` is then run in each mode, the modes interleaved over
``--rounds`` rounds (same world, same source; ``--duration`` s per mode in total, warm-up per segment):

* ``topic``: ModelState messages on the asynchronous /gazebo/set_model_state topic (our default);
* ``service``: one synchronous /gazebo/set_model_state service call per model per cycle through a plain
  (non-persistent) rospy.ServiceProxy -- a new TCP connection per call, as the paper's code did;
* ``service, persistent``: the same with one kept-open connection (the best a service can do).

Measured per mode:
- world-side: distinct samples seen in /gazebo/model_states per second (achieved mirror rate as the world
  applies it) and the lag ground-truth stamp -> receipt here of the first model_states showing that sample
  (includes up to one world period 1/world_rate of publishing quantisation, the same for every mode);
- mirror-side: the mirror's own diagnostics (rate, lag stamp -> send complete);
- CPU (user+sys, psutil) of the mirror process and of the world process, in % of one core.
Prints a table and writes benchmarks/results/mirror.md.

Needs the workspace environment (``source env.bash``, or .ws/devel/setup.bash + the venv on PATH).
Run: .venv/bin/python benchmarks/bench_mirror.py [--duration 30] [--rounds 6] [--rate 100] [--no-write]
(about 3 minutes with the defaults)
"""
import argparse
import os
import platform
import shutil
import sys
import tempfile
import threading
import time

import numpy as np
import psutil

from anafi_sim.processes import Processes, cpu_seconds, private_master, require

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPTS = os.path.join(ROOT, 'anafi_sim', 'scripts')
RESULTS = os.path.join(ROOT, 'benchmarks', 'results', 'mirror.md')
STEP = 0.001  # m of x per sample number
MODES = [
    ('topic', {'use_service': False}),
    ('service (new connection per call, paper)', {'use_service': True, 'persistent_service': False}),
    ('service (persistent connection)', {'use_service': True, 'persistent_service': True}),
]


class Source(threading.Thread):
    """Publishes the synthetic ground truth at ``rate`` Hz (wall-paced) and remembers each sample's stamp."""

    def __init__(self, rate):
        threading.Thread.__init__(self)
        self.daemon = True
        import rospy
        from nav_msgs.msg import Odometry
        from anafi_sim.msg import DroneData
        self.rospy, self.Odometry, self.DroneData = rospy, Odometry, DroneData
        self.period = 1.0 / rate
        self.odom = rospy.Publisher('/bench/ground_truth/odom', Odometry, queue_size=10, tcp_nodelay=True)
        self.data = rospy.Publisher('/bench/ground_truth/drone_data', DroneData, queue_size=10, tcp_nodelay=True)
        self.stamps = {}
        self.k = 0
        self.running = True

    def run(self):
        next_t = time.time()
        while self.running:
            self.k += 1
            now = time.time()
            stamp = self.rospy.Time.from_sec(now)
            d = self.DroneData()
            d.header.stamp = stamp
            d.gimbalPitchMotorAngle = 0.3
            self.data.publish(d)
            o = self.Odometry()
            o.header.stamp = stamp
            o.header.frame_id = 'world'
            o.child_frame_id = 'bench/base_link'
            o.pose.pose.position.x = self.k * STEP
            o.pose.pose.position.z = 5.0
            o.pose.pose.orientation.w = 1.0
            self.stamps[self.k] = now
            self.odom.publish(o)
            next_t += self.period
            delay = next_t - time.time()
            if delay > 0:
                time.sleep(delay)
            else:
                next_t = time.time()


class WorldWatcher(object):
    """/gazebo/model_states: first receipt time of each sample number shown for model 'bench'."""

    def __init__(self):
        import rospy
        from anafi_sim.ros import gazebo_types
        self.lock = threading.Lock()
        self.first_seen = {}
        self.names = set()
        rospy.Subscriber('/gazebo/model_states', gazebo_types.model_states_class(), self.on_states,
                         queue_size=100, tcp_nodelay=True)

    def on_states(self, msg):
        now = time.time()
        with self.lock:
            self.names = set(msg.name)
            for name, pose in zip(msg.name, msg.pose):
                if name == 'bench':
                    k = int(round(pose.position.x / STEP))
                    if k not in self.first_seen:
                        self.first_seen[k] = now


class MirrorDiag(object):
    def __init__(self):
        import rospy
        from diagnostic_msgs.msg import DiagnosticArray
        self.last = None
        rospy.Subscriber('/diagnostics', DiagnosticArray, self.on_diag, queue_size=20)

    def on_diag(self, msg):
        for status in msg.status:
            if 'gazebo mirror' in status.name:
                self.last = dict((kv.key, kv.value) for kv in status.values)


def run_segment(label, params, procs, env, source, watcher, diag, world, duration, warmup, log):
    """One measured segment of a mode: raw numbers (aggregated over rounds by ``aggregate``)."""
    import rospy
    for key in ('use_service', 'persistent_service'):
        rospy.set_param('/bench/gazebo_mirror/' + key, params.get(key, False))
    rospy.set_param('/bench/gazebo_mirror/drone_name', 'bench')
    rospy.set_param('/bench/gazebo_mirror/rate', float(source_rate(source)))
    rospy.set_param('/bench/gazebo_mirror/stale_timeout', 0.5)
    log('mode %s: starting gazebo_mirror_node.py' % label)
    mirror = procs.start('mirror', [sys.executable, os.path.join(SCRIPTS, 'gazebo_mirror_node.py'),
                                    '__name:=gazebo_mirror', '__ns:=/bench'], env)
    try:
        require(lambda: {'bench', 'bench_camera'} <= watcher.names, 30, 'the mirrored models',
                lambda: procs.log_tail('mirror'))
        time.sleep(warmup)
        diag.last = None
        c0, w0, t0, k0 = cpu_seconds(mirror.pid), cpu_seconds(world.pid), time.time(), source.k
        time.sleep(duration)
        c1, w1, t1, k1 = cpu_seconds(mirror.pid), cpu_seconds(world.pid), time.time(), source.k
        require(lambda: diag.last is not None, 5, 'mirror diagnostics')
        mirror_diag = dict(diag.last)
    finally:
        procs.stop('mirror', grace=5.0)
    with watcher.lock:
        seen = dict((k, t) for k, t in watcher.first_seen.items() if k0 < k <= k1)
    return {'lags': [t - source.stamps[k] for k, t in seen.items() if k in source.stamps], 'seen': len(seen),
            'published': k1 - k0, 'wall': t1 - t0, 'mirror_cpu': c1 - c0, 'world_cpu': w1 - w0,
            'diag_rate': mirror_diag.get('mirror rate [Hz]', 'n/a'),
            'diag_p99': mirror_diag.get('lag p99 [ms]', 'n/a')}


def aggregate(label, segments):
    """Per-mode figures over its segments (all rounds)."""
    lags = np.array([v for seg in segments for v in seg['lags']])
    wall = sum(seg['wall'] for seg in segments)
    published = sum(seg['published'] for seg in segments)
    seen = sum(seg['seen'] for seg in segments)
    nan = float('nan')
    return {
        'mode': label,
        'world_rate': seen / wall,
        'delivered': seen / float(published) if published else nan,
        'lag_p50': float(np.percentile(lags, 50)) if len(lags) else nan,
        'lag_p99': float(np.percentile(lags, 99)) if len(lags) else nan,
        'lag_max': float(lags.max()) if len(lags) else nan,
        'mirror_cpu': 100.0 * sum(seg['mirror_cpu'] for seg in segments) / wall,
        'world_cpu': 100.0 * sum(seg['world_cpu'] for seg in segments) / wall,
        'segment_rates': [seg['seen'] / seg['wall'] for seg in segments],
        'segment_p99': [float(np.percentile(seg['lags'], 99)) if seg['lags'] else nan for seg in segments],
        'mirror_diag_rate': ', '.join(seg['diag_rate'] for seg in segments),
        'mirror_diag_p99': ', '.join(seg['diag_p99'] for seg in segments),
    }


def source_rate(source):
    return 1.0 / source.period


def table(results):
    head = ('| mode | achieved rate at the world [Hz] (segments min-max) | samples applied | lag p50 [ms] | '
            'lag p99 [ms] (segments min-max) | lag max [ms] | mirror CPU [% core] | world CPU [% core] |')
    rows = [head, '|' + '---|' * 8]
    for r in results:
        rows.append('| %s | %.1f (%.1f-%.1f) | %.1f %% | %.2f | %.2f (%.1f-%.1f) | %.2f | %.1f | %.1f |' % (
            r['mode'], r['world_rate'], min(r['segment_rates']), max(r['segment_rates']), 100.0 * r['delivered'],
            1e3 * r['lag_p50'], 1e3 * r['lag_p99'], 1e3 * min(r['segment_p99']), 1e3 * max(r['segment_p99']),
            1e3 * r['lag_max'], r['mirror_cpu'], r['world_cpu']))
    rows += ['', 'The mirror\'s own diagnostics at the end of each segment (rate of completed sends [Hz] / lag '
             'stamp -> send complete, p99 [ms]; for a service call, complete = the world answered):', '']
    for r in results:
        rows.append('- %s: %s / %s' % (r['mode'], r['mirror_diag_rate'], r['mirror_diag_p99']))
    return '\n'.join(rows)


def measure(args, log):
    """Every mode in ``args.rounds`` interleaved rounds on a private master: the aggregated figures per mode."""
    import rospy
    tmp = tempfile.mkdtemp(prefix='bench_mirror_')
    procs = Processes(tmp)
    source = None
    try:
        uri, env = private_master(procs, tmp, join=True)
        log('roscore at %s (logs in %s)' % (uri, tmp))
        rospy.init_node('bench_mirror', disable_signals=True)
        rospy.set_param('/gazebo/rate', float(args.world_rate))
        rospy.set_param('/gazebo/ground_plane', False)
        world = procs.start('world', [sys.executable, os.path.join(SCRIPTS, 'kinematic_world_node.py'),
                                      '__name:=gazebo'], env)
        watcher = WorldWatcher()
        diag = MirrorDiag()
        source = Source(args.rate)
        source.start()
        segments = dict((label, []) for label, _ in MODES)
        for round_ in range(args.rounds):  # modes interleaved: load changes hit every mode alike
            for label, params in MODES:
                seg = run_segment(label, params, procs, env, source, watcher, diag, world,
                                  args.duration / args.rounds, args.warmup, log)
                segments[label].append(seg)
                log('round %d, %s: %.1f Hz at the world, lag p99 %.2f ms' % (
                    round_ + 1, label, seg['seen'] / seg['wall'],
                    1e3 * np.percentile(seg['lags'], 99) if seg['lags'] else float('nan')))
                time.sleep(0.5)
        return [aggregate(label, segments[label]) for label, _ in MODES]
    finally:
        if source is not None:
            source.running = False
        procs.stop_all()


def ratio_lines(results):
    """Each mode against the topic stream (the first mode): rate, lag p99, mirror and world CPU."""
    topic = results[0]
    return ['- %s vs topic: rate x%.2f, lag p99 x%.1f, mirror CPU x%.2f, world CPU x%.2f' % (
        r['mode'], r['world_rate'] / topic['world_rate'], r['lag_p99'] / topic['lag_p99'],
        r['mirror_cpu'] / topic['mirror_cpu'], r['world_cpu'] / topic['world_cpu']) for r in results[1:]]


def report(args, text, ratios):
    """The Markdown of benchmarks/results/mirror.md around the table ``text`` and the ``ratios`` lines."""
    body = [
        '# Gazebo mirror: topic stream vs per-cycle service call',
        '',
        'Generated by `benchmarks/bench_mirror.py` (%s, Python %s, %d CPU cores, %s). One run '
        'against the same kinematic world (%g Hz, stand-in for Gazebo) and the same synthetic ground truth '
        '(%g Hz, stamped at publication); %d rounds, each running every mode in turn (%g s measured per mode '
        'in total, after %g s warm-up per segment), so background load hits all modes alike. Two models '
        '(drone + camera) per cycle. Machine load (1-min load average) at the end: %.2f.'
        % (time.strftime('%Y-%m-%d'), platform.python_version(), psutil.cpu_count(), platform.platform(),
           args.world_rate, args.rate, args.rounds, args.duration, args.warmup, os.getloadavg()[0]),
        '',
        text,
        '',
        'Ratios (same run):',
        '',
        '\n'.join(ratios),
        '',
        'Definitions: *achieved rate at the world* = distinct ground-truth samples that appeared in '
        '/gazebo/model_states per second; *samples applied* = their share of the published samples; *lag* = '
        'ground-truth stamp -> receipt here of the first /gazebo/model_states showing that sample (includes up '
        'to one world period, %.1f ms, of publishing quantisation, identical for all modes); CPU = user+sys '
        'time of the process over the window / wall time. Segment figures show how much background load moved '
        'the numbers; the pooled figures and the ratios are the comparison.'
        % (1e3 / args.world_rate),
        '',
        'The paper called the /gazebo/set_model_state service every cycle (synchronous: each call waits for '
        'Gazebo, and a plain rospy.ServiceProxy opens a new connection per call); the mirror streams on the '
        'topic Gazebo also subscribes to, so the mirror never waits for the world. The kinematic world answers '
        'a service call at once; a real Gazebo has to synchronise the call with its physics loop, so its '
        'round trip is likely longer (not measured here: no Gazebo on this machine).',
        '',
    ]
    return '\n'.join(body)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--duration', type=float, default=30.0, help='measured seconds per mode (all rounds)')
    parser.add_argument('--rounds', type=int, default=6, help='rounds; each runs every mode in turn')
    parser.add_argument('--warmup', type=float, default=1.5, help='seconds per segment before measuring')
    parser.add_argument('--rate', type=float, default=100.0, help='ground-truth and mirror rate [Hz]')
    parser.add_argument('--world-rate', type=float, default=250.0, help='kinematic world rate [Hz]')
    parser.add_argument('--no-write', action='store_true', help='do not write ' + RESULTS)
    args = parser.parse_args()
    try:
        import rospy  # noqa: F401
        from anafi_sim.msg import DroneData  # noqa: F401  (generated messages available?)
    except ImportError as exc:
        raise SystemExit('cannot import ROS / the generated messages (%s): source env.bash first' % exc)
    if shutil.which('roscore') is None:
        raise SystemExit('roscore not found on PATH: source env.bash first')

    def log(text):
        print('[bench_mirror] %s' % text, flush=True)

    results = measure(args, log)
    text = table(results)
    ratios = ratio_lines(results)
    print(text)
    print('\n'.join(ratios))
    if args.no_write:
        return
    os.makedirs(os.path.dirname(RESULTS), exist_ok=True)
    with open(RESULTS, 'w') as f:
        f.write(report(args, text, ratios))
    print('wrote %s' % RESULTS)


if __name__ == '__main__':
    main()
