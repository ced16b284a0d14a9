#!/usr/bin/env python3
"""The paper's "Interface": Sphinx ground-truth telemetry -> ROS (thin node).

Stage: telemetry -> **interface** -> (mirror | controllers).
Runs ~telemetry_command as one supervised subprocess (anafi_sim.interface.supervisor): only one of the
known tools with its own arguments (anafi_sim.interface.telemetry_command: Sphinx's tlm-data-logger or
our stand-in, never through a shell; anything else is a bad parameter),
parses its lines (anafi_sim.telemetry.protocol.TelemetryParser), decimates to ~rate
and checks them (anafi_sim.interface.ground_truth.GroundTruthInterface), and publishes
each accepted sample at once, from the reader thread (all publishers are
queued, so ROS I/O never blocks the reader):

- sphinx/drone_data (sphinx_with_gazebo/Sphinx, the reference implementation's type and md5, built at
  run time by anafi_sim.ros.wire_types unless installed; no header): every telemetry value, so the
  reference implementation's nodes (its Gazebo mirror, its controllers) read ours unchanged;
- ground_truth/drone_data (anafi_sim/DroneData): the same values with a header (stamp, frame_id);
- ground_truth/odom (nav_msgs/Odometry): ~frame_id -> <drone>/base_link_gt,
  twist in the body frame;
- /tf, one TFMessage per sample: ~frame_id -> <drone>/stability_axes
  (position, heading) -> <drone>/base_link_gt (roll, pitch) -> <drone>/camera
  (~camera_offset, gimbal roll and pitch); static <drone>/camera ->
  <drone>/camera_optical (z along the view, the Gazebo camera's image frame); with ~publish_body_fixed also
  ~frame_id -> <drone>/body_fixed (position, roll, pitch, yaw: the frame the reference implementation's
  interface publishes and its Gazebo mirror poses the camera through);
- /diagnostics at 1 Hz of wall time (so it reports even when /clock stops): ERROR while
  there is no fresh sample, while the telemetry process is not running (killed,
  restarting) and after a restart until samples flow again; the restart note stays in
  the message.

With ~simulator_node (our simulator, e.g. anafi_sim in the same namespace) the port of the command's
inet:HOST:PORT argument is the one that node serves on (its ~telemetry_bound_port, read before each start:
telemetry_port 0 works) and only samples with its stream id (~telemetry_stream_id) are published; a
stream with another id or none (another drone, a stale port) is refused: ERROR, nothing published, the
telemetry process restarted after ~restart_timeout (anafi_sim.interface.telemetry_source).

The telemetry process is restarted when it exits, prints no byte or no complete sample
for ~restart_timeout s and is judged hung, not starved (anafi_sim.interface.supervisor.hang_verdict: the
process's CPU time and state, the reader's own wake-up lag; a live but starved process is waited for, logged
"late, not hung", counted in the diagnostics' "process starved"); the diagnostics give the reader's largest
wake-up lag of each report period ("reader wake-up lag max [s]", read by the experiment monitor); lines
longer than MAX_LINE bytes are dropped and counted (process oversize lines). Restart warnings are throttled (10 s) with running counts.

Namespace /<drone> (default drone name: the namespace's last part; in the
root namespace the topics go under /<~drone_name>/). Parameters: see
anafi_sim/config/interface.yaml. Under the reference implementation's names (compat.launch): node name
sphinx_interface_node, ~publish_hz = ~rate (wins when set); the node sets ~publish_hz to the rate it
publishes at, where the reference implementation's MPC reads it. Bad parameters: logfatal, then the node stays up in ERROR (not respawned:
docs/nodes.md).
"""
import shlex
import threading
import time

import rospy
from nav_msgs.msg import Odometry
from tf2_msgs.msg import TFMessage

from anafi_sim.interface import ground_truth as gt
from anafi_sim.interface.supervisor import READER_LAG_KEY, ProcessSupervisor
from anafi_sim.interface.telemetry_source import WAITING_FOR_SIMULATOR, SimulatorSource, with_port
from anafi_sim.interface.telemetry_command import allowed_argv

#: [bytes] longest telemetry line taken (a Sphinx line is < 100 bytes); longer ones are dropped and counted
MAX_LINE = 4096
from anafi_sim.msg import DroneData
from anafi_sim import names
from anafi_sim.ros import conversions
from anafi_sim.ros.context import NodeContext
from anafi_sim.ros.wire_types import SPHINX_FIELDS, sphinx_class
from anafi_sim.ros.node import diagnostics_publisher, health_status, private_params, run_node, \
    start_diagnostics_thread
