#!/usr/bin/env python3
"""Benchmark: the ground-truth interface (telemetry -> interface stage) -- parser, latency, CPU, vs the paper's way.

Parts (``--parts``, default all):

* ``parser``: lines/s of ``TelemetryParser.feed_line`` on the lines the CLI prints (``format_sample`` of a
  simulated flight, blank line between samples) next to a naive regex parser, alternating rounds.
* ``interface``: a ``TelemetryServer`` hosted here is fed at ``--rate`` Hz by a wall-paced thread with
  samples stamped with their wall time of generation; our own roscore on a free port; the real
  ``interface_node.py`` with ``~telemetry_command`` = the stand-in CLI ``tlm_data_logger.py -r 0`` pointed at
  that server; we subscribe ``/anafi/sphinx/drone_data`` and, over ``--duration`` s, record
  header.stamp - generation (generation -> publish) and receipt wall time - generation (generation -> ROS
  message received), the published rate, and the CPU time (user+sys, psutil) of the node and its CLI child.
* ``paper``: ``benchmarks/paper_interface.py`` (the paper's 24 ``CLI | grep KEY`` pipelines + a node
  publishing the last values from a 100 Hz timer) runs together with ours on the same server for one
  further window; CPU of each whole process tree (sampled every second, so processes that end still
  count up to their last sample), ratio, latency and torn messages of both.

Sample timestamps: ``format_sample`` prints 9 significant digits, so the timestamp is the wall time minus a
fixed whole-second epoch taken at start (values ~10..300 s: resolution <= 10 us).
Needs the workspace environment (``source env.bash``). Writes benchmarks/results/interface.md.

Run: .venv/bin/python benchmarks/bench_interface.py [--parts parser,interface,paper] [--duration 30] [--no-write]
"""
import argparse
import math
import os
import platform
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np
import psutil

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from anafi_sim.sim.drone_model import AnafiModel, load_model_params  # noqa: E402
from anafi_sim.interface.ground_truth import GroundTruthInterface  # noqa: E402
from anafi_sim.telemetry.protocol import FIELDS, TelemetryParser, TelemetrySample, format_sample, key_map  # noqa: E402
from anafi_sim.telemetry.server import TelemetryServer  # noqa: E402
from bench_common import cpu_model

CLI_SCRIPT = os.path.join(ROOT, 'anafi_sim', 'scripts', 'tlm_data_logger.py')
NODE_SCRIPT = os.path.join(ROOT, 'anafi_sim', 'scripts', 'interface_node.py')
PAPER_SCRIPT = os.path.join(ROOT, 'benchmarks', 'paper_interface.py')
RESULTS = os.path.join(ROOT, 'benchmarks', 'results', 'interface.md')
PARTS = ('parser', 'interface', 'paper')


# ----------------------------------------------------------------------------- samples
def flight_samples(n, seed=1):
    """``n`` varied ground-truth samples, 10 ms apart, of the model flying changing PCMDs."""
    model = AnafiModel(load_model_params(), seed=seed)
    model.reset(x=1.0, y=-2.0, z=5.0, yaw=0.3, flying=True)
    dt, t, out = 0.005, 0.0, []
    k = 0
    while len(out) < n:
        if k % 10 == 0:  # 20 Hz PCMD, slowly varying
            model.set_command(int(30 * math.sin(0.7 * t)), int(25 * math.cos(0.5 * t)),
                              int(20 * math.sin(0.3 * t)), int(15 * math.sin(0.9 * t)), t)
            model.set_gimbal_pitch(0.3 + 0.2 * math.sin(0.2 * t))
        model.step(dt, t)
        t += dt
        k += 1
        if k % 2 == 0:
            out.append(model.truth_sample(t))
    return out


def rounded(value):
    """A value as the interface sees it after ``format_sample`` (9 significant digits)."""
    return float('%.9g' % value)


# ----------------------------------------------------------------------------- part 1: parser
class NaiveRegexParser(object):
    """What one would write first: a regex per line, a dict of values, a sample when all keys are in."""

    LINE = re.compile(r'^\s*(\S+)\s*:\s*(\S+)\s*$')

    def __init__(self, prefix='omniscient_anafi.'):
        self.fields = key_map(prefix)
        self.values = {}
        self.samples = 0

    def feed_line(self, line):
        m = self.LINE.match(line)
        if m is None:
            return None
        field = self.fields.get(m.group(1))
        if field is None:
            return None
        try:
            value = float(m.group(2))
        except ValueError:
            return None
        if not math.isfinite(value):
            return None
        self.values[field] = value
        if len(self.values) < len(FIELDS):
            return None
        sample = TelemetrySample(**self.values)
        self.values = {}
        self.samples += 1
        return sample


