#!/usr/bin/env python3
"""Benchmark: the paper's straight-line scenario (Table 3) in closed loop with the simulated Anafi.

For each speed v: a private ROS master (unique port) runs sim.launch under simulated time (rtf x real
time) plus the controller's launch file (``--controller pid`` -> anafi_sim/launch/pid.launch, ``mpc`` ->
mpc.launch, or any ``--launch`` taking the args drone_name, state_topic, output). The drone climbs to
(0, 0, 7) and hovers (static waypoint), then the target starts there and moves along +x at v (waypoint
(v t, 0, 7, v, 0, 0, yaw 0) published at 10 Hz of simulated time, as the paper). After ``--settle`` s
the error is measured for ``--measure`` s:

* e (paper, Table 3): |last published waypoint - drone estimate| (drone/odom, the controller's input),
  one value per estimate message (30 Hz);
* e vs truth: the same against the ground truth (ground_truth/odom of the interface, 100 Hz).

Each sample is taken at its header stamp (simulated time) and paired with the waypoint published
last before that stamp, so a slow delivery on a loaded machine does not bias e.

Samples with non-finite or absurd (> 1e4 m) coordinates are counted as garbage and left out (reported).
Prints a Markdown table next to the paper's rows and writes benchmarks/results/straight_line_<ctrl>.md.

Run (inside the built workspace's environment, venv first on PATH):
    .venv/bin/python benchmarks/straight_line.py --controller pid --speeds 1 2 3 4 5 [--rtf 2]
One speed at a time; everything started is stopped at the end (process group of roslaunch).
``benchmarks/cpu_usage.py`` reuses this harness for the CPU comparison.
"""
import argparse
import bisect
import datetime
import json
import math
import os
import platform
import signal
import socket
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RESULTS = os.path.join(ROOT, 'benchmarks', 'results')

PAPER_TABLE3 = {'pid': (1.32, 2.67, 4.07, 5.32, 7.00), 'mpc': (0.16, 0.36, 0.59, 0.82, 1.41)}
PAPER_SPEEDS = (1.0, 2.0, 3.0, 4.0, 5.0)
ALTITUDE = 7.0
GARBAGE_LIMIT = 1.0e4      # m: a coordinate beyond this is a logging artefact (cf. z_anafi = 65280)

LAUNCH_TEMPLATE = """<launch>
  <include file="$(find anafi_sim)/anafi_sim/launch/sim.launch">
    <arg name="drone_name" value="{drone}"/>
    <arg name="use_sim_time" value="{sim_time}"/>
    <arg name="rtf" value="{rtf}"/>
    <arg name="telemetry_port" value="{telemetry_port}"/>
  </include>
  <include file="{controller_launch}">
    <arg name="drone_name" value="{drone}"/>
    <arg name="state_topic" value="{state_topic}"/>
    <arg name="output" value="log"/>{extra_args}
  </include>
</launch>
"""


# ------------------------------------------------------------------ process management
def free_port(lo=None, hi=None):
    """A free TCP port on localhost: the OS's pick, or the first free one in [lo, hi)."""
    if lo is None:
        s = socket.socket()
        s.bind(('127.0.0.1', 0))
        port = s.getsockname()[1]
        s.close()
        return port
    import random
    candidates = list(range(lo, hi))
    random.shuffle(candidates)
    for port in candidates:
        s = socket.socket()
        try:
            s.bind(('127.0.0.1', port))
            return port
        except OSError:
            continue
        finally:
            s.close()
    raise RuntimeError('no free port in [%d, %d)' % (lo, hi))


def controller_launch_path(args):
    if args.launch:
        return os.path.abspath(args.launch)
    path = os.path.join(ROOT, 'anafi_sim', 'launch', '%s.launch' % args.controller)
    if not os.path.exists(path):
        raise SystemExit('no launch file for controller %r (%s); give --launch' % (args.controller, path))
    return path


