#!/usr/bin/env python3
"""Soak benchmark (not a test): the demo graph for a long time, sampled every minute.

Graph, on a private ROS master at real time under simulation time (rtf 1): world.launch (kinematic world,
simulated Anafi, ground-truth interface at 100 Hz, Gazebo mirror) + mpc.launch + the trajectory generator
flying the circle scenario again and again (``restart`` on every trajectory/end) + rosbag record of the
demo's topics. Every ``--period`` s of wall time (default 60) one row: per node RSS [MB] and CPU [%] of one
core over the period (psutil), the rates [Hz] of ground_truth/odom, drone/odom, drone/rpyt and the
waypoints seen by this script, the interface's counters (published, parse errors, restarts) and the
controller's (cycles, holds, silent). At the end: RSS growth first -> last row per node, the bag's message
counts vs what the interface says it published meanwhile (drops), and every node still alive.

Writes benchmarks/results/soak.md (table + summary) and soak.json. Run (inside env.bash), e.g. in the
background at low priority:

    nice -n 10 python benchmarks/soak.py --minutes 30 [--period 60] [--scenario circle_r2_v1]
"""
import argparse
import datetime
import json
import os
import platform
import shutil
import sys
import tempfile
import threading
import time

import psutil

from anafi_sim import processes
from anafi_sim.mission.fleet import launch_document
from anafi_sim.numeric import fmt

BENCH = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(BENCH, 'results')
DRONE = 'anafi'
NODES = ('/gazebo', '/anafi/anafi_sim', '/anafi/interface', '/anafi/gazebo_mirror', '/anafi/mpc_controller',
         '/anafi/trajectory_generator', '/anafi/recorder')
RATE_TOPICS = (('ground_truth/odom', 'nav_msgs/Odometry'), ('drone/odom', 'nav_msgs/Odometry'),
               ('drone/rpyt', None), ('position_control/waypoint', 'anafi_sim/Waypoint'))
BAG_TOPICS = ('position_control/waypoint', 'drone/odom', 'ground_truth/odom', 'drone/rpyt', 'mpc/stats')

def launch_text(scenario, bag, telemetry_port):
    """The soak graph: world.launch + mpc.launch, the trajectory generator looping ``scenario``, the recorder."""
    body = ['  <group ns="%s">' % DRONE,
            '    <node pkg="anafi_sim" type="trajectory_generator.py" name="trajectory_generator" output="log">',
            '      <param name="scenario" value="%s"/>' % scenario,
            '      <param name="autostart" value="true"/>',
            '      <param name="wait_for_flying" value="true"/>',
            '    </node>',
            '    <node pkg="anafi_sim" type="record_bag.py" name="recorder" output="log"',
            '          args="-O %s %s"/>' % (bag, ' '.join('/%s/%s' % (DRONE, t) for t in BAG_TOPICS)),
            '  </group>']
    return launch_document([('world.launch', [('drone_name', DRONE), ('rtf', '1.0'), ('use_sim_time', 'true'),
                                              ('telemetry_port', telemetry_port)]),
                            ('mpc.launch', [('drone_name', DRONE), ('output', 'log')])], body)

# interface / controller diagnostic values reported per row (diagnostic key -> column)
INTERFACE_VALUES = (('samples published', 'gt_published'), ('parse malformed', 'gt_malformed'),
                    ('process restarts', 'gt_restarts'), ('rejected non-finite samples', 'gt_nonfinite'))
CONTROLLER_VALUES = (('cycles', 'mpc_cycles'), ('hold', 'mpc_hold'), ('silent', 'mpc_silent'),
                     ('solver_failed', 'mpc_solver_failed'))