def _parse_all(parser, lines):
    feed = parser.feed_line
    n = 0
    for line in lines:
        if feed(line) is not None:
            n += 1
    return n


def bench_parser(n_samples=2000, rounds=9, target_s=0.3):
    samples = flight_samples(n_samples)
    text = ''.join(format_sample(s) + '\n' for s in samples)  # the server's blocks, printed unchanged by the CLI
    lines = text.splitlines(True)
    # correctness first: both give the same samples
    ours = [s for s in map(TelemetryParser().feed_line, lines) if s is not None]
    naive_p = NaiveRegexParser()
    naive = [s for s in map(naive_p.feed_line, lines) if s is not None]
    expected = [TelemetrySample(*[rounded(v) for v in s]) for s in samples]
    if ours != expected or naive != expected:
        raise RuntimeError('parsers disagree with the formatted samples (ours ok: %s, naive ok: %s)'
                           % (ours == expected, naive == expected))
    t0 = time.perf_counter()
    _parse_all(TelemetryParser(), lines)
    reps = max(1, int(round(target_s / max(time.perf_counter() - t0, 1e-6))))
    work = lines * reps
    rates = {'ours': [], 'naive': []}
    for _ in range(rounds):  # alternate, so background load hits both alike
        for name, make in (('ours', TelemetryParser), ('naive', NaiveRegexParser)):
            parser = make()
            t0 = time.perf_counter()
            got = _parse_all(parser, work)
            elapsed = time.perf_counter() - t0
            if got != n_samples * reps:
                raise RuntimeError('%s parser returned %d samples, expected %d' % (name, got, n_samples * reps))
            rates[name].append(len(work) / elapsed)
    return {'lines_per_sample': len(lines) / float(n_samples), 'n_lines': len(work), 'rounds': rounds,
            'ours': rates['ours'], 'naive': rates['naive']}


# ----------------------------------------------------------------------------- processes
def free_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.bind(('127.0.0.1', 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Processes(object):
    """Every process this benchmark starts, each in its own session; ``stop_all`` kills them and their trees."""

    def __init__(self, log_dir):
        self.log_dir = log_dir
        self.started = []  # (name, Popen, log path)

    def start(self, name, argv, env):
        path = os.path.join(self.log_dir, name + '.log')
        log = open(path, 'wb')
        try:
            proc = subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                    start_new_session=True)
        finally:
            log.close()
        self.started.append((name, proc, path))
        return proc

    def log_tail(self, name, n=20):
        for nm, _, path in self.started:
            if nm == name:
                with open(path, 'rb') as f:
                    return b''.join(f.readlines()[-n:]).decode('utf-8', 'replace')
        return ''

    @staticmethod
    def _tree(proc):
        try:
            root = psutil.Process(proc.pid)
            return [root] + root.children(recursive=True)
        except psutil.Error:
            return []

    def stop(self, name, grace=3.0):
        for nm, proc, _ in list(self.started):
            if nm == name:
                self._stop_one(proc, grace)

    def _stop_one(self, proc, grace):
        tree = self._tree(proc)  # collected first: children in other sessions survive a killpg
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, signal.SIGINT)  # ROS nodes shut down cleanly on SIGINT
            except OSError:
                pass
            try:
                proc.wait(grace)
            except subprocess.TimeoutExpired:
                for sig in (signal.SIGTERM, signal.SIGKILL):
                    try:
                        os.killpg(proc.pid, sig)
                    except OSError:
                        pass
                    try:
                        proc.wait(1.0)
                        break
                    except subprocess.TimeoutExpired:
                        continue
        leftovers = [p for p in tree if p.is_running()]
        for p in leftovers:
            try:
                p.kill()
            except psutil.Error:
                pass
        psutil.wait_procs(leftovers, timeout=2.0)

    def stop_all(self):
        for _, proc, _ in reversed(self.started):
            try:
                self._stop_one(proc, 3.0)
            except Exception as exc:  # keep cleaning up the others
                sys.stderr.write('cleanup of pid %d failed: %s\n' % (proc.pid, exc))


