#!/usr/bin/env python3
"""Probe run ON THE GAZEBO HOST by tools/two_hosts.sh: what crosses the link, measured where it arrives.

    tools/two_hosts.sh --scenario-file test/ros/experiment_short.yaml -- python test/ros/two_hosts_probe.py --json OUT

Waits for the mirrored models in /gazebo/model_states, records for ~--window s of wall time (after the
drone flies): the interface's /<drone>/ground_truth/odom (published on the Sphinx host, stamped with the
Sphinx host's ROS time at receipt of the telemetry: both namespaces share this machine's clock, so receipt -
stamp is the crossing latency), the mirror's /gazebo/set_model_state (matched to the ground-truth sample it
mirrors by the exact position: lag = its receipt - that sample's stamp), /gazebo/model_states and the
controller's /<drone>/drone/rpyt; then, with --wait-summary, waits for the evaluator's final
/<drone>/evaluation/summary. Writes one JSON dict (see ``report``) and exits 0; 1 when the models never came.
Used by test/ros/test_two_hosts.py (assertions) and benchmarks/bench_two_hosts.py (figures).
"""
import argparse
import json
import sys
import threading
import time

import numpy as np
import rospy
import yaml
from nav_msgs.msg import Odometry
from std_msgs.msg import String

from anafi_sim.processes import wait_for
from anafi_sim import names
from anafi_sim.ros import gazebo_types
from anafi_sim.ros.wire_types import piloting_command_class


def percentiles(values, scale=1e3):
    """{'p50', 'p99', 'max', 'n'} of values (scaled, default s -> ms), None entries when empty."""
    a = np.asarray(values, dtype=float)
    if not len(a):
        return {'p50': None, 'p99': None, 'max': None, 'n': 0}
    return {'p50': round(scale * float(np.percentile(a, 50)), 3), 'p99': round(scale * float(np.percentile(a, 99)), 3),
            'max': round(scale * float(a.max()), 3), 'n': int(len(a))}


class Probe(object):
    def __init__(self, drone):
        self.drone = drone
        self.lock = threading.Lock()
        self.recording = False
        self.gt = []             # (stamp, receipt, position tuple)
        self.sent = []           # (position tuple, receipt)
        self.world = []          # (receipt, drone position or None, camera present)
        self.commands = []       # receipt
        self.names = set()
        self.state = ''
        self.summary = None
        ns = '/' + drone + '/'
        rospy.Subscriber(ns + names.GROUND_TRUTH, Odometry, self.on_gt, queue_size=500, tcp_nodelay=True)
        rospy.Subscriber(names.gazebo(names.SET_MODEL_STATE), gazebo_types.model_state_class(), self.on_set,
                         queue_size=500, tcp_nodelay=True)
        rospy.Subscriber(names.gazebo(names.MODEL_STATES), gazebo_types.model_states_class(), self.on_states,
                         queue_size=50, tcp_nodelay=True)
        rospy.Subscriber(ns + names.COMMAND, piloting_command_class(), self.on_command, queue_size=50)
        rospy.Subscriber(ns + names.DRONE_STATE, String, self.on_state, queue_size=5)
        rospy.Subscriber(ns + names.EVALUATION_SUMMARY, String, self.on_summary, queue_size=5)

    def on_gt(self, msg):
        now = time.time()
        p = msg.pose.pose.position
        with self.lock:
            if self.recording:
                self.gt.append((msg.header.stamp.to_sec(), now, (p.x, p.y, p.z)))

    def on_set(self, msg):
        now = time.time()
        if msg.model_name != self.drone:
            return
        p = msg.pose.position
        with self.lock:
            if self.recording:
                self.sent.append(((p.x, p.y, p.z), now))

    def on_states(self, msg):
        now = time.time()
        models = set(msg.name)
        drone = None
        if self.drone in models:
            p = msg.pose[list(msg.name).index(self.drone)].position
            drone = (p.x, p.y, p.z)
        with self.lock:
            self.names = models
            if self.recording:
                self.world.append((now, drone, self.drone + '_camera' in models))

    def on_command(self, _msg):
        with self.lock:
            if self.recording:
                self.commands.append(time.time())

    def on_state(self, msg):
        self.state = msg.data

    def on_summary(self, msg):
        try:
            summary = yaml.safe_load(msg.data)
        except yaml.YAMLError:
            return
        if isinstance(summary, dict):
            self.summary = summary

    def report(self, window):
        """The figures: ground truth crossing (rate, gaps, latency), mirror (lag, share mirrored, world
        error), commands crossing back, evaluator summary."""
        with self.lock:
            gt, sent, world, commands = list(self.gt), list(self.sent), list(self.world), list(self.commands)
        out = {'window_s': window, 'drone_state': self.state}
        stamps = np.array([g[0] for g in gt])
        out['gt_samples'] = len(gt)
        out['gt_rate_hz'] = round(len(gt) / window, 2)
        span = float(stamps.max() - stamps.min()) if len(stamps) > 1 else 0.0
        out['gt_stamp_rate_hz'] = round((len(stamps) - 1) / span, 2) if span > 0.0 else 0.0   # per s of stamps
        gaps = np.diff(np.sort(stamps)) if len(stamps) > 1 else np.array([])
        out['gt_max_gap_ms'] = round(1e3 * float(gaps.max()), 2) if len(gaps) else None
        out['gt_gaps_over_15ms'] = int((gaps > 0.015).sum()) if len(gaps) else 0
        out['gt_latency_ms'] = percentiles([g[1] - g[0] for g in gt])
        by_position = dict((g[2], g[0]) for g in gt)
        lags = [t - by_position[key] for key, t in sent if key in by_position]
        out['mirror_lag_ms'] = percentiles(lags)
        out['mirrored_share'] = round(len(lags) / float(len(gt)), 4) if gt else 0.0
        out['mirror_rate_hz'] = round(len(sent) / window, 2)
        # world model vs the latest ground truth received before the world state (both on this host)
        errors = []
        receipts = np.array([g[1] for g in gt])
        for t, drone, _ in world:
            if drone is None or not len(receipts):
                continue
            i = int(np.searchsorted(receipts, t)) - 1
            if i >= 0:
                errors.append(float(np.linalg.norm(np.subtract(drone, gt[i][2]))))
        out['world_error_mm'] = percentiles(errors)
        out['world_states'] = len(world)
        out['world_has_drone_and_camera'] = bool(world) and all(d is not None and c for _, d, c in world)
        out['command_rate_hz'] = round(len(commands) / window, 2)
        if len(gt) > 1:
            z = [g[2][2] for g in gt]
            xy = np.array([g[2][:2] for g in gt])
            out['gt_z_range_m'] = round(max(z) - min(z), 3)
            out['gt_z_max_m'] = round(max(z), 3)
            out['gt_xy_span_m'] = round(float(np.ptp(xy, axis=0).max()), 3)
        out['summary'] = self.summary
        out['node_hosts'] = node_hosts()
        return out