class Watcher(object):
    """This script's rospy side: message counts per topic, the latest diagnostics, restarts of the scenario."""

    def __init__(self):
        import rospy
        from diagnostic_msgs.msg import DiagnosticArray
        from std_msgs.msg import Header, String
        self.rospy = rospy
        rospy.init_node('soak_watcher', anonymous=True, disable_signals=True)
        self.lock = threading.Lock()
        self.counts = dict((t, 0) for t, _ in RATE_TOPICS)
        self.diag = {}
        self.laps = 0
        self.subs = []
        for topic, _ in RATE_TOPICS:
            self.subs.append(rospy.Subscriber('/%s/%s' % (DRONE, topic), rospy.AnyMsg, self._count, topic))
        self.subs.append(rospy.Subscriber('/diagnostics', DiagnosticArray, self._diag))
        self.cmd = rospy.Publisher('/%s/trajectory_generator/command' % DRONE, String, queue_size=1, latch=False)
        self.subs.append(rospy.Subscriber('/%s/trajectory/end' % DRONE, Header, self._end))

    def _count(self, _msg, topic):
        with self.lock:
            self.counts[topic] += 1

    def _diag(self, msg):
        with self.lock:
            for s in msg.status:
                self.diag[s.name] = (s.level, s.message, dict((kv.key, kv.value) for kv in s.values))

    def _end(self, _msg):
        from std_msgs.msg import String
        self.laps += 1
        threading.Timer(2.0, lambda: self.cmd.publish(String('restart'))).start()

    def snapshot(self):
        with self.lock:
            return dict(self.counts), dict(self.diag), self.laps

    def close(self):
        self.rospy.signal_shutdown('soak done')


def find_diag(diag, node):
    """The diagnostics entry of ``node`` (its status name starts with 'node:' or ends with ': node')."""
    for name, value in diag.items():
        if name.startswith(node + ':') or name.endswith(': ' + node):
            return value
    return None


def value_of(entry, key):
    if entry is None:
        return None
    v = entry[2].get(key)
    try:
        return int(float(v))
    except (TypeError, ValueError):
        return None


def start_graph(procs, workdir, scenario, bag):
    """Private master + the soak graph (``launch_text``); returns the master's URI once every node of NODES is up."""
    uri, env = processes.private_master(procs, os.path.join(workdir, 'ros_home'), os.path.join(workdir, 'log'),
                                        join=True)
    port = int(uri.rsplit(':', 1)[1])
    launch = os.path.join(workdir, 'soak.launch')
    with open(launch, 'w') as f:
        f.write(launch_text(scenario, bag, processes.free_port()))
    procs.start('roslaunch', ['roslaunch', '--port', str(port), launch], env)
    if not processes.wait_for(lambda: all(processes.node_pid(n, uri) for n in NODES), 120.0, 0.5):
        missing = [n for n in NODES if not processes.node_pid(n, uri)]
        raise SystemExit('nodes did not come up: %s\n%s' % (missing, procs.log_tail('roslaunch', 40)))
    return uri


class Sampler(object):
    """One row per call of ``row``: per node RSS, CPU and liveness (psutil), topic rates, real-time factor and the
    interface's and controller's counters since the previous row."""

    def __init__(self, watcher, uri):
        self.watcher = watcher
        self.ps = dict((n, psutil.Process(processes.node_pid(n, uri))) for n in NODES)
        for p in self.ps.values():
            p.cpu_percent(None)
        self.counts, _, _ = watcher.snapshot()
        self.sim = watcher.rospy.get_time()
        self.t0 = self.wall = time.time()

    def row(self):
        now = time.time()
        counts, diag, laps = self.watcher.snapshot()
        row = {'t_min': (now - self.t0) / 60.0, 'laps': laps, 'rss_mb': {}, 'cpu_pct': {}, 'alive': {}}
        for n, p in self.ps.items():
            try:
                row['rss_mb'][n] = p.memory_info().rss / 1e6
                row['cpu_pct'][n] = p.cpu_percent(None)
                row['alive'][n] = p.is_running() and p.status() != psutil.STATUS_ZOMBIE
            except psutil.Error:
                row['rss_mb'][n] = row['cpu_pct'][n] = None
                row['alive'][n] = False
        row['rate_hz'] = dict((t, (counts[t] - self.counts[t]) / (now - self.wall)) for t in counts)
        sim = self.watcher.rospy.get_time()
        row['rtf'] = (sim - self.sim) / (now - self.wall)     # simulation s per wall s (target 1)
        self.counts, self.wall, self.sim = counts, now, sim
        gi = find_diag(diag, '/%s/interface' % DRONE)
        gc = find_diag(diag, '/%s/mpc_controller' % DRONE)
        for key, col in INTERFACE_VALUES:
            row[col] = value_of(gi, key)
        for key, col in CONTROLLER_VALUES:
            row[col] = value_of(gc, key)
        row['gt_level'] = None if gi is None else gi[0]
        row['mpc_level'] = None if gc is None else gc[0]
        return row