class TreeCpu(object):
    """CPU time (user+sys) of a process and all its descendants over a window, polled with ``poll``.

    Every process is keyed by (pid, create_time); its CPU counts from the window start (or its
    creation) to its last poll, so processes that end during the window keep their share up to then.
    """

    def __init__(self, pid, roles):
        self.pid = pid
        self.roles = roles  # callable(psutil.Process, is_root) -> role name
        self.base = {}
        self.last = {}
        self.role = {}
        self.ended = 0

    def _snapshot(self):
        out = {}
        try:
            root = psutil.Process(self.pid)
            procs = [root] + root.children(recursive=True)
        except psutil.Error:
            return out
        for p in procs:
            try:
                with p.oneshot():
                    key = (p.pid, p.create_time())
                    t = p.cpu_times()
                    out[key] = t.user + t.system
                    if key not in self.role:
                        self.role[key] = self.roles(p, p.pid == self.pid)
            except psutil.Error:
                continue
        return out

    def start_window(self):
        self.base = self._snapshot()
        self.last = dict(self.base)
        self.ended = 0

    def poll(self):
        snap = self._snapshot()
        self.last.update(snap)
        return snap

    def end_window(self):
        snap = self.poll()
        self.ended = sum(1 for k in self.last if k not in snap)
        per_role = {}
        for key, cpu in self.last.items():
            role = self.role.get(key, 'other')
            entry = per_role.setdefault(role, [0.0, 0])
            entry[0] += cpu - self.base.get(key, 0.0)
            entry[1] += 1
        return per_role


def role_of(p, is_root):
    if is_root:
        return 'node'
    try:
        name = p.name()
        cmd = ' '.join(p.cmdline())
    except psutil.Error:
        return 'other'
    if 'tlm_data_logger' in cmd and name not in ('sh', 'dash', 'bash'):
        return 'CLI'
    if name == 'grep':
        return 'grep'
    if name in ('sh', 'dash', 'bash'):
        return 'sh'
    return name


# ----------------------------------------------------------------------------- the stream
class Feeder(object):
    """Publishes the samples on the server at ``rate`` Hz of wall time, stamped with their generation time."""

    def __init__(self, server, samples, rate, epoch):
        self.server = server
        self.samples = samples
        self.period = 1.0 / rate
        self.epoch = epoch
        self.sent = {}      # rounded timestamp -> rounded sample (what the interface must publish)
        self.times = []     # generation wall times
        self.lateness = []  # behind schedule at each tick [s]
        self.late = 0       # ticks more than 2 ms behind schedule
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='feeder', daemon=True)

    def start(self):
        self._thread.start()

    def stop(self):
        self._stop.set()
        self._thread.join(2.0)

    def _run(self):
        i = 0
        n = len(self.samples)
        due = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if now < due:
                self._stop.wait(due - now)
                continue
            if now - due > 0.002:
                self.late += 1
            if now - due > 0.5:  # badly stalled: resynchronise instead of bursting
                due = now
            wall = time.time()
            self.lateness.append(now - due)
            sample = self.samples[i % n]._replace(timestamp=wall - self.epoch)
            key = rounded(sample.timestamp)
            self.sent[key] = TelemetrySample(*[rounded(v) for v in sample])
            self.times.append(wall)
            self.server.publish(sample)
            i += 1
            due += self.period


class Recorder(object):
    """Subscriber callback storing (receipt wall time, message)."""

    def __init__(self):
        self.rx = []

    def __call__(self, msg):
        self.rx.append((time.time(), msg))

    def count_since(self, t):
        return sum(1 for r, _ in self.rx[-500:] if r >= t)


MSG_OF_FIELD = {
    'x': 'posX', 'y': 'posY', 'z': 'posZ', 'vx': 'velXENU', 'vy': 'velYENU', 'vz': 'velZENU',
    'roll': 'attitudeX', 'pitch': 'attitudeY', 'yaw': 'attitudeZ',
    'body_vx': 'velXABC', 'body_vy': 'velYABC', 'body_vz': 'velZABC',
    'body_wx': 'angVelXABC', 'body_wy': 'angVelYABC', 'body_wz': 'angVelZABC',
    'body_ax': 'accXABC', 'body_ay': 'accYABC', 'body_az': 'accZABC',
    'body_alpha_x': 'angAccXABC', 'body_alpha_y': 'angAccYABC', 'body_alpha_z': 'angAccZABC',
    'timestamp': 'timeStamp', 'gimbal_pitch': 'gimbalPitchMotorAngle', 'gimbal_roll': 'gimbalRollMotorAngle',
}