from anafi_sim.telemetry.protocol import DEFAULT_PREFIX, TelemetryParser

DEFAULT_COMMAND = 'tlm-data-logger -r 0 inet:127.0.0.1:9060'
STALE_LOG_PERIOD = 10.0  # s between repeated "stale" log lines
#: x ~restart_timeout: the silence allowed before a telemetry process's first byte (its simulator may still be
#: starting) when it is blocked; a stopped process is killed after ~restart_timeout all the same
START_TIMEOUT_FACTOR = 5.0


def read_params(ctx):
    """All ~params of the instance ``ctx`` (a NodeContext), validated; raises ValueError with a clear message."""
    reader = private_params(ctx)
    p = {'telemetry_command': allowed_argv(reader.command('telemetry_command', DEFAULT_COMMAND)),
         'prefix': reader.word('prefix', DEFAULT_PREFIX, forbidden=':')}
    for name, default in (('rate', 100.0), ('stale_timeout', 0.5), ('restart_timeout', 2.0),
                          ('backoff_initial', 0.2), ('backoff_max', 5.0)):
        p[name] = reader.positive(name, default)
    if ctx.has_param('publish_hz'):        # the reference implementation's name of ~rate wins when set
        p['rate'] = reader.positive('publish_hz', p['rate'])
    p['publish_body_fixed'] = reader.flag('publish_body_fixed', False)
    if p['backoff_max'] < p['backoff_initial']:
        raise ValueError('~backoff_max (%g) must be >= ~backoff_initial (%g)'
                         % (p['backoff_max'], p['backoff_initial']))
    p['camera_offset'] = reader.vector('camera_offset', [0.1, 0.0, 0.0], 3)   # [m]
    p['frame_id'] = reader.ros_name('frame_id', 'world')
    namespace = ctx.namespace.strip('/')
    p['drone_name'] = reader.base_name('drone_name', namespace.split('/')[-1] if namespace else 'anafi')
    p['stamp_with_sample_time'] = reader.flag('stamp_with_sample_time', False)
    p['simulator_node'] = reader.string('simulator_node', '')
    p['topic_base'] = '' if namespace else p['drone_name'] + '/'
    return p


_transform = conversions.transform


