#!/usr/bin/env python3
"""rostest: the fault matrix. Each fault is injected into a running graph with a flying drone.

The graph runs on a private ROS master of this test (so that the master itself can be restarted, the last
case): world.launch (simulated Anafi + interface + kinematic Gazebo world + mirror) + mpc.launch whose state comes through this test
(``fault/odom``, a relay of drone/odom that the test can corrupt or stop) + a second interface in
/garbage whose telemetry (the stand-in tool connected to ``GARBAGE_PROXY``, a relay of the simulator's
telemetry port) carries garbage, a malformed number and a 10 kB line before the real telemetry.
Wall clock, rtf 1, about 2 min.

For each fault (``FAULTS``): the drone flies along x at about 3 m/s (a moving waypoint); the fault is
injected; checked: the diagnostic level and message of the node concerned, the counter, that the drone
stops (speed < ``STOP_SPEED`` within ``STOP_TIME``, no farther than 1.2 x the firmware brake from the same
speed -- measured in the first case, the controller killed -- plus the speed x the detection delay), and
the recovery (time until the node reports OK / tracking again after the fault is removed). The observed
matrix is written to test_results/fault_matrix.json; ``tools/fault_table.py`` turns it into the table of
docs/reliability.md (``test/unit/sim/test_fault_glue.py`` checks that the table lists exactly ``FAULTS``).

Layouts: the environment variable ``FAULT_MATRIX_LAYOUT`` (per_drone by default: fault_matrix.test;
fault_matrix_shared.test sets ``shared``). In the shared layout the graph is the same launch hosted as a fleet's
(``fleet_launcher.shared_launch``: ``fleet_host.py`` processes /fleet_drones and /fleet_ground_truth run the
simulator, controller, interfaces and mirror as instances) and the rows that kill or shut down a node's process
are adapted to the host that process is, or skipped (``SHARED``); results in
test_results/fault_matrix_shared.json, the table of docs/reliability.md's shared-layout section.
"""
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import unittest
import xmlrpc.client

import psutil
import rosgraph
import rospy
import rostest
from diagnostic_msgs.msg import DiagnosticArray
from dynamic_reconfigure.client import Client
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Log
from std_msgs.msg import String

from anafi_sim import paths, processes
from anafi_sim.mission.fleet import launch_document
from anafi_sim.mission.fleet_layout import HOSTS, check_layout
from anafi_sim.run_files import atomic_write_text
from anafi_sim.msg import Waypoint
from anafi_sim.ros import gazebo_types
from anafi_sim.ros.wire_types import piloting_command_class

DRONE = 'anafi'
NAN = float('nan')
SPEED = 3.0          # [m/s] flight speed before a fault
STOP_SPEED = 0.3     # [m/s] "stopped"
STOP_TIME = 12.0     # [s] to stop
STEADY = 2.0        # [s] of steady flight before a fault
RECOVERY_TIME = 10.0  # [s] to report OK again once the fault is removed
#: the graph's layout (anafi_sim.mission.fleet_layout.LAYOUTS)
LAYOUT = check_layout(os.environ.get('FAULT_MATRIX_LAYOUT', 'per_drone'))
SHARED_LAYOUT = LAYOUT == 'shared'
RESULTS = os.path.join(paths.package_dir(), 'test_results',
                       'fault_matrix_shared.json' if SHARED_LAYOUT else 'fault_matrix.json')

#: (name, fault injected, expected) -- the rows of the table in docs/reliability.md (same order)
FAULTS = (
    ('controller_killed', 'mpc_controller killed (SIGKILL) in flight (and the waypoints stop: the firmware brake alone)',
     'no command: the firmware brake stops the drone (the reference distance); roslaunch respawns the node'),
    ('nan_waypoint', 'NaN waypoints at 10 Hz', 'HOLD: WARN "holding position: non-finite waypoint", '
     'rejected_waypoints grows, the drone stops'),
    ('stale_waypoint', 'waypoints stop', 'HOLD after waypoint_timeout (1 s): WARN "holding position: stale '
     'waypoint", the drone stops'),
    ('old_waypoint_stream', 'a second waypoint stream 7.5 m to the side, stamped 5 s old, interleaved at 10 Hz',
     'dropped (stale stamp, > waypoint_max_age 1 s), counted, WARN "dropped waypoints"; the drone keeps '
     'tracking the real stream (no swing)'),
    ('out_of_order_waypoint', 'a second waypoint stream 7.5 m to the side, stamped 0.3 s behind the real one',
     'dropped (out of order), counted, WARN "dropped waypoints"; the drone keeps tracking the real stream'),
    ('far_waypoint', 'a waypoint 1 km away', 'limited by the flight envelope: WARN "limiting: target moved into '
     'the geofence ...", limited_geofence grows, commands keep flowing (toward the fence, at most 10 m/s)'),
    ('foreign_frame_waypoint', 'the waypoints arrive in anafi/base_link (20 m to the side of the drone)',
     'refused (foreign frame), counted; no usable waypoint: HOLD after waypoint_timeout (WARN "holding '
     'position: stale waypoint ...; dropped waypoints: N foreign frame"), the drone stops'),
    ('nan_state', 'NaN state (odometry) at 30 Hz', 'SILENT: WARN "no command, firmware hover brake: '
     'non-finite state", rejected_states grows, no command, the firmware brake stops the drone'),
    ('stale_state', 'state stops', 'SILENT after state_timeout (0.5 s): WARN "no command, firmware hover brake: '
     'stale state", no command, the drone stops'),
    ('solver_failure', 'MPC solver fails (OSQP max_iter lowered to 1 by dynamic_reconfigure in flight)',
     'SILENT: ERROR "no command, firmware hover brake: solver ...", solver_failed grows, no command, the '
     'firmware brake stops the drone; max_iter back -> tracking'),
    ('cli_killed', 'telemetry CLI killed (SIGKILL)', 'restarted at once (process restarts grows, last exit '
     'code -9), OK again; the controller (on the drone\'s estimate) keeps tracking'),
    ('cli_hung', 'telemetry CLI stopped (SIGSTOP: no output, no exit)', 'interface ERROR (stale), the CLI is '
     'killed and restarted after restart_timeout (process hangs grows), OK again'),
    ('telemetry_garbage', 'garbage, a malformed number (1_000) and a 10 kB line in the telemetry',
     'lines counted (parse malformed, process oversize lines), dropped; samples flow: OK'),
    ('simulator_restart', 'simulated Anafi (anafi_sim node: Sphinx + firmware) killed (SIGKILL)',
     'interface ERROR while the telemetry is gone, controller SILENT (stale state); roslaunch respawns the '
     'simulator (a new flight from the take-off point); interface OK within 5 s of its first sample, the '
     'controller tracks again'),
    ('foreign_stream', 'another drone\'s telemetry (its own stream id) served on the port the interface reads '
     '(the simulator\'s port parameter pointed at it, the telemetry CLI restarted)',
     'interface ERROR "refusing the telemetry of another drone", nothing published (no ground truth from the '
     'other drone); the right port back -> OK; the controller (on the estimate) keeps tracking'),
    ('taken_port', 'a second simulator told to serve on the port the first one uses',
     'the second simulator logs one FATAL line naming ~telemetry_port and the taken port and stays up in ERROR '
     '(no respawn loop); the first simulator\'s stream and the interface unaffected (OK, same stream id)'),
    ('world_killed', 'Gazebo world (/gazebo) killed (SIGKILL), respawned by world.launch',
     'the mirror survives (same pid), counts the world restart, respawns both models, OK again; the drone keeps '
     'tracking (the controller does not use the world)'),
    ('master_restart', 'ROS master killed and restarted on the same port', 'every node exits (code 75) and is '
     'respawned with its parameters; new publishers reach the controller again'),
    ('clock_jump', '/clock jumps 5 s back under use_sim_time (as when the simulator respawns), on a graph of '
     'its own: the MPC and the distributed PID, each given a hovering state and a waypoint; then /clock stops '
     'for 6 s', 'the timers keep running (rospy.Timer died before): the controllers go SILENT (clock_jump) and '
     'command again; the nodes count the jump ("ROS time jumps back") and log it; with /clock stopped the MPC\'s '
     'health is WARN "stalled: ..." (its cycles frozen), never "tracking"'),
    ('second_commander', 'a second MPC (node mpc_rival) started on the flying drone; then an operator (this '
     'test node) publishes hover commands on drone/rpyt for 2 s', 'one commander at any time: the newcomer '
     'hears the commands and never commands (ERROR "second commander: ... also publishes ..."), the flying '
     'controller keeps tracking; the controller yields to the operator (ERROR naming it, no command) and '
     'tracks again once the operator is gone (quiet 2 s, no longer publishing)'),
    ('hostile_command', 'the attack: an executable EVIL/tlm-data-logger (it would create FILE) in a writable folder, '
     'the /garbage interface\'s ~telemetry_command set to "EVIL/tlm-data-logger -r 0 inet:127.0.0.1:1" '
     '(rosparam), then its XML-RPC shutdown called (roslaunch respawns it with the new parameter)',
     'refused: the respawned interface runs nothing, stays up in ERROR "bad parameters: telemetry_command: '
     'refused to run \'EVIL/tlm-data-logger\': not one of the allowed tools ..." (not respawned again), FILE '
     'never created; the parameter put back and the node shut down again -> it reads the telemetry, OK'),
    ('fleet_cap', 'roslaunch anafi_sim fleet.launch drones:=50 (305 processes, 11 GB, the master unresponsive '
     'for 150 s before)', 'refused before anything starts: one line naming drones and the cap (this machine\'s '
     'own measured figure from the ROS home\'s cache, else the conservative default: which, and where it came '
     'from), roslaunch exits non-zero, no node started'),
    ('stderr_flood', '600 MB on the telemetry tool\'s stderr without a newline while it prints samples (a third '
     'interface, /flood, whose tlm-data-logger found on PATH is a test tool that floods stderr, then runs the '
     'stand-in)', 'stderr read with the same 4096-byte cap as stdout: the interface\'s memory stays that of an '
     'interface without the flood, the bytes are counted, samples flow: OK'),
    ('velocity_stream', 'waypoints at the drone\'s own position with vx = 1e6 (finite), stamped, at 10 Hz, until '
     'the drone stops; then the legitimate stream (the waypoint where the fault began) again (the graph\'s MPC has '
     'a 100 m geofence, FENCE)',
     'bounded by the flight envelope: WARN "limiting: reference speed 1e+06 m/s > 10.0 m/s ..." throughout, never '
     '"tracking"; the drone at most 10 m/s and inside the geofence; the legitimate waypoint reached again within '
     'distance / 10 m/s + 15 s (no lock-out)'),
    ('second_waypoint_source', 'a second waypoint stream from another node, 7.5 m to the side: first stamped 0 with '
     'frame \'\', then stamped 0.9 s ahead (inside the age limit), 10 Hz, 4 s each',
     'refused: the waypoint source is the first publisher heard (by its URI, from the master): dropped as "another '
     'publisher than the waypoint source", counted; the drone keeps tracking the legitimate stream (no swing, none '
     'of it dropped as out of order)'),
    ('claimed_commander', 'a node whose connection header claims callerid=<the controller\'s node> publishes '
     'piloting commands on drone/rpyt for 2 s',
     'seen by its publisher URI: the controller stands down, ERROR "second commander: <URI> (claims to be <the '
     'controller>) also publishes ..."; tracks again once it is gone'),
    ('huge_telemetry', 'telemetry of the drone\'s own stream id with position x = 1e308 (the simulator\'s port '
     'parameter pointed at it, the telemetry CLI restarted)',
     'malformed input: counted ("rejected samples beyond physical bounds"), no ground truth published from it; '
     'the right port back -> OK'),
    ('file_parameters', 'a simulator started with ~model_file and a trajectory generator with ~scenario_file '
     'pointing at a file outside the allowed folders (holding a secret line)',
     'refused unread: one FATAL line naming the parameter ("refused ... only .yaml/.yml files in ..."), the '
     'file\'s text in no log and not on /rosout_agg'),
    ('remote_telemetry_host', 'a simulator started with ~telemetry_host 0.0.0.0',
     'bad parameter: one FATAL line naming ~telemetry_host (loopback only unless allow_remote_telemetry), up in '
     'ERROR, nothing listens on 0.0.0.0'),
    ('launch_numbers', 'roslaunch sim.launch rtf:=1e308, initial_x:=1e300 and rtf:=1e0 (--nodes); the simulator '
     'given ~rtf as the text \'1e0\'; fleet.launch drones:=\u00b2',
     'one parser for the check and the nodes: 1e308 / 1e300 refused in one line with the range (exit 1, nothing '
     'started), \u00b2 one line (no traceback), 1e0 accepted by both (the node runs, not in ERROR)'),
    ('hostile_fleet_file', 'a fleet file whose target.model is "$(eval exec(...os.system(\'touch FILE\')...))": '
     'roslaunch --nodes anafi_sim fleet.launch fleet:=FILE and roslaunch anafi_sim fleet.launch fleet:=FILE',
     'refused at load in one line naming target.model, exit 1, nothing started, FILE never created'),
    ('untrusted_text', '49 commands of 1 MB each on a trajectory generator\'s ~command topic; a scenario file '
     'holding a YAML alias bomb given to a generator as ~scenario_file',
     'commands logged clipped (<= 300 characters) and throttled: the logs grow by kilobytes, not 205 MB; the alias '
     'bomb refused in one FATAL line (exit 1) without building or quoting the expanded value'),
)

