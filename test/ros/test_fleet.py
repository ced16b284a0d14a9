#!/usr/bin/env python3
"""rostest (fleet.test): three drones in one kinematic world, started by fleet.launch from fleet_three.yaml.

The test starts ``roslaunch anafi_sim fleet.launch fleet:=~fleet [layout:=~layout] evaluate:=false`` on the
test's master with out_dir in a tempfile folder of its own, and stops it (with every process it started) and
removes the folder at the end. Checks:

1. /gazebo/model_states holds the 3 x 2 models of the fleet (<name>, <name>_camera), and no other drone model;
2. each drone reaches its own waypoint (the fleet file's, shifted by its offset: ground truth within 0.3 m
   and 10 deg, held for 2 s), and the world's model <name> is there too (the mirror of each drone moves its
   own model);
3. no topic of one drone's namespace reaches another drone's nodes: through the master's system state,
   every node under /<a>/ publishes and subscribes only topics under /<a>/ or shared ones (/diagnostics,
   /rosout, /tf, /tf_static, /clock, /gazebo/...), and every topic under /<a>/ has only /<a>/ nodes at
   both ends; each drone's chain is complete (simulator, interface, mirror, controller, generator).
   In the shared layout (fleet_shared.test, ~layout shared) the master sees the fleet hosts' ends: each
   host's ~wiring says which instance uses which topic, and those instances are checked as nodes.
4. a fleet file that splits the ground-truth host (drones_per_host, fleet_three_split.yaml): each mirror in
   the host of its group, the world in the first (1. and 2. checked every drone's models in the one world).
"""
import math
import os
import shutil
import tempfile
import threading
import time
import unittest

import rosgraph
import rospy
import rostest
from nav_msgs.msg import Odometry

from anafi_control.frames import yaw_from_quaternion
from anafi_sim.mission.fleet import drone_scenario, load_fleet
from anafi_sim.processes import start, stop, wait_for
from anafi_sim.ros import gazebo_types

SHARED = ('/diagnostics', '/rosout', '/rosout_agg', '/tf', '/tf_static', '/clock')
REACH_DISTANCE = 0.3   # m
REACH_YAW = 10.0       # deg
HOLD = 2.0             # s within reach
#: [s wall] hang guards, not performance bounds: on a loaded machine the fleet's 20-odd processes take minutes
#: to start (the .test files' time-limit stays above their sum)
START_TIMEOUT = 240.0
REACH_TIMEOUT = 120.0


def namespace(name):
    """'/anafi1/pid/x' -> 'anafi1'; '/gazebo' -> '' (root)."""
    parts = name.strip('/').split('/')
    return parts[0] if len(parts) > 1 else ''


class FleetTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node('test_fleet')
        fleet_file, layout = rospy.get_param('~fleet'), rospy.get_param('~layout', '')
        cls.fleet = load_fleet(fleet_file)
        cls.tmp = tempfile.mkdtemp(prefix='fleet_test_')
        cls.log = os.path.join(cls.tmp, 'fleet.log')
        cls.launch = start(['roslaunch', 'anafi_sim', 'fleet.launch', 'fleet:=' + fleet_file, 'evaluate:=false',
                            'out_dir:=' + os.path.join(cls.tmp, 'fleet')] + (['layout:=' + layout] if layout else []),
                           log=cls.log)
        cls.names = [d.name for d in cls.fleet.drones]
        cls.goals = {}
        for drone in cls.fleet.drones:
            s = drone_scenario(drone)['trajectory']
            cls.goals[drone.name] = (tuple(s['position']), s['yaw'])
        cls.lock = threading.Lock()
        cls.truth = {}
        cls.reached = {}
        cls.models = None
        for name in cls.names:
            rospy.Subscriber('/%s/ground_truth/odom' % name, Odometry, cls.on_truth, callback_args=name,
                             queue_size=5)
        rospy.Subscriber('/gazebo/model_states', gazebo_types.model_states_class(), cls.on_models, queue_size=1)

    @classmethod
    def tearDownClass(cls):
        left = stop(cls.launch, grace=30.0)
        if left:
            rospy.logwarn('test_fleet: processes still alive after stopping the fleet: %s', left)
        shutil.rmtree(cls.tmp, ignore_errors=True)

    def launch_log(self):
        """The fleet launch's state and the end of its log, for failure messages."""
        with open(self.log, errors='replace') as f:
            return 'fleet launch %s; its log ends:\n%s' % (
                'running' if self.launch.poll() is None else 'ended (%s)' % self.launch.returncode, f.read()[-3000:])

    @classmethod
    def on_truth(cls, msg, name):
        p = msg.pose.pose.position
        q = msg.pose.pose.orientation
        yaw = math.degrees(yaw_from_quaternion(q.x, q.y, q.z, q.w))
        (gx, gy, gz), gyaw = cls.goals[name]
        dist = math.sqrt((p.x - gx) ** 2 + (p.y - gy) ** 2 + (p.z - gz) ** 2)
        dyaw = abs((yaw - gyaw + 180.0) % 360.0 - 180.0)
        now = time.monotonic()
        with cls.lock:
            cls.truth[name] = (p.x, p.y, p.z, yaw)
            if dist < REACH_DISTANCE and dyaw < REACH_YAW:
                cls.reached.setdefault(name, now)
            else:
                cls.reached.pop(name, None)

    @classmethod
    def on_models(cls, msg):
        with cls.lock:
            cls.models = dict((n, (p.position.x, p.position.y, p.position.z)) for n, p in zip(msg.name, msg.pose))

    def test_1_three_times_two_models_in_the_world(self):
        expected = set(self.names) | set(n + '_camera' for n in self.names)
        ok = wait_for(lambda: self.models is not None and expected <= set(self.models), START_TIMEOUT,
                      0.2)
        with self.lock:
            models = dict(self.models or {})
        self.assertTrue(ok, 'models in /gazebo/model_states: %s, expected %s\n%s'
                        % (sorted(models), sorted(expected), self.launch_log()))
        self.assertEqual(set(models) - expected, {'ground_plane'})

    def test_2_each_drone_reaches_its_own_waypoint(self):
        def all_held():
            now = time.monotonic()
            with self.lock:
                return all(now - self.reached.get(n, now) >= HOLD for n in self.names) and \
                    len(self.reached) == len(self.names)
        ok = wait_for(all_held, REACH_TIMEOUT, 0.2)
        with self.lock:
            truth, models = dict(self.truth), dict(self.models or {})
        self.assertTrue(ok, 'drones at %s, waypoints %s\n%s' % (truth, self.goals, self.launch_log()))
        for name in self.names:
            (gx, gy, gz), _ = self.goals[name]
            mx, my, mz = models[name]
            self.assertLess(math.sqrt((mx - gx) ** 2 + (my - gy) ** 2 + (mz - gz) ** 2), REACH_DISTANCE + 0.1,
                            'model %s at %s, its waypoint %s' % (name, models[name], self.goals[name]))

    def test_3_no_topic_crosses_namespaces(self):
        master = rosgraph.Master('/test_fleet')
        chain = ('anafi_sim', 'interface', 'gazebo_mirror', 'trajectory_generator')
        want = set('/%s/%s' % (n, c) for n in self.names for c in chain)
        self.assertTrue(wait_for(lambda: want <= self._nodes(master), 30.0, 0.5),
                        'nodes: %s' % sorted(self._nodes(master)))
        hosts = self._hosts(master)
        self.assertEqual(bool(hosts), rospy.get_param('~layout', 'per_drone') == 'shared',
                         'fleet hosts: %s' % sorted(hosts))
        ends = 0
        for node, role, topic in self._ends(master):
            if node == rospy.get_name():   # this test listens to every drone
                continue
            t_ns, n_ns = namespace(topic), namespace(node)
            if n_ns in self.names:
                ends += 1
                shared = topic in SHARED or topic.startswith('/gazebo/')
                self.assertTrue(t_ns == n_ns or shared, '%s (drone %s) %s %s' % (node, n_ns, role, topic))
            if t_ns in self.names:
                self.assertEqual(n_ns if n_ns in self.names else t_ns, t_ns,
                                 '%s of drone %s has %s node %s' % (topic, t_ns, role, node))
                self.assertNotEqual(n_ns, '', '%s of drone %s: root node %s %s it' % (topic, t_ns, node, role))
        self.assertGreater(ends, 20 * len(self.names))
        for name in self.names:
            controller = [n for n in self._nodes(master) if n.startswith('/%s/' % name)
                          and n.rsplit('/', 1)[-1] in ('mpc_controller', 'pid_framework', 'pid_command')]
            self.assertTrue(controller, 'no controller node in /%s' % name)

    def test_4_a_split_ground_truth_host_keeps_every_mirror_in_one_world(self):
        """A fleet file's drones_per_host splits the ground-truth host: every drone's mirror runs in the host of
        its group (the world in the first), and test_1 / test_2 saw each one's models in the one world."""
        split = self.fleet.drones_per_host.get('fleet_ground_truth')
        if rospy.get_param('~layout', 'per_drone') != 'shared' or not split:
            return
        master = rosgraph.Master('/test_fleet')
        groups = [self.names[k:k + split] for k in range(0, len(self.names), split)]
        want = ['/fleet_ground_truth_%d' % (i + 1) for i in range(len(groups))]
        self.assertTrue(wait_for(lambda: set(want) <= set(self._hosts(master)), 30.0, 0.5),
                        'hosts: %s' % sorted(self._hosts(master)))
        hosts = self._hosts(master)
        for host, group in zip(want, groups):
            mirrors = sorted(n for n in hosts[host] if n.endswith('/gazebo_mirror'))
            self.assertEqual(mirrors, sorted('/%s/gazebo_mirror' % d for d in group), host)
        worlds = [[n for n in hosts[h] if namespace(n) == ''] for h in want]     # the world at the root
        self.assertEqual([len(w) for w in worlds], [1] + [0] * (len(want) - 1), 'root instances: %s' % worlds)

    @staticmethod
    def _hosts(master):
        """{host node: its ~wiring} of the fleet hosts (shared layout): per instance the topics it uses."""
        pubs, subs, srvs = master.getSystemState()
        nodes = set(n for entries in (pubs, subs, srvs) for _, ns in entries for n in ns)
        return dict((n, rospy.get_param(n + '/wiring')) for n in nodes if rospy.has_param(n + '/wiring'))

    @classmethod
    def _ends(cls, master):
        """[(node, 'publishes' | 'subscribes', topic)] from the master's system state; a fleet host's ends are
        its instances' (its ~wiring), and every topic the master has for a host is one of its instances'
        (or the host's own /diagnostics, /rosout)."""
        pubs, subs, _ = master.getSystemState()
        hosts = cls._hosts(master)
        out = []
        for role, entries in (('publishes', pubs), ('subscribes', subs)):
            for topic, nodes in entries:
                for node in nodes:
                    if node not in hosts:
                        out.append((node, role, topic))
                        continue
                    used = set(t for w in hosts[node].values() for t in w[role])
                    assert topic in used or topic in SHARED, '%s %s %s: no instance of it does' % (node, role, topic)
        for wiring in hosts.values():
            for instance, w in wiring.items():
                out += [(instance, role, topic) for role in ('publishes', 'subscribes') for topic in w[role]]
        return out

    @classmethod
    def _nodes(cls, master):
        pubs, subs, srvs = master.getSystemState()
        nodes = set(n for entries in (pubs, subs, srvs) for _, ns in entries for n in ns)
        return nodes | set(i for wiring in cls._hosts(master).values() for i in wiring)


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'test_fleet', FleetTest)