def analyse(rx, t0, t1, feeder):
    """Latency / rate / consistency of the messages received in [t0, t1]."""
    epoch = feeder.epoch
    pub, recv, stamps = [], [], []
    torn = unknown = 0
    for r, msg in rx:
        if not t0 <= r <= t1:
            continue
        gen = epoch + msg.timeStamp
        pub.append(msg.header.stamp.to_sec() - gen)
        recv.append(r - gen)
        stamps.append(msg.timeStamp)
        sent = feeder.sent.get(msg.timeStamp)
        if sent is None:
            unknown += 1
        elif any(getattr(msg, MSG_OF_FIELD[f]) != getattr(sent, f) for f in FIELDS):
            torn += 1
    generated = sum(1 for w in feeder.times if t0 <= w <= t1)
    late = [lt for w, lt in zip(feeder.times, feeder.lateness) if t0 <= w <= t1]
    # What the interface's own rate limiter (on sample timestamps) lets through of the generated stream:
    # a feeder tick that comes late bunches timestamps, and the limiter rightly drops the too-close ones.
    limiter = GroundTruthInterface(publish_rate=1.0 / feeder.period)
    publishable = 0
    for ts, sample in list(feeder.sent.items()):
        if limiter.on_sample(sample, feeder.epoch + ts) is not None and t0 <= feeder.epoch + ts <= t1:
            publishable += 1
    n = len(recv)

    def pct(values):
        a = np.array(values) * 1e3
        return dict(p50=np.percentile(a, 50), p95=np.percentile(a, 95), p99=np.percentile(a, 99),
                    max=a.max(), n=len(a)) if len(a) else None
    return dict(n=n, rate=n / (t1 - t0), generated=generated, gen_rate=generated / (t1 - t0),
                publishable=publishable, late2ms=sum(1 for lt in late if lt > 0.002),
                late_p99=1e3 * np.percentile(late, 99) if late else float('nan'),
                distinct=len(set(stamps)), torn=torn, unknown=unknown, pub=pct(pub), recv=pct(recv))


def machine_busy(before, after):
    """Busy share of all cores between two psutil.cpu_times() [%]."""
    idle = (after.idle + getattr(after, 'iowait', 0.0)) - (before.idle + getattr(before, 'iowait', 0.0))
    total = sum(after) - sum(before)
    return 100.0 * (1.0 - idle / total) if total > 0 else float('nan')


class Window(object):
    """One measurement window: CPU of some process trees, load, machine busy share."""

    def __init__(self, trees, duration):
        self.trees = trees  # name -> TreeCpu
        self.duration = duration

    def run(self):
        me = psutil.Process()
        self.load_before = os.getloadavg()
        cpu0 = psutil.cpu_times()
        me0 = me.cpu_times()
        for tree in self.trees.values():
            tree.start_window()
        self.t0 = time.time()
        end = self.t0 + self.duration
        while True:
            left = end - time.time()
            if left <= 0:
                break
            time.sleep(min(1.0, left))
            for tree in self.trees.values():
                tree.poll()
        self.t1 = time.time()
        self.cpu = dict((name, tree.end_window()) for name, tree in self.trees.items())
        self.ended = dict((name, tree.ended) for name, tree in self.trees.items())
        me1 = me.cpu_times()
        self.bench_cpu = (me1.user + me1.system) - (me0.user + me0.system)
        self.busy = machine_busy(cpu0, psutil.cpu_times())
        self.load_after = os.getloadavg()
        self.wall = self.t1 - self.t0

    def share(self, name, role=None):
        """CPU [% of one core] of a tree (or one role in it) over the window."""
        per_role = self.cpu[name]
        cpu = sum(v[0] for r, v in per_role.items() if role is None or r == role)
        return 100.0 * cpu / self.wall

    def count(self, name, role=None):
        return sum(v[1] for r, v in self.cpu[name].items() if role is None or r == role)


# ----------------------------------------------------------------------------- parts 2-4
def wait_for(cond, timeout, what, on_fail=None):
    end = time.time() + timeout
    while time.time() < end:
        if cond():
            return
        time.sleep(0.1)
    detail = on_fail() if on_fail else ''
    raise RuntimeError('timed out after %.0f s waiting for %s\n%s' % (timeout, what, detail))