#: the rows that do not run as in the per-drone layout when the graph is hosted (fault_matrix_shared.test):
#: name -> ('adapted' | 'skipped', how / why); every other row runs with the same expectations (the node of a
#: hosted instance: its host, whose ~wiring lists it; an interface's telemetry CLI: the host's child serving
#: that interface's port). The table of docs/reliability.md's shared-layout section (tools/fault_table.py).
SHARED = {
    'controller_killed': ('adapted', 'the controller\'s process is the drones host (/fleet_drones, with the '
                          'simulator): killing it is simulator_restart\'s row here; this row measures the '
                          'firmware-brake reference of the other rows with the solver failing instead (no command '
                          'from the next 10 Hz cycle on)'),
    'simulator_restart': ('adapted', 'the drones host (simulator + controller) killed (SIGKILL): interface ERROR, '
                          'roslaunch respawns the host (a new flight from the take-off point), interface OK within '
                          '5 s of its first sample, the controller tracks again (a failed simulator share alone: '
                          'test/ros/shared_faults.test)'),
    'second_commander': ('adapted', 'the same, with the hosted controller\'s commands named by its host '
                         '(/fleet_drones) for the nodes and this test outside the host'),
    'stderr_flood': ('adapted', 'the /flood interface stays a process (its own environment); the reference '
                     'memory is the ground-truth host (two interfaces and the mirror)'),
    'hostile_command': ('adapted', 'the XML-RPC shutdown goes to the ground-truth host (the master\'s node of '
                        '/garbage/interface): respawned, it does not start that instance (\'hosted instance\' '
                        'ERROR naming the refused command), FILE never created; the parameter put back and the '
                        'host shut down again -> OK'),
    'fleet_cap': ('adapted', 'fleet.launch drones:=50 layout:=shared: refused against the shared layout\'s cap'),
    'world_killed': ('adapted', 'the world (/gazebo) is an instance of the ground-truth host with the interfaces '
                     'and the mirror: the host killed (SIGKILL) and respawned by roslaunch, the world back with both '
                     'models, the mirror OK; the drone keeps tracking (the controller does not use the world or the '
                     'ground truth)'),
    'master_restart': ('adapted', 'every process exits (75), the hosts too, and is respawned with its parameters '
                       '(the hosts with every instance); new publishers reach the hosted controller'),
    'clock_jump': ('skipped', 'a graph of its own with no hosted node (layout-independent as built): runs in '
                   'fault_matrix.test only'),
    'claimed_commander': ('adapted', 'the header claims the name the hosted controller\'s commands carry, its host '
                          '(/fleet_drones)'),
    'file_parameters': ('adapted', 'the simulator and the generator started as processes of their own (the node code '
                        'a host runs as an instance), as in the per-drone layout'),
    'remote_telemetry_host': ('adapted', 'the simulator started as a process of its own, as in the per-drone layout'),
    'launch_numbers': ('adapted', 'fleet.launch drones:=\u00b2 layout:=shared; sim.launch and the simulator as in '
                       'the per-drone layout'),
    'hostile_fleet_file': ('adapted', 'fleet.launch ... layout:=shared'),
}

#: a second interface on a garbage telemetry stream (malformed lines, a 10 kB line, then the real stream)
GARBAGE_GROUP = """  <group ns="garbage">
    <node pkg="anafi_sim" type="interface_node.py" name="interface" output="log" respawn="true">
      <rosparam command="load" file="$(find anafi_sim)/anafi_sim/config/interface.yaml"/>
      <param name="drone_name" value="garbage"/>
      <param name="telemetry_command"
             value="$(find anafi_sim)/anafi_sim/scripts/tlm_data_logger.py -r 0 inet:127.0.0.1:{garbage_port}"/>
    </node>
  </group>
  <group ns="flood">
    <node pkg="anafi_sim" type="interface_node.py" name="interface" output="log" respawn="true">
      <env name="PATH" value="{fake_bin}:$(env PATH)"/>
      <rosparam command="load" file="$(find anafi_sim)/anafi_sim/config/interface.yaml"/>
      <param name="drone_name" value="flood"/>
      <param name="telemetry_command" value="tlm-data-logger -r 0 inet:127.0.0.1:{port}"/>
    </node>
  </group>
"""


#: [m] the geofence radius of the graph's MPC (velocity_stream flies to it and back; the other rows stay well
#: inside it: they fly +-x in turn)
FENCE = 100.0
FENCE_LINE = '  <param name="/%s/mpc_controller/geofence_radius" value="%.1f"/>' % (DRONE, FENCE)


def launch_text(port, garbage_port, fake_bin):
    """The graph: world.launch + mpc.launch on the fault relay's state, the garbage interface (on the garbage
    relay of ``garbage_port``) and the stderr-flood interface (its tlm-data-logger found first in ``fake_bin``)."""
    return launch_document([('world.launch', [('drone_name', DRONE), ('telemetry_port', port)]),
                            ('mpc.launch', [('drone_name', DRONE), ('state_topic', 'fault/odom'), ('output', 'log')])],
                           GARBAGE_GROUP.format(port=port, garbage_port=garbage_port, fake_bin=fake_bin).splitlines()
                           + [FENCE_LINE],
                           head=['  <param name="/use_sim_time" value="false"/>'])


class Graph(object):
    """The test's view of the graph: state relay (with faults), waypoints, speed, diagnostics, commands."""

    def __init__(self):
        self.lock = threading.Lock()
        self.diag = {}            # status name -> (wall time, level, message, {key: value})
        self.truth = []           # (wall time, x, y, z)
        self.commands = []        # wall times of drone/rpyt
        self._state_mode = 'relay'  # relay | nan | off (the relay process, RELAY)
        self.wp_mode = 'off'       # off | track | nan | far | stop | foreign (track, in anafi/base_link)
        self.second = None         # None | old (a second stream stamped 5 s old) | behind (0.3 s behind)
        self.track = None          # (t0, x0, y0, direction)
        self.point = None          # (x, y, z) of the mode 'point'
        self.pub_mode = rospy.Publisher('/%s/fault/mode' % DRONE, String, queue_size=1, latch=True)
        self.pub_wp = rospy.Publisher('/%s/position_control/waypoint' % DRONE, Waypoint, queue_size=10)
        rospy.Subscriber('/%s/sim/truth' % DRONE, Odometry, self.on_truth, queue_size=1, tcp_nodelay=True)
        self.truth_speed = None     # [m/s] of the last ground truth (its twist: not from receipt times)
        self.estimate = None        # (x, y, z) of the drone's estimate (drone/odom: what the controller flies on)
        rospy.Subscriber('/%s/drone/odom' % DRONE, Odometry, self.on_estimate, queue_size=1, tcp_nodelay=True)
        rospy.Subscriber('/diagnostics', DiagnosticArray, self.on_diag, queue_size=50)
        rospy.Subscriber('/%s/drone/rpyt' % DRONE, piloting_command_class(), self.on_cmd, queue_size=50)
        self.models = (0.0, ())     # (wall time, names) of the last /gazebo/model_states
        rospy.Subscriber('/gazebo/model_states', gazebo_types.model_states_class(), self.on_models, queue_size=1)
        self.timer = rospy.Timer(rospy.Duration(0.1), self.publish_waypoint)

    @property
    def state_mode(self):
        return self._state_mode

    @state_mode.setter
    def state_mode(self, mode):
        self._state_mode = mode
        self.pub_mode.publish(String(mode))

    def on_truth(self, msg):
        p = msg.pose.pose.position
        v = msg.twist.twist.linear
        self.truth_speed = math.sqrt(v.x ** 2 + v.y ** 2 + v.z ** 2)   # the simulated drone's own speed
        with self.lock:
            self.truth.append((time.time(), p.x, p.y, p.z))
            del self.truth[:-3000]

    def on_estimate(self, msg):
        p = msg.pose.pose.position
        self.estimate = (p.x, p.y, p.z)

    def on_diag(self, msg):
        now = time.time()
        with self.lock:
            for s in msg.status:
                self.diag[s.name] = (now, s.level, s.message, dict((kv.key, kv.value) for kv in s.values))

    def on_models(self, msg):
        with self.lock:
            self.models = (time.time(), tuple(msg.name))

    def on_cmd(self, _msg):
        with self.lock:
            self.commands.append(time.time())
            del self.commands[:-500]

    def publish_waypoint(self, _event):
        mode = self.wp_mode
        if mode in ('off', 'stop'):
            return
        w = Waypoint()
        now = rospy.Time.now()
        w.header.stamp, w.header.frame_id = now, 'world'
        if mode == 'nan':
            w.x = w.y = w.z = NAN
        elif mode == 'far':
            w.x, w.y, w.z = 1000.0, 0.0, 3.0
        elif mode == 'vx':          # the drone's own position, vx = 1e6 (finite)
            p = self.position()
            if p is None:
                return
            w.x, w.y, w.z, w.vx = p[0], p[1], p[2], 1e6
        elif mode == 'point':       # one fixed waypoint, at rest
            w.x, w.y, w.z = self.point
        elif mode == 'foreign':     # "20 m to the side" in the drone's body frame
            w.header.frame_id = '%s/base_link' % DRONE
            w.x, w.y, w.z = 0.0, 20.0, 0.0
        else:
            t0, x0, y0, d = self.track
            t = time.time() - t0
            w.x, w.y, w.z = x0 + d * SPEED * t, y0, 3.0
            w.vx = d * SPEED
        self.pub_wp.publish(w)
        if self.second is not None and mode == 'track':
            other = Waypoint()
            other.header.frame_id = 'world'
            other.header.stamp = now - rospy.Duration(5.0 if self.second == 'old' else 0.3)
            other.x, other.y, other.z, other.vx = w.x, w.y + 7.5, w.z, w.vx
            self.pub_wp.publish(other)

    # -- queries
    def position(self):
        with self.lock:
            return self.truth[-1][1:] if self.truth else None

    def speed(self, window=0.3):
        """Horizontal + vertical speed [m/s] from the truth positions over the last ``window`` s."""
        with self.lock:
            pts = list(self.truth)
        if len(pts) < 2:
            return None
        t1 = pts[-1][0]
        older = [p for p in pts if p[0] <= t1 - window]
        if not older:
            return None
        a, b = older[-1], pts[-1]
        return math.sqrt(sum((b[i] - a[i]) ** 2 for i in (1, 2, 3))) / (b[0] - a[0])

    def status(self, suffix, since=0.0):
        with self.lock:
            for name, entry in self.diag.items():
                if (name.endswith(suffix) or name.startswith(suffix + ':')) and entry[0] >= since:
                    return entry
        return None

    def command_rate(self, window=1.0):
        now = time.time()
        with self.lock:
            return sum(1 for t in self.commands if t > now - window) / window


def counter_lead(entry, key):
    """The number a diagnostic value starts with ('12 (last: ...)' -> 12), None when there is none."""
    try:
        return int(entry[3][key].split()[0])
    except (TypeError, KeyError, ValueError, IndexError):
        return None


def counter(entry, key):
    try:
        return int(float(entry[3][key]))
    except (TypeError, KeyError, ValueError):
        return None