def bag_figures(bag):
    """(message count per topic, the ground truth's stamp gaps) of the recorded bag; an unreadable bag (one that
    did not close) is a finding: ({'error': ...}, None)."""
    try:
        import rosbag
        with rosbag.Bag(bag) as b:
            info = b.get_type_and_topic_info().topics
            return (dict((t, info[t].message_count) for t in info),
                    stamp_gaps(b, '/%s/ground_truth/odom' % DRONE, 0.01))
    except Exception as exc:
        return {'error': '%s: %s' % (type(exc).__name__, exc)}, None


def soak(args, workdir, bag):
    """Run the graph for ``args.minutes``: (rows, interface samples published at the end, nodes alive at the end)."""
    procs = processes.Processes(workdir, grace=20.0)
    rows = []
    watcher = None
    try:
        uri = start_graph(procs, workdir, args.scenario, bag)
        watcher = Watcher()
        sampler = Sampler(watcher, uri)
        end = sampler.t0 + 60.0 * args.minutes
        print('[soak] running %.0f min, a row every %.0f s (work dir %s)' % (args.minutes, args.period, workdir))
        sys.stdout.flush()
        while time.time() < end:
            time.sleep(max(0.0, min(args.period, end - time.time())))
            row = sampler.row()
            rows.append(row)
            print('[soak] %5.1f min  gt %.1f Hz  rpyt %.1f Hz  RSS %s' % (
                row['t_min'], row['rate_hz']['ground_truth/odom'], row['rate_hz']['drone/rpyt'],
                ' '.join('%s %.0f' % (n.rsplit('/', 1)[1], v) for n, v in row['rss_mb'].items() if v)))
            sys.stdout.flush()
        _, diag, _ = watcher.snapshot()
        published_end = value_of(find_diag(diag, '/%s/interface' % DRONE), 'samples published')
        alive = dict((n, bool(processes.node_pid(n, uri))) for n in NODES)
    finally:
        if watcher is not None:
            watcher.close()
        procs.stop_all()
    return rows, published_end, alive


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--minutes', type=float, default=30.0)
    ap.add_argument('--period', type=float, default=60.0, help='s wall between rows')
    ap.add_argument('--scenario', default='circle_r2_v1')
    ap.add_argument('--out', default=os.path.join(RESULTS, 'soak'), help='output base (.md, .json)')
    ap.add_argument('--keep', action='store_true', help='keep the work directory (bag, logs)')
    args = ap.parse_args(argv)
    workdir = tempfile.mkdtemp(prefix='anafi_soak_')
    bag = os.path.join(workdir, 'soak.bag')
    started = datetime.datetime.utcnow()
    rows, published_end, alive = soak(args, workdir, bag)
    bag_counts, gaps = bag_figures(bag)
    result = {'date': started.strftime('%Y-%m-%d %H:%M UTC'), 'minutes': args.minutes, 'period_s': args.period,
              'scenario': args.scenario, 'machine': '%s, %d cores' % (platform.machine(), os.cpu_count() or 0),
              'rows': rows, 'bag_counts': bag_counts, 'gaps': gaps, 'published_end': published_end, 'alive_end': alive}
    with open(args.out + '.json', 'w') as f:
        json.dump(result, f, indent=1, sort_keys=True)
    with open(args.out + '.md', 'w') as f:
        f.write(markdown(result))
    print(markdown(result))
    if not args.keep:
        shutil.rmtree(workdir, ignore_errors=True)
    return 0


def stamp_gaps(bag, topic, period):
    """Samples missing in ``topic`` of ``bag`` by its header stamps (simulation time, one sample per ``period``
    s): {'messages', 'missing', 'largest_gap_s', 'span_s'}."""
    missing, largest, prev, first, n = 0, 0.0, None, None, 0
    for _, msg, _ in bag.read_messages(topics=[topic]):
        t = msg.header.stamp.to_sec()
        n += 1
        if prev is not None:
            dt = t - prev
            largest = max(largest, dt)
            if dt > 1.5 * period:
                missing += int(round(dt / period)) - 1
        else:
            first = t
        prev = t
    return {'messages': n, 'missing': missing, 'largest_gap_s': largest,
            'span_s': 0.0 if prev is None else prev - first}