def bench_ros(parts, duration, rate, tcp_nodelay, log):
    """Parts 'interface' and/or 'paper'; returns a dict of results."""
    try:
        import rosgraph
        import rospy
        from anafi_sim.msg import DroneData
    except ImportError as exc:
        raise SystemExit('cannot import ROS / the generated messages (%s): source env.bash (or the catkin '
                         'workspace devel/setup.bash) first' % exc)
    if shutil.which('roscore') is None:
        raise SystemExit('roscore not found on PATH: source env.bash first')
    results = {}
    tmp = tempfile.mkdtemp(prefix='bench_interface_')
    procs = Processes(tmp)
    server = TelemetryServer(host='127.0.0.1', port=0)
    feeder = None
    ros_started = False
    try:
        master_port = free_port()
        uri = 'http://127.0.0.1:%d' % master_port
        env = dict(os.environ)
        env.update(ROS_MASTER_URI=uri, ROS_LOG_DIR=tmp, ROS_HOME=tmp, PYTHONUNBUFFERED='1')
        env['PATH'] = os.path.dirname(sys.executable) + os.pathsep + env.get('PATH', '')
        os.environ.update(ROS_MASTER_URI=uri, ROS_LOG_DIR=tmp, ROS_HOME=tmp)
        log('starting roscore on port %d (logs in %s)' % (master_port, tmp))
        procs.start('roscore', ['roscore', '-p', str(master_port)], env)

        def master_up():
            try:
                rosgraph.Master('/bench_interface', master_uri=uri).getPid()
                return True
            except Exception:
                return False
        wait_for(master_up, 30, 'roscore', lambda: procs.log_tail('roscore'))
        rospy.init_node('bench_interface', disable_signals=True)
        ros_started = True

        port = server.start()
        epoch = float(int(time.time())) - 10.0
        feeder = Feeder(server, flight_samples(3000, seed=2), rate, epoch)
        feeder.start()
        cli = '%s %s -r 0' % (sys.executable, CLI_SCRIPT)

        ours_rx, paper_rx = Recorder(), Recorder()
        rospy.Subscriber('/anafi/sphinx/drone_data', DroneData, ours_rx, queue_size=1000, tcp_nodelay=tcp_nodelay)
        rospy.set_param('/anafi/interface/telemetry_command', '%s inet:127.0.0.1:%d' % (cli, port))
        rospy.set_param('/anafi/interface/rate', float(rate))
        node_env = dict(env, ROS_NAMESPACE='/anafi')
        log('starting interface_node.py (telemetry command: %s inet:127.0.0.1:%d)' % (cli, port))
        node = procs.start('interface', [sys.executable, NODE_SCRIPT, '__name:=interface'], node_env)
        wait_for(lambda: ours_rx.count_since(time.time() - 1.0) > 0.8 * rate, 30, 'interface messages',
                 lambda: procs.log_tail('interface'))
        time.sleep(3.0)  # warm-up
        ours_tree = TreeCpu(node.pid, role_of)

        if 'interface' in parts:
            log('window A: interface alone, %.0f s ...' % duration)
            win = Window({'ours': ours_tree}, duration)
            win.run()
            results['A'] = dict(window=win, ours=analyse(ours_rx.rx, win.t0, win.t1, feeder),
                                clients=server.client_count)
        if 'paper' in parts:
            rospy.Subscriber('/paper/sphinx/drone_data', DroneData, paper_rx, queue_size=1000,
                             tcp_nodelay=tcp_nodelay)
            for k, v in (('cli', cli), ('host', '127.0.0.1'), ('port', port), ('rate', float(rate))):
                rospy.set_param('/paper/paper_interface/' + k, v)
            log('starting paper_interface.py (24 pipelines "%s inet:127.0.0.1:%d | grep --line-buffered KEY")'
                % (cli, port))
            paper = procs.start('paper', [sys.executable, PAPER_SCRIPT, '__name:=paper_interface'],
                                dict(env, ROS_NAMESPACE='/paper'))
            n_keys = len(key_map())
            wait_for(lambda: server.client_count >= 1 + n_keys and paper_rx.rx and paper_rx.rx[-1][1].timeStamp > 0
                     and paper_rx.count_since(time.time() - 1.0) > 0.8 * rate, 60, 'paper pipelines',
                     lambda: procs.log_tail('paper'))
            time.sleep(3.0)
            log('window B: ours and the paper\'s side by side, %.0f s ...' % duration)
            win = Window({'ours': ours_tree, 'paper': TreeCpu(paper.pid, role_of)}, duration)
            win.run()
            results['B'] = dict(window=win, ours=analyse(ours_rx.rx, win.t0, win.t1, feeder),
                                paper=analyse(paper_rx.rx, win.t0, win.t1, feeder), clients=server.client_count)
        results['late_ticks'] = feeder.late
        results['ticks'] = len(feeder.times)
        results['slow_drops'] = server.clients_dropped_slow
    finally:
        if feeder is not None:
            feeder.stop()
        procs.stop_all()
        server.stop()
        if ros_started:
            rospy.signal_shutdown('benchmark done')
        shutil.rmtree(tmp, ignore_errors=True)
    return results


