#!/usr/bin/env python3
"""straight_line.py's worker: the rospy client that flies the straight-line scenario on a running master and
measures the tracking error (started by straight_line_run.RosRun, one process per speed).

The drone climbs to (0, 0, 7) and hovers (static waypoint), then the target starts there and moves along
+x at ``--speed`` (waypoint (v t, 0, 7, v, 0, 0, yaw 0) at 10 Hz of simulated time). After ``--settle`` s
the error is measured for ``--measure`` s: each estimate (drone/odom) and ground-truth (ground_truth/odom)
sample, taken at its header stamp, against the waypoint published last before that stamp. With
``--cpu-nodes`` also the CPU time of those nodes over the window. Writes a JSON dict to ``--out``.
"""
import argparse
import bisect
import json
import math
import sys
import threading
import time

from anafi_sim import processes
from anafi_sim.numeric import summary_stats

ALTITUDE = 7.0
GARBAGE_LIMIT = 1.0e4      # m: a coordinate beyond this is a logging artefact (cf. z_anafi = 65280)
CALLER = '/straight_line_benchmark'


def stats(values):
    """{'n', 'mean', 'std', 'min', 'max'} of the values (NaN figures when there are none)."""
    return summary_stats(values) or {'n': 0, 'mean': float('nan'), 'max': float('nan'), 'std': float('nan')}


def pair_with_waypoints(samples, sent, t0, t1):
    """Rows (stamp, x, y, z, wx, wy, wz, lag): each sample stamped within [t0, t1] against the waypoint
    published last before its stamp (the sample's simulated time), as the paper's logs pair them."""
    sent_times = [w[0] for w in sent]
    rows = []
    for stamp, x, y, z, lag in samples:
        i = bisect.bisect_right(sent_times, stamp) - 1
        if t0 <= stamp <= t1 and i >= 0:
            rows.append((stamp, x, y, z, sent[i][1], sent[i][2], sent[i][3], lag))
    return rows


def error_figures(rows, speed, t_start):
    """Statistics of the tracking error of paired rows; ``e_continuous_target`` against the target's exact
    position at the sample time (not the last 10 Hz waypoint), for reference."""
    e = [math.sqrt((wx - x) ** 2 + (wy - y) ** 2 + (wz - z) ** 2) for _, x, y, z, wx, wy, wz, _ in rows]
    e_cont = [math.sqrt((speed * (t - t_start) - x) ** 2 + y ** 2 + (ALTITUDE - z) ** 2)
              for t, x, y, z, _, _, _, _ in rows]
    return {'e': stats(e), 'e_continuous_target': stats(e_cont),
            'ex': stats([wx - x for _, x, _, _, wx, _, _, _ in rows]),
            'ey': stats([wy - y for _, _, y, _, _, wy, _, _ in rows]),
            'ez': stats([wz - z for _, _, _, z, _, _, wz, _ in rows]),
            'delivery_lag': stats([r[7] for r in rows])}