def markdown(r):
    rows = r['rows']
    nodes = [n for n in NODES if rows and n in rows[0]['rss_mb']]
    short = [n.rsplit('/', 1)[1] for n in nodes]
    out = ['# Soak: the demo graph for %.0f min' % r['minutes'], '',
           'Generated by `benchmarks/soak.py` on %s (%s): world.launch (kinematic world, simulated Anafi, '
           'interface at 100 Hz, Gazebo mirror) + mpc.launch + the trajectory generator flying `%s` in a loop '
           '+ rosbag record, real time under simulation time, started with `nice -n 10` on a machine shared with '
           'other jobs. One row per %.0f s of wall time: RSS [MB] and CPU [%% of one core] per node, the achieved '
           'real-time factor (simulation s per wall s; the rates scale with it), the rates this script received '
           '[Hz, wall], the interface\'s and the controller\'s counters (totals).'
           % (r['date'], r['machine'], r['scenario'], r['period_s']), '']
    head = ['min', 'laps'] + ['RSS %s' % s for s in short] + ['CPU %s' % s for s in short] + [
        'rtf', 'gt Hz', 'odom Hz', 'rpyt Hz', 'wp Hz', 'gt published', 'gt malformed', 'gt restarts', 'mpc cycles',
        'mpc hold', 'mpc silent']
    out.append('| ' + ' | '.join(head) + ' |')
    out.append('|' + '---|' * len(head))
    for row in rows:
        cells = ['%.1f' % row['t_min'], str(row['laps'])]
        cells += [fmt(row['rss_mb'].get(n), 0) for n in nodes]
        cells += [fmt(row['cpu_pct'].get(n), 0) for n in nodes]
        cells += [fmt(row['rtf'], 2)] + [fmt(row['rate_hz'][t], 1) for t, _ in RATE_TOPICS]
        cells += [fmt(row[c], 0) for c in ('gt_published', 'gt_malformed', 'gt_restarts', 'mpc_cycles',
                                           'mpc_hold', 'mpc_silent')]
        out.append('| ' + ' | '.join(cells) + ' |')
    out += ['', '## Summary', '']
    if len(rows) >= 2:
        for n, s in zip(nodes, short):
            a, b = rows[0]['rss_mb'].get(n), rows[-1]['rss_mb'].get(n)
            if a and b:
                out.append('- RSS %s: %.1f MB -> %.1f MB (%+.1f MB over %.0f min)' % (s, a, b, b - a,
                                                                                     rows[-1]['t_min'] - rows[0]['t_min']))
        rates = [row['rate_hz']['ground_truth/odom'] for row in rows]
        out.append('- ground_truth/odom received by this script: min %.1f Hz, max %.1f Hz per row'
                   % (min(rates), max(rates)))
        rtfs = [row['rtf'] for row in rows]
        out.append('- achieved real-time factor: min %.2f, max %.2f per row (below 1: the machine did not keep up; '
                   'the 100 Hz of simulation time then arrive as fewer Hz of wall time)' % (min(rtfs), max(rtfs)))
    out.append('- nodes alive at the end: %s' % ', '.join('%s %s' % (n, 'yes' if v else 'NO')
                                                        for n, v in sorted(r['alive_end'].items())))
    bc = r['bag_counts']
    out.append('- bag message counts: %s' % ', '.join('%s %s' % (t, c) for t, c in sorted(bc.items())))
    g = r.get('gaps')
    if g:
        out.append('- drops in the recording chain (interface -> rosbag), from the bag\'s ground_truth/odom stamps '
                   '(simulation time, one sample per 0.01 s): %d messages over %.1f s of simulation time, %d samples '
                   'missing, largest gap %.3f s' % (g['messages'], g['span_s'], g['missing'], g['largest_gap_s']))
    if r['published_end']:
        out.append('- the interface\'s own count at its last diagnostics: %d samples published (from its start, '
                   'before the recorder subscribed; diagnostics lag up to 1 s)' % r['published_end'])
    out.append('')
    return '\n'.join(out)


if __name__ == '__main__':
    sys.exit(main())