# ----------------------------------------------------------------------------- report
def versions():
    out = ['Python %s' % platform.python_version()]
    try:
        import rospkg
        with open(os.path.join(rospkg.RosPack().get_path('rospy'), 'package.xml')) as f:
            out.append('rospy %s' % re.search(r'<version>([^<]+)</version>', f.read()).group(1))
    except Exception:
        out.append('rospy unknown')
    distro = os.environ.get('ROS_DISTRO', '')
    try:
        deb = subprocess.run(['dpkg-query', '-W', '-f=${Version}', 'ros-core'], stdout=subprocess.PIPE,
                             stderr=subprocess.DEVNULL, universal_newlines=True, timeout=5).stdout.strip()
    except Exception:
        deb = ''
    if deb:
        out.append('ROS 1 %s packages (ros-core %s)' % (distro or 'distribution', deb))
    elif distro:
        out.append('ROS %s' % distro)
    out.append('psutil %s' % psutil.__version__)
    return ', '.join(out)


FEEDER_NOTE = ('- feeder: %d samples generated in the window, %d ticks more than 2 ms late (p99 %.2f ms late); '
               'of them the interface\'s rate limiter (GroundTruthInterface, on the sample timestamps, re-run '
               'here offline) lets %d through: samples bunched by a late tick are dropped by design')


def fmt_lat(d):
    if d is None:
        return '| - | - | - | - | 0 |'
    return '| %.2f | %.2f | %.2f | %.2f | %d |' % (d['p50'], d['p95'], d['p99'], d['max'], d['n'])


def met(ok):
    return 'met' if ok else '**NOT met**'