class Flight(object):
    """The rospy side of one run: odometry recorded while ``recording``, the waypoint of ``target`` at 10 Hz."""

    def __init__(self, drone):
        import rospy
        from nav_msgs.msg import Odometry
        from std_msgs.msg import String

        from anafi_sim.msg import Waypoint

        self.rospy, self.Waypoint = rospy, Waypoint
        self.ns = '/%s/' % drone
        self.lock = threading.Lock()
        self.last = {}
        self.target = None
        self.sent = []                  # (publish time, x, y, z) of every waypoint sent [sim s, m]
        self.rec = {'est': [], 'truth': []}
        self.recording = False
        self.garbage = {'est': 0, 'truth': 0}
        self.state = None
        rospy.Subscriber(self.ns + 'drone/odom', Odometry, self.on_odom, callback_args='est', queue_size=50)
        rospy.Subscriber(self.ns + 'ground_truth/odom', Odometry, self.on_odom, callback_args='truth',
                         queue_size=200)
        rospy.Subscriber(self.ns + 'drone/state', String, lambda m: setattr(self, 'state', m.data))
        self.pub = rospy.Publisher(self.ns + 'position_control/waypoint', Waypoint, queue_size=5)

    def on_odom(self, msg, key):
        p = msg.pose.pose.position
        t = self.rospy.get_time()
        stamp = msg.header.stamp.to_sec()
        with self.lock:
            self.last[key] = (t, p.x, p.y, p.z)
            if not self.recording:
                return
            if not all(math.isfinite(v) and abs(v) < GARBAGE_LIMIT for v in (p.x, p.y, p.z)):
                self.garbage[key] += 1
                return
            self.rec[key].append((stamp, p.x, p.y, p.z, t - stamp))

    def set_target(self, function):
        with self.lock:
            self.target = function

    def publish(self, event):
        rospy = self.rospy
        t = rospy.get_time()
        with self.lock:
            f = self.target
        wp = None if f is None else f(t)
        if wp is None:
            return
        msg = self.Waypoint()
        msg.header.stamp = rospy.Time.from_sec(t)
        msg.header.frame_id = 'world'
        msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz, msg.yaw = wp
        try:
            self.pub.publish(msg)
        except rospy.ROSException:       # shutting down
            return
        with self.lock:
            self.sent.append((t, wp[0], wp[1], wp[2]))

    def wait_sim(self, seconds):
        t_end = self.rospy.get_time() + seconds
        processes.require(lambda: self.rospy.get_time() >= t_end, 60.0 + 3.0 * seconds,
                          '%.0f s of simulated time' % seconds, step=0.05)

    def start(self):
        """Wait for the simulator, both odometries, the flying state and the controller; start the waypoints."""
        rospy = self.rospy
        for pred, what in ((lambda: rospy.get_time() > 0.0, '/clock (simulator)'),
                           (lambda: 'est' in self.last and 'truth' in self.last, 'drone/odom and ground_truth/odom'),
                           (lambda: self.state == 'flying', 'the drone to fly (drone/state)')):
            processes.require(pred, 120.0, what, step=0.05)
        check_graph(self.ns)
        rospy.Timer(rospy.Duration(0.1), self.publish)

    def hover(self, timeout=40.0):
        """Climb to (0, 0, ALTITUDE) and hover until 2 s within 0.15 m (or ``timeout`` s of simulated time)."""
        rospy = self.rospy
        hover = (0.0, 0.0, ALTITUDE, 0.0, 0.0, 0.0, 0.0)
        self.set_target(lambda t: hover)
        t_climb = rospy.get_time()
        settled_since = [None]

        def hovering():
            with self.lock:
                _, x, y, z = self.last['est']
            near = math.sqrt(x * x + y * y + (z - ALTITUDE) ** 2) < 0.15
            now = rospy.get_time()
            if not near:
                settled_since[0] = None
            elif settled_since[0] is None:
                settled_since[0] = now
            return (settled_since[0] is not None and now - settled_since[0] >= 2.0) or now - t_climb > timeout

        processes.require(hovering, 200.0, 'hover at (0, 0, 7)', step=0.05)


def worker(opts):
    """Fly the scenario on the running master; write a JSON dict of results to opts.out."""
    import rospy
    rospy.init_node(CALLER[1:], disable_signals=True)
    flight = Flight(opts.drone)
    wall0 = time.time()
    flight.start()
    flight.hover()
    v = opts.speed
    t_s = rospy.get_time()
    flight.set_target(lambda t: (v * (t - t_s), 0.0, ALTITUDE, v, 0.0, 0.0, 0.0))
    with flight.lock:
        flight.recording = True
    flight.wait_sim(opts.settle)
    cpu0 = processes.cpu_snapshot(node_pids(opts.cpu_nodes)) if opts.cpu_nodes else None
    t_m0, wall_m0 = rospy.get_time(), time.time()
    flight.wait_sim(opts.measure)
    t_m1, wall_m1 = rospy.get_time(), time.time()
    cpu1 = processes.cpu_snapshot(node_pids(opts.cpu_nodes)) if opts.cpu_nodes else None
    flight.wait_sim(1.0)              # samples stamped inside the window that are still in flight
    with flight.lock:
        flight.recording = False
    result = {'speed': v, 'settle': opts.settle, 'measure_sim': t_m1 - t_m0, 'measure_wall': wall_m1 - wall_m0,
              'rtf_achieved': (t_m1 - t_m0) / max(wall_m1 - wall_m0, 1e-9), 'wall_total': time.time() - wall0,
              'garbage': flight.garbage}
    for key in ('est', 'truth'):
        result[key] = error_figures(pair_with_waypoints(flight.rec[key], flight.sent, t_m0, t_m1), v, t_s)
    if cpu0 is not None:
        result['cpu'] = processes.cpu_delta(cpu0, cpu1)
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
        pubs, _, _ = rosgraph.Master(CALLER).getSystemState()
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
    pids = {}
    for name in node_names:
        pid = processes.node_pid(name, caller=CALLER)
        if pid is None:
            raise RuntimeError('node %s is not running' % name)
        pids[name] = pid
    return pids


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--out', required=True, help='JSON results file')
    ap.add_argument('--speed', type=float, required=True, help='target speed along +x [m/s]')
    ap.add_argument('--settle', type=float, default=15.0, help='s of tracking before measuring')
    ap.add_argument('--measure', type=float, default=20.0, help='s of measurement')
    ap.add_argument('--drone', default='anafi')
    ap.add_argument('--cpu-nodes', nargs='*', default=None, help='nodes whose CPU time to measure')
    return ap.parse_args(argv)


if __name__ == '__main__':
    worker(parse(sys.argv[1:]))