def node_hosts():
    """{node name: host of its XML-RPC URI} from the master: which host each node runs on."""
    import rosnode
    try:
        from urllib.parse import urlparse
    except ImportError:   # pragma: no cover
        from urlparse import urlparse
    master = rospy.get_master()
    hosts = {}
    for name in rosnode.get_node_names():
        try:
            code, _, uri = master.lookupNode(name)
        except Exception:   # a node going away meanwhile
            continue
        if code == 1:
            hosts[name] = urlparse(uri).hostname
    return hosts


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--drone', default='anafi')
    ap.add_argument('--window', type=float, default=10.0, help='s of wall time recorded')
    ap.add_argument('--ready-timeout', type=float, default=90.0)
    ap.add_argument('--wait-summary', type=float, default=0.0,
                    help='s to wait for the evaluator final summary after the window (0 = do not)')
    ap.add_argument('--json', default='-', help='output file (- = stdout)')
    args = ap.parse_args(rospy.myargv(argv)[1:] if argv is None else argv)
    rospy.init_node('two_hosts_probe', anonymous=True, disable_signals=True)
    probe = Probe(args.drone)
    models = {args.drone, args.drone + '_camera'}
    ready = wait_for(lambda: models <= probe.names and probe.state == 'flying', args.ready_timeout)
    if not ready:
        sys.stderr.write('two_hosts_probe: models %s / drone state %r not there after %.0f s (saw %s)\n'
                         % (sorted(models), probe.state, args.ready_timeout, sorted(probe.names)))
        return 1
    with probe.lock:
        probe.recording = True
    time.sleep(args.window)
    with probe.lock:
        probe.recording = False
    if args.wait_summary > 0:
        wait_for(lambda: (probe.summary or {}).get('state') == 'final', args.wait_summary)
    text = json.dumps(probe.report(args.window), indent=1, sort_keys=True)
    if args.json == '-':
        print(text)
    else:
        with open(args.json, 'w') as f:
            f.write(text + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