class RosRun(object):
    """roslaunch (sim + controller) on a private master; ``env`` points clients at it. Use as a context."""

    def __init__(self, args, workdir):
        self.args = args
        self.workdir = workdir
        self.port = free_port(11400, 11900)
        self.env = dict(os.environ)
        self.env['ROS_MASTER_URI'] = 'http://localhost:%d' % self.port
        self.env['ROS_HOME'] = os.path.join(workdir, 'ros_home')
        self.env['ROS_LOG_DIR'] = os.path.join(workdir, 'ros_log')
        extra = ''.join('\n    <arg name="%s" value="%s"/>' % tuple(a.split(':=', 1)) for a in args.launch_arg)
        self.launch_file = os.path.join(workdir, 'run_%d.launch' % self.port)
        with open(self.launch_file, 'w') as f:
            f.write(LAUNCH_TEMPLATE.format(
                drone=args.drone, sim_time='true' if not args.wall_clock else 'false',
                rtf=1.0 if args.wall_clock else args.rtf, telemetry_port=free_port(),
                controller_launch=controller_launch_path(args), state_topic=args.state_topic,
                extra_args=extra))
        self.proc = None
        self.core = None
        self.log = None

    def __enter__(self):
        self.log = open(os.path.join(self.workdir, 'roslaunch_%d.log' % self.port), 'w')
        self.core = self._own_master()
        self.proc = subprocess.Popen(['roslaunch', '--port', str(self.port), self.launch_file],
                                     stdout=self.log, stderr=subprocess.STDOUT, env=self.env,
                                     start_new_session=True)
        return self

    def __exit__(self, *exc):
        self.stop()

    def _own_master(self):
        """Start roscore on a free port and make sure the master answering there is ours.

        (roslaunch silently joins any master already running on its port: another run's nodes
        with the same names would then be replaced by ours, and the measurements mixed.)"""
        import psutil
        from xmlrpc.client import ServerProxy
        for attempt in range(5):
            core = subprocess.Popen(['roscore', '-p', str(self.port)], stdout=self.log, stderr=subprocess.STDOUT,
                                    env=self.env, start_new_session=True)
            end = time.time() + 20.0
            while time.time() < end and core.poll() is None:
                try:
                    code, _, pid = ServerProxy(self.env['ROS_MASTER_URI']).getPid('/straight_line_benchmark')
                except (OSError, IOError):
                    time.sleep(0.2)
                    continue
                mine = [c.pid for c in psutil.Process(core.pid).children(recursive=True)]
                if code == 1 and pid in mine:
                    return core
                break
            self._stop_process(core)
            self.port = free_port(11400, 11900)
            self.env['ROS_MASTER_URI'] = 'http://localhost:%d' % self.port
        raise RuntimeError('could not start a private ROS master')

    @staticmethod
    def _stop_process(proc):
        """SIGINT, SIGTERM, SIGKILL to ``proc``'s own session (started with start_new_session) and its children."""
        import psutil
        try:       # roslaunch starts each node in its own session: remember them to be sure they end
            children = psutil.Process(proc.pid).children(recursive=True)
        except psutil.Error:
            children = []
        for sig, wait in ((signal.SIGINT, 20.0), (signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
            if proc.poll() is not None:
                break
            try:
                os.killpg(proc.pid, sig)
            except ProcessLookupError:
                break
            try:
                proc.wait(wait)
            except subprocess.TimeoutExpired:
                pass
        try:
            os.killpg(proc.pid, signal.SIGKILL)      # stragglers of that session
        except (ProcessLookupError, PermissionError):
            pass
        for child in children:
            try:
                child.wait(5.0)
            except psutil.TimeoutExpired:
                child.kill()
            except psutil.Error:
                pass

    def stop(self):
        if self.proc is not None:
            self._stop_process(self.proc)
            self.proc = None
        if getattr(self, 'core', None) is not None:
            self._stop_process(self.core)
            self.core = None
        if self.log:
            self.log.close()
            self.log = None

    def run_worker(self, worker_args, timeout):
        """Run this script's worker (a rospy client of the private master); returns its JSON result."""
        out = os.path.join(self.workdir, 'result_%d.json' % self.port)
        cmd = [sys.executable, os.path.abspath(__file__), '--worker', '--out', out] + worker_args
        rc = subprocess.call(cmd, env=self.env, timeout=timeout)
        if rc != 0 or not os.path.exists(out):
            self.log.flush()
            with open(self.log.name) as f:
                tail = f.readlines()[-40:]
            raise RuntimeError('worker failed (exit %d); end of the roslaunch log:\n%s' % (rc, ''.join(tail)))
        with open(out) as f:
            return json.load(f)


# ------------------------------------------------------------------ worker (rospy side)
def stats(values):
    if not values:
        return {'n': 0, 'mean': float('nan'), 'max': float('nan'), 'std': float('nan')}
    mean = sum(values) / len(values)
    var = sum((v - mean) ** 2 for v in values) / len(values)
    return {'n': len(values), 'mean': mean, 'max': max(values), 'std': math.sqrt(var)}


def worker(opts):
    """Fly the scenario on the running master; write a JSON dict of results to opts.out."""
    import threading

    import rospy
    from nav_msgs.msg import Odometry
    from std_msgs.msg import String

    from anafi_sim.msg import Waypoint

    rospy.init_node('straight_line_benchmark', disable_signals=True)
    ns = '/%s/' % opts.drone
    lock = threading.Lock()
    last = {}
    wp_state = {'wp': None}
    sent = []                  # (publish time, x, y, z) of every waypoint sent [sim s, m]
    rec = {'est': [], 'truth': []}
    recording = {'on': False}
    garbage = {'est': 0, 'truth': 0}
    flight = {'state': None}

    def on_odom(msg, key):
        p = msg.pose.pose.position
        t = rospy.get_time()
        stamp = msg.header.stamp.to_sec()
        with lock:
            last[key] = (t, p.x, p.y, p.z)
            if not recording['on']:
                return
            if not all(math.isfinite(v) and abs(v) < GARBAGE_LIMIT for v in (p.x, p.y, p.z)):
                garbage[key] += 1
                return
            rec[key].append((stamp, p.x, p.y, p.z, t - stamp))

    rospy.Subscriber(ns + 'drone/odom', Odometry, on_odom, callback_args='est', queue_size=50)
    rospy.Subscriber(ns + 'ground_truth/odom', Odometry, on_odom, callback_args='truth', queue_size=200)
    rospy.Subscriber(ns + 'drone/state', String, lambda m: flight.__setitem__('state', m.data))
    pub = rospy.Publisher(ns + 'position_control/waypoint', Waypoint, queue_size=5)

    def target(t):
        with lock:
            f = wp_state['wp']
        return None if f is None else f(t)

    def publish(event):
        t = rospy.get_time()
        wp = target(t)
        if wp is None:
            return
        msg = Waypoint()
        msg.header.stamp = rospy.Time.from_sec(t)
        msg.header.frame_id = 'world'
        msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz, msg.yaw = wp
        try:
            pub.publish(msg)
        except rospy.ROSException:       # shutting down
            return
        with lock:
            sent.append((t, wp[0], wp[1], wp[2]))

    def wait(pred, what, wall=120.0):
        end = time.time() + wall
        while time.time() < end:
            if pred():
                return
            time.sleep(0.05)
        raise RuntimeError('timed out waiting for %s' % what)

    def wait_sim(seconds):
        t_end = rospy.get_time() + seconds
        wait(lambda: rospy.get_time() >= t_end, '%.0f s of simulated time' % seconds, wall=60.0 + 3.0 * seconds)

    wall0 = time.time()
    wait(lambda: rospy.get_time() > 0.0, '/clock (simulator)')
    wait(lambda: 'est' in last and 'truth' in last, 'drone/odom and ground_truth/odom')
    wait(lambda: flight['state'] == 'flying', 'the drone to fly (drone/state)')
    check_graph(ns)
    rospy.Timer(rospy.Duration(0.1), publish)

    # climb to (0, 0, 7) and hover
    hover = (0.0, 0.0, ALTITUDE, 0.0, 0.0, 0.0, 0.0)
    with lock:
        wp_state['wp'] = lambda t: hover
    t_climb = rospy.get_time()
    settled_since = [None]

    def hovering():
        with lock:
            _, x, y, z = last['est']
        near = math.sqrt(x * x + y * y + (z - ALTITUDE) ** 2) < 0.15
        now = rospy.get_time()
        if not near:
            settled_since[0] = None
        elif settled_since[0] is None:
            settled_since[0] = now
        return (settled_since[0] is not None and now - settled_since[0] >= 2.0) or now - t_climb > 40.0

    wait(hovering, 'hover at (0, 0, 7)', wall=200.0)

    # the moving target
    v = opts.speed
    t_s = rospy.get_time()
    with lock:
        wp_state['wp'] = lambda t: (v * (t - t_s), 0.0, ALTITUDE, v, 0.0, 0.0, 0.0)
    with lock:
        recording['on'] = True
    wait_sim(opts.settle)
    cpu0 = cpu_snapshot(opts.cpu_nodes) if opts.cpu_nodes else None
    t_m0 = rospy.get_time()
    wall_m0 = time.time()
    wait_sim(opts.measure)
    t_m1 = rospy.get_time()
    wall_m1 = time.time()
    cpu1 = cpu_snapshot(opts.cpu_nodes) if opts.cpu_nodes else None
    wait_sim(1.0)              # samples stamped inside the window that are still in flight
    with lock:
        recording['on'] = False

    result = {'speed': v, 'settle': opts.settle, 'measure_sim': t_m1 - t_m0, 'measure_wall': wall_m1 - wall_m0,
              'rtf_achieved': (t_m1 - t_m0) / max(wall_m1 - wall_m0, 1e-9), 'wall_total': time.time() - wall0,
              'garbage': garbage}
    sent_times = [w[0] for w in sent]
    for key in ('est', 'truth'):
        # each sample (by its header stamp, i.e. the sample's simulated time) against the waypoint
        # published last before it, as the paper's logs pair them
        rows = []
        for stamp, x, y, z, lag in rec[key]:
            i = bisect.bisect_right(sent_times, stamp) - 1
            if t_m0 <= stamp <= t_m1 and i >= 0:
                rows.append((stamp, x, y, z, sent[i][1], sent[i][2], sent[i][3], lag))
        e = [math.sqrt((wx - x) ** 2 + (wy - y) ** 2 + (wz - z) ** 2) for _, x, y, z, wx, wy, wz, _ in rows]
        # the target's exact position at the sample time (not the last 10 Hz waypoint), for reference
        e_cont = [math.sqrt((v * (t - t_s) - x) ** 2 + y ** 2 + (ALTITUDE - z) ** 2) for t, x, y, z, _, _, _, _ in rows]
        result[key] = {'e': stats(e), 'e_continuous_target': stats(e_cont),
                       'ex': stats([wx - x for _, x, _, _, wx, _, _, _ in rows]),
                       'ey': stats([wy - y for _, _, y, _, _, wy, _, _ in rows]),
                       'ez': stats([wz - z for _, _, _, z, _, _, wz, _ in rows]),
                       'delivery_lag': stats([r[7] for r in rows])}
    if cpu0 is not None:
        result['cpu'] = cpu_delta(cpu0, cpu1)
    rospy.signal_shutdown('done')
    with open(opts.out, 'w') as f:
        json.dump(result, f, indent=1)


def check_graph(ns, wall=90.0):
    """Wait until the controller publishes piloting commands; refuse a master shared with another run.

    Exactly one /clock publisher (under simulated time) and exactly one drone/rpyt publisher.
    """
    import rosgraph
    import rospy
    expect = {ns + 'drone/rpyt': 1}
    if rospy.get_param('/use_sim_time', False):
        expect['/clock'] = 1
    end = time.time() + wall
    while True:
        pubs, _, _ = rosgraph.Master('/straight_line_benchmark').getSystemState()
        pubs = dict((topic, nodes) for topic, nodes in pubs)
        counts = dict((topic, len(pubs.get(topic, []))) for topic in expect)
        if any(counts[t] > n for t, n in expect.items()):
            raise RuntimeError('publishers %s (expected %s): not a private run' % (pubs, expect))
        if counts == expect:
            return
        if time.time() > end:
            raise RuntimeError('no controller / simulator up after %.0f s: publishers %s' % (wall, counts))
        time.sleep(0.5)


def node_pids(node_names):
    """{node name: pid} through each node's XML-RPC getPid (works for any launch file's nodes)."""
    from xmlrpc.client import ServerProxy

    import rosgraph
    master = rosgraph.Master('/straight_line_benchmark')
    pids = {}
    for name in node_names:
        try:
            uri = master.lookupNode(name)
        except rosgraph.MasterError:
            raise RuntimeError('node %s is not running' % name)
        code, _, pid = ServerProxy(uri).getPid('/straight_line_benchmark')
        if code != 1:
            raise RuntimeError('getPid failed for %s' % name)
        pids[name] = pid
    return pids


def cpu_snapshot(node_names):
    """{node: (pid, user+system CPU seconds incl. threads)} now."""
    import psutil
    snap = {}
    for name, pid in node_pids(node_names).items():
        t = psutil.Process(pid).cpu_times()
        snap[name] = (pid, t.user + t.system, time.time())
    return snap


def cpu_delta(a, b):
    per_node = {}
    for name in a:
        if name in b and a[name][0] == b[name][0]:
            per_node[name] = b[name][1] - a[name][1]
    return {'per_node': per_node, 'total': sum(per_node.values())}


def launch_nodes(args):
    """Node names (absolute) started by the controller launch file with the run's arguments."""
    cmd = ['roslaunch', '--nodes', controller_launch_path(args), 'drone_name:=' + args.drone,
           'state_topic:=' + args.state_topic] + list(args.launch_arg)
    out = subprocess.check_output(cmd, universal_newlines=True)
    return [line.strip() for line in out.splitlines() if line.strip().startswith('/')]


# ------------------------------------------------------------------ orchestration and report
def run_speed(args, speed, workdir, cpu_nodes=None, measure=None):
    with RosRun(args, workdir) as run:
        worker_args = ['--speed', repr(speed), '--settle', repr(args.settle),
                       '--measure', repr(measure if measure is not None else args.measure),
                       '--drone', args.drone]
        if cpu_nodes:
            worker_args += ['--cpu-nodes'] + list(cpu_nodes)
        time.sleep(2.0)
        result = run.run_worker(worker_args, timeout=900)
    return result


def fmt(x, digits=2):
    return '-' if x is None or (isinstance(x, float) and math.isnan(x)) else ('%.*f' % (digits, x))


def report(args, results):
    ctrl = args.controller
    paper = dict(zip(PAPER_SPEEDS, PAPER_TABLE3.get(ctrl, (None,) * 5)))
    lines = []
    lines.append('# Straight line, %s (paper Table 3)' % ctrl.upper())
    lines.append('')
    lines.append('Generated by `benchmarks/straight_line.py --controller %s --speeds %s --rtf %g --settle %g '
                 '--measure %g%s` on %s (%s, Python %s).'
                 % (ctrl, ' '.join('%g' % s for s in args.speeds), args.rtf, args.settle, args.measure,
                    ''.join(' --launch-arg %s' % a for a in args.launch_arg),
                    datetime.date.today().isoformat(), platform.machine(), platform.python_version()))
    lines.append('')
    lines.append('Scenario: simulated Anafi (sim.launch, simulated time at rtf %g; model anafi_sim/config/'
                 'anafi_model.yaml) + `%s` on the state topic `%s`. Climb to (0, 0, 7), hover, then the '
                 'waypoint (v t, 0, 7, v, 0, 0, yaw 0) at 10 Hz; error measured for %g s after %g s of '
                 'tracking. e = |last waypoint - drone estimate| (the paper\'s metric, 30 Hz samples); '
                 'e truth = the same against the ground truth (100 Hz); each sample is taken at its header '
                 'stamp (simulated time) and paired with the waypoint published last before it. Ratio = '
                 'e / paper. Delivery lag = simulated time between a sample\'s stamp and its reception by '
                 'the benchmark (machine load shows here).'
                 % (args.rtf, os.path.relpath(controller_launch_path(args), ROOT), args.state_topic,
                    args.measure, args.settle))
    lines.append('')
    lines.append('| speed [m/s] | paper e [m] | e mean [m] | ratio | e max [m] | e std [m] | e truth mean [m] '
                 '| along-x lag (est) [m] | cross (y, z) mean [m] | garbage samples | rtf achieved '
                 '| estimate delivery lag [ms sim] |')
    lines.append('|---|---|---|---|---|---|---|---|---|---|---|---|')
    for r in results:
        est, tru = r['est'], r['truth']
        p = paper.get(r['speed'])
        ratio = est['e']['mean'] / p if p else None
        lines.append('| %g | %s | %s | %s | %s | %s | %s | %s | %s / %s | %d | %.2f | %.0f |' % (
            r['speed'], fmt(p), fmt(est['e']['mean']), fmt(ratio), fmt(est['e']['max']), fmt(est['e']['std']),
            fmt(tru['e']['mean']), fmt(est['ex']['mean']), fmt(est['ey']['mean']), fmt(est['ez']['mean']),
            r['garbage']['est'] + r['garbage']['truth'], r['rtf_achieved'],
            1000.0 * est['delivery_lag']['mean']))
    lines.append('')
    lines.append('Row as in Table 3 (mean e [m], 1..5 m/s): paper %s %s; here %s %s.' % (
        ctrl.upper(), ' '.join(fmt(paper.get(s)) for s in PAPER_SPEEDS), ctrl.upper(),
        ' '.join(fmt(next((r['est']['e']['mean'] for r in results if r['speed'] == s), None))
                 for s in PAPER_SPEEDS)))
    within = [abs(r['est']['e']['mean'] / paper[r['speed']] - 1.0) <= 0.25
              for r in results if paper.get(r['speed'])]
    if within:
        lines.append('')
        lines.append('Within 25 %% of the paper: %d of %d speeds.' % (sum(within), len(within)))
    return '\n'.join(lines) + '\n'


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--controller', default='pid', help='pid | mpc (launch file anafi_sim/launch/<name>.launch)')
    ap.add_argument('--launch', default=None, help='controller launch file (default from --controller)')
    ap.add_argument('--launch-arg', action='append', default=[], metavar='NAME:=VALUE',
                    help='extra argument for the controller launch (e.g. mode:=single)')
    ap.add_argument('--speeds', type=float, nargs='+', default=list(PAPER_SPEEDS))
    ap.add_argument('--rtf', type=float, default=2.0,
                    help='real-time factor of the simulation (message latency between the nodes is wall '
                         'time, it counts rtf times in simulated time: keep it modest on a loaded machine)')
    ap.add_argument('--settle', type=float, default=15.0, help='s of tracking before measuring')
    ap.add_argument('--measure', type=float, default=20.0, help='s of measurement')
    ap.add_argument('--state-topic', default='drone/odom')
    ap.add_argument('--drone', default='anafi')
    ap.add_argument('--wall-clock', action='store_true', help='no simulated time (rtf 1, wall clock)')
    ap.add_argument('--no-write', action='store_true')
    ap.add_argument('--output', default=None, help='results file (default benchmarks/results/straight_line_<ctrl>.md)')
    # worker mode (internal)
    ap.add_argument('--worker', action='store_true', help=argparse.SUPPRESS)
    ap.add_argument('--out', help=argparse.SUPPRESS)
    ap.add_argument('--speed', type=float, help=argparse.SUPPRESS)
    ap.add_argument('--cpu-nodes', nargs='*', default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    for a in args.launch_arg:
        if ':=' not in a:
            ap.error('--launch-arg must be NAME:=VALUE, got %r' % a)
    if not args.worker and (args.rtf <= 0 or any(s <= 0 for s in args.speeds)):
        ap.error('--rtf and --speeds must be > 0')
    return args


def main(argv=None):
    args = parse(argv)
    if args.worker:
        worker(args)
        return 0
    results = []
    with tempfile.TemporaryDirectory(prefix='straight_line_') as workdir:
        for speed in args.speeds:
            t0 = time.time()
            r = run_speed(args, speed, workdir)
            results.append(r)
            print('v = %g m/s: e mean %.3f m (estimate), %.3f m (truth); lag along x %.3f m; rtf %.2f; %.0f s wall'
                  % (speed, r['est']['e']['mean'], r['truth']['e']['mean'], r['est']['ex']['mean'],
                     r['rtf_achieved'], time.time() - t0), flush=True)
    text = report(args, results)
    print(text)
    if not args.no_write:
        path = args.output or os.path.join(RESULTS, 'straight_line_%s.md' % args.controller)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, 'w') as f:
            f.write(text)
        print('written %s' % os.path.relpath(path, ROOT))
    return 0


if __name__ == '__main__':
    sys.exit(main())