class InterfaceNode(object):
    """The interface of one drone (``ctx``: the NodeContext it runs in; None: the process's node)."""

    def __init__(self, ctx=None):
        self.ctx = ctx = ctx or NodeContext.process()
        self.p = params = read_params(ctx)
        drone = params['drone_name']
        self.frame_id = params['frame_id']
        self.base_link = names.ground_truth_frame(drone)
        self.stability_axes = drone + '/stability_axes'
        self.camera = drone + '/camera'
        self.body_fixed = drone + '/body_fixed' if params['publish_body_fixed'] else None
        ctx.set_param('publish_hz', params['rate'])     # read by the reference implementation's MPC
        self.parser = TelemetryParser(prefix=params['prefix'])
        self.core = gt.GroundTruthInterface(publish_rate=params['rate'], stale_timeout=params['stale_timeout'])
        self.lock = threading.Lock()  # parser + core: reader thread vs diagnostics thread
        self.publish_errors = 0
        self.last_publish_error = ''
        base = params['topic_base']
        self.pub_data = ctx.publisher(base + names.DRONE_DATA, DroneData, queue_size=50)
        self.sphinx_class = sphinx_class()
        self.pub_sphinx = ctx.publisher(base + names.SPHINX_DATA, self.sphinx_class, queue_size=50)
        self.pub_odom = ctx.publisher(base + names.GROUND_TRUTH, Odometry, queue_size=50)
        self.pub_diag = diagnostics_publisher()
        self.pub_tf = ctx.publisher(names.TF, TFMessage, queue_size=100)
        ctx.send_static_transforms([_transform(rospy.Time(0), self.camera, drone + '/camera_optical',
                                               (0.0, 0.0, 0.0), gt.CAMERA_OPTICAL_ROTATION)])
        self.diag_name = '%s: ground truth interface' % ctx.name
        self.source = None
        if params['simulator_node']:     # our simulator: its bound port and stream id, read before each start
            self.source = SimulatorSource(params['simulator_node'],
                                          lambda name: rospy.get_param(ctx.resolve(name), None))
            with_port(shlex.split(params['telemetry_command']) if isinstance(params['telemetry_command'], str)
                      else params['telemetry_command'], 1)    # ValueError now if it has no inet:HOST:PORT
        self.supervisor = ProcessSupervisor(   # ValueError for a command string shlex cannot split
            params['telemetry_command'], self.on_line, restart_timeout=params['restart_timeout'],
            backoff_initial=params['backoff_initial'], backoff_max=params['backoff_max'],
            on_event=self.on_event, sample_timeout=params['restart_timeout'], max_line=MAX_LINE,
            start_timeout=START_TIMEOUT_FACTOR * params['restart_timeout'],
            prepare=self._prepare if self.source is not None else None)

    def run(self):
        self.ctx.loginfo('interface: running %r, publishing %s at %.0f Hz', self.supervisor.argv,
                         self.p['topic_base'] + names.GROUND_TRUTH, self.p['rate'])
        rospy.on_shutdown(self.supervisor.stop)
        self.supervisor.start()
        start_diagnostics_thread(1.0, self.diagnostic_statuses, self.pub_diag, ctx=self.ctx)
        rospy.spin()
        self.supervisor.stop()

    def shutdown(self):
        """Stop the telemetry process (the host calls it before ROS shuts down)."""
        self.supervisor.stop()

    # -- supervisor callbacks (supervisor threads) ---------------------------------------
    def _prepare(self, argv):
        argv = self.source.prepare(argv)
        with self.lock:
            if self.core.expected_stream_id != self.source.stream_id:
                self.ctx.loginfo('interface: reading the telemetry of %s on port %d, stream id %d',
                                 self.source.node, self.source.port, self.source.stream_id)
            self.core.expected_stream_id = self.source.stream_id
        return argv

    def on_event(self, kind, info):
        if kind == 'start':
            with self.lock:
                self.parser.reset()  # a sample cut by the previous process must not be completed by this one
                self.parser.stream_id = None
                self.core.on_process_start()   # ERROR until samples flow again
            self.ctx.loginfo('interface: telemetry process started (pid %s)', info.get('pid'))
        elif kind == 'exit':     # throttled: a simulator that is down makes the tool exit again and again
            self.ctx.logwarn_throttle(10.0, 'interface: telemetry process %s exited with code %s%s; restarting in '
                                      '%.1f s (%d exits so far)' % (
                                          info.get('pid'), info.get('code'),
                                          (' (stderr: %s)' % info['stderr']) if info.get('stderr') else '',
                                          info.get('restart_in', 0.0), self.supervisor.exits))
        elif kind == 'hang':
            self.ctx.logwarn_throttle(10.0, 'interface: telemetry process %s hung (%s): killed, restarting in %.1f s '
                                      '(%d hangs so far)' % (
                                          info.get('pid'), info.get('reason', 'no sample for %.1f s'
                                                                    % info.get('silent_for', float('nan'))),
                                          info.get('restart_in', 0.0), self.supervisor.hangs))
        elif kind == 'starved':   # live but starved of CPU (or the reader was): waited for, not killed
            self.ctx.logwarn_throttle(10.0, 'interface: telemetry process %s is late, not hung: %s; waiting (%d '
                                      'such silences so far)' % (info.get('pid'), info.get('reason'),
                                                                 self.supervisor.starved))
        elif kind == 'spawn_failed' and WAITING_FOR_SIMULATOR in str(info.get('message')):
            # the usual start-up order (the simulator binds its port after the interface starts): not an error
            # yet; the diagnostics say ERROR "no telemetry received yet" until samples flow
            self.ctx.loginfo_throttle(10.0, 'interface: %s; retrying in %.1f s' % (
                info.get('message'), info.get('restart_in', 0.0)))
        elif kind == 'spawn_failed':
            self.ctx.logerr_throttle(10.0, 'interface: cannot start telemetry command %r: %s; retrying in %.1f s '
                                     '(%d failures so far)' % (self.supervisor.argv, info.get('message'),
                                                               info.get('restart_in', 0.0),
                                                               self.supervisor.spawn_failures))
        elif kind == 'callback_error':
            self.ctx.logerr('interface: %s', info.get('message'))

    def on_line(self, line, wall_time):
        with self.lock:
            sample = self.parser.feed_line(line, line.endswith('\n'))
            if sample is None:
                return False
            refused = self.core.foreign_samples
            out = self.core.on_sample(sample, wall_time, self.parser.stream_id)
            refused = self.core.foreign_samples > refused
            restarted = self.core.restarted
        if refused:
            self.ctx.logerr_throttle(5.0, 'interface: refusing the telemetry of another drone (stream id %s, '
                                     'expected %s; %d samples refused): nothing published' % (
                                         self.parser.stream_id, self.core.expected_stream_id,
                                         self.core.foreign_samples))
            return False    # not our sample: after restart_timeout the supervisor restarts (re-reads the port)
        if restarted:
            self.ctx.logwarn('interface: simulator restart detected (timestamp jumped back to %.3f s); state reset',
                             sample.timestamp)
        if out is not None:
            try:
                self.publish(out)
            except Exception as exc:  # e.g. shutting down, a value rospy cannot stamp
                self.publish_errors += 1
                self.last_publish_error = '%s: %s' % (type(exc).__name__, exc)
                if not rospy.is_shutdown():
                    self.ctx.logerr_throttle(5.0, 'interface: publishing failed (%d times): %s'
                                             % (self.publish_errors, self.last_publish_error))
        return True     # a sample: the supervisor's sample timer (hang on bytes without samples)

    # -- publishing --------------------------------------------------------------------
    def publish(self, s):
        """One accepted sample -> ground_truth/odom, ground_truth/drone_data, sphinx/drone_data and tf; a
        message nobody subscribes to is not built (publishing it would do nothing)."""
        stamp = rospy.Time.from_sec(s.timestamp) if self.p['stamp_with_sample_time'] else rospy.Time.now()
        odo = gt.odometry(s)
        if self.pub_odom.get_num_connections():
            o = Odometry()
            o.header.stamp = stamp
            o.header.frame_id = self.frame_id
            o.child_frame_id = self.base_link
            o.pose.pose = conversions.pose(odo.position, odo.orientation)
            o.twist.twist = conversions.twist(odo.linear, odo.angular)
            self.pub_odom.publish(o)
        data = self.pub_data.get_num_connections()
        if data or self.pub_sphinx.get_num_connections():
            d = conversions.drone_data(DroneData(), s, stamp, self.frame_id)
            if data:
                self.pub_data.publish(d)
            if self.pub_sphinx.get_num_connections():
                self.pub_sphinx.publish(self.sphinx_class(**dict((f, getattr(d, f)) for f in SPHINX_FIELDS)))
        if self.pub_tf.get_num_connections():
            t_sa, q_sa = gt.stability_axes_pose(s.x, s.y, s.z, s.yaw)
            t_bl, q_bl = gt.base_link_in_stability_axes(s.roll, s.pitch)
            t_cam, q_cam = gt.camera_in_base_link(s.gimbal_roll, s.gimbal_pitch, self.p['camera_offset'])
            transforms = [_transform(stamp, self.frame_id, self.stability_axes, t_sa, q_sa),
                          _transform(stamp, self.stability_axes, self.base_link, t_bl, q_bl),
                          _transform(stamp, self.base_link, self.camera, t_cam, q_cam)]
            if self.body_fixed is not None:     # the reference implementation's frame: the pose in one transform
                transforms.append(_transform(stamp, self.frame_id, self.body_fixed, odo.position, odo.orientation))
            self.pub_tf.publish(TFMessage(transforms=transforms))

    # -- diagnostics (the glue's thread, wall clock) -------------------------------------
    def diagnostic_statuses(self):
        now = time.time()
        with self.lock:
            health = self.core.health(now, self.parser.counters, self.supervisor.snapshot())
            notice = self.core.outage_notice(now, STALE_LOG_PERIOD)
            age = self.core.sample_age(now)
        if notice == 'stale':
            self.ctx.logerr('interface: %s (telemetry process %s): publishing paused',
                            'no ground truth received yet' if age is None else 'no ground truth for %.1f s' % age,
                            'running' if self.supervisor.running else 'not running')
        elif notice == 'flowing':
            self.ctx.loginfo('interface: ground truth flowing again')
        return [health_status(self.diag_name, health, self.p['drone_name'],
                              [('publish errors', str(self.publish_errors)),
                               (READER_LAG_KEY, '%.3f' % self.supervisor.take_reader_lag()),
                               ('telemetry command', ' '.join(self.supervisor.argv))])]


def main():
    run_node('interface', InterfaceNode, fatal_exit_code=2, respawned=True)