class TestFaultMatrix(unittest.TestCase):
    rows = []
    direction = 1.0

    @classmethod
    def setUpClass(cls):
        cls.workdir = tempfile.mkdtemp(prefix='fault_matrix_')
        cls.procs = processes.Processes(cls.workdir, grace=10.0)
        cls.uri, cls.env = processes.private_master(cls.procs, os.path.join(cls.workdir, 'ros_home'),
                                                  os.path.join(cls.workdir, 'log'), join=True)
        cls.port = int(cls.uri.rsplit(':', 1)[1])
        launch = os.path.join(cls.workdir, 'faults.launch')
        port, garbage_port = processes.free_port(), processes.free_port()
        fake_bin = os.path.join(cls.workdir, 'bin')       # the /flood interface's "Sphinx tool"
        os.makedirs(fake_bin)
        with open(os.path.join(fake_bin, 'tlm-data-logger'), 'w') as f:
            f.write(FLOOD_TOOL.format(python=sys.executable, mb=FLOOD_MB,
                                      stand_in=paths.data_path('scripts', 'tlm_data_logger.py')))
        os.chmod(os.path.join(fake_bin, 'tlm-data-logger'), 0o755)
        settings = os.path.join(cls.workdir, 'settings')    # the telemetry allow-list lists the test tool
        os.makedirs(settings)
        with open(os.path.join(settings, 'telemetry_tools'), 'w') as f:
            f.write(os.path.join(fake_bin, 'tlm-data-logger') + '\n')
        cls.env['ANAFI_SIM_SETTINGS_DIR'] = settings
        text = launch_text(port, garbage_port, fake_bin)
        if SHARED_LAYOUT:   # the same launch expanded by roslaunch and hosted as a fleet's (fleet.params.yaml)
            from anafi_sim.nodes.fleet_launcher import shared_launch
            text = shared_launch(text, cls.workdir, 'log', 'fault matrix')
        with open(launch, 'w') as f:
            f.write(text)
        cls.telemetry_port, cls.garbage_port = port, garbage_port
        cls.procs.start('garbage_proxy', [sys.executable, '-c', GARBAGE_PROXY.format(listen=garbage_port,
                                                                                    upstream=port)], cls.env)
        cls.procs.start('roslaunch', ['roslaunch', '--port', str(cls.port), launch], cls.env)
        # the controller's state comes through this relay, a process of its own (this one is busy measuring)
        cls.procs.start('relay', [sys.executable, '-c', RELAY.format(drone=DRONE)], cls.env)
        rospy.init_node('fault_matrix', anonymous=True)
        cls.g = Graph()
        ok = processes.wait_for(lambda: cls.g.status('/%s/mpc_controller' % DRONE) is not None
                              and cls.g.position() is not None, 90.0, 0.2)
        if not ok:
            raise RuntimeError('graph did not come up:\n' + cls.procs.log_tail('roslaunch', 40))
        cls.brake = None   # (speed, distance) of the firmware brake (controller killed)

    @classmethod
    def tearDownClass(cls):
        try:
            atomic_write_text(RESULTS, json.dumps({
                'layout': LAYOUT, 'faults': [name for name, _, _ in FAULTS], 'rows': cls.rows,
                'shared': SHARED if SHARED_LAYOUT else {},
                'date': time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, indent=1))
        finally:
            cls.procs.stop_all()
            shutil.rmtree(cls.workdir, ignore_errors=True)

    # -- helpers
    def node_of(self, name):
        """The node the master knows for the node ``name``: itself, or in the shared layout the host whose
        ~wiring lists it as an instance (name of a host, e.g. /fleet_drones)."""
        if SHARED_LAYOUT:     # the hosts: HOSTS, split by drone into <host>_1, _2 ... in a large fleet
            master = processes.xmlrpc_proxy(self.uri)
            code, _, state = master.getSystemState(processes.HARNESS_CALLER)
            nodes = set(n for kind in (state if code == 1 else ()) for _, names in kind for n in names)
            for node in sorted(n for n in nodes if any(n.lstrip('/').startswith(h) for h in HOSTS)):
                code, _, wiring = master.getParam(processes.HARNESS_CALLER, node + '/wiring')
                if code == 1 and name in wiring:
                    return node
        return name

    def pid_of(self, name):
        """Process id of the node ``name`` (of its host in the shared layout), None when there is none."""
        return processes.node_pid(self.node_of(name), self.uri)

    def cli_of(self, interface, port):
        """The telemetry CLI the interface ``interface`` runs: the child of its process (its host's) whose
        command line reads ``port`` (a host runs the CLIs of several interfaces)."""
        children = psutil.Process(self.pid_of(interface)).children()
        mine = [c for c in children if any(a.endswith(':%d' % port) for a in c.cmdline())]
        self.assertEqual(len(mine), 1, '%s: CLIs %s' % (interface, [c.cmdline() for c in children]))
        return mine[0]

    def skip_shared(self, name):
        if SHARED_LAYOUT and SHARED.get(name, ('',))[0] == 'skipped':
            self.skipTest('%s in the shared layout: %s' % (name, SHARED[name][1]))

    def fly(self, timeout=40.0):
        """Fly along +-x until the speed is >= 0.8 SPEED; the speed reached."""
        g = self.g
        g.state_mode = 'relay'
        pos = None
        processes.require(lambda: g.position() is not None, 10.0, 'truth')
        pos = g.position()
        TestFaultMatrix.direction = self.inward(pos)
        g.track = (time.time(), pos[0], pos[1], self.direction)
        g.wp_mode = 'track'
        steady = [None]

        def flying():       # within 35 % of SPEED for STEADY s: the attitude is about level, as in every case
            now, v = time.time(), g.speed() or 0.0
            if abs(v - SPEED) > 0.35 * SPEED:
                steady[0] = None
            elif steady[0] is None:
                steady[0] = now
            return steady[0] is not None and now - steady[0] >= STEADY
        processes.require(flying, timeout, 'the drone flying steadily at %.1f m/s' % SPEED,
                        lambda: 'speed %s, controller %s' % (g.speed(), g.status('/%s/mpc_controller' % DRONE)))
        return g.speed()

    def inward(self, pos):
        """The direction along x (+-1) toward the controller's geofence centre from ``pos`` (the rows fly back and
        forth through it: the legitimate stream goes on between the rows, so the drone never reaches the fence)."""
        e = self.controller(0.0)
        centre = e[3].get('geofence centre (take-off point) [m]', 'none yet') if e is not None else 'none yet'
        cx = 0.0 if centre == 'none yet' else float(centre.split()[0])
        return -1.0 if pos[0] > cx else 1.0

    def wait_stop(self, t_fault, pos0):
        """(seconds, farthest horizontal distance [m]) until the drone stopped."""
        g = self.g
        far = [0.0]

        def stopped():
            p = g.position()
            far[0] = max(far[0], math.hypot(p[0] - pos0[0], p[1] - pos0[1]))
            return time.time() - t_fault > 1.0 and (g.speed() or 9.0) < STOP_SPEED
        processes.require(stopped, STOP_TIME, 'the drone stopped', lambda: 'speed %s' % g.speed())
        return time.time() - t_fault, far[0]

    def record(self, name, observed, stop=None, recovery=None, ok=True):
        TestFaultMatrix.rows.append({'name': name, 'observed': observed, 'stop': stop, 'recovery': recovery,
                                     'ok': ok})

    def controller(self, since):
        return self.g.status('/%s/mpc_controller' % DRONE, since)

    def wait_controller(self, since, predicate, timeout, what):
        entry = [None]

        def check():
            entry[0] = self.controller(since)
            return entry[0] is not None and predicate(entry[0])
        processes.require(check, timeout, what, lambda: 'last diagnostic %s' % (entry[0],))
        return entry[0]

    def recover(self, t_fixed):
        """Seconds until the controller tracks again (OK 'tracking' diagnostic, 1 Hz) after the fault is removed
        (a fresh moving waypoint from where the drone is)."""
        g = self.g
        g.state_mode = 'relay'
        pos = g.position()
        TestFaultMatrix.direction = self.inward(pos)
        g.track = (time.time(), pos[0], pos[1], self.direction)
        g.wp_mode = 'track'
        e = self.wait_controller(t_fixed, lambda e: e[1] == 0 and 'tracking' in e[2], RECOVERY_TIME + 25.0,
                                 'controller tracking again')
        return e[0] - t_fixed

    def bound(self, speed, delay):
        v0, d0 = self.brake
        return 1.2 * d0 * (speed / v0) ** 2 + speed * delay + 0.5

    def hold_case(self, name, mode, message, counter_key, delay):
        g = self.g
        v = self.fly()
        before = counter(self.controller(0.0), counter_key) if counter_key else None
        pos0, t0 = g.position(), time.time()
        g.wp_mode = mode
        secs, dist = self.wait_stop(t0, pos0)
        e = self.wait_controller(t0 + delay, lambda e: message in e[2], 5.0, message)
        self.assertEqual(e[1], 1, e)                                   # WARN
        self.assertIn('holding position', e[2])
        self.assertGreater(g.command_rate(), 5.0, 'HOLD keeps commanding')
        if counter_key:
            self.assertGreater(counter(e, counter_key), before, e)
        bound = self.bound(v, delay)
        self.assertLess(dist, bound, '%s: %.1f m from %.1f m/s > bound %.1f m' % (name, dist, v, bound))
        t_fixed = time.time()
        rec = self.recover(t_fixed)
        self.record(name, 'WARN "%s"; %s; commands %.0f Hz' % (e[2], '%s %d -> %d' % (
            counter_key, before, counter(e, counter_key)) if counter_key else 'stopped',
            g.command_rate()), '%.1f m from %.1f m/s in %.1f s (bound %.1f m)' % (dist, v, secs, bound), rec)

    def limit_case(self, name, mode, message, counter_key, seconds):
        """The fault for ``seconds``: the controller keeps commanding, WARN 'limiting: <message>' (never
        'tracking'), ``counter_key`` grows; then the legitimate stream again: tracking."""
        g = self.g
        v = self.fly()
        before = counter(self.controller(0.0), counter_key)
        t0 = time.time()
        g.wp_mode = mode
        e = self.wait_controller(t0, lambda e: message in e[2], 5.0, message)
        self.assertEqual(e[1], 1, e)                                   # WARN
        self.assertTrue(e[2].startswith('limiting: '), e)
        self.assertGreater(g.command_rate(), 5.0, 'limiting keeps commanding')
        self.assertGreater(counter(e, counter_key), before, e)
        time.sleep(max(0.0, t0 + seconds - time.time()))
        rec = self.recover(time.time())
        self.record(name, 'WARN "%s"; %s %d -> %d; commands %.0f Hz' % (e[2], counter_key, before,
                                                                       counter(e, counter_key), g.command_rate()),
                    'flies on from %.1f m/s, limited' % v, rec)

    def silent_case(self, name, mode, message, counter_key, delay):
        g = self.g
        v = self.fly()
        before = counter(self.controller(0.0), counter_key)
        pos0, t0 = g.position(), time.time()
        g.state_mode = mode
        secs, dist = self.wait_stop(t0, pos0)
        e = self.wait_controller(t0 + delay, lambda e: message in e[2], 5.0, message)
        self.assertEqual(e[1], 1, e)
        self.assertIn('no command, firmware hover brake', e[2])
        self.assertEqual(g.command_rate(), 0.0, 'SILENT sends nothing')
        self.assertGreater(counter(e, counter_key), before, e)
        bound = self.bound(v, delay)
        self.assertLess(dist, bound, '%s: %.1f m from %.1f m/s > bound %.1f m' % (name, dist, v, bound))
        g.state_mode = 'relay'
        rec = self.recover(time.time())
        self.record(name, 'WARN "%s"; %s %d -> %d; commands 0 Hz' % (e[2], counter_key, before,
                                                                   counter(e, counter_key)),
                    '%.1f m from %.1f m/s in %.1f s (bound %.1f m)' % (dist, v, secs, bound), rec)

    # -- the matrix, in the order of FAULTS
    def test_01_controller_killed(self):
        if SHARED_LAYOUT:
            return self.brake_reference()
        g = self.g
        v = self.fly()
        old = processes.node_pid('/%s/mpc_controller' % DRONE, self.uri)
        pos0, t0 = g.position(), time.time()
        os.kill(old, signal.SIGKILL)
        # the waypoints stop with it, so that the respawned controller (after respawn_delay 1 s) stays silent
        # (no waypoint yet) and the stop is the firmware brake alone: the reference of the other rows
        g.wp_mode = 'off'
        secs, dist = self.wait_stop(t0, pos0)
        self.assertEqual(g.command_rate(), 0.0)
        TestFaultMatrix.brake = (v, dist)
        new = [None]
        processes.require(lambda: new.__setitem__(0, processes.node_pid('/%s/mpc_controller' % DRONE, self.uri))
                        or (new[0] not in (None, old)), 20.0, 'the controller respawned')
        rec = self.recover(t0)
        self.record('controller_killed', 'no command (0 Hz); respawned (pid %d -> %d)' % (old, new[0]),
                    '%.1f m from %.1f m/s in %.1f s (firmware brake: the reference)' % (dist, v, secs), rec)

    def brake_reference(self):
        """controller_killed in the shared layout (the controller's process is the drones host, killed in
        simulator_restart): the firmware-brake reference, the solver failing (no command from the next 10 Hz
        cycle on)."""
        g = self.g
        client = Client('/%s/mpc_controller' % DRONE, timeout=20.0)
        v = self.fly()
        pos0, t0 = g.position(), time.time()
        self.assertEqual(client.update_configuration({'max_iter': 1})['max_iter'], 1)
        try:
            secs, dist = self.wait_stop(t0, pos0)
            self.assertEqual(g.command_rate(), 0.0)
        finally:
            client.update_configuration({'max_iter': 4000})
        TestFaultMatrix.brake = (v, dist)
        rec = self.recover(time.time())
        self.record('controller_killed', 'the controller\'s process is the drones host %s (killed in '
                    'simulator_restart); the firmware-brake reference: no command (0 Hz) while the solver fails'
                    % self.node_of('/%s/mpc_controller' % DRONE),
                    '%.1f m from %.1f m/s in %.1f s (solver failure: the reference)' % (dist, v, secs), rec)

    def test_02_nan_waypoint(self):
        self.hold_case('nan_waypoint', 'nan', 'non-finite waypoint', 'rejected_waypoints', 0.2)

    def test_03_stale_waypoint(self):
        # detected waypoint_timeout (1 s) after the last waypoint, at the next 10 Hz cycle
        self.hold_case('stale_waypoint', 'stop', 'stale waypoint', 'stale_waypoint', 1.1)

    def second_stream_case(self, name, mode, reason):
        g = self.g
        self.fly()
        key = 'dropped waypoints: %s' % reason
        before = counter(self.controller(0.0), key) or 0
        y0 = g.track[2]
        t0 = time.time()
        g.second = mode
        worst = [0.0]

        def watch():
            p = g.position()
            worst[0] = max(worst[0], abs(p[1] - y0))
            return time.time() - t0 > 4.0
        processes.require(watch, 10.0, 'flying with the second stream')
        e = self.wait_controller(t0 + 1.0, lambda e: 'dropped waypoints' in e[2], 5.0, 'dropped waypoints diagnostic')
        g.second = None
        self.assertEqual(e[1], 1, e)                                   # WARN
        self.assertIn('tracking', e[2])
        self.assertGreater(counter(e, key), before, e)
        self.assertLess(worst[0], 1.0, '%s: the second stream moved the drone %.2f m sideways' % (name, worst[0]))
        self.assertGreater(g.command_rate(), 5.0)
        t_fixed = time.time()
        rec = self.recover(t_fixed)
        self.record(name, 'WARN "%s"; %s %d -> %d; largest sideways deviation %.2f m (the second stream is 7.5 m '
                    'away)' % (e[2], key, before, counter(e, key), worst[0]),
                    'not needed (the drone keeps tracking at %.1f m/s)' % (g.speed() or 0.0), rec)

    def test_03b_old_waypoint_stream(self):
        self.second_stream_case('old_waypoint_stream', 'old', 'stale stamp')

    def test_03c_out_of_order_waypoint(self):
        self.second_stream_case('out_of_order_waypoint', 'behind', 'out of order')

    def test_04_far_waypoint(self):
        self.limit_case('far_waypoint', 'far', 'target moved into the geofence', 'limited_geofence', 2.0)

    def test_04b_foreign_frame_waypoint(self):
        # nothing usable arrives: the stale-waypoint HOLD waypoint_timeout (1 s) after the last world waypoint
        self.hold_case('foreign_frame_waypoint', 'foreign', 'stale waypoint', 'dropped waypoints: foreign frame',
                       1.1)

    def test_05_nan_state(self):
        self.silent_case('nan_state', 'nan', 'non-finite state', 'rejected_states', 0.2)

    def test_06_stale_state(self):
        # detected state_timeout (0.5 s) after the last state sample (30 Hz: up to 1/30 s old when the relay
        # stops), at the next 10 Hz cycle
        self.silent_case('stale_state', 'off', 'stale state', 'stale_state', 0.65)

    def test_06b_solver_failure(self):
        g = self.g
        client = Client('/%s/mpc_controller' % DRONE, timeout=20.0)
        v = self.fly()
        before = counter(self.controller(0.0), 'solver_failed') or 0
        pos0, t0 = g.position(), time.time()
        self.assertEqual(client.update_configuration({'max_iter': 1})['max_iter'], 1)
        try:
            secs, dist = self.wait_stop(t0, pos0)
            e = self.wait_controller(t0 + 0.2, lambda e: 'solver' in e[2], 5.0, 'solver failure diagnostic')
            self.assertEqual(e[1], 2, e)                                  # ERROR: the controller itself failed
            self.assertIn('no command, firmware hover brake', e[2])
            self.assertEqual(g.command_rate(), 0.0, 'a failed solve sends nothing')
            self.assertGreater(counter(e, 'solver_failed'), before, e)
            bound = self.bound(v, 0.2)
            self.assertLess(dist, bound, 'solver_failure: %.1f m from %.1f m/s > bound %.1f m' % (dist, v, bound))
        finally:
            client.update_configuration({'max_iter': 4000})
        rec = self.recover(time.time())
        self.record('solver_failure', 'ERROR "%s"; solver_failed %d -> %d; commands 0 Hz' % (
            e[2], before, counter(e, 'solver_failed')),
            '%.1f m from %.1f m/s in %.1f s (bound %.1f m)' % (dist, v, secs, bound), rec)

    def test_06c_second_commander(self):
        g = self.g
        Command = piloting_command_class()
        seen = []       # (wall time, caller) of every command on the drone's command topic
        sub = rospy.Subscriber('/%s/drone/rpyt' % DRONE, Command, lambda m: seen.append(
            (time.time(), m._connection_header.get('callerid', ''))), queue_size=50)

        def callers(t0, t1):
            return sorted(set(c for t, c in list(seen) if t0 <= t < t1))
        me = rospy.get_name()
        commander = self.node_of('/%s/mpc_controller' % DRONE)    # its host's name outside a host
        self.fly()
        before = self.controller(0.0)
        # 1. a second MPC started on the flying drone: it hears the commands and never commands
        t0 = time.time()
        self.procs.start('rival', ['rosrun', 'anafi_sim', 'controller_node.py', '__name:=mpc_rival',
                                   '__ns:=/%s' % DRONE, '_controller:=mpc', '_state_topic:=fault/odom'], self.env)
        try:
            rival = [None]

            def rival_error():
                rival[0] = g.status('/%s/mpc_rival' % DRONE, t0)
                return rival[0] is not None and rival[0][1] == 2 and 'second commander' in rival[0][2]
            processes.require(rival_error, 60.0, 'the rival in ERROR', lambda: str(rival[0]))
            self.assertIn(commander, rival[0][2])
            t1 = time.time()
            main = self.wait_controller(t1, lambda e: 'mpc_rival' in e[3].get(
                'other publishers of the command topic', ''), 5.0, 'the rival listed by the controller')
            self.assertEqual((main[1], main[2]), (0, 'tracking'), main)
            time.sleep(3.0)
            only = callers(t1, time.time())
            self.assertEqual(only, [commander], 'commands from one node only')
            speed = g.speed() or 0.0
            self.assertGreater(speed, 0.6 * SPEED, 'the drone keeps flying')
            # 2. an operator takes over (this node publishes hover commands for 2 s): the controller yields
            teleop = rospy.Publisher('/%s/drone/rpyt' % DRONE, Command, queue_size=10)
            time.sleep(0.5)
            t2 = time.time()
            while time.time() - t2 < 2.0:
                teleop.publish(Command())
                time.sleep(0.1)
            e = self.wait_controller(t2, lambda e: e[1] == 2 and 'second commander' in e[2], 5.0,
                                     'the controller yields: ERROR second commander')
            self.assertIn(me, e[2])
            during = callers(t2 + 0.5, t2 + 2.0)
            self.assertEqual(during, [me], 'only the operator commands')
            teleop.unregister()
            t3 = time.time()
            rec = self.recover(t3)
            after = self.controller(t3)
            self.assertEqual(callers(time.time() - 1.0, time.time()), [commander])
        finally:
            sub.unregister()
            self.procs.stop('rival')
        self.record('second_commander', 'newcomer: the rival ERROR "%s", never commands; the controller OK '
                    '"tracking" (other publishers: %s), commands from %s only, the drone at %.1f m/s; operator: '
                    'the controller ERROR "%s" within 1 s, only the operator commands; second commander episodes '
                    '%s -> %s' % (rival[0][2], main[3].get('other publishers of the command topic'), only[0], speed,
                                  e[2], counter(before, 'second commander episodes'),
                                  counter(after, 'second commander episodes')),
                    'not needed (one commander at any time; the operator\'s commands fly the drone)', rec)

    def _interface(self, since=0.0):
        return self.g.status('/%s/interface' % DRONE, since)

    def test_07_cli_killed(self):
        g = self.g
        self.fly()
        cli = self.cli_of('/%s/interface' % DRONE, self.telemetry_port)
        before = self._interface()
        t0 = time.time()
        cli.kill()
        ok = [None]

        def back():      # a new process, samples published again, OK (diagnostics at 1 Hz: an ERROR may not show)
            ok[0] = self._interface(t0)
            return ok[0] is not None and ok[0][1] == 0 and ok[0][3]['process pid'] != str(cli.pid) and \
                counter(ok[0], 'samples published') > counter(before, 'samples published')
        processes.require(back, RECOVERY_TIME, 'interface publishing again with a new process', lambda: str(ok[0]))
        self.assertEqual(counter(ok[0], 'process restarts'), counter(before, 'process restarts') + 1, ok[0])
        self.assertEqual(ok[0][3]['process last exit code'], '-9', ok[0])
        self.assertEqual(self.controller(t0)[2], 'tracking', 'the controller flies on the estimate')
        self.record('cli_killed', 'process restarts %d -> %d (last exit code -9); OK again "%s" with pid %s; the '
                    'controller keeps tracking' % (counter(before, 'process restarts'), counter(ok[0], 'process restarts'),
                                                   ok[0][2], ok[0][3]['process pid']),
                    'not needed (the drone keeps tracking at %.1f m/s)' % g.speed(), ok[0][0] - t0)

    def test_07b_cli_hung(self):
        g = self.g
        self.fly()
        cli = self.cli_of('/%s/interface' % DRONE, self.telemetry_port)
        before = self._interface()
        t0 = time.time()
        cli.suspend()                    # SIGSTOP: prints nothing, does not exit
        err = [None]

        def error_seen():
            err[0] = self._interface(t0)
            return err[0] is not None and err[0][1] == 2
        processes.require(error_seen, 5.0, 'interface ERROR while the CLI hangs', lambda: str(err[0]))
        ok = [None]

        def back():
            ok[0] = self._interface(err[0][0])
            return ok[0] is not None and ok[0][1] == 0
        processes.require(back, RECOVERY_TIME, 'interface OK after the hang', lambda: str(ok[0]))
        self.assertEqual(counter(ok[0], 'process hangs'), counter(before, 'process hangs') + 1, ok[0])
        self.assertNotEqual(ok[0][3]['process pid'], str(cli.pid))
        self.assertEqual(self.controller(t0)[2], 'tracking', 'the controller flies on the estimate')
        self.record('cli_hung', 'ERROR "%s"; process hangs %d -> %d (killed after restart_timeout 2 s), OK again'
                    % (err[0][2], counter(before, 'process hangs'), counter(ok[0], 'process hangs')),
                    'not needed (the drone keeps tracking)', ok[0][0] - t0)

    def test_08_telemetry_garbage(self):
        g = self.g
        e = [None]

        def flowing():
            # each start of the command reads the garbage once: a status taken just after a restart of the tool
            # (its stream ended) counts the start before the garbage it reads, so wait for the two to agree
            e[0] = g.status('/garbage/interface')
            return e[0] is not None and e[0][1] == 0 and (counter(e[0], 'process oversize lines') or 0) >= 1 \
                and counter(e[0], 'process oversize lines') == counter(e[0], 'process starts')
        processes.require(flowing, 20.0, 'the garbage interface OK with counted lines', lambda: str(e[0]))
        malformed = counter(e[0], 'parse malformed')
        oversize = counter(e[0], 'process oversize lines')
        starts = counter(e[0], 'process starts')     # each start of the command prints the garbage once
        self.assertEqual(oversize, starts, e[0])
        self.assertGreaterEqual(malformed, 2 * starts, e[0])     # 'garbage line' + '1_000'
        self.assertGreater(counter(e[0], 'samples published'), 100, e[0])
        self.record('telemetry_garbage', 'OK "%s"; per start of the command (%d): parse malformed %d, process '
                    'oversize lines %d; samples published %s' % (e[0][2], starts, malformed, oversize,
                                                                 e[0][3]['samples published']), 'not needed', None)

    def test_08a_stderr_flood(self):
        g = self.g
        e, ref = [None], [None]

        def flooded():
            e[0], ref[0] = g.status('/flood/interface'), g.status('/garbage/interface')
            return e[0] is not None and ref[0] is not None and e[0][1] == 0 \
                and e[0][3].get('process last stderr') == 'flood done'
        processes.require(flooded, 60.0, 'the flood interface OK after the flood', lambda: str(e[0]))
        rss = dict((n, psutil.Process(self.pid_of('/%s/interface' % n)).memory_info().rss / 2.0 ** 20)
                   for n in ('flood', 'garbage'))
        flood_bytes = counter(e[0], 'process stderr bytes')
        self.assertGreaterEqual(flood_bytes, FLOOD_MB * 2 ** 20, e[0])
        self.assertLess(rss['flood'], rss['garbage'] + 30.0, rss)     # the flood is not kept
        self.assertGreater(counter(e[0], 'samples published'), 100, e[0])
        self.record('stderr_flood', 'OK "%s"; process stderr bytes %d (%d oversize lines), last stderr "%s"; '
                    'interface RSS %.0f MB (%s without the flood: %.0f MB); samples published %s'
                    % (e[0][2], flood_bytes, counter(e[0], 'process stderr oversize lines'),
                       e[0][3].get('process last stderr'), rss['flood'],
                       'the ground-truth host, two interfaces and the mirror,' if SHARED_LAYOUT else 'an interface',
                       rss['garbage'],
                       e[0][3]['samples published']), 'not needed', None)

    def test_08d_hostile_command(self):
        g = self.g
        name = '/garbage/interface'
        marker = os.path.join(self.workdir, 'pwned')
        original = rospy.get_param(name + '/telemetry_command')

        node = self.node_of(name)     # the ground-truth host in the shared layout
        status = name + (': hosted instance' if SHARED_LAYOUT else ': bad parameters')

        def shutdown():
            before = processes.node_pid(node, self.uri)

            def sent():
                # the node may end before its reply is written (a dropped connection): it was shut down once its
                # process is gone, and a respawned one is never shut down again
                if before is not None and processes.node_pid(node, self.uri) not in (None, before):
                    return True
                try:
                    uri = rosgraph.Master(rospy.get_name()).lookupNode(node)
                    xmlrpc.client.ServerProxy(uri).shutdown(rospy.get_name(), 'fault matrix: hostile_command')
                    return True
                except (OSError, rosgraph.MasterError):
                    return False
            processes.require(sent, 10.0, 'the XML-RPC shutdown of %s' % node,
                              lambda: self.procs.log_tail('roslaunch', 30))
        old = processes.node_pid(node, self.uri)
        self.assertIsNotNone(old, '%s is not running:\n%s' % (node, self.procs.log_tail('roslaunch', 30)))
        evil = os.path.join(self.workdir, 'EVIL')      # the file name of Sphinx's tool, anywhere else
        os.makedirs(evil, exist_ok=True)
        with open(os.path.join(evil, 'tlm-data-logger'), 'w') as f:
            f.write('#!/bin/sh\ntouch %s\n' % marker)
        os.chmod(os.path.join(evil, 'tlm-data-logger'), 0o755)
        rospy.set_param(name + '/telemetry_command', '%s/tlm-data-logger -r 0 inet:127.0.0.1:1' % evil)
        t0 = time.time()
        shutdown()
        e, pid = [None], [None]

        def refused():
            e[0], pid[0] = g.status(status, t0), processes.node_pid(node, self.uri)
            return e[0] is not None and e[0][1] == 2 and 'refused' in e[0][2] and pid[0] not in (None, old)
        processes.require(refused, 30.0, 'the respawned interface refusing the command', lambda: str(e[0]))
        self.assertIn("telemetry_command: refused to run '%s/tlm-data-logger': not one of the allowed tools" % evil,
                      e[0][2])
        time.sleep(3.0)
        self.assertEqual(processes.node_pid(node, self.uri), pid[0], 'up in ERROR, not respawned again')
        self.assertFalse(os.path.exists(marker), 'the hostile command ran')
        rospy.set_param(name + '/telemetry_command', original)
        t_fixed = time.time()
        shutdown()
        ok = [None]

        def flowing():
            ok[0] = g.status(name + ': ground truth interface', t_fixed)
            return ok[0] is not None and ok[0][1] == 0 and 'publishing' in ok[0][2]
        processes.require(flowing, 30.0, 'the interface reading the telemetry again', lambda: str(ok[0]))
        self.record('hostile_command', '%srespawned (pid %d -> %d), ERROR "%s", same pid 3 s later, %s not created; '
                    'parameter put back: OK "%s"' % ('%s (host of %s) ' % (node, name) if SHARED_LAYOUT else '', old,
                                                     pid[0], e[0][2], os.path.basename(marker), ok[0][2]),
                    'not needed (the drone\'s own interface %s)' % (
                        'restarted with its host; the drone flies on its estimate' if SHARED_LAYOUT else 'untouched'),
                    ok[0][0] - t_fixed)

    def test_08e_fleet_cap(self):
        from anafi_sim.launch_check import cap_cache_path, machine_cap
        env = dict(self.env, ROS_MASTER_URI='http://127.0.0.1:%d' % processes.free_port())   # no master there
        t0 = time.time()
        out = subprocess.run(['roslaunch', 'anafi_sim', 'fleet.launch', 'drones:=50', 'layout:=%s' % LAYOUT], env=env,
                             stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             universal_newlines=True, timeout=120)
        seconds = time.time() - t0
        lines = [line for line in out.stdout.splitlines() if line.startswith('launch argument drones:=50')]
        self.assertNotEqual(out.returncode, 0, out.stdout[-2000:])
        self.assertEqual(len(lines), 1, out.stdout[-2000:])
        cap = machine_cap(LAYOUT, cache_path=cap_cache_path(env))   # this machine's, as the launch check reads it
        self.assertIn('more than the fleet cap of %d' % cap.drones, lines[0])
        self.assertNotIn('started with pid', out.stdout)               # nothing started, not even a master
        self.record('fleet_cap', 'exit status %d after %.1f s, nothing started: "%s"' % (out.returncode, seconds,
                                                                                        lines[0]),
                    'not needed', None)

    def test_08b_simulator_restart(self):
        g = self.g
        self.fly()
        host = self.node_of('/%s/anafi_sim' % DRONE)     # the drones host in the shared layout
        old = processes.node_pid(host, self.uri)
        before = self._interface()
        ctl_before = self.controller(0.0)
        t0 = time.time()
        os.kill(old, signal.SIGKILL)
        err = [None]

        def interface_error():
            err[0] = self._interface(t0)
            return err[0] is not None and err[0][1] == 2
        processes.require(interface_error, 8.0, 'interface ERROR without telemetry', lambda: str(err[0]))
        def stale_cycles(e):
            return (counter(e, 'stale_state') or 0) + (counter(e, 'no_state') or 0)

        # the 1 Hz diagnostic can miss a short gap (the respawned simulator is back within ~1-2 s);
        # its cumulative counters cannot: the controller was silent on the stale state if they grew
        silent = self.wait_controller(t0, lambda e: 'stale state' in e[2] or 'no state' in e[2]
                                      or stale_cycles(e) > stale_cycles(ctl_before), 8.0,
                                      'controller silent on the stale state')
        new = [None]
        processes.require(lambda: new.__setitem__(0, processes.node_pid(host, self.uri))
                        or (new[0] not in (None, old)), 20.0, 'the simulator respawned')
        with g.lock:
            g.truth = []                  # the old flight's positions are not the new flight's
        processes.require(lambda: g.position() is not None, 20.0, 'the new simulator flying (sim/truth)')
        t_back = g.truth[0][0]
        ok = [None]

        def interface_ok():
            ok[0] = self._interface(t_back)
            return ok[0] is not None and ok[0][1] == 0 and \
                counter(ok[0], 'samples published') > counter(before, 'samples published')
        processes.require(interface_ok, 8.0, 'interface OK after the new simulator', lambda: str(ok[0]))
        iface_rec = ok[0][0] - t_back
        self.assertLess(iface_rec, 5.0 + 1.0, ok[0])     # + the 1 Hz diagnostics
        t_fixed = time.time()
        tracking_at = t_fixed + self.recover(t_fixed)
        self.record('simulator_restart', 'interface ERROR "%s", controller silent (%s); '
                    'simulator respawned (%spid %d -> %d); interface OK "%s" %.1f s after the new simulator\'s first '
                    'sample (process restarts %d -> %d)'
                    % (err[0][2], 'respawned with the host: "%s"' % silent[2] if SHARED_LAYOUT else
                       'stale/no-state cycles %d -> %d' % (stale_cycles(ctl_before), stale_cycles(silent)),
                       'the drones host %s with the controller, ' % host if SHARED_LAYOUT else '', old, new[0],
                       ok[0][2], iface_rec,
                       counter(before, 'process restarts'), counter(ok[0], 'process restarts')),
                    'the simulated drone restarts (a new flight); no command meanwhile',
                    max(ok[0][0], tracking_at) - t_back)

    def test_08d_foreign_stream(self):
        from anafi_sim.telemetry.protocol import FIELDS, TelemetrySample
        from anafi_sim.telemetry.server import TelemetryServer
        g = self.g
        self.fly()
        param = '/%s/anafi_sim/telemetry_bound_port' % DRONE
        own_port = rospy.get_param(param)
        own_id = rospy.get_param('/%s/anafi_sim/telemetry_stream_id' % DRONE)
        other = TelemetryServer('127.0.0.1', 0, stream_id=own_id % (2 ** 31 - 1) + 1)
        other.start()
        stop = threading.Event()
        seen = {'other': 0, 'total': 0}

        def serve():            # the other drone hovers at x = 50 m
            t = 0.0
            values = dict((f, 0.0) for f in FIELDS)
            while not stop.is_set():
                t += 0.01
                values.update(x=50.0, z=3.0, timestamp=t)
                other.publish(TelemetrySample(**values))
                time.sleep(0.01)

        def on_truth(msg):
            seen['total'] += 1
            if abs(msg.pose.pose.position.x - 50.0) < 1.0:
                seen['other'] += 1
        server = threading.Thread(target=serve, daemon=True)
        server.start()
        sub = rospy.Subscriber('/%s/ground_truth/odom' % DRONE, Odometry, on_truth, queue_size=100)
        try:
            before = self._interface()
            t0 = time.time()
            rospy.set_param(param, other.port)         # a stale / wrong port: the other drone's stream
            self.cli_of('/%s/interface' % DRONE, own_port).kill()
            err = [None]

            def refused():
                err[0] = self._interface(t0)
                return err[0] is not None and err[0][1] == 2 and 'another drone' in err[0][2]
            processes.require(refused, 10.0, 'interface ERROR refusing the other stream', lambda: str(err[0]))
            time.sleep(2.0)
            self.assertEqual(seen['other'], 0, 'ground truth of the other drone was published')
            refused_n = counter(err[0], 'refused samples of another stream')
            self.assertGreater(refused_n, 0, err[0])
            self.assertEqual(self.controller(t0)[2], 'tracking', 'the controller flies on the estimate')
            t_fixed = time.time()
            rospy.set_param(param, own_port)           # the interface restarts the refused stream by itself
            ok = [None]

            def back():
                ok[0] = self._interface(t_fixed)
                return ok[0] is not None and ok[0][1] == 0 and \
                    counter(ok[0], 'samples published') > counter(before, 'samples published')
            processes.require(back, RECOVERY_TIME + 5.0, 'interface OK on its own stream', lambda: str(ok[0]))
        finally:
            stop.set()
            sub.unregister()
            other.stop()
            rospy.set_param(param, own_port)
        self.assertEqual(seen['other'], 0)
        self.record('foreign_stream', 'ERROR "%s"; no ground truth of the other drone published (0 of %d messages '
                    'during the fault); OK again on its own stream' % (err[0][2], seen['total']),
                    'not needed (the drone keeps tracking on its estimate)', ok[0][0] - t_fixed)

    def test_08e_taken_port(self):
        port = rospy.get_param('/%s/anafi_sim/telemetry_bound_port' % DRONE)
        own_id = rospy.get_param('/%s/anafi_sim/telemetry_stream_id' % DRONE)
        script = os.path.join(paths.package_dir(), 'anafi_sim', 'scripts', 'anafi_sim_node.py')
        log = os.path.join(self.workdir, 'taken_port.log')
        t0 = time.time()
        proc = processes.start([sys.executable, script, '__name:=anafi_sim', '__ns:=/taken',
                              '_telemetry_port:=%d' % port], env=self.env, log=log)
        fatal, took = [], [None]

        def said_fatal():
            fatal[:] = [line for line in open(log).read().splitlines() if 'FATAL' in line]
            took[0] = time.time() - t0
            return bool(fatal) or proc.poll() is not None
        try:
            processes.require(said_fatal, 30.0, 'the second simulator\'s FATAL line', lambda: open(log).read()[-2000:])
            time.sleep(2.0)
            running = proc.poll() is None       # up in ERROR (a respawned node would only fail again)
        finally:
            processes.stop(proc)
        text = open(log).read()
        self.assertTrue(running, 'the second simulator exited instead of staying up in ERROR: ' + text[-2000:])
        self.assertTrue(fatal and '~telemetry_port' in fatal[-1] and str(port) in fatal[-1], text[-2000:])
        ok = [None]

        def fine():
            ok[0] = self._interface(time.time() - 0.5)
            return ok[0] is not None and ok[0][1] == 0
        processes.require(fine, 5.0, 'the first interface still OK', lambda: str(ok[0]))
        self.assertEqual(rospy.get_param('/%s/anafi_sim/telemetry_stream_id' % DRONE), own_id)
        self.assertEqual(ok[0][3]['expected stream id'], str(own_id))
        self.record('taken_port', 'second simulator: one FATAL line after %.1f s, then up in ERROR (no respawn '
                    'loop): "%s"; the first interface OK "%s", stream id unchanged'
                    % (took[0], fatal[-1].split('bad parameters: ')[-1][:200], ok[0][2]),
                    'not needed (nothing else changes)', None)

    def _mirror(self, since=0.0):
        return self.g.status('/%s/gazebo_mirror' % DRONE, since)

    def test_08c_world_killed(self):
        if SHARED_LAYOUT and self.node_of('/gazebo') != '/gazebo':
            return self.world_host_killed()
        g = self.g
        self.fly()
        models = ('anafi', 'anafi_camera')
        processes.require(lambda: set(models) <= set(g.models[1]), 20.0, 'both models in the world',
                        lambda: str(g.models))
        mirror = self.pid_of('/%s/gazebo_mirror' % DRONE)
        world = processes.node_pid('/gazebo', self.uri)
        processes.require(lambda: self._mirror() is not None, 10.0, 'mirror diagnostics')
        before = self._mirror()
        commands0 = g.command_rate()
        t0 = time.time()
        os.kill(world, signal.SIGKILL)
        bad = [None]
        ok = [None]

        def back():
            e = self._mirror(t0)
            if e is not None and e[1] != 0 and bad[0] is None:
                bad[0] = e
            ok[0] = e
            return bad[0] is not None and e is not None and e[1] == 0 and set(models) <= set(g.models[1]) \
                and g.models[0] > t0 and processes.node_pid('/gazebo', self.uri) not in (None, world)
        processes.require(back, 20.0, 'mirror reporting the lost world, then OK with both models back',
                        lambda: 'first non-OK %s, last %s, models %s' % (bad[0], ok[0], g.models))
        self.assertEqual(self.pid_of('/%s/gazebo_mirror' % DRONE), mirror, 'the mirror died')
        lost = counter(ok[0], 'world restarts') + counter(ok[0], 'world losses')
        self.assertGreater(lost, counter(before, 'world restarts') + counter(before, 'world losses'), ok[0])
        self.assertGreaterEqual(counter(ok[0], 'respawns'), counter(before, 'respawns') + 2, ok[0])
        tracking = self.controller(t0)
        self.assertEqual(tracking[2], 'tracking', 'the controller does not depend on the world')
        self.assertGreater(g.command_rate(), 5.0)
        self.record('world_killed', 'mirror %s "%s", then OK "%s" (same pid %d); world restarts + losses %d -> %d, '
                    'respawns %d -> %d; controller "%s", commands %.0f Hz (before %.0f Hz)'
                    % ({1: 'WARN', 2: 'ERROR'}.get(bad[0][1], bad[0][1]), bad[0][2], ok[0][2], mirror,
                       counter(before, 'world restarts') + counter(before, 'world losses'), lost,
                       counter(before, 'respawns'), counter(ok[0], 'respawns'), tracking[2], g.command_rate(),
                       commands0),
                    'not needed (the drone keeps tracking at %.1f m/s)' % (g.speed() or 0.0), ok[0][0] - t0)

    def world_host_killed(self):
        """world_killed in the shared layout: the world's process is the ground-truth host (with the mirror)."""
        g = self.g
        self.fly()
        models = ('anafi', 'anafi_camera')
        processes.require(lambda: set(models) <= set(g.models[1]), 20.0, 'both models in the world',
                          lambda: str(g.models))
        host = self.node_of('/gazebo')
        self.assertEqual(host, self.node_of('/%s/gazebo_mirror' % DRONE))
        old = processes.node_pid(host, self.uri)
        commands0 = g.command_rate()
        t0 = time.time()
        os.kill(old, signal.SIGKILL)
        ok, new = [None], [None]

        def back():
            ok[0], new[0] = self._mirror(t0), processes.node_pid(host, self.uri)
            return ok[0] is not None and ok[0][1] == 0 and set(models) <= set(g.models[1]) and g.models[0] > t0 \
                and new[0] not in (None, old)
        processes.require(back, 30.0, 'the host respawned, the world with both models, the mirror OK',
                          lambda: 'mirror %s, models %s, host pid %s' % (ok[0], g.models, new[0]))
        for m in models:      # the new mirror's models, in the new world (model_states since the kill: back())
            self.assertIn('%s=spawned' % m, ok[0][3].get('models', ''), ok[0])
        tracking = self.controller(t0)
        self.assertEqual(tracking[2], 'tracking', 'the controller does not depend on the world')
        self.assertGreater(g.command_rate(), 5.0)
        self.record('world_killed', 'the ground-truth host %s (world, interfaces, mirror) killed and respawned '
                    '(pid %d -> %d); the world back with both models, the new mirror OK "%s" (models %s); controller '
                    '"%s", commands %.0f Hz (before %.0f Hz)'
                    % (host, old, new[0], ok[0][2], ok[0][3].get('models'), tracking[2], g.command_rate(),
                       commands0),
                    'not needed (the drone keeps tracking at %.1f m/s)' % (g.speed() or 0.0), ok[0][0] - t0)

    # -- the reproductions of the security review (each refused or bounded with one clear line)
    def fence(self):
        """(centre (x, y), radius) of the controller's geofence, from its diagnostics."""
        e = self.wait_controller(0.0, lambda e: e[3].get('geofence centre (take-off point) [m]', 'none yet')
                                 != 'none yet', 10.0, 'the controller\'s geofence on /diagnostics')
        x, y = (float(v) for v in e[3]['geofence centre (take-off point) [m]'].split())
        return (x, y), float(e[3]['geofence radius [m]'])

    def test_08f_velocity_stream(self):
        g = self.g
        v0 = self.fly()
        (cx, cy), radius = self.fence()
        self.assertEqual(radius, FENCE)
        before = counter(self.controller(0.0), 'limiting') or 0
        pos0, t0 = g.position(), time.time()
        g.wp_mode = 'vx'

        def legitimate_again():     # should the row fail: the legitimate waypoint for the next rows
            if g.wp_mode == 'vx':
                g.point, g.wp_mode = pos0, 'point'
        self.addCleanup(legitimate_again)
        seen = {'far': 0.0, 'far_estimate': 0.0, 'vmax': 0.0, 'tracking': [], 'limiting': None,
                'z': (pos0[2], pos0[2])}

        def stopped_at_fence():
            p, v, q = g.position(), g.speed() or 0.0, g.estimate
            seen['far'] = max(seen['far'], math.hypot(p[0] - cx, p[1] - cy))
            seen['vmax'] = max(seen['vmax'], g.truth_speed or 0.0)
            seen['far_estimate'] = max(seen['far_estimate'], math.hypot(q[0] - cx, q[1] - cy))
            seen['z'] = (min(seen['z'][0], p[2]), max(seen['z'][1], p[2]))
            e = self.controller(t0 + 1.5)           # the first 1 Hz diagnostic may be the cycle before the fault
            if e is not None:
                if 'tracking' in e[2] and not e[2].startswith('limiting'):
                    seen['tracking'].append(e[2])
                elif e[2].startswith('limiting') and seen['limiting'] is None:
                    seen['limiting'] = e
            return seen['limiting'] is not None and time.time() - t0 > 5.0 and v < STOP_SPEED
        processes.require(stopped_at_fence, 2.0 * FENCE / 10.0 + 40.0, 'the drone stopped by the fence',
                          lambda: 'speed %s, position %s, controller %s' % (g.speed(), g.position(),
                                                                         self.controller(0.0)))
        e = self.wait_controller(time.time() - 1.5, lambda e: True, 10.0, 'the controller\'s diagnostics')
        self.assertEqual(e[1], 1, e)                                    # WARN
        self.assertTrue(e[2].startswith('limiting: '), e)
        self.assertIn('reference speed 1e+06 m/s', e[2])
        self.assertEqual(seen['tracking'], [], 'the health said tracking under the 1e6 stream')
        self.assertGreater(counter(e, 'limiting'), before, e)
        self.assertGreater(g.command_rate(3.0), 5.0, 'limiting keeps commanding')
        self.assertLessEqual(seen['far'], radius, 'the drone left the geofence (the estimate: %.2f m)'
                             % seen['far_estimate'])
        self.assertLess(seen['vmax'], 10.0 * 1.1, 'faster than the envelope\'s 10 m/s')
        at_fence = g.position()
        # the legitimate stream again: the waypoint where the fault began
        g.point = pos0
        t1 = time.time()
        dist = math.sqrt(sum((a - b) ** 2 for a, b in zip(at_fence, pos0)))
        allowed = dist / 10.0 + 15.0
        back = [None]

        def returned():
            p = g.position()
            back[0] = math.sqrt(sum((a - b) ** 2 for a, b in zip(p, pos0)))
            return back[0] < 1.0 and (g.speed() or 9.0) < STOP_SPEED
        g.wp_mode = 'point'
        processes.require(returned, allowed + 60.0, 'the drone back at its waypoint',
                          lambda: '%.1f m from it; controller %s' % (back[0], self.controller(0.0)))
        took = time.time() - t1
        self.assertLess(took, allowed, 'back after %.1f s > %.1f s (%.1f m at 10 m/s + 15 s)' % (took, allowed, dist))
        rec = self.recover(time.time())
        self.record('velocity_stream', 'WARN "%s" (no "tracking" under the stream); limiting %d -> %d; commands %.0f '
                    'Hz; at most %.1f m/s, %.1f m from the take-off point (fence %.0f m); the legitimate waypoint '
                    'reached again after %.1f s from %.1f m away (allowed %.1f s)'
                    % (e[2], before, counter(e, 'limiting'), g.command_rate(3.0), seen['vmax'], seen['far'], radius,
                       took, dist, allowed),
                    'stopped inside the fence (%.1f m of %.0f m), from %.1f m/s' % (seen['far'], radius, v0),
                    took + rec)

    def test_08g_second_waypoint_source(self):
        g = self.g
        self.fly()
        other = 'dropped waypoints: another publisher than the waypoint source'
        order = 'dropped waypoints: out of order'
        first = self.controller(0.0)
        before = (counter(first, other) or 0, counter(first, order) or 0)
        y0 = g.track[2]
        worst, notes, warned = [0.0], [], {}
        for mode in ('zero', 'future'):
            t0 = time.time()
            b = counter(self.controller(0.0), other) or 0
            name = 'second_source_%s' % mode
            self.procs.start(name, [sys.executable, '-c', SECOND_SOURCE.format(drone=DRONE, mode=mode)], self.env)
            try:
                def published():
                    p, e = g.position(), self.controller(t0)
                    worst[0] = max(worst[0], abs(p[1] - y0))
                    if e is not None and 'another publisher than the waypoint source' in e[2]:
                        warned[mode] = e        # the WARN of a diagnostic period with drops
                    return 'PUBLISHED' in open(self.procs.log_path(name)).read()
                processes.require(published, 60.0, 'the second stream (%s) published for 4 s' % mode,
                                  lambda: self.procs.log_tail(name, 20))
            finally:
                self.procs.stop(name)
            e = self.wait_controller(t0, lambda e: (counter(e, other) or 0) > b + 10, 5.0,
                                     'the second stream (%s) dropped as another publisher' % mode)
            self.assertIn(mode, warned, 'no WARN naming the drops of the second stream (%s)' % mode)
            self.assertEqual(warned[mode][1], 1, warned[mode])
            notes.append('%s: WARN "%s"' % ('stamped 0, frame \'\'' if mode == 'zero' else 'stamped +0.9 s',
                                            warned[mode][2]))
        self.assertEqual(counter(e, order) or 0, before[1], 'the legitimate stream was dropped as out of order')
        self.assertLess(worst[0], 1.0, 'the second stream moved the drone %.2f m sideways' % worst[0])
        self.assertGreater(g.command_rate(), 5.0)
        rec = self.recover(time.time())
        self.record('second_waypoint_source', '%s; %s %d -> %d, out of order %d -> %d; largest sideways deviation '
                    '%.2f m (the second stream is 7.5 m away); waypoint source %s'
                    % ('; '.join(notes), other, before[0], counter(e, other), before[1], counter(e, order) or 0,
                       worst[0], e[3].get('waypoint source')),
                    'not needed (the drone keeps tracking at %.1f m/s)' % (g.speed() or 0.0), rec)

    def test_08h_claimed_commander(self):
        commander = self.node_of('/%s/mpc_controller' % DRONE)    # its host's name in the shared layout
        self.fly()
        t0 = time.time()
        self.procs.start('imposter', [sys.executable, '-c', IMPOSTER.format(drone=DRONE, claim=commander)], self.env)
        try:
            e = self.wait_controller(t0, lambda e: e[1] == 2 and 'second commander' in e[2], 60.0,
                                     'the controller standing down: ERROR second commander')
            self.assertIn('(claims to be %s)' % commander, e[2])
            processes.require(lambda: 'PUBLISHED' in open(self.procs.log_path('imposter')).read(), 30.0,
                              'the imposter done', lambda: self.procs.log_tail('imposter', 20))
        finally:
            self.procs.stop('imposter')
        rec = self.recover(time.time())
        self.record('claimed_commander', 'ERROR "%s"; second commander episodes %s' % (
            e[2], e[3].get('second commander episodes')),
            'not needed (the controller stands down; the other node\'s commands fly the drone meanwhile)', rec)

    def test_08i_huge_telemetry(self):
        from anafi_sim.telemetry.protocol import FIELDS, TelemetrySample
        from anafi_sim.telemetry.server import TelemetryServer
        g = self.g
        self.fly()
        param = '/%s/anafi_sim/telemetry_bound_port' % DRONE
        own_port = rospy.get_param(param)
        own_id = rospy.get_param('/%s/anafi_sim/telemetry_stream_id' % DRONE)
        huge = TelemetryServer('127.0.0.1', 0, stream_id=own_id)
        huge.start()
        stop = threading.Event()
        seen = {'huge': 0, 'total': 0}

        def serve():
            t = 0.0
            values = dict((f, 0.0) for f in FIELDS)
            while not stop.is_set():
                t += 0.01
                values.update(x=1e308, z=3.0, timestamp=t)
                huge.publish(TelemetrySample(**values))
                time.sleep(0.01)

        def on_truth(msg):
            seen['total'] += 1
            if not abs(msg.pose.pose.position.x) < 1e5:
                seen['huge'] += 1
        threading.Thread(target=serve, daemon=True).start()
        sub = rospy.Subscriber('/%s/ground_truth/odom' % DRONE, Odometry, on_truth, queue_size=100)
        key = 'rejected samples beyond physical bounds'
        try:
            before = self._interface()
            t0 = time.time()
            rospy.set_param(param, huge.port)
            self.cli_of('/%s/interface' % DRONE, own_port).kill()
            err = [None]

            def rejected():
                err[0] = self._interface(t0)
                return err[0] is not None and (counter_lead(err[0], key) or 0) > (counter_lead(before, key) or 0)
            processes.require(rejected, 15.0, 'the interface rejecting the samples', lambda: str(err[0]))
            time.sleep(2.0)
            err[0] = self._interface(time.time() - 1.5) or err[0]
            self.assertEqual(seen['huge'], 0, 'ground truth beyond physical bounds was published')
            self.assertEqual(self.controller(t0)[2], 'tracking', 'the controller flies on the estimate')
            t_fixed = time.time()
            rospy.set_param(param, own_port)
            self.cli_of('/%s/interface' % DRONE, huge.port).kill()
            ok = [None]

            def back():
                ok[0] = self._interface(t_fixed)
                return ok[0] is not None and ok[0][1] == 0 and \
                    counter(ok[0], 'samples published') > counter(err[0], 'samples published')
            processes.require(back, RECOVERY_TIME + 5.0, 'interface OK on its own stream', lambda: str(ok[0]))
        finally:
            stop.set()
            sub.unregister()
            huge.stop()
            rospy.set_param(param, own_port)
        self.assertEqual(seen['huge'], 0)
        self.record('huge_telemetry', '%s "%s"; %s: %s; no ground truth beyond the bounds published (0 of %d '
                    'messages); OK again on its own stream' % ({0: 'OK', 1: 'WARN', 2: 'ERROR'}.get(err[0][1]),
                                                               err[0][2], key, err[0][3].get(key), seen['total']),
                    'not needed (the drone keeps tracking on its estimate)', ok[0][0] - t_fixed)

    def start_node(self, name, argv, params=()):
        """A node of this test's own (argv after the interpreter), its log file; ``params`` set first."""
        for key, value in params:
            rospy.set_param(key, value)
        log = os.path.join(self.workdir, name + '.log')
        proc = processes.start([sys.executable] + argv, env=self.env, log=log)
        return proc, log

    def fatal_lines(self, log):
        with open(log) as f:
            return [line for line in f.read().splitlines() if 'FATAL' in line]

    def test_08j_file_parameters(self):
        outside = '/dev/shm' if os.access('/dev/shm', os.W_OK) else '/var/tmp'
        folder = tempfile.mkdtemp(prefix='fault_matrix_secret_', dir=outside)
        secret = 'secret_%d_line' % os.getpid()
        rosout = []
        sub = rospy.Subscriber('/rosout_agg', Log, lambda m: rosout.append(m.msg), queue_size=200)
        try:
            path = os.path.join(folder, 'model.yaml')
            with open(path, 'w') as f:
                f.write('mass: 0.5\n%s: 1\n' % secret)
            sim, sim_log = self.start_node('file_sim', [paths.data_path('scripts', 'anafi_sim_node.py'),
                                                        '__name:=anafi_sim', '__ns:=/repro_file'],
                                           [('/repro_file/anafi_sim/model_file', path)])
            gen, gen_log = self.start_node('file_gen', [paths.data_path('scripts', 'trajectory_generator.py'),
                                                        '__name:=trajectory_generator', '__ns:=/repro_file'],
                                           [('/repro_file/trajectory_generator/scenario_file', path),
                                            ('/repro_file/trajectory_generator/wait_for_flying', False)])
            try:
                processes.require(lambda: self.fatal_lines(sim_log) and gen.poll() is not None, 60.0,
                                  'the simulator\'s FATAL line and the generator\'s exit',
                                  lambda: open(sim_log).read()[-1500:] + open(gen_log).read()[-1500:])
                time.sleep(2.0)
                sim_up = sim.poll() is None
            finally:
                processes.stop(sim)
                processes.stop(gen)
            texts = dict((n, open(l).read()) for n, l in (('simulator', sim_log), ('generator', gen_log)))
            fatal = dict((n, [line for line in t.splitlines() if 'FATAL' in line]) for n, t in texts.items())
            self.assertTrue(sim_up, 'the simulator exited instead of staying up in ERROR: ' + texts['simulator'][-2000:])
            self.assertEqual(len(fatal['simulator']), 1, texts['simulator'][-2000:])
            self.assertIn('model_file', fatal['simulator'][0])
            self.assertIn('refused', fatal['simulator'][0])
            self.assertEqual(gen.returncode, 1, texts['generator'][-2000:])
            self.assertEqual(len(fatal['generator']), 1, texts['generator'][-2000:])
            self.assertIn('scenario_file', fatal['generator'][0])
            self.assertIn('refused', fatal['generator'][0])
            time.sleep(1.0)
            for n, t in texts.items():
                self.assertNotIn(secret, t, 'the %s echoed the file' % n)
            self.assertFalse([m for m in rosout if secret in m], 'the file on /rosout_agg')
            for root, _, files in os.walk(self.env['ROS_LOG_DIR']):
                for name in files:
                    with open(os.path.join(root, name), errors='replace') as f:
                        self.assertNotIn(secret, f.read(), 'the file in the log %s' % name)
        finally:
            sub.unregister()
            shutil.rmtree(folder, ignore_errors=True)
        self.record('file_parameters', 'simulator (up in ERROR): "%s"; generator (exit 1): "%s"; the file\'s text in '
                    'no log, not on /rosout_agg' % (fatal['simulator'][0].split(']: ', 1)[-1][:300],
                                                    fatal['generator'][0].split(']: ', 1)[-1][:300]),
                    'not needed (nothing read)', None)

    def test_08k_remote_telemetry_host(self):
        sim, log = self.start_node('remote_sim', [paths.data_path('scripts', 'anafi_sim_node.py'), '__name:=anafi_sim',
                                                  '__ns:=/repro_remote'],
                                   [('/repro_remote/anafi_sim/telemetry_host', '0.0.0.0')])
        try:
            processes.require(lambda: self.fatal_lines(log) or sim.poll() is not None, 60.0,
                              'the simulator\'s FATAL line', lambda: open(log).read()[-2000:])
            time.sleep(2.0)
            up = sim.poll() is None
            listening = [c.laddr for p in [psutil.Process(sim.pid)] + psutil.Process(sim.pid).children(recursive=True)
                         for c in p.connections('inet') if c.status == psutil.CONN_LISTEN] if up else []
        finally:
            processes.stop(sim)
        fatal = self.fatal_lines(log)
        self.assertTrue(up, 'the simulator exited instead of staying up in ERROR: ' + open(log).read()[-2000:])
        self.assertEqual(len(fatal), 1, open(log).read()[-2000:])
        self.assertIn('telemetry_host', fatal[0])
        everywhere = [a for a in listening if a.ip in ('0.0.0.0', '::')]
        self.assertEqual(everywhere, [], 'listening on every interface')
        self.record('remote_telemetry_host', 'one FATAL line, then up in ERROR: "%s"; listening: %s'
                    % (fatal[0].split(']: ', 1)[-1][:300], ', '.join('%s:%d' % (a.ip, a.port) for a in listening)
                       or 'nothing'), 'not needed (nothing listens)', None)

    def roslaunch_line(self, args, prefix):
        """Run ``roslaunch ARGS`` without a master (the launch check refuses before anything starts): (exit
        status, the lines starting with ``prefix``, the whole output)."""
        env = dict(self.env, ROS_MASTER_URI='http://127.0.0.1:%d' % processes.free_port())
        out = subprocess.run(['roslaunch'] + args, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, universal_newlines=True, timeout=120)
        return out.returncode, [line for line in out.stdout.splitlines() if line.startswith(prefix)], out.stdout

    def test_08l_launch_numbers(self):
        seen = []
        for arg in ('rtf:=1e308', 'initial_x:=1e300'):
            rc, lines, text = self.roslaunch_line(['anafi_sim', 'sim.launch', arg], 'launch argument %s' % arg)
            self.assertNotEqual(rc, 0, text[-2000:])
            self.assertEqual(len(lines), 1, text[-2000:])
            self.assertNotIn('started with pid', text)
            seen.append('%s: exit %d, "%s"' % (arg, rc, lines[0]))
        rc, lines, text = self.roslaunch_line(['anafi_sim', 'fleet.launch', 'drones:=\u00b2', 'layout:=%s' % LAYOUT],
                                              'launch argument drones:=')
        self.assertNotEqual(rc, 0, text[-2000:])
        self.assertEqual(len(lines), 1, text[-2000:])
        self.assertNotIn('invalid literal', text)
        self.assertNotIn('Traceback', text)
        seen.append('drones:=\u00b2: exit %d, "%s"' % (rc, lines[0]))
        rc, _, text = self.roslaunch_line(['--nodes', 'anafi_sim', 'sim.launch', 'rtf:=1e0'], '')
        self.assertEqual(rc, 0, text[-2000:])
        seen.append('rtf:=1e0 passes the check (exit 0)')
        ns = '/repro_numbers/anafi_sim'
        sim, log = self.start_node('numbers_sim', [paths.data_path('scripts', 'anafi_sim_node.py'), '__name:=anafi_sim',
                                                   '__ns:=/repro_numbers'], [(ns + '/rtf', '1e0')])
        try:
            port = [None]

            def serving():
                try:
                    port[0] = rospy.get_param(ns + '/telemetry_bound_port')
                except KeyError:
                    return sim.poll() is not None
                return True
            processes.require(serving, 60.0, 'the simulator serving with ~rtf \'1e0\'', lambda: open(log).read()[-2000:])
            time.sleep(1.0)
            up = sim.poll() is None
        finally:
            processes.stop(sim)
        text = open(log).read()
        self.assertTrue(up, text[-2000:])
        self.assertEqual(self.fatal_lines(log), [], text[-2000:])
        self.assertIsNotNone(port[0], text[-2000:])
        seen.append('the simulator given ~rtf \'1e0\' runs (telemetry on port %s, no FATAL)' % port[0])
        self.record('launch_numbers', '; '.join(seen), 'not needed (nothing started for a refused number)', None)

    def test_08m_hostile_fleet_file(self):
        marker = os.path.join(self.workdir, 'pwned_fleet')
        fleet = os.path.join(self.workdir, 'hostile_fleet.yaml')
        with open(fleet, 'w') as f:
            f.write('name: hostile\ndrones:\n  - name: a\n    target: {model: "$(eval exec(\\"import os; '
                    'os.system(\'touch %s\')\\", dict()))"}\n' % marker)
        seen = []
        for args in (['--nodes', 'anafi_sim', 'fleet.launch', 'fleet:=%s' % fleet, 'layout:=%s' % LAYOUT],
                     ['anafi_sim', 'fleet.launch', 'fleet:=%s' % fleet, 'layout:=%s' % LAYOUT]):
            rc, lines, text = self.roslaunch_line(args, 'launch argument fleet:=')
            self.assertNotEqual(rc, 0, text[-2000:])
            self.assertEqual(len(lines), 1, text[-2000:])
            self.assertIn('target.model', lines[0])
            self.assertNotIn('started with pid', text)
            seen.append('%s: exit %d' % (' '.join(a for a in args[:3] if not a.startswith('anafi')), rc))
        self.assertFalse(os.path.exists(marker), 'the fleet file ran its code')
        self.record('hostile_fleet_file', '%s, nothing started, FILE not created: "%s"'
                    % (', '.join(seen), lines[0].split(': ', 1)[-1][:300]), 'not needed', None)

    def test_08n_untrusted_text(self):
        from std_msgs.msg import String as Text
        ns = '/repro_text'
        gen, gen_log = self.start_node('text_gen', [paths.data_path('scripts', 'trajectory_generator.py'),
                                                    '__name:=trajectory_generator', '__ns:=' + ns],
                                       [(ns + '/trajectory_generator/wait_for_flying', False),
                                        (ns + '/trajectory_generator/autostart', False)])
        logs = self.env['ROS_LOG_DIR']

        def size(pred):
            return sum(os.path.getsize(os.path.join(r, n)) for r, _, fs in os.walk(logs) for n in fs
                       if pred(os.path.join(r, n)))
        try:
            pub = rospy.Publisher(ns + '/trajectory_generator/command', Text, queue_size=100)
            processes.require(lambda: pub.get_num_connections() > 0 or gen.poll() is not None, 60.0,
                              'the generator listening', lambda: open(gen_log).read()[-2000:])
            mine = lambda p: 'repro_text' in p or p == gen_log
            before, before_all = size(mine) + os.path.getsize(gen_log), size(lambda p: True)
            t0 = time.time()
            for i in range(49):
                pub.publish(Text('switch ' + chr(65 + i % 26) * (1 << 20)))
                time.sleep(0.1)
            time.sleep(3.0)
            up = gen.poll() is None
            grown, grown_all = size(mine) + os.path.getsize(gen_log) - before, size(lambda p: True) - before_all
            seconds = time.time() - t0
            pub.unregister()
        finally:
            processes.stop(gen)
        self.assertTrue(up, open(gen_log).read()[-2000:])
        self.assertLess(grown, 100 * 1024, 'the generator logged %d bytes for 49 MB of commands' % grown)
        longest = max([len(line) for line in open(gen_log).read().splitlines()] or [0])
        self.assertLess(longest, 1000, 'a log line of %d characters' % longest)
        # the alias bomb, in a folder scenario files may come from (ROS_HOME)
        bomb = os.path.join(self.env['ROS_HOME'], 'bomb.yaml')
        with open(bomb, 'w') as f:
            f.write('a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]\n')
            for k in range(1, 12):
                f.write('%s: &%s [%s]\n' % (chr(97 + k), chr(97 + k), ','.join(['*' + chr(96 + k)] * 9)))
        bgen, bomb_log = self.start_node('bomb_gen', [paths.data_path('scripts', 'trajectory_generator.py'),
                                                      '__name:=trajectory_generator', '__ns:=/repro_bomb'],
                                         [('/repro_bomb/trajectory_generator/scenario_file', bomb),
                                          ('/repro_bomb/trajectory_generator/wait_for_flying', False)])
        t1 = time.time()
        try:
            processes.require(lambda: bgen.poll() is not None, 60.0, 'the generator refusing the alias bomb',
                              lambda: open(bomb_log).read()[-2000:])
        finally:
            processes.stop(bgen)
        bomb_seconds = time.time() - t1
        text = open(bomb_log).read()
        fatal = [line for line in text.splitlines() if 'FATAL' in line]
        self.assertEqual(bgen.returncode, 1, text[-2000:])
        self.assertEqual(len(fatal), 1, text[-2000:])
        self.assertLess(len(fatal[0]), 1000, fatal[0][:2000])
        self.assertLess(text.count('lol'), 20, 'the expanded value in the log')
        self.record('untrusted_text', '49 commands of 1 MB in %.1f s: the generator\'s logs grew %d bytes (all logs '
                    'of the graph %d bytes), longest line %d characters; alias bomb: exit 1 after %.1f s, one FATAL '
                    'line "%s"' % (seconds, grown, grown_all, longest, bomb_seconds,
                                   fatal[0].split(']: ', 1)[-1][:300]),
                    'not needed', None)

    def test_09_master_restart(self):
        g = self.g
        self.fly()
        pids = dict((n, self.pid_of(n)) for n in ('/%s/mpc_controller' % DRONE,
                                                                  '/%s/interface' % DRONE, '/%s/anafi_sim' % DRONE))
        hosts = dict((n, self.node_of(n)) for n in pids)    # in the shared layout, the host of each
        t0 = time.time()
        self.procs.stop('roscore')
        time.sleep(2.0)
        core = self.procs.start('roscore', ['roscore', '-p', str(self.port)], self.env)
        processes.require(lambda: processes.master_pid(self.uri) is not None, 30.0, 'the new master')
        del core
        new = {}

        def respawned():
            for n, old in pids.items():
                p = self.pid_of(n)
                if p is None or p == old:
                    return False
                new[n] = p
            return True
        processes.require(respawned, 60.0, 'every node respawned on the new master',
                        lambda: '%s\n%s' % (new, self.procs.log_tail('roslaunch', 30)))
        t_back = time.time()
        # this process cannot register again either: a fresh probe process publishes waypoints and reads
        # the controller's diagnostics on the new master
        probe = PROBE.format(drone=DRONE)
        out = processes.start([sys.executable, '-c', probe], env=self.env)
        rc = out.wait(90.0)
        self.assertEqual(rc, 0, 'probe: the controller did not track a new waypoint publisher on the new master')
        recovery = time.time() - t0
        self.record('master_restart', 'nodes exited (75) and respawned: %s; a new waypoint publisher reaches the '
                    'controller (OK tracking)' % ', '.join(
                        '%s%s %d -> %d' % (n.rsplit('/', 1)[1], ' (%s)' % hosts[n] if hosts[n] != n else '', pids[n],
                                           new[n]) for n in sorted(new)),
                    'the respawned simulator starts a new flight', recovery)
        del t_back, g

    def test_10_clock_jump(self):
        """Own master with use_sim_time: the probe drives /clock, jumps it back, counts the commands."""
        self.skip_shared('clock_jump')
        workdir = os.path.join(self.workdir, 'clock_jump')
        env = processes.ros_env(ros_home=os.path.join(workdir, 'ros_home'), log_dir=os.path.join(workdir, 'log'))
        env['PATH'] = os.path.dirname(sys.executable) + os.pathsep + env.get('PATH', '')
        uri = processes.start_master(self.procs, env, name='roscore_clock')
        launch = os.path.join(workdir, 'clock_jump.launch')
        with open(launch, 'w') as f:
            f.write(CLOCK_LAUNCH)
        port = uri.rsplit(':', 1)[1]
        self.procs.start('roslaunch_clock', ['roslaunch', '--port', port, launch], env)
        probe = processes.start([sys.executable, '-c', CLOCK_PROBE], env=env,
                              log=open(os.path.join(workdir, 'probe.log'), 'w'))
        rc = probe.wait(150.0)
        with open(os.path.join(workdir, 'probe.log')) as f:
            text = f.read()
        self.procs.stop('roslaunch_clock')
        self.procs.stop('roscore_clock')
        lines = [line for line in text.splitlines() if line.startswith('RESULT ')]
        self.assertEqual(rc, 0, text[-3000:])
        r = json.loads(lines[-1][len('RESULT '):])
        for drone in ('m', 'p'):
            d = r[drone]
            self.assertGreater(d['before'], 5, r)          # commands in the 2 s before the jump (10 Hz)
            self.assertGreater(d['after'], 5, r)           # ... and in the last 2 s after it
        for node, jumps in r['jumps'].items():
            self.assertGreaterEqual(jumps, 1, r)
        self.assertGreaterEqual(r['mpc_clock_jumps'], 1, r)     # the MPC's input gate saw it: SILENT, inputs dropped
        self.assertTrue(r['stalled'] and r['stalled'][0][0] == 1 and r['stalled'][0][1].startswith('stalled'), r)
        self.record('clock_jump', 'commands in the 2 s before / the last 2 s after: MPC %d / %d, PID %d / %d; '
                    'first command after the jump: MPC %.1f s, PID %.1f s; "ROS time jumps back": %s; '
                    'MPC clock_jumps %d; /clock stopped: the MPC WARN "%s"'
                    % (r['m']['before'], r['m']['after'], r['p']['before'], r['p']['after'], r['m']['first'],
                       r['p']['first'], ', '.join('%s %d' % kv for kv in sorted(r['jumps'].items())),
                       r['mpc_clock_jumps'], r['stalled'][0][1][:200]),
                    'not needed (no drone in this graph: the controllers\' own cycles are checked)',
                    max(r['m']['first'], r['p']['first']))


#: the clock-jump graph: the MPC (drone m) and the distributed PID (drone p), on a /clock the probe drives
CLOCK_LAUNCH = """<launch>
  <param name="/use_sim_time" value="true"/>
  <include file="$(find anafi_sim)/anafi_sim/launch/mpc.launch">
    <arg name="drone_name" value="m"/>
    <arg name="output" value="log"/>
  </include>
  <include file="$(find anafi_sim)/anafi_sim/launch/pid.launch">
    <arg name="drone_name" value="p"/>
    <arg name="output" value="log"/>
  </include>
</launch>
"""

#: publishes /clock (100 Hz wall, 1 s of sim time per s), a hovering state and a waypoint per drone; once
#: both controllers command steadily the clock jumps 5 s back; prints RESULT {json}: commands per drone before / after, the first command
#: after the jump [s wall], the jump counters of the diagnostics, the MPC's message seen after the jump
CLOCK_PROBE = """
import json, sys, threading, time
import rospy
from rosgraph_msgs.msg import Clock
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from anafi_sim.msg import Waypoint
from anafi_sim.ros.wire_types import piloting_command_class
rospy.init_node('clock_probe', anonymous=True)
Command = piloting_command_class()
lock = threading.Lock()
times = {'m': [], 'p': []}
jumps, silent, stalled = {}, [], []
def on_cmd(drone):
    def cb(msg):
        with lock:
            times[drone].append(time.time())
    return cb
def on_diag(msg):
    for st in msg.status:
        for kv in st.values:
            if kv.key.startswith('ROS time jumps back'):
                node = st.name.split(': ', 1)[-1] if st.name.startswith(('mpc', 'pid')) else st.name
                with lock:
                    jumps[node] = max(jumps.get(node, 0), int(kv.value))
        if st.name.endswith('/m/mpc_controller'):
            if stop_wall is not None and time.time() > stop_wall:
                with lock:
                    stalled.append((st.level, st.message))
            for kv in st.values:
                if kv.key == 'clock_jumps':
                    with lock:
                        silent.append(int(kv.value))
for d in times:
    rospy.Subscriber('/%s/drone/rpyt' % d, Command, on_cmd(d), queue_size=50)
rospy.Subscriber('/diagnostics', DiagnosticArray, on_diag, queue_size=50)
clock = rospy.Publisher('/clock', Clock, queue_size=10)
odom = dict((d, rospy.Publisher('/%s/drone/odom' % d, Odometry, queue_size=10)) for d in times)
wp = dict((d, rospy.Publisher('/%s/position_control/waypoint' % d, Waypoint, queue_size=10)) for d in times)
t_sim, tick, jump_wall, end, stop_wall = 100.0, 0, None, None, None
start = time.time()
while True:
    now = time.time()
    with lock:      # jump once both controllers have commanded for 2 s (at most 90 s after the start)
        steady = all(sum(1 for t in ts if t > now - 2.0) >= 15 for ts in times.values())
    if jump_wall is None and (steady or now - start > 90.0):
        t_sim -= 5.0
        jump_wall = now
    if jump_wall is not None and now - jump_wall > 12.0:
        break
    t_sim += 0.01
    tick += 1
    stamp = rospy.Time.from_sec(t_sim)
    clock.publish(Clock(clock=stamp))
    if tick % 3 == 0:
        for d in times:
            o = Odometry()
            o.header.stamp = stamp
            o.header.frame_id = 'world'
            o.child_frame_id = '%s/base_link' % d
            o.pose.pose.position.z = 2.0
            o.pose.pose.orientation.w = 1.0
            odom[d].publish(o)
    if tick % 10 == 0:
        for d in times:
            w = Waypoint()
            if hasattr(w, 'header'):
                w.header.stamp = stamp
                w.header.frame_id = 'world'
            w.z = 2.0
            wp[d].publish(w)
    time.sleep(max(0.0, start + tick * 0.01 - time.time()))
stop_wall = time.time()      # /clock stops (and with it the inputs): the MPC's cycles freeze
while time.time() - stop_wall < 6.0:
    time.sleep(0.1)
out = {'jumps': jumps, 'mpc_clock_jumps': silent[-1] if silent else -1}
with lock:
    out['stalled'] = [m for m in stalled if m[1].startswith('stalled')][-1:] or stalled[-1:]
with lock:
    for d, ts in times.items():
        after = [t for t in ts if t > jump_wall]
        out[d] = {'before': sum(1 for t in ts if jump_wall - 2.0 < t <= jump_wall),
                  'after': sum(1 for t in ts if t > jump_wall + 10.0),
                  'first': (after[0] - jump_wall) if after else -1.0}
print('RESULT ' + json.dumps(out))
sys.stdout.flush()
"""

RELAY = """
import rospy
from nav_msgs.msg import Odometry
from std_msgs.msg import String
rospy.init_node('fault_relay')
mode = ['relay']
pub = rospy.Publisher('/{drone}/fault/odom', Odometry, queue_size=10, tcp_nodelay=True)
def relay(msg):
    if mode[0] == 'off':
        return
    if mode[0] == 'nan':
        msg.pose.pose.position.x = float('nan')
    pub.publish(msg)
rospy.Subscriber('/{drone}/fault/mode', String, lambda m: mode.__setitem__(0, m.data))
rospy.Subscriber('/{drone}/drone/odom', Odometry, relay, queue_size=10, tcp_nodelay=True)
rospy.spin()
"""

PROBE = """
import sys, time, rospy
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from std_msgs.msg import String
from anafi_sim.msg import Waypoint
rospy.init_node('fault_probe', anonymous=True)
state = {{'ok': False}}
relay = rospy.Publisher('/{drone}/fault/odom', Odometry, queue_size=10)
rospy.Subscriber('/{drone}/drone/odom', Odometry, relay.publish)
def diag(msg):
    for s in msg.status:
        if s.name.endswith('/{drone}/mpc_controller') and s.level == 0 and 'tracking' in s.message:
            state['ok'] = True
rospy.Subscriber('/diagnostics', DiagnosticArray, diag)
pub = rospy.Publisher('/{drone}/position_control/waypoint', Waypoint, queue_size=10)
end = time.time() + 80
while time.time() < end and not state['ok']:
    w = Waypoint(); w.x, w.y, w.z = 0.0, 0.0, 3.0
    pub.publish(w)
    time.sleep(0.1)
sys.exit(0 if state['ok'] else 1)
"""

#: a second waypoint stream from a node of its own ({mode}: 'zero' stamped 0 with frame '', 'future' stamped 0.9 s
#: ahead in world), 7.5 m to the side of the drone, 10 Hz for 4 s once the controller is connected; prints PUBLISHED
SECOND_SOURCE = """
import sys, time, rospy
from nav_msgs.msg import Odometry
from anafi_sim.msg import Waypoint
rospy.init_node('second_source', anonymous=True)
last = []
rospy.Subscriber('/{drone}/sim/truth', Odometry, lambda m: last.append(m.pose.pose.position), queue_size=1)
pub = rospy.Publisher('/{drone}/position_control/waypoint', Waypoint, queue_size=10)
end = time.time() + 30.0
while (not last or pub.get_num_connections() == 0) and time.time() < end:
    time.sleep(0.05)
t0 = time.time()
while time.time() - t0 < 4.0 and not rospy.is_shutdown():
    p = last[-1]
    w = Waypoint()
    if '{mode}' == 'future':
        w.header.stamp = rospy.Time.now() + rospy.Duration(0.9)
        w.header.frame_id = 'world'
    w.x, w.y, w.z = p.x, p.y + 7.5, 3.0
    pub.publish(w)
    time.sleep(0.1)
print('PUBLISHED')
sys.stdout.flush()
time.sleep(30.0)
"""

#: a node registered as itself whose TCPROS connection header claims callerid {claim}; publishes hover commands
#: on the drone's command topic for 2 s once the controller is connected; prints PUBLISHED
IMPOSTER = """
import sys, time, rospy
import rospy.impl.tcpros_pubsub as tcpros
from anafi_sim.ros.wire_types import piloting_command_class
header = tcpros.TCPROSPub.get_header_fields
def forged(self):
    fields = header(self)
    fields['callerid'] = '{claim}'
    return fields
tcpros.TCPROSPub.get_header_fields = forged
rospy.init_node('imposter', anonymous=True)
Command = piloting_command_class()
pub = rospy.Publisher('/{drone}/drone/rpyt', Command, queue_size=10)
end = time.time() + 30.0
while pub.get_num_connections() == 0 and time.time() < end:
    time.sleep(0.05)
t0 = time.time()
while time.time() - t0 < 2.0:
    pub.publish(Command())
    time.sleep(0.1)
print('PUBLISHED')
sys.stdout.flush()
time.sleep(30.0)
"""

#: [MB] written on stderr by the /flood interface's telemetry tool at each start
FLOOD_MB = 600
#: the /flood interface's tlm-data-logger: runs the stand-in (stdout: the samples), floods stderr meanwhile
FLOOD_TOOL = """#!{python}
import os, subprocess, sys
tool = subprocess.Popen([{stand_in!r}] + sys.argv[1:])
chunk = b'E' * (1 << 20)
for _ in range({mb}):
    os.write(2, chunk)
os.write(2, b'\\nflood done\\n')
sys.exit(tool.wait())
"""

#: a TCP relay of the simulator's telemetry port that sends garbage, a malformed number and a 10 kB line
#: first on every connection (each start of the garbage interface's telemetry tool)
GARBAGE_PROXY = """
import socket, threading
GARBAGE = b'garbage line\\nomniscient_anafi.worldPosition.x : 1_000\\n' + b'x' * 10000 + b'\\n'
def pump(a, b):
    try:
        while True:
            data = a.recv(65536)
            if not data:
                break
            b.sendall(data)
    except OSError:
        pass
    for s in (a, b):
        try:
            s.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
def serve(client):
    try:
        upstream = socket.create_connection(('127.0.0.1', {upstream}), timeout=5.0)
    except OSError:
        client.close()
        return
    upstream.settimeout(None)
    client.sendall(GARBAGE)
    pump(upstream, client)
server = socket.socket()
server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
server.bind(('127.0.0.1', {listen}))
server.listen(8)
while True:
    client, _ = server.accept()
    threading.Thread(target=serve, args=(client,), daemon=True).start()
"""


if __name__ == '__main__':
    rostest.rosrun('anafi_sim', 'fault_matrix_shared' if SHARED_LAYOUT else 'fault_matrix', TestFaultMatrix, sys.argv)