def report(args, parser_res, ros_res):
    L = []
    L.append('# Ground-truth interface: parser, latency, CPU, and the paper\'s 24 pipelines side by side')
    L.append('')
    L.append('Generated by `benchmarks/bench_interface.py --parts %s --duration %g --rate %g%s`. '
             'CPU: %s, %d logical cores; %s.' % (','.join(args.parts), args.duration, args.rate,
                                                 ' --tcp-nodelay' if args.tcp_nodelay else '',
                                                 cpu_model(), os.cpu_count() or 0, versions()))
    L.append('The machine is shared with other jobs: load and the machine-wide busy share are given per window; '
             'side-by-side figures come from one window, so load hits both alike.')
    L.append('')
    if parser_res is not None:
        o, n = np.array(parser_res['ours']), np.array(parser_res['naive'])
        per_s = args.rate * parser_res['lines_per_sample']
        L.append('## 1. Parser throughput')
        L.append('')
        L.append('Lines = `format_sample` of 2000 samples of a simulated flight plus the blank line ending each '
                 'block (%.0f lines per sample), fed %d lines per round, %d rounds alternating the parsers '
                 '(both checked to return exactly the formatted samples). Naive = a per-line regex '
                 '`^\\s*(\\S+)\\s*:\\s*(\\S+)\\s*$` + dict of values, sample when all 24 keys are in.'
                 % (parser_res['lines_per_sample'], parser_res['n_lines'], parser_res['rounds']))
        L.append('')
        L.append('| parser | lines/s median | lines/s best | us/line (median) | one core at %g Hz [%%] |'
                 % args.rate)
        L.append('|---|---|---|---|---|')
        for name, a in (('TelemetryParser.feed_line (ours)', o), ('naive regex', n)):
            med = np.median(a)
            L.append('| %s | %.0f | %.0f | %.3f | %.3f |' % (name, med, a.max(), 1e6 / med, 100.0 * per_s / med))
        L.append('')
        L.append('- ours / naive: x%.2f (median), x%.2f (best)' % (np.median(o) / np.median(n), o.max() / n.max()))
        L.append('')
    if ros_res and 'A' in ros_res:
        A = ros_res['A']
        w, r = A['window'], A['ours']
        L.append('## 2. End-to-end latency at %g Hz (interface alone)' % args.rate)
        L.append('')
        L.append('Window %.1f s; load average (1 min) %.2f before, %.2f after; machine busy %.0f %% of all cores; '
                 'benchmark process (server + feeder + subscriber) %.1f %% of one core; subscriber '
                 'tcp_nodelay=%s (the ROS default is False).'
                 % (w.wall, w.load_before[0], w.load_after[0], w.busy, 100.0 * w.bench_cpu / w.wall,
                    args.tcp_nodelay))
        L.append('')
        L.append('| latency [ms] | p50 | p95 | p99 | max | n |')
        L.append('|---|---|---|---|---|---|')
        L.append('| generation -> publish (header.stamp - generation) ' + fmt_lat(r['pub']))
        L.append('| generation -> ROS message received ' + fmt_lat(r['recv']))
        L.append('')
        L.append('- published %.2f Hz (generated %.2f Hz); %d messages, %d distinct samples, %d with fields from '
                 'another sample than their timestamp, %d with an unknown timestamp'
                 % (r['rate'], r['gen_rate'], r['n'], r['distinct'], r['torn'], r['unknown']))
        L.append(FEEDER_NOTE % (r['generated'], r['late2ms'], r['late_p99'], r['publishable']))
        p99 = r['recv']['p99'] if r['recv'] else float('inf')
        L.append('- target p99 < 10 ms (generation -> received): %s (%.2f ms)' % (met(p99 < 10.0), p99))
        L.append('')
        L.append('## 3. CPU share of the interface at %g Hz (same window)' % args.rate)
        L.append('')
        L.append('| process | processes | CPU [% of one core] |')
        L.append('|---|---|---|')
        for role, label in (('node', 'interface_node.py'), ('CLI', 'tlm_data_logger.py (its child)')):
            L.append('| %s | %d | %.2f |' % (label, w.count('ours', role), w.share('ours', role)))
        total = w.share('ours')
        L.append('| **total** | %d | **%.2f** |' % (w.count('ours'), total))
        L.append('')
        L.append('- target < 10 %% of one core: %s (%.2f %%)' % (met(total < 10.0), total))
        L.append('- per sample the node also builds ground_truth/odom and one /tf message (3 transforms) and '
                 'publishes /diagnostics at 1 Hz; nothing subscribes to those here, and rospy does not serialise '
                 'messages of a topic without subscribers.')
        L.append('')
    if ros_res and 'B' in ros_res:
        B = ros_res['B']
        w = B['window']
        L.append('## 4. The paper\'s approach side by side (same server, same window)')
        L.append('')
        L.append('Ours: one `tlm_data_logger.py -r 0` + `interface_node.py`. Paper (`benchmarks/paper_interface.py`): '
                 '24 shell pipelines `tlm_data_logger.py -r 0 inet:H:P | grep --line-buffered KEY`, a reader thread '
                 'per pipe keeping the last value, DroneData published from a %g Hz rospy.Timer. CPU = user+sys of '
                 'each whole process tree (polled every second; processes ending keep their CPU up to the last '
                 'poll). Window %.1f s; load average (1 min) %.2f before, %.2f after; machine busy %.0f %% of all '
                 'cores; %d server clients.' % (args.rate, w.wall, w.load_before[0], w.load_after[0], w.busy,
                                                B['clients']))
        L.append('')
        L.append('| implementation | process | processes | CPU [% of one core] |')
        L.append('|---|---|---|---|')
        for role, label in (('node', 'interface_node.py'), ('CLI', 'tlm_data_logger.py')):
            L.append('| ours | %s | %d | %.2f |' % (label, w.count('ours', role), w.share('ours', role)))
        L.append('| **ours** | **total** | %d | **%.2f** |' % (w.count('ours'), w.share('ours')))
        for role, label in (('node', 'paper_interface.py'), ('CLI', 'tlm_data_logger.py'), ('grep', 'grep'),
                            ('sh', 'sh (pipeline shells)')):
            L.append('| paper | %s | %d | %.2f |' % (label, w.count('paper', role), w.share('paper', role)))
        others = [r for r in w.cpu['paper'] if r not in ('node', 'CLI', 'grep', 'sh')]
        for role in others:
            L.append('| paper | %s | %d | %.2f |' % (role, w.count('paper', role), w.share('paper', role)))
        L.append('| **paper** | **total** | %d | **%.2f** |' % (w.count('paper'), w.share('paper')))
        L.append('')
        ratio = w.share('paper') / w.share('ours') if w.share('ours') > 0 else float('inf')
        L.append('- paper / ours CPU: **x%.1f**; target >= x5: %s' % (ratio, met(ratio >= 5.0)))
        ours_wo = w.share('ours') - w.share('ours', 'CLI')
        paper_wo = w.share('paper') - w.share('paper', 'CLI')
        L.append('- without the CLI processes (as if the telemetry CLI cost nothing, e.g. a cheaper native '
                 'tlm-data-logger): paper %.2f %% / ours %.2f %% = x%.1f'
                 % (paper_wo, ours_wo, paper_wo / ours_wo if ours_wo > 0 else float('inf')))
        L.append('- processes that ended during the window: ours %d, paper %d' % (w.ended['ours'], w.ended['paper']))
        L.append('')
        L.append('| latency [ms], same window | p50 | p95 | p99 | max | n |')
        L.append('|---|---|---|---|---|---|')
        L.append('| ours: generation -> received ' + fmt_lat(B['ours']['recv']))
        L.append('| paper: generation of its timeStamp -> received ' + fmt_lat(B['paper']['recv']))
        L.append('')
        L.append('- window B ' + FEEDER_NOTE[2:] % (B['ours']['generated'], B['ours']['late2ms'], B['ours']['late_p99'],
                                                 B['ours']['publishable']))
        for name in ('ours', 'paper'):
            r = B[name]
            L.append('- %s: %.2f Hz published, %d messages, %d distinct timestamps, %d (%.1f %%) mixing fields of '
                     'different samples (lower bound: fields equal in consecutive samples cannot show it)'
                     % (name, r['rate'], r['n'], r['distinct'], r['torn'], 100.0 * r['torn'] / max(r['n'], 1)))
        L.append('')
    if ros_res:
        L.append('Feeder: %d samples published, %d ticks more than 2 ms late; slow clients dropped by the '
                 'server: %d.' % (ros_res['ticks'], ros_res['late_ticks'], ros_res['slow_drops']))
        L.append('')
    return '\n'.join(L)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--parts', default=','.join(PARTS), help='comma list of %s' % ', '.join(PARTS))
    ap.add_argument('--duration', type=float, default=30.0, help='measurement window per part [s] (>= 30 for the '
                                                                  'committed figures)')
    ap.add_argument('--rate', type=float, default=100.0, help='telemetry and publish rate [Hz]')
    ap.add_argument('--tcp-nodelay', action='store_true',
                    help='subscribe with tcp_nodelay=True (default: the ROS default, False: Nagle on the publisher)')
    ap.add_argument('--no-write', action='store_true', help='print only, do not write %s' % RESULTS)
    args = ap.parse_args(argv)
    args.parts = [p.strip() for p in args.parts.split(',') if p.strip()]
    bad = [p for p in args.parts if p not in PARTS]
    if bad or not args.parts:
        ap.error('unknown part(s) %s; choose from %s' % (bad, ', '.join(PARTS)))
    if not (args.duration > 0 and args.rate > 0):
        ap.error('--duration and --rate must be > 0')

    def log(text):
        sys.stderr.write('[bench_interface] %s\n' % text)
        sys.stderr.flush()

    # Ctrl-C raises KeyboardInterrupt; make SIGTERM do the same so the finally blocks clean up.
    def _terminate(signum, frame):
        raise KeyboardInterrupt('SIGTERM')
    signal.signal(signal.SIGTERM, _terminate)
    parser_res = ros_res = None
    try:
        if 'parser' in args.parts:
            log('parser throughput ...')
            parser_res = bench_parser()
        if 'interface' in args.parts or 'paper' in args.parts:
            ros_res = bench_ros(args.parts, args.duration, args.rate, args.tcp_nodelay, log)
    except KeyboardInterrupt:
        log('interrupted: every process started was stopped; nothing written')
        return 130
    text = report(args, parser_res, ros_res)
    print(text)
    if not args.no_write:
        os.makedirs(os.path.dirname(RESULTS), exist_ok=True)
        with open(RESULTS, 'w') as f:
            f.write(text + '\n')
        log('wrote %s' % RESULTS)
    return 0


if __name__ == '__main__':
    sys.exit(main())
